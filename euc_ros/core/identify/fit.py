"""Identification of the rider CoG height h (EUC paper, Section 4 and Fig. 8).

The driving torque is not measured, so h is the value that makes the two model expressions of the
driving torque agree best: it minimises ``RMSE(h) = sqrt(mean((M_d1 - M_d2)^2))`` over the valid
samples, for the 3-DoF model (eqs (9)-(10)) and for the reduced 2-DoF model (eq (13)).

Vectorization. With ``w = [R, 1, 1]`` (which annihilates both input directions, see
:mod:`euc_ros.core.model.torque`) the residual of one sample is

    e(h) = M_d1 - M_d2 = c N(h) / D(h),   c = R m11,
    N(h) = w . (M q_ddot + h_vec - Q_g - Q_extra) = a0 + a1 h + a2 h^2,
    D(h) = w . M[:, 0] = d0 + d1 h,

because h enters (6)-(8) at most quadratically (``m33 = J + m h^2``) and D linearly. The six
coefficients are computed once per sample, from the model functions themselves (at h = 0, 1, -1),
and the whole RMSE(h) grid then costs a few multiply-adds per sample and grid point, evaluated in
chunks. The optimum is refined with :func:`scipy.optimize.minimize_scalar` (bounded) between the
grid neighbours of the grid minimum.

Pooling over recordings means one RMSE over all their valid samples together.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np
from scipy.optimize import minimize_scalar

from euc_ros.core.errors import ConfigError, InputError
from euc_ros.core.model.terms import EucParams, bias_terms, gravity_forces, mass_matrix

#: Default grid of CoG heights [m] (0.1 to 1.2 m in 5 mm steps).
DEFAULT_H_GRID = np.linspace(0.1, 1.2, 221)
#: Model names: the paper's 3-DoF model and the reduced 2-DoF model of Section 3.2.
MODELS = ("3dof", "2dof")
#: Step [m] used for the sharpness of an RMSE(h) curve (relative RMSE increase at h* +- this).
SHARPNESS_STEP_M = 0.1


def model_params(params: EucParams, model: str) -> EucParams:
    """Parameters of ``model``: "3dof" as given, "2dof" with ``J0 = h0 = l0 = 0``.

    Parameters
    ----------
    params : EucParams
        The nominal parameters.
    model : {"3dof", "2dof"}
        The model.

    Returns
    -------
    EucParams

    Raises
    ------
    ConfigError
        ``model`` is not one of :data:`MODELS` (key ``model``).
    """
    if model == "3dof":
        return params
    if model == "2dof":
        return params.reduced()
    raise ConfigError(f"model must be one of {MODELS}, got {model!r}", key="model")


def _consistency(args: Sequence[np.ndarray], p: EucParams, extra_Q) -> tuple[np.ndarray, ...]:
    """Return ``(c, N, D)`` of the residual ``e = c N / D`` at the parameters ``p`` (see module doc)."""
    gamma, phi, gamma_dot, phi_dot, x_ddot, gamma_ddot, phi_ddot = (np.asarray(a, dtype=float) for a in args)
    zero = np.zeros_like(gamma)
    q = np.stack([zero, gamma, phi], -1)
    qd = np.stack([zero, gamma_dot, phi_dot], -1)
    qdd = np.stack([x_ddot, gamma_ddot, phi_ddot], -1)
    M = mass_matrix(q, p)
    r = np.einsum("...ij,...j->...i", M, qdd) + bias_terms(q, qd, p) - gravity_forces(q, p)
    if extra_Q is not None:
        r = r - np.asarray(extra_Q, dtype=float)
    R = np.asarray(p.R, dtype=float)
    N = R * r[..., 0] + r[..., 1] + r[..., 2]
    D = R * M[..., 0, 0] + M[..., 1, 0] + M[..., 2, 0]
    return R * M[..., 0, 0], N, D


#: Samples per block of :func:`residual_coefficients` (its temporaries are ~20 arrays of this size).
_COEF_BLOCK = 8192


def residual_coefficients(args: Sequence[np.ndarray], params: EucParams, model: str = "3dof",
                          extra_Q=None) -> np.ndarray:
    """Per-sample coefficients ``(c, a0, a1, a2, d0, d1)`` of ``e(h) = c (a0 + a1 h + a2 h^2) / (d0 + d1 h)``.

    Parameters
    ----------
    args : sequence of 7 arrays (n,)
        ``gamma, phi, gamma_dot, phi_dot, x_ddot, gamma_ddot, phi_ddot`` (see
        :meth:`~euc_ros.core.states.kinematics.RiderStates.torque_args`).
    params : EucParams
        Model parameters (``h`` ignored); fields may be arrays of shape (n,).
    model : {"3dof", "2dof"}
    extra_Q : array_like (n, 3), optional
        Extra generalized force independent of h [N, N m, N m].

    Returns
    -------
    ndarray (6, n)
        ``c`` [m], ``a0, a1, a2`` [N m, N, N/m] and ``d0, d1`` [kg m, kg].
    """
    p = model_params(params, model)
    n = int(np.shape(args[0])[0]) if np.ndim(args[0]) == 1 else 0
    scalar = all(np.ndim(v) == 0 for v in dataclasses.astuple(p))
    if n > _COEF_BLOCK and scalar:
        # per sample: block by block, so the mass matrices and forces of the whole recording never exist
        out = np.empty((6, n))
        for lo in range(0, n, _COEF_BLOCK):
            hi = min(n, lo + _COEF_BLOCK)
            out[:, lo:hi] = residual_coefficients([np.asarray(a, dtype=float)[lo:hi] for a in args], p, "3dof",
                                                  None if extra_Q is None else np.asarray(extra_Q, float)[lo:hi])
        return out
    c, n0, d0 = _consistency(args, p.with_h(0.0), extra_Q)
    _, n1, d1 = _consistency(args, p.with_h(1.0), extra_Q)
    _, nm, _ = _consistency(args, p.with_h(-1.0), extra_Q)
    a1 = 0.5 * (n1 - nm)
    a2 = 0.5 * (n1 + nm) - n0
    return np.stack(np.broadcast_arrays(c, n0, a1, a2, d0, d1 - d0))


def sse_grid(coef: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Sum of squared residuals for every h.

    One compiled pass over the samples: :func:`~euc_ros.core.identify.fit_compiled.sse_curve`.

    Parameters
    ----------
    coef : ndarray (6, n)
        Rows ``c, a0, a1, a2, d0, d1`` of :func:`residual_coefficients`.
    h : array_like (g,)
        CoG heights [m].

    Returns
    -------
    ndarray (g,)
        ``sum e(h)^2`` [N^2 m^2]; zeros without samples.
    """
    from euc_ros.core.identify.fit_compiled import sse_curve  # numba: on first use only

    h = np.ascontiguousarray(h, dtype=float).reshape(-1)
    if coef.shape[1] == 0:
        return np.zeros(h.size)
    return sse_curve(np.ascontiguousarray(coef, dtype=float), h)


