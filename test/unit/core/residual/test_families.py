"""The discovery's function families (:mod:`euc_ros.core.residual.families`) and their group selection.

* each family's basis represents its kind of force to a tolerance derived from approximation theory (the
  complete cubic spline's error bound ``5/384 H^4 max|f''''|``, exact Fourier harmonics, the frequency-domain
  error of the filter bank), on random draws;
* the group selection picks the family of a random force of a random family, with noise;
* end to end on simulated rides, a force of a shape the hand-picked basis did not have (a draught over
  one stretch of the lab): found in the lab-field family, the held-out RMSE after at most 0.6 of before.
"""
# covers: euc_ros/core/residual/groups.py
# covers: euc_ros/core/residual/search.py
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy import signal

from euc_ros.core.residual.basis_filters import low_pass, resonator_columns
from euc_ros.core.residual.families import (
    FAMILIES,
    LAB_LEVELS,
    RESONANCE_HZ,
    SPLINE_LEVELS,
    TIME_CONSTANTS_S,
    Families,
    n_levels,
    uniform_knots,
)
from euc_ros.core.residual.search import fewest_within_one_se, group_path, independent_columns

R = 0.2
DT = 0.1
SEEDS = range(8)


def fake_ctx(rng, name: str, duration: float = 30.0, heading: float | None = None):
    """A recording's context at 10 Hz: a smooth random forward speed, a heading that turns, lab position by
    integration, random pitch rates."""
    t = np.arange(0.0, duration, DT)
    n = t.size

    def smooth(scale, cutoff_hz):
        b, a = signal.butter(2, cutoff_hz * 2 * DT)
        return scale * signal.filtfilt(b, a, rng.standard_normal(n + 200))[100:-100] / 0.15

    v = 0.3 + np.abs(1.5 + smooth(1.5, 0.05))
    psi = (rng.uniform(-np.pi, np.pi) if heading is None else heading) + np.cumsum(smooth(0.3, 0.05)) * DT
    X = np.cumsum(v * np.cos(psi)) * DT + rng.uniform(-3, 3)
    Y = np.cumsum(v * np.sin(psi)) * DT + rng.uniform(-3, 3)
    s = np.cumsum(v) * DT
    return SimpleNamespace(t=t, x_dot=v, psi=psi, phi_dot=smooth(0.3, 0.5), gamma_dot=smooth(0.2, 0.5),
                           params=SimpleNamespace(R=R), extras={"path_s": s, "lab_x": X, "lab_y": Y,
                                                                "recording": name})


def fit_rel_error(B: np.ndarray, y: np.ndarray) -> float:
    c, *_ = np.linalg.lstsq(B, y, rcond=None)
    return float(np.sqrt(np.mean((y - B @ c) ** 2)))


def family_index(basis: Families, kind: str, option: tuple = ()) -> int:
    return next(i for i, f in enumerate(basis.families) if f.kind == kind and (not option or f.option == option))


def spline_bound(knots: np.ndarray, lo: float, hi: float, d4: float) -> float:
    """Error bound of the complete cubic spline interpolant, 5/384 H^4 max|f''''| (H: largest knot spacing);
    the least-squares fit on the samples does at least as well in RMS."""
    H = float(np.max(np.diff(np.concatenate([[lo], knots, [hi]]))))
    return 5.0 / 384.0 * H ** 4 * d4


