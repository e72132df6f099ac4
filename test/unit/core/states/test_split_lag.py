"""Split low-lag estimator: the pieces add up to the geometry, the composition is exact on
cubic pieces (against finite differences of the composed functions), one smoothing time reduces to
the plain filter of C, and streaming equals offline within a derived round-off bound."""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.filters.causal import fir_derivatives
from euc_ros.core.mocap.bridging import bridge_series
from euc_ros.core.ridesim.mocap_synth import MocapNoise
from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
from euc_ros.core.states.geometry import frame_geometry
from euc_ros.core.states.settings import ReconstructionSettings
from euc_ros.core.states.split_lag import (
    GROUPS,
    SPLIT_SMOOTHING,
    StreamingSplit,
    compose,
    group_columns,
    split_derivatives,
    split_pieces,
    split_weights,
    unwrap_turns,
)

DT = 1.0 / 120.0
EPS = np.finfo(float).eps
FIELDS = ("gamma", "gamma_dot", "gamma_ddot", "phi", "phi_dot", "phi_ddot", "x_dot", "x_ddot")


@pytest.fixture(scope="module")
def ride():
    r = simulate_ride(RideConfig(maneuver="figure_eight", runs=1, seed=5, duration_s=16.0,
                                 noise=MocapNoise(gaps=0)))
    series, _ = bridge_series(r.runs[0].mocap, 5)
    return r.session, series


@pytest.mark.parametrize("center", [(0.0, 0.0, 0.0), (0.1, -0.05, -0.25)])
def test_pieces_add_up_to_the_geometry(ride, center):
    session, s = ride
    pc = split_pieces(s.position, s.quat, s.tracked, session, s.bodies, euc_center=center)
    geo = frame_geometry(s.position, s.quat, s.tracked, session, s.bodies)
    c, si = np.cos(pc["psi"]), np.sin(pc["psi"])
    C_x = pc["E_x"] + c * pc["u_f"] - si * pc["u_l"]
    C_y = pc["E_y"] + si * pc["u_f"] + c * pc["u_l"]
    scale = np.nanmax(np.abs(geo["C"][:, :2]))
    assert np.nanmax(np.abs(C_x - geo["C"][:, 0])) < 16 * EPS * scale
    assert np.nanmax(np.abs(C_y - geo["C"][:, 1])) < 16 * EPS * scale
    for j, ax in ((0, "x"), (2, "z")):
        r = pc[f"rpos_{ax}"] + pc[f"rseg_{ax}"] + pc[f"reuc_{ax}"]
        # G and A are sums of positions of size max|E|: round-off of that size, not of |r|
        assert np.nanmax(np.abs(r - geo["r_AG"][:, j])) < 64 * EPS * np.nanmax(np.abs(s.position))
    assert np.array_equal(pc["gamma"], geo["gamma"], equal_nan=True)


def test_unwrap_turns_is_exact_and_streams():
    psi = np.linspace(0, 9 * np.pi, 400)
    wrapped = np.angle(np.exp(1j * psi))
    wrapped[[50, 51, 200]] = np.nan
    off, _, _ = unwrap_turns(wrapped)
    ok = np.isfinite(wrapped)
    assert np.allclose(off[ok], psi[ok], atol=1e-12) and np.all(np.isnan(off[~ok]))
    turns, last, on = 0, None, []
    for v in wrapped:
        u, turns, last = unwrap_turns(v, turns, last)
        on.append(u[0])
    assert np.array_equal(np.array(on), off, equal_nan=True)


def _cubic_pieces(t):
    rng = np.random.default_rng(4)
    cols = {}
    for g, names in GROUPS.items():
        for nm in names:
            c = rng.normal(0.0, 1.0, 4) * np.array([1.0, 0.5, 0.3, 0.1])
            cols[nm] = c
    cols["rpos_z"][0] += 3.0          # keep r away from the origin (atan2 well conditioned)
    return cols


def _poly(c, t, d=0):
    p = np.polynomial.Polynomial(c)
    return p.deriv(d)(t) if d else p(t)