def _as_list(states) -> list:
    return list(states) if isinstance(states, (list, tuple)) else [states]


def _valid_args(st, extra_Q) -> tuple[tuple[np.ndarray, ...], Any]:
    mask = np.asarray(st.valid, dtype=bool)
    args = st.torque_args(mask)
    if extra_Q is not None and not callable(extra_Q):
        extra_Q = np.asarray(extra_Q, dtype=float)
        if extra_Q.shape != (st.n, 3):
            raise InputError(f"extra_Q must have shape ({st.n}, 3), got {extra_Q.shape}", key="extra_Q")
        extra_Q = extra_Q[mask]
    return args, extra_Q


def _valid_coefficients(st, params: EucParams, model: str, extra_Q) -> np.ndarray:
    """:func:`residual_coefficients` of the valid samples of ``st`` (6, n_valid), in one compiled pass.

    The compiled pass over the recording is :func:`~euc_ros.core.identify.fit_compiled.consistency_coefficients`, so the
    valid samples' seven state arrays are never copied (56 bytes a sample beside the coefficients' 48). The same terms
    sorted by powers of h: equal to round-off (``test_fit_compiled``). Scalar parameters only.
    """
    from euc_ros.core.identify.fit_compiled import consistency_coefficients  # numba: on first use only

    mask = np.ascontiguousarray(st.valid, dtype=bool)
    if extra_Q is not None:
        extra_Q = np.asarray(extra_Q, dtype=float)
        if extra_Q.shape != (st.n, 3):
            raise InputError(f"extra_Q must have shape ({st.n}, 3), got {extra_Q.shape}", key="extra_Q")
    p = model_params(params, model)
    packed = np.array([p.m, p.J, p.m0, p.J0, p.mw, p.Jw, p.R, p.h0, p.l0, p.g], dtype=float)
    extra = np.zeros((0, 3)) if extra_Q is None else np.ascontiguousarray(extra_Q)
    args = [np.ascontiguousarray(a, dtype=float) for a in st.torque_args()]
    return consistency_coefficients(*args, mask, packed, extra)