@pytest.mark.parametrize("seed", SEEDS)
def test_lab_field_represents_a_random_smooth_field(seed):
    """A random field along lab x, sum of 3 sinusoids of wavelengths down to the observed range; a level with knots
    holds it over the span two passes meet (the whole range when none do)."""
    rng = np.random.default_rng(seed)
    ctxs = [fake_ctx(rng, f"r{i}") for i in range(4)]
    basis = Families(ctxs)
    f = family_index(basis, "lab", ("X", "1"))
    lo, hi, knots = basis.ranges["X"]
    top = len(SPLINE_LEVELS) - 1
    spacing = LAB_LEVELS[top][1]
    if basis.spans["X"] is not None:
        lo, hi = basis.spans["X"]
        knots = {top: uniform_knots(lo, hi, spacing)}
    amp = rng.normal(0, 1, 3)
    w = 2 * np.pi / ((hi - lo) * rng.uniform(1.0, 3.0, 3))
    ph = rng.uniform(0, 2 * np.pi, 3)
    field = lambda x: np.sum(amp * np.sin(np.outer(x, w) + ph), axis=1)  # noqa: E731
    B = np.concatenate([basis.columns(c)[(f, top)] for c in ctxs])
    X = np.concatenate([c.extras["lab_x"] for c in ctxs])
    y = field(X) * np.concatenate([np.cos(c.psi) for c in ctxs])
    inside = (X >= lo) & (X <= hi)
    assert inside.sum() > 20
    tol = spline_bound(knots[top], lo, hi, float(np.sum(np.abs(amp) * w ** 4)))
    assert fit_rel_error(B[inside], y[inside]) <= tol, (fit_rel_error(B[inside], y[inside]), tol)


@pytest.mark.parametrize("seed", SEEDS)
def test_wheel_rotation_represents_a_random_harmonic_series(seed):
    rng = np.random.default_rng(seed)
    ctxs = [fake_ctx(rng, f"r{i}") for i in range(3)]
    basis = Families(ctxs)
    f = family_index(basis, "wheel")
    K = int(rng.integers(1, n_levels(basis.families[f]) + 1))
    a, b = rng.normal(0, 1, K), rng.normal(0, 1, K)
    th = np.concatenate([c.extras["path_s"] / R for c in ctxs])
    k = np.arange(1, K + 1)
    y = np.sin(np.outer(th, k)) @ a + np.cos(np.outer(th, k)) @ b
    B = np.concatenate([basis.columns(c)[(f, K - 1)] for c in ctxs])
    assert fit_rel_error(B, y) <= 1e-9 * np.std(y)     # exact up to rounding


@pytest.mark.parametrize("seed", SEEDS)
def test_speed_family_represents_a_random_monotone_law(seed):
    """F(v) = sign(v) (a |v| + b v^2 + c (1 - exp(-|v| / v_s))), a, b, c > 0: viscous, quadratic and a
    Coulomb-like saturation (its fourth derivative, at most c / v_s^4, sets the bound)."""
    rng = np.random.default_rng(seed)
    ctxs = [fake_ctx(rng, f"r{i}") for i in range(3)]
    basis = Families(ctxs)
    odd = [i for i, fam in enumerate(basis.families) if fam.kind == "speed"]
    lo, hi, knots = basis.ranges["speed"]
    a, b, c = rng.uniform(0.5, 2.0, 3)
    vs = rng.uniform(1.0, 2.0)
    law = lambda u: a * u + b * u ** 2 + c * (1 - np.exp(-u / vs))  # noqa: E731
    v = np.concatenate([x.x_dot for x in ctxs])
    y = np.tanh(v / 0.05) * law(np.abs(v))
    top = len(SPLINE_LEVELS) - 1
    f = next(i for i in odd if basis.families[i].option == ("odd",))
    B = np.concatenate([basis.columns(x)[(f, top)] for x in ctxs])
    # the family's odd factor is the same smooth sign: the error is the spline's on |v|
    tol = spline_bound(knots[top], lo, hi, c / vs ** 4)
    err = fit_rel_error(B, y)
    assert err <= tol, (err, tol)


