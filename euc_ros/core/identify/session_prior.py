"""h from the dynamics combined with the segments' geometric h: two measurements of one height.

``identify`` measures h twice. The dynamics give it through the torque balance, with an interval from the
data (pose noise, soft-tissue sliding, the filter) and from the session's values the dynamics use. The
rider's segments give it without any dynamics: the median distance of the rider CoG G from the ankle hinge
(:func:`~.held.geometric_h`), uncertain by the session's tolerances of the CoM offsets, l0 and the mass
fractions (Type B, :func:`~.held.geometric_h_uncertainty`). The headline h combines them as a posterior: the
geometric h as a normal prior, the dynamics' interval as a split-normal likelihood (each side's standard deviation its
half-width over 1.96; a side the data do not bound is flat), on a grid over the search range; h is the
posterior median. Its interval is the intersection of both intervals, each taken at a level such that their
misses sum to 5 % (Bonferroni: the truth lies in both with at least 95 %, whatever their shapes), the 5 % shared
in proportion to their precisions (:func:`split_levels`; 97.5 % each for equal widths): the dynamics' interval
stacks bounds (the filter's distortion, the sliding) that are no normal spread, and a product of normals would
narrow it below what those bounds allow.

Why both. A few millimetres of soft-tissue sliding that follows the rider's lean cannot be told from h by
the dynamics (h's variance grows 4-14 times when such a mode is freed), so the dynamics' interval is wide;
the same sliding moves the segments' CoG by a few millimetres, so the geometric h hardly moves. On such a
ride the combination is the geometric h, checked by the data; on a clean ride the data sharpen it.

The check. The two disagree when those intervals do not meet (the JSON also gives
``z = (h_d - h_g) / sqrt(s^2 + u_g^2)``, ``s`` the data's side facing ``h_g``): a session whose offsets are off
by more than their tolerance, or an effect the model lacks pulling the dynamics' h (``euc-ros residual`` looks
for it). Then the interval is the hull of both 95 % intervals and a warning says why.

Examples
--------
>>> c = combine(0.60, (0.58, 0.62), 0.61, 0.005)
>>> round(c.h_m, 3), c.consistent
(0.608, True)
>>> [round(v, 4) for v in c.ci95_m]                   # the geometric h's interval, inside the data's
[0.5997, 0.6203]
>>> c = combine(0.60, (0.58, 0.62), 0.70, 0.005)       # they disagree: the hull of both intervals
>>> c.consistent, [round(v, 3) for v in c.ci95_m]
(False, [0.58, 0.71])
>>> c = combine(0.60, (0.50, None), 0.80, 0.005)       # the data bound h below only: the geometric h
>>> c.consistent, round(c.h_m, 3), c.weight_data
(True, 0.8, 0.0)
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from statistics import NormalDist

import numpy as np

from euc_ros.core.identify.held import Z95, geometric_h, geometric_h_uncertainty
from euc_ros.core.identify.interval import json_float
from euc_ros.core.identify.options import H_BOUNDS

#: Normal quantile of a 97.5 % interval (two intervals that must both hold the truth: Bonferroni).
Z975 = 2.241403
#: What the combined interval may miss (a 95 % interval).
MISS = 0.05
#: Least and largest share of :data:`MISS` either interval gets (neither is ever dropped).
SHARE_RANGE = (0.05, 0.95)
#: Grid step of the posterior [m] (a tenth of a millimetre: the quantiles to well below the intervals' 1 mm).
GRID_STEP_M = 1e-4


def _sd(h: float, end, bounds: tuple[float, float]) -> float:
    """One side's standard deviation from its 95 % end; infinite where the data do not bound that side."""
    if end is None or not math.isfinite(float(end)):
        return math.inf
    end = float(end)
    if end <= bounds[0] + 1e-9 or end >= bounds[1] - 1e-9:   # an end at the search range's edge bounds nothing
        return math.inf
    return abs(h - end) / Z95


