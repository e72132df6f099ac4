"""Close the loop: fit candidate effects to the residual M_d1 - M_d2, select by held-out error.

Steps (issue 5): identify h with the paper's 3-DoF model; compute r(t) = M_d1 - M_d2; check each
candidate's detectability (is its generalized force in span(b_d, b_h)?); fit each detectable
candidate's parameters jointly with h on training data and evaluate on held-out data (other runs,
or other segments of a single run); select by held-out error with a one-sided paired test over
blocks of the held-out residual (family-wise over the candidates: max-T) and a minimum relative
gain; repeat greedily with the selected effects in the model until nothing significant remains.

The residual of a model is ``M_d1 - M_d2 = R m11 (w . (M q_ddot + h - Q_g - dQ)) / D``
(:mod:`euc_ros.core.model.torque`), so an extra force with ``w . dQ = 0`` cannot change it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
from scipy import optimize, signal, stats

from euc_ros.core.filters.derivatives import savgol_coefficients, savgol_derivatives
from euc_ros.core.model.effects import Candidate, FloorGeometry, ModelContext, make_candidates
from euc_ros.core.model.terms import EucParams, consistency_weights
from euc_ros.core.model.torque import torque_difference
from euc_ros.core.residual.floor import FloorFit, fit_floor, rolling_radius_from_floor, slope_along_path
from euc_ros.core.states.geometry import to_moving_frame
from euc_ros.core.states.kinematics import DEFAULT_SG_POLYORDER, DEFAULT_WINDOW_S, RiderStates

#: Savitzky-Golay settings of the residual analysis: the project defaults (measured: with a 0.9 s
#: quartic the attenuation of the accelerations inflated inertia-type parameters, rider mass by
#: +25-30 %; 1.2 s / order 6 keeps the noise floor with less bias, rider mass within 15 %).
RESIDUAL_WINDOW_S = DEFAULT_WINDOW_S
RESIDUAL_POLYORDER = DEFAULT_SG_POLYORDER
#: Significance level of the selection test (family-wise over the candidates of one step).
DEFAULT_ALPHA = 0.01
#: A selected effect must cut the held-out RMSE by at least this fraction.
DEFAULT_MIN_GAIN = 0.10
#: Length of the blocks the paired test compares [s] (longer than the derivative filter's window).
DEFAULT_BLOCK_S = 1.0
#: Fewest folds of the held-out evaluation (segments per run = ceil(this / runs), at least 2).
MIN_FOLDS = 6
#: The residual's slow part (an effect's signature) is removed over this many filter windows before its
#: autocorrelation sets the block length (:func:`residual_block_length`).
TREND_WINDOWS = 16.0
#: Shortest block of the paired test, in filter windows. The block is twice the residual noise's integrated
#: correlation time, measured at 0.35-0.47 s on the power rides (1.2 s window); a floor of one window used to set
#: every block (15 blocks in 3 runs of 7 s). Measured on 100 no-effect rides (README, statistical power): the
#: per-candidate p-values stay uniform or conservative from 0.3 s to 1.2 s blocks (lag-1 correlation of the
#: blocks' log ratios -0.04); below half a window a block holds 3-4 correlated samples at the analysis rate and
#: its mean square can come near 0 (log ratios of -10), which costs power.
MIN_BLOCK_WINDOWS = 0.5
#: Sign flips of the max-T correction over the candidates of a selection step (:func:`max_t_adjusted`); exact
#: enumeration when the blocks are at most log2 of this.
MAX_T_FLIPS = 1 << 15
#: Relative tolerance of the least-squares fits: a cost change of 1e-6 moves a parameter by ~1e-3 of its
#: standard error, far below what the selection can resolve (scipy's default 1e-8 took ~40 evaluations).
FIT_TOL = 1e-6
#: Sample rate the analysis works at [Hz] (:func:`decimation_step`): 4x the derivative filter's passband.
ANALYSIS_RATE_HZ = 10.0
#: An effect is undetectable when its generalized force projects on w = [R, 1, 1] by less than this
#: fraction of its size (it lies in the span of the input directions).
DETECTABILITY_TOL = 1e-6
#: Another candidate is reported as ambiguous with the selected one unless the selected one is better
#: than it at this one-sided level (paired block test).
AMBIGUITY_ALPHA = 0.05
#: A measured rolling radius (wheel-centre height over the floor) this far from the nominal one is a
#: wheel_radius_error found by geometry [m] (tyre and ground-plane tolerances are a few mm).
RADIUS_TOL_M = 0.005
#: h bounds of the joint fits [m].
H_BOUNDS = (0.05, 1.6)
#: Plausible rider CoG heights above the ankle hinge [m] (adult riders standing on pedals: the paper's
#: 0.61 m, +-0.3 m for build, posture and session geometry); a model whose h leaves it is not selected.
H_PLAUSIBLE = (0.3, 1.2)
#: A model's h may differ from the geometric one (median |G - A| of the segment CoG over the hinge, from
#: the session's mass fractions and CoM positions) by at most this much [m]. Measured: with an effect in
#: the data the base model's h can be 0.5 m off (a 4 deg slope: 0.12 m for a true 0.61 m), so the base
#: model is no reference; the segments' geometry is (session CoM errors of 1-3 cm move it by < 0.05 m).
H_MAX_GEOMETRIC_DEV_M = 0.15
#: The residual is above its noise floor when its held-out RMSE exceeds this many noise floors. The floor
#: is one realisation of the white pose noise propagated (within 3 % of the true noise contribution on a
#: simulated ride, test_noise.py); on no-effect rides the held-out RMSE is 0.9x it at 120 Hz and 1.1x at
#: 360 Hz (filter bias, 3-D reconstruction): 1.5x leaves ~4 standard errors of that ratio on 3 runs of 7 s
#: (~30 blocks). It was 3x, which reported swinging arms at 1.8 floors as `none` ("at the noise floor");
#: coloured noise the floor does not see is then `unexplained`, which is what it is.
NOISE_FLOOR_FACTOR = 1.5
#: A parameter closer than this fraction of its range to a bound is "on the bound".
AT_BOUND_FRACTION = 1e-3
#: Which of the candidates the held-out data cannot tell apart is named (all of them are reported as tied with
#: the h each implies): "heldout", the lowest held-out RMSE; "prior", the one needing the most typical parameter
#: values (each in units of ParamInfo.scale). Measured on the power rides (README, statistical power; seeds
#: 100-109 per family): the truth named in 74/80 trials with "heldout", 60/80 with "prior" (which named
#: viscous_friction for aero_drag in 8/10 and rider_inertia_error for rider_mass_error in 6/10; it helped only
#: viscous_friction against its twin mocap_time_offset, 9/10 against 6/10); both pass every undeclared-effect case.
TIE_BREAK = "heldout"


# --------------------------------------------------------------------------------------------
# data
# --------------------------------------------------------------------------------------------
@dataclass
class Recording:
    """One recording prepared for the analysis: its valid samples as a model context."""

    name: str
    ctx: ModelContext
    block: np.ndarray  # block index of each sample (for the paired test and single-run folds)
    index: np.ndarray | None = None  # sample index in the recording of each valid sample


#: Samples per block of the time-shift hook's geometry (:func:`_hinge`, :func:`_phi_about_hinge`): the
#: temporaries of the whole recording's (n, 3) rotations were ~60 MB an hour at 120 Hz.
_SHIFT_BLOCK = 1 << 16


def _hinge(st: RiderStates, l0: float) -> np.ndarray:
    """Ankle hinge A = C - l0 z_E (n, 3), z_E = Rz(psi) Rx(theta) Ry(gamma) e_z the EUC body's z axis
    (block by block: elementwise, so the same numbers as the whole at once)."""
    n = st.C.shape[0]
    out = np.empty((n, 3))
    for lo in range(0, n, _SHIFT_BLOCK):
        hi = min(n, lo + _SHIFT_BLOCK)
        gamma, psi, theta = st.gamma[lo:hi], st.psi[lo:hi], st.theta[lo:hi]
        zb = np.stack([np.sin(gamma), -np.sin(theta) * np.cos(gamma), np.cos(theta) * np.cos(gamma)], axis=1)
        zw = np.stack([np.cos(psi) * zb[:, 0] - np.sin(psi) * zb[:, 1],
                       np.sin(psi) * zb[:, 0] + np.cos(psi) * zb[:, 1], zb[:, 2]], axis=1)
        out[lo:hi] = st.C[lo:hi] - l0 * zw
    return out


def _phi_about_hinge(G: np.ndarray, A: np.ndarray, psi: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Rider pitch of G about A in the moving frame, ``arctan2(r_x, r_z)`` of ``r = T(G - A)`` (n,), block by block."""
    n = G.shape[0]
    out = np.empty(n)
    for lo in range(0, n, _SHIFT_BLOCK):
        hi = min(n, lo + _SHIFT_BLOCK)
        r = to_moving_frame(G[lo:hi] - A[lo:hi], psi[lo:hi], theta[lo:hi])
        out[lo:hi] = np.arctan2(r[:, 0], r[:, 2])
    return out