@pytest.mark.parametrize("seed", SEEDS)
def test_dynamics_family_represents_a_first_order_law_off_its_grid(seed):
    """y = 1 / (tau s + 1) u with tau drawn between the grid's time constants (not on it). Tolerance: the
    largest error of the filter bank's best fit of that frequency response over the input's band (the
    discrete filters' responses) times the input's RMS (Parseval), plus the out-of-band part; the
    transients of the first 3 tau_max seconds are left out."""
    rng = np.random.default_rng(seed)
    ctx = fake_ctx(rng, "r0", duration=200.0)
    tau = float(np.exp(rng.uniform(np.log(TIME_CONSTANTS_S[0]), np.log(TIME_CONSTANTS_S[-1]))))
    while min(abs(np.log(tau / g)) for g in TIME_CONSTANTS_S) < 0.2:
        tau = float(np.exp(rng.uniform(np.log(TIME_CONSTANTS_S[0]), np.log(TIME_CONSTANTS_S[-1]))))
    u = ctx.x_dot - ctx.x_dot.mean()
    ctx.x_dot = u
    basis = Families([ctx])
    f = family_index(basis, "dyn", ("x_dot",))
    y = low_pass(u, tau, DT)
    B = basis.columns(ctx)[(f, 1)]
    skip = int(3 * max(TIME_CONSTANTS_S) / DT)
    # frequency-domain bound over the input's band (99.9 % of its power)
    freqs, pu = signal.periodogram(u, 1 / DT)
    band = freqs <= freqs[np.searchsorted(np.cumsum(pu) / np.sum(pu), 0.999)]
    w = 2 * np.pi * freqs[band] * DT

    def response(t_c):
        a = np.exp(-DT / t_c)
        return signal.freqz([1 - a], [1, -a], worN=w)[1]

    H = np.stack([response(t) for t in TIME_CONSTANTS_S]
                 + [response(t) ** 2 for t in TIME_CONSTANTS_S], axis=1)
    target = response(tau)
    A = np.concatenate([H.real, H.imag])
    c, *_ = np.linalg.lstsq(A, np.concatenate([target.real, target.imag]), rcond=None)
    sup = float(np.max(np.abs(H @ c - target)))
    # in band: at most sup times the input (Parseval); out of band (0.1 % of the power): at most the
    # responses' sum
    rms_u = float(np.sqrt(np.mean(u[skip:] ** 2)))
    tol = sup * rms_u + np.sqrt(1e-3) * rms_u * (1 + np.sum(np.abs(c)))
    err = fit_rel_error(B[skip:], y[skip:])
    assert err <= tol + 1e-12, (tau, err, tol)


@pytest.mark.parametrize("seed", SEEDS)
def test_oscillator_family_represents_a_payload_off_its_grid(seed):
    """A payload's reaction (resonance of random frequency 0.55-3.6 Hz, off the grid, damping 0.05-0.2) carried at
    a random speed: its nearer grid level's four columns explain at least 0.7 of its variance (0.78-0.90 on five
    draws; the columns leave out the carried mass's quasi-static part, in phase with the carrier's
    acceleration, and the part above the resonance)."""
    rng = np.random.default_rng(seed)
    dt = 1 / 120
    n = int(60 / dt)
    b, a = signal.butter(2, 5.0, fs=1 / dt)
    u = np.cumsum(signal.lfilter(b, a, rng.standard_normal(n))) * dt
    u -= u.mean()
    grid = np.log(RESONANCE_HZ)
    f = float(np.exp(rng.uniform(grid[1], grid[-2])))
    zeta = float(rng.uniform(0.05, 0.2))
    # the payload's reaction: its mass times its acceleration, the carrier's plus the relative one, from the
    # relative displacement e'' + 2 zeta w e' + w^2 e = -x'' integrated by scipy's lsim (its own discretisation)
    w = 2 * np.pi * f
    t = np.arange(n) * dt
    _, e_dot, _ = signal.lsim(([-1.0, 0.0, 0.0], [1.0, 2 * zeta * w, w * w]), u, t)
    y = np.gradient(e_dot + u, dt)
    k = int(np.argmin(np.abs(grid - np.log(f))))
    B = resonator_columns(u, RESONANCE_HZ[k], dt)
    skip = int(3.0 / dt)
    c, *_ = np.linalg.lstsq(B[skip:], y[skip:], rcond=None)
    explained = 1 - np.var(y[skip:] - B[skip:] @ c) / np.var(y[skip:])
    assert explained >= 0.7, (f, zeta, explained)


