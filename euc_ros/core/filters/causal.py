"""Low-lag derivative estimation: a steady-state Kalman fixed-lag smoother per coordinate.

The Savitzky-Golay filter of :mod:`euc_ros.core.filters.derivatives` gives each state half its window
late (0.6 s with the 1.2 s default). This module gives the value, first and second derivative of a
signal ``lag`` frames late, for any lag from 0 (causal) upwards, with the same two forms and the same
gap handling:

* :func:`kalman_derivatives` (offline, vectorized): a whole recording at once;
* :class:`StreamingKalman` (online): one sample at a time; on every stretch it returns the same numbers
  as the offline function to round-off (same weights, same samples).

Model. Each coordinate is a chain of ``order`` integrators driven by white noise (``order = 4``: a
constant-jerk model, state ``[y, y', y'', y''']`` with white snap) and measured with white noise of
variance ``r``. The continuous noise density of the driving noise is set from a smoothing time
``tau``: ``q = r dt / tau^(2 order)``, so that the steady-state filter's bandwidth is ``1 / tau``
[rad/s] whatever the rate; only the ratio ``q / r`` matters, so the measurement noise need not be
known. The estimate of the state ``lag`` frames back given all samples so far is the steady-state
fixed-lag smoother (innovations form, Anderson & Moore, *Optimal Filtering*, ch. 7)::

    x(k-L | k) = x(k-L | k-L-1) + sum_{i=0..L} P (F^T)^i H^T S^-1 e(k-L+i)

with ``P`` the predicted error covariance (discrete algebraic Riccati equation,
``scipy.linalg.solve_discrete_are``), ``S = H P H^T + r``, ``F = A (I - K H)`` and ``e`` the
innovations. This is a linear time-invariant map from the samples to the estimate; its impulse
response decays geometrically (the poles of ``F``), and it is truncated where the remaining weight is
below ``tol`` of the total (:data:`DEFAULT_TOL`), then corrected by the smallest change that keeps
polynomials of degree ``order - 1`` exact (as the untruncated smoother is). The result is a set of
FIR weights (:func:`kalman_weights`), applied like the Savitzky-Golay weights: a stretch gives no
output until ``window`` samples are buffered (the filter's memory, :attr:`StreamingKalman.window`),
and the last ``lag`` samples of a stretch have no output (their future is not there yet).

Gaps: exactly as :func:`~euc_ros.core.filters.derivatives.savgol_derivatives`: runs of at most
``max_gap`` missing frames are filled by linear interpolation (those samples are flagged ``filled``),
longer runs split the signal into stretches and reset the streaming filter.

Units: ``dt``, ``lag_s``, ``smoothing_s`` in seconds; derivatives per second and per second squared.

Examples
--------
>>> import numpy as np
>>> dt = 1 / 120
>>> t = np.arange(600) * dt
>>> d = kalman_derivatives(dt, 0.5 * t**2, lag_s=0.1, smoothing_s=0.07)
>>> k = np.flatnonzero(np.isfinite(d.y_ddot))
>>> bool(np.allclose(d.y_ddot[k], 1.0, atol=1e-6)), d.lag
(True, 12)
"""
from __future__ import annotations

from dataclasses import dataclass
from math import factorial

import numpy as np
from numpy.polynomial import legendre

from euc_ros.core.errors import ConfigError, InputError
from euc_ros.core.filters.derivatives import (
    DEFAULT_MAX_GAP,
    Derivatives,
    StreamingSavgol,
    filter_stretches,
    grid_positions,
    window_samples,
)