def _phi_shift_fn(st: RiderStates, params: EucParams, window: int, polyorder: int, valid: np.ndarray
                  ) -> Callable[[float], tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Build dt -> change of (phi, phi_dot, phi_ddot) when the rider CoG G is shifted by dt in time.

    The hinge path and the unshifted pitch (4 numbers a sample) are made on the first call and kept:
    every recording is prepared (the noise floor's re-noised ones too), few are shifted.
    """
    t = st.t
    psi, theta = st.psi, st.theta
    idx = np.flatnonzero(valid)
    half = (window - 1) // 2
    base: dict = {}

    def geometry():
        if not base:
            A = _hinge(st, params.l0)
            base["A"], base["phi0"] = A, _phi_about_hinge(st.G, A, psi, theta)
            uniform = st.frame is not None and len(st.frame) == len(t) and bool(np.all(np.diff(st.frame) == 1)) \
                and np.isfinite(st.dt)
            # the filter's centre weights evaluated only at the samples the analysis uses (valid samples lie at
            # least half a window inside their stretch, so the centre weights are the ones the full filter uses)
            base["weights"] = savgol_coefficients(window, polyorder, st.dt, [half])[:, 0, :] if uniform else None
        return base["A"], base["phi0"], base["weights"]

    def shift(dt: float):
        A, phi0, weights = geometry()
        Gs = np.stack([np.interp(t + dt, t, st.G[:, k], left=np.nan, right=np.nan) for k in range(3)], axis=1)
        d = _phi_about_hinge(Gs, A, psi, theta)
        d -= phi0
        if weights is not None:
            W = np.lib.stride_tricks.sliding_window_view(np.pad(d, half, constant_values=np.nan), window)[idx]
            out = W @ weights.T
            return out[:, 0], out[:, 1], out[:, 2]
        der = savgol_derivatives(t, d, window=window, polyorder=polyorder, frame=st.frame)
        return der.y[valid], der.y_dot[valid], der.y_ddot[valid]

    return shift


def decimation_step(dt: float, analysis_rate_hz: float | None) -> int:
    """Keep every k-th sample so that the analysis runs at about ``analysis_rate_hz`` (1: all samples).

    The states come out of the Savitzky-Golay filter, whose passband ends near 2.5 Hz for the default
    1.2 s window (response below 1 % of its peak from 2.6 Hz on, sidelobes of 6-22 % above it): the
    residual's signal is over-sampled at 120-360 Hz and a sub-sample at :data:`ANALYSIS_RATE_HZ` keeps it
    (the fits and held-out errors on the sub-sample are unbiased; measured against every sample in
    ``test_decimation.py``), while the fits' cost falls with the number of samples.
    """
    if not analysis_rate_hz or not np.isfinite(dt) or dt <= 0:
        return 1
    return max(1, int(math.floor(1.0 / (dt * analysis_rate_hz) + 1e-9)))


def prepare(states: Sequence[RiderStates], params: EucParams, *, block_s: float = DEFAULT_BLOCK_S,
            floor: FloorFit | None = None, analysis_rate_hz: float | None = None) -> list[Recording]:
    """Turn reconstructed recordings into analysis inputs (valid samples, yaw rate, time-shift hook).

    ``analysis_rate_hz``: keep every k-th sample (:func:`decimation_step`); None keeps all of them.

    With a ``floor`` that is not flat, each context also carries the floor's slope along travel under
    the wheel (``extras['floor_a']``) and the wheel centre's vertical acceleration (``extras['c_zdd']``,
    the states' derivative filter) for :class:`~euc_ros.core.model.effects.FloorGeometry`.
    """
    out = []
    for st in states:
        window = st.window if st.window and st.window % 2 == 1 else 9
        valid = np.asarray(st.valid, bool).copy()   # already half a window inside each stretch
        dpsi = savgol_derivatives(st.t, np.unwrap(st.psi), window=window, polyorder=st.polyorder, frame=st.frame)
        valid &= np.isfinite(dpsi.y_dot) & np.isfinite(st.theta)
        step = decimation_step(st.dt if np.isfinite(st.dt) else float(np.median(np.diff(st.t))), analysis_rate_hz)
        if step > 1:
            valid &= (np.arange(valid.size) % step) == 0
        ctx = ModelContext(
            t=st.t[valid] - st.t[0], x_dot=st.x_dot[valid], x_ddot=st.x_ddot[valid], gamma=st.gamma[valid],
            gamma_dot=st.gamma_dot[valid], gamma_ddot=st.gamma_ddot[valid], phi=st.phi[valid],
            phi_dot=st.phi_dot[valid], phi_ddot=st.phi_ddot[valid], psi=np.unwrap(st.psi)[valid],
            psi_dot=dpsi.y_dot[valid], theta=st.theta[valid], params=params)
        if st.phi_definition == "hinge":
            ctx.extras["phi_shift"] = _phi_shift_fn(st, params, window, st.polyorder, valid)
        if floor is not None and not floor.flat:
            a = slope_along_path(st.C, st.theta, st.psi, st.valid, params.R, floor)
            czz = savgol_derivatives(st.t, st.C[:, 2], window=window, polyorder=st.polyorder, frame=st.frame).y_ddot
            ctx.extras["floor_a"] = np.nan_to_num(a[valid])
            ctx.extras["c_zdd"] = np.nan_to_num(czz[valid])
        dt = st.dt if np.isfinite(st.dt) else float(np.median(np.diff(st.t)))
        block = np.floor((st.t[valid] - st.t[0]) / max(block_s, dt)).astype(int)
        xd = np.nan_to_num(st.x_dot)
        s_path = np.concatenate([[0.0], np.cumsum(0.5 * (xd[1:] + xd[:-1]) * np.diff(st.t))])
        ctx.extras["path_s"] = s_path[valid]
        ctx.extras["lab_x"] = np.nan_to_num(st.C[valid, 0])
        ctx.extras["lab_y"] = np.nan_to_num(st.C[valid, 1])
        out.append(Recording(st.name, ctx, block, np.flatnonzero(valid)))
    return out


# --------------------------------------------------------------------------------------------
# models
# --------------------------------------------------------------------------------------------
@dataclass
class Model:
    """The base model plus a list of candidate effects; parameter vector ``[h, theta_1..., theta_2...]``."""

    effects: list[Candidate] = field(default_factory=list)

    @property
    def name(self) -> str:
        """``none`` or the effect names joined with ``+`` in selection order."""
        return "+".join(c.name for c in self.effects) or "none"

    @property
    def n_params(self) -> int:
        """1 (h) plus every effect's parameters."""
        return 1 + sum(c.n_params for c in self.effects)

    def split(self, x: np.ndarray) -> tuple[float, list[np.ndarray]]:
        """Return (h, [theta per effect])."""
        out, k = [], 1
        for c in self.effects:
            out.append(np.asarray(x[k:k + c.n_params], float))
            k += c.n_params
        return float(x[0]), out

    def residual(self, rec: Recording, x: np.ndarray, extra_dQ: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
        """Return (M_d1 - M_d2 [N m], usable mask) of the model with parameters ``x`` on ``rec``
        (``extra_dQ``: a further generalized force, for the discovery's sensitivities)."""
        h, thetas = self.split(x)
        ctx = rec.ctx.copy()
        ctx.overrides["h"] = h
        ctx.params = ctx.params.with_h(h)
        mask = np.ones(ctx.t.shape[0], bool)
        for c, th in zip(self.effects, thetas):
            c.modify(ctx, th)
            if ctx.mask is not None:
                mask &= ctx.mask
                ctx.mask = None
        for c, th in zip(self.effects, thetas):
            dQ = c.force(ctx, th)
            if dQ is not None:
                ctx.add_force(dQ)
        if extra_dQ is not None:
            ctx.add_force(extra_dQ)
        p_mod = ctx.p()
        diff = torque_difference(ctx.gamma, ctx.phi, ctx.gamma_dot, ctx.phi_dot, ctx.x_ddot, ctx.gamma_ddot,
                                 ctx.phi_ddot, p_mod, extra_Q=ctx.extra_Q)
        # M_d1 - M_d2 = R m11 (x_ddot - x_ddot*): compare models on the acceleration mismatch scaled by the
        # NOMINAL R m11, so a parameter change (R, m) cannot shrink the residual by rescaling the equations.
        # For the base model and every effect that keeps R and m this is exactly M_d1 - M_d2.
        p_nom = rec.ctx.params
        ratio = (p_nom.R * _m11(p_nom)) / (np.asarray(p_mod.R, float) * _m11(p_mod))
        r = diff * ratio
        mask &= np.isfinite(r)
        return np.where(mask, r, 0.0), mask

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of ``x``."""
        lo = [H_BOUNDS[0]] + [q.low for c in self.effects for q in c.params]
        hi = [H_BOUNDS[1]] + [q.high for c in self.effects for q in c.params]
        return np.array(lo), np.array(hi)

    def scales(self) -> np.ndarray:
        """Typical magnitudes of ``x`` (least-squares scaling)."""
        return np.array([0.1] + [q.scale for c in self.effects for q in c.params])

    def starts(self, h0: float, fixed: np.ndarray | None = None) -> list[np.ndarray]:
        """Starting points: the last effect's starts appended to ``fixed`` (the previous fit) or defaults."""
        head = np.array([h0]) if fixed is None else np.asarray(fixed, float)
        known = head.size - 1
        rest = []
        k = 0
        for c in self.effects:
            if k >= known:
                rest.append(c.starts())
            k += c.n_params
        if not rest:
            return [head]
        combos = [head]
        for options in rest:
            combos = [np.concatenate([base, s]) for base in combos for s in options]
        return combos

    def report(self, x: np.ndarray) -> dict[str, float]:
        """All effect parameters by their reported names."""
        _, thetas = self.split(x)
        out: dict[str, float] = {}
        for c, th in zip(self.effects, thetas):
            out.update(c.report(th))
        return out


@dataclass
class Fit:
    """A model fitted on some recordings."""

    model: Model
    x: np.ndarray
    rmse: float
    n: int

    @property
    def h(self) -> float:
        """Fitted CoG height [m]."""
        return float(self.x[0])


def _m11(p: EucParams):
    """First diagonal entry of the mass matrix, eq (6): m + m0 + mw + Jw / R^2."""
    return p.m + p.m0 + p.mw + p.Jw / np.asarray(p.R, float) ** 2


def _stack_residual(model: Model, recs: Sequence[Recording], x: np.ndarray) -> np.ndarray:
    parts = [model.residual(r, x)[0] for r in recs]
    return np.concatenate(parts) if parts else np.zeros(0)


def fit_model(model: Model, recs: Sequence[Recording], h0: float, fixed: np.ndarray | None = None,
              start: np.ndarray | None = None) -> Fit:
    """Least-squares fit of h and the effects' parameters to zero residual on ``recs``.

    Several starting points (multi-modal parameters such as a period) are tried and the best is kept,
    unless one ``start`` is given (e.g. the fit on all data, as the start of a fold's fit).
    """
    lo, hi = model.bounds()
    best = None
    for x0 in ([start] if start is not None else model.starts(h0, fixed)):
        x0 = np.clip(x0, lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo))
        try:
            sol = optimize.least_squares(lambda x: _stack_residual(model, recs, x), x0, bounds=(lo, hi),
                                         x_scale=model.scales(), method="trf", max_nfev=200 * len(x0),
                                         ftol=FIT_TOL, xtol=FIT_TOL, gtol=FIT_TOL)
        except ValueError:
            continue
        cost = float(np.sum(sol.fun ** 2))
        if best is None or cost < best[0]:
            best = (cost, sol.x)
    if best is None:
        raise RuntimeError(f"fit of model {model.name} failed from every start")
    masks = [model.residual(r, best[1])[1] for r in recs]
    n = int(sum(int(m.sum()) for m in masks))
    return Fit(model, best[1], math.sqrt(best[0] / max(n, 1)), n)


def fit_base_h(recs: Sequence[Recording], h_grid=np.linspace(0.1, 1.2, 45)) -> float:
    """Grid-then-refine estimate of h with the base model (a good start for every joint fit)."""
    base = Model()
    sse = [float(np.sum(_stack_residual(base, recs, np.array([h])) ** 2)) for h in h_grid]
    k = int(np.argmin(sse))
    lo, hi = h_grid[max(k - 1, 0)], h_grid[min(k + 1, len(h_grid) - 1)]
    res = optimize.minimize_scalar(lambda h: float(np.sum(_stack_residual(base, recs, np.array([h])) ** 2)),
                                   bounds=(lo, hi), method="bounded")
    return float(res.x)


def floor_from_states(states: Sequence[RiderStates], radius: float):
    """The floor fit (:func:`euc_ros.core.residual.floor.fit_floor`) of the contact path of every run."""
    if not states:
        return None
    C = np.concatenate([st.C for st in states])
    theta = np.concatenate([st.theta for st in states])
    valid = np.concatenate([st.valid for st in states])
    seg = np.concatenate([np.full(len(st.t), i) for i, st in enumerate(states)])
    return fit_floor(C, theta, valid, radius, seg)


class _MeasuredWheelRadius(Candidate):
    """wheel_radius_error with its parameter measured (wheel-centre height), not fitted."""

    name = "wheel_radius_error"
    params = ()

    def __init__(self, delta: float):
        self.delta = float(delta)

    def modify(self, ctx, theta):
        ctx.overrides["R"] = ctx.params.R + self.delta

    def report(self, theta):
        return {"delta_r_m": self.delta}


# --------------------------------------------------------------------------------------------
# detectability
# --------------------------------------------------------------------------------------------
def detectability(candidate: Candidate, recs: Sequence[Recording], h: float) -> float:
    """Fraction of the candidate's generalized force that is visible in M_d1 - M_d2.

    The generalized-force equivalent of a unit-scale parameter change is compared with its
    projection on ``w = [R, 1, 1]`` (which annihilates b_d and b_d): 0 means it lies in
    span(b_d, b_h) and cannot show in the residual.
    """
    model = Model([candidate])
    num = den = 0.0
    for rec in recs:
        x0 = np.concatenate([[h], candidate.starts()[0]])
        x1 = x0.copy()
        x1[1:] += np.array([q.scale for q in candidate.params])
        dQ = _equivalent_force(model, rec, x1) - _equivalent_force(model, rec, x0)
        w = consistency_weights(rec.ctx.params)
        proj = dQ @ np.asarray(w, float) / np.linalg.norm(w)
        num += float(np.nansum(proj ** 2))
        den += float(np.nansum(dQ ** 2))
    return math.sqrt(num / den) if den > 0 else 0.0


def _equivalent_force(model: Model, rec: Recording, x: np.ndarray) -> np.ndarray:
    """Generalized force a model adds, in the base model's terms: f_base - f_model (n, 3)."""
    from euc_ros.core.model.terms import bias_terms, gravity_forces, mass_matrix

    h, thetas = model.split(x)
    ctx = rec.ctx.copy()
    ctx.params = ctx.params.with_h(h)
    for c, th in zip(model.effects, thetas):
        c.modify(ctx, th)
    for c, th in zip(model.effects, thetas):
        dQ = c.force(ctx, th)
        if dQ is not None:
            ctx.add_force(dQ)
    n = ctx.t.shape[0]
    q = np.stack([np.zeros(n), ctx.gamma, ctx.phi], 1)
    qd = np.stack([ctx.x_dot, ctx.gamma_dot, ctx.phi_dot], 1)
    qdd = np.stack([ctx.x_ddot, ctx.gamma_ddot, ctx.phi_ddot], 1)
    p = ctx.p()
    f = np.einsum("nij,nj->ni", np.broadcast_to(mass_matrix(q, p), (n, 3, 3)), qdd) + bias_terms(q, qd, p) \
        - gravity_forces(q, p)
    if ctx.extra_Q is not None:
        f = f - ctx.extra_Q
    return -f


# --------------------------------------------------------------------------------------------
# held-out evaluation and selection
# --------------------------------------------------------------------------------------------
@dataclass
class Fold:
    """One train/test split as sample masks per recording (``train[i]``, ``test[i]``: bool over rec i)."""

    train: list[np.ndarray]
    test: list[np.ndarray]
    name: str = ""


def _guard(t: np.ndarray, test: np.ndarray, guard_s: float) -> np.ndarray:
    """Samples within ``guard_s`` of a test sample (they share raw frames through the filter)."""
    if not test.any():
        return np.zeros_like(test)
    tt = t[test]
    j = np.searchsorted(tt, t)
    left = np.abs(t - tt[np.clip(j - 1, 0, tt.size - 1)])
    right = np.abs(tt[np.clip(j, 0, tt.size - 1)] - t)
    return np.minimum(left, right) < guard_s


def folds_of(recs: Sequence[Recording], n_segments: int = 3, guard_s: float = 0.0) -> list[Fold]:
    """Train/test splits within runs as well as across runs.

    Every run is cut into ``n_segments`` contiguous segments of whole blocks; each fold holds out one
    segment of one run and trains on everything else (the other runs, and the rest of that run minus
    ``guard_s`` on either side of the held-out segment: the derivative filter and coloured noise
    correlate neighbouring samples). So every sample is held out once, and each fold trains on
    ``1 - 1/(runs x segments)`` of the data (leave-one-run-out trained on ``1 - 1/runs``).
    """
    folds = []
    for i, rec in enumerate(recs):
        ub = np.unique(rec.block)
        if ub.size == 0:
            continue
        k = max(1, min(n_segments, ub.size))
        for j, chunk in enumerate(np.array_split(ub, k)):
            test = np.isin(rec.block, chunk)
            train = [np.ones(r.block.shape, bool) for r in recs]
            train[i] = ~(test | _guard(rec.ctx.t, test, guard_s))
            tests = [np.zeros(r.block.shape, bool) for r in recs]
            tests[i] = test
            folds.append(Fold(train, tests, f"{rec.name}[{j}]"))
    return folds


def residual_block_length(recs: Sequence[Recording], residuals: Sequence[np.ndarray], *, min_s: float,
                          trend_s: float, max_fraction: float = 0.25) -> float:
    """Block length [s] of the paired test from the residual's measured autocorrelation.

    The slow part of the residual (a cubic Savitzky-Golay fit over ``trend_s``: an unexplained effect's signature)
    is removed first, so the blocks follow the correlation of the residual's noise (the derivative filter,
    coloured pose noise), not the effect the test is looking for. Block = twice the noise's integrated
    autocorrelation time (``dt (1 + 2 sum rho_k)`` up to the first zero crossing: ``m dt`` for an m-sample
    moving average), at least ``min_s`` (one filter window), at most ``max_fraction`` of the shortest
    recording.
    """
    lags = []
    for rec, r in zip(recs, residuals):
        t = rec.ctx.t
        if t.size < 16:
            continue
        dt = float(np.median(np.diff(t)))
        m = min(max(5, int(round(trend_s / dt)) | 1), (t.size - 1) | 1 if t.size % 2 == 0 else t.size)
        trend = signal.savgol_filter(r, m, 3, mode="interp") if m > 3 and m <= r.size else np.full(r.size, r.mean())
        e = r - trend
        e = e - e.mean()
        n = e.size
        f = np.fft.rfft(e, 2 * n)
        acf = np.fft.irfft(f * np.conj(f))[:n]
        if acf[0] <= 0:
            continue
        acf = acf / acf[0]
        below = np.flatnonzero(acf[1:] <= 0)
        zc = below[0] + 1 if below.size else n
        # integrated autocorrelation time up to the first zero crossing: dt (1 + 2 sum rho_k); robust to
        # the crossing's estimation noise (the tail it may cut is where rho is small)
        lags.append(dt * (1.0 + 2.0 * float(np.sum(acf[1:zc]))))
    if not lags:
        return float(min_s)
    shortest = min(float(rec.ctx.t[-1] - rec.ctx.t[0]) for rec in recs if rec.ctx.t.size) if recs else np.inf
    return float(min(max(2.0 * float(np.median(lags)), min_s), max(min_s, max_fraction * shortest)))


def with_blocks(recs: Sequence[Recording], block_s: float) -> list[Recording]:
    """The recordings with their samples grouped into blocks of ``block_s`` seconds."""
    out = []
    for rec in recs:
        t = rec.ctx.t
        block = np.floor((t - (t[0] if t.size else 0.0)) / block_s).astype(int)
        out.append(Recording(rec.name, rec.ctx, block, rec.index))
    return out


@dataclass
class HeldOut:
    """Held-out residuals of a model over all folds, with their blocks (unique over recordings)."""

    model: Model
    residual: np.ndarray
    block: np.ndarray
    params: list[np.ndarray]

    @property
    def rmse(self) -> float:
        """Held-out RMSE [N m]."""
        return float(np.sqrt(np.mean(self.residual ** 2))) if self.residual.size else float("nan")


def _block_offsets(recs: Sequence[Recording]) -> list[int]:
    out, off = [], 0
    for r in recs:
        out.append(off)
        off += int(r.block.max()) + 1 if r.block.size else 0
    return out


def model_jacobian(model: Model, recs: Sequence[Recording], x: np.ndarray, res0=None
                   ) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray]]:
    """Per recording: residual at ``x``, its usable mask and d(residual)/dx by forward differences
    (steps of 1e-4 of each parameter's typical scale, inward at a bound)."""
    res0 = res0 or [model.residual(r, x) for r in recs]
    lo, hi = model.bounds()
    steps = 1e-4 * model.scales()
    J = [np.empty((r.ctx.t.shape[0], x.size)) for r in recs]
    for k in range(x.size):
        x1 = np.array(x, float)
        step = steps[k] if x1[k] + steps[k] <= hi[k] else -steps[k]
        x1[k] += step
        for i, r in enumerate(recs):
            J[i][:, k] = (model.residual(r, x1)[0] - res0[i][0]) / step
    return [a for a, _ in res0], [m for _, m in res0], J


