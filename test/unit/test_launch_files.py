"""The ROS 2 launch files (issue 14, bullet 3), checked statically, and their YAML mirrors.

launch_ros is not on PyPI, so the ``launch/*.launch.py`` files are read as Python syntax trees: every
``Node(package="euc_ros", executable=...)`` names an installed node, every params file exists, every
parameter it sets is declared by that node (with a value its declaration accepts where the value is
written out), and every ``LaunchConfiguration`` is a declared argument. Each ``X.launch.py`` has an
``X.yaml`` for ``euc-ros launch`` with the same arguments (and defaults) and the same nodes setting the
same parameters. Where launch_ros imports, the last test runs a launch file for real.
"""
from __future__ import annotations

import ast
import os
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest
import yaml

from euc_ros import launch as euc_launch
from euc_ros.core.errors import ConfigError
from euc_ros.ros.params import validate_params_file
from euc_ros.ros.registry import NODES, node_class

REPO = Path(__file__).resolve().parents[2]
LAUNCH = REPO / "launch"
PY_FILES = sorted(LAUNCH.glob("*.launch.py"))


def _name(node: ast.AST) -> str:
    return node.id if isinstance(node, ast.Name) else node.attr if isinstance(node, ast.Attribute) else ""


def _calls(tree: ast.AST, name: str) -> list[ast.Call]:
    return [n for n in ast.walk(tree) if isinstance(n, ast.Call) and _name(n.func) == name]


def _kw(call: ast.Call, key: str):
    return next((k.value for k in call.keywords if k.arg == key), None)


def _literal(node):
    try:
        return ast.literal_eval(node)
    except ValueError:
        return None


def parse_launch_py(path: Path) -> dict:
    """Arguments (name -> default text or None), argument uses, and nodes of a launch file."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    args = {}
    for call in _calls(tree, "DeclareLaunchArgument"):
        default = _kw(call, "default_value")
        args[_literal(call.args[0])] = None if default is None else _literal(default)
        assert _literal(_kw(call, "description")), f"{path.name}: argument {_literal(call.args[0])} has no description"
    uses = {_literal(c.args[0]) for n in ("LaunchConfiguration", "LaunchConfigurationEquals",
                                          "LaunchConfigurationNotEquals") for c in _calls(tree, n)}
    nodes = []
    for call in _calls(tree, "Node"):
        assert _literal(_kw(call, "package")) == "euc_ros", f"{path.name}: a Node of another package"
        executable = _literal(_kw(call, "executable"))
        params_files, params = [], {}
        for item in _kw(call, "parameters").elts:
            if isinstance(item, ast.Dict):
                for k, v in zip(item.keys, item.values):
                    params[_literal(k)] = _literal(v)       # None where the value is a substitution
            elif isinstance(item, ast.Call) and _name(item.func) == "_params_file":
                params_files.append(f"{_literal(item.args[0])}.yaml")
            elif isinstance(item, ast.Call) and _name(item.func) == "PathJoinSubstitution":
                parts = item.args[0].elts
                assert _literal(parts[-2]) == "config", f"{path.name}: params file outside config/"
                params_files.append(_literal(parts[-1]))
            else:
                pytest.fail(f"{path.name}: unrecognised parameters entry {ast.dump(item)[:80]}")
        nodes.append({"executable": executable, "params_files": params_files, "params": params,
                      "line": call.lineno})
    for call in _calls(tree, "_params_file"):   # the helper must point at config/<node>.yaml
        assert (REPO / "config" / f"{_literal(call.args[0])}.yaml").exists()
    return {"args": args, "uses": uses, "nodes": nodes,
            "processes": [[_literal(a) for a in _kw(c, "cmd").elts] for c in _calls(tree, "ExecuteProcess")]}


def test_there_are_launch_files_for_every_use():
    assert {p.name for p in PY_FILES} == {"pipeline.launch.py", "unicycle.launch.py", "record.launch.py",
                                          "replay.launch.py"}


@pytest.mark.parametrize("path", PY_FILES, ids=lambda p: p.name)
def test_launch_py_names_real_executables_files_and_parameters(path, tmp_path):
    parsed = parse_launch_py(path)
    assert parsed["nodes"], path.name
    undeclared = parsed["uses"] - set(parsed["args"])
    assert not undeclared, f"{path.name}: LaunchConfiguration of undeclared arguments {undeclared}"
    unused = set(parsed["args"]) - parsed["uses"] - {a for cmd in parsed["processes"] for a in cmd if a}
    assert not unused, f"{path.name}: declared but unused arguments {unused}"
    for node in parsed["nodes"]:
        where = f"{path.name}:{node['line']}"
        composed = _composed(node["executable"])
        assert composed, f"{where}: no executable {node['executable']!r}"
        assert node["params_files"] == [f"{n}.yaml" for n in composed], where
        assert all((REPO / "config" / f).exists() for f in node["params_files"]), where
        classes = [node_class(n) for n in composed]
        declared = {s.name for cls in classes for s in cls.SPECS}
        assert set(node["params"]) <= declared, f"{where}: undeclared {set(node['params']) - declared}"
        # the values written out must be accepted by the nodes' declarations (type, range, choices)
        for cls in classes:
            mine = {s.name for s in cls.SPECS}
            literal = {k: v for k, v in node["params"].items() if v is not None and k in mine}
            pf = tmp_path / f"{cls.NAME}.yaml"
            pf.write_text(yaml.safe_dump({cls.NAME: {"ros__parameters": literal}}), encoding="utf-8")
            validate_params_file(str(pf), cls.NAME, cls.SPECS)


def _composed(executable: str) -> list[str]:
    """The registered nodes an executable runs: itself, or the container's default composition."""
    if executable == "pipeline_container":
        from euc_ros.nodes.container import DEFAULT_NODES

        return list(DEFAULT_NODES)
    return [executable] if executable in NODES else []


