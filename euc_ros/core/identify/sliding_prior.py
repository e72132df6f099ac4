"""The soft tissue no kinematic check can see: a stated prior, propagated into h by re-simulation.

Markers sit on skin and clothes, so every rider rigid body slides against its bone. Sliding that
differs between two linked bodies shows in the chain's links and is measured
(:mod:`euc_ros.core.identify.sliding`). Sliding that all the rider's bodies share, a rigid rider's
soft tissue following the common motion, moves the measured CoG G as a whole and shows nowhere: the
data cannot settle it, so its size is a stated prior and its effect on h goes into the interval.

The prior (:class:`SlidingPrior`) is the RMS of a common displacement of G per in-plane axis, in the
band of the motion (``band_hz``), a share ``accel_share`` of its variance following G's acceleration
with the opposite sign (soft tissue lags behind the bone) and the rest band-limited white noise. Its
size is user-settable (``--sliding-prior-mm``; 0 leaves it out). By default it comes from the recording:
the sliding the links show, mass-weighted with every body in phase (:func:`rms_from_sliding`), i.e. the
common part is taken as large as the parts that differ. The biomechanics literature puts skin-mounted
cluster motion against the bone at a few millimetres on the trunk and pelvis and up to 1-3 cm on the
thigh during gait (Leardini et al. 2005, Gait & Posture 21:212-225; Peters et al. 2010, Gait & Posture
31:1-8); it does not split it into shared and differing parts, so no fixed default is taken from it:
h is so sensitive to a shared, acceleration-following sliding (measured on simulated rides: about
45 mm of h per mm of RMS) that a fixed millimetre would make every interval some 10 cm wide, also on
rides whose links show no sliding at all.

Propagation (:func:`prior_spread`): G enters the model only through the rider pitch phi (the angle of
the line A-G, or C-G, in the moving frame), so a displacement ``(dx, dz)`` of G moves phi by
``(r_z dx - r_x dz) / |r|^2`` (``r`` = A-G in the moving frame). Every replicate adds one draw of
the prior to phi (the sliding the recording may hold, once more) and subtracts it (the recording
without it), filters phi with the states' own Savitzky-Golay filter and fits h again; the draws come
in antithetic pairs of the white part. ``h(+) - h`` and ``h - h(-)`` both estimate how far h lies
from the truth under the prior (equal for a linear response; h saturates for large slides, where
only one of them is right); their extremes over the replicates, with 0, are the range the interval is
extended by, on the side it points to, and never narrowed.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.signal import butter, sosfiltfilt

from euc_ros.core.errors import ConfigError
from euc_ros.core.filters.derivatives import savgol_derivatives
from euc_ros.core.identify.fit import DEFAULT_H_GRID, coefficients_for, pooled_fit
from euc_ros.core.states.geometry import to_moving_frame

#: Replicates of :func:`prior_spread` (antithetic pairs of the white part).
PRIOR_REPLICATES = 2
#: Seed of the prior's draws (the same recording gives the same interval).
PRIOR_SEED = 7


@dataclass(frozen=True)
class SlidingPrior:
    """Common sliding of the rider's CoG that the data cannot see.

    Parameters
    ----------
    rms_m : float or None
        RMS displacement of G per in-plane axis (forward, up) [m]; 0 for none; None (the default): from
        the recording, the mass-weighted sliding the chain's links show (:func:`rms_from_sliding`).
    band_hz : (float, float)
        Its frequency band [Hz].
    accel_share : float
        Share of its variance that follows G's acceleration with the opposite sign (0-1).

    Raises
    ------
    ConfigError
        ``rms_m`` outside 0-0.1 m, a band not ``0 < low < high``, or ``accel_share`` outside [0, 1].
    """

    rms_m: float | None = None
    band_hz: tuple[float, float] = (0.3, 3.0)
    accel_share: float = 0.5

    def __post_init__(self) -> None:
        if self.rms_m is not None and not (np.isfinite(self.rms_m) and 0.0 <= self.rms_m <= 0.1):
            raise ConfigError(f"the sliding prior's RMS must be 0-100 mm, got {self.rms_m * 1e3:g} mm",
                              key="--sliding-prior-mm")
        lo, hi = self.band_hz
        if not 0.0 < lo < hi:
            raise ConfigError(f"need 0 < low < high, got {self.band_hz}", key="band_hz")
        if not 0.0 <= self.accel_share <= 1.0:
            raise ConfigError(f"must be in [0, 1], got {self.accel_share}", key="accel_share")


def rms_from_sliding(sliding: dict | None, session, min_rms_m: float) -> float:
    """The prior's RMS from the measured sliding: ``sum_i f_i rms_i`` over the rider's bodies [m].

    ``f_i``: the mass fractions; every body's sliding is taken in phase, the most a common part can be. 0 when no body
    slides by ``min_rms_m`` or more (white noise and round-off) or nothing was measured.

    Parameters
    ----------
    sliding : dict or None
        The measured sliding (:func:`~euc_ros.core.states.link_sliding.estimate_sliding`: ``bodies``, ``rms_m``,
        ``rms_max_m``).
    session : Session
        The session (the segments' mass fractions).
    min_rms_m : float
        Smallest sliding counted [m].

    Returns
    -------
    float
        The prior's RMS [m].
    """
    if not sliding or float(sliding.get("rms_max_m") or 0.0) < min_rms_m:
        return 0.0
    names, fractions, _ = session.segment_arrays()
    frac = dict(zip(names, fractions))
    return float(sum(frac.get(b, 0.0) * float(r) for b, r in zip(sliding["bodies"], sliding["rms_m"])))


def _pitch_lever(st, l0: float) -> tuple[np.ndarray, np.ndarray]:
    """``(r_x, r_z)``: the rider line (A-G for the hinge pitch, C-G for eq (3)) in the moving frame [m]."""
    r = to_moving_frame(np.asarray(st.G, float) - np.asarray(st.C, float), st.psi, st.theta)
    rx, rz = r[:, 0], r[:, 2]
    if st.phi_definition == "hinge":
        rx = rx + l0 * np.sin(st.gamma)
        rz = rz + l0 * np.cos(st.gamma)
    return rx, rz


def _band(x: np.ndarray, dt: float, band: tuple[float, float]) -> np.ndarray:
    """Zero-phase band-pass of the finite samples of ``x`` (NaN as 0), unit RMS over the finite ones."""
    ok = np.isfinite(x)
    nyq = 0.5 / dt
    lo, hi = band[0] / nyq, min(band[1] / nyq, 0.99)
    y = np.where(ok, x, 0.0)
    if y.size > 30 and lo < hi:
        sos = butter(2, [lo, hi], btype="band", output="sos")
        y = sosfiltfilt(sos, y)
    rms = float(np.sqrt(np.mean(y[ok] ** 2))) if ok.any() else 0.0
    return y / rms if rms > 0 else np.zeros_like(y)


def _phi_shifts(st, l0: float, prior: SlidingPrior, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """The acceleration-following and the white parts of one draw's shift of phi [rad] (n,) each."""
    dt = float(st.dt)
    rx, rz = _pitch_lever(st, l0)
    r2 = rx * rx + rz * rz
    # G's acceleration in the moving frame from the filtered states: C's plus the rider line's rotation
    L = np.sqrt(r2)
    ph, pd, pdd = st.phi, st.phi_dot, st.phi_ddot
    ax = st.x_ddot + L * (np.cos(ph) * pdd - np.sin(ph) * pd * pd)
    az = -L * (np.sin(ph) * pdd + np.cos(ph) * pd * pd)
    c = prior.accel_share
    acc = [-np.sqrt(c) * _band(a, dt, prior.band_hz) for a in (ax, az)]
    white = [np.sqrt(1.0 - c) * _band(rng.standard_normal(st.n), dt, prior.band_hz) for _ in range(2)]

    def to_phi(dx, dz):
        with np.errstate(invalid="ignore", divide="ignore"):
            return prior.rms_m * (rz * dx - rx * dz) / r2

    return to_phi(*acc), to_phi(*white)


def _refiltered(st, phi_raw: np.ndarray):
    d = savgol_derivatives(float(st.dt), phi_raw, window=int(st.window), polyorder=int(st.polyorder),
                           frame=np.asarray(st.frame))
    return dataclasses.replace(st, phi=d.y, phi_dot=d.y_dot, phi_ddot=d.y_ddot, valid=st.valid & np.isfinite(d.y_ddot))


def prior_spread(states, params, h: float, prior: SlidingPrior = SlidingPrior(), *,
                 replicates: int = PRIOR_REPLICATES, seed: int = PRIOR_SEED) -> dict:
    """How far the common sliding of the prior moves h (see the module docstring).

    Parameters
    ----------
    states : sequence of RiderStates
        The recordings' states (their ``window``, ``polyorder`` and ``phi_definition`` are used).
    params : EucParams
    h : float
        The pooled 3-DoF h of ``states`` [m].
    prior : SlidingPrior
    replicates : int
        Draws: each in antithetic pairs of the white part, each added and subtracted (``2 replicates``
        fits).
    seed : int

    Returns
    -------
    dict
        ``sliding_prior_rms_m`` (the prior), ``sliding_prior_shift_m`` (mean change of h over the
        replicates), ``sliding_prior_sd_m`` (their standard deviation) and ``sliding_prior_range_m``
        ``[lo, hi]``: the change of h the prior allows (the replicates' extremes, widened to contain 0).
        Zeros for a prior of 0 or NaN h.
    """
    if prior.rms_m is None:
        raise ConfigError("the prior's RMS must be resolved first (rms_from_sliding)", key="rms_m")
    zero = {"sliding_prior_rms_m": float(prior.rms_m), "sliding_prior_shift_m": 0.0, "sliding_prior_sd_m": 0.0,
            "sliding_prior_range_m": [0.0, 0.0]}
    if prior.rms_m == 0.0 or not np.isfinite(h) or not states:
        return zero
    rng = np.random.default_rng(seed)
    l0 = float(params.l0)
    raw = [np.asarray(st.phi_hinge if st.phi_definition == "hinge" else st.phi_eq3, float) for st in states]

    def h_with(shifts) -> float:
        coefs = []
        for st, y, d in zip(states, raw, shifts):
            coefs += coefficients_for([_refiltered(st, y + np.nan_to_num(d))], params, "3dof", None)
        return float(pooled_fit(coefs, DEFAULT_H_GRID, "3dof").h_m)

    dh = []
    for _ in range(max(1, replicates // 2)):
        parts = [_phi_shifts(st, l0, prior, rng) for st in states]
        for white_sign in (1.0, -1.0):
            # the recording plus one draw (the sliding it may hold, once more) and minus it (the recording
            # without the sliding it may hold): h - truth is about h(+) - h, or h - h(-), whichever the
            # response's curvature makes larger
            plus = h_with([acc + white_sign * white for acc, white in parts])
            minus = h_with([-(acc + white_sign * white) for acc, white in parts])
            dh += [plus - float(h), float(h) - minus]
    dh = np.asarray(dh)
    dh = dh[np.isfinite(dh)]
    if dh.size == 0:
        return zero
    mean = float(np.mean(dh))
    sd = float(np.std(dh, ddof=1)) if dh.size > 1 else 0.0
    lo, hi = min(0.0, float(dh.min())), max(0.0, float(dh.max()))
    return {"sliding_prior_rms_m": float(prior.rms_m), "sliding_prior_shift_m": mean, "sliding_prior_sd_m": sd,
            "sliding_prior_range_m": [lo, hi]}