#: Default model order (number of states per coordinate): 4 is a constant-jerk model.
DEFAULT_ORDER = 4
#: Impulse-response weight left out of the truncated filter (relative L1 mass of each derivative).
DEFAULT_TOL = 1e-4
#: Measured smoothing time [s] per lag [s] on simulated rides with the paper's noise (0.2 mm, 0.5 deg),
#: order 4, the same filter on every coordinate: the smoothing time (of 0.04, 0.05, 0.065, 0.08, 0.1,
#: 0.13 s) that minimised the RMS error of M_d1 and M_d2 against the simulator's true M_d on the
#: training seeds (studies/lag_curve.py, docs/low_lag.md). Linear between the tabulated lags.
SMOOTHING_TABLE = ((0.0, 0.065), (0.3, 0.065), (0.4, 0.08), (0.6, 0.08))
#: Derivative estimators of the state reconstruction: centred (or off-centre) Savitzky-Golay, or the
#: Kalman fixed-lag smoother of this module.
ESTIMATORS = ("savgol", "kalman")
#: State estimators of :class:`~euc_ros.core.online.estimators.RiderStateEstimator` (and the ``rider_state``
#: node): the per-coordinate filters above, or ``split`` (:mod:`euc_ros.core.states.split_lag`: pieces
#: split by noise source, filtered per group; it needs the poses, so it has no :func:`streaming_filter`).
STATE_ESTIMATORS = ESTIMATORS + ("split",)
#: Lag [s] of the shipped low-lag mode (``estimator="kalman"`` without ``lag_s``).
LOW_LAG_S = 0.1
#: Longest impulse response considered [samples] before giving up (a very slow filter).
MAX_MEMORY_SAMPLES = 100_000


def default_smoothing_s(lag_s: float) -> float:
    """The smoothing time [s] of :data:`SMOOTHING_TABLE` for a lag [s] (linear between the entries).

    Parameters
    ----------
    lag_s : float
        Output delay [s]; outside the table, its first or last entry's smoothing time.

    Returns
    -------
    float
        Smoothing time [s].
    """
    lags, taus = np.array(SMOOTHING_TABLE).T
    return float(np.interp(lag_s, lags, taus))


def _check(dt: float, lag: int, order: int, smoothing_s: float, tol: float) -> None:
    if not (np.isfinite(dt) and dt > 0):
        raise InputError(f"sample spacing must be > 0 s, got {dt!r}", key="dt")
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or not 3 <= order <= 6:
        raise ConfigError(f"order must be an integer in [3, 6] (second derivatives), got {order!r}", key="order")
    if isinstance(lag, bool) or not isinstance(lag, (int, np.integer)) or lag < 0:
        raise ConfigError(f"lag must be an integer >= 0 frames, got {lag!r}", key="lag")
    if not (np.isfinite(smoothing_s) and smoothing_s > 0):
        raise ConfigError(f"smoothing_s must be > 0 s, got {smoothing_s!r}", key="smoothing_s")
    if smoothing_s < dt:
        raise ConfigError(f"smoothing_s {smoothing_s:g} s is shorter than one sample ({dt:g} s)", key="smoothing_s")
    if not 0 < tol < 1:
        raise ConfigError(f"tol must be in (0, 1), got {tol!r}", key="tol")


