"""The package's ROS 2 XML launch files, and the parser ``euc-ros launch`` reads them with.

launch_ros is not on PyPI, so ``ros2 launch`` cannot run here. Two independent checks stand in:
the XML is read with ElementTree and held against what ROS 2 Jazzy's frontend reads (the tags and
attributes of launch's and launch_ros' ``parse`` methods, its substitutions), and every file is
resolved with :mod:`euc_ros.ros.launch_file` for every argument combination that changes what starts,
each process checked against the node's ParamSpec table (names declared, values of the declared
type, range and choices) and its params files. Where launch_ros imports, the last test runs a file
through the real ``ros2 launch`` machinery.
"""
from __future__ import annotations

import itertools
import os
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import yaml

from euc_ros.core.errors import ConfigError
from euc_ros.ros import launch_file as lf
from euc_ros.ros.launcher import NodeSpec, typed_parameters
from euc_ros.ros.params import validate_params_file
from euc_ros.ros.registry import NODES, node_class

REPO = Path(__file__).resolve().parents[2]
LAUNCH = REPO / "launch"
FILES = sorted(LAUNCH.glob("*.launch.xml"))

#: What ROS 2 Jazzy's XML frontend reads: element -> attributes (launch.actions.*.parse and
#: launch_ros.actions.Node.parse; ``if``/``unless`` come from Action.parse).
_PROCESS = {"cmd", "cwd", "name", "on_exit", "launch-prefix", "output", "respawn", "respawn_max_retries",
            "respawn_delay", "sigkill_timeout", "sigterm_timeout", "shell", "emulate_tty", "if", "unless"}
JAZZY_ELEMENTS = {
    "launch": {"deprecated"},
    "arg": {"name", "default", "description", "if", "unless"},
    "choice": {"value"},
    "executable": _PROCESS,
    "node": (_PROCESS - {"cmd"}) | {"pkg", "exec", "name", "namespace", "args", "ros_args", "node-name", "exec_name"},
    "param": {"name", "value", "value-sep", "type", "from", "allow_substs"},
    "remap": {"from", "to"},
    "env": {"name", "value"},
}
#: Where each element may appear in Jazzy (children parsed by their parent's parse method).
JAZZY_CHILDREN = {"launch": {"arg", "node", "executable"}, "arg": {"choice"}, "node": {"param", "remap", "env"},
                  "executable": {"env"}, "param": {"param"}}
#: Substitutions Jazzy's frontend exposes (launch and launch_ros ``expose_substitution``).
JAZZY_SUBSTITUTIONS = {"anon", "not", "and", "or", "any", "all", "command", "env", "equals", "not-equals",
                       "file-content", "find-exec", "if", "var", "launch_log_dir", "log_dir", "eval", "filename",
                       "dirname", "exec-in-pkg", "find-pkg-prefix", "find-pkg-share", "param"}
#: ``<param type>`` identifiers of Jazzy (launch.frontend.type_utils.get_data_type_from_identifier).
JAZZY_PARAM_TYPES = {"str", "bool", "float", "int", "list_of_str", "list_of_bool", "list_of_float", "list_of_int",
                     "yaml"}
#: What ROS 2 condition expressions accept after substitution (evaluate_condition_expression).
CONDITION_VALUES = {"true", "1", "false", "0"}


def test_the_package_has_its_four_launch_files_in_one_format():
    assert {p.name for p in FILES} == {"pipeline.launch.xml", "record.launch.xml", "replay.launch.xml",
                                       "unicycle.launch.xml"}
    assert sorted(p.name for p in LAUNCH.iterdir()) == [p.name for p in FILES]


