"""Helpers of the node tests, in one place: MocapFrame messages of a series, a :class:`Pipe` that drains
frames through the nodes under test, the rider_state and torque_estimator nodes with the tests' settings,
and the ROS-free core on the same input to compare with.

The tests run with ``--import-mode=importlib``: a test file loads this file with
:func:`euc_ros.testing.load_module` (``H = load_module(Path(__file__).with_name("helpers.py"), ...)``);
conftest.py provides its fixtures ``ride`` and ``pipes`` and keeps it out of the doctest collection
(it imports rclpy).
"""
from __future__ import annotations

import dataclasses
import time
from types import SimpleNamespace

import numpy as np
import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from euc_msgs.msg import MocapFrame, RiderState, TorqueEstimate
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter

from euc_ros.core.mocap.frame import Frame
from euc_ros.core.model.terms import EucParams
from euc_ros.core.online.estimators import RiderStateEstimator, TorqueEstimator
from euc_ros.core.session import save_session
from euc_ros.core.states.settings import ReconstructionSettings
from euc_ros.nodes.rider_state import RiderStateNode
from euc_ros.nodes.torque_estimator import TorqueEstimatorNode
from euc_ros.ros import convert
from euc_ros.ros import interfaces as itf
from euc_ros.testing import spin_executor_until

T0_NS = 1_700_000_000_123_456_789   # a realistic epoch stamp: the ns round trip must be exact


def stamp_ns(stamp) -> int:
    return stamp.sec * 10**9 + stamp.nanosec


def frame_msgs(series, t0_ns=T0_NS, frames=None):
    """MocapFrame messages of a Z-up MocapSeries (stamps t0 + t)."""
    out = []
    for k in range(series.n_frames) if frames is None else frames:
        f = Frame(t0_ns + int(round(float(series.t[k]) * 1e9)), int(series.frame[k]), list(series.bodies),
                  series.position[:, k], series.quat[:, k], series.tracked[:, k], series.mean_marker_error[:, k])
        out.append(convert.frame_to_msg(f, "world", MocapFrame.STAMP_FILE_TIME))
    return out


class Pipe:
    """A feeder of MocapFrame, the nodes under test, a probe of every output; one executor.

    ``feed`` publishes frames one at a time and spins until each has gone through every node and every
    output has reached the probe (``drained``).
    """

    def __init__(self, ctx, nodes=()):
        self.ctx = ctx
        self.feeder = rclpy.create_node("feeder", context=ctx)
        self.frame_pub = self.feeder.create_publisher(MocapFrame, itf.MOCAP_FRAME, itf.RELIABLE_QOS)
        self.state_pub = self.feeder.create_publisher(RiderState, itf.RIDER_STATE, itf.RELIABLE_QOS)
        self.probe = rclpy.create_node("probe", context=ctx)
        self.states: list[RiderState] = []
        self.torques: list[TorqueEstimate] = []
        self.diag: list[DiagnosticArray] = []
        self.probe.create_subscription(RiderState, itf.RIDER_STATE, self.states.append, itf.RELIABLE_QOS)
        self.probe.create_subscription(TorqueEstimate, itf.TORQUE, self.torques.append, itf.RELIABLE_QOS)
        self.probe.create_subscription(DiagnosticArray, itf.DIAGNOSTICS, self.diag.append, itf.DIAGNOSTICS_QOS)
        self.ex = SingleThreadedExecutor(context=ctx)
        self.ex.add_node(self.feeder)
        self.ex.add_node(self.probe)
        self.nodes = []
        self.fed_states = 0
        self.removed_states = 0
        self.removed_torques = 0
        for n in nodes:
            self.add(n)

    def add(self, node):
        self.nodes.append(node)
        self.ex.add_node(node)
        node._pipe_base = self.total_states()   # a torque node joining late sees only later states
        return node

    def remove(self, node):
        self.ex.remove_node(node)
        self.nodes.remove(node)
        if isinstance(node, RiderStateNode):
            self.removed_states += node.counts["states"]
        if hasattr(node, "torque_pub"):
            self.removed_torques += node.published
        node.destroy_node()

    def total_states(self):
        return sum(r.counts["states"] for r in self._riders()) + self.removed_states + self.fed_states

    def spin_until(self, predicate, timeout_s=10.0, what="condition"):
        spin_executor_until(self.ex, predicate, timeout_s, what)

    def settle(self, seconds):
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.ex.spin_once(timeout_sec=0.01)

    def _riders(self):
        return [n for n in self.nodes if isinstance(n, RiderStateNode)]

    def _torque_nodes(self):
        return [n for n in self.nodes if hasattr(n, "estimator") and hasattr(n, "torque_pub")]

    def matched(self):
        monitors = sum(1 for n in self.nodes if n.NAME == "monitor")
        torques = len(self._torque_nodes())
        ok = self.frame_pub.get_subscription_count() >= len(self._riders()) + monitors
        ok &= self.state_pub.get_subscription_count() >= 1 + torques + monitors
        for r in self._riders():
            ok &= r.state_pub.get_subscription_count() >= 1 + torques + monitors
        for t in self._torque_nodes():
            ok &= t.torque_pub.get_subscription_count() >= 1 + monitors
        return ok

    def drained(self):
        states = self.total_states()
        if len(self.states) < states:
            return False
        torque_nodes = self._torque_nodes()
        if len(self.torques) < sum(t.published for t in torque_nodes) + self.removed_torques:
            return False
        return all(t.estimator.counts["states"] + t.drops.errors + t.drops.unexpected + t.rate_gate.held
                   >= states - t._pipe_base for t in torque_nodes)

    def wait_matched(self):
        self.spin_until(self.matched, what="publishers and subscriptions to match")

    def feed(self, msgs):
        self.wait_matched()
        for m in msgs:
            riders = self._riders()
            before = [r.counts["frames"] for r in riders]
            self.frame_pub.publish(m)
            self.spin_until(lambda: all(r.counts["frames"] > b for r, b in zip(riders, before)) and self.drained(),
                            what="a frame to pass through the pipeline")

    def feed_states(self, msgs):
        self.wait_matched()
        for m in msgs:
            self.state_pub.publish(m)
            self.fed_states += 1
            self.spin_until(self.drained, what="a state to pass through the pipeline")

    def close(self):
        self.ex.shutdown()
        for n in list(self.nodes):
            n.destroy_node()
        self.feeder.destroy_node()
        self.probe.destroy_node()