def held_out(model: Model, recs: Sequence[Recording], h0: float, folds=None,
             fixed: np.ndarray | None = None, start: np.ndarray | None = None) -> HeldOut:
    """Fit on each fold's training samples, collect the residual on its held-out samples.

    The fold fits are Gauss-Newton steps from the fit on all data (``start``; fitted here without it):
    the model's Jacobian is evaluated once, each fold's parameters are ``x + dx`` with ``dx`` the
    linear least-squares step on its training rows (clipped to the bounds), and the held-out residual is
    the model evaluated at those parameters. The fold optima lie close to the full one (each fold drops a
    small part of the data), where one step of Gauss-Newton is the standard approximate leave-out fit;
    ``test_heldout.py`` compares it with refitting every fold from scratch.
    """
    folds = folds or folds_of(recs)
    if start is None:
        start = fit_model(model, recs, h0, fixed).x
    x = np.asarray(start, float)
    r_all, m_all, J = model_jacobian(model, recs, x)
    lo, hi = model.bounds()
    sc = model.scales()
    offsets = _block_offsets(recs)
    res, blocks, params = [], [], []
    for fold in folds:
        rows = [np.asarray(tr, bool) & m for tr, m in zip(fold.train, m_all)]
        A = np.concatenate([Ji[rw] for Ji, rw in zip(J, rows)]) * sc
        b = -np.concatenate([ri[rw] for ri, rw in zip(r_all, rows)])
        ok = np.all(np.isfinite(A), axis=0)
        dx = np.zeros(x.size)
        if ok.any():
            dx[ok] = np.linalg.lstsq(A[:, ok], b, rcond=None)[0] * sc[ok]
        xf = np.clip(x + dx, lo, hi)
        params.append(xf)
        for i, (r, te) in enumerate(zip(recs, fold.test)):
            if not np.any(te):
                continue
            rr, mask = model.residual(r, xf)
            keep = np.asarray(te, bool) & mask
            res.append(rr[keep])
            blocks.append(r.block[keep] + offsets[i])
    return HeldOut(model, np.concatenate(res) if res else np.zeros(0),
                   np.concatenate(blocks) if blocks else np.zeros(0, int), params)


