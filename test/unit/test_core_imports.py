"""The core stays ROS-free: no module under euc_ros/core imports rclpy, *_msgs or matplotlib at module level."""
import ast
from pathlib import Path

import pytest

CORE = Path(__file__).resolve().parents[2] / "euc_ros" / "core"
BANNED = ("rclpy", "euc_msgs", "matplotlib")


def _module_level_imports(tree: ast.Module):
    for node in tree.body:
        if isinstance(node, ast.Import):
            yield from (a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            yield node.module


@pytest.mark.parametrize("path", sorted(CORE.rglob("*.py")), ids=lambda p: str(p.relative_to(CORE)))
def test_core_module_is_ros_free(path):
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for name in _module_level_imports(tree):
        top = name.split(".")[0]
        assert top not in BANNED and not top.endswith("_msgs"), f"{path.name} imports {name}"
    # no import of them anywhere in the file either (lazy imports included), except matplotlib in functions
    for node in ast.walk(tree):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]
            for name in names:
                top = name.split(".")[0]
                assert top != "rclpy" and not top.endswith("_msgs"), f"{path.name} imports {name}"
