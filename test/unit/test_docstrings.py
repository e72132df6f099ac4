"""The public functions, classes and methods of the documented core modules carry numpydoc sections.

Every public function, class and public method defined in a module of ``DOCUMENTED`` (not imported into it)
passes ``numpydoc.validate.validate`` for the error codes of ``CODES``. Add a subpackage or module to
``DOCUMENTED`` once its docstrings are written; the list only grows.

Run as a script (``python test/unit/test_docstrings.py``) it prints, per core subpackage, how many objects
fail the checks, documented or not.
"""
from __future__ import annotations

import ast
import dataclasses
import importlib
import inspect
import pkgutil
import textwrap
import typing
from collections import Counter

import pytest

validate = pytest.importorskip("numpydoc.validate", reason="numpydoc is not installed (requirements.txt)")

#: The numpydoc error codes this test enforces.
CODES = {
    "GL08": "no docstring",                        # the object is not documented at all
    "PR01": "a parameter is not documented",       # a signature parameter missing from Parameters
    "PR02": "a documented parameter is unknown",   # Parameters names something the signature lacks
    "RT01": "no Returns section",                  # a function that returns a value does not say what
}

#: Packages and modules under euc_ros/core whose docstrings are complete (a package includes its submodules).
DOCUMENTED: tuple[str, ...] = (
    "euc_ros.core.errors", "euc_ros.core.memory", "euc_ros.core.robust", "euc_ros.core.rotations",
    "euc_ros.core.yamlfile", "euc_ros.core.anthropometry", "euc_ros.core.session",
    "euc_ros.core.io", "euc_ros.core.model", "euc_ros.core.mocap", "euc_ros.core.online",
    "euc_ros.core.unicycle", "euc_ros.core.ridesim", "euc_ros.core.identify",
    "euc_ros.core.openworld", "euc_ros.core.worldsim", "euc_ros.core.states", "euc_ros.core.filters",
    "euc_ros.core.residual",
)

#: Modules of DOCUMENTED packages whose sections are still to write, with why (the list only shrinks: a module
#: that passes must leave it).
PENDING: dict[str, str] = {}

#: Objects exempt from the check, with why.
EXEMPT = {
    # the compiled right-hand side's argument pack: one field per attribute of the simulator objects it mirrors
    # (named in its docstring), read by the numba kernel only
    "euc_ros.core.ridesim.compiled:RunParams": "numba kernel's parameter pack",
}

#: Modules exempt from the check: sympy writes them (``ridesim/eom_codegen.py``), their parameters are the
#: model's symbols, documented once in the generator.
GENERATED = frozenset({"euc_ros.core.ridesim.eom_generated"})


def modules(names) -> list[str]:
    """Dotted names of the modules of ``names``, packages expanded to their submodules."""
    out = []
    for name in names:
        mod = importlib.import_module(name)
        out.append(name)
        if hasattr(mod, "__path__"):
            out += [m.name for m in pkgutil.walk_packages(mod.__path__, name + ".")]
    return sorted(set(out) - GENERATED)


def is_compiled(obj) -> bool:
    """Whether ``obj`` is a numba dispatcher (exempt).

    A kernel's signature is the flat arrays and scalars its one caller unpacks for it (numba takes no objects);
    the caller's docstring documents those quantities, and the kernel's says how it lays them out.
    """
    return type(obj).__module__.startswith("numba")


def is_generated_method(cls, name: str) -> bool:
    """Whether ``cls.name`` is written by ``dataclasses`` or ``typing.NamedTuple`` rather than by hand."""
    if dataclasses.is_dataclass(cls) and name in {"__init__", "__repr__", "__eq__", "__hash__", "__setattr__",
                                                  "__delattr__", "__match_args__", "__replace__"}:
        return True
    return issubclass(cls, tuple) and hasattr(cls, "_fields")


