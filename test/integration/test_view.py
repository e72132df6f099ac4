"""`euc-ros view` seen by Foxglove's own WebSocket client, over a real connection, with live nodes.

mocap_ingest replays a simulated ride that outlasts the measurement (a replay that loops restarts
rider_state's filters at each loop, which gaps its states), rider_state and torque_estimator run on
it, each its own process. ``euc-ros view`` runs as a subprocess on a free
port; tools/foxglove_live/view_client.mjs connects with @foxglove/ws-protocol (subprotocol
``foxglove.sdk.v1``, the one foxglove-sdk servers accept), subscribes to every advertised channel,
decodes each message with @foxglove/rosmsg2-serialization from the channel's ros2msg schema, and
reports per channel the count, the rate and one decoded message.

Checked: every expected channel is advertised as ros2msg/cdr with its ROS type (and every topic the
layout names); every message decodes, with no bytes the schema does not account for but CDR's end
padding; samples hold plausible values; each rate equals its publisher's, within a tolerance derived
from the span the client measured over and the timing jitter (:func:`rate_tolerance`); SIGINT ends
the viewer with exit code 0.

Needs node and npm (Node 20): skipped with the reason where they are absent or the npm registry
cannot be reached. The npm packages are pinned (package-lock.json) and installed with ``npm ci`` into
a cache outside the repository, keyed by the lock file's hash.
"""
from __future__ import annotations

import io
import json
import math
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import yaml

from euc_ros.ros.launcher import Launcher, NodeSpec

pytestmark = [pytest.mark.ros, pytest.mark.integration, pytest.mark.slow]
REPO = Path(__file__).resolve().parents[2]
CONFIG = REPO / "config"
TOOL = REPO / "tools" / "foxglove_live"

#: How long the client listens [s]; rates are measured over what it receives in that time.
LISTEN_S = 8.0
#: Largest delay of one message's delivery beyond its publisher's schedule on a loaded 2-core host
#: (scheduling, DDS, the viewer's executor, the WebSocket): bounds the error of each end of a span [s].
JITTER_S = 0.1
#: Length of the simulated ride: start-up, the bridging of every topic, the filters' start and the
#: listening all fit in it with room to spare [s].
RIDE_S = 20.0
#: Bodies of the simulated ride (the standard marker set of the session).
BODIES = ("H", "CHR", "CHL", "UAR", "UAL", "LAR", "LAL", "HR", "HL", "TR", "TL", "LR", "LL", "E")


def rate_tolerance(rate_hz: float, span_s: float, publishers: int = 1) -> float:
    """Largest relative error of a rate measured as ``(n - 1) / span`` from message arrival times.

    Each end of the span can be late by up to :data:`JITTER_S`, so the span is off by up to twice that;
    with several periodic publishers merged on one topic, the first and last messages can come from
    different publishers, which shifts the count by up to ``publishers - 1``.

    Parameters
    ----------
    rate_hz : float
        Expected rate of the topic (all publishers together) [Hz].
    span_s : float
        Time between the first and the last message received [s].
    publishers : int
        Periodic publishers on the topic.

    Returns
    -------
    float
        Relative tolerance.
    """
    return (2 * JITTER_S + (publishers - 1) / rate_hz) / span_s


@pytest.fixture(scope="module")
def client_dir(npm_tool):
    return npm_tool(TOOL, "@foxglove/ws-protocol", "view_client.mjs", "Foxglove's WebSocket client")


