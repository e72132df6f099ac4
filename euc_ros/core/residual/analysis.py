"""Close the loop: fit candidate effects to the residual M_d1 - M_d2, select by held-out error.

Steps (issue 5): identify h with the paper's 3-DoF model; compute r(t) = M_d1 - M_d2; check each
candidate's detectability (is its generalized force in span(b_d, b_h)?); fit each detectable
candidate's parameters jointly with h on training data and evaluate on held-out data (other runs,
or other segments of a single run); select by held-out error with a one-sided paired test over
blocks of the held-out residual (Bonferroni-corrected over the candidates) and a minimum relative
gain; repeat greedily with the selected effects in the model until nothing significant remains.

The residual of a model is ``M_d1 - M_d2 = R m11 (w . (M q_ddot + h - Q_g - dQ)) / D``
(:mod:`euc_ros.core.euc.torque`), so an extra force with ``w . dQ = 0`` cannot change it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
from scipy import optimize, stats

from euc_ros.core.euc.kinematics import DEFAULT_SG_POLYORDER, DEFAULT_WINDOW_S, RiderStates, to_moving_frame
from euc_ros.core.euc.model import EucParams, consistency_weights
from euc_ros.core.euc.torque import torques
from euc_ros.core.filters.derivatives import savgol_derivatives
from euc_ros.core.residual.candidates import Candidate, FloorGeometry, ModelContext, make_candidates
from euc_ros.core.residual.floor import FloorFit, fit_floor, rolling_radius_from_floor, slope_along_path

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
#: 360 Hz (filter bias, 3-D reconstruction); 3x leaves room for coloured noise the floor does not see.
NOISE_FLOOR_FACTOR = 3.0
#: A parameter closer than this fraction of its range to a bound is "on the bound".
AT_BOUND_FRACTION = 1e-3


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


def _hinge(st: RiderStates, l0: float) -> np.ndarray:
    """Ankle hinge A = C - l0 z_E (n, 3), z_E = Rz(psi) Rx(theta) Ry(gamma) e_z the EUC body's z axis."""
    gamma, psi, theta = st.gamma, st.psi, st.theta
    zb = np.stack([np.sin(gamma), -np.sin(theta) * np.cos(gamma), np.cos(theta) * np.cos(gamma)], axis=1)
    zw = np.stack([np.cos(psi) * zb[:, 0] - np.sin(psi) * zb[:, 1],
                   np.sin(psi) * zb[:, 0] + np.cos(psi) * zb[:, 1], zb[:, 2]], axis=1)
    return st.C - l0 * zw


