"""The API reference builds from the docstrings: ``docs/build_api.py`` writes one HTML page per module.

The build runs in a subprocess, as a user runs it, into a temporary folder, with ``--no-source``: the
highlighted source is pdoc's own rendering of the same modules and half of the build's time. Only modules whose place
is stable are asserted by name (the top package and the CLI dispatcher); the rest is counted.
"""
from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SCRIPT = REPO / "docs" / "build_api.py"
pytestmark = pytest.mark.slow   # the build imports every module and renders ~260 pages (~45 s)

#: Fewer pages than this means whole subpackages went missing (the package has well over 100 modules).
MIN_MODULE_PAGES = 60


def first_docstring_line(path: Path) -> str:
    """The first line of a module's docstring, read without importing it."""
    doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8")))
    assert doc, f"{path} has no module docstring"
    return doc.splitlines()[0]


@pytest.fixture(scope="module")
def api_dir(tmp_path_factory) -> Path:
    pytest.importorskip("pdoc", reason="pdoc is not installed (requirements-build.txt)")
    out = tmp_path_factory.mktemp("api")
    r = subprocess.run([sys.executable, str(SCRIPT), "--out", str(out), "--no-source"], cwd=REPO,
                       capture_output=True, text=True, timeout=170)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    return out


@pytest.mark.parametrize(("module", "page"), [
    ("euc_ros/__init__.py", "euc_ros.html"),
    ("euc_ros/cli/main.py", "euc_ros/cli/main.html"),
])
def test_key_module_pages_hold_their_docstrings(api_dir, module, page):
    html = (api_dir / page).read_text(encoding="utf-8")
    # pdoc renders the docstring as HTML: compare words, not markup
    words = [w.strip("`.,:()") for w in first_docstring_line(REPO / module).split()]
    for word in (w for w in words if w.isalpha() and len(w) > 3):
        assert word in html, f"{page} lacks {word!r} of the module docstring"


def test_every_subpackage_has_pages(api_dir):
    pages = list((api_dir / "euc_ros").rglob("*.html"))
    assert len(pages) >= MIN_MODULE_PAGES, sorted(p.name for p in pages)
    for sub in ("core", "cli", "nodes"):
        assert (api_dir / "euc_ros" / f"{sub}.html").is_file()
        assert any((api_dir / "euc_ros" / sub).rglob("*.html")), f"no module page under euc_ros/{sub}/"
    assert (api_dir / "index.html").is_file()
