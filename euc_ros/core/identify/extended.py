"""The h of the 3-DoF model extended with effects the residual analysis selected.

Fitted on the same grid and with the same refinement as the paper's models (:mod:`.fit`).

The residual of a sample is ``M_d1 - M_d2`` of :class:`~euc_ros.core.model.extended.Model` with
the effects' parameters fixed (:func:`extended_inputs` gives the samples); :func:`fit_from_sse` turns a
sum of squares over h into a :class:`~euc_ros.core.identify.fit.ModelFit` as the paper's fits do.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import minimize_scalar

from euc_ros.core.filters.derivatives import savgol_derivatives
from euc_ros.core.identify.fit import SHARPNESS_STEP_M, ModelFit
from euc_ros.core.model.extended import Model
from euc_ros.core.states.contexts import prepare

#: The extended model's input arrays, by name (:meth:`~euc_ros.core.model.extended.Model.torques`).
EXTENDED_KEYS = ("t", "x_dot", "x_ddot", "gamma", "gamma_dot", "gamma_ddot", "phi", "phi_dot", "phi_ddot", "psi",
                  "psi_dot", "theta")


def fit_from_sse(sse_of, h_grid: np.ndarray, n: int, model: str):
    """A :class:`~euc_ros.core.identify.fit.ModelFit` from a sum-of-squares function ``sse_of(h)``.

    Same steps as the paper models' fits: grid minimum, bounded refinement between its neighbours,
    formal std from the curvature (``sigma^2 = 2 s^2 / SSE''``), sharpness at +-0.1 m.

    Parameters
    ----------
    sse_of : callable
        ``sse_of(h) -> float``: the sum of squared residuals at h [m], in [N^2 m^2].
    h_grid : ndarray (g,)
        CoG heights [m], increasing.
    n : int
        Number of samples the sums run over.
    model : str
        The model's name, copied into the fit.

    Returns
    -------
    ModelFit
        NaN values when ``n`` is 0 or no sum is finite.
    """
    sse = np.array([sse_of(float(h)) for h in h_grid])
    if n == 0 or not np.any(np.isfinite(sse)):
        return ModelFit(model, np.nan, np.nan, n, np.full(h_grid.size, np.nan), False, np.nan, np.nan)
    i = int(np.nanargmin(sse))
    lo, hi = h_grid[max(i - 1, 0)], h_grid[min(i + 1, h_grid.size - 1)]
    h_opt, sse_opt = float(h_grid[i]), float(sse[i])
    if hi > lo:
        res = minimize_scalar(sse_of, bounds=(lo, hi), method="bounded", options={"xatol": 1e-7})
        if res.fun <= sse_opt:
            h_opt, sse_opt = float(res.x), float(res.fun)
    d = 1e-3
    curv = (sse_of(h_opt - d) + sse_of(h_opt + d) - 2 * sse_opt) / d**2
    h_std = float(np.sqrt(2 * sse_opt / max(n - 1, 1) / curv)) if curv > 0 else np.nan
    rmse_opt = float(np.sqrt(sse_opt / n))
    side = np.sqrt(np.array([sse_of(h_opt - SHARPNESS_STEP_M), sse_of(h_opt + SHARPNESS_STEP_M)]) / n)
    sharp = float(np.mean(side) / rmse_opt - 1.0) if rmse_opt > 0 else np.inf
    return ModelFit(model, h_opt, rmse_opt, n, np.sqrt(sse / n), i in (0, h_grid.size - 1), h_std, sharp)


def extended_inputs(states, params, effects: dict) -> list[tuple[dict, dict]]:
    """Per recording: the extended model's input arrays over its samples, and its ``extras``.

    The samples are the recording's valid ones (those of the paper's models) with a finite yaw and
    tilt; the yaw rate is the Savitzky-Golay derivative of the (unwrapped) yaw with the states' own
    window. With ``mocap_time_offset``, which needs the time-shift hook of the residual analysis, the
    inputs are those of :func:`euc_ros.core.states.contexts.prepare` (its sample set).

    Parameters
    ----------
    states : sequence of RiderStates
        The recordings' states.
    params : EucParams
        The session's parameters.
    effects : dict
        ``{effect: {parameter: value}}`` of the extended model.

    Returns
    -------
    list of (dict, dict)
        Per recording, the arrays of :data:`EXTENDED_KEYS` over its samples (SI units: ``t`` [s], angles
        [rad]) and the effects' ``extras``.
    """
    if "mocap_time_offset" in effects:
        out = []
        for rec in prepare(states, params):
            c = rec.ctx
            out.append(({k: getattr(c, k) for k in EXTENDED_KEYS}, c.extras))
        return out
    out = []
    for st in states:
        window = st.window if st.window and st.window % 2 == 1 else 9
        dpsi = savgol_derivatives(st.dt if np.isfinite(st.dt) else st.t, st.psi, window=window,
                                  polyorder=st.polyorder, frame=st.frame)
        mask = np.asarray(st.valid, bool) & np.isfinite(st.psi) & np.isfinite(st.theta) & np.isfinite(dpsi.y_dot)
        arrays = {k: np.asarray(getattr(st, k), float)[mask] for k in EXTENDED_KEYS if k not in ("t", "psi_dot")}
        arrays["t"] = st.t[mask] - (st.t[0] if st.n else 0.0)
        arrays["psi_dot"] = dpsi.y_dot[mask]
        out.append((arrays, {}))
    return out


def extended_fits(states, params, effects: dict, h_grid: np.ndarray):
    """Identify h for the 3-DoF model extended with ``effects``, per recording and pooled.

    The residual of a sample is ``M_d1 - M_d2`` of
    :class:`~euc_ros.core.model.extended.Model` with the effects' parameters fixed (see
    :func:`extended_inputs` for the samples). The sum of squares is evaluated at every h of the grid
    (vectorized over samples), then refined as for the paper's models.

    Parameters
    ----------
    states : sequence of RiderStates
        The recordings' states.
    params : EucParams
        The session's parameters.
    effects : dict
        ``{effect: {parameter: value}}`` of the extended model.
    h_grid : ndarray (g,)
        CoG heights [m], increasing.

    Returns
    -------
    name : str
        ``"3dof+<effect>..."``.
    per_recording : list of ModelFit
    pooled : ModelFit
    """
    model = Model.from_report(params, effects)
    inputs = extended_inputs(states, params, effects)

    def residual(k: int, h: float) -> np.ndarray:
        arrays, extras = inputs[k]
        m1, m2 = model.torques(arrays, h=h, extras=extras)
        return np.asarray(m1 - m2, float)

    mid = float(np.median(h_grid))
    masks = [np.isfinite(residual(k, mid)) for k in range(len(inputs))]
    cache: dict[tuple[int, float], float] = {}

    def sse_rec(k: int, h: float) -> float:
        if (k, h) not in cache:
            e = residual(k, h)[masks[k]]
            cache[(k, h)] = float(np.dot(e, e))
        return cache[(k, h)]

    per = [fit_from_sse(lambda h, k=k: sse_rec(k, h), h_grid, int(masks[k].sum()), model.label)
           for k in range(len(inputs))]
    pooled = fit_from_sse(lambda h: sum(sse_rec(k, h) for k in range(len(inputs))), h_grid,
                           int(sum(m.sum() for m in masks)), model.label)
    return model.label, per, pooled


def extended_interval(states, params, effects: dict, h: float, block_s: float, *, level: float = 0.95
                      ) -> tuple[float, float, float, int]:
    """The statistical interval of the extended model's h: ``(low, high, standard error, blocks)``.

    The effects' parameters are fixed, so h is a one-parameter least-squares fit of the residual
    ``r(h)``; its block-robust (sandwich) standard error is ``sqrt(sum_b s_b^2) / sum J^2`` with
    ``J = dr/dh`` (central differences) and ``s_b`` the sum of ``J r`` over a block of ``block_s``
    seconds of one recording (blocks about as long as the base model's bootstrap blocks, so nearly
    independent), times ``B / (B - 1)``; the interval uses Student's t with ``B - 1`` degrees of freedom.

    Parameters
    ----------
    states : sequence of RiderStates
        The recordings' states.
    params : EucParams
        The session's parameters.
    effects : dict
        ``{effect: {parameter: value}}`` of the extended model.
    h : float
        The extended model's fitted h [m].
    block_s : float
        Block length [s].
    level : float
        Confidence level of the interval.

    Returns
    -------
    (float, float, float, int)
        Low and high end [m], standard error [m] and number of blocks; NaN ends and error with fewer than 3
        blocks or no sensitivity to h.
    """
    from scipy.stats import t as student

    model = Model.from_report(params, effects)
    inputs = extended_inputs(states, params, effects)
    step = 1e-5
    jr, jj, blocks = [], [], []
    for k, (arrays, extras) in enumerate(inputs):
        def res(hh, arrays=arrays, extras=extras):
            m1, m2 = model.torques(arrays, h=hh, extras=extras)
            return np.asarray(m1 - m2, float)

        r0, rp, rm = res(h), res(h + step), res(h - step)
        J = (rp - rm) / (2 * step)
        ok = np.isfinite(r0) & np.isfinite(J)
        t = np.asarray(arrays["t"], float)[ok]
        jr.append((J * r0)[ok])
        jj.append(float(np.dot(J[ok], J[ok])))
        blocks.append(k * 10_000_000 + np.floor((t - (t[0] if t.size else 0.0)) / block_s).astype(np.int64))
    ids, inv = np.unique(np.concatenate(blocks), return_inverse=True) if blocks else (np.zeros(0), None)
    nb = int(ids.size)
    den = float(sum(jj))
    if nb < 3 or not den > 0:
        return float("nan"), float("nan"), float("nan"), nb
    scores = np.bincount(inv, weights=np.concatenate(jr), minlength=nb)
    se = float(np.sqrt(np.sum(scores ** 2) * nb / (nb - 1)) / den)
    q = float(student.ppf(0.5 + level / 2, nb - 1))
    return h - q * se, h + q * se, se, nb