def admissibility(model: Model, x: np.ndarray, h_geometric: float) -> str | None:
    """Why a fitted model cannot be selected (None when it can): a parameter on its physical bound
    explains nothing, an h outside :data:`H_PLAUSIBLE` or further than :data:`H_MAX_GEOMETRIC_DEV_M`
    from the segments' geometric h is not this rider."""
    lo, hi = model.bounds()
    span = hi - lo
    k = 1
    for c in model.effects:
        for q in c.params:
            v = float(x[k])
            if q.reported and (v - q.low <= AT_BOUND_FRACTION * span[k] or q.high - v <= AT_BOUND_FRACTION * span[k]):
                # a lower bound of 0 reached means "no effect", an upper bound "more than physical"
                return f"{c.name}: {q.name} = {v:.4g} {q.unit} on its physical bound [{q.low:g}, {q.high:g}]"
            k += 1
    h = float(x[0])
    if not H_PLAUSIBLE[0] <= h <= H_PLAUSIBLE[1]:
        return f"h = {h:.3f} m outside the plausible range [{H_PLAUSIBLE[0]}, {H_PLAUSIBLE[1]}] m"
    if math.isfinite(h_geometric) and abs(h - h_geometric) > H_MAX_GEOMETRIC_DEV_M:
        return (f"h = {h:.3f} m is {abs(h - h_geometric):.3f} m from the segments' geometric {h_geometric:.3f} m "
                f"(more than {H_MAX_GEOMETRIC_DEV_M} m)")
    return None


def geometric_h(states: Sequence[RiderStates], params: EucParams) -> float:
    """Median distance of the rider CoG G from the ankle hinge A = C - l0 z_E over the valid samples [m]."""
    vals = []
    for st in states:
        d = np.linalg.norm(st.G - _hinge(st, params.l0), axis=1)
        vals.append(d[np.asarray(st.valid, bool) & np.isfinite(d)])
    v = np.concatenate(vals) if vals else np.zeros(0)
    return float(np.median(v)) if v.size else float("nan")


def _implausibility(candidate: Candidate, theta) -> float:
    """Size of a candidate's reported-scale parameters in units of their typical magnitude."""
    th = np.asarray(theta, float)
    scales = np.array([q.scale for q in candidate.params], float)
    keep = np.array([q.reported for q in candidate.params], bool)
    if hasattr(candidate, "PERIOD_STARTS"):      # time_varying_h: amplitude of (a_sin, a_cos)
        return float(np.hypot(th[0], th[1]) / scales[0])
    return float(np.sqrt(np.sum((th[keep] / scales[keep]) ** 2))) if keep.any() else 0.0


def paired_block_test(base: HeldOut, cand: HeldOut) -> float:
    """One-sided p-value that the candidate's held-out squared residual is smaller than the base's.

    Samples within a block (~1 s) are correlated by the derivative filter, so blocks are the units:
    per block the log ratio of the mean squared residuals, tested with a one-sided t-test for a mean
    above 0. The log ratio weighs every block alike, so a few loud blocks cannot dominate, and is
    symmetric under exchange of the two models.
    """
    ub = np.unique(base.block)
    mb = np.array([np.mean(base.residual[base.block == b] ** 2) for b in ub])
    mc = np.array([np.mean(cand.residual[cand.block == b] ** 2) if np.any(cand.block == b) else np.nan for b in ub])
    ok = np.isfinite(mc) & (mb > 0) & (mc > 0)
    d = np.log(mb[ok] / mc[ok])
    if d.size < 3 or np.allclose(d, 0):
        return 1.0
    return float(stats.ttest_1samp(d, 0.0, alternative="greater").pvalue)


def _block_log_ratios(base: HeldOut, cands: Sequence[HeldOut]) -> np.ndarray:
    """Per candidate and block of ``base``: log of the base's over the candidate's held-out mean square
    (NaN where the candidate has no sample of that block or a mean square is 0)."""
    ub, inv = np.unique(base.block, return_inverse=True)
    mb = np.bincount(inv, base.residual ** 2, ub.size) / np.maximum(np.bincount(inv, None, ub.size), 1)
    D = np.full((len(cands), ub.size), np.nan)
    for j, c in enumerate(cands):
        pos = np.searchsorted(ub, c.block)
        inside = (pos < ub.size) & (ub[np.minimum(pos, ub.size - 1)] == c.block)
        cnt = np.bincount(pos[inside], None, ub.size)
        mc = np.bincount(pos[inside], c.residual[inside] ** 2, ub.size) / np.maximum(cnt, 1)
        ok = (cnt > 0) & (mb > 0) & (mc > 0)
        D[j, ok] = np.log(mb[ok] / mc[ok])
    return D