def test_composition_is_exact_on_cubic_pieces():
    """Every piece a cubic: the smoothers reproduce them and their derivatives exactly, so the states
    equal the composition of the analytic pieces; that composition is checked against finite
    differences of phi(t) = atan2(r_x, r_z) and of e_x . C(t) (an independent route)."""
    n = 1600
    t = np.arange(n) * DT - 6.0
    cs = _cubic_pieces(t)
    pieces = {nm: _poly(c, t) for nm, c in cs.items()}
    pieces["psi"] = np.angle(np.exp(1j * pieces["psi"]))       # wrapped, as measured
    st = split_derivatives(DT, pieces)
    k = np.flatnonzero(np.isfinite(st.x_ddot))
    assert k.size > 500
    exact_d = {g: tuple(np.stack([_poly(cs[nm], t, d) for nm in names], -1) for d in range(3))
               for g, names in GROUPS.items()}
    exact = compose(exact_d)
    # polynomial reproduction in floating point: a dot product of W terms is within W eps sum|w| max|y|
    # of the exact one (per group and derivative), carried through the composition to first order
    w = split_weights(DT, 12)
    cols = group_columns(pieces)
    bounds = {g: [w[g].shape[1] * EPS * np.abs(w[g][j]).sum() * np.nanmax(np.abs(cols[g])) for j in range(3)]
              for g in GROUPS}
    tol = _jacobian_bound({g: tuple(a[k] for a in v) for g, v in exact_d.items()}, bounds)
    for f in FIELDS:
        a, b = getattr(st, f)[k], getattr(exact, f)[k]
        assert np.all(np.abs(a - b) <= tol[f]), f
    # independent route: finite differences of the composed functions
    ts = t[k[::97]]
    h = 1e-3
    for tt in ts:
        def phi_at(x):
            rx = sum(_poly(cs[nm], x) for nm in ("rpos_x", "rseg_x", "reuc_x"))
            rz = sum(_poly(cs[nm], x) for nm in ("rpos_z", "rseg_z", "reuc_z"))
            return np.arctan2(rx, rz)

        def xc_at(x, psi0):
            psi = _poly(cs["psi"], x)
            uf, ul = _poly(cs["u_f"], x), _poly(cs["u_l"], x)
            Cx = _poly(cs["E_x"], x) + np.cos(psi) * uf - np.sin(psi) * ul
            Cy = _poly(cs["E_y"], x) + np.sin(psi) * uf + np.cos(psi) * ul
            return np.cos(psi0) * Cx + np.sin(psi0) * Cy

        i = np.flatnonzero(t == tt)[0]
        psi0 = _poly(cs["psi"], tt)
        cases = ((phi_at, (st.phi_dot[i], st.phi_ddot[i])), (lambda x: xc_at(x, psi0), (st.x_dot[i], st.x_ddot[i])))
        for g, ref in cases:
            d1 = [(g(tt + hh) - g(tt - hh)) / (2 * hh) for hh in (h, h / 2)]
            d2 = [(g(tt + hh) - 2 * g(tt) + g(tt - hh)) / hh**2 for hh in (h, h / 2)]
            # truncation error O(h^2): the difference between h and h/2 bounds it (x 4/3), plus round-off
            for est, got in ((d1, ref[0]), (d2, ref[1])):
                err = 4.0 / 3.0 * abs(est[0] - est[1]) + 1e-7
                assert abs(got - est[1]) < 2 * err + 1e-6, (tt, got, est)


def test_one_smoothing_time_and_straight_heading_is_the_plain_filter():
    """All groups alike and psi = 0: x_ddot is the one filter applied to C_x = E_x + u_f (linearity)."""
    rng = np.random.default_rng(2)
    n = 900
    pieces = {nm: np.cumsum(rng.normal(0, 1e-3, n)) for names in GROUPS.values() for nm in names}
    pieces["rpos_z"] = pieces["rpos_z"] + 0.9
    pieces["psi"] = np.zeros(n)
    tau = {g: 0.065 for g in GROUPS}
    st = split_derivatives(DT, pieces, smoothing=tau)
    w = split_weights(DT, 12, tau)["pos"]
    Cx = pieces["E_x"] + pieces["u_f"]
    ref = fir_derivatives(DT, Cx, w, 12)
    k = np.flatnonzero(np.isfinite(st.x_ddot))
    bound = 3 * w.shape[1] * EPS * np.abs(w[2]).sum() * np.abs(Cx).max()
    assert np.max(np.abs(st.x_ddot[k] - ref.y_ddot[k])) <= bound


def _jacobian_bound(d, bounds):
    """First-order bound of the composed states' change when each smoothed input moves by its bound:
    sum_j |d out / d in_j| b_j, the derivatives by central differences (x 2 for their own error)."""
    base = compose(d)
    out = {f: np.zeros_like(getattr(base, f)) for f in FIELDS}
    for g in d:
        for j in range(3):
            for c in range(d[g][j].shape[-1]):
                step = 1e-6 * max(1.0, float(np.nanmax(np.abs(d[g][j][..., c]))))
                plus = {kk: tuple(a.copy() for a in v) for kk, v in d.items()}
                minus = {kk: tuple(a.copy() for a in v) for kk, v in d.items()}
                plus[g][j][..., c] += step
                minus[g][j][..., c] -= step
                cp, cm = compose(plus), compose(minus)
                for f in FIELDS:
                    out[f] += np.abs((getattr(cp, f) - getattr(cm, f)) / (2 * step)) * bounds[g][j]
    return {f: 2 * v for f, v in out.items()}