def _yaml_nodes(path: Path) -> list[dict]:
    return yaml.safe_load(path.read_text(encoding="utf-8"))["nodes"]


@pytest.mark.parametrize("path", PY_FILES, ids=lambda p: p.name)
def test_yaml_mirror_has_the_same_arguments_nodes_and_parameters(path):
    mirror = path.with_name(path.name.replace(".launch.py", ".yaml"))
    assert mirror.exists(), f"{mirror.name} (for euc-ros launch) is missing"
    parsed = parse_launch_py(path)
    args = {a.name: a.default for a in euc_launch.launch_arguments(mirror)}
    assert args == parsed["args"], f"{mirror.name} arguments differ from {path.name}"

    def signature(executable, params):
        return executable, tuple(sorted(params))

    py = Counter(signature(n["executable"], n["params"]) for n in parsed["nodes"])
    ym = Counter(signature(n["executable"], n.get("parameters") or {}) for n in _yaml_nodes(mirror)
                 if _composed(n["executable"]))
    assert py == ym, f"{mirror.name} and {path.name} start different nodes: {py} != {ym}"
    assert len(parsed["processes"]) == sum(1 for n in _yaml_nodes(mirror) if not _composed(n["executable"]))


def _required_args(path: Path) -> dict[str, str]:
    return {a.name: "x.yaml" for a in euc_launch.launch_arguments(path) if a.default is None}


@pytest.mark.parametrize("path", sorted(LAUNCH.glob("*.yaml")), ids=lambda p: p.name)
@pytest.mark.parametrize("bag", ["", "out/bag"])
def test_yaml_launch_files_resolve_to_valid_node_commands(path, bag, tmp_path):
    given = _required_args(path)
    if "bag" in {a.name for a in euc_launch.launch_arguments(path)}:
        given["bag"] = bag
    specs = euc_launch.load_launch_file(path, given)
    names = [s.executable for s in specs]
    if "bag" in given and "recorder" in [n["executable"] for n in _yaml_nodes(path)] and path.stem != "record":
        assert ("recorder" in names) == bool(bag), f"{path.name}: if: $(arg bag) not honoured"
    assert len(set(s.label for s in specs)) == len(specs), f"{path.name}: two processes with one name"
    for spec in specs:
        composed = _composed(spec.executable)
        if not composed:
            assert spec.executable == "euc-ros" and not spec.ros_args
            continue
        for name in composed:
            cls = node_class(name)
            mine = {s.name for s in cls.SPECS}
            pf = tmp_path / f"{name}.yaml"
            pf.write_text(yaml.safe_dump({cls.NAME: {"ros__parameters": {k: v for k, v in spec.parameters.items()
                                                                         if k in mine}}}), encoding="utf-8")
            validate_params_file(str(pf), cls.NAME, cls.SPECS)       # types, ranges and choices
        assert {k for k in spec.parameters} <= {s.name for n in composed for s in node_class(n).SPECS}
        files = [spec.params_file, *spec.params_files]
        assert [Path(f).resolve() for f in files] == [(REPO / "config" / f"{n}.yaml").resolve() for n in composed]


