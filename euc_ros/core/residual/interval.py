"""The final model's intervals: h and every effect parameter, with what the data cannot settle.

The final model (the base model with the selected and discovered effects) is a joint least-squares fit
of ``x = [h, theta...]`` to zero residual. Its covariance is the block-robust sandwich

    cov = (J^T J)^-1 (sum_b s_b s_b^T) (J^T J)^-1 * B / (B - p),    s_b = J_b^T r_b,

with ``J`` the residual's Jacobian at the fit, ``r`` the residual, ``b`` the blocks of the analysis'
paired test (each about twice the residual's correlation time, so the block scores are nearly
independent) and ``B / (B - p)`` the small-sample correction for ``p`` fitted parameters (the
cluster-robust estimator's CR1). It holds for a residual that is correlated within blocks and of any
variance, which the residual of an imperfect model is. The 95 % interval uses Student's t with
``B - p`` degrees of freedom. A reported parameter that is a function of ``x`` (an amplitude and a
phase, a unit change) gets its interval by the delta method.

What the fit's statistics do not hold is added to h's interval:

* the widening ``identify`` applies to the base model's bootstrap interval (errors in variables from
  the pose noise, soft-tissue sliding, the filter's distortion), taken alike for the final model
  (the same recordings, filtered alike; passed in as ``extra_low_m``/``extra_high_m``);
* every admissible explanation the data cannot tell from the final one (the tied models, named or
  discovered): the interval covers each one's h with the same half-width, since they are fitted on the
  same samples with nearly the same sensitivity of the residual to h.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np

from euc_ros.core.model.extended import H_BOUNDS, Model
from euc_ros.core.residual.folds import with_blocks
from euc_ros.core.residual.selection import block_offsets, fit_model, model_jacobian
from euc_ros.core.states.contexts import Recording, prepare

#: Level of the intervals.
LEVEL = 0.95
#: An h this close to the edge of the search range (:data:`~euc_ros.core.residual.selection.H_BOUNDS`) is
#: held by the bound, not by the data: its interval is unbounded [m].
EDGE_M = 1e-6


@dataclass(frozen=True)
class FinalInterval:
    """Intervals of the final model.

    Parameters
    ----------
    h_m : float
        The final model's h [m].
    h_se_m : float
        Its block-robust standard error [m].
    quantile : float
        Student's t quantile of the intervals (``B - p`` degrees of freedom).
    parameters_ci95 : dict of str to list of float
        Per reported effect parameter (keys of ``Model.report``), its ``[low, high]`` interval.
    n_blocks : int
        Blocks of the sandwich.
    tied_h_m : tuple of float
        h of the other admissible explanations the interval covers [m].
    extra_low_m, extra_high_m : float
        Widening beyond the statistics, below and above [m] (:meth:`widened`).
    filter_h_m : float
        The same model's h on states filtered with the window chosen from the data (NaN: not measured)
        [m]; the interval covers it with the same half-width widened by ``filter_floor_m``, the bound on
        that filter's own distortion (:func:`filter_refit`).
    filter_floor_m : float
        That bound [m] (0: not measured).
    """

    h_m: float
    h_se_m: float
    quantile: float
    parameters_ci95: dict[str, list[float]]
    n_blocks: int
    tied_h_m: tuple[float, ...] = ()
    extra_low_m: float = 0.0
    extra_high_m: float = 0.0
    filter_h_m: float = float("nan")
    filter_floor_m: float = 0.0

    @property
    def h_ci95_m(self) -> tuple[float, float]:
        """The interval of h: its own, and each tied h with the same half-width, widened by the extras [m]."""
        half = self.quantile * self.h_se_m if math.isfinite(self.h_se_m) else float("inf")
        if not math.isfinite(self.h_m) or min(self.h_m - H_BOUNDS[0], H_BOUNDS[1] - self.h_m) < EDGE_M:
            half = float("inf")         # a fit at the edge of the search range: the data do not bound h
        hs = [self.h_m, *self.tied_h_m]
        lo, hi = min(v - half for v in hs) - self.extra_low_m, max(v + half for v in hs) + self.extra_high_m
        if math.isfinite(self.filter_h_m):
            lo = min(lo, self.filter_h_m - half - self.filter_floor_m - self.extra_low_m)
            hi = max(hi, self.filter_h_m + half + self.filter_floor_m + self.extra_high_m)
        return lo, hi

    def widened(self, extra_low_m: float, extra_high_m: float) -> "FinalInterval":
        """The same intervals with h's widened below and above.

        Parameters
        ----------
        extra_low_m, extra_high_m : float
            The widening below and above [m] (negative values count as 0; ``inf``: unbounded on that side).

        Returns
        -------
        FinalInterval
        """
        return replace(self, extra_low_m=max(float(extra_low_m), 0.0), extra_high_m=max(float(extra_high_m), 0.0))

    def widened_by(self) -> list[str]:
        """What h's interval holds beyond its own statistics, in words.

        Returns
        -------
        list of str
            One phrase per term (the base model's widening, the data filter's h, the tied h); empty: none.
        """
        out = []
        if math.isinf(self.extra_low_m) or math.isinf(self.extra_high_m):
            out.append("the base model's h, which the data do not bound")
        elif self.extra_low_m > 0 or self.extra_high_m > 0:
            out.append(f"the base model's bias terms (-{self.extra_low_m * 1e3:.1f} / "
                       f"+{self.extra_high_m * 1e3:.1f} mm)")
        if math.isfinite(self.filter_h_m):
            out.append(f"the h with the filter chosen from the data, {self.filter_h_m:.3f} m +- "
                       f"{self.filter_floor_m * 1e3:.1f} mm (the filters' distortion)")
        if self.tied_h_m:
            out.append("the h of " + ", ".join(f"{v:.3f}" for v in self.tied_h_m) + " m (tied explanations)")
        return out

    def to_json(self) -> dict:
        """The JSON keys ``h_after_ci95_m``, ``effect_parameters_ci95`` and ``h_after_uncertainty``.

        Returns
        -------
        dict
            Those keys, a value that is not finite as None.
        """
        def f(v):
            return float(v) if math.isfinite(v) else None

        return {"h_after_ci95_m": [f(v) for v in self.h_ci95_m],
                "effect_parameters_ci95": {k: [f(v) for v in iv] for k, iv in self.parameters_ci95.items()},
                "h_after_uncertainty": {"method": "block sandwich", "h_se_m": f(self.h_se_m),
                                        "n_blocks": self.n_blocks, "t_quantile": f(self.quantile),
                                        "h_with_data_filter_m": f(self.filter_h_m),
                                        "filter_floor_m": f(self.filter_floor_m),
                                        "widened_by": self.widened_by()}}


def sandwich_covariance(model: Model, recs: Sequence[Recording], x: np.ndarray) -> tuple[np.ndarray, int]:
    """Block-robust covariance of the fitted ``x`` (p, p) and the number of blocks.

    Parameters without a finite sensitivity get NaN variances. With fewer blocks than parameters + 2
    the covariance is all NaN (no degrees of freedom left).

    Parameters
    ----------
    model : Model
        The fitted model.
    recs : sequence of Recording
        The recordings it is fitted on, with their blocks.
    x : ndarray (p,)
        The fitted parameters ``[h, theta...]``.

    Returns
    -------
    cov : ndarray (p, p)
        The covariance of ``x`` (h [m^2]).
    n_blocks : int
        Blocks with a usable sample, over all recordings.
    """
    x = np.asarray(x, float)
    r, masks, J = model_jacobian(model, recs, x)
    offsets = block_offsets(recs)
    rows = [np.asarray(m, bool) & np.all(np.isfinite(j), axis=1) for m, j in zip(masks, J)]
    Jm = np.concatenate([j[k] for j, k in zip(J, rows)]) if recs else np.zeros((0, x.size))
    rm = np.concatenate([ri[k] for ri, k in zip(r, rows)]) if recs else np.zeros(0)
    blocks = np.concatenate([np.asarray(rec.block)[k] + o for rec, k, o in zip(recs, rows, offsets)]) \
        if recs else np.zeros(0, int)
    p = x.size
    cov = np.full((p, p), np.nan)
    used, ids = np.unique(blocks, return_inverse=True)
    n_blocks = int(used.size)
    if n_blocks < p + 2:
        return cov, n_blocks
    active = np.any(Jm != 0.0, axis=0)
    A = Jm[:, active]
    scores = np.zeros((n_blocks, A.shape[1]))
    np.add.at(scores, ids, A * rm[:, None])
    bread = np.linalg.pinv(A.T @ A)
    meat = scores.T @ scores
    sub = bread @ meat @ bread * (n_blocks / (n_blocks - p))
    cov[np.ix_(active, active)] = sub
    return cov, n_blocks


def _report_jacobian(model: Model, x: np.ndarray) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Reported parameter names, values and d(report)/dx by central differences."""
    base = model.report(x)
    names = list(base)
    values = np.array([base[k] for k in names], float)
    G = np.zeros((len(names), x.size))
    lo, hi = model.bounds()
    steps = 1e-6 * model.scales()
    for j in range(1, x.size):
        a, b = x.copy(), x.copy()
        a[j] = max(x[j] - steps[j], lo[j])
        b[j] = min(x[j] + steps[j], hi[j])
        if b[j] == a[j]:
            continue
        ra, rb = model.report(a), model.report(b)
        G[:, j] = [(rb[k] - ra[k]) / (b[j] - a[j]) for k in names]
    return names, values, G