@dataclass(frozen=True)
class Combined:
    """The dynamics' h combined with the geometric h.

    Parameters
    ----------
    h_m : float
        The headline h [m]: the posterior median.
    ci95_m : tuple of float
        Its 95 % interval [m]: both intervals intersected at levels whose misses sum to 5 %; the hull of both
        95 % intervals when they
        disagree.
    h_data_m : float
        The dynamics' h [m].
    h_data_ci95_m : tuple of float
        Its 95 % interval [m] (an unbounded end NaN).
    h_geometric_m : float
        The segments' geometric h [m].
    u_geometric_m : float
        Its standard uncertainty [m].
    z : float
        The disagreement in combined standard deviations (0 where the data do not bound the side).
    consistent : bool
        Whether the two intervals (at their levels) meet.
    weight_data : float
        The data's share of the posterior's precision (0: the geometric h alone; 1: the data alone), from the
        side of the data facing the posterior median.
    """

    h_m: float
    ci95_m: tuple[float, float]
    h_data_m: float
    h_data_ci95_m: tuple[float, float]
    h_geometric_m: float
    u_geometric_m: float
    z: float
    consistent: bool
    weight_data: float

    @property
    def std_m(self) -> float:
        """The interval's half-width over 1.96 [m]."""
        return (self.ci95_m[1] - self.ci95_m[0]) / (2 * Z95)

    def to_json(self) -> dict:
        """The JSON's ``diagnostics.h_combined``: both measurements, the check and the combination.

        Returns
        -------
        dict
            ``h_m``, ``ci95_m``, ``h_from_data_m``, ``h_from_data_ci95_m``, ``h_geometric_m``, ``u_geometric_m``,
            ``z``, ``consistent``, ``weight_data`` and ``method`` (non-finite numbers None).
        """
        f = json_float
        return {"h_m": f(self.h_m), "ci95_m": [f(v) for v in self.ci95_m], "h_from_data_m": f(self.h_data_m),
                "h_from_data_ci95_m": [f(v) for v in self.h_data_ci95_m], "h_geometric_m": f(self.h_geometric_m),
                "u_geometric_m": f(self.u_geometric_m), "z": f(self.z), "consistent": bool(self.consistent),
                "weight_data": f(self.weight_data),
                "method": "h: posterior median of the geometric h (normal prior, the session's Type B uncertainty) "
                          "and the data's interval (split-normal likelihood); interval: both intersected at levels "
                          "whose misses sum to 5 %, shared by precision (Bonferroni), the hull of both 95 % "
                          "intervals when they disagree"}

    def console_line(self) -> str:
        """One line: the combined h, where it comes from, and whether the two agree.

        Returns
        -------
        str
        """
        lo, hi = self.ci95_m
        dlo, dhi = ("-" if not math.isfinite(v) else f"{v:.3f}" for v in self.h_data_ci95_m)
        head = (f"h = {self.h_m:.3f} m, 95 % interval [{lo:.3f}, {hi:.3f}] m: the one to use (the data's h "
                f"{self.h_data_m:.3f} m [{dlo}, {dhi}] combined with the segments' geometric h "
                f"{self.h_geometric_m:.3f} m, u {1e3 * self.u_geometric_m:.1f} mm from the session tolerances; "
                f"the data carry {100 * self.weight_data:.0f} % of it)")
        return head if self.consistent else head + "; " + self.warning()

    def warning(self) -> str:
        """Why the two disagree, and what to check ("" when they agree).

        Returns
        -------
        str
        """
        if self.consistent:
            return ""
        return (f"the data's h ({self.h_data_m:.3f} m) and the segments' geometric h ({self.h_geometric_m:.3f} m) "
                f"disagree ({abs(self.z):.1f} combined standard deviations): the session's CoM offsets or l0 may be "
                "off by more than their tolerance, or an effect the model lacks pulls the data's h (euc-ros "
                "residual looks for it); the interval spans both")


