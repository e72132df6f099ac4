"""Signal filters that make the discovery's columns (:mod:`.families`) and smooth them as the states see them.

* :func:`low_pass`: the dynamics family's causal first-order low-pass ``1 / (tau s + 1)``;
* :func:`resonate` (a resonator), :func:`payload_band` (a resonance without its ends) and
  :func:`resonator_columns` (the oscillator family's columns: a payload on a spring), bilinear transforms of
  their transfer functions;
* :func:`savgol_kernel`: the Savitzky-Golay smoothing weights the columns made at the full rate pass through
  (a force reaches the residual through the states' filtered accelerations).

The recursive filters start in the steady state of their input's first sample. Times in seconds, frequencies in Hz.
"""
from __future__ import annotations

import numpy as np
from scipy import signal

#: Relative step of the frequency derivative's central difference.
RESONANCE_STEP = 0.03
#: Damping ratio of the oscillator family's resonators.
RESONANCE_DAMPING = 0.1


def low_pass(u: np.ndarray, tau: float, dt: float) -> np.ndarray:
    """Causal first-order low-pass ``1 / (tau s + 1)`` of ``u`` sampled every ``dt``.

    Exact for a signal held over each step; started in its steady state at the first sample.

    Parameters
    ----------
    u : ndarray (n,)
    tau : float
        Time constant [s].
    dt : float
        Sample spacing [s].

    Returns
    -------
    ndarray (n,)
    """
    a = float(np.exp(-dt / tau))
    b, den = [1.0 - a], [1.0, -a]
    y, _ = signal.lfilter(b, den, u, zi=signal.lfilter_zi(b, den) * u[0])
    return y


def resonate(u: np.ndarray, f_hz: float, dt: float, zeta: float = RESONANCE_DAMPING) -> np.ndarray:
    """``u`` through the resonator ``w^2 / (s^2 + 2 zeta w s + w^2)`` and ``w s / (...)`` (``w = 2 pi f_hz``): (n, 2).

    The bilinear transform of the two transfer functions, sampled every ``dt``, started in the steady state of
    the first sample (the first column equal to it, the second zero).

    Parameters
    ----------
    u : ndarray (n,)
    f_hz : float
        Resonance frequency [Hz].
    dt : float
        Sample spacing [s].
    zeta : float
        Damping ratio.

    Returns
    -------
    ndarray (n, 2)
    """
    w = 2.0 * np.pi * float(f_hz)
    den = [1.0, 2.0 * zeta * w, w * w]
    out = np.empty((u.size, 2))
    for j, num in enumerate(([w * w], [w, 0.0])):
        b, a = signal.bilinear(num, den, fs=1.0 / dt)
        out[:, j], _ = signal.lfilter(b, a, u, zi=signal.lfilter_zi(b, a) * u[0])
    return out


def payload_band(u: np.ndarray, f_hz: float, dt: float, zeta: float = RESONANCE_DAMPING) -> np.ndarray:
    """A resonance of the carrier's velocity ``u`` without its ends: (n, 2).

    ``w s^2 / ((s + w) D)`` and ``s^3 / ((s + w) D)`` of ``u``, ``D = s^2 + 2 zeta w s + w^2``: in quadrature at
    the resonance, of the order ``s^2`` at low frequency (no mass: the carried mass at rest on its spring is a
    force in phase with the carrier's acceleration, which the residual is linear in) and no faster than a
    velocity above it (no acceleration either). Bilinear transform, started in the steady state of the first
    sample.

    Parameters
    ----------
    u : ndarray (n,)
    f_hz : float
        Resonance frequency [Hz].
    dt : float
        Sample spacing [s].
    zeta : float
        Damping ratio.

    Returns
    -------
    ndarray (n, 2)
    """
    w = 2.0 * np.pi * float(f_hz)
    den = np.polymul([1.0, w], [1.0, 2.0 * zeta * w, w * w])
    out = np.empty((u.size, 2))
    for j, num in enumerate(([w, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0])):
        b, a = signal.bilinear(num, den, fs=1.0 / dt)
        out[:, j], _ = signal.lfilter(b, a, u, zi=signal.lfilter_zi(b, a) * u[0])
    return out


def resonator_columns(u: np.ndarray, f_hz: float, dt: float) -> np.ndarray:
    """The oscillator family's columns at one resonance frequency (n, 4).

    :func:`payload_band` at ``f_hz`` and its central difference in ``ln f`` (steps of :data:`RESONANCE_STEP`): a
    resonance near ``f_hz`` is a combination of the four.

    Parameters
    ----------
    u : ndarray (n,)
    f_hz : float
        Resonance frequency [Hz].
    dt : float
        Sample spacing [s].

    Returns
    -------
    ndarray (n, 4)
    """
    a, b = (payload_band(u, f_hz * m, dt) for m in (1.0 + RESONANCE_STEP, 1.0 / (1.0 + RESONANCE_STEP)))
    return np.concatenate([payload_band(u, f_hz, dt), a - b], axis=1)


def savgol_kernel(window: int, polyorder: int) -> np.ndarray:
    """The Savitzky-Golay smoothing weights (value at the window's centre) of ``window`` samples.

    Parameters
    ----------
    window : int
        Samples, odd.
    polyorder : int

    Returns
    -------
    ndarray (window,)
    """
    return signal.savgol_coeffs(int(window), int(polyorder), deriv=0, use="dot")
