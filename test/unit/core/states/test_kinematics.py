"""State reconstruction: frame geometry on hand-built frames, missing bodies, projections, and states."""
# covers: euc_ros/core/states/geometry.py
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from euc_ros.core.errors import ConfigError, InputError
from euc_ros.core.filters.derivatives import DEFAULT_MAX_GAP
from euc_ros.core.model.terms import EucParams
from euc_ros.core.session import default_session
from euc_ros.core.states.geometry import frame_geometry, to_moving_frame
from euc_ros.core.states.kinematics import DEFAULT_SG_POLYORDER, reconstruct_states
from euc_ros.testing import savgol_roundoff

SESSION = default_session(world_up="z")


def _frames(rng, n):
    psi = rng.uniform(-np.pi, np.pi, n)
    theta = rng.uniform(-0.4, 0.4, n)
    gamma = rng.uniform(-0.2, 0.2, n)
    phi = rng.uniform(-0.3, 0.3, n)
    C = np.column_stack([rng.uniform(-3, 3, n), rng.uniform(-3, 3, n), np.full(n, 0.2)])
    h = rng.uniform(0.3, 1.0, n)[:, None]
    return psi, theta, gamma, phi, C, h


def test_frame_geometry_recovers_the_angles_and_points_it_was_built_from(rng, synth):
    n = 64
    psi, theta, gamma, phi, C, h = _frames(rng, n)
    series = [synth.synthesize_mocap(SESSION, t=np.arange(2) * 0.01, C=C[i:i + 1].repeat(2, 0),
                                     psi=psi[i:i + 1].repeat(2), theta=theta[i:i + 1].repeat(2),
                                     gamma=gamma[i:i + 1].repeat(2), phi=phi[i:i + 1].repeat(2), h=float(h[i, 0]))
              for i in range(n)]
    pos = np.concatenate([s.position[:, :1] for s in series], axis=1)
    quat = np.concatenate([s.quat[:, :1] for s in series], axis=1)
    geo = frame_geometry(pos, quat, None, SESSION, series[0].bodies)
    # built and recovered through a few rotations of <= 3 m vectors and one arcsin/atan2 each: a few
    # ulps (~1e-15); atol 1e-12 leaves >= 300x
    np.testing.assert_allclose(geo["psi"], psi, atol=1e-12)
    np.testing.assert_allclose(geo["theta"], theta, atol=1e-12)
    np.testing.assert_allclose(geo["gamma"], gamma, atol=1e-12)
    np.testing.assert_allclose(geo["C"], C, atol=1e-12)
    np.testing.assert_allclose(geo["phi_hinge"], phi, atol=1e-12)
    # Eq (3) by plane geometry: G - C = l0 (-sin g, -cos g) + h (sin phi, cos phi) in the moving frame.
    l0 = SESSION.euc.l0
    hh = h[:, 0]
    expected_eq3 = np.arctan2(hh * np.sin(phi) - l0 * np.sin(gamma), hh * np.cos(phi) - l0 * np.cos(gamma))
    np.testing.assert_allclose(geo["phi_eq3"], expected_eq3, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(geo["r_AG"], axis=-1), hh, atol=1e-12)
    assert np.allclose(geo["r_AG"][:, 1], 0, atol=1e-12)  # G lies in the longitudinal plane
    assert geo["has_rider"].all() and geo["has_euc"].all()


def test_moving_frame_is_the_transpose_of_yaw_then_tilt(rng):
    psi, theta = rng.uniform(-3, 3, 20), rng.uniform(-1, 1, 20)
    v = rng.normal(size=(20, 3))
    T = Rotation.from_euler("ZX", np.column_stack([psi, theta])).as_matrix()
    # two products of a unit rotation with O(1) vectors, in other orders: a few ulps
    np.testing.assert_allclose(to_moving_frame(v, psi, theta), np.einsum("nji,nj->ni", T, v), atol=1e-13)


def _straight_series(synth, rng=None, n=600, psi0=0.7, **noise):
    t = np.arange(n) / 120.0
    x = 2.0 * t + 0.25 * t**2
    C = np.column_stack([np.cos(psi0) * x, np.sin(psi0) * x, np.full(n, 0.2)])
    gamma = 0.02 * np.sin(2 * t)
    phi = 0.05 * np.sin(1.5 * t) + 0.02
    return synth.synthesize_mocap(SESSION, t=t, C=C, psi=np.full(n, psi0), theta=np.zeros(n), gamma=gamma, phi=phi,
                            h=0.6, rng=rng, **noise), dict(t=t, x_dot=2.0 + 0.5 * t, gamma=gamma, phi=phi)