def coefficients_for(states_list, params: EucParams, model: str, extra_Q) -> list[np.ndarray]:
    """Per recording, :func:`residual_coefficients` of its valid samples.

    Parameters
    ----------
    states_list : sequence of RiderStates
        The recordings' states.
    params : EucParams
        Model parameters (``h`` ignored).
    model : {"3dof", "2dof"}
    extra_Q : array_like (n, 3) or None, or a list or tuple of them
        Extra generalized force independent of h [N, N m, N m]: one for every recording, or one per recording.

    Returns
    -------
    list of ndarray (6, n_valid)
        Each recording's rows ``c, a0, a1, a2, d0, d1``; with scalar parameters and no callable force in one
        compiled pass over the recording (:func:`_valid_coefficients`).
    """
    extras = extra_Q if isinstance(extra_Q, (list, tuple)) else [extra_Q] * len(states_list)
    scalar = all(np.ndim(v) == 0 for v in dataclasses.astuple(model_params(params, model)))
    out = []
    for st, ex in zip(states_list, extras):
        if scalar and not callable(ex):
            out.append(_valid_coefficients(st, params, model, ex))
            continue
        args, ex = _valid_args(st, ex)
        out.append(residual_coefficients(args, params, model, ex))
    return out


def _sse_callable(st, params: EucParams, model: str, h_grid: np.ndarray, extra_Q: Callable) -> np.ndarray:
    """SSE over a grid when the extra force depends on h: ``extra_Q(states, h) -> (n, 3)``."""
    mask = np.asarray(st.valid, dtype=bool)
    args = st.torque_args(mask)
    p = model_params(params, model)
    sse = np.empty(h_grid.size)
    for k, h in enumerate(h_grid):
        ex = np.asarray(extra_Q(st, float(h)), dtype=float)[mask]
        c, N, D = _consistency(args, p.with_h(float(h)), ex)
        e = c * N / D
        sse[k] = float(np.dot(e, e))
    return sse


def rmse_curve(states, params: EucParams, h_grid=DEFAULT_H_GRID, model: str = "3dof", extra_Q=None) -> np.ndarray:
    """RMSE of ``M_d1 - M_d2`` over the valid samples for every CoG height in ``h_grid`` (Fig. 8).

    Parameters
    ----------
    states : RiderStates or sequence of RiderStates
        One recording, or several pooled (one RMSE over all their valid samples).
    params : EucParams
        Nominal parameters (``h`` is replaced by the grid values).
    h_grid : array_like (g,)
        CoG heights [m].
    model : {"3dof", "2dof"}
        Eqs (9)-(10) or the reduced eq (13).
    extra_Q : array_like (n, 3), list of them, or callable, optional
        Extra generalized force added to (5) (see :func:`~euc_ros.core.model.torque.torques`): one
        (n, 3) array per recording (a list when pooling), or ``extra_Q(states, h) -> (n, 3)`` when it
        depends on h.

    Returns
    -------
    ndarray (g,)
        RMSE [N m]; NaN if there is no valid sample.
    """
    h_grid = np.asarray(h_grid, dtype=float).reshape(-1)
    states_list = _as_list(states)
    model_params(params, model)
    if callable(extra_Q):
        sse = sum(_sse_callable(st, params, model, h_grid, extra_Q) for st in states_list)
        n = sum(int(np.count_nonzero(st.valid)) for st in states_list)
    else:
        coefs = coefficients_for(states_list, params, model, extra_Q)
        coef = np.concatenate(coefs, axis=1)
        sse, n = sse_grid(coef, h_grid), coef.shape[1]
    return np.sqrt(sse / n) if n else np.full(h_grid.size, np.nan)