def max_t_adjusted(base: HeldOut, cands: Sequence[HeldOut], n_flips: int = MAX_T_FLIPS, seed: int = 0) -> np.ndarray:
    """Family-wise adjusted one-sided p-values of the candidates of one selection step (max-T, sign flips).

    Per block the log ratio of the held-out mean squares (as :func:`paired_block_test`); per candidate the
    t statistic of their mean. Under the null hypothesis (no candidate explains anything) the blocks' log
    ratios are symmetric about 0 or shifted below it (a fitted candidate overfits its training data), and
    blocks are independent units: flipping the signs of whole blocks, the same flips for every candidate,
    draws from the joint null distribution of the statistics, so the correlation between candidates (the
    twins of the library fit nearly the same signature) is kept. The adjusted p of a candidate is the
    fraction of flips whose largest statistic over all candidates reaches its own (Westfall and Young's
    single-step max-T): the family-wise error is at most alpha, like Bonferroni's, but Bonferroni's
    alpha / (number of candidates) holds under any dependence and so is conservative for correlated tests.
    Exact over all 2^blocks flips when they are at most ``n_flips``, otherwise ``n_flips`` random ones
    (fixed ``seed``, the identity included).
    """
    if not cands:
        return np.zeros(0)
    D = _block_log_ratios(base, cands)
    ok = np.isfinite(D)
    n = ok.sum(axis=1)
    D0 = np.where(ok, D, 0.0)
    nb = D.shape[1]
    if nb == 0:
        return np.ones(len(cands))
    ss = np.sum(D0 ** 2, axis=1)                      # invariant under sign flips
    nn = np.maximum(n, 2).astype(float)

    def t_of(mean):
        var = np.maximum(ss - nn * mean ** 2, 0.0) / (nn - 1)
        return mean / np.sqrt(np.maximum(var, 1e-300) / nn)

    t_obs = t_of(D0.sum(axis=1) / nn)
    exact = 2 ** nb <= n_flips
    total = 2 ** nb if exact else n_flips
    # the flips in chunks of ~2^21 signs: a 60-minute recording has ~6000 blocks, and all 2^15 flips at once
    # were 1.5 GB (memory that grows with the recording, and most of the step's time)
    chunk = max(1, (1 << 21) // nb)
    rng = None if exact else np.random.default_rng(seed)
    t_max = np.empty(total)
    for lo in range(0, total, chunk):
        hi = min(lo + chunk, total)
        if exact:
            S = 1.0 - 2.0 * ((np.arange(lo, hi)[:, None] >> np.arange(nb)[None, :]) & 1)
        else:
            S = 1.0 - 2.0 * rng.integers(0, 2, size=(hi - lo, nb), dtype=np.int8)
            if lo == 0:
                S[0] = 1.0                            # the identity
        T = t_of((S @ D0.T) / nn)                     # (flips, candidates)
        T[:, n < 3] = -np.inf
        t_max[lo:hi] = T.max(axis=1)
    t_max.sort()
    exceed = t_max.size - np.searchsorted(t_max, t_obs - 1e-12 * np.abs(t_obs), side="left")
    # (the random flips include the identity: exceed / flips is (1 + others) / (1 + other flips), a valid p)
    p = np.minimum(exceed / t_max.size, 1.0)
    p[(n < 3) | np.all(np.isclose(D0, 0.0), axis=1)] = 1.0
    return p


@dataclass
class CandidateResult:
    """One row of the candidate table."""

    effect: str
    detectable: bool
    visibility: float
    rmse_after_nm: float
    p_value: float
    parameters: dict
    h_m: float
    inadmissible: str | None = None
    p_adjusted: float | None = None

    def to_dict(self) -> dict:
        """JSON row."""
        d = {"effect": self.effect, "rmse_after_nm": self.rmse_after_nm, "p_value": self.p_value,
             "p_adjusted": self.p_adjusted,
             "detectable": self.detectable, "visibility": self.visibility, "effect_parameters": self.parameters,
             "h_m": self.h_m}
        if self.inadmissible:
            d["inadmissible"] = self.inadmissible
        return d


@dataclass
class ResidualResult:
    """Outcome of :func:`analyze`."""

    h_base: float
    rmse_train_base: float
    rmse_before: float
    rmse_after: float
    effect: str
    effect_parameters: dict
    h_after: float
    final_x: np.ndarray
    selected: list[str]
    candidates: list[CandidateResult]
    steps: list[dict]
    alpha: float
    min_gain: float
    folds: int
    fold_kind: str
    base_heldout: HeldOut
    final_heldout: HeldOut
    final_model: Model
    geometry: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)
    h_range: tuple = (float("nan"), float("nan"))
    tied: list = field(default_factory=list)
    residual_significant: bool = False
    unexplained: bool = False
    discovered: list = field(default_factory=list)
    discovery: dict = field(default_factory=dict)
    noise_floor_nm: float = float("nan")
    residual_after_above_noise: bool | None = None
    floor_fit: FloorFit | None = None
    block_s: float = float("nan")

    def to_json(self) -> dict:
        """JSON per recording-format spec section 5 (plus the analysis settings and steps)."""
        rows = sorted(self.candidates, key=lambda c: (not c.detectable, c.rmse_after_nm))
        table = [c.to_dict() for c in rows]
        if not any(c["effect"] == "none" for c in table):
            table.append({"effect": "none", "rmse_after_nm": self.rmse_before, "p_value": None, "detectable": True,
                          "effect_parameters": {}, "h_m": self.h_base})
            table.sort(key=lambda c: (not c["detectable"], c["rmse_after_nm"]))
        ambiguous = sorted({a for s in self.steps for a in s.get("ambiguous_with", [])})
        return {"h_m": self.h_base, "rmse_before_nm": self.rmse_before, "effect": self.effect,
                "effect_parameters": self.effect_parameters, "rmse_after_nm": self.rmse_after,
                "ambiguous_with": ambiguous,
                "h_after_m": self.h_after, "candidates": table, "selection_steps": self.steps,
                "significance_level": self.alpha, "min_relative_gain": self.min_gain,
                "held_out": {"folds": self.folds, "kind": self.fold_kind, "block_s": self.block_s},
                "geometry": self.geometry,
                "undetectable": [c.effect for c in self.candidates if not c.detectable],
                "h_range_m": [float(self.h_range[0]), float(self.h_range[1])], "tied_models": self.tied,
                "residual_significant": bool(self.residual_significant), "unexplained": bool(self.unexplained),
                "discovered": self.discovered, "discovery": self.discovery,
                "noise_floor_nm": None if not math.isfinite(self.noise_floor_nm) else self.noise_floor_nm,
                "residual_after_above_noise": self.residual_after_above_noise,
                "analysis_warnings": list(self.warnings)}


