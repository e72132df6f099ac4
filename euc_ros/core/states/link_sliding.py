"""Soft-tissue sliding measured from the rigid links between a rider's bodies.

A link's vector ``R_a^T (p_b - p_a)`` is constant for rigid bones, and its deviation from the
session's median is the two bodies' sliding plus their pose noise. Per link, the variance of the
deviation minus its white part (third differences) is ``q_a + q_b``: the sliding variances of its two
bodies (rotation sliding folded into the pivot's, E taken as not sliding). Non-negative least squares
over the links gives every body's ``q``, and the links' mean power spectrum gives the sliding's colour.
Noise that is not white (a tracker's smoothing, soft tissue) shows here the same way: it is the
filter choice's evidence of coloured noise (:func:`~euc_ros.core.states.filter_choice.choose_filter`)
and the sliding whose bias of h identify measures (:mod:`euc_ros.core.identify.sliding`).
"""
from __future__ import annotations

import dataclasses

import numpy as np
from scipy.optimize import nnls

from euc_ros.core.errors import ConfigError
from euc_ros.core.robust import median
from euc_ros.core.rotations import rotation_matrices
from euc_ros.core.states.skeleton import DEFAULT_LINKS, SkeletonFitConfig

#: Below this RMS sliding [m] the bias is not computed (0): white noise and round-off.
MIN_SLIDING_M = 5e-4


def estimate_sliding(series_list, session, skeleton=None, usable: list | None = None) -> dict:
    """Per-body RMS sliding (3-D) [m] and its normalised power spectrum, measured from the links.

    Parameters
    ----------
    series_list : sequence of MocapSeries
        Recordings of one session (Z-up).
    session : Session
    skeleton : SkeletonModel, optional
        The session's chain (default: estimated from ``series_list``).
    usable : list of ndarray, optional
        Per recording, :func:`usable_poses` (default: made here).

    Returns
    -------
    dict
        ``bodies`` (rider bodies), ``rms_m`` (per body), ``rms_max_m``, ``spectrum`` (frequencies [Hz],
        power normalised to sum 1) for :func:`sliding_bias`.
    """
    names, euc_body, links = _chain_links(session, skeleton)
    config = SkeletonFitConfig()
    chain = names + [euc_body]
    m = len(names)
    rows, vals = [], []
    spec_f, spec_p = None, None
    usable = [usable_poses(s) for s in series_list] if usable is None else list(usable)
    seen = 0
    freqs: dict[int, np.ndarray] = {}                   # per recording, its spectrum's frequencies
    for a, b, vector, threshold in links:
        # one link at a time: its deviation over every recording (no other link's arrays exist meanwhile)
        devs = [link_deviation(s, a, b, np.zeros(3) if vector is None else vector, usable=ok)
                for s, ok in zip(series_list, usable)]
        if vector is None:
            fit = _fit_link(devs, config)
            if fit is None:
                continue                                # links never seen together are left out
            threshold, dist = fit
        else:
            dist = [None] * len(devs)
        seen += 1
        ia, ib = chain.index(a), chain.index(b)
        for s, (d, both), near in zip(series_list, devs, dist):
            n = s.n_frames
            if n < 16:
                continue
            if near is None:
                good = both & (np.linalg.norm(d, axis=1) <= threshold)
            else:
                good = both.copy()
                good[both] = near <= threshold
            if good.sum() < 16:
                continue
            centre, total, white = _deviation_variances(d, good)
            row = np.zeros(m)
            for i in (ia, ib):
                if i < m:
                    row[i] = 1.0
            rows.append(row)
            vals.append(max(total - white, 0.0))
            p = _deviation_power(d, good, centre)
            f = freqs.get(id(s))
            if f is None:
                f = freqs[id(s)] = np.fft.rfftfreq(n, 1.0 / s.rate_hz)
            if spec_f is None or f.size > spec_f.size:
                # keep the longest recording's grid; others are interpolated onto it
                spec_p = None if spec_p is None else np.interp(f, spec_f, spec_p)
                spec_f = f
            if f is not spec_f:                         # on its own grid a spectrum is already there
                p = np.interp(spec_f, f, p)
            spec_p = p if spec_p is None else spec_p + p
        del devs
    if skeleton is None and not seen:
        raise ConfigError("no chain link has a frame with both of its bodies tracked", key="cog_method")
    if not rows:
        return {"bodies": list(names), "rms_m": [0.0] * m, "rms_max_m": 0.0, "spectrum": None}
    q, _ = nnls(np.array(rows), np.array(vals))
    spectrum = None
    if spec_p is not None and spec_p.sum() > 0:
        spectrum = (spec_f, spec_p / spec_p.sum())
    rms = np.sqrt(q)
    return {"bodies": list(names), "rms_m": [float(v) for v in rms], "rms_max_m": float(rms.max()),
            "spectrum": spectrum}