@dataclass
class ModelFit:
    """Optimal h of one model on one recording (or pooled).

    Parameters
    ----------
    model : str
        "3dof" or "2dof".
    h_m : float
        Optimal CoG height [m] (NaN without data).
    rmse_nm : float
        RMSE of ``M_d1 - M_d2`` at ``h_m`` [N m].
    n_samples : int
        Valid samples used.
    rmse_curve_nm : ndarray (g,)
        RMSE over the grid [N m].
    at_bound : bool
        The grid minimum is at an end of the grid (the optimum may lie outside it).
    h_std_m : float
        Formal standard deviation of ``h_m`` [m] from the curvature of the sum of squares
        (``sigma^2 = 2 s^2 / SSE''(h)``, ``s^2 = SSE / (n - 1)``); it treats samples as independent,
        so it is optimistic for smoothed (correlated) data.
    sharpness : float
        Relative RMSE increase at ``h_m +- 0.1 m`` (mean of both sides): small for a flat curve.
    """

    model: str
    h_m: float
    rmse_nm: float
    n_samples: int
    rmse_curve_nm: np.ndarray
    at_bound: bool
    h_std_m: float
    sharpness: float

    def summary(self) -> dict[str, Any]:
        """JSON-ready scalars of the fit.

        Returns
        -------
        dict
            ``model``, ``h_m``, ``rmse_nm``, ``n_samples``, ``h_std_m``, ``sharpness``, ``at_bound`` (non-finite
            numbers None).
        """
        return {"model": self.model, "h_m": _f(self.h_m), "rmse_nm": _f(self.rmse_nm), "n_samples": self.n_samples,
                "h_std_m": _f(self.h_std_m), "sharpness": _f(self.sharpness), "at_bound": bool(self.at_bound)}


def _f(v: float) -> float | None:
    return None if not np.isfinite(v) else float(v)


def _fit(coef: np.ndarray, h_grid: np.ndarray, model: str, sse: np.ndarray | None = None) -> ModelFit:
    n = coef.shape[1]
    if sse is None:
        sse = sse_grid(coef, h_grid)
    if n == 0 or not np.any(np.isfinite(sse)):
        return ModelFit(model, np.nan, np.nan, n, np.full(h_grid.size, np.nan), False, np.nan, np.nan)
    curve = np.sqrt(sse / n)
    i = int(np.nanargmin(sse))
    lo, hi = h_grid[max(i - 1, 0)], h_grid[min(i + 1, h_grid.size - 1)]

    def f(h: float) -> float:
        return float(sse_grid(coef, np.array([h]))[0])

    if hi > lo:
        res = minimize_scalar(f, bounds=(lo, hi), method="bounded", options={"xatol": 1e-7})
        h_opt, sse_opt = (float(res.x), float(res.fun)) if res.fun <= sse[i] else (float(h_grid[i]), float(sse[i]))
    else:
        h_opt, sse_opt = float(h_grid[i]), float(sse[i])
    d = 1e-3
    s_m, s_p = sse_grid(coef, np.array([h_opt - d, h_opt + d]))
    curv = (s_m + s_p - 2 * sse_opt) / d**2
    h_std = float(np.sqrt(2 * sse_opt / max(n - 1, 1) / curv)) if curv > 0 else np.nan
    r_side = np.sqrt(sse_grid(coef, np.array([h_opt - SHARPNESS_STEP_M, h_opt + SHARPNESS_STEP_M])) / n)
    rmse_opt = np.sqrt(sse_opt / n)
    sharp = float(np.mean(r_side) / rmse_opt - 1.0) if rmse_opt > 0 else np.inf
    return ModelFit(model, h_opt, float(rmse_opt), n, curve, i in (0, h_grid.size - 1), h_std, sharp)