def final_interval(model: Model, recs: Sequence[Recording], x: np.ndarray, *, tied_h: Sequence[float] = (),
                   extra_low_m: float = 0.0, extra_high_m: float = 0.0, level: float = LEVEL) -> FinalInterval:
    """Intervals of the final model's h and reported effect parameters (see the module docstring).

    Parameters
    ----------
    model : Model
        The final model.
    recs : sequence of Recording
        The analysis' recordings, with the blocks of its paired test.
    x : ndarray
        The final fit ``[h, theta...]``.
    tied_h : sequence of float
        h of every other admissible explanation the data cannot tell from this one [m].
    extra_low_m, extra_high_m : float
        What h's interval is widened by below and above, beyond its statistics [m] (>= 0).
    level : float
        Coverage of the intervals.

    Returns
    -------
    FinalInterval
    """
    from scipy.stats import t as student

    x = np.asarray(x, float)
    cov, n_blocks = sandwich_covariance(model, recs, x)
    dof = n_blocks - x.size
    q = float(student.ppf(0.5 + level / 2, dof)) if dof > 0 else float("inf")
    h = float(x[0])
    se = float(math.sqrt(cov[0, 0])) if np.isfinite(cov[0, 0]) and cov[0, 0] >= 0 else float("nan")
    others = tuple(float(v) for v in tied_h if math.isfinite(v) and float(v) != h)
    names, values, G = _report_jacobian(model, x)
    params = {}
    c = np.where(np.isfinite(cov), cov, 0.0)
    bad = ~np.isfinite(np.diag(cov))
    for k, name in enumerate(names):
        g = G[k]
        if np.any(g[bad] != 0.0):
            params[name] = [float("nan"), float("nan")]
            continue
        s = float(math.sqrt(max(g @ c @ g, 0.0)))
        params[name] = [float(values[k] - q * s), float(values[k] + q * s)]
    return FinalInterval(h, se, q, params, n_blocks, others).widened(extra_low_m, extra_high_m)


