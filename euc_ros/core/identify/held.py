"""h held at the segments' geometric h where the data do not bound it, with a Type B uncertainty.

h is identified from the pitch and acceleration dynamics; a ride without enough speed changes leaves the
RMSE curve of M_d1 - M_d2 nearly flat, and its optimum goes wherever the pose noise's errors in variables
and the filter's distortion push it, often to the edge of the search range. The criterion is identify's
excitation measure (:mod:`~euc_ros.core.identify.excitation`, :func:`data_bound_h`). The curve's sharpness
is ``sqrt(1 + (0.1 S / RMSE0)^2) - 1``: a curve flatter than
:data:`~euc_ros.core.identify.interval.MIN_SHARPNESS` is a small sensitivity S of the residual to h (too
few speed changes) or a large residual RMSE0 left by an effect the model lacks. The measure tells them
apart by the RMS acceleration from speed changes the criterion needs (S grows with it, RMSE0 does not): within
what a ride gives (:data:`~euc_ros.core.identify.interval.MAX_RIDE_ACCEL_RMS_MPS2`), the ride lacks speed
changes, the data do not bound h, and h is held; beyond it the residual is an effect's (a slope nobody
declared leaves the demo's decelerations an unbounded interval), the residual analysis fits h jointly with
the effect, and h is not held. An interval from the data that is unbounded for other reasons (too few
blocks) is not a want of excitation either: more runs like these bound it.

Then h is held at the segments' geometric h (:func:`geometric_h`: the median distance of the rider CoG G
from the ankle hinge A over the valid samples, which the session's segments give without any dynamics),
with a standard uncertainty of Type B from the tolerances of the session values it rests on
(:func:`geometric_h_uncertainty`). :func:`held_h` makes the record both ``identify`` and ``residual``
report (the JSON's ``h_held``).

Examples
--------
>>> u = geometric_h_uncertainty({"rider.segments.com_offset": 0.01, "euc.l0": 0.005}, l0=0.05)
>>> round(u * 1e3, 2)
6.45
>>> data_bound_h(1.2, 0.5), data_bound_h(0.3, 0.5), data_bound_h(0.3, 11.0), data_bound_h(0.3, None)
(True, False, True, True)
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from euc_ros.core.identify.budget import DEFAULT_TOLERANCES, LOWER_LIMBS, absolute_tolerance
from euc_ros.core.identify.interval import MAX_RIDE_ACCEL_RMS_MPS2, MIN_SHARPNESS
from euc_ros.core.mocap.blocks import pose_block
from euc_ros.core.states.contexts import hinge_path
from euc_ros.core.states.geometry import frame_geometry

#: Normal quantile of the held h's 95 % interval.
Z95 = 1.959964
#: The tolerances (identify's budget keys) the geometric h rests on.
GEOMETRIC_TOLERANCE_KEYS = ("rider.segments.com_offset", "euc.l0", "rider.segments.mass_fraction",
                            "rider.segments.mass_fraction_each")
#: Most frames per recording the mass-fraction sensitivity is taken over (evenly spaced).
SENSITIVITY_FRAMES = 2000
#: What the held value is, for the JSON and the console.
SOURCE = "the segments' geometric h: median |G - A| of the rider CoG over the ankle hinge, valid samples"


def geometric_h(states: Sequence, params) -> float:
    """Median distance of the rider CoG G from the ankle hinge A = C - l0 z_E over the valid samples [m].

    Parameters
    ----------
    states : sequence of RiderStates
        The recordings' states (``G``, ``C`` and the EUC's angles).
    params : EucParams
        The session's parameters (``l0``).

    Returns
    -------
    float
        NaN without a valid sample.
    """
    vals = []
    for st in states:
        d = np.linalg.norm(st.G - hinge_path(st, params.l0), axis=1)
        vals.append(d[np.asarray(st.valid, bool) & np.isfinite(d)])
    v = np.concatenate(vals) if vals else np.zeros(0)
    return float(np.median(v)) if v.size else float("nan")


@dataclass(frozen=True)
class MassSensitivity:
    """How the geometric h moves with the session's mass fractions.

    Parameters
    ----------
    share : float
        dh_g / d(share of the body mass moved from the legs to the upper body) [m per unit of body mass]
        (NaN: not known).
    levers : dict
        dh_g / d(relative change of one segment's fraction, the others rescaled to the same sum) by segment
        name [m per unit relative change]: ``f_i (c_i - G) . e``.
    """

    share: float
    levers: dict

    @property
    def known(self) -> bool:
        """Whether the sensitivities were measured."""
        return math.isfinite(self.share) or bool(self.levers)


def geometric_mass_sensitivity(series_list: Sequence, session) -> MassSensitivity:
    """How the geometric h moves with the mass fractions: a share moved legs -> upper body, and each segment's.

    The session's mass fractions come from anthropometric tables, which differ by about 10 % per segment
    (de Leva 1996 against Dempster's and Zatsiorsky's data). Two ways they can be off:

    * a share ``d`` of the body mass moved from the legs (:data:`~euc_ros.core.identify.budget.LOWER_LIMBS`) to
      the upper body, each side's fractions scaled alike, moves the rider CoG by ``d (G_upper - G_legs)`` (each
      side's fraction-weighted CoM);
    * one segment's fraction ``f_i`` scaled by ``1 + e``, all rescaled to their former sum, moves G by
      ``e f_i (c_i - G)`` to first order (``c_i`` the segment's CoM): its lever.

    To first order the geometric h moves by these along ``(G - A) / |G - A|``. Each is the median over evenly
    spaced frames with every weighted segment and the EUC (at most :data:`SENSITIVITY_FRAMES` per recording); G,
    A and the CoMs come from :func:`~euc_ros.core.states.geometry.frame_geometry`, the reconstruction's own
    geometry.

    Parameters
    ----------
    series_list : sequence of MocapSeries or None
        The recordings (a None: not kept, the sensitivities are not known).
    session : Session
        Mass fractions, CoM offsets, the EUC body and ``l0``.

    Returns
    -------
    MassSensitivity
        ``share`` NaN when one side has no mass; nothing known when a recording is None or no frame has every
        needed body.
    """
    segs = session.rider.segments
    weighted = [n for n, g in segs.items() if g.mass_fraction > 0]
    legs = {n for n in weighted if n in LOWER_LIMBS}
    upper = set(weighted) - legs
    if not weighted or any(series is None for series in series_list):
        return MassSensitivity(float("nan"), {})

    def only(names):         # the session with the other segments weightless: their CoM as G
        moved = {n: g if n in names else dataclasses.replace(g, mass_fraction=0.0) for n, g in segs.items()}
        return dataclasses.replace(session, rider=dataclasses.replace(session.rider, segments=moved))

    sides = (only(legs), only(upper)) if legs and upper else ()
    alone = {n: only({n}) for n in weighted}
    share, levers = [], {n: [] for n in weighted}
    for series in series_list:
        step = max(1, int(series.n_frames) // SENSITIVITY_FRAMES)
        pos, quat, trk = (a[:, ::step] for a in pose_block(series, 0, int(series.n_frames)))
        geo = frame_geometry(pos, quat, trk, session, series.bodies)
        d = geo["G"] - geo["A"]
        e = d / np.linalg.norm(d, axis=1, keepdims=True)
        if sides:
            g_legs, g_upper = (frame_geometry(pos, quat, trk, side, series.bodies)["G"] for side in sides)
            share.append(np.einsum("ij,ij->i", e, g_upper - g_legs))
        for n, one in alone.items():
            c = frame_geometry(pos, quat, trk, one, series.bodies)["G"]
            levers[n].append(segs[n].mass_fraction * np.einsum("ij,ij->i", e, c - geo["G"]))

    def median(parts):       # frames without every weighted segment or the EUC are NaN
        v = np.concatenate(parts) if parts else np.zeros(0)
        v = v[np.isfinite(v)]
        return float(np.median(v)) if v.size else float("nan")

    lv = {n: median(p) for n, p in levers.items()}
    return MassSensitivity(median(share), {n: v for n, v in lv.items() if math.isfinite(v)})


def _mass_term_m(tol: dict, mass_sensitivity: MassSensitivity | None) -> float:
    """The mass fractions' tolerance as a move of the geometric h [m] (NaN when the sensitivities are not known).

    ``sqrt(sum_i (lever_i a_each)^2)``: every segment's own relative error, independent. The legs' share of the
    body mass then scatters by what its segments' errors give it (a standard deviation of about 0.015 of the body
    mass at 10 % per segment, the order of the budget's 0.02), the one error of the tables counted once;
    without the levers, the share moved legs -> upper body (``s a_share``) stands for it.
    """
    if mass_sensitivity is None or not mass_sensitivity.known:
        return float("nan")
    if mass_sensitivity.levers:
        each = np.asarray(list(mass_sensitivity.levers.values()), float)
        return float(absolute_tolerance(tol["rider.segments.mass_fraction_each"], 0.0) * math.sqrt(np.sum(each ** 2)))
    return abs(mass_sensitivity.share) * absolute_tolerance(tol["rider.segments.mass_fraction"], 0.0)


def geometric_h_uncertainty(tolerances: dict | None, *, l0: float,
                            mass_sensitivity: MassSensitivity | None = None) -> float:
    """Standard uncertainty of the geometric h from the tolerances of the values it rests on [m] (Type B).

    Parameters
    ----------
    tolerances : dict or None
        identify's budget tolerances (:data:`~euc_ros.core.identify.budget.DEFAULT_TOLERANCES`, or the
        user's ``--tolerance``); the keys of :data:`GEOMETRIC_TOLERANCE_KEYS` are used.
    l0 : float
        The session's l0 [m] (a tolerance given in per cent is of it).
    mass_sensitivity : MassSensitivity, optional
        :func:`geometric_mass_sensitivity`; with it the mass fractions' tolerances
        (``rider.segments.mass_fraction`` and ``rider.segments.mass_fraction_each``) add their term (None or
        nothing known: left out).

    Returns
    -------
    float

    Notes
    -----
    ``h_g = median_t |G - A|`` with ``G = sum_i f_i (P_i + R_i o_i)`` (mass fractions ``f_i`` summing to 1,
    segment poses ``P_i, R_i``, CoM offsets ``o_i``) and ``A = C - l0 z_E``. Moving every offset by ``d``
    along its body's z axis moves G by ``d sum_i f_i R_i e_z``, a convex combination of unit vectors, so by
    at most ``|d|``; changing l0 by ``e`` moves A by ``e |z_E| = |e|``. By the triangle inequality each
    sample's ``|G - A|`` moves by at most ``|d| + |e|``, and so does the median. For a rider standing on the
    pedals the bodies' z axes and z_E lie close to G - A, so the bound is nearly reached: both sensitivities
    are taken as 1. Each segment's fraction off by a relative ``a_e`` moves it by ``lever_i a_e`` (the levers
    measured by :func:`geometric_mass_sensitivity`; without them, a share ``a_f`` of the body mass moved between
    the legs and the upper body, ``s a_f``, stands for the mass fractions). Each tolerance ``+-a`` is read as a
    rectangular distribution (GUM 4.3.7: standard uncertainty ``a / sqrt(3)``), and they are independent:
    ``u = sqrt(a_offset^2 + a_l0^2 + sum_i (lever_i a_e)^2) / sqrt(3)``.
    """
    tol = dict(DEFAULT_TOLERANCES)
    tol.update(tolerances or {})
    a_offset = absolute_tolerance(tol["rider.segments.com_offset"], 0.0)
    a_l0 = absolute_tolerance(tol["euc.l0"], l0)
    a_mass = _mass_term_m(tol, mass_sensitivity)
    a_mass = a_mass if math.isfinite(a_mass) else 0.0
    return float(math.sqrt(a_offset ** 2 + a_l0 ** 2 + a_mass ** 2) / math.sqrt(3.0))


def data_bound_h(sharpness: float, accel_needed_mps2: float | None) -> bool:
    """Whether the data bound h: False when the RMSE curve is flat for want of the speed changes a ride gives.

    Parameters
    ----------
    sharpness : float
        The pooled 3-DoF RMSE curve's relative rise at h* +- 0.1 m (NaN: not known, not judged).
    accel_needed_mps2 : float or None
        The RMS acceleration from speed changes the sharpness criterion needs (identify's
        ``uncertainty.excitation.speed_change_accel_rms_needed_mps2``); None or NaN: not known, not judged.

    Returns
    -------
    bool
        False when the curve is flatter than :data:`MIN_SHARPNESS` and the acceleration it needs is one a ride
        gives (at most :data:`MAX_RIDE_ACCEL_RMS_MPS2`, the bound beyond which identify's reason names an effect
        the model lacks); else True.
    """
    a = float("nan") if accel_needed_mps2 is None else float(accel_needed_mps2)
    return not (sharpness < MIN_SHARPNESS and a <= MAX_RIDE_ACCEL_RMS_MPS2)


@dataclass(frozen=True)
class HeldH:
    """The held h with its Type B uncertainty and why it is held.

    Parameters
    ----------
    h_m : float
        The segments' geometric h [m] (:func:`geometric_h`).
    std_m : float
        Its standard uncertainty [m] (:func:`geometric_h_uncertainty`).
    reason : str
        Why h is held (the data's verdict).
    h_from_data_m : float
        The h the data alone gave [m] (not for use).
    h_from_data_ci95_m : tuple of float
        Its 95 % interval [m] (an unbounded end is infinite or NaN).
    tolerances_m : dict
        The tolerances the uncertainty comes from [m].
    """

    h_m: float
    std_m: float
    reason: str
    h_from_data_m: float
    h_from_data_ci95_m: tuple[float, float]
    tolerances_m: dict

    @property
    def ci95_m(self) -> tuple[float, float]:
        """The held h's 95 % interval ``h_m -+ 1.96 std_m`` [m]."""
        return self.h_m - Z95 * self.std_m, self.h_m + Z95 * self.std_m

    def to_json(self) -> dict:
        """The JSON's ``h_held``: the value, its uncertainty and interval, the source, the reason, the data's h.

        Returns
        -------
        dict
            ``held``, ``h_m``, ``std_m``, ``ci95_m``, ``source``, ``uncertainty``, ``tolerances_m``, ``reason``,
            ``h_from_data_m`` and ``h_from_data_ci95_m`` (non-finite numbers None).
        """
        def f(v):
            return float(v) if v is not None and math.isfinite(float(v)) else None

        return {"held": True, "h_m": f(self.h_m), "std_m": f(self.std_m), "ci95_m": [f(v) for v in self.ci95_m],
                "source": SOURCE, "uncertainty": "Type B from the session tolerances (rectangular; sensitivity 1 for "
                "the CoM offsets and l0, measured for the mass fractions)",
                "tolerances_m": {k: f(v) for k, v in self.tolerances_m.items()}, "reason": self.reason,
                "h_from_data_m": f(self.h_from_data_m),
                "h_from_data_ci95_m": [f(v) for v in self.h_from_data_ci95_m]}

    def console_line(self) -> str:
        """One line: h is held at the geometric value, why, and the number to use.

        Returns
        -------
        str
        """
        lo, hi = self.ci95_m
        return (f"h held at the segments' geometric h: use h = {self.h_m:.3f} m (standard uncertainty "
                f"{self.std_m * 1e3:.1f} mm from the session tolerances, 95 % interval [{lo:.3f}, {hi:.3f}] m), "
                f"because {self.reason}")


def held_h(states: Sequence, params, h_data: float, ci95, *, tolerances: dict | None = None,
           sharpness: float = float("nan"), accel_needed_mps2: float | None = None,
           mass_sensitivity: MassSensitivity | None = None) -> HeldH | None:
    """The held h when the data do not bound h (:func:`data_bound_h`), else None.

    Parameters
    ----------
    states : sequence of RiderStates
        The recordings' states (the geometric h).
    params : EucParams
        The session's parameters.
    h_data : float
        The h the data gave [m] (identify's headline before holding).
    ci95 : pair of float or None
        Its 95 % interval from the data [m] (for the record; None or non-finite ends: unbounded).
    tolerances : dict, optional
        identify's budget tolerances (default :data:`~euc_ros.core.identify.budget.DEFAULT_TOLERANCES`).
    sharpness : float
        The pooled 3-DoF RMSE curve's relative rise at h* +- 0.1 m (NaN: not judged).
    accel_needed_mps2 : float, optional
        The RMS acceleration the sharpness criterion needs (:func:`data_bound_h`; None: not judged).
    mass_sensitivity : MassSensitivity, optional
        :func:`geometric_mass_sensitivity` (None: the mass fractions' term left out).

    Returns
    -------
    HeldH or None
        None when the data bound h (:func:`data_bound_h`), when nothing about the data's interval is known
        (``ci95`` None: the uncertainty was not computed), or when the geometric h cannot be measured.
    """
    if ci95 is None or data_bound_h(sharpness, accel_needed_mps2):
        return None
    h_g = geometric_h(states, params)
    if not math.isfinite(h_g):
        return None
    tol = dict(DEFAULT_TOLERANCES)
    tol.update(tolerances or {})
    used = {"rider.segments.com_offset": absolute_tolerance(tol["rider.segments.com_offset"], 0.0),
            "euc.l0": absolute_tolerance(tol["euc.l0"], params.l0),
            "rider.segments.mass_fraction": _mass_term_m(tol, mass_sensitivity)}    # both mass keys, as a move of h
    lo, hi = (float("nan") if v is None else float(v) for v in ci95)
    ends = ", ".join("unbounded" if not math.isfinite(v) else f"{v:.3f}" for v in (lo, hi))
    why = (f"the RMSE curve rises only {100 * sharpness:.0f} % at h +- 0.1 m (at least {100 * MIN_SHARPNESS:.0f} % "
           f"needed), and speed changes giving an RMS acceleration of {accel_needed_mps2:.2f} m/s^2, which a ride "
           "gives, would raise it: the ride lacks speed changes")
    reason = f"the data do not bound h: {why} (the data's h, {h_data:.3f} m, 95 % interval [{ends}] m, is not for use)"
    return HeldH(h_g, geometric_h_uncertainty(tolerances, l0=params.l0, mass_sensitivity=mass_sensitivity), reason,
                 float(h_data), (lo, hi), used)