def test_missing_segment_gives_no_cog_for_that_frame_only(synth):
    s, _ = _straight_series(synth, )
    j = s.bodies.index("CHL")
    gap = DEFAULT_MAX_GAP + 1                 # longer than the bridge: really missing
    s.tracked[j, 100:100 + gap] = False
    s.position[j, 100:100 + gap] = np.nan
    geo = frame_geometry(s.position, s.quat, s.tracked, SESSION, s.bodies)
    sl = slice(100, 100 + gap)
    assert not geo["has_rider"][sl].any() and geo["has_rider"][:100].all() and geo["has_rider"][100 + gap:].all()
    assert np.isnan(geo["G"][sl]).all() and np.isnan(geo["phi_hinge"][sl]).all()
    assert np.isfinite(geo["gamma"][sl]).all()  # the EUC is still there
    st = reconstruct_states(s, SESSION, window_s=0.2)
    assert not st.valid[sl].any()
    assert st.valid[200:400].all()


def test_a_short_segment_loss_is_bridged_and_costs_nothing(synth):
    """Bridged per body before the geometry (core.bridging): the states there are valid and equal
    the unbroken ones to the interpolation error of a 3-frame slerp of a smooth motion."""
    s, _ = _straight_series(synth, )
    ref = reconstruct_states(s, SESSION, window_s=0.2)
    j = s.bodies.index("CHL")
    s.tracked[j, 100:103] = False
    s.position[j, 100:103] = np.nan
    st = reconstruct_states(s, SESSION, window_s=0.2)
    np.testing.assert_array_equal(st.valid, ref.valid)
    assert st.meta["bridged_samples"] == 3
    assert np.nanmax(np.abs(st.phi - ref.phi)) < 1e-3     # rad; interpolation over 25 ms of a ~1 Hz motion


@pytest.mark.parametrize("phi_definition", ["hinge", "eq3"])
def test_lean_states_are_the_full_states_the_residual_reads(synth, phi_definition):
    """Lean states (for callers that reduce them to the residual's coefficients at once) hold what the residual
    reads, number for number, with gaps and bridged frames; the rest is empty, and the residual coefficients of
    both are the same."""
    from euc_ros.core.identify.fit import coefficients_for
    from euc_ros.core.states.kinematics import iter_states_filters

    s, _ = _straight_series(synth, rng=np.random.default_rng(3), n=900, pos_noise=2e-4)
    j = s.bodies.index("CHL")
    s.tracked[j, 100:103] = False                  # bridged
    s.position[j, 100:103] = np.nan
    s.tracked[0, 400:420] = False                  # a gap that splits the stretch
    s.position[0, 400:420] = np.nan
    kept = ("x_dot", "x_ddot", "gamma", "gamma_dot", "gamma_ddot", "phi", "phi_dot", "phi_ddot", "valid",
            "phi_hinge" if phi_definition == "hinge" else "phi_eq3")
    dropped = ("x", "psi", "theta", "C", "G", "has_euc", "has_rider",
               "phi_eq3" if phi_definition == "hinge" else "phi_hinge")
    full = reconstruct_states(s, SESSION, window_s=0.2, phi_definition=phi_definition)
    params = EucParams.from_session(SESSION)
    filters = [(0.2, DEFAULT_SG_POLYORDER), (0.35, 4)]
    both = [reconstruct_states(s, SESSION, window_s=0.2, phi_definition=phi_definition, lean=True),
            *iter_states_filters(s, SESSION, filters, phi_definition=phi_definition, shared=True, lean=True)]
    refs = [full, full, reconstruct_states(s, SESSION, window_s=0.35, polyorder=4, phi_definition=phi_definition)]
    for lean, ref in zip(both, refs):
        assert lean.valid.sum() > 500 and not lean.valid[400:420].any()
        for key in kept:
            np.testing.assert_array_equal(getattr(lean, key), getattr(ref, key), err_msg=key)
        for key in dropped:
            assert getattr(lean, key).size == 0, key
        assert lean.n == ref.n and lean.window == ref.window and lean.meta == ref.meta
        a, = coefficients_for([lean], params, "3dof", None)
        b, = coefficients_for([ref], params, "3dof", None)
        np.testing.assert_array_equal(a, b)


def test_zero_mass_segment_may_be_missing(synth):
    s, _ = _straight_series(synth, n=60)
    j = s.bodies.index("HR")  # hip markers only, mass fraction 0
    s.tracked[j] = False
    geo = frame_geometry(s.position, s.quat, s.tracked, SESSION, s.bodies)
    assert geo["has_rider"].all()