def analyze(states: Sequence[RiderStates], params: EucParams, *, candidates: Sequence[Candidate] | None = None,
            alpha: float = DEFAULT_ALPHA, min_gain: float = DEFAULT_MIN_GAIN, max_effects: int = 3,
            n_folds: int | None = None, use_geometry: bool = True, discover: bool = True,
            noise_floor_of: Callable[[Model, np.ndarray], float] | None = None,
            analysis_rate_hz: float | None = ANALYSIS_RATE_HZ,
            progress: Callable[[str], None] | None = None) -> ResidualResult:
    """Trace the residual M_d1 - M_d2 of ``states`` to the candidate effects (greedy forward selection).

    Parameters
    ----------
    states : sequence of RiderStates
        Reconstructed recordings (phi about the hinge for the time-offset candidate).
    params : EucParams
        Nominal parameters (``h`` is identified).
    candidates : sequence of Candidate, optional
        The library (default: all of :data:`~euc_ros.core.model.effects.LIBRARY`).
    alpha : float
        Family-wise significance level of each selection step (max-T over the candidates, :func:`max_t_adjusted`).
    min_gain : float
        Minimum relative cut of the held-out RMSE for a selection.
    use_geometry : bool
        Measure the floor from the wheel's contact path: a floor tilted or uneven in the mocap frame goes
        into the model as geometry; a flat one may measure the rolling radius.
    discover : bool
        After the named effects, look for structure left in the residual (:mod:`.discovery`).
    analysis_rate_hz : float or None
        Work on a sub-sample at about this rate (:func:`decimation_step`); None: every sample.
    noise_floor_of : callable, optional
        ``(model, x) -> RMS [N m]``: the residual's noise floor for a fitted model (the recordings' pose
        noise propagated, :func:`euc_ros.core.residual.noise.noise_floor`); without it the significance
        of the residual rests on the held-out test of the discovery step alone.
    """
    say = progress or (lambda _m: None)
    candidates = list(candidates) if candidates is not None else make_candidates()
    # geometry first: the contact path measures the floor (plane, smooth deviation, scatter)
    floor = floor_from_states(states, params.R) if use_geometry else None
    recs = prepare(states, params, floor=floor, analysis_rate_hz=analysis_rate_hz)
    h_geo = geometric_h(states, params)
    h0 = fit_base_h(recs)
    base_fit = fit_model(Model(), recs, h0)
    # blocks of the paired test and guard bands of the folds from the residual's measured autocorrelation
    st0 = states[0]
    window_s = st0.window * st0.dt if st0.window and np.isfinite(st0.dt) else DEFAULT_BLOCK_S
    block_s = residual_block_length(recs, [Model().residual(r, base_fit.x)[0] for r in recs],
                                    min_s=MIN_BLOCK_WINDOWS * window_s, trend_s=TREND_WINDOWS * window_s)
    recs = with_blocks(recs, block_s)
    n_segments = n_folds if n_folds else max(2, math.ceil(MIN_FOLDS / len(recs)))
    folds = folds_of(recs, n_segments, guard_s=max(window_s, 0.5 * block_s))
    say(f"held-out: {len(folds)} folds ({n_segments} segments per run), blocks of {block_s:.2f} s")
    say(f"base model: h = {base_fit.h:.3f} m, RMSE {base_fit.rmse:.3f} N m (training)")

    visible = {c.name: detectability(c, recs, base_fit.h) for c in candidates}
    detectable = [c for c in candidates if visible[c.name] > DETECTABILITY_TOL]
    for c in candidates:
        if c not in detectable:
            say(f"{c.name}: undetectable (its generalized force lies in span(b_d, b_h))")

    current = Model()
    current_ho = held_out(current, recs, h0, folds, start=base_fit.x)
    base_ho = current_ho
    current_x = base_fit.x
    rows: dict[str, CandidateResult] = {}
    steps = []
    warnings: list[str] = []
    remaining = list(detectable)
    last_trials = None      # (model, trials) of the last selection step: the named alternatives to discovery
    if floor is not None and not floor.flat:
        # a floor tilted or uneven in the mocap frame (level-calibrated lab): known from geometry, in the
        # model before any dynamic candidate; the dynamic ground_slope (a mocap frame tilted against
        # gravity) then has nothing left to explain on this floor
        geo = FloorGeometry(math.degrees(math.atan(floor.plane[1])), math.degrees(math.atan(floor.plane[2])))
        geo_model = Model([geo])
        geo_fit = fit_model(geo_model, recs, h0)
        geo_ho = held_out(geo_model, recs, h0, folds, start=geo_fit.x)
        say(f"geometry: floor slope {math.degrees(floor.slope_along_travel_rad):+.2f} deg along travel, deviation "
            f"{floor.deviation_m * 1e3:.1f} mm: in the model (held-out RMSE {current_ho.rmse:.3f} -> "
            f"{geo_ho.rmse:.3f} N m)")
        steps.append({"model": current.name, "rmse_nm": current_ho.rmse, "selected": "ground_slope",
                      "evidence": "geometry: floor measured from the wheel's contact path (level lab)",
                      "rmse_after_nm": geo_ho.rmse})
        rows["ground_slope"] = CandidateResult("ground_slope", True, 1.0, geo_ho.rmse, 0.0,
                                               geo_model.report(geo_fit.x), geo_fit.h)
        current, current_ho, current_x = geo_model, geo_ho, geo_fit.x
        remaining = [c for c in remaining if c.name != "ground_slope"]
    while remaining and len(current.effects) < max_effects:
        trials = []
        for c in remaining:
            model = Model(current.effects + [c])
            full = fit_model(model, recs, h0, fixed=current_x)
            ho = held_out(model, recs, h0, folds, start=full.x)
            p = paired_block_test(current_ho, ho)
            why = admissibility(model, full.x, h_geo)
            trials.append((c, model, ho, p, full, why))
            last_trials = (current, trials)
        # family-wise over this step's candidates: max-T over sign flips of whole blocks (the candidates' test
        # statistics are strongly correlated, so this asks less of each than Bonferroni's alpha / candidates)
        p_adj = dict(zip((t[0].name for t in trials), max_t_adjusted(current_ho, [t[2] for t in trials])))
        for c, model, ho, p, full, why in trials:
            say(f"  + {c.name}: held-out RMSE {ho.rmse:.3f} N m (p = {p:.2g}, adjusted {p_adj[c.name]:.2g})"
                + (f"; not admissible: {why}" if why else ""))
            if c.name not in rows:
                rows[c.name] = CandidateResult(c.name, True, visible[c.name], ho.rmse, p,
                                               model.report(full.x), full.h, why, p_adj[c.name])
        threshold = alpha
        passing = [t for t in trials if p_adj[t[0].name] < threshold and t[2].rmse <= (1 - min_gain) * current_ho.rmse]
        ok = [t for t in passing if t[5] is None]
        for t in passing:
            if t[5] is not None:
                warnings.append(f"{t[0].name} would cut the held-out RMSE {current_ho.rmse:.3f} -> {t[2].rmse:.3f} "
                                f"N m but is not admissible: {t[5]}")
        step = {"model": current.name, "rmse_nm": current_ho.rmse, "threshold_p": threshold,
                "correction": "max-T over the step's candidates (sign flips of whole blocks)",
                "tried": [{"effect": t[0].name, "rmse_after_nm": t[2].rmse, "p_value": t[3],
                           "p_adjusted": p_adj[t[0].name], "h_m": t[4].h,
                           **({"inadmissible": t[5]} if t[5] else {})} for t in trials]}
        if not ok:
            step["selected"] = None
            steps.append(step)
            break
        best = min(ok, key=lambda t: t[2].rmse)
        # candidates the held-out data cannot tell apart from the best one (not significantly worse)
        tied = [t for t in ok if t is best or paired_block_test(t[2], best[2]) >= AMBIGUITY_ALPHA]
        if TIE_BREAK == "prior":
            # among those, prefer the explanation that needs the least implausible parameters (each parameter in
            # units of its typical magnitude, ParamInfo.scale): a prior-weighted tie-break, reported as such
            best = min(tied, key=lambda t: _implausibility(t[0], t[4].x[-t[0].n_params:] if t[0].n_params else []))
        step["selected"] = best[0].name
        # reported as tied: every admissible candidate the held-out data cannot tell from the selected one,
        # also those that did not pass the (family-wise) test against the current model on their own
        tied = [t for t in trials if t[5] is None and t[2].rmse <= (1 - min_gain) * current_ho.rmse
                and (t is best or paired_block_test(t[2], best[2]) >= AMBIGUITY_ALPHA)]
        ambiguous = [t[0].name for t in tied if t is not best]
        step["ambiguous_with"] = ambiguous
        step["tied"] = [{"effect": t[0].name, "h_m": t[4].h, "rmse_after_nm": t[2].rmse,
                         "effect_parameters": t[1].report(t[4].x)} for t in tied]
        steps.append(step)
        say(f"selected {best[0].name}: held-out RMSE {current_ho.rmse:.3f} -> {best[2].rmse:.3f} N m")
        current, current_ho, current_x = best[1], best[2], best[4].x
        remaining = [c for c in remaining if c is not best[0]]
    for c in candidates:
        if c not in detectable:
            rows[c.name] = CandidateResult(c.name, False, visible[c.name], base_ho.rmse, 1.0, {}, base_fit.h)
    # geometry: the contact path measures the floor; only a flat floor measures the rolling radius, which
    # the residual cannot separate from h (quasi-static riding): a significant offset of a flat floor is a
    # wheel_radius_error found by geometry; a sloped or uneven floor is reported, never read as a radius
    r_meas, r_significant, r_reason = rolling_radius_from_floor(floor, params.R, RADIUS_TOL_M)
    geometry = {"rolling_radius_measured_m": r_meas, "rolling_radius_std_m": floor.scatter_m if floor else float("nan"),
                "samples": floor.samples if floor else 0, "rolling_radius_nominal_m": float(params.R),
                "rolling_radius_reason": r_reason if use_geometry else "geometry not used",
                "floor": floor.as_dict() if floor else None, "used": False}
    if floor is not None and not floor.flat:
        say(f"geometry: {r_reason}")
    if (np.isfinite(r_meas) and r_significant
            and "wheel_radius_error" not in [c.name for c in current.effects]
            and any(c.name == "wheel_radius_error" for c in candidates)):
        geo_model = Model(current.effects + [_MeasuredWheelRadius(r_meas - params.R)])
        geo_fit = fit_model(geo_model, recs, h0, fixed=current_x)
        geo_ho = held_out(geo_model, recs, h0, folds, start=geo_fit.x)
        say(f"geometry: rolling radius {r_meas:.4f} m measured against {params.R:.4f} m nominal: "
            f"wheel_radius_error by geometry (held-out RMSE {current_ho.rmse:.3f} -> {geo_ho.rmse:.3f} N m)")
        steps.append({"model": current.name, "rmse_nm": current_ho.rmse, "selected": "wheel_radius_error",
                      "evidence": "geometry: wheel-centre height over the floor", "rmse_after_nm": geo_ho.rmse})
        geometry["used"] = True
        current, current_ho, current_x = geo_model, geo_ho, geo_fit.x
    # what is left: structure above the noise floor? (discovery: held-out, consistent across runs)
    disc_info: dict = {"run": False}
    discovered_rows: list[dict] = []
    p_disc = 1.0
    disc_alt: dict = {}
    dynamic_named = [c for c in current.effects if not getattr(c, "geometric", False)]
    if discover and dynamic_named:
        # a named effect is dropped for the discovered alternative (from the model without the named dynamic
        # effects) when that is significantly better (the same paired test at alpha) by the minimum gain. Without
        # the gain, a tilted mocap frame's true ground_slope (0.342 N m) lost to one discovered term, a force
        # cos(psi) at the rider CoG (0.341 N m, p = 0.002): the basis mimics library effects (speed at the
        # contact is viscous friction), so a near-equal fit is a tie, not a better explanation. A tie (the
        # named not significantly better either) is reported: the alternative is listed with the h it implies.
        root = Model([c for c in current.effects if getattr(c, "geometric", False)])
        root_fit = fit_model(root, recs, h0)
        root_ho = held_out(root, recs, h0, folds, start=root_fit.x)
        alt = discover_terms(root, root_fit.x, recs, folds, h0, root_ho, h_geo)
        sel = alt["info"].pop("selection_heldout", None)
        if sel is not None and sel.residual.shape == current_ho.residual.shape:
            p_alt = paired_block_test(current_ho, sel)
            disc_alt = {"rmse_after_nm": sel.rmse, "p_value_against_named": p_alt,
                        "fitted_rmse_after_nm": alt["heldout"].rmse if alt.get("heldout") is not None else None,
                        "terms": ([r["formula"] for r in alt["model"].effects[-1].describe(
                            alt["x"][-alt["model"].effects[-1].n_params:])] if alt.get("model") is not None else []),
                        "linearised_at_h_m": alt["info"].get("linearised_at_h_m"),
                        "linearisations_tried_h_m": alt["info"].get("linearisations_tried_h_m")}
            if p_alt < alpha and sel.rmse <= (1 - min_gain) * current_ho.rmse:
                warnings.append(f"named {current.name} not reported: a discovered combination explains "
                                f"significantly more (held-out {current_ho.rmse:.3f} -> {sel.rmse:.3f} N m, p = {p_alt:.2g})")
                steps.append({"model": current.name, "rmse_nm": current_ho.rmse, "selected": None,
                              "dropped_for_discovery": current.name, "p_value": p_alt})
                current, current_ho, current_x = root, root_ho, root_fit.x
            elif alt.get("model") is not None and paired_block_test(sel, current_ho) >= AMBIGUITY_ALPHA:
                # statistically tied: the named effect is kept (the physical hypothesis of the library) and the
                # discovered alternative is listed with the h it implies
                terms = disc_alt["terms"]
                label = "discovered: " + "; ".join(terms)
                h_alt = float(alt["x"][0])
                last = next((st for st in reversed(steps) if st.get("selected")), None)
                if last is not None:
                    last.setdefault("tied", []).append({"effect": label, "h_m": h_alt, "rmse_after_nm": sel.rmse,
                                                        "effect_parameters": {}})
                    last["ambiguous_with"] = list(last.get("ambiguous_with", [])) + [label]
                disc_alt["tied_with_named"] = True
                warnings.append(f"named {current.name} is statistically tied with discovered terms ({'; '.join(terms)}: "
                                f"held-out {current_ho.rmse:.3f} against {sel.rmse:.3f} N m, h {h_alt:.3f} m): the "
                                f"residual cannot tell them apart; both are listed")
    named_model, named_ho, named_x = current, current_ho, current_x
    if discover:
        say("discovery: sparse basis forces on what the named effects leave")
        disc = discover_terms(current, current_x, recs, folds, h0, current_ho, h_geo)
        disc_info = disc.pop("info")
        disc_info["alternative_to_named"] = disc_alt
        if disc.get("model") is not None:
            sel = disc_info.pop("selection_heldout", None)
            p_disc = paired_block_test(current_ho, sel if sel is not None else disc["heldout"])
            gain_ok = disc["heldout"].rmse <= (1 - min_gain) * current_ho.rmse
            why = admissibility(disc["model"], disc["x"], h_geo)
            disc_info.update({"p_value": p_disc, "rmse_after_nm": disc["heldout"].rmse, "threshold_p": alpha,
                              "inadmissible": why})
            d_eff = disc["model"].effects[-1]
            rows_found = d_eff.describe(disc["x"][-d_eff.n_params:])
            say(f"discovery: {'; '.join(r['formula'] for r in rows_found)}: held-out RMSE {current_ho.rmse:.3f} -> "
                f"{disc['heldout'].rmse:.3f} N m (p = {p_disc:.2g})")
            named_equal = None
            if p_disc < alpha and gain_ok and last_trials is not None and last_trials[0] is current:
                # (the structure test stands even when the discovered model itself is not admissible)
                # the discovery showed structure at alpha (one test: the terms were chosen within the folds); a
                # named effect that cuts the residual as much (its own test at alpha now that structure is
                # shown, not Bonferroni over the library) and that the discovered terms do not beat
                # significantly is the physical explanation of it: reported instead of the terms
                sel_ho = sel if sel is not None else disc["heldout"]
                equal = []
                for c, model, ho, p, full, why_c in last_trials[1]:
                    if why_c is None and p < alpha and ho.rmse <= (1 - min_gain) * current_ho.rmse \
                            and ho.residual.shape == sel_ho.residual.shape:
                        p_better = paired_block_test(ho, sel_ho)
                        if p_better >= AMBIGUITY_ALPHA:
                            equal.append((c, model, ho, p, full, p_better))
                if equal:
                    named_equal = min(equal, key=lambda t: t[2].rmse)
                    best_ho = named_equal[2]
                    # the named effects the data cannot tell apart from the best one
                    equal = [t for t in equal if t is named_equal or paired_block_test(t[2], best_ho) >= AMBIGUITY_ALPHA]
            if named_equal is not None:
                c, model, ho, p, full, p_better = named_equal
                steps.append({"model": current.name, "rmse_nm": current_ho.rmse, "selected": c.name, "p_value": p,
                              "evidence": f"the discovery found structure (p = {p_disc:.2g}); {c.name} explains it as well "
                                          f"as the discovered terms (p = {p_better:.2g} that they explain more)",
                              "rmse_after_nm": ho.rmse, "discovered_alternative": [r["formula"] for r in rows_found],
                              "ambiguous_with": [t[0].name for t in equal if t[0] is not c],
                              "tied": [{"effect": t[0].name, "h_m": t[4].h, "rmse_after_nm": t[2].rmse,
                                        "effect_parameters": t[1].report(t[4].x)} for t in equal]})
                say(f"named instead of the discovered terms: {c.name} (held-out RMSE {ho.rmse:.3f} N m, terms "
                    f"{disc['heldout'].rmse:.3f} N m)")
                current, current_ho, current_x = model, ho, full.x
                named_model, named_ho, named_x = current, current_ho, current_x
                disc_info["named_instead"] = c.name
                p_disc = 1.0          # the structure is the named effect's: what is left is judged on its own
            elif p_disc < alpha and gain_ok and why is None:
                discovered_rows = rows_found
                for row in discovered_rows:
                    row["rmse_after_nm"] = disc["heldout"].rmse
                steps.append({"model": current.name, "rmse_nm": current_ho.rmse, "selected": "discovered",
                              "p_value": p_disc, "rmse_after_nm": disc["heldout"].rmse,
                              "terms": [r["formula"] for r in discovered_rows]})
                current, current_ho, current_x = disc["model"], disc["heldout"], disc["x"]
            elif why is not None and p_disc < alpha:
                warnings.append(f"discovered terms would cut the held-out RMSE but are not admissible: {why}")
    noise = float("nan")
    if noise_floor_of is not None:
        try:
            noise = float(noise_floor_of(named_model, named_x))
        except Exception as exc:  # noqa: BLE001 - a floor we cannot measure is reported, not fatal
            warnings.append(f"noise floor not measured: {exc}")
    above_noise = math.isfinite(noise) and named_ho.rmse > NOISE_FLOOR_FACTOR * noise
    residual_significant = bool(p_disc < alpha or above_noise)
    still_above = math.isfinite(noise) and current_ho.rmse > NOISE_FLOOR_FACTOR * noise
    # explained when the discovered terms were accepted (their formula is the explanation offered); what
    # they leave above the noise floor is reported as residual_after_above_noise
    unexplained = bool(residual_significant and not discovered_rows)
    final_fit = fit_model(current, recs, h0, fixed=current_x) if current.effects else base_fit
    # h of every model the data cannot tell apart from the selected one
    tied = [t for s_ in steps for t in s_.get("tied", []) if s_.get("selected")]
    hs = [final_fit.h] + [t["h_m"] for t in tied]
    h_range = (float(min(hs)), float(max(hs)))
    if h_range[1] - h_range[0] > 0.01:
        warnings.append(f"tied models imply h from {h_range[0]:.3f} to {h_range[1]:.3f} m: h is not determined "
                        f"better than that by these recordings")
    effect = current.name
    if discovered_rows:
        effect = "+".join([c.name for c in current.effects if c.name != "discovered"] + ["discovered"])
    if unexplained and not discovered_rows:
        effect = "+".join([c.name for c in current.effects] + ["unexplained"])
    return ResidualResult(
        h_base=base_fit.h, rmse_train_base=base_fit.rmse, rmse_before=base_ho.rmse, rmse_after=current_ho.rmse,
        effect=effect, effect_parameters=current.report(final_fit.x), h_after=final_fit.h,
        final_x=final_fit.x, selected=[c.name for c in current.effects], candidates=list(rows.values()),
        steps=steps, alpha=alpha, min_gain=min_gain, folds=len(folds),
        fold_kind=f"segments within runs ({n_segments} per run, across {len(recs)} run(s)), blocks {block_s:.2f} s",
        block_s=block_s,
        base_heldout=base_ho, final_heldout=current_ho, final_model=current, geometry=geometry, warnings=warnings,
        h_range=h_range, tied=tied, residual_significant=residual_significant, unexplained=unexplained,
        discovered=discovered_rows, discovery=disc_info, noise_floor_nm=noise, floor_fit=floor,
        residual_after_above_noise=bool(still_above) if math.isfinite(noise) else None)


