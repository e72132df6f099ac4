"""Print the sympy-derived truth equations as plain numeric functions (:mod:`.eom_generated`).

:mod:`.eom_derivation` derives the equations of motion of the three truth geometries (level, floor of
varying slope, pedals that flex) from the point kinematics with sympy. The derivation is the single
source; this module prints its expressions, after common-subexpression elimination, as Python
functions of floats that use only ``numpy`` functions. The printed file, :mod:`.eom_generated`, serves

* the simulator without sympy at run time (the derivation costs a few seconds per process), and
* the compiled right-hand side (:mod:`.compiled`), which compiles the same functions with numba.

The functions work on floats and on broadcasting numpy arrays alike. Regenerate the file after
changing a derivation::

    python -m euc_ros.core.ridesim.eom_codegen

``test/unit/core/ridesim/test_eom_generated.py`` checks that the file is exactly what this module prints
and that its functions agree with the lambdified derivation.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

#: Truth geometries and the functions each one provides (``jac_g``/``vel_g``: rider CoG, level model only).
MODELS = (("planar", ("mass", "bias", "jac_g", "vel_g")), ("floor", ("mass", "bias")), ("pedal", ("mass", "bias")))

#: The file this module writes.
TARGET = Path(__file__).with_name("eom_generated.py")

_DOCS = {
    "mass": "Mass matrix M: the upper triangle of the symmetric 3x3 row by row (6 entries).",
    "mass4": "Mass matrix M: all 16 entries of the 4x4, row-major.",
    "bias": "Bias vector b: velocity terms, rheonomic h(t) terms and minus the gravity forces.",
    "jac_g": "Rider CoG Jacobian dG/dq (2x3), row-major.",
    "vel_g": "In-plane velocity of the rider CoG G, including the h_dot term.",
}

_HEADER = '''"""Numeric truth equations, printed from the sympy derivation of :mod:`.eom_derivation`: do not edit.

Written by :mod:`euc_ros.core.ridesim.eom_codegen` (``python -m euc_ros.core.ridesim.eom_codegen``).
Each function returns a tuple of floats or of broadcasting numpy arrays; the arguments are the
derivation's symbols (SI units, rad), the physical parameters last in the order of
:class:`~euc_ros.core.ridesim.truth_model.PlanarParams` (m, m0, mw, Jw, J0, J, R, l0, h0).
"""
# ruff: noqa: E501
import numpy

'''


def _derivations() -> dict:
    from euc_ros.core.ridesim import eom_derivation as d

    return {"planar": d.derive_planar, "floor": d.derive_floor, "pedal": d.derive_pedal}


def _function_source(name: str, args, exprs, doc: str) -> str:
    """Source of one function: common subexpressions first, then the returned tuple."""
    import sympy as sp
    from sympy.printing.numpy import NumPyPrinter

    printer = NumPyPrinter({"fully_qualified_modules": True, "allow_unknown_functions": False})

    def show(e) -> str:
        if e.is_number:
            return repr(float(e))
        return printer.doprint(e)

    subs, reduced = sp.cse(list(exprs), symbols=sp.numbered_symbols("c_"), order="canonical")
    lines = [f"def {name}({', '.join(str(a) for a in args)}):", f'    """{doc}"""']
    lines += [f"    {s} = {show(e)}" for s, e in subs]
    out = ", ".join(show(e) for e in reduced)
    lines.append(f"    return ({out},)" if len(reduced) == 1 else f"    return ({out})")
    return "\n".join(lines) + "\n"


def generated_source() -> str:
    """The full text of :mod:`.eom_generated` as the current derivation prints it.

    Returns
    -------
    str
        The module's source.
    """
    derive = _derivations()
    parts = [_HEADER]
    names = []
    for model, funcs in MODELS:
        compiled = derive[model]()
        for f in funcs:
            args, exprs = compiled.functions[f]
            name = f"{model}_{f}"
            names.append(name)
            doc = _DOCS["mass4" if f == "mass" and len(exprs) == 16 else f]
            parts.append("\n" + _function_source(name, args, exprs, doc) + "\n")
    parts.append("\n__all__ = [" + ", ".join(f'"{n}"' for n in names) + "]\n")
    return "".join(parts).replace("\n\n\n\n", "\n\n\n")


def main(argv: list[str] | None = None) -> int:
    """Write :data:`TARGET` (``--check``: exit 1 when it differs from what the derivation prints).

    Parameters
    ----------
    argv : list of str, optional
        Command-line arguments (``--check``); default ``sys.argv[1:]``.

    Returns
    -------
    int
        Exit code: 0, or 1 when ``--check`` finds a difference.
    """
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="compare instead of writing")
    args = parser.parse_args(argv)
    text = generated_source()
    if args.check:
        same = TARGET.is_file() and TARGET.read_text(encoding="utf-8") == text
        print(f"{TARGET.name}: {'up to date' if same else 'differs from the derivation'}")
        return 0 if same else 1
    TARGET.write_text(text, encoding="utf-8")
    print(f"wrote {TARGET}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