def synthetic_problem(rng, truth: str):
    """Columns of every family and level on random recordings, and a force of the family ``truth`` with
    random coefficients at a random level, plus white noise of 0.3 times its RMS."""
    ctxs = [fake_ctx(rng, f"r{i}") for i in range(4)]
    basis = Families(ctxs)
    cands, keys = [], []
    for f in range(len(basis.families)):
        for lv in range(n_levels(basis.families[f])):
            cands.append(np.concatenate([basis.columns(c)[(f, lv)] for c in ctxs]))
            keys.append(f)
    options = {"lab": ("X", "1"), "speed": ("odd",), "dyn": ("phi_dot",), "wheel": ()}
    f_true = family_index(basis, truth, options[truth])
    lv = int(rng.integers(0, n_levels(basis.families[f_true])))
    B = cands[keys.index(f_true) + lv]
    y = B @ rng.normal(0, 1, B.shape[1])
    y = y + 0.3 * np.std(y) * rng.standard_normal(y.size)
    return basis, cands, keys, f_true, y


@pytest.mark.parametrize("truth", ["lab", "wheel", "speed", "dyn"])
@pytest.mark.parametrize("seed", SEEDS)
def test_group_selection_picks_the_right_family(truth, seed):
    rng = np.random.default_rng(1000 * seed + hash(truth) % 997)
    basis, cands, keys, f_true, y = synthetic_problem(rng, truth)
    path = group_path(y, cands, keys, 3, n_eff=y.size / 5)
    assert keys[path[0][0]] == f_true, (basis.families[keys[path[0][0]]].key, basis.families[f_true].key)


def test_independent_columns_drops_a_collinear_column():
    rng = np.random.default_rng(0)
    A = rng.normal(size=(50, 3))
    A = np.column_stack([A, A[:, 0] + A[:, 1] + 1e-6 * rng.normal(size=50)])
    assert len(independent_columns(A)) == 3


def test_fewest_within_one_se_prefers_fewer_groups_inside_the_noise():
    """A second group that cuts the mean square by 1 % while the blocks scatter by +-20 % is not taken; one
    that halves the error is."""
    rng = np.random.default_rng(1)
    n, blocks = 600, np.repeat(np.arange(60), 10)
    e0 = rng.normal(0, 1.0, n)
    e1 = rng.normal(0, 1.0, n)
    e1 = 0.5 * e1 / np.sqrt(np.bincount(blocks, e1 ** 2) / 10)[blocks]     # the same mean square in every block
    a = np.where(np.arange(60) % 2 == 0, 0.19, -0.21)[blocks]
    e2 = e1 * np.sqrt(1 + a)
    assert np.mean(e2 ** 2) < np.mean(e1 ** 2)
    assert fewest_within_one_se({0: e0, 1: e1, 2: e2}, blocks) == 1
    assert fewest_within_one_se({0: e0, 1: e0 * 1.001}, blocks) == 0


def test_duplicate_families_are_dropped_when_the_speed_keeps_its_sign():
    rng = np.random.default_rng(2)
    ctxs = [fake_ctx(rng, f"r{i}") for i in range(3)]
    for c in ctxs:
        c.x_dot = np.abs(c.x_dot) + 0.5
    kinds = [(f.kind, f.option) for f in Families(ctxs).families]
    assert ("speed", ("odd",)) in kinds and ("speed", ("even",)) not in kinds
    assert ("lab", ("X", "sign")) not in kinds and ("dyn", ("|x_dot|",)) not in kinds
    assert len(FAMILIES) > len(kinds)


def per_run_drift(basis: Families) -> int:
    return next(i for i, f in enumerate(basis.families) if f.kind == "drift" and not f.option)


def test_drift_is_per_recording():
    rng = np.random.default_rng(3)
    ctxs = [fake_ctx(rng, f"r{i}") for i in range(3)]
    basis = Families(ctxs)
    f = per_run_drift(basis)
    cols = basis.columns(ctxs[1])[(f, 1)]
    assert np.all(cols[:, [0, 1, 4, 5]] == 0) and np.any(cols[:, 2:4] != 0)