def kalman_weights(dt: float, lag: int, *, order: int = DEFAULT_ORDER, smoothing_s: float,
                   tol: float = DEFAULT_TOL) -> np.ndarray:
    """FIR weights of the steady-state Kalman fixed-lag smoother (see the module docstring).

    Parameters
    ----------
    dt : float
        Sample spacing [s].
    lag : int
        Output delay [frames].
    order : int
        Number of states of the integrator chain (3: constant acceleration, 4: constant jerk).
    smoothing_s : float
        Smoothing time ``tau`` [s]: the filter's bandwidth is ``1 / tau`` rad/s.
    tol : float
        Truncate the impulse response where the weight left is below ``tol`` of the total.

    Returns
    -------
    ndarray (3, window)
        ``w[d] @ y[k - window + 1 : k + 1]`` (oldest sample first) is the d-th derivative [unit/s^d]
        at frame ``k - lag``.

    Examples
    --------
    >>> w = kalman_weights(1 / 120, 12, smoothing_s=0.07)
    >>> [abs(round(float(v), 9)) for v in w.sum(axis=1)]   # a constant: itself, no rate, no acceleration
    [1.0, 0.0, 0.0]
    """
    from scipy.linalg import solve_discrete_are

    _check(dt, lag, order, smoothing_s, tol)
    n = int(order)
    lag = int(lag)
    # state in sample units (y, y' dt, y'' dt^2, ...): A is the same at any rate and well conditioned
    A = np.array([[1.0 / factorial(j - i) if j >= i else 0.0 for j in range(n)] for i in range(n)])
    rho = (dt / smoothing_s) ** (2 * n)   # q dt^(2n-1) / r with q = r dt / tau^(2n)
    a = n - 1 - np.arange(n)
    fa = np.array([factorial(int(v)) for v in a], dtype=float)
    Q = rho / (np.outer(fa, fa) * (a[:, None] + a[None, :] + 1))
    H = np.zeros((1, n))
    H[0, 0] = 1.0
    P = solve_discrete_are(A.T, H.T, Q, np.ones((1, 1)))
    S = float(P[0, 0]) + 1.0
    K = P[:, 0] / S
    F = A @ (np.eye(n) - np.outer(K, H[0]))
    # smoother gains G_i = P (F^T)^i H^T / S, i = 0..lag
    G = np.empty((lag + 1, n))
    Ft = F.T
    v = H[0].copy()
    for i in range(lag + 1):
        G[i] = P @ v / S
        v = Ft @ v
    # impulse response of the predictor: x(k|k-1) and the innovations for y = delta(k)
    xs, es = [], []
    x = np.zeros(n)
    peak = 0.0
    for k in range(MAX_MEMORY_SAMPLES):
        e = (1.0 if k == 0 else 0.0) - x[0]
        xs.append(x)
        es.append(e)
        x = A @ (x + K * e)
        size = float(np.max(np.abs(x)))
        peak = max(peak, size)
        if k > lag + n and size < 1e-3 * tol * peak:
            break
    else:
        raise ConfigError(f"smoothing_s {smoothing_s:g} s needs a memory beyond {MAX_MEMORY_SAMPLES} samples",
                          key="smoothing_s")
    xs = np.array(xs + [np.zeros(n)] * lag)
    es = np.concatenate([es, np.zeros(lag)])
    m = xs.shape[0]
    h = np.zeros((m, n))          # response at output time k (estimate of frame k - lag)
    h[lag:] = xs[:m - lag]
    for i in range(lag + 1):
        shift = lag - i
        h[shift:] += np.outer(es[:m - shift], G[i])
    h = h[:, :3] / dt ** np.arange(3)   # sample units -> unit/s^d
    tail = np.cumsum(np.abs(h[::-1]), axis=0)[::-1]
    short = np.flatnonzero(np.all(tail <= tol * tail[0], axis=1))
    length = max(int(short[0]) if short.size else m, lag + n + 1)
    w = h[:length][::-1].T.copy()       # oldest sample first
    return _keep_polynomials(w, lag, n - 1, dt)


def _keep_polynomials(w: np.ndarray, lag: int, degree: int, dt: float) -> np.ndarray:
    """Smallest change of the weights (3, W) that makes polynomials up to ``degree`` exact."""
    W = w.shape[1]
    c = (W - 1) / 2.0
    V = legendre.legvander((np.arange(W) - c) / c, degree)
    u0 = (W - 1 - lag - c) / c
    eye = np.eye(degree + 1)
    out = w.copy()
    for d in range(3):
        # d-th derivative of each Legendre polynomial at the output position, in sample units
        target = np.array([legendre.legval(u0, legendre.legder(eye[k], d) if d else eye[k])
                           for k in range(degree + 1)]) / c**d
        scaled = w[d] * dt**d
        fix = V @ np.linalg.lstsq(V.T @ V, target - V.T @ scaled, rcond=None)[0]
        out[d] = (scaled + fix) / dt**d
    return out


