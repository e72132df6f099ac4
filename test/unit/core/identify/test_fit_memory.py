"""The memory-lean paths of the h fit give the numbers of the plain ones (to round-off where the arithmetic
differs): the one-pass compiled coefficients, the SSE grid, the pooled h from coefficients with the states
dropped, and the time-shift hook made lazily and block by block."""
# covers: euc_ros/core/identify/fit_compiled.py
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.identify import fit as I
from euc_ros.core.model.terms import EucParams
from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
from euc_ros.core.states.geometry import to_moving_frame
from euc_ros.core.states.kinematics import reconstruct_states


@pytest.fixture(scope="module")
def ride():
    r = simulate_ride(RideConfig(maneuver="deceleration", runs=2, seed=3))
    params = EucParams.from_session(r.session)
    states = [reconstruct_states(run.mocap, r.session) for run in r.runs]
    return r, params, states


@pytest.mark.parametrize("model", ["3dof", "2dof"])
def test_compiled_coefficients_are_the_model_functions(ride, model):
    """The one-pass coefficients (the model's terms sorted by powers of h) against the model functions
    evaluated at h = 0, 1, -1 on the masked copies: equal to round-off. Each coefficient is a sum of some
    twenty products, each rounded once (relative eps) and cancelling at most down to the row's own size;
    1e-12 of the row's largest magnitude bounds that with two orders of magnitude to spare."""
    _, params, states = ride
    rng = np.random.default_rng(1)
    for st in states:
        for ex in (None, rng.normal(size=(st.n, 3))):
            new = I.coefficients_for([st], params, model, ex)[0]
            args, exm = I._valid_args(st, ex)
            old = I.residual_coefficients(args, params, model, exm)
            assert new.shape == old.shape == (6, int(st.valid.sum()))
            scale = np.max(np.abs(old), axis=1, keepdims=True)
            assert np.all(np.abs(new - old) <= 1e-12 * scale)


def test_compiled_coefficients_on_random_states_and_parameters():
    """Random angles over whole turns, rates, accelerations and parameters (l0, h0 of either sign): the
    compiled coefficients are the model functions' (same round-off bound as above)."""
    from dataclasses import dataclass

    rng = np.random.default_rng(7)

    @dataclass
    class St:
        n: int
        valid: np.ndarray
        gamma: np.ndarray
        phi: np.ndarray
        gamma_dot: np.ndarray
        phi_dot: np.ndarray
        x_ddot: np.ndarray
        gamma_ddot: np.ndarray
        phi_ddot: np.ndarray

        def torque_args(self, mask=None):
            arrs = (self.gamma, self.phi, self.gamma_dot, self.phi_dot, self.x_ddot, self.gamma_ddot, self.phi_ddot)
            return arrs if mask is None else tuple(a[mask] for a in arrs)

    for trial in range(5):
        n = 4000
        st = St(n, rng.random(n) < 0.8, *rng.uniform(-np.pi, np.pi, (2, n)), *rng.normal(0, 3, (2, n)),
                *rng.normal(0, 5, (3, n)))
        p = EucParams(m=rng.uniform(40, 120), J=rng.uniform(5, 30), m0=rng.uniform(5, 30), J0=rng.uniform(0.1, 2),
                      mw=rng.uniform(1, 6), Jw=rng.uniform(0.02, 0.4), R=rng.uniform(0.1, 0.3),
                      h0=rng.uniform(-0.1, 0.2), l0=rng.uniform(-0.1, 0.2), g=rng.uniform(9.7, 9.9))
        ex = rng.normal(0, 10, (n, 3)) if trial % 2 else None
        new = I.coefficients_for([st], p, "3dof", ex)[0]
        args, exm = I._valid_args(st, ex)
        old = I.residual_coefficients(args, p, "3dof", exm)
        scale = np.max(np.abs(old), axis=1, keepdims=True)
        assert np.all(np.abs(new - old) <= 1e-12 * scale), trial