@pytest.fixture(scope="module")
def ride(tmp_path_factory):
    """A 4 s deceleration run of the ride simulator (Z-up mocap) with a lost EUC, a lost rider segment
    (short and long) and dropped frames; the session written to a file."""
    from euc_ros.core.mocap.series import MocapSeries
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride

    result = simulate_ride(RideConfig(maneuver="deceleration", runs=1, seed=8, duration_s=4.0))
    s = result.runs[0].mocap
    tracked = s.tracked.copy()
    e, chl = s.bodies.index("E"), s.bodies.index("CHL")
    tracked[e, 150:160] = False            # EUC lost: no state for these frames
    tracked[chl, 250:252] = False          # a rider segment lost for 2 frames: bridged, flagged
    tracked[chl, 300:340] = False          # ... and for 40 frames: EUC state without phi
    pos, quat = s.position.copy(), s.quat.copy()
    pos[~tracked] = np.nan
    quat[~tracked] = np.nan
    keep = np.ones(s.n_frames, bool)
    keep[[100, 101, 400]] = False          # dropped frames
    series = MocapSeries(s.t[keep], s.frame[keep], list(s.bodies), pos[:, keep], quat[:, keep], tracked[:, keep],
                         s.mean_marker_error[:, keep], s.name, dict(s.meta))
    d = tmp_path_factory.mktemp("rider_state")
    save_session(result.session, d / "session.yaml")
    return series, result.session, d / "session.yaml"


@pytest.fixture
def pipes(ros_context):
    made = []

    def make(nodes=()):
        p = Pipe(ros_context, nodes)
        made.append(p)
        return p

    yield make
    for p in made:
        p.close()


#: These tests cut a 4 s ride into short stretches; a 0.9 s quartic filter leaves states in each of
#: them (the project default, 1.2 s / order 6, is exercised by the live-pipeline and core tests).
TEST_FILTER = {"window_s": 0.9, "polyorder": 4}


def rider_node(ctx, session_file, **params):
    params = {**TEST_FILTER, **params}
    overrides = [Parameter("session_file", value=str(session_file))]
    overrides += [Parameter(k, value=v) for k, v in params.items()]
    return RiderStateNode(context=ctx, parameter_overrides=overrides)


def live_estimator(session, **kw):
    """The core's live estimator at the session's rate: the settings' keywords (TEST_FILTER by default) go into
    its ReconstructionSettings, the rest to the estimator."""
    kw = {**TEST_FILTER, **kw}
    names = {f.name for f in dataclasses.fields(ReconstructionSettings)}
    settings = ReconstructionSettings(**{k: v for k, v in kw.items() if k in names})
    return RiderStateEstimator(session, 1 / session.rate_hz, settings=settings,
                               **{k: v for k, v in kw.items() if k not in names})


def core_states(series, session, frames=None, **kw):
    """The core estimator on the same frames, keyed by the capture stamp of each state's frame [ns]."""
    est = live_estimator(session, **kw)
    out = {}
    for _, s in est.update_series(series, frames):
        out[T0_NS + int(round(s.t * 1e9))] = s
    return out


def torque_node(ctx, session_file, **params):
    overrides = [Parameter("session_file", value=str(session_file))]
    overrides += [Parameter(k, value=v) for k, v in params.items()]
    return TorqueEstimatorNode(context=ctx, parameter_overrides=overrides)


def core_torques(state_msgs, session, h=0.61, **kw):
    """The core TorqueEstimator on RiderState messages (times relative to the first one), by stamp."""
    te = TorqueEstimator(EucParams.from_session(session, h), 1 / session.rate_hz, **kw)
    t0 = stamp_ns(state_msgs[0].header.stamp)
    out = {}
    for m in state_msgs:
        st = SimpleNamespace(t=(stamp_ns(m.header.stamp) - t0) * 1e-9, frame=-1, valid=True,
                             **{k: getattr(m, k) for k in ("x_dot", "x_ddot", "gamma", "gamma_dot", "gamma_ddot",
                                                           "phi", "phi_dot", "phi_ddot", "psi", "theta")})
        o = te.update(st)
        if o is not None:
            out[stamp_ns(m.header.stamp)] = o
    return out, te