def _chain_links(session, skeleton) -> tuple[list, str, list]:
    """The rider's bodies, E's body and the chain's links ``(a, b, vector, threshold)`` for :func:`estimate_sliding`.

    From ``skeleton`` when given; else the chain's links as SkeletonModel.estimate defines them, with the vector
    and threshold None (made by :func:`_fit_link`).
    """
    if skeleton is not None:
        names, euc_body = list(skeleton.bodies), skeleton.euc_body
        links = [(a, b, v, t) for (a, b), v, t in zip(skeleton.links, skeleton.vectors, skeleton.threshold_m)]
    else:
        # the chain's links as SkeletonModel.estimate defines them (vector: the median of R_a^T (p_b - p_a)
        # over every recording's usable frames; threshold: median + fault_sigmas robust standard deviations of
        # the distance to it, at least fault_floor_m), made here link by link from the same deviations the
        # sliding is measured on, without the chain's relative rotations (the sliding does not use them)
        names_, _, _ = session.segment_arrays()
        names, euc_body = list(names_), session.euc.body
        known = set(names) | {euc_body}
        links = [(a, b, None, None) for a, b in DEFAULT_LINKS if a in known and b in known and a != b]
        if not links:
            raise ConfigError("no chain link between the session's bodies", key="cog_method")
    return names, euc_body, links


def _fit_link(devs: list, config: SkeletonFitConfig):
    """A link's vector and fault threshold from its deviations (taken off them in place).

    ``devs``: per recording, ``(deviation from a zero vector, both bodies usable)``. Returns
    ``(threshold, dist)`` (``dist``: per recording, the distances to the vector over the frames where both
    bodies are usable), or None when the link is never seen with both.
    """
    seen_both = [d[both] for d, both in devs]       # each recording's frames where both are usable
    v = seen_both[0] if len(seen_both) == 1 else np.concatenate(seen_both)
    if v.shape[0] == 0:
        return None
    vector = median(np.ascontiguousarray(v.T), axis=1)       # per component, over contiguous memory
    del v
    for d, _ in devs:
        d -= vector                                 # in place: no second copy of the deviations
    # the distances to the vector over the frames where both bodies are usable, kept per recording
    # (numpy's norm over the three components, written out: the same sums in the same order)
    dist = []
    for sb in seen_both:
        sb -= vector
        dist.append(np.sqrt((sb[:, 0] * sb[:, 0] + sb[:, 1] * sb[:, 1]) + sb[:, 2] * sb[:, 2]))
    del seen_both
    e = np.concatenate(dist)
    med = float(median(e))
    mad = float(median(np.abs(e - med)))
    threshold = max(config.fault_floor_m, med + config.fault_sigmas * 1.4826 * mad)
    return threshold, dist


def _deviation_variances(d: np.ndarray, good: np.ndarray) -> tuple[np.ndarray, float, float]:
    """A link deviation's mean over the ``good`` frames, its total variance there and that variance's white part."""
    dg = d[good]
    centre = dg.mean(0)
    dg -= centre
    total = float(np.mean(np.sum(dg ** 2, 1)))
    del dg
    trip = good[3:] & good[2:-1] & good[1:-2] & good[:-3]
    # components as rows: the medians select over contiguous memory (the same order statistics)
    d3 = np.diff(d.T, n=3, axis=1)[:, trip]
    white = float(np.sum((1.4826 * median(np.abs(d3 - median(d3, 1, keepdims=True)), 1)) ** 2)
                  / 20.0) if d3.shape[1] >= 10 else 0.0
    return centre, total, white