def test_sse_grid_is_the_whole_products(ride):
    _, params, states = ride
    coef = I.coefficients_for(states[:1], params, "3dof", None)[0]
    h = np.asarray(I.DEFAULT_H_GRID)
    c, a0, a1, a2, d0, d1 = coef
    H = h[:, None]
    num = (((H * (c * a2)) + c * a1) * H + c * a0) / (H * d1 + d0)      # every product made whole
    ref = np.sum(num * num, axis=1)
    # the same terms summed in another order: within n eps of the sum of positive terms
    n = coef.shape[1]
    np.testing.assert_allclose(I.sse_grid(coef, h), ref, rtol=n * np.finfo(float).eps, atol=0)
    assert I.sse_grid(coef[:, :0], h).tolist() == [0.0] * h.size


def test_pooled_h_of_states_is_identify_h_and_drops_the_states(ride):
    _, params, states = ride
    want = I.fit_h(states, params, models=("3dof",)).pooled["3dof"].h_m
    work = list(states)
    assert I.pooled_h_of_states(work, params) == want
    assert work == []
    assert I.pooled_h_of_states((st for st in states), params) == want     # states made one at a time
    one = [states[0]]
    assert I.pooled_h_of_states(list(one), params) == I.fit_h(one, params, models=("3dof",)).pooled["3dof"].h_m


def test_time_shift_hook_is_the_eager_whole_recording_one(ride, monkeypatch):
    from euc_ros.core.filters.derivatives import savgol_coefficients
    from euc_ros.core.states import contexts as A

    _, params, states = ride
    st = states[0]
    valid = np.asarray(st.valid, bool)
    window, polyorder = st.window, st.polyorder
    monkeypatch.setattr(A, "_SHIFT_BLOCK", 101)
    shift = A._phi_shift_fn(st, params, window, polyorder, valid)

    # the reference: the whole recording at once
    g, ps, th = st.gamma, st.psi, st.theta
    zb = np.stack([np.sin(g), -np.sin(th) * np.cos(g), np.cos(th) * np.cos(g)], axis=1)
    zw = np.stack([np.cos(ps) * zb[:, 0] - np.sin(ps) * zb[:, 1], np.sin(ps) * zb[:, 0] + np.cos(ps) * zb[:, 1],
                   zb[:, 2]], axis=1)
    hinge = st.C - params.l0 * zw

    def phi_of(G):
        r = to_moving_frame(G - hinge, ps, th)
        return np.arctan2(r[:, 0], r[:, 2])

    half = (window - 1) // 2
    weights = savgol_coefficients(window, polyorder, st.dt, [half])[:, 0, :]
    idx = np.flatnonzero(valid)
    for dt in (0.0, 0.013, -0.04):
        Gs = np.stack([np.interp(st.t + dt, st.t, st.G[:, k], left=np.nan, right=np.nan) for k in range(3)], axis=1)
        d = phi_of(Gs) - phi_of(st.G)
        W = np.lib.stride_tricks.sliding_window_view(np.pad(d, half, constant_values=np.nan), window)[idx]
        ref = W @ weights.T
        got = shift(dt)
        for k in range(3):
            assert np.array_equal(got[k], ref[:, k], equal_nan=True)


def test_a_time_shift_hook_forgets_its_geometry_and_makes_it_again_the_same(ride):
    """forget_shift_caches lets the hooks drop their hinge path and trigonometry; a shift asked for after it
    gives the same numbers as before."""
    from euc_ros.core.states import contexts as A

    _, params, states = ride
    recs = A.prepare(states[:1], params, analysis_rate_hz=10.0)
    shift = recs[0].ctx.extras["phi_shift"]
    before = shift(0.021)
    kept = shift.forget.__self__                         # the hook's dict of kept geometry
    assert kept                                          # kept between shifts
    A.forget_shift_caches(recs)
    assert not kept
    after = shift(0.021)
    for a, b in zip(before, after):
        assert np.array_equal(a, b, equal_nan=True)
