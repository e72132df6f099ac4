"""The test tree mirrors the core: every ``euc_ros/core/<sub>/<module>.py`` has its
``test/unit/core/<sub>/test_<module>.py``, or a test file that exercises it (imports it or calls it) names it
in a line ``# covers: euc_ros/core/<sub>/<module>.py``.

Run as a script (``python test/unit/test_test_layout.py``) it prints each core module with the test that covers it.
"""
from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
CORE = REPO / "euc_ros" / "core"
TESTS = REPO / "test"
COVERS = re.compile(r"^# covers: (euc_ros/core/\S+\.py)\s*$", re.MULTILINE)

#: Core modules that still need tests: no test file imports them or calls them directly (each is exercised only
#: through other modules or a command). Remove a module from here when its test is written.
UNCOVERED: set[str] = set()


def core_modules() -> list[str]:
    return sorted(p.relative_to(REPO).as_posix() for p in CORE.rglob("*.py") if p.name != "__init__.py")


def mirror(module: str) -> Path:
    """``euc_ros/core/<sub>/<module>.py`` -> ``test/unit/core/<sub>/test_<module>.py``."""
    rel = Path(module).relative_to("euc_ros/core")
    return TESTS / "unit" / "core" / rel.parent / f"test_{rel.name}"


def covers() -> dict[str, list[str]]:
    """Module -> the test files that name it in a ``# covers:`` line."""
    out: dict[str, list[str]] = {}
    for f in sorted(TESTS.rglob("test_*.py")):
        for module in COVERS.findall(f.read_text(encoding="utf-8")):
            out.setdefault(module, []).append(f.relative_to(REPO).as_posix())
    return out


def test_every_core_module_has_a_test_of_its_name_or_one_that_covers_it():
    named = covers()
    missing = [m for m in core_modules() if not mirror(m).is_file() and m not in named and m not in UNCOVERED]
    assert not missing, ("core modules without test/unit/core/<sub>/test_<module>.py or a test file naming them "
                         "in '# covers: <path>':\n  " + "\n  ".join(missing))


def test_covers_lines_and_the_uncovered_list_name_modules_that_exist():
    modules = set(core_modules())
    stale = {m: files for m, files in covers().items() if m not in modules}
    assert not stale, f"'# covers:' lines naming no core module: {stale}"
    assert UNCOVERED <= modules, f"UNCOVERED names no core module: {sorted(UNCOVERED - modules)}"
    tested = {m for m in UNCOVERED if mirror(m).is_file() or m in covers()}
    assert not tested, f"these have a test now: remove them from UNCOVERED: {sorted(tested)}"


if __name__ == "__main__":
    named = covers()
    for m in core_modules():
        how = (mirror(m).relative_to(REPO).as_posix() if mirror(m).is_file() else
               ", ".join(named.get(m, [])) or ("UNCOVERED" if m in UNCOVERED else "MISSING"))
        print(f"{m:50s} {how}")