def _deviation_power(d: np.ndarray, good: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """The centred deviation's power spectrum (zero off the ``good`` frames), summed over its three components."""
    # the components as contiguous rows: each one's transform over contiguous memory (the same numbers),
    # their powers summed in the order numpy's sum over the short axis takes
    x = np.where(good, np.ascontiguousarray((d - centre).T), 0.0)
    a = np.abs(np.fft.rfft(x, axis=1)) ** 2
    del x
    return (a[0] + a[1]) + a[2]


def sliding_or_none(series_list, session, usable: list | None = None) -> dict | None:
    """:func:`estimate_sliding` with the session's default chain.

    None when the chain has no link between the recorded bodies.

    Parameters
    ----------
    series_list : sequence of MocapSeries
        Recordings of one session (Z-up).
    session : Session
        The session.
    usable : list of ndarray, optional
        Per recording, :func:`usable_poses` (default: made here).

    Returns
    -------
    dict or None
        :func:`estimate_sliding`'s result, or None when it raises a ConfigError.
    """
    try:
        return estimate_sliding(series_list, session, usable=usable)
    except ConfigError:
        return None


def usable_poses(series) -> np.ndarray:
    """(b, n) bool: pose finite, quaternion of non-zero norm, tracked (the chain's usable frames).

    Body by body (the temporaries are one body's, never a copy of the recording's quaternions).

    Parameters
    ----------
    series : MocapSeries
        The recording.

    Returns
    -------
    numpy.ndarray of bool (b, n)
        Per body and frame.
    """
    b, n = series.quat.shape[0], series.quat.shape[1]
    out = np.empty((b, n), dtype=bool)
    for i in range(b):
        q = series.quat[i]
        # a NaN component makes the squared norm NaN, which is not > 0
        out[i] = (np.einsum("ni,ni->n", q, q) > 0) & np.isfinite(q).all(-1) \
            & np.isfinite(series.position[i]).all(-1) & series.tracked[i]
    return out


def link_deviation(series, a: str, b: str, vector: np.ndarray, usable=None):
    """``R_a^T (p_b - p_a) - vector`` (n, 3) of one link over a recording, and where both bodies are usable.

    Unusable frames give the values of a zero pivot and an identity rotation (they are masked out by
    the caller). Computed frame by frame in one compiled loop
    (:func:`~euc_ros.core.states.geometry_compiled.link_vectors`: the quaternions, no rotation matrices).

    Parameters
    ----------
    series : MocapSeries
        The recording (Z-up).
    a, b : str
        The link's bodies: ``a`` is the reference whose frame the vector is expressed in.
    vector : array_like (3,)
        Link vector subtracted [m], in ``a``'s frame.
    usable : numpy.ndarray of bool (b, n), optional
        :func:`usable_poses` of ``series`` (default: made here).

    Returns
    -------
    deviation : numpy.ndarray (n, 3)
        The deviation [m] (``-vector`` throughout when a body is not in the recording).
    both : numpy.ndarray of bool (n,)
        Frames where both bodies are usable.
    """
    n = series.n_frames
    if a not in series.bodies or b not in series.bodies:
        return np.broadcast_to(-np.asarray(vector, float), (n, 3)).copy(), np.zeros(n, bool)
    if usable is None:
        usable = usable_poses(series)
    from euc_ros.core.states.geometry_compiled import link_vectors  # numba: on first use only

    return link_vectors(np.ascontiguousarray(series.position, dtype=float),
                        np.ascontiguousarray(series.quat, dtype=float), np.ascontiguousarray(usable),
                        series.bodies.index(a), series.bodies.index(b), np.asarray(vector, dtype=float))


def _surrogate(rng: np.random.Generator, n: int, rate_hz: float, spectrum) -> np.ndarray:
    """(n, 3) Gaussian series with the given normalised power spectrum and unit 3-D RMS."""
    f = np.fft.rfftfreq(n, 1.0 / rate_hz)
    sf, sp = spectrum
    amp = np.sqrt(np.interp(f, sf, sp, left=0.0, right=0.0))
    z = (rng.normal(0.0, 1.0, (f.size, 3)) + 1j * rng.normal(0.0, 1.0, (f.size, 3))) * amp[:, None]
    x = np.fft.irfft(z, n=n, axis=0)
    r = np.sqrt(np.mean(np.sum(x ** 2, 1)))
    return x / r if r > 0 else x


def add_sliding(series, sliding: dict, rng: np.random.Generator):
    """A copy of ``series`` with independent surrogate sliding added to every rider body's pivot.

    Each body's sliding is a Gaussian series of the measured spectrum and RMS, drawn in the body's frame and
    rotated into the world.

    Parameters
    ----------
    series : MocapSeries
        The recording (Z-up).
    sliding : dict
        :func:`estimate_sliding`'s result (``bodies``, ``rms_m`` [m], ``spectrum``); bodies with an RMS of 0
        or not recorded are left as they are.
    rng : numpy.random.Generator
        Source of the surrogate series.

    Returns
    -------
    MocapSeries
        The copy, its positions changed.
    """
    pos = series.position.copy()
    n = series.n_frames
    for nm, rms in zip(sliding["bodies"], sliding["rms_m"]):
        if nm not in series.bodies or rms <= 0:
            continue
        i = series.bodies.index(nm)
        d = _surrogate(rng, n, series.rate_hz, sliding["spectrum"]) * rms
        R = rotation_matrices(series.quat[i])
        pos[i] = pos[i] + np.einsum("nij,nj->ni", R, d)
    return dataclasses.replace(series, position=pos)
