"""How much a ride excites h, in the lab's terms, and how much more it needs to identify h.

:func:`measure_excitation` measures what the recordings had: the speed change of each recording
(max - min of ``x_dot``), the RMS and peak longitudinal acceleration, the rider's pitch range, the
usable seconds, and the RMS sensitivity ``S`` of the residual to h. :meth:`Excitation.needs` turns
the sharpness criterion into the sensitivity, acceleration and speed change a ride needs;
:func:`more_data_for_blocks` and :func:`more_data_for_seconds` turn the data-amount criteria into
seconds to record and runs to add.

Sharpness from the sensitivity
------------------------------
Near the fitted ``h*`` each sample's residual is ``e_i(h) = r_i + s_i (h - h*) + ...`` with
``s_i = de_i/dh`` [N m per m], and ``sum r_i s_i = 0`` at the minimum, so

    RMSE(h)^2 = RMSE0^2 + S^2 (h - h*)^2,    S = sqrt(mean(s_i^2)),

and the sharpness (mean relative rise of the RMSE at ``h* +- delta``, ``delta`` =
:data:`~euc_ros.core.identify.fit.SHARPNESS_STEP_M`) is ``sqrt(1 + (delta S / RMSE0)^2) - 1``
(:func:`predicted_sharpness`). A sharpness ``sigma`` needs ``S = RMSE0 sqrt((1 + sigma)^2 - 1) / delta``
(:func:`needed_sensitivity`: 15 RMSE0 per m for ``sigma`` = 0.8). Riding longer adds samples of the
same kind and leaves ``S`` and RMSE0 as they are: only more excitation (or less noise) sharpens the curve.

The expansion leaves out the residual's curvature in h. With ``e = c N(h) / D(h)`` (:mod:`.fit`),
``D = d0 + d1 h`` linear and ``N`` quadratic (``a2 = m phi_ddot``), the Taylor coefficients are
``e2 = (c a2 - s d1) / D`` and ``e3 = -e2 d1 / D``, and the two-sided mean of ``e^2`` at ``+-delta``
is ``r^2 + (s^2 + 2 r e2) delta^2 + (e2^2 + 2 s e3) delta^4 + ...`` (the odd powers cancel). Relative
to ``s^2 delta^2`` the left-out terms are ``2 r e2 / s^2`` and ``3 kappa^2 + u^2 - 4 kappa u``, with
``kappa = d1 delta / D`` the relative change of the denominator over ``delta`` (about 0.12:
``m delta / (R m_eq + m h)``) and ``u = c a2 delta / (D s)`` the rider's pitch-acceleration term. So
the rise ``(delta S / RMSE0)^2`` of the mean square is off by at most ``3 kappa^2 + U + 4 kappa sqrt(U)
+ |2 mean(r e2)| / S^2`` relatively (``U = mean(u^2 s^2) / S^2``; :func:`quadratic_error_bound`, 9-16 %
on the simulator's rides). Measured there (decelerations at speed scales 0.2-2, two noise levels): the
rise is within 3 % of the quadratic model's, the sharpness within 8 %.

What the sensitivity is made of
-------------------------------
``N'(h) = m (x_ddot cos phi - g sin phi) + m (R + 2 h) phi_ddot + ...`` (:mod:`~euc_ros.core.model.terms`:
``m13 = m h cos phi``, ``Q_g3 = m g h sin phi``, ``m33 = J + m h^2``): the rider's translational
acceleration against gravity's lean term. In a steady acceleration ``a`` (no pitch rates) the
residual vanishes at the true h, ``m h (a cos phi - g sin phi) = -a B`` with
``B = R m_eq - m l0 + m0 h0``, so ``s = c N' / D = -R m_eq B a / (h D)``: proportional to the
acceleration, with the quasi-static gain ``R m_eq B / (h D)`` [N m/m per m/s^2] (7.6 for the
default session at h = 0.6 m; :func:`quasi_static_gain`, from the residual's coefficients ``c d0 / (h D)``).

The rider's balance corrections (pitch sway, the EUC's balance loop) accelerate too, and they stay
when the speed changes grow. The acceleration is therefore split: ``a_m`` is ``x_ddot`` averaged
over :data:`SPEED_CHANGE_WINDOW_S` (the speed changes), and ``s = alpha a_m + s_o`` by least squares
(``s_o`` orthogonal to ``a_m``), so ``S^2 = S_m^2 + S_o^2`` with ``S_m = |alpha| RMS(a_m)``. Speed
changes ``k`` times as large in the same time make ``S(k)^2 = k^2 S_m^2 + S_o^2``, so the sharpness
criterion needs an RMS acceleration from speed changes of ``sqrt(S_needed^2 - S_o^2) / alpha``, ``k``
times the ride's. ``alpha`` is the ride's own when its speed changes carry a fifth of ``S^2`` or more
(:data:`MIN_SPEED_CHANGE_SHARE`), else the quasi-static gain (the 1-s averages of a constant-speed
ride are balance motion, whose regression says nothing of speed changes). The quadratic model is
calibrated on the measured sharpness first (:meth:`Excitation.needs`), so its few % do not enter.

Measured on the simulator (decelerations at speed scales 0.2-1.2, three seeds, noise twice the
default): ``k`` predicts the speed scale at which the sharpness reaches 0.8 within 4 % for ``k``
up to 2.2, within 16 % up to ``k`` = 5, and the needed RMS acceleration predicted from rides of one
seed at all speed scales agrees within 8 %. Scaling the total RMS acceleration by ``S_needed / S``
instead (all acceleration alike) falls short by up to 30 %: the balance motion does not grow with
the speed changes.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from euc_ros.core.identify.fit import SHARPNESS_STEP_M

#: Averaging window that separates the speed changes from the balance motion in ``x_ddot`` [s]. The
#: rider's sway and the EUC's balance loop move at 0.3-1.5 Hz, a speed change over seconds; chosen by
#: measurement on the simulator's decelerations (0.5 s leaves the balance motion in and predicts the
#: needed speed change up to 60 % low, 3 s smooths the speed changes and predicts it up to 50 % high;
#: 1 and 2 s did best).
SPEED_CHANGE_WINDOW_S = 1.0
#: Smallest ``S_m / S_o`` for which the ride's own gain ``alpha`` is used (its speed changes carry at least a
#: fifth of ``S^2``): below it the regression measures balance motion (on the simulator's constant-speed
#: rides ``alpha`` scatters from 0.3 to 1.6 times the quasi-static gain, on its decelerations 0.8 to 1.2).
MIN_SPEED_CHANGE_SHARE = 0.5


def sensitivities(coef: np.ndarray, h: float) -> np.ndarray:
    """Per-sample ``s = de/dh`` of the residual ``e = c N / D`` at ``h`` [N m per m].

    Parameters
    ----------
    coef : ndarray (6, n)
        Rows ``c, a0, a1, a2, d0, d1`` of :func:`~euc_ros.core.identify.fit.residual_coefficients`.
    h : float
        CoG height [m].

    Returns
    -------
    ndarray (n,)
        ``de/dh`` of every sample [N m per m].
    """
    c, a0, a1, a2, d0, d1 = coef
    n = a0 + h * (a1 + h * a2)
    d = d0 + d1 * h
    return c * ((a1 + 2.0 * a2 * h) * d - n * d1) / (d * d)


def needed_sensitivity(rmse_nm: float, min_sharpness: float, step_m: float = SHARPNESS_STEP_M) -> float:
    """RMS sensitivity ``S`` [N m per m] whose quadratic RMSE curve rises by ``min_sharpness`` at ``+-step_m``.

    Parameters
    ----------
    rmse_nm : float
        RMSE at the optimum, RMSE0 [N m].
    min_sharpness : float
        Relative rise of the RMSE curve wanted at ``+-step_m``.
    step_m : float
        Distance from the optimum [m].

    Returns
    -------
    float
        ``RMSE0 sqrt((1 + min_sharpness)^2 - 1) / step_m`` [N m per m].
    """
    return float(rmse_nm * math.sqrt(max((1.0 + min_sharpness) ** 2 - 1.0, 0.0)) / step_m)


def predicted_sharpness(sensitivity: float, rmse_nm: float, step_m: float = SHARPNESS_STEP_M) -> float:
    """Relative rise ``sqrt(1 + (step S / RMSE0)^2) - 1`` of the quadratic RMSE curve at ``+-step_m``.

    Parameters
    ----------
    sensitivity : float
        RMS sensitivity ``S`` of the residual to h [N m per m].
    rmse_nm : float
        RMSE at the optimum, RMSE0 [N m].
    step_m : float
        Distance from the optimum [m].

    Returns
    -------
    float
        The sharpness (inf when ``rmse_nm`` is not positive).
    """
    return float(math.sqrt(1.0 + (step_m * sensitivity / rmse_nm) ** 2) - 1.0) if rmse_nm > 0 else math.inf


def quasi_static_gain(coefs: Sequence[np.ndarray], h: float) -> float:
    """``R m_eq B / (h D)`` [N m per m, per m/s^2]: the sensitivity a steady acceleration of 1 m/s^2 gives.

    See the module docstring. Taken as the mean of ``|c d0 / (h D)|`` over the samples (``c = R m_eq``, ``d0 = B`` at
    level EUC pitch); NaN without samples.

    Parameters
    ----------
    coefs : sequence of ndarray (6, n_i)
        Per recording, the residual coefficients of its valid samples.
    h : float
        CoG height [m].

    Returns
    -------
    float
        The gain [N m per m, per m/s^2].
    """
    num = cnt = 0.0
    for coef in coefs:
        if coef.shape[1] == 0:
            continue
        c, _, _, _, d0, d1 = coef
        g = np.abs(c * d0 / (h * (d0 + d1 * h)))
        g = g[np.isfinite(g)]
        num += float(g.sum())
        cnt += g.size
    return num / cnt if cnt else float("nan")


def quadratic_error_bound(coefs: Sequence[np.ndarray], h: float, step_m: float = SHARPNESS_STEP_M) -> float:
    """Bound on the relative error of the quadratic model's rise ``(step S / RMSE0)^2`` of the mean square residual.

    The rise is the two-sided one; the bound is ``3 kappa^2 + U + 4 kappa sqrt(U) + |2 mean(r e2)| / S^2`` (module
    docstring; ``kappa^2`` and ``U`` weighted by ``s^2`` over the samples); NaN without samples.

    Parameters
    ----------
    coefs : sequence of ndarray (6, n_i)
        Per recording, the residual coefficients of its valid samples.
    h : float
        The fitted h [m].
    step_m : float
        Distance from the optimum [m].

    Returns
    -------
    float
        The relative error bound.
    """
    sk = ss = su = sr = 0.0
    for coef in coefs:
        if coef.shape[1] == 0:
            continue
        c, a0, a1, a2, d0, d1 = coef
        d = d0 + d1 * h
        s = sensitivities(coef, h)
        e2 = (c * a2 - s * d1) / d
        r = c * (a0 + h * (a1 + h * a2)) / d
        sk += float(np.sum((s * d1 * step_m / d) ** 2))
        su += float(np.sum((c * a2 * step_m / d) ** 2))
        sr += float(np.sum(r * e2))
        ss += float(np.sum(s * s))
    if not ss > 0:
        return float("nan")
    kappa2, u = sk / ss, su / ss
    return 3.0 * kappa2 + u + 4.0 * math.sqrt(kappa2 * u) + abs(2.0 * sr) / ss


@dataclass(frozen=True)
class Needs:
    """What the sharpness criterion needs of a ride, from :meth:`Excitation.needs`.

    Parameters
    ----------
    sensitivity_nm_per_m : float
        RMS sensitivity ``S`` needed [N m per m].
    speed_change_factor : float
        How many times the recordings' speed changes (in the same time) give it (< 1: a margin; 0 when the
        balance motion alone gives it; inf when the recordings have no speed change).
    speed_change_accel_rms_mps2 : float
        RMS acceleration from speed changes needed [m/s^2].
    accel_rms_mps2 : float
        Total RMS longitudinal acceleration needed (the balance motion as recorded) [m/s^2].
    speed_change_mps : tuple of float
        Per recording, its speed change times the factor [m/s] (inf without a speed change): the speed
        change needed with the recording's profile (meaningful when its speed changes carry the
        sensitivity, :attr:`Excitation.gain_from_ride`).
    """

    sensitivity_nm_per_m: float
    speed_change_factor: float
    speed_change_accel_rms_mps2: float
    accel_rms_mps2: float
    speed_change_mps: tuple


@dataclass(frozen=True)
class Excitation:
    """What excites h in a set of recordings (their valid samples), in the lab's terms.

    Without the recordings' states the ride's quantities are NaN (or empty) and only the
    sensitivities are measured.

    Parameters
    ----------
    usable_s : tuple of float
        Per recording, the seconds of valid samples [s] (empty without the states).
    speed_change_mps : tuple of float
        Per recording, max - min of ``x_dot`` [m/s].
    phi_range_rad : tuple of float
        Per recording, max - min of the rider's pitch ``phi`` [rad].
    accel_rms_mps2, accel_peak_mps2 : float
        RMS and largest absolute longitudinal acceleration ``x_ddot`` [m/s^2].
    speed_change_accel_rms_mps2 : float
        RMS of ``x_ddot`` averaged over :data:`SPEED_CHANGE_WINDOW_S`: the speed changes' share [m/s^2].
    speed_rms_mps : float
        RMS of ``x_dot`` [m/s].
    sensitivity_nm_per_m : float
        RMS sensitivity ``S`` of the residual to h at the fitted h [N m per m].
    speed_change_sensitivity_nm_per_m, other_sensitivity_nm_per_m : float
        ``S_m`` and ``S_o`` (``S^2 = S_m^2 + S_o^2``; module docstring).
    gain : float
        Sensitivity per m/s^2 of speed-change acceleration [N m per m, per m/s^2]: the ride's own
        (``|alpha|``) when its speed changes carry a fifth of ``S^2`` or more, else the quasi-static gain.
    gain_from_ride : bool
        Whether :attr:`gain` is the ride's own (else the recordings' averaged accelerations are mostly
        balance motion, whose regression says nothing of speed changes).
    rmse_nm : float
        RMSE of ``M_d1 - M_d2`` at the fitted h [N m].
    """

    usable_s: tuple
    speed_change_mps: tuple
    phi_range_rad: tuple
    accel_rms_mps2: float
    accel_peak_mps2: float
    speed_change_accel_rms_mps2: float
    speed_rms_mps: float
    sensitivity_nm_per_m: float
    speed_change_sensitivity_nm_per_m: float
    other_sensitivity_nm_per_m: float
    gain: float
    gain_from_ride: bool
    rmse_nm: float

    @property
    def has_ride(self) -> bool:
        """The ride's quantities were measured (the states were given)."""
        return bool(self.speed_change_mps) and math.isfinite(self.accel_rms_mps2)

    def needs(self, min_sharpness: float, step_m: float = SHARPNESS_STEP_M, sharpness: float | None = None) -> Needs:
        """What a sharpness of ``min_sharpness`` needs (module docstring).

        ``sharpness``, the RMSE curve's measured one, calibrates the quadratic model: the sensitivities
        are scaled to the ``S`` that gives it (a few % from the measured ``S``), and the factor is then
        at least ``S_needed / S`` for a ride below the criterion and at most that for one above it
        (``S(k)`` lies between ``S`` and ``k S``), so the factor never reads as enough for a ride that
        falls short, nor as short for one that has enough.

        Parameters
        ----------
        min_sharpness : float
            The sharpness wanted (relative RMSE rise at ``+-step_m``).
        step_m : float
            Distance from the optimum [m].
        sharpness : float, optional
            The RMSE curve's measured sharpness (None: the quadratic model uncalibrated).

        Returns
        -------
        Needs
        """
        s_n = needed_sensitivity(self.rmse_nm, min_sharpness, step_m)
        q = 1.0
        if sharpness is not None and math.isfinite(sharpness) and sharpness > 0 and self.sensitivity_nm_per_m > 0:
            # a curve that does not rise (sharpness <= 0: its minimum at a bound, or flat) calibrates nothing
            q = needed_sensitivity(self.rmse_nm, sharpness, step_m) / self.sensitivity_nm_per_m
        s_o, a_m, gain = q * self.other_sensitivity_nm_per_m, self.speed_change_accel_rms_mps2, q * self.gain
        rest = math.sqrt(max(s_n * s_n - s_o * s_o, 0.0)) if math.isfinite(s_o) else float("nan")
        am_needed = rest / gain if gain > 0 else float("nan")
        if not (math.isfinite(am_needed) and math.isfinite(a_m)):
            k = float("nan")
        elif am_needed == 0.0:
            k = 0.0
        else:
            k = am_needed / a_m if a_m > 0 else math.inf
        if sharpness is not None and math.isfinite(sharpness) and math.isfinite(k) and self.sensitivity_nm_per_m > 0:
            # S(k)^2 = k^2 S_m^2 + S_o^2 lies between k^2 S^2 and S^2: the factor is at least S_needed / S
            # when the ride falls short and at most that when it has enough, whatever the gain
            k0 = s_n / (q * self.sensitivity_nm_per_m)
            k = max(k, k0) if sharpness < min_sharpness else min(k, k0)
            am_needed = k * a_m
        a = self.accel_rms_mps2
        total = math.sqrt(max(a * a - a_m * a_m, 0.0) + am_needed * am_needed) if math.isfinite(a) else float("nan")
        return Needs(s_n, k, am_needed, total, tuple(k * v if k != 0.0 else 0.0 for v in self.speed_change_mps))