@dataclass
class RecordingFit:
    """Fits of both models on one recording.

    Parameters
    ----------
    recording : str
        The recording's name.
    n_samples : int
        Its valid samples.
    fits : dict of str to ModelFit
        The fit of each model, by model name.
    """

    recording: str
    n_samples: int
    fits: dict[str, ModelFit]


@dataclass
class IdentifyResult:
    """Optimal h per recording and pooled, for each model (Section 4, Fig. 8).

    Parameters
    ----------
    h_grid : ndarray (g,)
        Grid of CoG heights [m].
    per_recording : list of RecordingFit
    pooled : dict of str -> ModelFit
    settings : dict
        What produced it (phi definition, filter window...), copied into the JSON.
    """

    h_grid: np.ndarray
    per_recording: list[RecordingFit]
    pooled: dict[str, ModelFit]
    settings: dict = field(default_factory=dict)

    def to_json(self, model: str = "3dof") -> dict[str, Any]:
        """The analysis output of docs/residual.md, JSON, headed by ``model``, plus every model's results and curves.

        Parameters
        ----------
        model : str
            The model heading the document (a key of :attr:`pooled`).

        Returns
        -------
        dict
            ``model``, ``h_m``, ``rmse_nm``, ``n_samples``, ``h_std_m``, ``at_bound``, ``per_recording``,
            ``models``, ``h_grid_m`` and ``settings`` (non-finite numbers None).
        """
        head = self.pooled[model]
        out: dict[str, Any] = {
            "model": model, "h_m": _f(head.h_m), "rmse_nm": _f(head.rmse_nm), "n_samples": head.n_samples,
            "h_std_m": _f(head.h_std_m), "at_bound": bool(head.at_bound),
            "per_recording": [],
        }
        for rec in self.per_recording:
            fit = rec.fits[model]
            entry = {"recording": rec.recording, "h_m": _f(fit.h_m), "rmse_nm": _f(fit.rmse_nm),
                     "n_samples": rec.n_samples, "at_bound": bool(fit.at_bound)}
            for other, ofit in rec.fits.items():
                if other != model:
                    entry[other] = {"h_m": _f(ofit.h_m), "rmse_nm": _f(ofit.rmse_nm), "at_bound": bool(ofit.at_bound)}
            out["per_recording"].append(entry)
        out["models"] = {
            name: dict(fit.summary(), rmse_curve_nm=[_f(v) for v in fit.rmse_curve_nm],
                       per_recording=[dict(rec.fits[name].summary(), recording=rec.recording,
                                           rmse_curve_nm=[_f(v) for v in rec.fits[name].rmse_curve_nm])
                                      for rec in self.per_recording])
            for name, fit in self.pooled.items()
        }
        out["h_grid_m"] = [float(v) for v in self.h_grid]
        out["settings"] = dict(self.settings)
        return out


