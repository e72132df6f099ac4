#!/usr/bin/env python3
"""Build the HTML API reference of euc_ros from its numpydoc docstrings with pdoc.

Usage (from the repository root, in the project's venv)::

    python docs/build_api.py                 # writes build/api/index.html and one page per module
    python docs/build_api.py --out DIR       # somewhere else
    python docs/build_api.py --no-source     # without each function's highlighted source (half the time)

Every public module of the package gets a page, including the submodules a package leaves out of
its ``__all__``. A module that cannot be imported on this machine (for example a node module where
rclpy is missing) is left out and named on stderr; the build fails only if the top package itself
does not import. pdoc is pinned in ``requirements-build.txt``.
"""
from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PACKAGE = "euc_ros"


def module_names(package: str = PACKAGE) -> tuple[list[str], list[str]]:
    """Return the importable public modules of ``package`` and the ones that failed to import.

    Parameters
    ----------
    package : str
        Name of the top package.

    Returns
    -------
    names : list of str
        Dotted names of the public modules that import, the top package first.
    failed : list of str
        ``"name: reason"`` for every public module that does not import.
    """
    top = importlib.import_module(package)
    names, failed = [package], []
    found = pkgutil.walk_packages(top.__path__, prefix=f"{package}.",
                                  onerror=lambda name: failed.append(f"{name}: cannot be walked"))
    for info in sorted(found, key=lambda i: i.name):
        if any(part.startswith("_") for part in info.name.split(".")):
            continue
        try:
            importlib.import_module(info.name)
        except Exception as exc:  # noqa: BLE001 - any import failure only leaves the page out
            failed.append(f"{info.name}: {type(exc).__name__}: {exc}")
            continue
        names.append(info.name)
    return names, failed


def build(out: Path, show_source: bool = True) -> int:
    """Write the API reference into ``out``; return the number of module pages.

    Parameters
    ----------
    out : Path
        Output folder (made if missing).
    show_source : bool
        Whether each page carries its objects' highlighted source (about half of the build's time).

    Returns
    -------
    int
        The number of module pages.
    """
    import pdoc
    import pdoc.render

    names, failed = module_names()
    for line in failed:
        print(f"build_api: left out {line}", file=sys.stderr)
    pdoc.render.configure(docformat="numpy", footer_text="euc_ros API reference", show_source=show_source)
    out.mkdir(parents=True, exist_ok=True)
    pdoc.pdoc(*names, output_directory=out)
    return len(names)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=REPO / "build" / "api",
                        help="output folder (default: build/api of the repository)")
    parser.add_argument("--no-source", dest="show_source", action="store_false",
                        help="leave out each object's highlighted source (the pages build in about half the time)")
    args = parser.parse_args(argv)
    try:
        import pdoc  # noqa: F401
    except ImportError:
        print("build_api: error: pdoc is not installed (pip install -r requirements-build.txt)",
              file=sys.stderr)
        return 2
    n = build(args.out, show_source=args.show_source)
    print(f"build_api: {n} module pages in {args.out}")
    return 0


if __name__ == "__main__":
    sys.path.insert(0, str(REPO))
    sys.exit(main())