def split_levels(s_data: float, u_geo: float) -> tuple[float, float]:
    """The normal quantiles of the data's and the geometric interval whose misses sum to 5 % (Bonferroni).

    The 5 % is shared in proportion to the two precisions (``1 / s^2``), so that the narrower interval, the one
    that sets the intersection, gets the larger share; each share is kept within :data:`SHARE_RANGE` of the 5 %,
    so neither interval is ever dropped. The split depends on the two widths only, never on where the two
    measurements lie, so the intersection holds the truth with at least 95 % whatever the widths are. Two
    equally precise measurements get 2.5 % each (97.5 % intervals, :data:`Z975`).

    Parameters
    ----------
    s_data : float
        The data's standard deviation [m] (infinite: the data bound neither side).
    u_geo : float
        The geometric h's standard uncertainty [m].

    Returns
    -------
    tuple of float
        ``(z_data, z_geometric)``.

    Examples
    --------
    >>> [round(v, 4) for v in split_levels(0.01, 0.01)]
    [2.2414, 2.2414]
    >>> [round(v, 3) for v in split_levels(0.03, 0.01)]      # the geometric h is 9 times as precise
    [2.807, 2.005]
    """
    p_d = 0.0 if not math.isfinite(s_data) else 1.0 / s_data ** 2
    p_g = 1.0 / u_geo ** 2
    share_d = min(max(p_d / (p_d + p_g), SHARE_RANGE[0]), SHARE_RANGE[1])
    ppf = NormalDist().inv_cdf
    return ppf(1.0 - MISS * share_d / 2.0), ppf(1.0 - MISS * (1.0 - share_d) / 2.0)


def combine(h_data: float, ci_data, h_geo: float, u_geo: float,
            bounds: tuple[float, float] = H_BOUNDS) -> Combined:
    """Combine the dynamics' h and interval with the geometric h and its standard uncertainty.

    Parameters
    ----------
    h_data : float
        The dynamics' h [m].
    ci_data : pair of float or None
        Its 95 % interval [m]; an end None, non-finite or at ``bounds`` is a side the data do not bound.
    h_geo : float
        The segments' geometric h [m].
    u_geo : float
        Its standard uncertainty [m] (> 0).
    bounds : tuple of float
        The search range [m]: the grid of the posterior.

    Returns
    -------
    Combined

    Raises
    ------
    ValueError
        ``h_geo`` or ``h_data`` not finite, or ``u_geo`` not positive.
    """
    if not (math.isfinite(h_geo) and math.isfinite(h_data)):
        raise ValueError(f"needs finite h, got data {h_data} and geometric {h_geo}")
    if not u_geo > 0:
        raise ValueError(f"needs a positive geometric uncertainty, got {u_geo}")
    lo_end, hi_end = (None, None) if ci_data is None else ci_data
    s_lo, s_hi = _sd(h_data, lo_end, bounds), _sd(h_data, hi_end, bounds)
    lo_b, hi_b = float(bounds[0]), float(bounds[1])
    grid = np.arange(lo_b, hi_b + GRID_STEP_M / 2, GRID_STEP_M)
    side = np.where(grid < h_data, s_lo, s_hi)
    with np.errstate(divide="ignore", invalid="ignore"):
        data_term = np.where(np.isfinite(side), ((grid - h_data) / side) ** 2, 0.0)
    log_post = -0.5 * (data_term + ((grid - h_geo) / u_geo) ** 2)
    w = np.exp(log_post - log_post.max())
    cdf = np.cumsum(w)
    cdf /= cdf[-1]
    h = float(np.interp(0.5, cdf, grid))
    s_toward = s_lo if h_geo < h_data else s_hi
    z = 0.0 if not math.isfinite(s_toward) else (h_data - h_geo) / math.hypot(s_toward, u_geo)
    s_at = s_lo if h < h_data else s_hi
    weight = 0.0 if not math.isfinite(s_at) else (1 / s_at ** 2) / (1 / s_at ** 2 + 1 / u_geo ** 2)
    # each interval at its own level, the two misses summing to 5 % (Bonferroni): the truth is in both with at
    # least 95 %
    z_d, z_g = split_levels(max((v for v in (s_lo, s_hi) if math.isfinite(v)), default=math.inf), u_geo)
    d_lo = h_data - z_d * s_lo if math.isfinite(s_lo) else lo_b
    d_hi = h_data + z_d * s_hi if math.isfinite(s_hi) else hi_b
    lo, hi = max(d_lo, h_geo - z_g * u_geo, lo_b), min(d_hi, h_geo + z_g * u_geo, hi_b)
    consistent = lo <= hi
    if consistent:
        h = min(max(h, lo), hi)
        ci = (float(lo), float(hi))
    else:                      # the hull of both 95 % intervals
        d_lo95 = h_data - Z95 * s_lo if math.isfinite(s_lo) else lo_b
        d_hi95 = h_data + Z95 * s_hi if math.isfinite(s_hi) else hi_b
        ci = (max(lo_b, min(d_lo95, h_geo - Z95 * u_geo)), min(hi_b, max(d_hi95, h_geo + Z95 * u_geo)))
    data_ci = (float(lo_end) if math.isfinite(s_lo) else math.nan, float(hi_end) if math.isfinite(s_hi) else math.nan)
    return Combined(h, ci, float(h_data), data_ci, float(h_geo), float(u_geo), float(z), bool(consistent),
                    float(weight))