class Viewer:
    """``euc-ros view --port 0`` as a subprocess, its output lines collected by a thread."""

    def __init__(self) -> None:
        exe = Path(sys.executable).parent / "euc-ros"
        cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "euc_ros.cli.main"]
        self.proc = subprocess.Popen([*cmd, "view", "--port", "0"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                     stdin=subprocess.DEVNULL, text=True, bufsize=1,
                                     env={**os.environ, "PYTHONUNBUFFERED": "1"})
        self.lines: list[str] = []
        self._thread = threading.Thread(target=self._pump, daemon=True)
        self._thread.start()

    def _pump(self) -> None:
        for line in self.proc.stdout:
            self.lines.append(line.rstrip("\n"))

    def text(self) -> str:
        return "\n".join(self.lines)

    def url(self) -> str | None:
        for line in self.lines:
            m = re.search(r"(ws://\S+?),", line)
            if m:
                return m.group(1)
        return None

    def bridged(self) -> set[str]:
        return {m.group(1) for line in self.lines if (m := re.fullmatch(r"view: (/\S+) \(\S+\)", line))}

    def stop(self) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
        try:
            code = self.proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            code = self.proc.wait()
        self._thread.join(timeout=5)
        return code


def node_specs(ride_dir: Path) -> list[NodeSpec]:
    session = str(ride_dir / "session.yaml")
    return [
        NodeSpec("torque_estimator", params_file=str(CONFIG / "torque_estimator.yaml"),
                 parameters={"session_file": session}),
        NodeSpec("rider_state", params_file=str(CONFIG / "rider_state.yaml"), parameters={"session_file": session}),
        NodeSpec("mocap_ingest", params_file=str(CONFIG / "mocap_ingest.yaml"),
                 parameters={"session_file": session, "source": "csv", "start_delay": 1.0,
                             "csv_path": str(ride_dir / "deceleration_01.csv")}),
    ]


def expected_rates(ride_dir: Path) -> dict[str, tuple[float, int]]:
    """topic -> (rate of all its publishers together [Hz], number of periodic publishers)."""
    frame_hz = float(yaml.safe_load((ride_dir / "session.yaml").read_text())["rate_hz"])
    ingest = yaml.safe_load((CONFIG / "mocap_ingest.yaml").read_text())["mocap_ingest"]["ros__parameters"]
    view_rate = float(ingest["view_rate"])
    # mocap_ingest shows a frame when 3/4 of the view period has passed since the last one shown
    every = max(1, math.ceil(0.75 * frame_hz / view_rate - 1e-9)) if view_rate > 0 else 1
    view_hz = frame_hz / every
    diag_hz = [1.0 / yaml.safe_load((CONFIG / f"{n}.yaml").read_text())[n]["ros__parameters"]["diagnostics_period"]
               for n in ("mocap_ingest", "rider_state", "torque_estimator")]
    rates = {"/mocap/frame": (frame_hz, 1), "/rider/state": (frame_hz, 1), "/euc/torque": (frame_hz, 1),
             "/tf": (view_hz, 1), "/diagnostics": (sum(diag_hz), len(diag_hz))}
    rates.update({f"/mocap/{b}/pose": (view_hz, 1) for b in BODIES})
    return rates


TYPES = {"/mocap/frame": "euc_msgs/msg/MocapFrame", "/rider/state": "euc_msgs/msg/RiderState",
         "/euc/torque": "euc_msgs/msg/TorqueEstimate", "/tf": "tf2_msgs/msg/TFMessage",
         "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
         **{f"/mocap/{b}/pose": "geometry_msgs/msg/PoseStamped" for b in BODIES}}


def finite(*values) -> bool:
    return all(isinstance(v, (int, float)) and math.isfinite(v) for v in values)


@pytest.fixture(scope="module")
def ride_dir(tmp_path_factory) -> Path:
    """A simulated deceleration run of :data:`RIDE_S` (Motive CSV and session.yaml)."""
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
    from euc_ros.core.ridesim.writers import write_ride

    out = tmp_path_factory.mktemp("view_ride")
    write_ride(simulate_ride(RideConfig(maneuver="deceleration", runs=1, seed=5, duration_s=RIDE_S)), out)
    return out


@pytest.fixture(scope="module")
def session_report(client_dir, ros_domain, ride_dir):
    """Nodes, viewer and client run once; yields the client's JSON, the viewer's output and exit code."""
    log = io.StringIO()
    viewer = None
    with Launcher(node_specs(ride_dir), stream=log) as launcher:
        try:
            viewer = Viewer()
            want = set(TYPES)
            ok = launcher.wait(60, until=lambda: viewer.proc.poll() is not None or want <= viewer.bridged())
            assert ok and viewer.proc.poll() is None, \
                f"topics not bridged in 60 s: {sorted(want - viewer.bridged())}\n{viewer.text()}\n{log.getvalue()}"
            assert launcher.poll(), "a node ended early:\n" + log.getvalue()
            time.sleep(2.0)    # rider_state measures the frame rate and fills its filter window first
            r = subprocess.run(["node", str(client_dir / "view_client.mjs"), viewer.url(), str(LISTEN_S)],
                               cwd=client_dir, capture_output=True, text=True, timeout=LISTEN_S + 60)
            assert r.returncode == 0, r.stderr[-3000:]
            assert launcher.poll(), "a node ended while the client listened:\n" + log.getvalue()
        finally:
            code = viewer.stop() if viewer is not None else None
    yield json.loads(r.stdout), viewer.text(), code


def test_the_client_connects_with_foxglove_sdk_subprotocol(session_report):
    out, text, _ = session_report
    assert out["subprotocol"] == "foxglove.sdk.v1"
    assert out["serverInfo"]["name"] == "euc_ros"
    assert out["problems"] == [], out["problems"]
    first = text.splitlines()[0]
    assert first.startswith("view: Foxglove WebSocket server at ws://127.0.0.1:") and "this machine only" in first


def test_every_expected_channel_is_advertised_as_ros2msg_cdr(session_report, layout_topics):
    out, _, _ = session_report
    topics = out["topics"]
    assert set(TYPES) <= set(topics), sorted(set(TYPES) - set(topics))
    for topic, type_name in TYPES.items():
        ch = topics[topic]
        assert (ch["encoding"], ch["schemaEncoding"], ch["schemaName"]) == ("cdr", "ros2msg", type_name), ch
    assert layout_topics <= set(topics), sorted(layout_topics - set(topics))


def test_every_message_decodes(session_report):
    out, _, _ = session_report
    for topic in TYPES:
        ch = out["topics"][topic]
        assert ch["count"] > 0, topic
        assert ch["failures"] == 0, topic
        assert ch["trailing"] < 4, (topic, ch["trailing"])   # only CDR end padding


def test_decoded_samples_are_plausible(session_report):
    out, _, _ = session_report
    topics = out["topics"]
    for body in BODIES:
        pose = topics[f"/mocap/{body}/pose"]["sample"]
        p, q = pose["pose"]["position"], pose["pose"]["orientation"]
        assert pose["header"]["frame_id"] == "world"
        assert finite(p["x"], p["y"], p["z"]) and max(abs(p["x"]), abs(p["y"]), abs(p["z"])) < 50.0, (body, p)
        assert abs(math.hypot(q["x"], q["y"], q["z"], q["w"]) - 1.0) < 1e-6, (body, q)
        assert pose["header"]["stamp"]["sec"] > 0
    tf = topics["/tf"]["sample"]["transforms"]
    assert {t["child_frame_id"] for t in tf} == set(BODIES) and {t["header"]["frame_id"] for t in tf} == {"world"}
    frame = topics["/mocap/frame"]["sample"]
    assert list(frame["body_names"]) == list(BODIES) and len(frame["poses"]) == len(BODIES)
    torque = topics["/euc/torque"]["sample"]
    fields = ("valid", "m_d1", "m_d2", "m_d1_2dof", "m_d2_2dof", "h", "residual", "rmse_window", "h_online",
              "model", "h_online_status")
    assert all(f in torque for f in fields), sorted(torque)
    assert torque["valid"] is True and torque["h"] == pytest.approx(0.61) and torque["model"].startswith("3dof")
    assert finite(torque["m_d1"], torque["m_d2"], torque["residual"])
    assert torque["residual"] == pytest.approx(torque["m_d1"] - torque["m_d2"], abs=1e-9)
    state = topics["/rider/state"]["sample"]
    assert finite(state["x_dot"], state["gamma"], state["phi"], state["phi_dot"])
    names = {s["name"] for s in topics["/diagnostics"]["sample"]["status"]}
    assert names and all(isinstance(n, str) and n for n in names)


def test_rates_are_the_publishers(session_report, ride_dir):
    out, _, _ = session_report
    rates = expected_rates(ride_dir)
    for topic, (want, publishers) in rates.items():
        ch = out["topics"][topic]
        assert ch["span_s"] > LISTEN_S / 2, (topic, ch["span_s"])
        tol = rate_tolerance(want, ch["span_s"], publishers)
        assert ch["rate_hz"] == pytest.approx(want, rel=tol), (topic, ch["rate_hz"], want, tol)


def test_sigint_ends_the_viewer_cleanly(session_report):
    _, text, code = session_report
    assert code == 0, text
    assert re.search(r"view: stopped; forwarded \d+ messages on \d+ topics", text), text
