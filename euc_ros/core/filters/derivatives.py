"""Savitzky-Golay smoothing with analytic first and second derivatives, offline and online.

The EUC paper (Section 2) smooths the motion-capture signals with the Savitzky-Golay method and
differentiates the fitted polynomials analytically. This module does the same in two forms that
give identical numbers on identical data:

* :func:`savgol_derivatives` (offline): a whole recording at once. The signal is split into
  gap-free stretches: a run of more than ``max_gap`` missing frames (NaN samples or frame numbers
  that skip) ends a stretch, and nothing is ever interpolated across it. Shorter runs are filled by
  linear interpolation between their neighbours before filtering; those samples get values but are
  flagged (:attr:`Derivatives.filled`). Stretches shorter than the window give NaN, never garbage.
  Inside a stretch the least-squares polynomial of every window gives the value and the
  derivatives; the first and last ``(window - 1) / 2`` samples are evaluated on the polynomial of
  the first and last full window (the response of ``scipy.signal.savgol_filter(mode="interp")``).
* :class:`StreamingSavgol` (online): push one sample at a time and receive the smoothed value and
  derivatives of the sample ``lag`` frames earlier. With the default (centred) lag
  ``(window - 1) / 2`` it is the same least-squares polynomial as the offline filter evaluated at
  the centre, so the outputs equal the offline ones on the interior of every stretch (the samples
  at least ``lag`` frames away from both ends of the stretch) to round-off. A smaller lag trades
  noise for delay (``lag=0`` is causal: the fit evaluated at the newest sample).

Both use :func:`savgol_coefficients`, which builds the fit in the normalised time
``u = (j - c) / c`` on ``[-1, 1]`` (``c = (window - 1) / 2``) with a Legendre basis and a QR
factorisation, and scales the d-th derivative by ``(1 / (c dt))**d`` afterwards. The conditioning
is then that of a fixed well-posed problem whatever the rate, window or time unit, so the
derivative coefficients sum to zero to round-off at any rate (``scipy.signal.savgol_coeffs`` builds
the Vandermonde matrix in sample units and loses that cancellation for long windows: at 360 Hz with
a 433-sample window and order 6 its second-derivative coefficients sum to ~50 instead of 0).

Units: ``dt`` in seconds; derivatives are per second and per second squared of ``y``'s unit.

Examples
--------
>>> import numpy as np
>>> dt = 1 / 120
>>> t = np.arange(240) * dt
>>> d = savgol_derivatives(dt, np.sin(t), window_s=0.2, polyorder=3)
>>> bool(np.allclose(d.y_dot[12:-12], np.cos(t[12:-12]), atol=1e-6))
True
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Iterator, NamedTuple

import numpy as np
from numpy.polynomial import legendre

from euc_ros.core.errors import ConfigError, InputError
from euc_ros.core.filters.overlap_add import oaconvolve_many


def _correlate1d():
    """scipy.ndimage.correlate1d, imported on first use (``euc-ros --help`` should not pay scipy)."""
    from scipy.ndimage import correlate1d

    return correlate1d


#: Stretches at least this many windows long are filtered by overlap-add FFT convolution, the value and both
#: derivatives in one pass (~7x cheaper than three direct correlations on a 10-minute recording at a 145-sample
#: window); shorter ones directly. The two agree to round-off of the signal's scale (the FFT's error is
#: relative to the stretch's largest value, ~1e-15; the filter's own output is of the same scale).
FFT_MIN_WINDOWS = 8


#: Default polynomial order (cubic: unbiased second derivative for signals up to cubic in time).
DEFAULT_POLYORDER = 3
#: Default longest run of missing frames filled by interpolation [frames].
DEFAULT_MAX_GAP = 5


def window_samples(dt: float, window_s: float | None = None, window: int | None = None,
                   polyorder: int = DEFAULT_POLYORDER) -> int:
    """Return an odd window length in samples from ``window_s`` [s] or ``window`` [samples].

    Parameters
    ----------
    dt : float
        Sample spacing [s].
    window_s : float, optional
        Window duration [s]; rounded to the nearest odd number of samples.
    window : int, optional
        Window length [samples]; must be odd. Give exactly one of ``window_s`` and ``window``.
    polyorder : int
        Polynomial order; the window must be longer than it.

    Returns
    -------
    int
        Window length [samples], odd and ``> polyorder``.

    Raises
    ------
    ConfigError
        Naming ``window_s``, ``window`` or ``polyorder`` when the combination is invalid.
    InputError
        Naming ``dt`` when it is not a finite positive number.
    """
    if (window_s is None) == (window is None):
        raise ConfigError("give exactly one of window_s [s] and window [samples]", key="window_s")
    if isinstance(polyorder, bool) or not isinstance(polyorder, (int, np.integer)) or polyorder < 2:
        raise ConfigError(f"polyorder must be an integer >= 2 (second derivatives), got {polyorder!r}",
                          key="polyorder")
    if not (np.isfinite(dt) and dt > 0):
        raise InputError(f"sample spacing must be > 0 s, got {dt!r}", key="dt")
    if window_s is not None:
        if not (np.isfinite(window_s) and window_s > 0):
            raise ConfigError(f"window_s must be > 0 s, got {window_s!r}", key="window_s")
        w = 2 * int(round((window_s / dt - 1.0) / 2.0)) + 1
        key = "window_s"
    else:
        w = int(window)
        key = "window"
        if w != window or w % 2 == 0:
            raise ConfigError(f"window must be an odd number of samples, got {window!r}", key="window")
    if w <= polyorder:
        raise ConfigError(f"window of {w} samples must be longer than polyorder {polyorder}", key=key)
    return w


def savgol_coefficients(window: int, polyorder: int, dt: float, positions,
                        derivs=(0, 1, 2)) -> np.ndarray:
    """Savitzky-Golay coefficients: value and derivatives of the local fit at given positions.

    The least-squares polynomial of order ``polyorder`` through ``window`` equally spaced samples,
    evaluated (or differentiated) at ``positions``, is a linear combination of the samples; this
    returns its weights. The fit is built in the normalised time ``u = (j - c) / c`` on ``[-1, 1]``
    (``c = (window - 1) / 2``) with Legendre polynomials, solved by QR, and the d-th derivative is
    scaled by ``(1 / (c dt))**d``: numerically sound at any rate and window length.

    Parameters
    ----------
    window : int
        Odd window length [samples], ``> polyorder``.
    polyorder : int
        Polynomial order.
    dt : float
        Sample spacing [s].
    positions : array_like of float (m,)
        Where to evaluate, in samples from the window's first sample (``c`` is the centre).
    derivs : sequence of int
        Derivative orders.

    Returns
    -------
    ndarray (len(derivs), m, window)
        ``out[i, j] @ samples`` is the ``derivs[i]``-th derivative [unit/s^d] at ``positions[j]``.

    Examples
    --------
    >>> h = savgol_coefficients(433, 6, 1 / 360, [216])
    >>> abs(float(h[2, 0].sum())) < 1e-9   # a constant has no acceleration, at any rate
    True
    """
    return _assemble(*_savgol_factors(int(window), int(polyorder), positions, tuple(derivs)), dt)


def _savgol_factors(window: int, polyorder: int, positions, derivs: tuple) -> tuple:
    """``(q, solves, c, derivs)`` of :func:`savgol_coefficients`.

    The QR factor ``q`` (window, p + 1) of the Legendre basis and, per derivative, the (p + 1, m) triangular
    solve; small beside the (m, window) coefficients they make.
    """
    from scipy.linalg import qr, solve_triangular

    c = (window - 1) / 2.0
    u = (np.arange(window) - c) / c
    q, r = qr(legendre.legvander(u, polyorder), mode="economic")
    up = (np.atleast_1d(np.asarray(positions, dtype=float)) - c) / c
    eye = np.eye(polyorder + 1)
    solves = []
    for d in derivs:
        # row k of g: the d-th derivative of Legendre polynomial k at every position
        g = np.stack([legendre.legval(up, legendre.legder(eye[k], d) if d else eye[k])
                      for k in range(polyorder + 1)])
        solves.append(solve_triangular(r, g, trans="T"))
    return q, tuple(solves), c, derivs


def _assemble(q: np.ndarray, solves: tuple, c: float, derivs: tuple, dt: float) -> np.ndarray:
    """The coefficients (len(derivs), m, window) from :func:`_savgol_factors`."""
    out = np.empty((len(derivs), solves[0].shape[1], q.shape[0]))
    for i, d in enumerate(derivs):
        out[i] = (q @ solves[i]).T / (c * dt) ** d
    return out


@functools.lru_cache(maxsize=32)
def _stretch_factors(w: int, polyorder: int) -> tuple:
    """:func:`_savgol_factors` of :func:`_stretch_coefficients`, cached.

    The analyses filter many series with the same window; a few (p + 1, w) arrays each, read-only.
    """
    half = (w - 1) // 2
    edges = np.arange(half)
    q, solves, c, derivs = _savgol_factors(w, polyorder, np.concatenate(([half], edges, edges + half + 1)), (0, 1, 2))
    for a in (q,) + solves:
        a.setflags(write=False)
    return q, solves, c, derivs


def _stretch_coefficients(w: int, polyorder: int, dt: float) -> np.ndarray:
    """Centre and edge coefficients of :func:`_filter_stretch`.

    An array (3, w, w), row 0 the centre, rows 1 to half the first half samples', the rest the last half's.
    Made from cached factors (the same numbers as :func:`savgol_coefficients`); the last
    :data:`STRETCH_COEFFICIENTS_KEPT` are kept, read-only (3 w^2 numbers each, 0.7 MB at w = 171): a
    reconstruction filters several signals with one filter, and the analyses reconstruct again with the same few.
    """
    return _kept_stretch_coefficients(int(w), int(polyorder), float(dt))


#: Filters whose :func:`_stretch_coefficients` are kept.
STRETCH_COEFFICIENTS_KEPT = 4


@functools.lru_cache(maxsize=STRETCH_COEFFICIENTS_KEPT)
def _kept_stretch_coefficients(w: int, polyorder: int, dt: float) -> np.ndarray:
    out = _assemble(*_stretch_factors(w, polyorder), dt)
    out.setflags(write=False)
    return out


def _filter_stretch(seg: np.ndarray, w: int, polyorder: int, dt: float, out=None) -> np.ndarray:
    """Value and derivatives (3, L, k) of a gap-free stretch ``seg`` (L >= w, k columns).

    ``out``: three (L, k) arrays to write into (e.g. views of the whole recording's outputs), so no
    (3, L, k) result is made and copied; the temporaries are one offset-free column and its transforms (a short
    stretch: the whole offset-free stretch).
    """
    half = (w - 1) // 2
    length = seg.shape[0]
    coeffs = _stretch_coefficients(int(w), int(polyorder), float(dt))
    centre, head, tail = coeffs[:, 0], coeffs[:, 1:half + 1], coeffs[:, half + 1:]
    if out is None:
        out = np.empty((3,) + seg.shape)
    # a constant offset cancels exactly in the derivatives; removing it keeps round-off at the
    # scale of the motion, not of the distance from the origin
    ref = np.array(seg[length // 2])
    if length >= FFT_MIN_WINDOWS * w:
        # correlation with c is convolution with c reversed: output i is the full convolution's i + half; one
        # column at a time, the column's offset removed as it is taken, its transform shared by the three
        # derivatives (each result scipy's oaconvolve's: oaconvolve_many), one derivative's result at a time
        kernel = centre[:, ::-1]
        for j in range(1 if seg.ndim == 1 else seg.shape[1]):
            col = (seg - ref if seg.ndim == 1 else seg[:, j] - ref[j])[None]
            for d, full in enumerate(oaconvolve_many(col, [kernel[d:d + 1] for d in range(3)], axes=1)):
                target = out[d] if seg.ndim == 1 else out[d][:, j]
                target[half:length - half] = full[0, 2 * half:length]
                del full
            del col
        x_head, x_tail = seg[:w] - ref, seg[length - w:] - ref
    else:
        x = seg - ref
        for d in range(3):
            _correlate1d()(x, centre[d], axis=0, mode="constant", output=out[d])
        x_head, x_tail = x[:w], x[length - w:]
    for d in range(3):
        out[d][:half] = head[d] @ x_head
        out[d][length - half:] = tail[d] @ x_tail
    out[0] += ref
    return out


@dataclass(frozen=True)
class Derivatives:
    """Smoothed signal and its analytic derivatives (unpacks as ``y, y_dot, y_ddot``).

    Parameters
    ----------
    y, y_dot, y_ddot : ndarray
        Value and its first and second derivatives [unit, unit/s, unit/s^2], the input's shape; NaN outside
        usable stretches.
    filled : ndarray of bool (n,)
        Samples that were missing in the input and were filled by interpolation across a short gap:
        they have values, but they are not measurements.
    window : int
        Window length used [samples].
    dt : float
        Sample spacing used [s].
    """

    y: np.ndarray
    y_dot: np.ndarray
    y_ddot: np.ndarray
    filled: np.ndarray
    window: int
    dt: float

    def __iter__(self) -> Iterator[np.ndarray]:
        return iter((self.y, self.y_dot, self.y_ddot))


def grid_positions(t_or_dt, n: int, frame) -> tuple[float, np.ndarray]:
    """The sample spacing and the integer grid position of every sample.

    Parameters
    ----------
    t_or_dt : float or array_like (n,)
        Sample spacing [s], or the sample times [s] (then the spacing is the median step, per frame when
        ``frame`` is given).
    n : int
        Number of samples.
    frame : array_like of int (n,) or None
        Frame numbers; when given they are the grid positions (from the first one).

    Returns
    -------
    dt : float
        Sample spacing [s]; NaN when times are given for fewer than two samples.
    k : numpy.ndarray of int (n,)
        Grid position of every sample, 0 at the first.

    Raises
    ------
    InputError
        Naming ``frame`` or ``t`` for a wrong shape, and ``t`` for times or frames that do not increase.
    """
    t_arr = np.asarray(t_or_dt, dtype=float)
    if frame is not None:
        k = np.asarray(frame, dtype=np.int64)
        if k.shape != (n,):
            raise InputError(f"frame must have shape ({n},), got {k.shape}", key="frame")
        k = k - k[0] if n else k
    if t_arr.ndim == 0:
        dt = float(t_arr)
        if frame is None:
            k = np.arange(n, dtype=np.int64)
    else:
        if t_arr.shape != (n,):
            raise InputError(f"t must have shape ({n},), got {t_arr.shape}", key="t")
        if n < 2:
            return float("nan"), np.arange(n, dtype=np.int64)
        if frame is not None:
            dk = np.diff(k)
            ok = dk > 0
            dt = float(np.median(np.diff(t_arr)[ok] / dk[ok])) if ok.any() else float("nan")
        else:
            dt = float(np.median(np.diff(t_arr)))
            if not (np.isfinite(dt) and dt > 0):
                raise InputError("time stamps must increase", key="t")
            k = np.rint((t_arr - t_arr[0]) / dt).astype(np.int64)
    if n > 1 and np.any(np.diff(k) <= 0):
        i = int(np.flatnonzero(np.diff(k) <= 0)[0])
        raise InputError(f"samples must be strictly increasing in time/frame (sample {i + 1})", key="t")
    return dt, k


def gap_stretches(k: np.ndarray, valid: np.ndarray, max_gap: int) -> list[tuple[int, int]]:
    """Split samples into gap-free stretches.

    Parameters
    ----------
    k : ndarray of int (n,)
        Grid position (frame number) of every sample, strictly increasing.
    valid : ndarray of bool (n,)
        Samples holding a measurement.
    max_gap : int
        Longest run of missing frames (absent frame numbers or invalid samples) that does not end a
        stretch.

    Returns
    -------
    list of (i0, i1)
        Index ranges ``[i0, i1]`` (inclusive) into the sample arrays; ``i0`` and ``i1`` are valid
        samples.
    """
    idx = np.flatnonzero(valid)
    if idx.size == 0:
        return []
    missing = np.diff(k[idx]) - 1
    breaks = np.flatnonzero(missing > max_gap)
    starts = np.concatenate(([0], breaks + 1))
    ends = np.concatenate((breaks, [idx.size - 1]))
    return [(int(idx[s]), int(idx[e])) for s, e in zip(starts, ends)]


def savgol_derivatives(t_or_dt, y, *, window_s: float | None = None, window: int | None = None,
                       polyorder: int = DEFAULT_POLYORDER, max_gap: int = DEFAULT_MAX_GAP,
                       frame=None) -> Derivatives:
    """Smooth ``y`` and differentiate it analytically (Savitzky-Golay), stretch by stretch.

    Parameters
    ----------
    t_or_dt : float or ndarray (n,)
        Sample spacing dt [s], or the sample times [s] (then dt is their median spacing and a time
        step of several dt counts as missing frames).
    y : ndarray (n,) or (n, k)
        Signal, time along axis 0. A sample with any NaN component is missing.
    window_s : float, optional
        Window duration [s] (rounded to an odd number of samples).
    window : int, optional
        Window length [samples], odd. Give exactly one of ``window_s`` and ``window``.
    polyorder : int
        Order of the local polynomial (>= 2).
    max_gap : int
        Runs of at most this many missing frames are filled by linear interpolation (and flagged);
        longer runs split the signal into separate stretches.
    frame : ndarray of int (n,), optional
        Frame numbers; when given they define the sample grid (gaps are skipped numbers).

    Returns
    -------
    Derivatives
        ``y``, ``y_dot`` [unit/s], ``y_ddot`` [unit/s^2], ``filled`` flags. NaN on stretches
        shorter than the window and on missing samples not filled.
    """
    y = np.asarray(y, dtype=float)
    if y.ndim not in (1, 2):
        raise InputError(f"y must have shape (n,) or (n, k), got {y.shape}", key="y")
    n = y.shape[0]
    if not isinstance(max_gap, (int, np.integer)) or max_gap < 0:
        raise ConfigError(f"max_gap must be an integer >= 0, got {max_gap!r}", key="max_gap")
    dt, k = grid_positions(t_or_dt, n, frame)
    out = [np.full(y.shape, np.nan) for _ in range(3)]
    filled = np.zeros(n, dtype=bool)
    if n < 2 or not np.isfinite(dt):
        return Derivatives(*out, filled, 0, dt)
    w = window_samples(dt, window_s, window, polyorder)
    filter_stretches(y, k, max_gap, w, lambda seg: _filter_stretch(seg, w, polyorder, dt), out, filled,
                     filter_into=lambda seg, dst: _filter_stretch(seg, w, polyorder, dt, out=dst))
    return Derivatives(out[0], out[1], out[2], filled, w, dt)


def filter_stretches(y: np.ndarray, k: np.ndarray, max_gap: int, min_length: int, filter_stretch,
                     out: list[np.ndarray], filled: np.ndarray, filter_into=None) -> None:
    """Apply ``filter_stretch`` to every gap-free stretch of ``y`` (in place into ``out`` and ``filled``).

    Stretches come from :func:`gap_stretches`; those shorter than ``min_length`` grid samples are skipped.
    Within a stretch the missing grid samples (at most ``max_gap`` in a row) are filled by linear
    interpolation and flagged in ``filled``; ``filter_stretch(seg)`` maps the gap-free (L, c) stretch to its
    value and derivatives (3, L, c), written back at the recorded samples. ``filter_into(seg, dst)``, if
    given, does the same for a stretch without missing samples straight into ``dst``, three (L, c) views
    of ``out`` (no copy of the stretch, no (3, L, c) result: the memory of filtering a long recording is
    its outputs plus one stretch).

    Parameters
    ----------
    y : numpy.ndarray (n,) or (n, c)
        Signal, time along axis 0; a sample with any non-finite component is missing.
    k : numpy.ndarray of int (n,)
        Grid position of every sample, strictly increasing.
    max_gap : int
        Longest run of missing grid samples bridged [samples].
    min_length : int
        Shortest stretch filtered [grid samples].
    filter_stretch : callable
        ``filter_stretch(seg) -> (3, L, c)`` for a gap-free (L, c) stretch.
    out : list of numpy.ndarray
        Three arrays of ``y``'s shape: value and first and second derivatives, written in place.
    filled : numpy.ndarray of bool (n,)
        Set in place to True at the samples filled by interpolation.
    filter_into : callable, optional
        ``filter_into(seg, dst)`` writing a stretch without missing samples into ``dst``.
    """
    n = y.shape[0]
    y2 = y.reshape(n, -1)
    valid = np.all(np.isfinite(y2), axis=1)
    for i0, i1 in gap_stretches(k, valid, max_gap):
        length = int(k[i1] - k[i0]) + 1
        if length < min_length:
            continue
        v = valid[i0:i1 + 1]
        if filter_into is not None and length == i1 - i0 + 1 and bool(v.all()):
            filter_into(y2[i0:i1 + 1], [o.reshape(n, -1)[i0:i1 + 1] for o in out])
            continue
        kk = k[i0:i1 + 1] - k[i0]
        grid = np.arange(length)
        seg = np.empty((length, y2.shape[1]))
        for c in range(y2.shape[1]):
            seg[:, c] = np.interp(grid, kk[v], y2[i0:i1 + 1][v, c])
        res = filter_stretch(seg)
        for d in range(3):
            out[d].reshape(n, -1)[i0:i1 + 1] = res[d][kk]
        filled[i0:i1 + 1] = ~v


class StreamSample(NamedTuple):
    """One output of :class:`StreamingSavgol`: the smoothed sample ``lag`` frames back.

    Parameters
    ----------
    frame : int
        Frame number of the sample.
    y, y_dot, y_ddot : float or numpy.ndarray (k,)
        Value and its first and second derivatives [unit, unit/s, unit/s^2] (floats for a scalar signal).
    filled : bool
        The sample was filled by interpolation across a short gap.
    """

    frame: int
    y: np.ndarray | float
    y_dot: np.ndarray | float
    y_ddot: np.ndarray | float
    filled: bool


class StreamingSavgol:
    """Online fixed-lag Savitzky-Golay filter with analytic derivatives.

    Push one sample per frame; once ``window`` consecutive frames are buffered, each push returns
    the local polynomial fit of the last ``window`` samples evaluated ``lag`` frames before the
    newest one. With the default centred lag this equals :func:`savgol_derivatives` on the interior
    of every stretch. A run of more than ``max_gap`` missing frames (a NaN sample or a frame number
    that skips) resets the filter; shorter runs are filled by linear interpolation when the next
    sample arrives, exactly as offline, and their outputs carry ``filled=True``.

    Parameters
    ----------
    window : int
        Odd window length [samples] (see :func:`window_samples`).
    polyorder : int
        Polynomial order (>= 2).
    dt : float
        Sample spacing [s].
    max_gap : int
        Longest run of missing frames that is bridged.
    lag : int, optional
        Output delay [frames], ``0 <= lag <= (window - 1) / 2``; default ``(window - 1) / 2``.
        The time lag is ``lag * dt`` (:attr:`lag_s`).

    Examples
    --------
    >>> f = StreamingSavgol(5, 2, 0.01)
    >>> outs = [f.push(0.5 * (0.01 * i) ** 2, frame=i) for i in range(6)]
    >>> [len(o) for o in outs]
    [0, 0, 0, 0, 1, 1]
    >>> s = outs[-1][0]
    >>> s.frame, round(float(s.y_ddot), 9)
    (3, 1.0)
    """

    def __init__(self, window: int, polyorder: int, dt: float, *, max_gap: int = DEFAULT_MAX_GAP,
                 lag: int | None = None) -> None:
        self.window = window_samples(dt, window=window, polyorder=polyorder)
        self.polyorder = int(polyorder)
        self.dt = float(dt)
        if not isinstance(max_gap, (int, np.integer)) or max_gap < 0:
            raise ConfigError(f"max_gap must be an integer >= 0, got {max_gap!r}", key="max_gap")
        self.max_gap = int(max_gap)
        half = (self.window - 1) // 2
        self.lag = half if lag is None else int(lag)
        if not 0 <= self.lag <= half:
            raise ConfigError(f"lag must be in [0, {half}] frames, got {lag!r}", key="lag")
        pos = self.window - 1 - self.lag
        self._coeffs = savgol_coefficients(self.window, self.polyorder, self.dt, [pos])[:, 0]
        self._init_buffer()

    def _init_buffer(self) -> None:
        """Empty buffers for :attr:`window` samples (called once the weights are set)."""
        # ring buffer written twice (at i and i + window) so the last ``window`` samples are always one
        # contiguous slice: no per-sample stacking of the window
        self._data: np.ndarray | None = None            # (2 window, k)
        self._frames = np.zeros(2 * self.window, dtype=np.int64)
        self._filled = np.zeros(2 * self.window, dtype=bool)
        self._n = 0                                     # samples in the current stretch
        self._last_frame: int | None = None
        self._last_value: np.ndarray | None = None
        self._scalar = True

    @property
    def lag_s(self) -> float:
        """Output delay [s]."""
        return self.lag * self.dt

    def reset(self) -> None:
        """Forget the buffered samples (the next push starts a new stretch)."""
        self._n = 0
        self._last_frame = None
        self._last_value = None

    def _append(self, frame: int, value: np.ndarray, filled: bool, out: list[StreamSample]) -> None:
        w = self.window
        if self._data is None or self._data.shape[1] != value.shape[0]:
            self._data = np.zeros((2 * w, value.shape[0]))
            self._n = 0
        i = self._n % w
        self._data[i] = value
        self._data[i + w] = value
        self._frames[i] = self._frames[i + w] = frame
        self._filled[i] = self._filled[i + w] = filled
        self._n += 1
        if self._n < w:
            return
        start = i + 1                                   # oldest sample of the window
        res = self._coeffs @ self._data[start:start + w]  # (3, k)
        j = start + w - 1 - self.lag
        frame_out, filled_out = int(self._frames[j]), bool(self._filled[j])
        if self._scalar:
            out.append(StreamSample(frame_out, float(res[0, 0]), float(res[1, 0]), float(res[2, 0]), filled_out))
        else:
            out.append(StreamSample(frame_out, res[0], res[1], res[2], filled_out))

    def push(self, y, frame: int | None = None) -> list[StreamSample]:
        """Add the sample of ``frame`` (default: the frame after the previous push).

        Parameters
        ----------
        y : float or array_like (k,)
            The new sample; any NaN component marks it missing.
        frame : int, optional
            Its frame number.

        Returns
        -------
        list of StreamSample
            Usually zero or one output; more when a bridged gap completes several windows at once.
        """
        value = np.atleast_1d(np.asarray(y, dtype=float)).ravel()
        self._scalar = np.ndim(y) == 0
        if frame is None:
            frame = 0 if self._last_frame is None else self._last_frame + 1
        frame = int(frame)
        out: list[StreamSample] = []
        if not np.all(np.isfinite(value)):
            if self._last_frame is not None and frame - self._last_frame > self.max_gap:
                self.reset()
            return out
        if self._last_frame is None:
            self._append(frame, value, False, out)
        else:
            missing = frame - self._last_frame - 1
            if missing < 0:
                raise InputError(f"frame {frame} does not follow frame {self._last_frame}", key="frame")
            if missing > self.max_gap or (self._last_value is not None and self._last_value.shape != value.shape):
                self.reset()
                self._append(frame, value, False, out)
            else:
                for j in range(1, missing + 1):
                    a = j / (missing + 1)
                    self._append(self._last_frame + j, (1 - a) * self._last_value + a * value, True, out)
                self._append(frame, value, False, out)
        self._last_frame = frame
        self._last_value = value
        return out


def trim_edges(mask: np.ndarray, k: int, position: np.ndarray | None = None,
               max_gap: int = DEFAULT_MAX_GAP) -> np.ndarray:
    """Drop the samples within ``k`` frames of either end of every stretch of True in ``mask``.

    Near the ends of a stretch a Savitzky-Golay fit extrapolates its polynomial, so its derivatives
    are much less accurate than inside; the online fixed-lag filter never outputs those samples.
    ``position`` gives each sample's frame number (rows may skip dropped frames; a skip of more than
    ``max_gap`` frames ends a stretch, as in :func:`savgol_derivatives`); default: the row index.

    Parameters
    ----------
    mask : array_like of bool (n,)
        Usable samples.
    k : int
        Frames dropped at each end of a stretch.
    position : array_like of int (n,), optional
        Frame number of every sample.
    max_gap : int
        Longest skip of frames inside a stretch.

    Returns
    -------
    numpy.ndarray of bool (n,)
        ``mask`` without the samples near the stretches' ends.
    """
    mask = np.asarray(mask, dtype=bool)
    if k <= 0:
        return mask.copy()
    pos = np.arange(mask.size) if position is None else np.asarray(position, dtype=np.int64)
    out = np.zeros_like(mask)
    rows = np.flatnonzero(mask)
    if rows.size == 0:
        return out
    p = pos[rows]
    breaks = np.flatnonzero((np.diff(rows) > 1) | (np.diff(p) > max_gap + 1)) + 1
    for seg in np.split(np.arange(rows.size), breaks):
        ps = p[seg]
        out[rows[seg]] = (ps - ps[0] >= k) & (ps[-1] - ps >= k)
    return out