def measure_excitation(coefs: Sequence[np.ndarray], h: float, rmse_nm: float, states=None, *,
                       window_s: float = SPEED_CHANGE_WINDOW_S) -> Excitation:
    """Measure a set of recordings' excitation of h.

    Parameters
    ----------
    coefs : sequence of ndarray (6, n_i)
        Per recording, the residual coefficients of its valid samples in time order
        (:func:`~euc_ros.core.identify.fit.coefficients_for`).
    h : float
        The fitted h [m].
    rmse_nm : float
        The RMSE at ``h`` [N m].
    states : sequence of RiderStates, optional
        The recordings' states, in the order of ``coefs`` (their valid samples are the coefficients'
        columns): the lab's quantities and the split of ``S`` need them.
    window_s : float
        Averaging window of the speed changes [s].

    Returns
    -------
    Excitation
    """
    from scipy.ndimage import uniform_filter1d

    nan = float("nan")
    n = 0
    s2 = sa = aa = xx = vv = 0.0
    peak = 0.0
    usable, dv, dphi = [], [], []
    for k, coef in enumerate(coefs):
        st = states[k] if states is not None else None
        m = coef.shape[1]
        if st is not None:
            usable.append(m * float(st.dt))
        if m == 0:
            if st is not None:
                dv.append(nan)
                dphi.append(nan)
            continue
        s = sensitivities(coef, h)
        s = np.where(np.isfinite(s), s, 0.0)
        s2 += float(np.dot(s, s))
        n += m
        if st is None:
            continue
        ok = np.asarray(st.valid, bool)
        xdd = np.asarray(st.x_ddot, float)[ok]
        xd = np.asarray(st.x_dot, float)[ok]
        phi = np.asarray(st.phi, float)[ok]
        am = uniform_filter1d(xdd, max(1, int(round(window_s / float(st.dt)))), mode="nearest")
        sa += float(np.dot(s, am))
        aa += float(np.dot(am, am))
        xx += float(np.dot(xdd, xdd))
        vv += float(np.dot(xd, xd))
        peak = max(peak, float(np.max(np.abs(xdd))))
        dv.append(float(np.ptp(xd)))
        dphi.append(float(np.ptp(phi)))
    S = math.sqrt(s2 / n) if n else nan
    ride = states is not None and n > 0
    if ride:
        alpha = sa / aa if aa > 0 else 0.0
        s_m = math.sqrt(alpha * alpha * aa / n)
        s_o = math.sqrt(max(S * S - s_m * s_m, 0.0))
        from_ride = bool(s_m > 0 and s_m >= MIN_SPEED_CHANGE_SHARE * s_o)
        gain = abs(alpha) if from_ride else quasi_static_gain(coefs, h)
        a_rms, a_m, v_rms = math.sqrt(xx / n), math.sqrt(aa / n), math.sqrt(vv / n)
    else:
        s_m = s_o = a_rms = a_m = v_rms = peak = nan
        gain, from_ride = (quasi_static_gain(coefs, h) if n else nan), False
    return Excitation(tuple(usable), tuple(dv), tuple(dphi), a_rms, peak, a_m, v_rms, S, s_m, s_o, gain, from_ride,
                      float(rmse_nm))