def force_map(model: Model, recs: Sequence[Recording], x: np.ndarray) -> list[np.ndarray]:
    """Per recording, the change of the residual per unit extra generalized force along x, gamma and phi
    (n, 3): the residual is linear in an extra force (``-R m11 (w . dQ) / D``), so three evaluations give
    the sensitivity of any force."""
    out = []
    for r in recs:
        n = r.ctx.t.shape[0]
        r0 = model.residual(r, x)[0]
        cols = []
        for j in range(3):
            e = np.zeros((n, 3))
            e[:, j] = 1.0
            cols.append(model.residual(r, x, e)[0] - r0)
        out.append(np.stack(cols, axis=1))
    return out


#: Most re-linearisations of the discovery around the h its terms imply (Gauss-Newton on the joint fit).
DISCOVERY_RELINEARISE = 3
#: A change of h [m] below which the discovery's linearisation is kept.
DISCOVERY_H_STEP_M = 1e-3


def discover_terms(current: Model, current_x: np.ndarray, recs: Sequence[Recording], folds, h0: float,
                   current_ho: HeldOut, h_geometric: float = float("nan")) -> dict:
    """The discovery step (:mod:`euc_ros.core.residual.discovery`): terms by best-subset selection within each
    fold's training data, their number by held-out error, then the chosen terms fitted jointly with h.

    The residual is linear in the terms' coefficients but not in h (the rider's inertia m h^2): the selection
    works on the residual linearised in h. When the effect to discover biased the current model's h far from
    the truth (a rope: 0.26-0.33 m against 0.61), that linearisation is poor and spare terms make up for the
    missing curvature in h. So the selection is also made linearised at the segments' geometric h
    (``h_geometric``, measured, the same the admissibility test uses) and then around the h the chosen terms
    imply (re-linearised at the h of the full fit, at most :data:`DISCOVERY_RELINEARISE` times while h moves
    by more than :data:`DISCOVERY_H_STEP_M`; h is refitted within each fold's training data at every
    linearisation but the first). The discovered models of the linearisations are compared by their held-out
    error after the full (non-linear) fit: a tie (paired block test at :data:`AMBIGUITY_ALPHA`) goes to the
    one with fewer terms. The first linearisation is the current model's own, so a ride where no other
    fits better held-out is unchanged.

    Returns ``{"model", "x", "heldout", "info"}`` (model None when no number of terms beats none).
    """
    from euc_ros.core.residual.discovery import DiscoveredEffect, all_terms, basis_sensitivities, best_subsets

    terms = all_terms()

    def with_h(r0, B, hc):
        # h is always in the model: the terms are chosen for, and fitted with, the h column projected out
        u = hc / max(np.linalg.norm(hc), 1e-300)
        return r0 - u * (u @ r0), B - np.outer(u, u @ B)

    def select(h_lin: float | None):
        # h_lin None: linearised at the current model's fit (in each fold its own h); else at h_lin, with h
        # refitted within each fold's training data (also without terms)
        x_lin = np.array(current_x, float)
        if h_lin is not None:
            x_lin[0] = h_lin
        L = force_map(current, recs, x_lin)
        B_all = [basis_sensitivities(r.ctx, Li) for r, Li in zip(recs, L)]
        base = [current.residual(r, x_lin) for r in recs]
        dh = 1e-3
        x1 = x_lin.copy()
        x1[0] += dh
        hcol = [(current.residual(r, x1)[0] - b[0]) / dh for r, b in zip(recs, base)]
        per_k: dict[int, list[np.ndarray]] = {}
        for fold, x_fold in zip(folds, current_ho.params):
            x_fold = np.array(x_fold, float)
            if h_lin is not None:
                x_fold[0] = h_lin
            fres = [current.residual(r, x_fold) if np.any(te) or np.any(tr) else None
                    for r, tr, te in zip(recs, fold.train, fold.test)]
            tr_rows = [np.asarray(tr, bool) & f[1] for tr, f in zip(fold.train, fres) if f is not None]
            idx = [i for i, f in enumerate(fres) if f is not None]
            r0 = np.concatenate([fres[i][0][rw] for i, rw in zip(idx, tr_rows)])
            B = np.concatenate([B_all[i][rw] for i, rw in zip(idx, tr_rows)])
            hc = np.concatenate([hcol[i][rw] for i, rw in zip(idx, tr_rows)])
            sets = best_subsets(*with_h(r0, B, hc))
            te_rows = [(i, np.asarray(fold.test[i], bool) & fres[i][1]) for i in idx if np.any(fold.test[i])]
            r0t = np.concatenate([fres[i][0][rw] for i, rw in te_rows])
            Bt = np.concatenate([B_all[i][rw] for i, rw in te_rows])
            hct = np.concatenate([hcol[i][rw] for i, rw in te_rows])
            if h_lin is None:
                per_k.setdefault(0, []).append(r0t)
            else:
                c0 = -(hc @ r0) / max(hc @ hc, 1e-300)
                per_k.setdefault(0, []).append(r0t + hct * c0)
            for k, cols in enumerate(sets, start=1):
                A = np.column_stack([hc, B[:, cols]])
                c, *_ = np.linalg.lstsq(A, -r0, rcond=None)
                per_k.setdefault(k, []).append(r0t + np.column_stack([hct, Bt[:, cols]]) @ c)
        complete = {k: np.concatenate(v) for k, v in per_k.items() if len(v) == len(folds)}
        rmse = {k: float(np.sqrt(np.mean(v ** 2))) for k, v in complete.items()}
        best_k = min(rmse, key=lambda k: (rmse[k], k))
        # the fewest terms within 2 % of the best held-out error (parsimony)
        best_k = min(k for k in rmse if rmse[k] <= 1.02 * rmse[best_k])
        if best_k == 0:
            return rmse, 0, complete, None, None, 0.0
        rows = [b[1] for b in base]
        r0 = np.concatenate([b[0][m] for b, m in zip(base, rows)])
        B = np.concatenate([Bi[m] for Bi, m in zip(B_all, rows)])
        hc = np.concatenate([h[m] for h, m in zip(hcol, rows)])
        cols = best_subsets(*with_h(r0, B, hc), best_k)[-1]
        c, *_ = np.linalg.lstsq(np.column_stack([hc, B[:, cols]]), -r0, rcond=None)
        return rmse, best_k, complete, cols, c[1:], float(c[0])

    def finalize(sel, h_lin):
        """The chosen terms fitted jointly with h and all parameters, and their held-out residual."""
        rmse, best_k, complete, cols, c, dhh = sel
        if best_k == 0:
            return None
        eff = DiscoveredEffect([terms[j] for j in cols], [max(abs(v), 1e-6) for v in c], start=c)
        model = Model(current.effects + [eff])
        start = np.concatenate([current_x, c])
        start[0] = float(np.clip(h_lin + dhh, *H_BOUNDS))
        full = fit_model(model, recs, h0, start=start)
        return {"model": model, "x": full.x, "heldout": held_out(model, recs, h0, folds, start=full.x),
                "sel": sel, "h_lin": h_lin, "k": best_k}

    def preferred(a, b):
        """The better of two discovered models by held-out error; a tie (the better not significantly better,
        paired block test at AMBIGUITY_ALPHA) goes to the one with fewer terms."""
        if a is None or b is None:
            return a if b is None else b
        lo, hi = (a, b) if a["heldout"].rmse <= b["heldout"].rmse else (b, a)
        if hi["k"] < lo["k"] and paired_block_test(hi["heldout"], lo["heldout"]) >= AMBIGUITY_ALPHA:
            return hi
        return lo

    h_cur = float(current_x[0])
    first = select(None)
    best = finalize(first, h_cur)
    h_path = [h_cur]
    if math.isfinite(h_geometric) and abs(h_geometric - h_cur) > DISCOVERY_H_STEP_M:
        h_g = float(np.clip(h_geometric, *H_BOUNDS))
        h_path.append(h_g)
        best = preferred(best, finalize(select(h_g), h_g))
    for _ in range(DISCOVERY_RELINEARISE):
        if best is None:
            break
        h_fit = float(np.clip(best["x"][0], *H_BOUNDS))
        if abs(h_fit - best["h_lin"]) < DISCOVERY_H_STEP_M:
            break
        h_path.append(h_fit)
        nxt = preferred(best, finalize(select(h_fit), h_fit))
        if nxt is best:
            break
        best = nxt
    sel = first if best is None else best["sel"]
    rmse, best_k, complete = sel[0], sel[1], sel[2]
    info = {"run": True, "heldout_rmse_by_terms": [rmse[k] for k in sorted(rmse)], "terms": best_k,
            "linearised_at_h_m": h_cur if best is None else best["h_lin"], "linearisations_tried_h_m": h_path}
    if best is None:
        return {"model": None, "x": None, "heldout": None, "info": info}
    # the held-out residual of the terms chosen within each fold (no leakage of the selection into the test)
    if complete[best_k].shape == current_ho.residual.shape:
        info["selection_heldout"] = HeldOut(current, complete[best_k], current_ho.block, [])
    return {"model": best["model"], "x": best["x"], "heldout": best["heldout"], "info": info}


