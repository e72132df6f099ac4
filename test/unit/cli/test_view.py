"""`euc-ros view` without a ROS graph: options, the address rule, the start line, bind errors, and the
topics and schemas it serves (the project's Foxglove layout names only topics it serves)."""
from __future__ import annotations

import socket
from pathlib import Path

import pytest

from euc_ros.cli.main import build_parser, main
from euc_ros.cli.view import start_line
from euc_ros.core.errors import ConfigError
from euc_ros.ros.foxglove_bridge import (
    DEFAULT_ADDRESS,
    DEFAULT_PORT,
    VIEW_TOPICS,
    SchemaBook,
    is_local_address,
    is_viewed,
    websocket_url,
)

REPO = Path(__file__).resolve().parents[3]


def test_defaults_are_this_machine_and_foxgloves_port():
    args = build_parser("view").parse_args(["view"])
    assert (args.address, args.port) == (DEFAULT_ADDRESS, DEFAULT_PORT) == ("127.0.0.1", 8765)
    assert is_local_address(args.address)


@pytest.mark.parametrize("port", ["70000", "-1", "http"])
def test_bad_port_is_refused_with_the_range(port, capsys):
    with pytest.raises(SystemExit) as exc:
        build_parser("view").parse_args(["view", "--port", port])
    assert exc.value.code == 2
    assert "0-65535" in capsys.readouterr().err


def test_help_states_the_address_rule(capsys):
    with pytest.raises(SystemExit):
        main(["view", "--help"])
    out = capsys.readouterr().out
    assert "--address" in out and "--port" in out and "127.0.0.1" in out
    assert "leave this" in out and "euc_pipeline.json" in out


@pytest.mark.parametrize("address, local", [
    ("127.0.0.1", True), ("127.0.1.1", True), ("::1", True), ("localhost", True),
    ("0.0.0.0", False), ("::", False), ("192.168.77.5", False), ("10.0.0.1", False),
])
def test_local_addresses_are_the_loopback_ones(address, local):
    assert is_local_address(address) is local


def test_unresolvable_address_says_what_to_give():
    with pytest.raises(ConfigError, match=r"--address.*cannot resolve 'a\.\.b'.*127\.0\.0\.1"):
        is_local_address("a..b")


def test_start_line_gives_the_url_and_whether_data_leave_the_machine():
    local = start_line("127.0.0.1", 8765, True)
    assert "ws://127.0.0.1:8765" in local and "this machine only" in local
    assert "only when --address names a non-local address" in local
    remote = start_line("0.0.0.0", 9000, False)
    assert "ws://0.0.0.0:9000" in remote and "live data can leave this machine" in remote
    assert "\n" not in local + remote
    assert websocket_url("::1", 8765) == "ws://[::1]:8765"


def test_port_in_use_is_exit_2_naming_the_fix(capsys):
    with socket.socket() as held:
        held.bind(("127.0.0.1", 0))
        held.listen()
        port = held.getsockname()[1]
        assert main(["view", "--port", str(port)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"port {port}" in err[0] and "--port" in err[0]


def test_address_of_another_machine_is_exit_2(capsys):
    assert main(["view", "--address", "192.0.2.1", "--port", "0"]) == 2   # TEST-NET-1: never ours
    err = capsys.readouterr().err
    assert "192.0.2.1" in err and "not an address of this machine" in err


def test_viewed_topics():
    assert {"/mocap/frame", "/rider/state", "/euc/torque", "/diagnostics", "/tf"} <= set(VIEW_TOPICS)
    assert is_viewed("/mocap/H/pose") and is_viewed("/mocap/RigidBody_01/pose")
    assert not is_viewed("/mocap/a/b/pose") and not is_viewed("/rosout") and not is_viewed("mocap/H/pose")


def test_the_layout_names_only_topics_the_viewer_serves(layout_topics):
    named = layout_topics
    assert named and all(is_viewed(t) for t in named), sorted(t for t in named if not is_viewed(t))


@pytest.mark.parametrize("type_name, first, dependency", [
    ("geometry_msgs/msg/PoseStamped", "std_msgs/Header header", "MSG: geometry_msgs/Quaternion"),
    ("euc_msgs/msg/TorqueEstimate", "std_msgs/Header header", "MSG: builtin_interfaces/Time"),
    ("euc_msgs/msg/MocapFrame", None, "MSG: geometry_msgs/Pose"),
    ("tf2_msgs/msg/TFMessage", "geometry_msgs/TransformStamped[] transforms", "MSG: geometry_msgs/Transform"),
    ("diagnostic_msgs/msg/DiagnosticArray", None, "MSG: diagnostic_msgs/KeyValue"),
])
def test_schemas_are_ros2msg_with_dependencies(type_name, first, dependency):
    text = SchemaBook().text(type_name)
    if first is not None:
        assert text.splitlines()[0] == first
    assert dependency in text.splitlines()
    assert "=" * 80 in text


def test_unknown_type_has_no_schema():
    with pytest.raises(KeyError):
        SchemaBook().text("nope_msgs/msg/Nothing")