def test_missing_euc_gives_no_state_and_absent_bodies_are_input_errors(synth):
    s, _ = _straight_series(synth, )
    i = s.bodies.index("E")
    s.tracked[i, 300:320] = False
    st = reconstruct_states(s, SESSION, window_s=0.2)
    assert not st.valid[300:320].any()
    assert np.isnan(st.gamma[300:320]).all() and np.isnan(st.x_ddot[300:320]).all()
    assert st.valid[100:250].all() and st.valid[350:500].all()
    # A recording without E at all, or without a segment of non-zero mass: named input errors.
    with pytest.raises(InputError, match="'E'"):
        reconstruct_states(s.select([b for b in s.bodies if b != "E"]), SESSION)
    with pytest.raises(InputError, match="TL"):
        reconstruct_states(s.select([b for b in s.bodies if b != "TL"]), SESSION)
    with pytest.raises(ConfigError, match="phi"):
        reconstruct_states(s, SESSION, phi_definition="chest")
    # frame_geometry itself never raises for missing data: no E row -> no state.
    geo = frame_geometry(s.position[1:], s.quat[1:], s.tracked[1:], SESSION, s.bodies[1:])
    assert not geo["has_euc"].any() and np.isnan(geo["C"]).all() and np.isnan(geo["phi_hinge"]).all()


def test_reconstructed_states_follow_the_built_motion_on_any_heading(synth):
    s, truth = _straight_series(synth, psi0=2.5)
    st = reconstruct_states(s, SESSION, window_s=0.2)
    inner = slice(20, -20)
    # x(t) = 2 t + t^2 / 4 is a quadratic: the order-6 fit reproduces it exactly, so the errors of
    # x_dot and x_ddot are round-off alone. C is 16 m from the origin at the end, and the filter sees
    # C, not its variation: the bound scales with max|C| (savgol_roundoff: coefficients, the sum of
    # the window's products, and the ~4 ulps of C rebuilt as E + R_E p from E = C - R_E p). For the
    # 25-sample window at 120 Hz: 2.1e-9 m/s^2 on x_ddot (sum|h2| = 4.6e3 s^-2) and 2.9e-11 m/s on
    # x_dot. The projection on the heading adds eps |a_C|, nothing at this scale.
    scale = np.abs(s.position).max() + np.linalg.norm(SESSION.euc.pivot_to_wheel_center)
    tol = {d: savgol_roundoff(st.window, DEFAULT_SG_POLYORDER, d, 1 / 120, scale) for d in (1, 2)}
    np.testing.assert_allclose(st.x_dot[inner], truth["x_dot"][inner], rtol=0, atol=tol[1])
    np.testing.assert_allclose(st.x_ddot[inner], 0.5, rtol=0, atol=tol[2])
    # gamma and phi are sines: the smoothed values carry the fit's truncation error, of the order of
    # the 8th-derivative term (omega T / 2)^8 / 8! * amplitude ~ 1e-13 rad; 1e-6 rad (5e-5 of the
    # amplitudes) leaves room for the noise-free synthesis and is far below any real error.
    np.testing.assert_allclose(st.gamma[inner], truth["gamma"][inner], atol=1e-6)
    np.testing.assert_allclose(st.phi[inner], truth["phi"][inner], atol=1e-6)
    # psi is one atan2 of rotation-matrix entries built from a unit quaternion: a few ulps of pi;
    # 1e-12 rad is ~1000 times that.
    np.testing.assert_allclose(st.psi, 2.5, atol=1e-12)
    assert st.window == 25 and st.phi_definition == "hinge"
    eq3 = reconstruct_states(s, SESSION, window_s=0.2, phi_definition="eq3")
    assert np.max(np.abs(eq3.phi[inner] - st.phi[inner])) > 1e-3  # the two definitions differ