def filter_refit(interval: FinalInterval, model: Model, x: np.ndarray, states, params, *, probe_states=None,
                 probe_ratio: float = float("nan"), floor=None, analysis_rate_hz: float | None = None,
                 block_s: float) -> FinalInterval:
    """``interval`` also covering the final model's h refitted on ``states`` filtered otherwise.

    The analysis runs on states of a fixed Savitzky-Golay window, which distorts the accelerations of
    fast motion and moves h (low); ``states`` are the same recordings filtered with the window chosen
    from their own spectra. The model (its effects as selected and measured) is fitted again on them
    from ``x``; the interval holds that h too. With ``probe_states`` (the companion filter whose
    distortion is ``probe_ratio`` times the chosen one's), the chosen filter's own distortion is bounded
    as identify bounds it, ``|h_probe - h| / (probe_ratio - 1)`` (a bias growing with the distortion),
    and the interval reaches that far beyond. Either states may be given as a function that makes them
    (:func:`~euc_ros.core.states.filter_choice.data_filters`): then each is made when needed and let go once
    prepared, so the two filters' states never exist together.

    Parameters
    ----------
    interval : FinalInterval
        The final model's intervals.
    model : Model
        The final model.
    x : ndarray
        Its fit ``[h, theta...]`` (the refits' start).
    states : list of RiderStates or callable
        The recordings filtered with the window chosen from the data, or a function that makes them.
    params : EucParams
        The session's nominal parameters.
    probe_states : list of RiderStates or callable, optional
        The recordings filtered with the companion filter, or a function that makes them.
    probe_ratio : float
        The companion filter's distortion over the chosen one's (the bound needs it above 1).
    floor : FloorFit, optional
        The floor measured from the contact path, as in the analysis.
    analysis_rate_hz : float or None
        Sub-sampling rate of the prepared recordings [Hz]; None: every sample.
    block_s : float
        Block length of the paired test [s].

    Returns
    -------
    FinalInterval
        ``interval`` with ``filter_h_m`` and ``filter_floor_m``.
    """
    def refit(sts) -> float:
        # states made here live as long as their contexts (dropped after the fit)
        recs = with_blocks(prepare(sts() if callable(sts) else sts, params, floor=floor,
                                   analysis_rate_hz=analysis_rate_hz), block_s)
        return float(fit_model(model, recs, float(x[0]), start=np.asarray(x, float)).h)

    h_data = refit(states)
    floor_m = 0.0
    if probe_states is not None and probe_ratio > 1:
        floor_m = abs(refit(probe_states) - h_data) / (probe_ratio - 1)
    return replace(interval, filter_h_m=h_data, filter_floor_m=floor_m)


