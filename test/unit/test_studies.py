"""The study scripts' folder shadows no installed package.

A script run as ``python studies/x.py`` puts ``studies/`` first on ``sys.path``: a module there named like an
installed package (``coverage``, which numba imports) would be imported instead of it, far from the cause.
"""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

STUDIES = Path(__file__).resolve().parents[2] / "studies"


def test_no_study_module_is_named_like_an_installed_package():
    here = {p.stem for p in STUDIES.glob("*.py")}
    saved = list(sys.path)
    sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() not in (STUDIES, STUDIES.parent)]
    try:
        shadowing = sorted(n for n in here if n != "__init__" and importlib.util.find_spec(n) is not None)
    finally:
        sys.path[:] = saved
    assert not shadowing, f"studies/ modules named like installed packages: {shadowing}; rename them"
    assert here, "no study scripts found"