def _walk(element: ET.Element, parent: str | None = None):
    yield element, parent
    for child in element:
        yield from _walk(child, element.tag)


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.name)
def test_xml_is_what_jazzy_reads(path):
    root = ET.parse(path).getroot()      # well-formed
    assert root.tag == "launch"
    declared = [a.get("name") for a in root.iter("arg")]
    assert len(set(declared)) == len(declared), f"{path.name}: an argument declared twice"
    used = set()
    for element, parent in _walk(root):
        where = f"{path.name}: <{element.tag} {element.attrib}>"
        assert element.tag in JAZZY_ELEMENTS, f"{where}: Jazzy has no <{element.tag}>"
        if parent is not None:
            assert element.tag in JAZZY_CHILDREN.get(parent, set()), f"{where}: not read inside <{parent}>"
        assert set(element.attrib) <= JAZZY_ELEMENTS[element.tag], f"{where}: attributes Jazzy does not read"
        assert not (element.text or "").strip(), where
        assert not ("if" in element.attrib and "unless" in element.attrib), where
        if element.tag in ("node", "executable"):
            assert element.get("output") == "screen", where
            assert element.get("on_exit", "shutdown") == "shutdown", where     # the only on_exit Jazzy parses
        if element.tag == "node":
            assert element.get("pkg") == "euc_ros" and element.get("exec"), where
        if element.tag == "param":
            assert ("from" in element.attrib) != ("name" in element.attrib), where
            assert element.get("type", "yaml") in JAZZY_PARAM_TYPES, where
        if element.tag == "arg":
            assert element.get("description"), f"{where}: no description"
            choices = [c.get("value") for c in element]
            if choices and element.get("default") is not None:
                assert element.get("default") in choices, f"{where}: Jazzy refuses a default outside the choices"
        for value in element.attrib.values():
            names = re.findall(r"\$\(([A-Za-z][\w-]*)", value)
            assert set(names) <= JAZZY_SUBSTITUTIONS, f"{where}: {value}"
            used |= set(re.findall(r"\$\(var (\w+)\)", value))
    assert used == set(declared), f"{path.name}: declared but unused {set(declared) - used}, " \
                                  f"used but undeclared {used - set(declared)}"


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.name)
def test_conditions_come_out_as_ros2_condition_values(path):
    """Every if/unless, for every combination below, gives true/false/1/0 as ROS 2 requires (the parser
    refuses anything else; this restates it on the raw text for the combinations)."""
    launch = lf.read_launch_file(path)
    ctx = lf._Context(path, [a.name for a in launch.arguments])
    for given in COMBINATIONS[path.name]:
        values = lf.resolve_arguments(launch, given)
        for element in launch.processes:
            for attribute in ("if", "unless"):
                if attribute in element.attrs:
                    text = ctx.evaluate(element, attribute, ctx.parse(element, attribute), values)
                    assert text.strip().lower() in CONDITION_VALUES, (path.name, given, text)


def _combinations(fixed: dict[str, str], **axes: list[str]) -> list[dict[str, str]]:
    return [dict(fixed, **dict(zip(axes, values))) for values in itertools.product(*axes.values())]


#: Argument combinations that change what starts or how, per file (the required arguments given).
COMBINATIONS = {
    "pipeline.launch.xml": _combinations({"session": "s.yaml", "h": "0.58", "csv_path": "ride.csv"},
                                         compose=["false", "true"], bag=["", "out/bag"],
                                         source=["natnet", "csv", "topics"]),
    "record.launch.xml": _combinations({"bag": "out/bag"}, all_topics=["false", "true"]),
    "replay.launch.xml": _combinations({"in_bag": "in/bag", "session": "s.yaml", "h": "0.58"}, bag=["", "out/bag"]),
    "unicycle.launch.xml": _combinations({}, bag=["", "out/bag"], maneuver=["lane_change", "turn"]),
}


def _composed(spec: NodeSpec) -> list[str]:
    """The registered nodes a process runs: itself, or the container's ``--nodes``."""
    if spec.executable == "pipeline_container":
        args = list(spec.args)
        return args[args.index("--nodes") + 1].split(",")
    return [spec.executable] if spec.executable in NODES else []


def _check_process(spec: NodeSpec, tmp_path: Path, where: str) -> None:
    """Params files, parameter names, types, ranges and choices against the nodes' ParamSpec tables."""
    composed = _composed(spec)
    if not composed:
        assert spec.executable == "euc-ros" and not spec.ros_args, f"{where}: unknown program {spec.executable}"
        return
    files = [spec.params_file, *spec.params_files]
    assert all(Path(f).is_file() for f in files), where
    assert [Path(f).resolve() for f in files] == [(REPO / "config" / f"{n}.yaml").resolve() for n in composed], where
    classes = [node_class(n) for n in composed]
    declared = {s.name for cls in classes for s in cls.SPECS}
    assert set(spec.parameters) <= declared, f"{where}: undeclared {set(spec.parameters) - declared}"
    # written with the declared types already (ros2 launch does not convert): the launcher changes nothing
    assert typed_parameters(spec.executable, spec.parameters, spec.args) == spec.parameters, where
    for key, value in spec.parameters.items():
        default = next(s.default for cls in classes for s in cls.SPECS if s.name == key)
        assert type(value) is type(default), f"{where}: {key}={value!r}, declared {default!r}"
    for cls in classes:        # types, ranges and choices as the node checks them
        mine = {k: v for k, v in spec.parameters.items() if k in {s.name for s in cls.SPECS}}
        pf = tmp_path / f"{cls.NAME}.yaml"
        pf.write_text(yaml.safe_dump({cls.NAME: {"ros__parameters": mine}}), encoding="utf-8")
        validate_params_file(str(pf), cls.NAME, cls.SPECS)