def with_geometric(states, params, h_data: float, ci_data, *, tolerances: dict | None = None,
                   mass_sensitivity=None, bounds: tuple[float, float] = H_BOUNDS,
                   admissible=None) -> Combined | None:
    """:func:`combine` the data's h with the recordings' geometric h and its Type B uncertainty.

    Parameters
    ----------
    states : sequence of RiderStates
        The recordings' states (:func:`~.held.geometric_h`).
    params : EucParams
        The session's parameters (``l0``).
    h_data : float
        The data's h [m].
    ci_data : pair of float or None
        Its 95 % interval [m].
    tolerances : dict, optional
        identify's budget tolerances (:func:`~.held.geometric_h_uncertainty`).
    mass_sensitivity : MassSensitivity, optional
        :func:`~.held.geometric_mass_sensitivity` (None: the mass fractions' terms left out).
    bounds : tuple of float
        The search range [m].
    admissible : pair of float, optional
        The range of h the rider's recorded joints allow [m] (:func:`~euc_ros.core.states.admissible.admissible_h`):
        the combination stays inside it and ``bounds``.

    Returns
    -------
    Combined or None
        None when the geometric h or the data's h is not finite, or the two ranges do not meet.
    """
    bounds = admissible_bounds(bounds, admissible)
    h_g = geometric_h(states, params)
    if not (math.isfinite(h_g) and math.isfinite(h_data)) or not bounds[0] < bounds[1]:
        return None
    u_g = geometric_h_uncertainty(tolerances, l0=params.l0, mass_sensitivity=mass_sensitivity)
    return combine(h_data, ci_data, h_g, u_g, bounds=bounds)


def admissible_bounds(bounds: tuple[float, float] = H_BOUNDS, admissible=None) -> tuple[float, float]:
    """The search range cut at the admissible range of h (identify's ``uncertainty.h_admissible_m``) [m].

    Parameters
    ----------
    bounds : tuple of float
        The search range [m].
    admissible : pair of float, optional
        The range the rider's recorded joints allow [m].

    Returns
    -------
    tuple of float
    """
    if admissible is None:
        return float(bounds[0]), float(bounds[1])
    return max(float(admissible[0]), float(bounds[0])), min(float(admissible[1]), float(bounds[1]))


def recombine(geometric: Combined, h_data: float, ci_data, *,
              bounds: tuple[float, float] = H_BOUNDS) -> Combined | None:
    """Another model's h from the data, combined with the geometric h of an earlier combination.

    The residual's final model (the base model with the selected and discovered effects) gives its own h and
    interval from the data; the rider's geometric h and its Type B uncertainty are the ones identify's
    combination used (:func:`with_geometric`).

    Parameters
    ----------
    geometric : Combined
        The combination whose geometric h and uncertainty are used.
    h_data : float
        The other model's h from the data [m].
    ci_data : pair of float or None
        Its 95 % interval [m].
    bounds : tuple of float
        The search range, cut at the admissible range (:func:`admissible_bounds`) [m].

    Returns
    -------
    Combined or None
        None when ``h_data`` is not finite or the range is empty.

    Examples
    --------
    >>> first = combine(0.60, (0.58, 0.62), 0.61, 0.005)
    >>> round(recombine(first, 0.63, (0.60, 0.66)).h_m, 3)
    0.612
    """
    if h_data is None or not math.isfinite(float(h_data)) or not bounds[0] < bounds[1]:
        return None
    return combine(float(h_data), ci_data, geometric.h_geometric_m, geometric.u_geometric_m, bounds=bounds)