def make_noise_floor(series_list: Sequence, states: Sequence[RiderStates], session, params: EucParams, *,
                     seed: int | None = None, analysis_rate_hz: float | None = ANALYSIS_RATE_HZ, share=None
                     ) -> Callable[[Model, np.ndarray], float]:
    """``noise_floor_of`` for :func:`analyze`: the recordings' own pose noise propagated through the
    reconstruction, the derivative filter and the given model (:func:`euc_ros.core.residual.noise.noise_floor`).

    The re-noised recordings are the first replicate of the h interval's SIMEX
    (:func:`euc_ros.core.identify.simex.first_replicate`, ``seed`` default its seed); with ``share`` (a
    :class:`~euc_ros.core.identify.simex.SimexShare` later given to ``eiv_bias``) that replicate's h is
    kept so SIMEX does not reconstruct it again.
    """
    from euc_ros.core.identify.simex import SIMEX_SEED, first_replicate
    from euc_ros.core.residual.noise import noise_floor

    floor = floor_from_states(states, params.R)
    st0 = states[0]
    window_s = st0.window * st0.dt if st0.window and np.isfinite(st0.dt) else None

    def of(model: Model, x: np.ndarray) -> float:
        def residual_of(st_list):
            recs = prepare(st_list, params, floor=floor, analysis_rate_hz=analysis_rate_hz)
            out = []
            for rec, st in zip(recs, st_list):
                r, m = model.residual(rec, x)
                full, mask = np.zeros(len(st.t)), np.zeros(len(st.t), bool)
                full[rec.index], mask[rec.index] = r, m
                out.append((full, mask))
            return out

        def floor_of(noisy):
            return noise_floor(series_list, states, session, residual_of, seed=0 if seed is None else seed,
                               window_s=window_s, polyorder=st0.polyorder, noisy=noisy)

        if window_s is not None:
            # the replicate's states go to the floor, then (dropped) to SIMEX's h: never beside its fit
            out = first_replicate(series_list, session, params, window_s=window_s, polyorder=st0.polyorder,
                                  phi_definition=st0.phi_definition, cog_method=getattr(st0, "cog_method", "segments"),
                                  seed=SIMEX_SEED if seed is None else seed, share=share, use=floor_of)
            if out is not None:
                return out
        return floor_of(None)

    return of