def _phi_shift_fn(st: RiderStates, params: EucParams, window: int, polyorder: int, valid: np.ndarray
                  ) -> Callable[[float], tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Build dt -> change of (phi, phi_dot, phi_ddot) when the rider CoG G is shifted by dt in time."""
    t = st.t
    psi, theta = st.psi, st.theta
    A = _hinge(st, params.l0)

    def phi_of(G):
        r = to_moving_frame(G - A, psi, theta)
        return np.arctan2(r[:, 0], r[:, 2])

    phi0 = phi_of(st.G)

    def shift(dt: float):
        Gs = np.stack([np.interp(t + dt, t, st.G[:, k], left=np.nan, right=np.nan) for k in range(3)], axis=1)
        d = phi_of(Gs) - phi0
        der = savgol_derivatives(t, d, window=window, polyorder=polyorder, frame=st.frame)
        return der.y[valid], der.y_dot[valid], der.y_ddot[valid]

    return shift


def prepare(states: Sequence[RiderStates], params: EucParams, *, block_s: float = DEFAULT_BLOCK_S,
            floor: FloorFit | None = None) -> list[Recording]:
    """Turn reconstructed recordings into analysis inputs (valid samples, yaw rate, time-shift hook).

    With a ``floor`` that is not flat, each context also carries the floor's slope along travel under
    the wheel (``extras['floor_a']``) and the wheel centre's vertical acceleration (``extras['c_zdd']``,
    the states' derivative filter) for :class:`~euc_ros.core.residual.candidates.FloorGeometry`.
    """
    out = []
    for st in states:
        window = st.window if st.window and st.window % 2 == 1 else 9
        valid = np.asarray(st.valid, bool).copy()   # already half a window inside each stretch
        dpsi = savgol_derivatives(st.t, np.unwrap(st.psi), window=window, polyorder=st.polyorder, frame=st.frame)
        valid &= np.isfinite(dpsi.y_dot) & np.isfinite(st.theta)
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
        m1, m2 = self.torques(ctx)
        # M_d1 - M_d2 = R m11 (x_ddot - x_ddot*): compare models on the acceleration mismatch scaled by the
        # NOMINAL R m11, so a parameter change (R, m) cannot shrink the residual by rescaling the equations.
        # For the base model and every effect that keeps R and m this is exactly M_d1 - M_d2.
        p_mod, p_nom = ctx.p(), rec.ctx.params
        ratio = (p_nom.R * _m11(p_nom)) / (np.asarray(p_mod.R, float) * _m11(p_mod))
        r = (m1 - m2) * ratio
        mask &= np.isfinite(r)
        return np.where(mask, r, 0.0), mask

    @staticmethod
    def torques(ctx: ModelContext) -> tuple[np.ndarray, np.ndarray]:
        """M_d1, M_d2 of a prepared context (eqs (9)-(10) with the context's extensions)."""
        return torques(ctx.gamma, ctx.phi, ctx.gamma_dot, ctx.phi_dot, ctx.x_ddot, ctx.gamma_ddot, ctx.phi_ddot,
                       ctx.p(), extra_Q=ctx.extra_Q)

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
                                         x_scale=model.scales(), method="trf", max_nfev=200 * len(x0))
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


def fit_base_h(recs: Sequence[Recording], h_grid=np.linspace(0.1, 1.2, 111)) -> float:
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
    from euc_ros.core.euc.model import bias_terms, gravity_forces, mass_matrix

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
def folds_of(recs: Sequence[Recording], n_folds: int = 4) -> list[tuple[list[Recording], list[Recording]]]:
    """Train/test splits: leave-one-run-out over runs (at most ``n_folds`` groups), or contiguous
    segments of a single run."""
    if len(recs) >= 2:
        groups = np.array_split(np.arange(len(recs)), min(n_folds, len(recs)))
        return [([recs[i] for i in range(len(recs)) if i not in g], [recs[i] for i in g]) for g in groups]
    rec = recs[0]
    n = rec.ctx.t.shape[0]
    edges = np.linspace(0, n, n_folds + 1).astype(int)
    parts = [_subset(rec, slice(edges[k], edges[k + 1]), f"{rec.name}[{k}]") for k in range(n_folds)]
    return [([p for j, p in enumerate(parts) if j != k], [parts[k]]) for k in range(n_folds)]


def _subset(rec: Recording, sl: slice, name: str) -> Recording:
    c = rec.ctx
    sub = ModelContext(**{k: getattr(c, k)[sl] for k in (
        "t", "x_dot", "x_ddot", "gamma", "gamma_dot", "gamma_ddot", "phi", "phi_dot", "phi_ddot", "psi",
        "psi_dot", "theta")}, params=c.params)
    shift = c.extras.get("phi_shift")
    if shift is not None:
        sub.extras["phi_shift"] = lambda dt, f=shift: tuple(a[sl] for a in f(dt))
    for k, v in c.extras.items():
        if isinstance(v, np.ndarray) and v.shape[:1] == c.t.shape:
            sub.extras[k] = v[sl]
    return Recording(name, sub, rec.block[sl])


@dataclass
class HeldOut:
    """Held-out residuals of a model over all folds, with their blocks."""

    model: Model
    residual: np.ndarray
    block: np.ndarray
    params: list[np.ndarray]

    @property
    def rmse(self) -> float:
        """Held-out RMSE [N m]."""
        return float(np.sqrt(np.mean(self.residual ** 2))) if self.residual.size else float("nan")


def held_out(model: Model, recs: Sequence[Recording], h0: float, folds=None,
             fixed: np.ndarray | None = None, start: np.ndarray | None = None) -> HeldOut:
    """Fit on each fold's training part, collect the residual on its held-out part.

    ``start`` (the fit on all data) seeds every fold's fit; without it each fold tries every start.
    """
    folds = folds or folds_of(recs)
    res, blocks, params = [], [], []
    offset = 0
    for train, test in folds:
        fit = fit_model(model, train, h0, fixed, start=start)
        params.append(fit.x)
        for r in test:
            rr, mask = model.residual(r, fit.x)
            res.append(rr[mask])
            blocks.append(r.block[mask] + offset)
            offset += int(r.block.max()) + 1 if r.block.size else 0
    return HeldOut(model, np.concatenate(res), np.concatenate(blocks), params)


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

    def to_dict(self) -> dict:
        """JSON row."""
        d = {"effect": self.effect, "rmse_after_nm": self.rmse_after_nm, "p_value": self.p_value,
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
                "held_out": {"folds": self.folds, "kind": self.fold_kind},
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
            n_folds: int = 3, use_geometry: bool = True, discover: bool = True,
            noise_floor_of: Callable[[Model, np.ndarray], float] | None = None,
            progress: Callable[[str], None] | None = None) -> ResidualResult:
    """Trace the residual M_d1 - M_d2 of ``states`` to the candidate effects (greedy forward selection).

    Parameters
    ----------
    states : sequence of RiderStates
        Reconstructed recordings (phi about the hinge for the time-offset candidate).
    params : EucParams
        Nominal parameters (``h`` is identified).
    candidates : sequence of Candidate, optional
        The library (default: all of :data:`~euc_ros.core.residual.candidates.LIBRARY`).
    alpha : float
        Family-wise significance level of each selection step (Bonferroni over the candidates).
    min_gain : float
        Minimum relative cut of the held-out RMSE for a selection.
    use_geometry : bool
        Measure the floor from the wheel's contact path: a floor tilted or uneven in the mocap frame goes
        into the model as geometry; a flat one may measure the rolling radius.
    discover : bool
        After the named effects, look for structure left in the residual (:mod:`.discovery`).
    noise_floor_of : callable, optional
        ``(model, x) -> RMS [N m]``: the residual's noise floor for a fitted model (the recordings' pose
        noise propagated, :func:`euc_ros.core.residual.noise.noise_floor`); without it the significance
        of the residual rests on the held-out test of the discovery step alone.
    """
    say = progress or (lambda _m: None)
    candidates = list(candidates) if candidates is not None else make_candidates()
    # geometry first: the contact path measures the floor (plane, smooth deviation, scatter)
    floor = floor_from_states(states, params.R) if use_geometry else None
    recs = prepare(states, params, floor=floor)
    folds = folds_of(recs, n_folds)
    h_geo = geometric_h(states, params)
    h0 = fit_base_h(recs)
    base_fit = fit_model(Model(), recs, h0)
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
            say(f"  + {c.name}: held-out RMSE {ho.rmse:.3f} N m (p = {p:.2g})" + (f"; not admissible: {why}" if why
                                                                                else ""))
            if c.name not in rows:
                rows[c.name] = CandidateResult(c.name, True, visible[c.name], ho.rmse, p,
                                               model.report(full.x), full.h, why)
        threshold = alpha / max(len(remaining), 1)
        passing = [t for t in trials if t[3] < threshold and t[2].rmse <= (1 - min_gain) * current_ho.rmse]
        ok = [t for t in passing if t[5] is None]
        for t in passing:
            if t[5] is not None:
                warnings.append(f"{t[0].name} would cut the held-out RMSE {current_ho.rmse:.3f} -> {t[2].rmse:.3f} "
                                f"N m but is not admissible: {t[5]}")
        step = {"model": current.name, "rmse_nm": current_ho.rmse, "threshold_p": threshold,
                "tried": [{"effect": t[0].name, "rmse_after_nm": t[2].rmse, "p_value": t[3], "h_m": t[4].h,
                           **({"inadmissible": t[5]} if t[5] else {})} for t in trials]}
        if not ok:
            step["selected"] = None
            steps.append(step)
            break
        best = min(ok, key=lambda t: t[2].rmse)
        # candidates the held-out data cannot tell apart from the best one (not significantly worse)
        tied = [t for t in ok if t is best or paired_block_test(t[2], best[2]) >= AMBIGUITY_ALPHA]
        # among those, prefer the explanation that needs the least implausible parameters (each parameter in
        # units of its typical magnitude, ParamInfo.scale): a prior-weighted tie-break, reported as such
        best = min(tied, key=lambda t: _implausibility(t[0], t[4].x[-t[0].n_params:] if t[0].n_params else []))
        step["selected"] = best[0].name
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
        # a named effect is reported only when the discovered alternative (from the model without the named
        # dynamic effects) is not significantly better than it
        root = Model([c for c in current.effects if getattr(c, "geometric", False)])
        root_fit = fit_model(root, recs, h0)
        root_ho = held_out(root, recs, h0, folds, start=root_fit.x)
        alt = discover_terms(root, root_fit.x, recs, folds, h0, root_ho)
        sel = alt["info"].pop("selection_heldout", None)
        if sel is not None and sel.residual.shape == current_ho.residual.shape:
            p_alt = paired_block_test(current_ho, sel)
            disc_alt = {"rmse_after_nm": sel.rmse, "p_value_against_named": p_alt}
            if p_alt < alpha:
                warnings.append(f"named {current.name} not reported: a discovered combination explains "
                                f"significantly more (held-out {current_ho.rmse:.3f} -> {sel.rmse:.3f} N m, p = {p_alt:.2g})")
                steps.append({"model": current.name, "rmse_nm": current_ho.rmse, "selected": None,
                              "dropped_for_discovery": current.name, "p_value": p_alt})
                current, current_ho, current_x = root, root_ho, root_fit.x
    named_model, named_ho, named_x = current, current_ho, current_x
    if discover:
        say("discovery: sparse basis forces on what the named effects leave")
        disc = discover_terms(current, current_x, recs, folds, h0, current_ho)
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
            if p_disc < alpha and gain_ok and why is None:
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
        fold_kind="leave-runs-out" if len(recs) >= 2 else "segments of one run",
        base_heldout=base_ho, final_heldout=current_ho, final_model=current, geometry=geometry, warnings=warnings,
        h_range=h_range, tied=tied, residual_significant=residual_significant, unexplained=unexplained,
        discovered=discovered_rows, discovery=disc_info, noise_floor_nm=noise, floor_fit=floor,
        residual_after_above_noise=bool(still_above) if math.isfinite(noise) else None)


