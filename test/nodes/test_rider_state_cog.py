"""rider_state with ``cog_method: skeleton``: the same states as the core estimator, no lag
added, flipped bodies counted in the diagnostics."""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rclpy")

from scipy.spatial.transform import Rotation  # noqa: E402

from euc_ros.testing import load_module  # noqa: E402

pytestmark = pytest.mark.ros


H = load_module(Path(__file__).with_name("helpers.py"), "node_helpers")
CALIBRATION_S = 1.0
FLIP = ("TR", slice(200, 203))


def _flipped(series):
    i = series.bodies.index(FLIP[0])
    quat = series.quat.copy()
    quat[i, FLIP[1]] = (Rotation.from_quat(quat[i, FLIP[1]]) * Rotation.from_rotvec([math.pi, 0.0, 0.0])).as_quat()
    return dataclasses.replace(series, quat=quat)


def test_skeleton_states_equal_the_core_and_flips_are_counted(pipes, ros_context, ride):
    series, session, path = ride
    series = _flipped(series)
    node = H.rider_node(ros_context, path, cog_method="skeleton", skeleton_calibration_s=CALIBRATION_S,
                        diagnostics_period=0.1)
    pipe = pipes([node])
    pipe.feed(H.frame_msgs(series))
    est = H.live_estimator(session, cog_method="skeleton",
                           skeleton_calibration_frames=int(round(CALIBRATION_S * session.rate_hz)))
    want = {}
    for _, s in est.update_series(series):
        want[H.T0_NS + int(round(s.t * 1e9))] = s
    got = {H.stamp_ns(m.header.stamp): m for m in pipe.states}
    assert set(got) == set(want) and len(got) > 100
    for stamp, m in got.items():
        s = want[stamp]
        for k in ("phi", "phi_dot", "phi_ddot", "phi_hinge"):
            np.testing.assert_allclose(getattr(m, k), getattr(s, k), rtol=1e-12, atol=1e-12, equal_nan=True,
                                       err_msg=k)
        np.testing.assert_allclose([m.g.x, m.g.y, m.g.z], s.G, rtol=1e-12, atol=1e-12)
        assert m.filter_lag == pytest.approx(est.lag_s)        # the chain fit adds no lag
    assert est.cog_faults == 3 and est.cog_fault_bodies == {"TR": 3}
    pipe.settle(0.3)
    kv = {k.key: k.value for a in pipe.diag for st in a.status if st.name == "rider_state: states" for k in st.values}
    assert kv["cog_method"] == "skeleton"
    assert float(kv["cog_lag_s"]) == 0.0
    assert int(kv["cog_excluded_body_frames"]) == 3
    assert kv["cog_excluded_bodies"] == "TR 3"