def test_a_drift_every_run_goes_through_again_is_one_shared_function():
    """Three recordings of different lengths starting at different clock times, each with the same function of
    the time since its start (a quadratic: 2 - 0.1 t + 0.004 t^2). The shared drift family holds it exactly with
    3 coefficients on all three, and predicts the third recording from a fit on the other two; the per-recording
    family (9 columns) cannot predict a recording it was not fitted on. Both are kept: the shared one lies in the
    per-recording span and comes first so that it is not pruned."""
    rng = np.random.default_rng(4)
    ctxs = [fake_ctx(rng, f"r{i}", duration=d) for i, d in enumerate((30.0, 24.0, 27.0))]
    for c, start in zip(ctxs, (0.0, 100.0, 250.0)):
        c.t = c.t + start
    basis = Families(ctxs)
    kinds = [(f.kind, f.option) for f in basis.families]
    assert ("drift", ("shared",)) in kinds and ("drift", ()) in kinds
    shared = family_index(basis, "drift", ("shared",))
    # degree 2: the shared drift's second level (it starts at degree 1: a shared constant is the library's)
    assert basis.width(shared, 1) == 3 and basis.width(per_run_drift(basis), 2) == 9
    assert basis.width(shared, 0) == 2 and n_levels(basis.families[shared]) == 2

    def law(c):
        tau = c.t - c.t[0]
        return 2.0 - 0.1 * tau + 0.004 * tau ** 2

    B = [np.asarray(basis.columns(c)[(shared, 1)]) for c in ctxs]
    coef, *_ = np.linalg.lstsq(np.vstack(B[:2]), np.concatenate([law(c) for c in ctxs[:2]]), rcond=None)
    assert np.max(np.abs(B[2] @ coef - law(ctxs[2]))) < 1e-9
    assert fit_rel_error(np.vstack(B), np.concatenate([law(c) for c in ctxs])) < 1e-12
    grid, Phi, curves = basis.curve(shared, 1)
    assert curves == [""] and grid[0] == 0.0 and grid[-1] == pytest.approx(29.9)
    assert np.allclose(Phi[0] @ coef, 2.0 - 0.1 * grid + 0.004 * grid ** 2, atol=1e-9)
    P = [np.asarray(basis.columns(c)[(per_run_drift(basis), 2)]) for c in ctxs]
    c2, *_ = np.linalg.lstsq(np.vstack(P[:2]), np.concatenate([law(c) for c in ctxs[:2]]), rcond=None)
    assert np.allclose(P[2] @ c2, 0.0)            # zero on a recording it was not fitted on


@pytest.mark.slow
def test_a_draught_over_one_stretch_of_the_lab_is_found_in_the_lab_field():
    """A horizontal force along lab x on the rider, a Gaussian bump of the wheel's lab x (10 N, centred at
    x = 10 m, width 4 m): neither constant nor linear in position, so the hand-picked basis (cos(psi),
    X cos(psi)) could not hold it. The runs are recorded in one lab frame; the forward runs cross the bump."""
    from euc_ros.core.model.terms import EucParams
    from euc_ros.core.residual.analysis import analyze
    from euc_ros.core.residual.noise import make_noise_floor
    from euc_ros.core.ridesim.external import ExternalForce
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
    from euc_ros.core.states.kinematics import reconstruct_states

    external = (ExternalForce("lab_bump", {"amp_n": 10.0, "x0_m": 10.0, "width_m": 4.0}),)
    states, series, session = [], [], None
    for i, (maneuver, runs) in enumerate((("acceleration", 3), ("deceleration", 3))):
        res = simulate_ride(RideConfig(maneuver=maneuver, runs=runs, seed=11 + 101 * i, external=external))
        session = res.session
        states += [reconstruct_states(r.mocap, session) for r in res.runs]
        series += [r.mocap for r in res.runs]
    params = EucParams.from_session(session)
    out = analyze(states, params, noise_floor_of=make_noise_floor(series, states, session, params)).to_json()
    assert out["residual_significant"] and out["discovered"], out["discovery"]
    assert any(d["family"] == "lab field" and d["argument"] == "lab X" for d in out["discovered"]), out["discovered"]
    assert out["rmse_after_nm"] <= 0.6 * out["rmse_before_nm"]
    for d in out["discovered"]:
        assert len(d["grid"]) == len(d["values"]) or d["curves"]