def discover_terms(current: Model, current_x: np.ndarray, recs: Sequence[Recording], folds, h0: float,
                   current_ho: HeldOut) -> dict:
    """The discovery step (:mod:`euc_ros.core.residual.discovery`): terms by forward selection within each
    fold's training data, their number by held-out error, then the chosen terms fitted jointly with h.

    Returns ``{"model", "x", "heldout", "info"}`` (model None when no number of terms beats none).
    """
    from euc_ros.core.residual.discovery import DiscoveredEffect, forward_select, sensitivities

    def res(rec, x, dQ):
        r, m = current.residual(rec, x, dQ)
        return np.where(m, r, 0.0)

    def h_column(recs_, x, r0, dh=1e-3):
        # d(residual)/dh by a forward difference from the residual r0 at x (sensitivities' r0)
        x1 = np.array(x, float)
        x1[0] += dh
        return (np.concatenate([res(r, x1, None) for r in recs_]) - r0) / dh

    def with_h(r0, B, hc):
        # h is always in the model: the terms are chosen for, and fitted with, the h column projected out
        u = hc / max(np.linalg.norm(hc), 1e-300)
        return r0 - u * (u @ r0), B - np.outer(u, u @ B)

    per_k: dict[int, list[np.ndarray]] = {}
    for (train, test), x_fold in zip(folds, current_ho.params):
        r0, B, terms = sensitivities(res, train, x_fold)
        hc = h_column(train, x_fold, r0)
        r0p, Bp = with_h(r0, B, hc)
        sets = forward_select(r0p, Bp)
        r0t, Bt, _ = sensitivities(res, test, x_fold)
        hct = h_column(test, x_fold, r0t)
        keep = np.concatenate([current.residual(r, x_fold)[1] for r in test])
        per_k.setdefault(0, []).append(r0t[keep])
        for k, cols in enumerate(sets, start=1):
            A = np.column_stack([hc, B[:, cols]])
            c, *_ = np.linalg.lstsq(A, -r0, rcond=None)
            per_k.setdefault(k, []).append((r0t + np.column_stack([hct, Bt[:, cols]]) @ c)[keep])
    complete = {k: np.concatenate(v) for k, v in per_k.items() if len(v) == len(folds)}
    rmse = {k: float(np.sqrt(np.mean(v ** 2))) for k, v in complete.items()}
    info = {"run": True, "heldout_rmse_by_terms": [rmse[k] for k in sorted(rmse)]}
    best_k = min(rmse, key=lambda k: (rmse[k], k))
    # the fewest terms within 2 % of the best held-out error (parsimony)
    best_k = min(k for k in rmse if rmse[k] <= 1.02 * rmse[best_k])
    info["terms"] = best_k
    if best_k == 0:
        return {"model": None, "x": None, "heldout": None, "info": info}
    # the held-out residual of the terms chosen within each fold (no leakage of the selection into the test)
    if complete[best_k].shape == current_ho.residual.shape:
        info["selection_heldout"] = HeldOut(current, complete[best_k], current_ho.block, [])
    r0, B, terms = sensitivities(res, recs, current_x)
    hc = h_column(recs, current_x, r0)
    cols = forward_select(*with_h(r0, B, hc), best_k)[-1]
    c, *_ = np.linalg.lstsq(np.column_stack([hc, B[:, cols]]), -r0, rcond=None)
    dh, c = float(c[0]), c[1:]
    scales = [max(abs(v), 1e-6) for v in c]
    eff = DiscoveredEffect([terms[j] for j in cols], scales, start=c)
    model = Model(current.effects + [eff])
    start = np.concatenate([current_x, c])
    start[0] = float(np.clip(current_x[0] + dh, *H_BOUNDS))
    full = fit_model(model, recs, h0, start=start)
    ho = held_out(model, recs, h0, folds, start=full.x)
    return {"model": model, "x": full.x, "heldout": ho, "info": info}


def make_noise_floor(series_list: Sequence, states: Sequence[RiderStates], session, params: EucParams, *,
                     seed: int = 0) -> Callable[[Model, np.ndarray], float]:
    """``noise_floor_of`` for :func:`analyze`: the recordings' own pose noise propagated through the
    reconstruction, the derivative filter and the given model (:func:`euc_ros.core.residual.noise.noise_floor`)."""
    from euc_ros.core.residual.noise import noise_floor

    floor = floor_from_states(states, params.R)
    st0 = states[0]
    window_s = st0.window * st0.dt if st0.window and np.isfinite(st0.dt) else None

    def of(model: Model, x: np.ndarray) -> float:
        def residual_of(st_list):
            recs = prepare(st_list, params, floor=floor)
            out = []
            for rec, st in zip(recs, st_list):
                r, m = model.residual(rec, x)
                full, mask = np.zeros(len(st.t)), np.zeros(len(st.t), bool)
                full[rec.index], mask[rec.index] = r, m
                out.append((full, mask))
            return out

        return noise_floor(series_list, states, session, residual_of, seed=seed, window_s=window_s,
                           polyorder=st0.polyorder)

    return of
