"""The memory-lean paths of the h fit give the numbers of the plain ones bit for bit (the SSE grid to the
round-off of its sum): block-made coefficients, the SSE grid, the pooled h from coefficients with the states
dropped, and the time-shift hook made lazily and block by block."""
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
def test_block_coefficients_are_the_masked_copies(ride, model, monkeypatch):
    _, params, states = ride
    monkeypatch.setattr(I, "_COEF_BLOCK", 97)      # many blocks, valid samples split across them
    for st in states:
        extra = np.random.default_rng(1).normal(size=(st.n, 3))
        for ex in (None, extra):
            new = I.coefficients_for([st], params, model, ex)[0]
            args, exm = I._valid_args(st, ex)
            # the reference: the whole masked arrays at once (the block size made larger than them)
            monkeypatch.setattr(I, "_COEF_BLOCK", 10**9)
            old = I.residual_coefficients(args, params, model, exm)
            monkeypatch.setattr(I, "_COEF_BLOCK", 97)
            assert new.shape == old.shape == (6, int(st.valid.sum()))
            assert np.array_equal(new, old, equal_nan=True)


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