def test_discovered_rows_carry_the_function_with_its_band_and_draw(tmp_path):
    """describe(): one row per group with the function on a grid over its argument's range and a 95 % band
    that holds the values (a drift: one curve per recording); the CLI's figure passes the layout checks."""
    from euc_ros.cli import figures
    from euc_ros.cli.figures import discovered_figure
    from euc_ros.core.residual.groups import DiscoveredEffect, Group

    rng = np.random.default_rng(5)
    ctxs = [fake_ctx(rng, f"r{i}") for i in range(3)]
    basis = Families(ctxs)
    groups = [Group(family_index(basis, "lab", ("X", "1")), 1, 1), Group(per_run_drift(basis), 1, 0),
              Group(family_index(basis, "dyn", ("x_dot",)), 0, 3)]
    eff = DiscoveredEffect(basis, groups, np.ones(60))
    theta = rng.normal(size=eff.n_params)
    A = rng.normal(size=(eff.n_params, eff.n_params))
    rows = eff.describe(theta, 0.01 * A @ A.T, dof=40)
    assert [r["family"] for r in rows] == ["lab field", "drift", "dynamics"]
    assert rows[2]["point"] == "rider" and rows[2]["coordinate"] == "pitch" and rows[2]["unit"] == "N m/(m/s)"
    for r in rows:
        v, lo, hi = (np.array(r[k], float) for k in ("values", "band_lo", "band_hi"))
        ok = np.isfinite(v)
        assert np.all(lo[ok] <= v[ok]) and np.all(v[ok] <= hi[ok]) and np.any(hi[ok] > lo[ok])
    assert len(rows[1]["curves"]) == 3 and np.array(rows[1]["values"], float).shape == (3, len(rows[1]["grid"]))
    figures.configure(strict=True)
    try:
        assert discovered_figure(rows, tmp_path / "discovered_functions.png").is_file()
    finally:
        figures.configure()


def test_independent_columns_ignores_round_off_in_the_pivots():
    # two orthogonal unit columns and their mean direction: any two span the three, and all three tie on
    # their norms, so the kept pair must not follow round-off (ties go to the first column)
    rng = np.random.default_rng(3)
    Q, _ = np.linalg.qr(rng.standard_normal((200, 2)))
    A = np.column_stack([Q[:, 0], Q[:, 1], (Q[:, 0] + Q[:, 1]) / np.sqrt(2.0)])
    for _ in range(20):
        noisy = A * (1.0 + 1e-13 * rng.standard_normal(A.shape))
        assert independent_columns(noisy).tolist() == [0, 1]
    # a column scaled by round-off still ties; one that adds a real direction is kept
    B = np.column_stack([A, rng.standard_normal(200)])
    assert independent_columns(B).tolist() == [0, 1, 3]


@pytest.fixture(scope="module")
def prepared_ride():
    """Two runs of a simulated ride prepared for the analysis (their contexts carry the full-rate signals)."""
    from euc_ros.core.model.terms import EucParams
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
    from euc_ros.core.states.contexts import prepare
    from euc_ros.core.states.kinematics import reconstruct_states

    ride = simulate_ride(RideConfig(maneuver="deceleration", runs=2, seed=4))
    p = EucParams.from_session(ride.session)
    return prepare([reconstruct_states(r.mocap, ride.session) for r in ride.runs], p)


def test_columns_filtered_a_few_at_a_time_are_the_whole_filter(prepared_ride, monkeypatch):
    """The families' columns made at the full rate go through the states' filter a few columns at a time
    and a lab coordinate's spline basis is kept one level at a time: every column equals the whole
    recording's columns filtered at once (each column is filtered on its own)."""
    import euc_ros.core.residual.families as fm

    ctx = prepared_ride[0].ctx
    assert "full" in ctx.extras and len(ctx.extras["full"]["t"]) > len(ctx.t)     # the full-rate path is used
    monkeypatch.setattr(fm, "_SEEN_BLOCK", 1 << 40)                 # every column at once
    whole = Families([r.ctx for r in prepared_ride]).columns(ctx)
    monkeypatch.setattr(fm, "_SEEN_BLOCK", 1)                       # one column at a time
    basis = Families([r.ctx for r in prepared_ride])
    parts = basis.columns(ctx)
    assert list(parts) == list(whole) == [(f, lv) for f, fam in enumerate(basis.families)
                                          for lv in range(n_levels(fam))]
    assert any(basis.families[f].kind == "lab" for f, _ in parts)
    for k in whole:
        assert parts[k].shape == (len(ctx.t), basis.width(*k)) and np.array_equal(parts[k], whole[k]), k