@pytest.mark.parametrize("name, given", [(name, g) for name, combos in COMBINATIONS.items() for g in combos],
                         ids=lambda v: v if isinstance(v, str) else ",".join(f"{k}={x}" for k, x in v.items()))
def test_every_combination_starts_valid_node_processes(name, given, tmp_path):
    specs = lf.load_launch_file(LAUNCH / name, given)
    where = f"{name} {given}"
    labels = [s.label for s in specs]
    assert len(set(labels)) == len(labels), f"{where}: two processes named alike: {labels}"
    for spec in specs:
        _check_process(spec, tmp_path, f"{where} {spec.label}")
    executables = [s.executable for s in specs]
    if name != "record.launch.xml":
        assert ("recorder" in executables) == bool(given.get("bag")), f"{where}: the recorder follows bag"
    assert any(s.required for s in specs), f"{where}: nothing ends the launch"
    if name == "pipeline.launch.xml":
        if given["compose"] == "true":
            assert sorted(executables) == sorted(["monitor", "pipeline_container"] + (["recorder"] if given["bag"]
                                                                                      else []))
            (c,) = [s for s in specs if s.executable == "pipeline_container"]
            assert c.name is None and "-r" not in c.command()     # no __node remap: each node keeps its name
            assert c.required
        else:
            ingest = specs[executables.index("mocap_ingest")]
            assert ingest.required and ingest.parameters["source"] == given["source"]
            assert executables[-1] == "mocap_ingest"   # started last, stopped first
        assert executables[0] == ("recorder" if given["bag"] else "monitor")   # the recorder subscribes first
    if name == "unicycle.launch.xml":
        (sim,) = [s for s in specs if s.executable == "unicycle_sim"]
        assert sim.parameters["wait_observers"] == (1 if given["bag"] else 0) and sim.required
    if name == "replay.launch.xml":
        play = specs[-1]
        assert play.executable == "euc-ros" and play.required and play.args[:2] == ["play", "in/bag"]


def test_arguments_reach_the_nodes_with_the_declared_types():
    specs = {s.executable: s for s in lf.load_launch_file(LAUNCH / "pipeline.launch.xml", {
        "session": "001.yaml", "h": "0.58", "source": "csv", "csv_path": "ride.csv", "rate_factor": "2",
        "bodies": "['E', 'PV']", "effects": "['ground_slope']", "expected_rate_hz": "240", "multicast": "false",
        "bag": "0042"})}
    assert specs["torque_estimator"].parameters == {"session_file": "001.yaml", "h": 0.58, "model": "",
                                                    "model_force": False, "effects": ["ground_slope"],
                                                    "effect_parameters": [""]}
    ingest = specs["mocap_ingest"].parameters
    assert ingest["rate_factor"] == 2.0 and isinstance(ingest["rate_factor"], float)
    assert ingest["bodies"] == ["E", "PV"] and ingest["multicast"] is False and ingest["csv_path"] == "ride.csv"
    assert specs["monitor"].parameters == {"expected_rate_hz": 240.0}
    assert specs["recorder"].parameters == {"output": "0042"}             # type="str": the text as written
    assert "rate_factor:=2.0" in specs["mocap_ingest"].command()