def test_launch_arguments_are_typed_like_launch_ros_and_checked():
    path = LAUNCH / "pipeline.yaml"
    specs = {s.executable: s for s in euc_launch.load_launch_file(
        path, {"session": "s.yaml", "source": "csv", "csv_path": "ride.csv", "h": "0.58",
               "bodies": "['E', 'PV']"})}
    assert specs["torque_estimator"].parameters == {"session_file": "s.yaml", "h": 0.58}
    assert specs["mocap_ingest"].parameters["bodies"] == ["E", "PV"]
    assert specs["mocap_ingest"].parameters["rate_factor"] == 1.0
    assert "recorder" not in specs
    with pytest.raises(ConfigError, match="'session' is required"):
        euc_launch.load_launch_file(path, {})
    with pytest.raises(ConfigError, match="must be one of natnet, topics, csv"):
        euc_launch.load_launch_file(path, {"session": "s", "source": "vrpn"})
    with pytest.raises(ConfigError, match="no launch argument 'sesion'"):
        euc_launch.load_launch_file(path, {"sesion": "s"})
    with pytest.raises(ConfigError, match="name:=value"):
        euc_launch.parse_launch_arguments(["session=s.yaml"])


def test_launch_cli_lists_the_arguments():
    r = subprocess.run([sys.executable, "-m", "euc_ros.cli.main", "launch", str(LAUNCH / "pipeline.yaml"),
                        "--show-args"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert "'session':" in r.stdout and "(required)" in r.stdout and "one of natnet, topics, csv" in r.stdout


@pytest.mark.parametrize("path", PY_FILES, ids=lambda p: p.name)
def test_launch_py_runs_for_real_where_launch_ros_imports(path, tmp_path):
    pytest.importorskip("launch_ros", reason="launch_ros is not on PyPI; the static checks above stand in")
    from launch.launch_description_sources import PythonLaunchDescriptionSource

    from launch import LaunchDescription, LaunchService
    from launch.actions import IncludeLaunchDescription

    description = PythonLaunchDescriptionSource(str(path)).get_launch_description(None)
    assert isinstance(description, LaunchDescription)
    if path.name != "unicycle.launch.py":
        return   # the others need a Motive host, a session or a bag; loading them is the check
    service = LaunchService(argv=[])
    service.include_launch_description(IncludeLaunchDescription(
        PythonLaunchDescriptionSource(str(path)),
        launch_arguments={"duration": "1.0", "bag": str(tmp_path / "bag")}.items()))
    env_before = dict(os.environ)
    try:
        assert service.run() == 0
    finally:
        os.environ.clear()
        os.environ.update(env_before)
    assert (tmp_path / "bag" / "metadata.yaml").exists()


@pytest.mark.parametrize("compose", ["false", "true"])
def test_pipeline_compose_runs_the_three_nodes_in_one_container_or_three_processes(compose):
    specs = euc_launch.load_launch_file(LAUNCH / "pipeline.yaml", {"session": "s.yaml", "source": "csv",
                                                                   "csv_path": "ride.csv", "compose": compose})
    names = sorted(s.executable for s in specs)
    if compose == "true":
        assert names == ["monitor", "pipeline_container"]
        (c,) = [s for s in specs if s.executable == "pipeline_container"]
        assert c.args == ["--nodes", "mocap_ingest,rider_state,torque_estimator"] and not c.name   # no __node remap
        cmd = c.command()
        assert cmd.count("--params-file") == 3 and "-r" not in cmd
        assert c.parameters["session_file"] == "s.yaml" and c.parameters["csv_path"] == "ride.csv"
    else:
        assert names == ["mocap_ingest", "monitor", "rider_state", "torque_estimator"]