def returns_none(func) -> bool:
    """Whether ``func`` returns nothing, so needs no Returns section.

    ``__init__`` and the like; a return annotation of ``None``; without a return annotation, a body with no
    ``return <value>`` (nested functions and classes not counted).
    """
    if func.__name__ in {"__init__", "__post_init__", "__setattr__", "__exit__", "__del__"}:
        return True
    raw = func.__annotations__.get("return", inspect.Signature.empty)
    if raw is not inspect.Signature.empty:
        try:
            ret = typing.get_type_hints(func).get("return")
        except (NameError, TypeError):   # a forward reference that does not resolve here: the annotation's text
            ret = raw
        return ret in (None, type(None), "None")
    tree = ast.parse(textwrap.dedent(inspect.getsource(func)))
    stack, found = list(tree.body[0].body), False
    while stack and not found:
        node = stack.pop()
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef, ast.Lambda)):
            continue
        found = isinstance(node, ast.Return) and node.value is not None and not (
            isinstance(node.value, ast.Constant) and node.value.value is None)
        stack.extend(ast.iter_child_nodes(node))
    return not found


def undocumented(message: str) -> set[str]:
    """The parameter names of a PR01 message (``Parameters {'a', 'b'} not documented``)."""
    return ast.literal_eval(message[message.index("{"):message.rindex("}") + 1])


def public_objects(module_name: str):
    """``(qualname, object)`` of the public functions, classes and methods defined in the module."""
    mod = importlib.import_module(module_name)
    for name, obj in vars(mod).items():
        if name.startswith("_") or getattr(obj, "__module__", None) != module_name or is_compiled(obj):
            continue
        if inspect.isfunction(obj):
            yield name, obj
        elif inspect.isclass(obj):
            yield name, obj
            for mname, member in vars(obj).items():
                if (mname.startswith("_") and mname != "__init__") or is_generated_method(obj, mname):
                    continue
                if isinstance(member, (staticmethod, classmethod)):
                    member = member.__func__
                if inspect.isfunction(member) and not is_compiled(member):
                    yield f"{name}.{mname}", member


def problems(module_name: str) -> list[str]:
    """``module:qualname CODE message`` for each error of ``CODES`` in the module."""
    out = []
    for qualname, obj in public_objects(module_name):
        if f"{module_name}:{qualname}" in EXEMPT:
            continue
        if qualname.endswith(".__init__") and not (obj.__doc__ or "").strip():
            continue  # numpydoc reads a class's parameters from the class docstring
        result = validate.validate(f"{module_name}.{qualname}")
        for code, message in result["errors"]:
            if code not in CODES or (code == "RT01" and (inspect.isclass(obj) or returns_none(obj))):
                continue
            if code == "PR01" and all(n.startswith("_") for n in undocumented(message)):
                continue  # private dataclass fields (a class's internal state) are no part of its interface
            out.append(f"{module_name}:{qualname} {code} {message}")
    return out


def test_documented_modules_have_numpydoc_sections():
    found = [p for m in modules(DOCUMENTED) if m not in PENDING for p in problems(m)]
    assert not found, f"{len(found)} numpydoc errors (codes: {CODES}):\n  " + "\n  ".join(found)


def test_pending_modules_are_documented_modules_that_still_fail():
    assert set(PENDING) <= set(modules(DOCUMENTED)), sorted(set(PENDING) - set(modules(DOCUMENTED)))
    done = [m for m in PENDING if not problems(m)]
    assert not done, f"these pass now: remove them from PENDING: {done}"


if __name__ == "__main__":
    # per core subpackage or top-level module: the objects with errors, and whether the test checks them
    failing, checked, total = Counter(), Counter(), Counter()
    documented = set(modules(DOCUMENTED)) - set(PENDING)
    for m in modules(["euc_ros.core"]):
        key = ".".join(m.split(".")[:3])
        total[key] += 1
        checked[key] += m in documented
        failing[key] += len({p.split(" ")[0] for p in problems(m)})
    for key in sorted(total):
        state = {0: "", total[key]: "documented"}.get(checked[key],
                                                      f"{checked[key]} of {total[key]} modules documented")
        print(f"{failing[key]:5d}  {key}  {state}")
    print(f"{sum(failing.values()):5d}  objects with errors in euc_ros/core")
