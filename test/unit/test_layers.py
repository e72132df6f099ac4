"""The core's layers and the package's import graph: every import (module level or inside a function)
goes down the order of :data:`euc_ros.core.LAYERS`, no import cycle exists anywhere in ``euc_ros``, and no
module imports another module's private (underscore) names."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

from euc_ros.core import LAYERS

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "euc_ros"
CORE = PACKAGE / "core"


def module_name(path: Path) -> str:
    """Dotted module name of a file under the repository root (``pkg/__init__.py`` -> ``pkg``)."""
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


MODULES = {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def imports_of(path: Path, modules=MODULES) -> list[tuple[str, int, tuple[str, ...]]]:
    """Every import of ``path`` (module level and inside functions): ``(target module, line, names)``.

    ``from a.b import c`` targets the module ``a.b.c`` when it is one, else ``a.b``; relative imports
    are resolved against the file's package.
    """
    mod = module_name(path)
    package = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out += [(a.name, node.lineno, ()) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")[:len(package.split(".")) - (node.level - 1)]
                base = ".".join(up + ([base] if base else []))
            for a in node.names:
                sub = f"{base}.{a.name}"
                out.append((sub, node.lineno, ()) if sub in modules else (base, node.lineno, (a.name,)))
    return out


def layer_of(module: str) -> tuple[int, str] | None:
    """``(rank, name)`` of a core module in :data:`LAYERS`, or None outside the core."""
    parts = module.split(".")
    if parts[:2] != ["euc_ros", "core"] or len(parts) < 3:
        return None
    for rank, names in enumerate(LAYERS):
        if parts[2] in names:
            return rank, parts[2]
    raise AssertionError(f"{module} is in no layer of euc_ros.core.LAYERS")


def test_every_core_module_has_a_layer():
    listed = {name for names in LAYERS for name in names}
    assert len(listed) == sum(len(names) for names in LAYERS), "a name is listed twice in LAYERS"
    present = {p.relative_to(CORE).parts[0].removesuffix(".py") for p in CORE.rglob("*.py")} - {"__init__"}
    assert present == listed, (f"not in LAYERS: {sorted(present - listed)}; "
                               f"listed but absent: {sorted(listed - present)}")


@pytest.mark.parametrize("path", sorted(CORE.rglob("*.py")), ids=lambda p: str(p.relative_to(CORE)))
def test_core_imports_go_down_the_layers(path):
    here = layer_of(module_name(path))
    if here is None:                    # euc_ros/core/__init__.py itself
        return
    bad = []
    for target, line, _ in imports_of(path):
        if target.split(".")[0] != "euc_ros":
            continue
        there = layer_of(target)
        assert there is not None, f"{path.name}:{line} imports {target} from outside the core"
        if there[0] > here[0]:
            bad.append(f"line {line}: {target} (layer {there[1]!r} is above {here[1]!r})")
        elif there[0] == here[0] and there[1] != here[1]:
            bad.append(f"line {line}: {target} ({there[1]!r} is a sibling of {here[1]!r})")
    assert not bad, f"{module_name(path)} breaks the layer order:\n" + "\n".join(bad)


def import_graph() -> dict[str, set[str]]:
    """Module -> the euc_ros modules it imports (module level and inside functions)."""
    graph = {}
    for mod, path in MODULES.items():
        graph[mod] = {t for t, _, _ in imports_of(path) if t in MODULES and t != mod}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), each as a list of modules."""
    index, low, stack, on_stack, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_cycles_finds_a_cycle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycle_in_the_package():
    found = cycles(import_graph())
    assert not found, "import cycles:\n" + "\n".join(" <-> ".join(c) for c in found)


def test_no_private_name_is_imported_across_modules():
    bad = []
    for mod, path in MODULES.items():
        for target, line, names in imports_of(path):
            if target.split(".")[0] == "euc_ros" and target != mod:
                bad += [f"{mod}:{line} imports {n} from {target}" for n in names if n.startswith("_")]
    assert not bad, "\n".join(bad)


def test_no_import_cycle_between_the_subpackages():
    """``cli`` may use ``bench`` or the reverse, not both: the graph folded to ``euc_ros.<first part>``."""
    folded: dict[str, set[str]] = {}
    for mod, targets in import_graph().items():
        here = ".".join(mod.split(".")[:2])
        folded.setdefault(here, set()).update(".".join(t.split(".")[:2]) for t in targets)
    for mod in folded:
        folded[mod].discard(mod)
    found = cycles({m: {t for t in ts if t in folded} for m, ts in folded.items()})
    assert not found, "import cycles between subpackages:\n" + "\n".join(" <-> ".join(c) for c in found)


def test_nothing_outside_the_cli_imports_the_cli():
    """The library does not depend on its command line (rosbag2's way round): the pipelines the commands run
    live in the core, and the API, the nodes, the benchmarks and the campaigns call them there."""
    bad = [f"{mod}:{line} imports {target}" for mod, path in MODULES.items() if not mod.startswith("euc_ros.cli")
           for target, line, _ in imports_of(path) if target == "euc_ros.cli" or target.startswith("euc_ros.cli.")]
    assert not bad, "\n".join(bad)