def more_data_for_blocks(counts: Sequence[int], n_per_recording: Sequence[int], length: int, needed: int,
                         dt: float) -> tuple[float, int]:
    """How much more recording gives ``needed`` blocks: ``(seconds more in one take, more runs like these)``.

    Parameters
    ----------
    counts : sequence of int
        Per recording, its blocks (:func:`~euc_ros.core.identify.bootstrap.block_counts`: ``max(1, n // length)``,
        0 without samples).
    n_per_recording : sequence of int
        Per recording, its valid samples.
    length : int
        Block length [samples].
    needed : int
        Blocks needed.
    dt : float
        Sample period [s].

    Returns
    -------
    (float, int)
        The usable seconds one take needs to grow by (the take for which that is least), and the
        number of added runs of the median recording's blocks; ``(0, 0)`` when there are enough.
    """
    deficit = int(needed) - int(sum(counts))
    if deficit <= 0:
        return 0.0, 0
    if length <= 0 or not counts:
        return float("nan"), 0
    # one take with b blocks reaches b + deficit at (b + deficit) * length samples (a take shorter than a
    # block counts as one)
    more = min(((max(b, 1) + deficit) * length - nk) for b, nk in zip(counts, n_per_recording))
    typical = max(1, int(np.median([nk for nk in n_per_recording if nk > 0] or [0])) // length)
    return max(more, 0) * float(dt), int(math.ceil(deficit / typical))


def more_data_for_seconds(usable_s: Sequence[float], needed_s: float) -> tuple[float, int]:
    """``(usable seconds more, more runs like these)`` for a total of ``needed_s`` usable seconds.

    A run like these has the median recording's usable seconds; ``(0, 0)`` when there are enough.

    Parameters
    ----------
    usable_s : sequence of float
        Per recording, its usable seconds [s].
    needed_s : float
        Usable seconds needed in all [s].

    Returns
    -------
    (float, int)
        The seconds missing [s], and the runs like these that add them (0 when no recording has usable seconds).
    """
    have = float(sum(usable_s))
    short = float(needed_s) - have
    if short <= 0:
        return 0.0, 0
    typical = float(np.median([u for u in usable_s if u > 0] or [0.0]))
    return short, (int(math.ceil(short / typical)) if typical > 0 else 0)