def fit_h(states_list, params: EucParams, h_grid=DEFAULT_H_GRID, *, models: Sequence[str] = MODELS,
               extra_Q=None, settings: dict | None = None) -> IdentifyResult:
    """Identify the CoG height h per recording and pooled, for each model (Section 4).

    Parameters
    ----------
    states_list : RiderStates or sequence of RiderStates
        Reconstructed recordings (see :func:`~euc_ros.core.states.kinematics.reconstruct_states`).
    params : EucParams
        Nominal parameters of the session (``h`` ignored).
    h_grid : array_like (g,)
        CoG heights [m], increasing.
    models : sequence of {"3dof", "2dof"}
    extra_Q : optional
        As in :func:`rmse_curve` (array or list of arrays independent of h).
    settings : dict, optional
        Stored in the result (and its JSON).

    Returns
    -------
    IdentifyResult
    """
    states_list = _as_list(states_list)
    h_grid = np.asarray(h_grid, dtype=float).reshape(-1)
    if h_grid.size < 3 or np.any(np.diff(h_grid) <= 0) or not np.all(np.isfinite(h_grid)):
        raise ConfigError("the h grid needs at least 3 increasing finite values", key="h_grid")
    if callable(extra_Q):
        raise ConfigError("fit_h takes extra_Q as arrays; use rmse_curve for an h-dependent force",
                          key="extra_Q")
    per_rec = [RecordingFit(st.name, int(np.count_nonzero(st.valid)), {}) for st in states_list]
    pooled: dict[str, ModelFit] = {}
    for model in models:
        coefs = coefficients_for(states_list, params, model, extra_Q)
        sses = [sse_grid(c, h_grid) for c in coefs]
        for rec, c, s in zip(per_rec, coefs, sses):
            rec.fits[model] = _fit(c, h_grid, model, s)
        if len(coefs) == 1:
            # one recording: the pooled fit is its fit (the same coefficients and curve), not fitted twice
            one = per_rec[0].fits[model]
            pooled[model] = dataclasses.replace(one, rmse_curve_nm=one.rmse_curve_nm.copy())
        else:
            pooled[model] = pooled_fit(coefs, h_grid, model, sses)
    return IdentifyResult(h_grid, per_rec, pooled, dict(settings or {}))


def pooled_fit(coefs: Sequence[np.ndarray], h_grid=DEFAULT_H_GRID, model: str = "3dof",
               sses: Sequence[np.ndarray] | None = None) -> ModelFit:
    """The pooled fit of :func:`fit_h` from the recordings' residual coefficients: what ``fit_h(...).pooled[model]`` is.

    Also from their SSE curves over ``h_grid`` (``sses``), computed here when not given.

    Parameters
    ----------
    coefs : sequence of ndarray (6, n_i)
        Per recording, the residual coefficients of its valid samples.
    h_grid : array_like (g,)
        CoG heights [m], increasing.
    model : str
        The model's name, copied into the fit.
    sses : sequence of ndarray (g,), optional
        Per recording, its SSE over ``h_grid`` [N^2 m^2].

    Returns
    -------
    ModelFit
    """
    h_grid = np.asarray(h_grid, dtype=float).reshape(-1)
    if sses is None:
        sses = [sse_grid(c, h_grid) for c in coefs]
    # one recording: its coefficients are the pooled ones (np.concatenate would copy them, 48 bytes a frame)
    pooled_coef = coefs[0] if len(coefs) == 1 else np.concatenate(coefs, axis=1)
    return _fit(pooled_coef, h_grid, model, np.sum(sses, axis=0))


def pooled_h_of_states(states, params: EucParams) -> float:
    """``fit_h(states, params, models=("3dof",)).pooled["3dof"].h_m`` without holding the recordings' states.

    Each recording's states are dropped as soon as they are reduced to their residual coefficients (48 bytes a valid
    sample, where the states are ~170 a frame), so the fit runs without them: a list ``states`` is emptied; any other
    iterable (e.g. a generator making each recording's states when asked) is read one recording at a time, none held
    beside the next.

    Parameters
    ----------
    states : list or iterable of RiderStates
        The recordings' states (a list is emptied).
    params : EucParams
        Model parameters (``h`` ignored).

    Returns
    -------
    float
        The pooled 3-DoF h [m] on :data:`DEFAULT_H_GRID` (NaN without a valid sample).
    """
    coefs = []
    if isinstance(states, list):
        while states:
            coefs += coefficients_for([states.pop(0)], params, "3dof", None)
    else:
        for st in states:
            coefs += coefficients_for([st], params, "3dof", None)
            del st                  # not held while the iterable makes the next recording's
    return float(pooled_fit(coefs, DEFAULT_H_GRID, "3dof").h_m)