def test_row_sensitivities_are_rows_of_the_whole_matrix(prepared_ride):
    """The selection's sensitivities, made group by group on some rows of some recordings, are those rows of
    the whole matrix (group_sensitivities) stacked in order."""
    from euc_ros.core.residual.groups import RowSensitivities, candidate_groups, group_sensitivities

    recs = prepared_ride
    basis = Families([r.ctx for r in recs])
    groups = candidate_groups(basis)
    rng = np.random.default_rng(2)
    L = [rng.normal(size=(r.ctx.t.shape[0], 3)) for r in recs]
    rows = [rng.random(r.ctx.t.shape[0]) < 0.6 for r in recs]
    whole = np.concatenate([group_sensitivities(basis, r.ctx, Li, groups)[m] for r, Li, m in zip(recs, L, rows)])
    S = RowSensitivities(basis, [(r.ctx, Li, m) for r, Li, m in zip(recs, L, rows)], groups)
    assert S.n == whole.shape[0] == sum(int(m.sum()) for m in rows)
    edges = np.concatenate([[0], np.cumsum([basis.width(g.family, g.level) for g in groups])])
    for j in range(len(groups)):
        assert np.array_equal(S.block(j), whole[:, edges[j]:edges[j + 1]]), j


def test_columns_asked_for_some_keys_are_those_of_every_column(prepared_ride):
    """A context asked for some (family, level) columns gets exactly those of the full set, and a later ask
    for every column completes it (the kept ones unchanged)."""
    ctx = prepared_ride[0].ctx
    whole = Families([r.ctx for r in prepared_ride]).columns(ctx)
    basis = Families([r.ctx for r in prepared_ride])
    keys = list(whole)[1::3]
    some = basis.columns(ctx, keys)
    assert list(some) == keys
    assert all(np.array_equal(some[k], whole[k]) for k in keys)
    every = basis.columns(ctx)
    assert list(every) == list(whole) and all(np.array_equal(every[k], whole[k]) for k in whole)
    assert all(every[k] is some[k] for k in keys)                 # kept, not made again


def test_full_rate_signals_are_the_states_own(prepared_ride):
    """A context's full-rate signals, read from its states when asked for, are the states' arrays (NaN as 0,
    time from the first sample, the path integrated by trapezoids, the heading unwrapped)."""
    rec = prepared_ride[0]
    full = rec.ctx.extras["full"]
    st = full._st
    xd = np.where(np.isfinite(st.x_dot), st.x_dot, 0.0)
    s = np.zeros(st.t.size)
    for i in range(1, st.t.size):                               # the path, sample by sample
        s[i] = s[i - 1] + 0.5 * (xd[i] + xd[i - 1]) * (st.t[i] - st.t[i - 1])
    np.testing.assert_allclose(full["s"], s, rtol=1e-12, atol=1e-12 * np.abs(s).max())
    assert np.array_equal(full["v"], xd) and full["t"][0] == 0.0
    assert np.all(np.abs(np.diff(full["psi"])) < np.pi)           # unwrapped
    assert np.array_equal(full["X"], np.nan_to_num(st.C[:, 0])) and np.array_equal(full["index"], rec.index)
    assert set(full) == {"t", "v", "s", "psi", "X", "Y", "phi_dot", "gamma_dot", "index", "window", "polyorder"}
    assert full["window"] == st.window and full["polyorder"] == st.polyorder


def test_retained_columns_are_kept_and_the_rest_made_again_alike(prepared_ride):
    """After a fit the basis keeps only the chosen groups' columns; asked again for every column it makes
    the others anew, the same numbers."""
    ctx = prepared_ride[0].ctx
    basis = Families([r.ctx for r in prepared_ride])
    whole = {k: v.copy() for k, v in basis.columns(ctx).items()}
    keep = list(whole)[:2]
    basis.retain(keep)
    assert set(basis._cache[next(iter(basis._cache))][1]) == set(keep)
    again = basis.columns(ctx)
    assert list(again) == list(whole) and all(np.array_equal(again[k], whole[k]) for k in whole)