def test_launcher_converts_overrides_to_the_declared_type():
    cmd = NodeSpec("mocap_ingest", parameters={"rate_factor": 2, "csv_path": 7, "bodies": [1, "E"], "loop": True,
                                               "not_a_parameter": 3}).command()
    assert {"rate_factor:=2.0", "csv_path:='7'", "bodies:=['1', 'E']", "loop:=true", "not_a_parameter:=3"} \
        <= set(cmd)
    # the container declares what its nodes declare
    cmd = NodeSpec("pipeline_container", args=["--nodes", "rider_state,torque_estimator"],
                   parameters={"h": 1, "rate_hz": 240}).command()
    assert "h:=1.0" in cmd and "rate_hz:=240.0" in cmd
    assert "wait_observers:=1" in NodeSpec("unicycle_sim", parameters={"wait_observers": 1.0}).command()
    # other programs are left alone
    assert "x:=2" in NodeSpec("some_tool", parameters={"x": 2}).command()
    # a path is typed by its file name (the colcon install's lib/euc_ros/<node>)
    assert "expected_rate_hz:=240.0" in NodeSpec("/ws/install/lib/euc_ros/monitor",
                                                 parameters={"expected_rate_hz": 240}).command()


def test_declared_types_come_from_the_config_files_the_tables_write():
    """The launcher reads the declared defaults from config/<node>.yaml (rclpy stays out of it): they must
    be the ParamSpec tables' names and types."""
    from euc_ros.nodes.container import DEFAULT_NODES
    from euc_ros.ros.launcher import CONTAINER_DEFAULT_NODES, declared_parameters

    assert CONTAINER_DEFAULT_NODES == DEFAULT_NODES
    for name in NODES:
        specs = node_class(name).SPECS
        declared = declared_parameters(name)
        assert set(declared) == {s.name for s in specs}, f"config/{name}.yaml: run python -m euc_ros.ros.registry"
        for spec in specs:
            value = declared[spec.name]
            assert type(value) is type(spec.default), (name, spec.name, value, spec.default)
            if isinstance(value, list):
                assert [type(v) for v in value] == [type(v) for v in spec.default], (name, spec.name)


def test_the_launcher_does_not_import_rclpy():
    import subprocess
    import sys

    code = ("import sys; from euc_ros.ros.launcher import NodeSpec; from euc_ros.ros.launch_file import "
            "load_launch_file; load_launch_file('launch/pipeline.launch.xml', {'session': 's', 'h': '1'}); "
            "assert 'rate_factor:=2.0' in NodeSpec('mocap_ingest', parameters={'rate_factor': 2}).command(); "
            "print(sorted(m for m in sys.modules if m.startswith(('rclpy', 'numpy', 'euc_ros.nodes'))))")
    r = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]", r.stdout


def test_launch_arguments_are_checked():
    path = LAUNCH / "pipeline.launch.xml"
    with pytest.raises(ConfigError, match="'session' is required"):
        lf.load_launch_file(path, {"h": "0.6"})
    # h may come from model:= instead: without either, torque_estimator refuses h = 0 (test_torque_estimator)
    (te,) = [s for s in lf.load_launch_file(path, {"session": "s.yaml", "model": "r.json"})
             if s.executable == "torque_estimator"]
    assert te.parameters["h"] == 0.0 and te.parameters["model"] == "r.json"
    with pytest.raises(ConfigError, match="must be one of natnet, topics, csv, got 'vrpn'"):
        lf.load_launch_file(path, {"session": "s", "h": "0.6", "source": "vrpn"})
    with pytest.raises(ConfigError, match="no launch argument 'sesion'"):
        lf.load_launch_file(path, {"sesion": "s"})
    with pytest.raises(ConfigError, match=r"<param name=\"h\">: value 'tall' is not a float"):
        lf.load_launch_file(path, {"session": "s", "h": "tall"})
    with pytest.raises(ConfigError, match="name:=value"):
        lf.parse_launch_arguments(["session=s.yaml"])
    assert lf.parse_launch_arguments(["a:=1", "b:=x:=y", "a:=2"]) == {"a": "2", "b": "x:=y"}


def test_no_world_up_argument_the_session_gives_it():
    names = {a.name for a in lf.launch_arguments(LAUNCH / "pipeline.launch.xml")}
    assert "world_up" not in names and {"multicast", "expected_rate_hz", "effects", "h"} <= names


# -- parser errors: file, line, element ------------------------------------------------------------

_NODE = '<node pkg="euc_ros" exec="monitor" name="monitor" output="screen"{attrs}>{body}</node>'


