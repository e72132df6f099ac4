"""A Savitzky-Golay window and order chosen from the recording itself, with the distortion it leaves.

A fixed window suits one kind of motion: too long for a fast balance loop, it flattens the
accelerations (the Savitzky-Golay second derivative of a window of ``T`` seconds and order ``p``
follows a sinusoid only well below ~``(p + 2) / (2 T)`` Hz); too short for noisy poses, it
amplifies the noise. Both errors bias the identified CoG height h. This module estimates, from the
raw signals of a recording (pitch angles, wheel-centre coordinates), their spectra and the noise
floor, predicts for every candidate window and order the two errors of each signal's second
derivative (distortion and noise), and picks the candidate with the smallest total.

The prediction needs no model of the ride: the signal's spectrum comes from the data (Welch, on the
second differences, so that the slow large motions leak nothing into the high frequencies), the
noise floor either from the stated pose noise or from the spectrum's flat high-frequency end, and
the filter's response from its own coefficients.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Mapping, NamedTuple, Sequence

import numpy as np

from euc_ros.core.errors import ConfigError, InputError
from euc_ros.core.filters.derivatives import DEFAULT_MAX_GAP, gap_stretches

#: Candidate polynomial orders (for the value and the second derivative, order 2k and 2k+1 give the
#: same centred coefficients, so odd orders add nothing).
DEFAULT_ORDERS = (2, 4, 6, 8)
#: Candidate windows [s]: a geometric grid from a few samples up to this length.
MAX_WINDOW_S = 2.5
#: Welch segment length [s] (frequency resolution 1 / this).
SEGMENT_S = 4.0
#: Share of the Nyquist band, at its top, from which the noise floor is read when it is not given.
NOISE_BAND = (0.6, 0.95)
#: A spectral bin holds motion while it exceeds the noise floor by this many standard deviations of
#: the estimate (about ``floor / sqrt(n_avg)``).
FLOOR_SIGMAS = 4.0


def savgol_kernel(window: int, polyorder: int, deriv: int, dt: float) -> np.ndarray:
    """Centred Savitzky-Golay weights: the ``deriv``-th derivative of the local fit at the window's centre.

    Parameters
    ----------
    window : int
        Odd window length [samples], ``> polyorder``.
    polyorder : int
    deriv : int
        Derivative order (0, 1, 2).
    dt : float
        Sample spacing [s].

    Returns
    -------
    ndarray (window,)
        Weights ``w_j``, ``j = -c..c`` (``c = (window - 1) / 2``): the estimate at sample ``i`` is
        ``sum_j w_j y_{i+j}`` [unit / s^deriv].

    Notes
    -----
    Least squares of ``y_j ~ sum_m a_m u_j^m`` in the normalised time ``u_j = j / c`` on ``[-1, 1]``
    (a Vandermonde matrix whose conditioning does not grow with the window, unlike one built in
    sample units); with ``V = QR`` the coefficients are ``a = R^-1 Q^T y`` and the ``d``-th time
    derivative at the centre is ``d! a_d / (c dt)^d``.
    """
    return _savgol_kernel(int(window), int(polyorder), int(deriv), float(dt)).copy()


@functools.lru_cache(maxsize=512)
def _savgol_kernel(window: int, polyorder: int, deriv: int, dt: float) -> np.ndarray:
    """:func:`savgol_kernel`, kept (read-only).

    The candidates of :func:`choose_window` are the same for every recording of a rate, and each is asked for its
    response and its weights.
    """
    if window % 2 != 1 or window <= polyorder:
        raise ConfigError(f"window must be odd and > polyorder, got {window} and {polyorder}", key="window")
    c = (window - 1) // 2
    u = np.arange(-c, c + 1) / c
    V = np.vander(u, polyorder + 1, increasing=True)
    q, r = np.linalg.qr(V)
    coef = np.linalg.solve(r, q.T)                      # (p + 1, window): a = coef @ y
    out = float(np.prod(np.arange(1, deriv + 1))) * coef[deriv] / (c * dt) ** deriv
    out.setflags(write=False)
    return out


def savgol_response(window: int, polyorder: int, deriv: int, dt: float, freqs) -> np.ndarray:
    """Frequency response of :func:`savgol_kernel` at ``freqs`` [Hz]: ``sum_j w_j exp(2 pi i f j dt)``.

    The ideal ``deriv``-th derivative has the response ``(2 pi i f)^deriv``. On a spectrum's own grid
    (``freqs`` the ``N``-point DFT's ``m / (N dt)``, to 1e-12 relative) it is one FFT: the weights folded
    modulo ``N`` (the exponential's period in ``j``), ``H_m = conj(rfft(a))_m``; elsewhere the sum itself.
    Both are the same sum to round-off.

    Parameters
    ----------
    window : int
        Odd window length [samples], ``> polyorder``.
    polyorder : int
        Polynomial order.
    deriv : int
        Derivative order (0, 1, 2).
    dt : float
        Sample spacing [s].
    freqs : array_like (m,)
        Frequencies [Hz].

    Returns
    -------
    numpy.ndarray of complex (m,)
        The response [1 / s^deriv].

    Raises
    ------
    ConfigError
        Naming ``window`` when it is even or not longer than ``polyorder``.
    """
    f = np.asarray(freqs, dtype=float)
    return _response(_savgol_kernel(int(window), int(polyorder), int(deriv), float(dt)), dt, f, _dft_length(f, dt))


def _response(w: np.ndarray, dt: float, f: np.ndarray, n: int | None) -> np.ndarray:
    """:func:`savgol_response` of the weights ``w`` at ``f``, ``n`` its :func:`_dft_length` (None: off the grid)."""
    c = (w.size - 1) // 2
    j = np.arange(-c, c + 1)
    if n is not None:
        a = np.bincount(j % n, weights=w, minlength=n)
        return np.conj(np.fft.rfft(a))
    ph = 2 * np.pi * f[:, None] * j[None, :] * dt
    return np.cos(ph) @ w + 1j * (np.sin(ph) @ w)


def _dft_length(f: np.ndarray, dt: float) -> int | None:
    """``N`` when ``f`` is ``numpy.fft.rfftfreq(N, dt)`` (to 1e-12 relative), else None."""
    if f.ndim != 1 or f.size < 2:
        return None
    for n in (2 * (f.size - 1), 2 * f.size - 1):
        grid = np.fft.rfftfreq(n, dt)
        if grid.size == f.size and np.allclose(f, grid, rtol=1e-12, atol=0.0):
            return n
    return None


def welch_linear(x: np.ndarray, fs: float, nperseg: int) -> tuple[np.ndarray, np.ndarray]:
    """Welch's one-sided power spectral density of ``x`` [unit^2/Hz].

    What ``scipy.signal.welch(x, fs, nperseg=nperseg, detrend="linear")`` gives (periodic Hann windows, half
    overlap, each segment's least-squares line removed, the segments' mean), with every segment detrended,
    windowed and transformed at once. scipy removes the lines one segment at a time by least squares; here
    each segment is projected off ``[1, t]`` (orthogonal, so the same line): equal to round-off
    (``test_auto_window``).

    Parameters
    ----------
    x : numpy.ndarray (n,)
        Evenly sampled signal, ``n >= nperseg``.
    fs : float
        Sampling rate [Hz].
    nperseg : int
        Segment length [samples].

    Returns
    -------
    freqs : numpy.ndarray (nperseg // 2 + 1,)
        Frequencies [Hz].
    psd : numpy.ndarray (nperseg // 2 + 1,)
        Power spectral density [unit^2/Hz].
    """
    x = np.asarray(x, dtype=float)
    n = int(nperseg)
    step = n - n // 2
    segs = np.lib.stride_tricks.sliding_window_view(x, n)[::step]
    t = np.arange(n) - 0.5 * (n - 1)                  # centred time: orthogonal to the constant
    d = segs - segs.mean(axis=1, keepdims=True)
    d -= np.outer(d @ t / (t @ t), t)
    win = 0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(n) / n)
    spec = np.fft.rfft(d * win, axis=1)
    p = (spec.real ** 2 + spec.imag ** 2).mean(axis=0) / (fs * float(win @ win))
    p[1:(n + 1) // 2] *= 2.0                          # one-sided: every bin but 0 Hz and an even length's Nyquist
    return np.fft.rfftfreq(n, 1.0 / fs), p


#: Longest run of missing samples a spectrum's stretch is continued across (interpolated, not split): the run
#: the states themselves fill (frames Motive dropped).
BRIDGED_GAP = DEFAULT_MAX_GAP


def _bridged_stretches(y: np.ndarray, min_len: int, max_gap: int = BRIDGED_GAP):
    """Runs of ``y`` of at least ``min_len`` samples, continued across gaps of at most ``max_gap`` missing samples.

    The runs are found as for the states (:func:`~euc_ros.core.filters.derivatives.gap_stretches`); the gaps'
    samples are linearly interpolated.

    A spectrum through second differences needs the stretch's samples on one grid, and zeroing (masking) the
    differences a gap touches would mix their high-frequency power (white noise's second differences rise as
    f^4) into the low bins. An interpolated sample follows its neighbours: with a share q of single samples
    interpolated, white noise's power at angular frequency w (per sample) becomes ``1 - q/2 + 2 q cos w`` of
    itself (to first order in q), about ``1 - 2 q`` over the top of the band where the floor is read (2 % for
    1 % of the frames dropped, 20 % for 10 %); the motion, far below, is the same.
    """
    ok = np.isfinite(y)
    out = []
    for a, b in gap_stretches(np.arange(y.size), ok, max_gap):
        if b + 1 - a < min_len:
            continue
        seg, m = y[a:b + 1], ok[a:b + 1]
        if not m.all():
            i = np.arange(seg.size)
            seg = np.interp(i, i[m], seg[m])
        out.append(seg)
    return out


def displacement_spectrum(y, dt: float, segment_s: float = SEGMENT_S) -> tuple[np.ndarray, np.ndarray, float]:
    """One-sided power spectral density of a signal, estimated through its second differences.

    Parameters
    ----------
    y : array_like (n,) or sequence of them
        Signal samples (NaN marks gaps: each finite stretch is used on its own, continued across runs of at
        most :data:`BRIDGED_GAP` missing samples, which are interpolated: :func:`_bridged_stretches`).
    dt : float
        Sample spacing [s].
    segment_s : float
        Welch segment length [s].

    Returns
    -------
    freqs : ndarray (k,)
        [Hz], from 0 to Nyquist.
    psd : ndarray (k,)
        [unit^2 / Hz]; NaN at 0 Hz.
    n_avg : float
        Number of (half-overlapping) segments averaged; a bin's relative standard deviation is about
        ``1 / sqrt(n_avg)``.

    Notes
    -----
    The second difference ``D y_i = y_{i+1} - 2 y_i + y_{i-1}`` has the response
    ``-4 sin^2(pi f dt)``, nearly flat in power against the ``f^-4`` fall of a smooth motion's
    spectrum; Welch's estimate (Hann windows, half overlap, linear detrending) of it is divided by
    ``16 sin^4(pi f dt)``. Estimating the signal itself would let the side lobes of its huge
    low-frequency power (a ride's travel, a slow lean) swamp the high frequencies that decide the
    filter. Segments are averaged over the stretches at least a segment long (over every stretch, on the
    finest grid, when none is), weighted by their counts.
    """
    # a sequence first: np.ndim of recordings of different lengths is an error, not a ragged 1
    if isinstance(y, (list, tuple)) or np.ndim(y) != 1:
        arrays = [np.asarray(a, dtype=float) for a in y]
    else:
        arrays = [np.asarray(y, dtype=float)]
    nper = max(16, int(round(segment_s / dt)))
    parts = []
    for arr in arrays:
        for seg in _bridged_stretches(arr, 8):
            d2 = seg[2:] - 2 * seg[1:-1] + seg[:-2]
            n = min(nper, d2.size)
            f, p = welch_linear(d2, 1.0 / dt, n)
            parts.append((f, p, max(1.0, 2.0 * d2.size / n - 1.0), n == nper))   # segments averaged (half overlap)
    if not parts:
        raise InputError("no finite stretch of at least 8 samples to estimate a spectrum from", key="y")
    # a stretch shorter than a segment (between dropped frames) resolves only 1 / its length: its low bins are
    # the strong slow motion's leakage, which the division by sin^4 turns into motion up to several Hz. As in
    # Welch's method, such stretches are left out when there are whole segments; when every stretch is short
    # they are all used, on the finest grid (the longest stretch's), whichever stretch comes first
    if any(whole for *_, whole in parts):
        parts = [q for q in parts if q[3]]
    freqs = max((f for f, *_ in parts), key=lambda f: f.size)
    total, weight = None, 0.0
    for f, p, k, _ in parts:
        if f is not freqs and (f.size != freqs.size or not np.array_equal(f, freqs)):
            p = np.interp(freqs, f, p)
        total = p * k if total is None else total + p * k
        weight += k
    psd = total / weight
    with np.errstate(divide="ignore", invalid="ignore"):
        out = psd / (16.0 * np.sin(np.pi * freqs * dt) ** 4)
    out[0] = np.nan
    return freqs, out, weight


@dataclass(frozen=True)
class WindowChoice:
    """The chosen filter and what it leaves.

    Parameters
    ----------
    window_s : float
        Window [s] (``window / rate``; pass it as ``--window-s``).
    window : int
        Window [samples], odd.
    polyorder : int
        Polynomial order.
    distortion : dict
        Per signal: the predicted relative RMS error of the filtered value, first and second
        derivative from the filter's response alone (``{"gamma": (d0, d1, d2), ...}``), each
        relative to the RMS of that derivative of the signal.
    noise : dict
        Per signal: the predicted RMS of the noise in the second derivative, relative to the RMS
        second derivative of the signal.
    noise_std : dict
        Per signal: the white-noise standard deviation used [signal unit].
    acceleration_rms : dict
        Per signal: the RMS of the signal's second derivative the spectrum implies [unit/s^2].
    band_hz : dict
        Per signal: frequencies below which 90 % and 99 % of the second derivative's power lie [Hz],
        and the end of the band resolved above the noise floor.
    probe : tuple
        ``(window_s, polyorder)`` of a companion filter whose predicted distortion is about twice
        the chosen one's (see :func:`choose_window`, Notes).
    probe_ratio : float
        The probe's predicted RMS distortion of the accelerations over the chosen filter's (about
        2; NaN when the chosen filter predicts none).
    noise_model : {"white", "coloured"}
        How the noise was modelled (:func:`choose_window`, Notes).
    near_optimal : list of tuple
        ``(window_s, polyorder)`` of every candidate whose score lies within :data:`NEAR_OPTIMAL_SIGMAS`
        standard deviations of its own noise of the chosen one's, shortest window first (:func:`choose_window`,
        Notes): filters the recording cannot tell apart.
    candidates : list of dict
        Every candidate evaluated, with its total score, the standard deviation of its score's difference from
        the chosen one's (``score_sd``) and whether it is near-optimal.
    """

    window_s: float
    window: int
    polyorder: int
    distortion: dict
    noise: dict
    noise_std: dict
    acceleration_rms: dict
    band_hz: dict
    probe: tuple
    probe_ratio: float = float("nan")
    noise_model: str = "white"
    near_optimal: list = field(repr=False, default_factory=list)
    candidates: list = field(repr=False, default_factory=list)

    def to_json(self) -> dict:
        """The plain-JSON form (``near_optimal`` and ``candidates`` left out).

        Returns
        -------
        dict
            The fields as JSON values (tuples as lists; a ``probe_ratio`` that is not finite as None).
        """
        return {"window_s": self.window_s, "window": self.window, "polyorder": self.polyorder,
                "distortion": {k: list(v) for k, v in self.distortion.items()}, "noise": dict(self.noise),
                "noise_std": dict(self.noise_std), "acceleration_rms": dict(self.acceleration_rms),
                "band_hz": {k: list(v) for k, v in self.band_hz.items()}, "probe": list(self.probe),
                "probe_ratio": self.probe_ratio if np.isfinite(self.probe_ratio) else None,
                "noise_model": self.noise_model}


#: Largest RMS distortion of an acceleration a choice with the white noise floor may predict: beyond it the
#: noise is taken as coloured (:func:`choose_window`, Notes).
MAX_WHITE_DISTORTION = 0.3
#: Width of the band above the cutoff whose median spectrum is the noise level below it [Hz].
NOISE_LEVEL_HZ = 1.0
#: Bands per octave over which :func:`_noise_rise_start` averages the acceleration spectrum.
RISE_BANDS_PER_OCTAVE = 4


def _noise_rise_start(f: np.ndarray, S: np.ndarray, n_avg: float, f_min: float) -> float:
    """Where the noise takes over the spectrum from below.

    The start of the final stretch over which the acceleration spectrum ``(2 pi f)^4 S(f)`` only rises (within
    its estimate's scatter) [Hz].

    A motion's acceleration spectrum falls off above its band; pose noise, white or coloured (a first
    order low-pass: flat, then ``f^-2``), gives an acceleration spectrum rising as ``f^4`` or ``f^2``
    up to Nyquist. The spectrum is averaged over fractional-octave bands (:data:`RISE_BANDS_PER_OCTAVE`;
    a band of ``m`` bins scatters by about ``1 / sqrt(n_avg m)``); the motion ends where the final rise
    begins: every band from there on lies within that scatter (:data:`FLOOR_SIGMAS` of it) of the
    smallest band at or above it. A motion peak at a high frequency (a fast balance loop) stays inside
    the band, since the rise that counts is the last one.
    """
    ok = np.isfinite(S) & (f >= f_min) & (f > 0)
    if ok.sum() < 4:
        return float(f[-1])
    A = (2 * np.pi * f) ** 4 * np.where(ok, S, 0.0)
    edges = f_min * 2.0 ** (np.arange(0, 64) / RISE_BANDS_PER_OCTAVE)
    edges = edges[edges <= f[-1] * (1 + 1e-9)]
    if edges.size < 3:
        return float(f[-1])
    idx = np.digitize(f, edges) - 1                      # band of every bin (-1 below f_min)
    nb = edges.size - 1
    use = ok & (idx >= 0) & (idx < nb)
    count = np.bincount(idx[use], minlength=nb).astype(float)
    total = np.bincount(idx[use], weights=A[use], minlength=nb)
    keep = count > 0
    band_lo = edges[:-1][keep]
    mean = total[keep] / count[keep]
    run_min = np.minimum.accumulate(mean[::-1])[::-1]
    tol = 1.0 + FLOOR_SIGMAS / np.sqrt(np.maximum(n_avg * count[keep], 1.0))
    rising = mean <= tol * run_min
    off = np.flatnonzero(~rising)
    return float(band_lo[off[-1] + 1]) if off.size and off[-1] + 1 < band_lo.size else \
        (float(f[-1]) if off.size else float(band_lo[0]))


def _candidate_windows(dt: float, orders: Sequence[int], max_window_s: float) -> list[tuple[int, int]]:
    longest = max(int(round(max_window_s / dt)) | 1, 5)
    out = []
    for p in orders:
        shortest = p + 3 if (p + 3) % 2 == 1 else p + 4
        grid = np.unique(np.round(np.geomspace(shortest, max(longest, shortest), 48)).astype(int) | 1)
        out += [(int(w), int(p)) for w in grid if w > p]
    return out


class _Spectra(NamedTuple):
    """The signals' displacement spectra on one grid, with their noise floors (:func:`_spectra_and_floors`)."""

    names: list            # signal names, in the order given
    f: np.ndarray          # the common frequency grid [Hz]
    S: dict                # per signal: displacement spectrum on ``f``
    floors: dict           # per signal: white noise floor N_s
    sigma: dict            # per signal: white-noise standard deviation used
    n_avg: dict            # per signal: number of Welch segments averaged
    estimated: dict        # per signal: whether the floor was read from the spectrum (not given)


def _spectra_and_floors(dt: float, signals: Mapping[str, object], noise_std: dict, segment_s: float) -> _Spectra:
    """Every signal's spectrum on one frequency grid and its white noise floor (:func:`choose_window`, Notes)."""
    specs, floors, sig_used, n_avg, estimated = {}, {}, {}, {}, {}
    spectra = {}
    for name, y in signals.items():
        spectra[name] = displacement_spectrum(y, dt, segment_s)
    # one frequency grid for every signal: a signal whose stretches are all shorter than a segment has a
    # coarser one (a short recording with gaps), so its spectrum is interpolated onto the finest
    grid = max((sp[0] for sp in spectra.values()), key=lambda f: f.size)
    for name, (f, S, n) in spectra.items():
        if f.size != grid.size:
            S = np.interp(grid, f[1:], S[1:])
            S[0] = np.nan                               # 0 Hz, as displacement_spectrum gives it
            spectra[name] = (grid, S, n)
    for name in signals:
        f, S, n_avg[name] = spectra.pop(name)
        top = (f >= NOISE_BAND[0] * f[-1]) & (f <= NOISE_BAND[1] * f[-1])
        estimated[name] = not (name in noise_std and noise_std[name] is not None)
        if not estimated[name]:
            sigma = float(noise_std[name])
            N = 2.0 * sigma**2 * dt
        else:
            N = float(np.nanmedian(S[top]))
            sigma = float(np.sqrt(N / (2.0 * dt)))
        specs[name] = (f, S)
        floors[name] = N
        sig_used[name] = sigma
    names = list(signals)
    return _Spectra(names=names, f=specs[names[0]][0], S={n: specs[n][1] for n in names}, floors=floors,
                    sigma=sig_used, n_avg=n_avg, estimated=estimated)


def _motion_spectra(sp: _Spectra, segment_s: float, coloured: bool):
    """Each signal's motion spectrum, its band's end, (``coloured``) its noise spectrum and the level under both.

    ``coloured`` False: above the white floor; True: above the noise measured above the motion's band, which
    may be coloured. Returns ``(S_sig, cutoff, S_noise, level)`` (``S_noise`` empty when not ``coloured``;
    ``level[n]`` is ``(value, bins its median was read from, or 0 for the white floor)``).
    """
    f = sp.f
    S_sig, cutoff, S_noise, levels = {}, {}, {}, {}
    for n in sp.names:
        S = np.where(np.isfinite(sp.S[n]), sp.S[n], np.inf)
        above = S > sp.floors[n] * (1.0 + FLOOR_SIGMAS / np.sqrt(sp.n_avg[n]))
        # the motion's band: from 0 Hz up to the first bin (past the lowest ones) under the threshold
        below = np.flatnonzero(~above & (f > 2.0 / segment_s))
        cutoff[n] = float(f[below[0]]) if below.size else float(f[-1])
        level, bins = sp.floors[n], 0
        if coloured:
            # no further than where the noise's rising acceleration spectrum takes over; the noise as
            # measured above that, and below it as flat as just above it
            cutoff[n] = min(cutoff[n], _noise_rise_start(f, sp.S[n], sp.n_avg[n], 2.0 / segment_s))
            near = (f >= cutoff[n]) & (f <= cutoff[n] + NOISE_LEVEL_HZ)
            measured = float(np.nanmedian(sp.S[n][near]))
            if measured > level:
                level, bins = measured, int(np.count_nonzero(near & np.isfinite(sp.S[n])))
            S_noise[n] = np.where(f >= cutoff[n], sp.S[n], level)
            S_noise[n][0] = 0.0
        levels[n] = (level, bins)
        S_sig[n] = np.where((f < cutoff[n]) & (f > 0), np.maximum(sp.S[n] - level, 0.0), 0.0)
    return S_sig, cutoff, S_noise, levels


class _Responses(NamedTuple):
    """Every candidate's second-derivative response on the spectra's grid (:func:`_responses`)."""

    windows: np.ndarray    # (C,) window [samples]
    orders: np.ndarray     # (C,) polynomial order
    e2: np.ndarray         # (C, F) |H_2 / (2 pi i f)^2 - 1|^2 (0 at 0 Hz)
    h2: np.ndarray | None  # (C, F) |H_2|^2 (coloured noise only)
    k2: np.ndarray         # (C,) sum of the squared second-derivative weights [1/s^4]


def _responses(dt: float, f: np.ndarray, orders: Sequence[int], max_window_s: float, coloured: bool) -> _Responses:
    """The candidates' responses (:func:`choose_window`, Notes), one row per candidate."""
    cands = _candidate_windows(dt, orders, max_window_s)
    w2 = (2 * np.pi * f) ** 2
    e2, h2, k2 = [], [], []
    n = _dft_length(f, dt)                     # the same grid for every candidate
    for W, p in cands:
        k = _savgol_kernel(int(W), int(p), 2, float(dt))
        H2 = _response(k, dt, f, n)
        with np.errstate(divide="ignore", invalid="ignore"):
            e2.append(np.where(f > 0, np.abs(H2 / (-(w2)) - 1.0) ** 2, 0.0))
        if coloured:
            h2.append(np.abs(H2) ** 2)
        k2.append(float(k @ k))
    return _Responses(np.array([c[0] for c in cands]), np.array([c[1] for c in cands]), np.array(e2),
                      np.array(h2) if coloured else None, np.array(k2))


def _welch_correlations(nper: int) -> tuple[float, float, float]:
    """``(rho, c_1, c_2)`` of the periodic Hann window: half-overlap and neighbouring-bin correlations.

    For a locally white spectrum a windowed periodogram's bins ``j`` apart correlate by
    ``c_j = |sum_n w_n^2 exp(-2 pi i j n / N)|^2 / (sum_n w_n^2)^2`` (4/9 and 1/36 for Hann), and the same bin
    of two segments overlapping by half by ``rho = (sum_n w_n w_{n + N/2})^2 / (sum_n w_n^2)^2`` (1/9).
    """
    n = max(int(nper), 4)
    w = 0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(n) / n)
    e = float(w @ w)
    rho = float(w[: n - n // 2] @ w[n // 2:]) ** 2 / e**2
    W2 = np.fft.fft(w**2)
    return rho, float(abs(W2[1]) ** 2 / e**2), float(abs(W2[2]) ** 2 / e**2)


def _evaluate(sp: _Spectra, dt: float, orders: Sequence[int], max_window_s: float, segment_s: float,
              noise_power: int, coloured: bool, ref: int | None = None):
    """The candidates scored with the white noise floor or with the noise as measured above the motion's band.

    ``coloured`` False: the white floor; True: the noise measured above the motion's band, which may be
    coloured. Returns ``(cands, best, S_sig, A, P, cutoff, worst)``; ``cands[i]["score_sd"]`` is the standard
    deviation of its score's difference from the smallest (:func:`_difference_variance`), ``["near_optimal"]``
    whether that difference is within :data:`NEAR_OPTIMAL_SIGMAS` of it (``ref``: the standard deviation
    of the difference from candidate ``ref`` instead).
    """
    names, f = sp.names, sp.f
    df = f[1] - f[0]
    w4 = (2 * np.pi * f) ** 4
    S_sig, cutoff, S_noise, levels = _motion_spectra(sp, segment_s, coloured)
    A = {n: w4 * S_sig[n] for n in names}
    P = {n: float(np.sum(A[n]) * df) for n in names}
    if any(v <= 0 for v in P.values()):
        empty = [n for n, v in P.items() if v <= 0]
        raise InputError(f"no motion above the noise floor in {', '.join(empty)}", key="signals")
    r = _responses(dt, f, orders, max_window_s, coloured)
    score = np.zeros(r.k2.size)
    B, V, terms = {}, {}, {}
    for n in names:
        B[n] = r.e2 @ A[n] * df
        V[n] = sp.sigma[n] ** 2 * r.k2
        # the coloured excess over the white noise: SIMEX does not remove its bias, so it counts whole
        X = np.maximum(r.h2 @ S_noise[n] * df - V[n], 0.0) if coloured else np.zeros_like(V[n])
        score += B[n] / P[n] + (V[n] / P[n]) ** noise_power + X / P[n]
        terms[n] = (B[n], V[n], X)
        V[n] = V[n] + X
    i_min = int(np.lexsort((r.windows, score))[0])
    sd = np.sqrt(sum(_difference_variance(sp, n, r, P[n], terms[n], levels[n], cutoff[n], S_noise.get(n),
                                          noise_power, i_min if ref is None else ref, segment_s, dt)
                     for n in names))
    near = score - score[i_min] <= NEAR_OPTIMAL_SIGMAS * sd
    cands = [{"window": int(r.windows[c]), "polyorder": int(r.orders[c]), "score": float(score[c]),
              "score_sd": float(sd[c]), "near_optimal": bool(near[c]), "B2": {n: float(B[n][c]) for n in names},
              "V": {n: float(V[n][c]) for n in names}} for c in range(score.size)]
    best = cands[i_min]
    worst = max(np.sqrt(cands[i_min]["B2"][n] / P[n]) for n in names)
    return cands, best, S_sig, A, P, cutoff, worst


def _difference_variance(sp: _Spectra, n: str, r: _Responses, P: float, terms: tuple, level: tuple, cutoff: float,
                         S_noise, noise_power: int, ref: int, segment_s: float, dt: float) -> np.ndarray:
    """Variance of every candidate's score less candidate ``ref``'s, from signal ``n``'s spectrum.

    Notes
    -----
    Each bin of a Welch average of ``K`` segments is a scaled chi-square variate,
    ``var S(f) = S(f)^2 / K_eff`` with ``K_eff = K / (1 + 2 rho (K - 1) / K)`` (``rho`` = 1/9 for
    half-overlapping Hann segments), and bins ``j`` apart correlate by ``c_j`` (4/9 and 1/36 for ``j`` = 1, 2;
    :func:`_welch_correlations`). The score is a ratio of sums linear in ``S``, so to first order (delta
    method) the difference ``D_c`` of candidate ``c``'s score from ``ref``'s has the variance
    ``sum_{f, f'} g_c(f) g_c(f') cov(S(f), S(f'))``, with ``g_c = d D_c / d S(f)`` written out below
    (through the motion's ``A``, its power ``P``, the noise spectrum above the band when coloured); the
    levels read as medians of ``m`` bins add theirs (``pi / 2`` of the variance of the bins' mean, the
    ``m`` bins ``m / (1 + 2 c_1 + 2 c_2)`` independent). The band's end and the noise's rise are thresholds,
    held fixed. Summed over the signals (independent spectra) this is ``score_sd^2``
    (``test_auto_window`` checks it against the scatter over noise draws).
    """
    f, S = sp.f, np.where(np.isfinite(sp.S[n]), sp.S[n], 0.0)
    df = f[1] - f[0]
    w4 = (2 * np.pi * f) ** 4
    B, V, X = terms
    k = noise_power
    band = (f > 0) & (f < cutoff) & (S > level[0])
    # d score / d A(f) on the motion's band, and d score / d S_noise(f) (coloured)
    gA = df * (r.e2 / P - ((B + X) / P**2 + k * (V / P) ** k / P)[:, None]) * band
    gN = (df / P) * r.h2 * (X > 0)[:, None] if S_noise is not None else np.zeros_like(gA)
    G = gA * w4 + gN * (f >= cutoff)                    # d score / d S(f)
    dL = -(gA @ w4)                                     # the level under the motion
    if S_noise is not None:
        dL += gN @ ((f > 0) & (f < cutoff))             # the noise below the band, as flat as the level
    dF = np.zeros_like(dL)                              # the white floor through sigma (when estimated)
    if not level[1]:
        dL += k * (V / P) ** k / level[0] - (X > 0) * V / (P * level[0])
    else:
        dF = k * (V / P) ** k / sp.floors[n] - (X > 0) * V / (P * sp.floors[n])
    rho, c1, c2 = _welch_correlations(int(round(segment_s / dt)))
    K = sp.n_avg[n] / (1.0 + 2.0 * rho * max(sp.n_avg[n] - 1.0, 0.0) / sp.n_avg[n])
    v = (G - G[ref]) * S
    var = (np.einsum("cf,cf->c", v, v) + 2 * c1 * np.einsum("cf,cf->c", v[:, 1:], v[:, :-1])
           + 2 * c2 * np.einsum("cf,cf->c", v[:, 2:], v[:, :-2])) / K
    # a median of m bins (m / (1 + 2 c_1 + 2 c_2) independent) scatters by sqrt(pi / 2) of their mean's
    spread = np.pi / 2 * (1 + 2 * c1 + 2 * c2) / K
    top = int(np.count_nonzero((f >= NOISE_BAND[0] * f[-1]) & (f <= NOISE_BAND[1] * f[-1])))
    var_floor = 0.0 if not sp.estimated[n] else sp.floors[n] ** 2 * spread / max(top, 1)
    var_level = level[0] ** 2 * spread / level[1] if level[1] else var_floor
    return var + (dL - dL[ref]) ** 2 * var_level + (dF - dF[ref]) ** 2 * var_floor


#: The score's noise a candidate may lie within of the smallest score to count as near-optimal [standard
#: deviations of the difference] (:func:`choose_window`, Notes).
NEAR_OPTIMAL_SIGMAS = 1.0


def _listing(cands: list, dt: float) -> dict:
    """``near_optimal`` and ``candidates`` of a :class:`WindowChoice`."""
    return {"near_optimal": sorted((c["window"] * dt, c["polyorder"]) for c in cands if c["near_optimal"]),
            "candidates": [{k: c[k] for k in ("window", "polyorder", "score", "score_sd", "near_optimal")}
                           for c in cands]}


def _diagnostics(sp: _Spectra, dt: float, best: dict, S_sig: dict, A: dict, P: dict, cutoff: dict):
    """What the chosen filter leaves, per signal: ``(distortion, noise, acceleration_rms, band_hz)``."""
    f = sp.f
    W, p = best["window"], best["polyorder"]
    distortion, noise, acc_rms, band = {}, {}, {}, {}
    for n in sp.names:
        rel = []
        for d in (0, 1, 2):
            H = savgol_response(W, p, d, dt, f)
            ideal = (2j * np.pi * f) ** d
            with np.errstate(divide="ignore", invalid="ignore"):
                e = np.where(f > 0, np.abs(H / ideal - 1.0) ** 2, 0.0)
            weight = (2 * np.pi * f) ** (2 * d) * S_sig[n]
            rel.append(float(np.sqrt(np.sum(e * weight) / np.sum(weight))) if np.sum(weight) > 0 else 0.0)
        distortion[n] = tuple(rel)
        noise[n] = float(np.sqrt(best["V"][n] / P[n]))
        acc_rms[n] = float(np.sqrt(P[n]))
        cum = np.cumsum(A[n]) / np.sum(A[n])
        band[n] = (float(f[np.searchsorted(cum, 0.90)]), float(f[np.searchsorted(cum, 0.99)]), cutoff[n])
    return distortion, noise, acc_rms, band


def _probe(cands: list, best: dict, P: dict, names: list, dt: float) -> tuple[tuple, float]:
    """Companion filter: the same order, the window whose summed distortion is nearest twice the choice's.

    Returns ``((window_s, polyorder), ratio)``.
    """
    W, p = best["window"], best["polyorder"]

    def rms_distortion(c):
        return sum(c["B2"][n] / P[n] for n in names) ** 0.5

    target = 2.0 * rms_distortion(best)
    same = [c for c in cands if c["polyorder"] == p and c["window"] > W]
    probe, ratio = (W * dt, p), float("nan")
    if same:
        c = min(same, key=lambda c: abs(rms_distortion(c) - target))
        probe = (c["window"] * dt, p)
        ratio = rms_distortion(c) / target * 2.0 if target > 0 else float("nan")
    return probe, ratio


def choose_window(dt: float, signals: Mapping[str, object], noise_std: Mapping[str, float] | None = None, *,
                  orders: Sequence[int] = DEFAULT_ORDERS, max_window_s: float = MAX_WINDOW_S,
                  segment_s: float = SEGMENT_S, noise_power: int = 1, coloured: bool = False) -> WindowChoice:
    r"""Choose the Savitzky-Golay window and order from a recording's raw signals.

    Parameters
    ----------
    dt : float
        Sample spacing [s].
    signals : mapping of str to array_like
        Raw (unfiltered) signals sampled every ``dt``, e.g. ``{"gamma": ..., "phi": ..., "C_x": ...,
        "C_y": ...}``; each an array (NaN at gaps) or a sequence of arrays (several recordings).
    noise_std : mapping of str to float, optional
        White-noise standard deviation of each signal [its unit], e.g. propagated from the stated
        pose noise. Missing signals get an estimate from the top of their spectrum (see Notes).
    orders : sequence of int
        Candidate polynomial orders.
    max_window_s : float
        Longest candidate window [s].
    segment_s : float
        Welch segment length [s].
    noise_power : {1, 2}
        The power of the relative noise variance in the score: 1 for the mean-square error of the
        accelerations, 2 when the noise's first-order bias of the estimate is removed afterwards
        (see Notes).
    coloured : bool
        The noise is known to be coloured (e.g. the rigid links between bodies show it): model it so
        from the start (see Notes).

    Returns
    -------
    WindowChoice

    Notes
    -----
    For each signal ``s`` the displacement spectrum ``S_s(f)`` (:func:`displacement_spectrum`) is the
    motion's spectrum plus a white noise floor ``N_s = 2 sigma_s^2 dt`` (one-sided). When
    ``sigma_s`` is not given, ``N_s`` is the median of ``S_s`` over the top of the band
    (:data:`NOISE_BAND` of Nyquist), where a smooth motion has no power left; that is an upper bound
    when the motion reaches up there. The motion's band ends at ``f_c``, the first frequency where
    ``S_s`` is within :data:`FLOOR_SIGMAS` standard deviations of the floor (what lies above is
    buried in the noise and cannot be resolved by any filter); the motion's acceleration spectrum is
    ``A_s(f) = (2 pi f)^4 (S_s(f) - N_s)`` below ``f_c``, its power ``P_s = int A_s df``. A candidate
    ``(W, p)`` with second-derivative response ``H_2(f)`` then leaves

    .. math::

        B_s^2 = \int |H_2(f) / (2\pi i f)^2 - 1|^2 A_s(f)\, df, \qquad
        V_s = \sigma_s^2 \sum_j w_{2,j}^2,

    the distortion and the noise variance of the filtered acceleration. The choice minimizes the
    summed relative mean-square error ``sum_s (B_s^2 + V_s) / P_s``: with noise-free poses this is
    the shortest window that resolves the motion, with noisy poses the balance of both. With
    ``noise_power=2`` the score is ``sum_s B_s^2 / P_s + (V_s / P_s)^2``: an estimate whose noise
    bias is removed by simulation-extrapolation (SIMEX, linear in the noise variance) keeps of the
    noise only the part of second order in ``V_s / P_s`` (the curvature of the bias in the
    variance), while the distortion stays whole; the noise then counts less and the window is
    shorter. The
    distortion the choice leaves is returned per signal and derivative order; as it is a bias of
    the filter, not noise, it does not average out. Since ``B`` grows steeply with the window, a
    companion filter with about twice the predicted distortion (``probe``) gives a model-free
    estimate of what the distortion does to any quantity ``h`` fitted from the filtered signals:
    to first order ``h(W) - h_true ~ h(W_probe) - h(W)``.

    Coloured pose noise (soft tissue, a tracker's own smoothing) has most of its power below the top
    of the band, where the white floor is read, so that floor lies far below it and the "motion" left
    above it is largely noise; the choice then follows it with a short window whose predicted
    distortion of what it keeps is large. When the chosen filter predicts an RMS distortion above
    :data:`MAX_WHITE_DISTORTION` for any signal, or when the caller knows it (``coloured``), the noise
    is taken as coloured: the motion's band ends
    where the acceleration spectrum's final rise begins (:func:`_noise_rise_start`; noise, white or
    coloured, gives an acceleration spectrum rising to Nyquist), the noise is the measured spectrum
    above that and flat below, and its part beyond the white floor counts whole in the score (SIMEX,
    which adds white noise, does not remove its bias). ``noise_model`` says which was used.

    Candidates within the score's noise of the choice (:func:`_difference_variance`) are ``near_optimal``.
    """
    if not (np.isfinite(dt) and dt > 0):
        raise InputError(f"sample spacing must be > 0 s, got {dt!r}", key="dt")
    if not signals:
        raise InputError("no signals given", key="signals")
    sp = _spectra_and_floors(dt, signals, dict(noise_std or {}), segment_s)
    cands, best, S_sig, A, P, cutoff, worst = (None,) * 6 + (np.inf,) if coloured else \
        _evaluate(sp, dt, orders, max_window_s, segment_s, noise_power, False)
    noise_model = "white"
    if worst > MAX_WHITE_DISTORTION:
        # a white floor read at the top of the band is far below coloured noise: the "motion" it leaves
        # is mostly noise, which the choice then follows with a filter that distorts what it keeps
        cands, best, S_sig, A, P, cutoff, worst = _evaluate(sp, dt, orders, max_window_s, segment_s, noise_power,
                                                            True)
        noise_model = "coloured"
    W, p = best["window"], best["polyorder"]
    distortion, noise, acc_rms, band = _diagnostics(sp, dt, best, S_sig, A, P, cutoff)
    probe, ratio = _probe(cands, best, P, sp.names, dt)
    return WindowChoice(window_s=W * dt, window=W, polyorder=p, distortion=distortion, noise=noise,
                        noise_model=noise_model, noise_std=sp.sigma, acceleration_rms=acc_rms, band_hz=band,
                        probe=probe, probe_ratio=ratio, **_listing(cands, dt))
