"""Maneuvers of the ride simulator: paths, speed profiles, tilt and rider sway.

A run is planned before it is simulated (:func:`plan_run`): its path is a heading ``psi(s)`` as a
function of the arc length ``s`` travelled by the wheel centre C (``s = x``, the planar model's
coordinate), its speed reference is a function of time (straight runs) or of the arc length
(figure-eight), and its tilt is the coordinated-turn lean plus a small wobble. Every function here
takes scalars or numpy arrays.

Maneuvers (EUC paper, Table 1 and Figs 6-7):

* ``constant_speed``: one speed (2.5-3.5 m/s).
* ``acceleration``: from about 1 m/s to 3.3-3.7 m/s over 4-5 s.
* ``deceleration``: from 3.3-3.7 m/s to about 1 m/s over 4-5 s.
* ``figure_eight``: about 1.7-2 m/s, 0.6 m/s slower in the tightest turns, on a figure-eight of
  heading ``psi(s) = psi0 + a sin(2 pi s / L)`` with ``a`` the first zero of the Bessel function J0
  (the curve then closes), L = 16 m (about 6 m x 2.2 m).

Straight runs alternate their direction (psi0 = 0, pi) as in the paper (U-turns outside the
capture volume) and wander by about 1.5 deg of heading.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from euc_ros.core.errors import ConfigError

#: Maneuver names accepted by the simulator.
MANEUVERS = ("constant_speed", "acceleration", "deceleration", "figure_eight")

#: First zero of J0: with this heading amplitude the sinusoidal-heading curve closes on itself.
FIGURE_EIGHT_AMPLITUDE = 2.404825557695773
#: Length of one figure-eight [m].
FIGURE_EIGHT_LENGTH_M = 16.0
#: Default recording duration per maneuver [s].
DEFAULT_DURATION_S = {"constant_speed": 5.0, "acceleration": 7.0, "deceleration": 7.0, "figure_eight": 30.0}


@dataclass(frozen=True)
class HeadingPath:
    """Heading as a function of arc length: ``psi(s) = psi0 + a sin(2 pi s / L + p)``.

    Parameters
    ----------
    psi0 : float
        Mean heading [rad].
    amplitude : float
        Heading amplitude a [rad].
    length : float
        Wavelength L [m].
    phase : float
        Phase p [rad].
    """

    psi0: float
    amplitude: float
    length: float
    phase: float = 0.0

    def psi(self, s):
        """Heading [rad] at arc length s [m].

        Parameters
        ----------
        s : float or array_like
            Arc length [m].

        Returns
        -------
        float or numpy.ndarray
            Heading [rad].
        """
        return self.psi0 + self.amplitude * np.sin(2 * np.pi * np.asarray(s) / self.length + self.phase)

    def kappa(self, s):
        """Curvature d psi / d s [1/m] at arc length s.

        Parameters
        ----------
        s : float or array_like
            Arc length [m].

        Returns
        -------
        float or numpy.ndarray
            Curvature [1/m].
        """
        k = 2 * np.pi / self.length
        return self.amplitude * k * np.cos(k * np.asarray(s) + self.phase)

    def dkappa(self, s):
        """The curvature's rate d kappa / d s [1/m^2] at arc length s.

        Parameters
        ----------
        s : float or array_like
            Arc length [m].

        Returns
        -------
        float or numpy.ndarray
            ``d kappa / d s`` [1/m^2].
        """
        k = 2 * np.pi / self.length
        return -self.amplitude * k * k * np.sin(k * np.asarray(s) + self.phase)


def smooth_step(u):
    """C-infinity step from 0 (u <= 0) to 1 (u >= 1) and its derivative d/du.

    ``s(u) = f(u) / (f(u) + f(1 - u))`` with ``f(u) = exp(-1/u)`` for u > 0, else 0.

    Parameters
    ----------
    u : float
        Argument.

    Returns
    -------
    s, ds : float
        ``s(u)`` and ``ds/du``.
    """
    if np.ndim(u) == 0:  # scalar fast path (ODE right-hand side), same formula
        u = float(u)
        if u <= 0.0 or u >= 1.0:
            return (1.0 if u >= 1.0 else 0.0), 0.0
        fa, fb = math.exp(-1.0 / u), math.exp(-1.0 / (1.0 - u))
        den = fa + fb
        return fa / den, (fa / u**2 * fb + fa * fb / (1.0 - u) ** 2) / den**2
    u = np.clip(np.asarray(u, float), 0.0, 1.0)
    inner = (u > 0) & (u < 1)
    uu = np.where(inner, u, 0.5)
    fa, fb = np.exp(-1.0 / uu), np.exp(-1.0 / (1.0 - uu))
    den = fa + fb
    s = np.where(inner, fa / den, np.where(u >= 1, 1.0, 0.0))
    ds = np.where(inner, (fa / uu**2 * fb + fa * fb / (1.0 - uu) ** 2) / den**2, 0.0)
    return s, ds


@dataclass(frozen=True)
class SpeedProfile:
    """Speed reference of the rider.

    Straight runs: ``v0`` until ``t1``, a C-infinity :func:`smooth_step` to ``v1`` over ``ramp_s``, then
    ``v1`` (a person's speed change has no corners, and smooth inputs keep the sampled truth smooth).
    Figure-eight (``slow_in_turns > 0``): ``v0 - slow_in_turns (kappa / kappa_max)^2`` along the path.

    Parameters
    ----------
    v0, v1 : float
        Speeds before and after the change [m/s].
    t1 : float
        Start of the change [s].
    ramp_s : float
        Duration of the change [s].
    slow_in_turns : float
        Speed lost at the largest curvature [m/s] (figure-eight).
    kappa_max : float
        Largest curvature of the path [1/m].
    """

    v0: float
    v1: float
    t1: float
    ramp_s: float
    slow_in_turns: float = 0.0
    kappa_max: float = 1.0

    def reference(self, t, kappa, dkappa_ds, x_dot):
        """``(v_ref, a_ref)`` [m/s, m/s^2] at time t for the curvature state along the path.

        Parameters
        ----------
        t : float
            Time [s].
        kappa : float
            Curvature at the rider's arc length [1/m].
        dkappa_ds : float
            Its rate along the path [1/m^2].
        x_dot : float
            Speed [m/s].

        Returns
        -------
        v_ref, a_ref : float
            Speed [m/s] and acceleration [m/s^2] references.
        """
        if self.v1 == self.v0:
            v, a = self.v0 + 0.0 * np.asarray(t, float), 0.0 * np.asarray(t, float)
        else:
            step, dstep = smooth_step((np.asarray(t, float) - self.t1) / self.ramp_s)
            v = self.v0 + (self.v1 - self.v0) * step
            a = (self.v1 - self.v0) * dstep / self.ramp_s
        if self.slow_in_turns:
            r = kappa / self.kappa_max
            v = v - self.slow_in_turns * r * r
            a = a - self.slow_in_turns * 2 * r * dkappa_ds / self.kappa_max * x_dot
        return v, a


@dataclass(frozen=True)
class Sinusoids:
    """A sum of sinusoids ``sum_k a_k sin(2 pi f_k t + p_k)`` (rider sway, tilt wobble) [rad].

    Parameters
    ----------
    amplitudes : tuple of float
        Amplitudes a_k [rad].
    freqs_hz : tuple of float
        Frequencies f_k [Hz].
    phases : tuple of float
        Phases p_k [rad].
    """

    amplitudes: tuple[float, ...]
    freqs_hz: tuple[float, ...]
    phases: tuple[float, ...]

    def __call__(self, t):
        """The sum at times ``t`` [rad].

        Parameters
        ----------
        t : float or array_like
            Times [s].

        Returns
        -------
        float or numpy.ndarray
            A float for a scalar ``t``, else an array of ``t``'s shape.
        """
        if np.ndim(t) == 0:  # scalar fast path (ODE right-hand side), same formula
            t = float(t)
            return sum(a * math.sin(2 * math.pi * f * t + p)
                       for a, f, p in zip(self.amplitudes, self.freqs_hz, self.phases))
        t = np.asarray(t, float)
        out = np.zeros_like(t)
        for a, f, p in zip(self.amplitudes, self.freqs_hz, self.phases):
            out = out + a * np.sin(2 * np.pi * f * t + p)
        return out


@dataclass(frozen=True)
class RunPlan:
    """Everything random about one run, drawn before simulation.

    Parameters
    ----------
    name : str
        Run name.
    maneuver : str
        One of :data:`MANEUVERS`.
    duration_s : float
        Recording duration [s].
    path : HeadingPath
        Heading along the path.
    speed : SpeedProfile
        Speed reference.
    sway : Sinusoids
        Rider sway [rad].
    tilt_wobble : Sinusoids
        Tilt wobble [rad].
    """

    name: str
    maneuver: str
    duration_s: float
    path: HeadingPath
    speed: SpeedProfile
    sway: Sinusoids
    tilt_wobble: Sinusoids

    def tilt(self, t, x_dot, kappa, g: float):
        """Tilt theta [rad]: coordinated-turn lean ``-atan(kappa x_dot^2 / g)`` plus a wobble.

        With ``R = Rz(psi) Rx(theta)`` a positive theta tips the top to the right (-y); in a left turn
        (kappa > 0) the rider leans left, so theta < 0.

        Parameters
        ----------
        t : float or array_like
            Time [s].
        x_dot : float or array_like
            Speed [m/s].
        kappa : float or array_like
            Path curvature [1/m].
        g : float
            Gravitational acceleration [m/s^2].

        Returns
        -------
        float or numpy.ndarray
            Tilt [rad].
        """
        return -np.arctan(kappa * x_dot * x_dot / g) + self.tilt_wobble(t)


def _sinusoids(rng: np.random.Generator, n: int, total_amp: float, f_lo: float, f_hi: float) -> Sinusoids:
    amps = rng.uniform(0.5, 1.0, n)
    amps = amps / amps.sum() * total_amp
    return Sinusoids(tuple(amps), tuple(rng.uniform(f_lo, f_hi, n)), tuple(rng.uniform(0, 2 * np.pi, n)))


def plan_run(maneuver: str, index: int, rng: np.random.Generator, duration_s: float | None = None,
             speed_scale: float = 1.0, path_scale: float = 1.0) -> RunPlan:
    """Draw the plan of run ``index`` (0-based) of a maneuver.

    Parameters
    ----------
    maneuver : str
        One of :data:`MANEUVERS`.
    index : int
        Run index; straight runs alternate heading 0 / pi with it.
    rng : numpy.random.Generator
        Source of the run's randomness (speeds, timing, sway, wobble).
    duration_s : float, optional
        Recording duration [s]; default :data:`DEFAULT_DURATION_S`.
    speed_scale : float
        Multiplies every speed of the plan (a more aggressive rider: e.g. 1.4 gives figure-eights at
        2.4-2.8 m/s with ~18 deg of tilt in the turns).
    path_scale : float
        Multiplies the figure-eight's length (wider turns: less yaw per filter window at equal tilt).

    Returns
    -------
    RunPlan
        The plan.

    Raises
    ------
    ConfigError
        Unknown maneuver, or a scale or duration that is not positive.
    """
    if not path_scale > 0:
        raise ConfigError(f"must be > 0, got {path_scale}", key="path_scale")
    if not speed_scale > 0:
        raise ConfigError(f"must be > 0, got {speed_scale}", key="speed_scale")
    if maneuver not in MANEUVERS:
        raise ConfigError(f"unknown maneuver {maneuver!r} (known: {', '.join(MANEUVERS)})", key="maneuver")
    dur = DEFAULT_DURATION_S[maneuver] if duration_s is None else float(duration_s)
    if not dur > 0:
        raise ConfigError(f"must be > 0, got {duration_s}", key="duration_s")
    sway = _sinusoids(rng, 3, math.radians(rng.uniform(1.0, 1.5)), 0.3, 1.5)
    wobble = _sinusoids(rng, 2, math.radians(rng.uniform(0.5, 1.0)), 0.2, 0.7)
    name = f"{maneuver}_{index + 1:02d}"
    if maneuver == "figure_eight":
        L = FIGURE_EIGHT_LENGTH_M * path_scale
        path = HeadingPath(-math.pi / 2 + rng.uniform(-0.1, 0.1), FIGURE_EIGHT_AMPLITUDE, L, 0.0)
        v = rng.uniform(1.7, 2.0) * speed_scale
        speed = SpeedProfile(v, v, 0.0, 1.0, slow_in_turns=0.6 * speed_scale,
                             kappa_max=FIGURE_EIGHT_AMPLITUDE * 2 * math.pi / L)
        return RunPlan(name, maneuver, dur, path, speed, sway, wobble)
    psi0 = 0.0 if index % 2 == 0 else math.pi
    path = HeadingPath(psi0, math.radians(rng.uniform(1.0, 2.0)), rng.uniform(6.0, 10.0), rng.uniform(0, 2 * math.pi))
    if maneuver == "constant_speed":
        v = rng.uniform(2.5, 3.5) * speed_scale
        speed = SpeedProfile(v, v, 0.0, 1.0)
    else:
        lo, hi = rng.uniform(0.8, 1.2) * speed_scale, rng.uniform(3.3, 3.7) * speed_scale
        v0, v1 = (lo, hi) if maneuver == "acceleration" else (hi, lo)
        t1 = rng.uniform(0.5, 1.0)
        ramp = rng.uniform(4.0, 5.0)
        speed = SpeedProfile(v0, v1, t1, ramp)
    return RunPlan(name, maneuver, dur, path, speed, sway, wobble)