@pytest.mark.parametrize("gap", [3, 40])
def test_streaming_equals_offline(ride, gap):
    """Bridged (3 frames) and splitting (40 frames) gaps; the difference is within the round-off of
    the two dot products per group (2 W eps sum|w| max|y|) carried through the composition."""
    session, s = ride
    pc = split_pieces(s.position, s.quat, s.tracked, session, s.bodies)
    frame = np.asarray(s.frame)
    keep = np.ones(frame.size, bool)
    keep[900:900 + gap] = False
    pc = {k: v[keep] for k, v in pc.items()}
    frame = frame[keep]
    off = split_derivatives(DT, pc, frame=frame)
    f = StreamingSplit(DT)
    got = {}
    for i in range(frame.size):
        for fr, stt, _ in f.push({k: v[i] for k, v in pc.items()}, frame=int(frame[i])):
            got[fr] = stt
    idx = {int(fr): i for i, fr in enumerate(frame)}
    rows = [idx[fr] for fr in got if fr in idx]
    # the bridged frames have streaming outputs (flagged filled) but no row offline
    assert len(got) - len(rows) == (gap if gap <= 5 else 0) and len(rows) > 100
    expected = np.flatnonzero(np.isfinite(off.x_ddot))
    assert sorted(rows) == list(expected)
    w = split_weights(DT, f.lag)
    cols = group_columns(pc)
    bounds = {g: [2 * w[g].shape[1] * EPS * np.abs(w[g][j]).sum() * np.nanmax(np.abs(cols[g])) for j in range(3)]
              for g in GROUPS}
    # the smoothed inputs of the offline path at the compared frames
    d = {}
    for g, names in GROUPS.items():
        r = fir_derivatives(DT, cols[g], w[g], f.lag, frame=frame)
        d[g] = tuple(a[rows] for a in (r.y, r.y_dot, r.y_ddot))
    tol = _jacobian_bound(d, bounds)
    for fld in FIELDS:
        on = np.array([float(getattr(got[fr], fld)) for fr in got if fr in idx])
        diff = np.abs(on - getattr(off, fld)[rows])
        assert np.all(diff <= tol[fld] + 4 * EPS * np.abs(on)), fld


def test_default_smoothing_and_memory():
    f = StreamingSplit(DT)
    assert f.lag == 12 and set(f.smoothing) == set(SPLIT_SMOOTHING)
    assert f.window == max(w.shape[1] for w in split_weights(DT, 12).values())


def test_rider_state_estimator_runs_the_split_estimator(ride):
    """RiderStateEstimator(estimator="split") gives, per frame, exactly what StreamingSplit gives on
    the pieces of each frame, 0.1 s late; the settings it cannot honour are refused."""
    from euc_ros.core.errors import ConfigError
    from euc_ros.core.filters.causal import streaming_filter
    from euc_ros.core.online.estimators import RiderStateEstimator

    session, s = ride
    est = RiderStateEstimator(session, DT, estimator="split")
    assert est.lag_s == pytest.approx(0.1)
    ref = StreamingSplit(DT)
    got, want = [], {}
    for i in range(s.position.shape[1]):
        fr = int(s.frame[i])
        got += est.update(fr, float(fr) * DT, s.position[:, i], s.quat[:, i], s.tracked[:, i], s.bodies)
        pc = split_pieces(s.position[:, i], s.quat[:, i], s.tracked[:, i], session, s.bodies)
        for f, stt, filled in ref.push(pc, frame=fr):
            if not filled:
                want[f] = stt
    assert len(got) == len(want) > 100
    for o in got:
        w = want[o.frame]
        assert (o.x_ddot, o.phi_ddot, o.gamma_ddot, o.x_dot, o.phi) == (
            float(w.x_ddot), float(w.phi_ddot), float(w.gamma_ddot), float(w.x_dot), float(w.phi))
        assert o.valid and o.filter_lag_s == pytest.approx(0.1)
    for bad in (dict(phi_definition="eq3"), dict(cog_method="skeleton")):
        with pytest.raises(ConfigError):
            RiderStateEstimator(session, DT, estimator="split", settings=ReconstructionSettings(window_s=1.2, **bad))
    for center in ((0.0, 0.1), (0.0, float("nan"), 0.0)):
        with pytest.raises(ConfigError, match="split_euc_center"):
            RiderStateEstimator(session, DT, estimator="split", split_euc_center=center)
    with pytest.raises(ConfigError):
        streaming_filter("split", DT, window_s=1.2, polyorder=6)