def _stretch(seg: np.ndarray, w: np.ndarray, lag: int) -> np.ndarray:
    """Value and derivatives (3, L, k) of a gap-free stretch: NaN where the online filter has no output."""
    from scipy.signal import lfilter

    length = seg.shape[0]
    W = w.shape[1]
    out = np.full((3,) + seg.shape, np.nan)
    if length < W:
        return out
    ref = seg[length // 2]
    x = seg - ref
    for d in range(3):
        # y_hat(k - lag) = sum_j w[d, W-1-j] x(k - j): an FIR filter run forward in time
        full = lfilter(w[d, ::-1], [1.0], x, axis=0)
        out[d, W - 1 - lag:length - lag] = full[W - 1:]
    out[0] += ref
    return out


@dataclass(frozen=True)
class LaggedDerivatives(Derivatives):
    """:class:`~euc_ros.core.filters.derivatives.Derivatives` of a fixed-lag filter.

    Parameters
    ----------
    y, y_dot, y_ddot : numpy.ndarray
        Filtered signal and its first and second derivatives [unit, unit/s, unit/s^2], the input's shape.
    filled : numpy.ndarray of bool (n,)
        Samples filled by interpolation across a short gap.
    window : int
        Memory of the filter [samples].
    dt : float
        Sample spacing [s].
    lag : int
        Output delay of the streaming twin [frames]: the last ``lag`` samples of a stretch are NaN.
    """

    lag: int = 0


def kalman_derivatives(t_or_dt, y, *, lag_s: float, smoothing_s: float | None = None,
                       order: int = DEFAULT_ORDER, max_gap: int = DEFAULT_MAX_GAP, frame=None,
                       tol: float = DEFAULT_TOL) -> LaggedDerivatives:
    """Low-lag value and derivatives of ``y`` (offline twin of :class:`StreamingKalman`).

    Parameters
    ----------
    t_or_dt : float or ndarray (n,)
        Sample spacing [s] or sample times [s] (as :func:`~.derivatives.savgol_derivatives`).
    y : ndarray (n,) or (n, k)
        Signal, time along axis 0; a sample with any NaN component is missing.
    lag_s : float
        Output delay [s], rounded to whole frames (``lag`` of the result).
    smoothing_s : float, optional
        Smoothing time [s]; default :func:`default_smoothing_s` of the lag.
    order : int
        Integrator-chain order (4: constant jerk).
    max_gap : int
        Longest run of missing frames bridged by interpolation (flagged ``filled``).
    frame : ndarray of int (n,), optional
        Frame numbers (define the sample grid).
    tol : float
        Truncation of the impulse response.

    Returns
    -------
    LaggedDerivatives
        NaN where the streaming filter gives no output: the first ``window - 1 - lag`` and the last
        ``lag`` samples of every stretch, stretches shorter than ``window``, unfilled missing
        samples. ``window`` is the filter's memory [samples], ``lag`` its delay [frames].
    """
    dt = grid_positions(t_or_dt, np.shape(y)[0], frame)[0] if np.ndim(t_or_dt) else float(t_or_dt)
    if not (np.isfinite(dt) and dt > 0):
        return fir_derivatives(t_or_dt, y, np.zeros((3, 1)), 0, max_gap=max_gap, frame=frame)
    lag = lag_frames(lag_s, dt)
    tau = default_smoothing_s(lag * dt) if smoothing_s is None else float(smoothing_s)
    w = kalman_weights(dt, lag, order=order, smoothing_s=tau, tol=tol)
    return fir_derivatives(t_or_dt, y, w, lag, max_gap=max_gap, frame=frame)


def fir_derivatives(t_or_dt, y, weights: np.ndarray, lag: int, *, max_gap: int = DEFAULT_MAX_GAP,
                    frame=None) -> LaggedDerivatives:
    """Apply fixed-lag FIR weights stretch by stretch, as the streaming filter would (offline, vectorized).

    Parameters
    ----------
    t_or_dt, y, max_gap, frame
        As :func:`kalman_derivatives`.
    weights : ndarray (3, window)
        ``weights[d] @ y[k - window + 1 : k + 1]`` is the d-th derivative at frame ``k - lag``
        (:func:`kalman_weights`, or Savitzky-Golay weights evaluated off-centre).
    lag : int
        Output delay [frames], ``0 <= lag < window``.

    Returns
    -------
    LaggedDerivatives
        See :func:`kalman_derivatives`.
    """
    y = np.asarray(y, dtype=float)
    if y.ndim not in (1, 2):
        raise InputError(f"y must have shape (n,) or (n, k), got {y.shape}", key="y")
    n = y.shape[0]
    if not isinstance(max_gap, (int, np.integer)) or max_gap < 0:
        raise ConfigError(f"max_gap must be an integer >= 0, got {max_gap!r}", key="max_gap")
    w = np.asarray(weights, dtype=float)
    if w.ndim != 2 or w.shape[0] != 3 or not 0 <= lag < w.shape[1]:
        raise ConfigError(f"weights must have shape (3, window > lag), got {w.shape} with lag {lag}", key="weights")
    dt, k = grid_positions(t_or_dt, n, frame)
    out = [np.full(y.shape, np.nan) for _ in range(3)]
    filled = np.zeros(n, dtype=bool)
    if n < 2 or not np.isfinite(dt):
        return _derivs(out, filled, 0, dt, lag)
    filter_stretches(y, k, max_gap, w.shape[1], lambda seg: _stretch(seg, w, lag), out, filled)
    return _derivs(out, filled, w.shape[1], dt, lag)


def _derivs(out, filled, window, dt, lag) -> LaggedDerivatives:
    return LaggedDerivatives(out[0], out[1], out[2], filled, window, dt, int(lag))


def lag_frames(lag_s: float, dt: float) -> int:
    """A lag [s] rounded to whole frames.

    Parameters
    ----------
    lag_s : float
        Lag [s], finite and ``>= 0``.
    dt : float
        Frame period [s].

    Returns
    -------
    int
        The lag [frames], ``>= 0``.

    Raises
    ------
    ConfigError
        Naming ``lag_s`` when it is negative or not finite.
    """
    if not (np.isfinite(lag_s) and lag_s >= 0):
        raise ConfigError(f"lag_s must be >= 0 s, got {lag_s!r}", key="lag_s")
    return int(round(lag_s / dt))


class StreamingKalman(StreamingSavgol):
    """Online low-lag smoother: push one sample per frame, get the estimate ``lag`` frames back.

    The steady-state Kalman fixed-lag smoother of the module docstring as FIR weights, run through
    the buffering, gap bridging and reset logic of
    :class:`~euc_ros.core.filters.derivatives.StreamingSavgol` (only the weights differ): equal to
    :func:`kalman_derivatives` to round-off on every stretch.

    Parameters
    ----------
    dt : float
        Sample spacing [s].
    lag_s : float
        Output delay [s] (rounded to frames; :attr:`lag`, :attr:`lag_s`).
    smoothing_s : float, optional
        Smoothing time [s]; default :func:`default_smoothing_s` of the lag.
    order : int
        Integrator-chain order.
    max_gap : int
        Longest run of missing frames bridged.
    tol : float
        Truncation of the impulse response.

    Attributes
    ----------
    window : int
        Memory of the filter [samples]: a stretch gives its first output after this many samples.
    smoothing_s : float

    Examples
    --------
    >>> f = StreamingKalman(0.01, lag_s=0.05, smoothing_s=0.05)
    >>> outs = [f.push(0.5 * (0.01 * i) ** 2, frame=i) for i in range(f.window + 1)]
    >>> s = outs[-1][0]
    >>> s.frame == f.window - f.lag, round(float(s.y_ddot), 6)
    (True, 1.0)
    """

    def __init__(self, dt: float, *, lag_s: float, smoothing_s: float | None = None, order: int = DEFAULT_ORDER,
                 max_gap: int = DEFAULT_MAX_GAP, tol: float = DEFAULT_TOL) -> None:
        self.dt = float(dt)
        if not isinstance(max_gap, (int, np.integer)) or max_gap < 0:
            raise ConfigError(f"max_gap must be an integer >= 0, got {max_gap!r}", key="max_gap")
        self.max_gap = int(max_gap)
        self.lag = lag_frames(lag_s, self.dt)
        self.smoothing_s = default_smoothing_s(self.lag * self.dt) if smoothing_s is None else float(smoothing_s)
        self.order = int(order)
        self._coeffs = kalman_weights(self.dt, self.lag, order=order, smoothing_s=self.smoothing_s, tol=tol)
        self.window = self._coeffs.shape[1]
        self.polyorder = self.order - 1
        self._init_buffer()


def streaming_filter(estimator: str, dt: float, *, window_s: float, polyorder: int, max_gap: int = DEFAULT_MAX_GAP,
                     lag_s: float | None = None, smoothing_s: float | None = None) -> StreamingSavgol:
    """The streaming derivative filter of a state estimator, by name.

    Parameters
    ----------
    estimator : {"savgol", "kalman"}
        ``savgol``: the Savitzky-Golay filter of ``window_s`` / ``polyorder``, evaluated ``lag_s``
        before the newest sample (default: its centre, half the window). ``kalman``: the fixed-lag
        smoother of this module with ``lag_s`` (default :data:`LOW_LAG_S`) and ``smoothing_s``
        (default from :data:`SMOOTHING_TABLE`); ``window_s`` and ``polyorder`` are not used.
    dt : float
        Frame period [s].
    window_s : float
        Savitzky-Golay window [s].
    polyorder : int
        Savitzky-Golay polynomial order.
    max_gap : int
        Longest run of missing frames bridged.
    lag_s : float, optional
        Output delay [s].
    smoothing_s : float, optional
        Smoothing time of the ``kalman`` filter [s].

    Returns
    -------
    StreamingSavgol
        A :class:`~euc_ros.core.filters.derivatives.StreamingSavgol`, or a :class:`StreamingKalman`.

    Raises
    ------
    ConfigError
        Unknown estimator, a Savitzky-Golay lag beyond half its window, bad settings.

    Examples
    --------
    >>> round(streaming_filter("savgol", 1 / 120, window_s=1.2, polyorder=6).lag_s, 3)
    0.6
    >>> round(streaming_filter("kalman", 1 / 120, window_s=1.2, polyorder=6).lag_s, 3)
    0.1
    """
    if estimator == "split":
        raise ConfigError("the split estimator filters pieces of the poses, not one coordinate: use "
                          "RiderStateEstimator(estimator='split')", key="estimator")
    if estimator not in ESTIMATORS:
        raise ConfigError(f"estimator must be one of {ESTIMATORS}, got {estimator!r}", key="estimator")
    if estimator == "kalman":
        return StreamingKalman(dt, lag_s=LOW_LAG_S if lag_s is None else lag_s, smoothing_s=smoothing_s,
                               max_gap=max_gap)
    window = window_samples(dt, window_s=window_s, polyorder=polyorder)
    lag = None if lag_s is None else lag_frames(lag_s, dt)
    if lag is not None and lag > (window - 1) // 2:
        raise ConfigError(f"a Savitzky-Golay lag of {lag_s:g} s exceeds half the {window * dt:g} s window",
                          key="lag_s")
    return StreamingSavgol(window, polyorder, dt, max_gap=max_gap, lag=lag)