@pytest.mark.parametrize("body, line, element, message", [
    ('<group>\n</group>', 3, "<group>", "unsupported element"),
    (_NODE.format(attrs=' respawn="true"', body=""), 3, '<node name="monitor">', "unsupported attribute 'respawn'"),
    (_NODE.format(attrs=' if="$(arg bag)"', body=""), 3, '<node name="monitor">', r"\$\(arg NAME\) is ROS 1 syntax"),
    (_NODE.format(attrs=' if="$(env X)"', body=""), 3, '<node name="monitor">', r"unsupported substitution \$\(env"),
    (_NODE.format(attrs=' if="$(var nope)"', body=""), 3, '<node name="monitor">', "names no <arg>"),
    (_NODE.format(attrs=' if="$(var bag"', body=""), 3, '<node name="monitor">', "is not closed"),
    (_NODE.format(attrs=' on_exit="restart"', body=""), 3, '<node name="monitor">', "only action is on_exit"),
    ('<node pkg="euc_ros" exec="monitor" output="log"/>', 3, '<node exec="monitor">', 'write output="screen"'),
    (_NODE.format(attrs="", body='\n<param name="x" value="1"/>\n<param from="f.yaml"/>'), 5,
     '<param from="f.yaml">', r"put every <param from=\.\.\.> before"),
    (_NODE.format(attrs="", body='\n<param name="x" value="1" type="double"/>'), 4, '<param name="x">',
     "type='double'"),
    (_NODE.format(attrs="", body='\n<param name="x"/>'), 4, '<param name="x">', "missing attribute 'value'"),
    (_NODE.format(attrs="", body='\n<choice value="a"/>'), 4, '<choice value="a">', "not allowed inside <node>"),
    ('<node pkg="other_pkg" exec="talker"/>', 3, '<node exec="talker">', "pkg must be 'euc_ros'"),
    ('<arg name="mode" default="c" description="d">\n<choice value="a"/>\n</arg>', 3, '<arg name="mode">',
     "default 'c' is not one of the choices a"),
    ('<arg name="bag" default="" description="again"/>', 3, '<arg name="bag">', "declared twice"),
    ('<node pkg="euc_ros" exec="monitor">\n  hello\n</node>', 4, '<node exec="monitor">', "text 'hello'"),
    ('<node pkg="euc_ros" exec="monitor">', 4, None, "not well-formed XML: mismatched tag"),
])
def test_parser_errors_name_file_line_and_element(tmp_path, body, line, element, message):
    path = tmp_path / "bad.launch.xml"
    path.write_text(f'<launch>\n<arg name="bag" default="" description="b"/>\n{body}\n</launch>\n', encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        lf.load_launch_file(path, {})
    text = str(info.value)
    assert text.startswith(f"{path}, line {line}: "), text
    if element:
        assert f": {element}: " in text, text
    assert re.search(message, text), text


@pytest.mark.parametrize("condition, given, message", [
    ('if="$(var bag)"', "out", "gave 'out': a condition must be true, false, 1 or 0"),
    ("if=\"$(eval '1 + $(var bag)')\"", "1", r"only comparisons of quoted strings"),
    ("if=\"$(eval '\\'$(var bag)\\' == \\'\\'')\"", "it's", r"only comparisons of quoted strings"),
])
def test_condition_errors_name_the_element(tmp_path, condition, given, message):
    path = tmp_path / "c.launch.xml"
    path.write_text(f'<launch>\n<arg name="bag" default="" description="b"/>\n'
                    f'<node pkg="euc_ros" exec="monitor" {condition}/>\n</launch>\n', encoding="utf-8")
    with pytest.raises(ConfigError, match=message) as info:
        lf.load_launch_file(path, {"bag": given})
    assert str(info.value).startswith(f"{path}, line 3: <node exec=\"monitor\">: ")


def test_substitutions_follow_the_ros2_grammar(tmp_path):
    path = tmp_path / "s.launch.xml"
    path.write_text("""<launch>
  <arg name="bag" default="" description="b"/>
  <arg name="dir" default="$(find-pkg-share euc_ros)/x" description="a default with a substitution"/>
  <node pkg="euc_ros" exec="recorder" name="rec_$(var bag)"
        if="$(eval '\\'$(var bag)\\' != \\'\\' and not \\'$(var bag)\\' == \\'skip\\'')">
    <param name="output" value="$(var dir)/$(var bag)"/>
    <remap from="in" to="/lab/$(var bag)"/>
    <env name="WHERE" value="$(var bag)"/>
  </node>
  <executable cmd="euc-ros   play $(var bag)/x --rate 2 'two words'" name="play"/>
</launch>
""", encoding="utf-8")
    share = lf.package_share()
    assert lf.load_launch_file(path, {"bag": ""})[0].args == ["play", "/x", "--rate", "2", "two words"]
    assert [s.label for s in lf.load_launch_file(path, {"bag": "skip"})] == ["play"]
    rec, play = lf.load_launch_file(path, {"bag": "my bag"})
    assert rec.name == "rec_my bag" and rec.parameters == {"output": f"{share}/x/my bag"}
    assert rec.remaps == {"in": "/lab/my bag"} and rec.env == {"WHERE": "my bag"} and not rec.required
    assert play.args == ["play", "my bag/x", "--rate", "2", "two words"] and not play.ros_args


def test_package_share_of_the_source_checkout_is_the_repository():
    import euc_ros

    if Path(euc_ros.__file__).resolve().parents[1] != REPO:
        pytest.skip("euc_ros is not imported from this checkout")
    assert lf.package_share() == REPO
    assert lf.find_launch_file("pipeline.launch.xml") == REPO / "launch" / "pipeline.launch.xml"
    with pytest.raises(ConfigError, match=r"no launch file 'pipeline\.yaml' .*pipeline\.launch\.xml"):
        lf.find_launch_file("pipeline.yaml")


def test_cli_shows_the_arguments_like_ros2_launch(capsys):
    from euc_ros.cli.main import main

    assert main(["launch", "euc_ros", "pipeline.launch.xml", "--show-args"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("Arguments (pass arguments as '<name>:=<value>'):\n")
    assert "\n    'session':\n        session YAML" in out and "(required: no default)" in out
    assert "Valid choices are: ['natnet', 'topics', 'csv']\n        (default: 'natnet')" in out
    assert main(["launch", str(LAUNCH / "record.launch.xml"), "-s"]) == 0
    assert "'all_topics':" in capsys.readouterr().out


def test_cli_errors_are_one_line_and_exit_2(tmp_path, capsys):
    from euc_ros.cli.main import main

    old = tmp_path / "l.yaml"
    old.write_text("nodes:\n  - executable: recorder\n")
    assert main(["launch", str(old)]) == 2
    err = capsys.readouterr().err
    assert f"{old}, line 1: not well-formed XML" in err and "*.launch.xml" in err
    assert main(["launch", "nope.launch.xml"]) == 2
    assert "pipeline.launch.xml, record.launch.xml" in capsys.readouterr().err


def test_help_documents_the_subset():
    from euc_ros.cli.launch_cmd import EPILOG

    for tag in lf.SCHEMA:
        assert f"<{tag}" in EPILOG, tag
    for name in lf.SUBSTITUTIONS:
        assert f"$({name}" in EPILOG, name
    doc = (REPO / "docs" / "launch.md").read_text(encoding="utf-8")
    for tag, rule in lf.SCHEMA.items():
        assert f"<{tag}" in doc, tag
        for attribute in rule["attributes"]:
            assert f"`{attribute}`" in doc, (tag, attribute)


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.name)
def test_launch_xml_runs_for_real_where_launch_ros_imports(path, tmp_path):
    pytest.importorskip("launch_ros", reason="launch_ros is not on PyPI; the checks above stand in")
    pytest.importorskip("launch_xml")
    from launch.actions import IncludeLaunchDescription
    from launch.launch_description_sources import AnyLaunchDescriptionSource

    from launch import LaunchDescription, LaunchService

    description = AnyLaunchDescriptionSource(str(path)).get_launch_description(None)
    assert isinstance(description, LaunchDescription)
    if path.name != "unicycle.launch.xml":
        return   # the others need a Motive host, a session or a bag; loading them is the check
    service = LaunchService(argv=[])
    service.include_launch_description(IncludeLaunchDescription(
        AnyLaunchDescriptionSource(str(path)),
        launch_arguments={"duration": "1.0", "bag": str(tmp_path / "bag")}.items()))
    env_before = dict(os.environ)
    try:
        assert service.run() == 0
    finally:
        os.environ.clear()
        os.environ.update(env_before)
    assert (tmp_path / "bag" / "metadata.yaml").exists()
