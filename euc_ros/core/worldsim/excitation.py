"""What drives a ride: band-limited disturbances and speed profiles, smooth and evaluable at any time.

Both are closed-form functions of time (sums of sinusoids, piecewise cosine ramps), so the integrator
sees a smooth input and its error control is not spent on interpolation knots.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Disturbance band limits the generator draws from [Hz].
BAND_LIMITS_HZ = (0.1, 3.0)
#: The band-pass is kept up to this multiple of its upper corner (the rest of the skirt is dropped).
SKIRT_FACTOR = 2.5


@dataclass(frozen=True)
class BandNoise:
    """One realization of band-limited Gaussian noise, ``d(t) = sum_k a_k cos(2 pi f_k t) + b_k sin(2 pi f_k t)``.

    Parameters
    ----------
    freqs : ndarray (k,)
        Frequencies [Hz] (multiples of ``1 / period``).
    a, b : ndarray (k,)
        Cosine and sine amplitudes [unit of the disturbance].
    """

    freqs: np.ndarray
    a: np.ndarray
    b: np.ndarray

    def __call__(self, t, deriv: int = 0):
        """Value (``deriv=0``) or first time derivative (``deriv=1``) at times ``t`` (any shape)."""
        t = np.asarray(t, dtype=float)
        w = 2.0 * np.pi * self.freqs
        ph = t[..., None] * w
        if deriv == 0:
            return np.cos(ph) @ self.a + np.sin(ph) @ self.b
        if deriv == 1:
            return np.cos(ph) @ (w * self.b) - np.sin(ph) @ (w * self.a)
        raise ValueError(f"deriv must be 0 or 1, got {deriv}")

    @property
    def rms(self) -> float:
        """Root mean square over one period [unit]: ``sqrt(sum (a_k^2 + b_k^2) / 2)``."""
        return float(np.sqrt(0.5 * np.sum(self.a**2 + self.b**2)))

    @staticmethod
    def zero() -> "BandNoise":
        """A disturbance that is identically zero.

        Returns
        -------
        BandNoise
            With no frequencies.
        """
        return BandNoise(np.zeros(0), np.zeros(0), np.zeros(0))


def band_noise(rng: np.random.Generator, period: float, f_lo: float, f_hi: float, rms: float,
               order_lo: int = 2, order_hi: int = 4) -> BandNoise:
    r"""Draw Gaussian noise filtered by a Butterworth-type band-pass, as a sum of sinusoids.

    Parameters
    ----------
    rng : numpy.random.Generator
    period : float
        Period of the realization [s] (at least the ride's duration); the frequency grid is
        ``k / period``.
    f_lo, f_hi : float
        Band corners [Hz], ``0 < f_lo < f_hi``.
    rms : float
        Root mean square of the result over one period.
    order_lo, order_hi : int
        Orders of the high-pass (lower skirt) and of the low-pass (upper skirt).

    Returns
    -------
    BandNoise

    Notes
    -----
    White Gaussian noise of period ``P`` has independent normal cosine and sine coefficients on the
    grid ``f_k = k / P``. Filtering multiplies them by the gain

    .. math:: |H(f)| = \frac{(f/f_{lo})^{n_l}}{\sqrt{1 + (f/f_{lo})^{2n_l}}}
              \frac{1}{\sqrt{1 + (f/f_{hi})^{2n_h}}},

    the magnitude of an order-``n_l`` Butterworth high-pass at ``f_lo`` in series with an order-``n_h``
    low-pass at ``f_hi``. The upper skirt is the steeper one: a disturbance torque's second
    derivative (what a pitch acceleration sees through a stiff loop) weights its power by ``f^4``,
    which an order-2 skirt would leave flat above ``f_hi``. The grid stops at
    ``SKIRT_FACTOR * f_hi``. The realization is scaled to the requested rms exactly.
    """
    if not (0.0 < f_lo < f_hi) or period <= 0.0:
        raise ValueError(f"need 0 < f_lo < f_hi and period > 0, got {f_lo}, {f_hi}, {period}")
    k = np.arange(1, int(np.floor(SKIRT_FACTOR * f_hi * period)) + 1)
    f = k / period
    gain = ((f / f_lo) ** order_lo / np.sqrt(1.0 + (f / f_lo) ** (2 * order_lo))
            / np.sqrt(1.0 + (f / f_hi) ** (2 * order_hi)))
    a = rng.standard_normal(f.size) * gain
    b = rng.standard_normal(f.size) * gain
    noise = BandNoise(f, a, b)
    scale = rms / noise.rms if noise.rms > 0 else 0.0
    return BandNoise(f, a * scale, b * scale)


def random_band(rng: np.random.Generator, limits=BAND_LIMITS_HZ, min_ratio: float = 3.0) -> tuple[float, float]:
    """Draw band corners ``f_lo < f_hi`` log-uniformly within ``limits`` with ``f_hi / f_lo >= min_ratio``.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the draws.
    limits : (float, float)
        Lowest and highest corner [Hz], at least ``min_ratio`` apart as a ratio.
    min_ratio : float
        Smallest ratio ``f_hi / f_lo``.

    Returns
    -------
    tuple of float
        ``(f_lo, f_hi)`` [Hz]: ``f_hi`` first, log-uniform in ``[limits[0] min_ratio, limits[1]]``, then
        ``f_lo`` log-uniform in ``[limits[0], f_hi / min_ratio]``.
    """
    lo, hi = np.log(limits[0]), np.log(limits[1])
    f_hi = float(np.exp(rng.uniform(lo + np.log(min_ratio), hi)))
    f_lo = float(np.exp(rng.uniform(lo, np.log(f_hi / min_ratio))))
    return f_lo, f_hi


@dataclass(frozen=True)
class SpeedProfile:
    """Piecewise speed reference: holds joined by cosine-acceleration ramps.

    Parameters
    ----------
    t0, t1 : ndarray (k,)
        Start and end of each piece [s], contiguous (``t0[i+1] == t1[i]``).
    v0, v1 : ndarray (k,)
        Speed at the start and end of each piece [m/s] (equal on a hold).

    Notes
    -----
    On a piece of duration ``D`` with ``tau = (t - t0) / D``,
    ``v = v0 + (v1 - v0) (tau - sin(2 pi tau) / (2 pi))`` and
    ``a = (v1 - v0) / D (1 - cos(2 pi tau))``: the acceleration rises and falls smoothly (zero at
    both ends, peak twice the mean), so the speed reference is continuously differentiable.
    Before ``t0[0]`` and after ``t1[-1]`` the speed is held.
    """

    t0: np.ndarray
    t1: np.ndarray
    v0: np.ndarray
    v1: np.ndarray

    def _piece(self, t):
        t = np.asarray(t, dtype=float)
        i = np.clip(np.searchsorted(self.t0, t, side="right") - 1, 0, self.t0.size - 1)
        d = self.t1[i] - self.t0[i]
        tau = np.clip((t - self.t0[i]) / d, 0.0, 1.0)
        return i, d, tau

    def speed(self, t):
        """Reference speed [m/s] at ``t``.

        Parameters
        ----------
        t : array_like
            Times [s] (any shape).

        Returns
        -------
        numpy.ndarray
            The shape of ``t`` [m/s].
        """
        i, _, tau = self._piece(t)
        return self.v0[i] + (self.v1[i] - self.v0[i]) * (tau - np.sin(2 * np.pi * tau) / (2 * np.pi))

    def acceleration(self, t):
        """Reference acceleration [m/s^2] at ``t`` (the derivative of :meth:`speed`).

        Parameters
        ----------
        t : array_like
            Times [s] (any shape).

        Returns
        -------
        numpy.ndarray
            The shape of ``t`` [m/s^2] (zero before the first piece and after the last).
        """
        i, d, tau = self._piece(t)
        return (self.v1[i] - self.v0[i]) / d * (1.0 - np.cos(2 * np.pi * tau))


#: Kinds of speed profile: a mixed ride, or one manoeuvre repeated.
PROFILE_KINDS = ("mixed", "accelerate", "brake", "stop_and_go", "cruise")


def random_speed_profile(rng: np.random.Generator, duration: float, *, kind: str = "mixed", v_max: float = 4.0,
                         accel_range=(0.3, 1.0), hold_range=(0.5, 3.0)) -> SpeedProfile:
    """Draw a speed profile of at least ``duration`` seconds.

    Parameters
    ----------
    rng : numpy.random.Generator
    duration : float
        Ride length [s].
    kind : str
        ``mixed`` (accelerations, cruises, brakings and stops in random order), ``accelerate``
        (from rest or low speed up), ``brake`` (down to rest), ``stop_and_go`` (rest, go, rest...) or
        ``cruise`` (small speed changes around a cruise speed).
    v_max : float
        Highest reference speed [m/s].
    accel_range : (float, float)
        Range of the mean acceleration of a ramp [m/s^2] (its peak is twice the mean).
    hold_range : (float, float)
        Range of the duration of a hold [s].

    Returns
    -------
    SpeedProfile
    """
    if kind not in PROFILE_KINDS:
        raise ValueError(f"kind must be one of {PROFILE_KINDS}, got {kind!r}")
    t = 0.0
    if kind in ("brake",):
        v = rng.uniform(0.6, 1.0) * v_max
    elif kind in ("accelerate", "stop_and_go"):
        v = 0.0
    else:
        v = rng.uniform(0.3, 0.8) * v_max
    pieces = []
    ramp = True
    while t < duration:
        if ramp:
            if kind == "mixed":
                target = 0.0 if rng.random() < 0.25 else rng.uniform(0.15, 1.0) * v_max
            elif kind == "accelerate":
                target = min(v_max, v + rng.uniform(0.3, 0.6) * v_max) if v < 0.9 * v_max else 0.2 * v_max
            elif kind == "brake":
                target = 0.0 if v > 0.1 * v_max else rng.uniform(0.6, 1.0) * v_max
            elif kind == "stop_and_go":
                target = rng.uniform(0.4, 1.0) * v_max if v < 0.05 * v_max else 0.0
            else:
                target = float(np.clip(v + rng.uniform(-0.25, 0.25) * v_max, 0.2 * v_max, v_max))
            dv = target - v
            a_mean = rng.uniform(*accel_range)
            dur = max(abs(dv) / a_mean, 0.4)
            pieces.append((t, t + dur, v, target))
            t, v = t + dur, target
        else:
            dur = rng.uniform(*hold_range)
            pieces.append((t, t + dur, v, v))
            t += dur
        ramp = not ramp
    arr = np.array(pieces, dtype=float)
    return SpeedProfile(arr[:, 0], arr[:, 1], arr[:, 2], arr[:, 3])
