"""Threshold of the live residual monitor from a calibration ride.

The monitor flags the model as inconsistent when the sliding RMSE of ``M_d1 - M_d2`` over ``n``
samples exceeds a threshold (:func:`~euc_ros.core.online.monitoring.consistency_health`). How low the
threshold may go depends on the derivative filter: a low-lag filter gives a noisier residual. This
module turns the residual of a ride on which the model holds (a level floor, no effect) into a
threshold with a stated false-alarm probability:

* the residual's RMS ``sigma`` and the integrated autocorrelation time ``tau2`` [samples] of its
  square (:func:`integrated_autocorrelation` with ``squared``; the filter correlates neighbouring
  samples);
* a window of ``n`` samples then holds about ``n_eff = n / tau2`` independent squares, and its mean
  square is about ``sigma^2 chi2(n_eff) / n_eff`` (Gaussian residual);
* the threshold is the ``1 - alpha`` quantile of that RMS (:func:`rmse_threshold`).

The approximation assumes a stationary Gaussian residual; a ride whose noise changes (speed,
manoeuvre) needs a smaller ``alpha`` or a calibration ride like the monitored one.
"""
from __future__ import annotations

import numpy as np

from euc_ros.core.errors import ConfigError, InputError


def _autocorrelation(r) -> np.ndarray:
    """Autocorrelation of the finite values of ``r`` at lags 0, 1, ... up to its first negative value."""
    from scipy.signal import correlate

    r = np.asarray(r, dtype=float)
    r = r[np.isfinite(r)]
    if r.size < 3:
        raise InputError(f"need at least 3 finite residuals, got {r.size}", key="residual")
    r = r - r.mean()
    rho = correlate(r, r, "full", method="fft")[r.size - 1:] / np.dot(r, r)
    stop = int(np.argmax(rho < 0)) or rho.size
    return rho[:stop]


def integrated_autocorrelation(r, *, squared: bool = False) -> float:
    """``1 + 2 sum_j rho(j)`` over the lags before the autocorrelation first drops below zero [samples].

    With ``squared`` the sum is of ``rho(j)^2``: the correlation time of ``r^2`` for a Gaussian ``r``
    (``corr(r_i^2, r_j^2) = rho^2``), the one that sets the spread of a mean square.

    Parameters
    ----------
    r : array_like
        The series (n,).
    squared : bool
        Sum ``rho(j)^2`` instead of ``rho(j)``.

    Returns
    -------
    float
        The integrated autocorrelation time [samples], at least 1.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> round(integrated_autocorrelation(rng.normal(size=20000)))   # white noise: 1
    1
    """
    rho = _autocorrelation(r)
    return max(1.0, float(1.0 + 2.0 * np.sum(rho[1:] ** 2 if squared else rho[1:])))


def rmse_threshold(residual_nm, window: int, alpha: float = 1e-6) -> float:
    """Sliding-RMSE threshold [N m] exceeded with probability ``alpha`` per window on a consistent ride.

    Parameters
    ----------
    residual_nm : array_like
        ``M_d1 - M_d2`` of a calibration ride on which the model holds [N m] (NaN ignored).
    window : int
        Samples in the sliding RMSE window.
    alpha : float
        False-alarm probability per independent window.

    Returns
    -------
    float
        ``sigma sqrt(chi2.ppf(1 - alpha, n_eff) / n_eff)`` (module docstring).

    Raises
    ------
    ConfigError
        When ``alpha`` is not in (0, 1) or ``window`` is not positive.
    """
    from scipy.stats import chi2

    if not 0 < alpha < 1:
        raise ConfigError(f"alpha must be in (0, 1), got {alpha!r}", key="alpha")
    if int(window) != window or window < 1:
        raise ConfigError(f"window must be a positive number of samples, got {window!r}", key="window")
    r = np.asarray(residual_nm, dtype=float)
    r = r[np.isfinite(r)]
    sigma = float(np.sqrt(np.mean(r**2))) if r.size else float("nan")
    n_eff = max(window / integrated_autocorrelation(r, squared=True), 1.0)
    return sigma * float(np.sqrt(chi2.ppf(1.0 - alpha, n_eff) / n_eff))