def base_widening(base_uncertainty: dict) -> tuple[float, float]:
    """How far identify's interval of the base model reaches beyond its block bootstrap, below and above [m].

    Those are the terms the fit's statistics do not hold (errors in variables, sliding, the filter's
    distortion, few blocks); the final model is fitted on the same states, so its interval is widened alike.
    An end of the base interval the data do not bound (None) is an infinite widening on that side.

    Parameters
    ----------
    base_uncertainty : dict
        identify's JSON of the base model: ``h_ci95_m`` and ``uncertainty.bootstrap_ci95_m``.

    Returns
    -------
    tuple of float
        ``(below, above)`` [m], each >= 0; ``inf`` on a side the data do not bound, ``(0, 0)`` when either
        interval is missing.
    """
    ci = base_uncertainty.get("h_ci95_m") or [None, None]
    boot = (base_uncertainty.get("uncertainty") or {}).get("bootstrap_ci95_m") or [None, None]
    if "h_ci95_m" in base_uncertainty and None in ci:
        # the base model's h is not bounded by the data: neither is the final model's, fitted on the same states
        return float("inf") if ci[0] is None else 0.0, float("inf") if ci[1] is None else 0.0
    if None in ci or None in boot:
        return 0.0, 0.0
    return max(boot[0] - ci[0], 0.0), max(ci[1] - boot[1], 0.0)