def test_longitudinal_acceleration_is_the_projection_of_a_C_on_a_circle(synth):
    """On a circle at constant speed a_C is centripetal: its longitudinal component is zero."""
    n, v, radius = 1200, 3.0, 4.0
    t = np.arange(n) / 120.0
    ang = v / radius * t
    C = np.column_stack([radius * np.sin(ang), radius * (1 - np.cos(ang)), np.full(n, 0.2)])
    s = synth.synthesize_mocap(SESSION, t=t, C=C, psi=ang, theta=np.full(n, -0.2), gamma=np.zeros(n),
                         phi=np.full(n, 0.03), h=0.6)
    st = reconstruct_states(s, SESSION, window_s=0.2)
    inner = slice(20, -20)
    # C moves on a circle: the order-6 fit over 0.2 s leaves a truncation error of the order of
    # (omega T / 2)^7 / 7! |v| ~ 1e-12 m/s at omega = 0.75 rad/s, and a round-off of
    # savgol_roundoff(25, 6, 1, 1/120, 8 m) = 1.4e-11 m/s: atol 1e-6 m/s (1e-4 m/s^2) only says "zero"
    np.testing.assert_allclose(st.x_dot[inner], v, atol=1e-6)
    np.testing.assert_allclose(st.x_ddot[inner], 0.0, atol=1e-4)
    np.testing.assert_allclose(st.theta, -0.2, atol=1e-12)   # one arcsin of a rotation entry: a few ulps
    # differences of psi up to 7.5 rad (ulp 9e-16): a few ulps; unwrapped, no jumps
    np.testing.assert_allclose(np.diff(st.psi), v / radius / 120, atol=1e-12)


def test_states_of_a_model_consistent_ride_match_the_exact_ones(symbolic, synth):
    p = EucParams.from_session(SESSION, 0.61)
    ride = synth.planar_ride(symbolic, p, duration=6.0, seed=4)
    n = ride["t"].size
    C = np.column_stack([ride["x"], np.zeros(n), np.full(n, SESSION.euc.wheel_radius)])
    s = synth.synthesize_mocap(SESSION, t=ride["t"], C=C, psi=np.zeros(n), theta=np.zeros(n), gamma=ride["gamma"],
                         phi=ride["phi"], h=0.61)
    st = reconstruct_states(s, SESSION, window_s=0.2)
    inner = slice(30, -30)
    # Tolerances: the 0.2 s cubic window attenuates second derivatives of ~1 Hz motions by a few %.
    for k, tol in (("x_dot", 1e-3), ("x_ddot", 4e-2), ("gamma_dot", 1e-2), ("phi_ddot", 4e-2)):
        assert np.max(np.abs(getattr(st, k)[inner] - ride[k][inner])) < tol * max(1, np.abs(ride[k]).max()), k


def test_one_frame_path_equals_the_vectorized_one(rng, synth):
    """A single frame goes through scalar arithmetic (the live nodes' path); it must give what the
    vectorized path gives for the same frame inside a batch, also with untracked bodies, NaN poses,
    an absent EUC, a missing zero-mass and a missing weighted segment. Both evaluate the same
    formulas in a different order: a few ulps on <= 4 m and O(1) rad quantities; atol 1e-12."""
    s, _ = _straight_series(synth, n=40)
    pos, quat, tracked = s.position.copy(), s.quat.copy(), s.tracked.copy()
    # turn, tilt and noise so that nothing is axis-aligned
    quat[:, :, :] += rng.normal(0, 0.05, quat.shape)
    pos += rng.normal(0, 0.01, pos.shape)
    e, tl, hr = s.bodies.index("E"), s.bodies.index("TL"), s.bodies.index("HR")
    tracked[e, 5] = False
    pos[e, 6] = np.nan
    tracked[tl, 7] = False
    quat[tl, 8] = np.nan
    tracked[hr, 9] = False                                  # zero mass fraction: G still defined
    cases = [(pos, quat, tracked, list(s.bodies)), (pos, quat, None, list(s.bodies)),
             (pos[1:], quat[1:], tracked[1:], list(s.bodies)[1:])]      # no E at all
    for P, Q, T, names in cases:
        batch = frame_geometry(P, Q, T, SESSION, names)
        for k in range(P.shape[1]):
            one = frame_geometry(P[:, k], Q[:, k], None if T is None else T[:, k], SESSION, names)
            assert set(one) == set(batch)
            for key, value in one.items():
                want = batch[key][k]
                assert np.shape(value) == np.shape(want), key
                np.testing.assert_allclose(value, want, atol=1e-12, rtol=0, err_msg=f"{key} at frame {k}")
    one = frame_geometry(pos[:, 5], quat[:, 5], tracked[:, 5], SESSION, s.bodies)
    assert not one["has_euc"] and np.isnan(one["C"]).all() and np.isnan(one["phi_hinge"])
    one = frame_geometry(pos[:, 7], quat[:, 7], tracked[:, 7], SESSION, s.bodies)
    assert one["has_euc"] and not one["has_rider"] and np.isnan(one["G"]).all()
    assert frame_geometry(pos[:, 9], quat[:, 9], tracked[:, 9], SESSION, s.bodies)["has_rider"]
