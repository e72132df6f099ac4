"""Wheel phases of the ``aligned`` wheel-rotation family (:mod:`.families`): one function, an offset per recording.

A tyre's angle when a recording starts is not measured, so the family's raw columns are each recording's own
Fourier series ``sin(k theta), cos(k theta)`` (k = 1..K, zero on the other recordings). The group selection
(:mod:`.groups`) finds the offsets (:func:`align_wheel_phases`) and turns the raw columns into one function
(:func:`wheel_phase_mix`, made of the blocks of :func:`phase_rotations`). Angles in radians.
"""
from __future__ import annotations

import numpy as np

#: Grid of a recording's wheel phase offset (then refined on a grid of a tenth of its step) [rad].
PHASE_GRID = 72
#: Sweeps of the coordinate-wise search of the phase offsets.
PHASE_SWEEPS = 2


def phase_rotations(deltas: np.ndarray, harmonics: int) -> np.ndarray:
    """Per offset ``d`` (m,), the (2 K, 2 K) block turning the wheel's Fourier columns by ``d``: (m, 2 K, 2 K).

    The block takes ``sin(k theta), cos(k theta)`` (k = 1..K, in that order) to
    ``sin(k (theta + d)), cos(k (theta + d))``.

    Parameters
    ----------
    deltas : array_like (m,)
        Offsets [rad].
    harmonics : int
        K.

    Returns
    -------
    ndarray (m, 2 K, 2 K)
    """
    d = np.atleast_1d(np.asarray(deltas, float))
    K = int(harmonics)
    k = np.arange(K)
    ang = np.outer(d, k + 1.0)
    c, s = np.cos(ang), np.sin(ang)
    R = np.zeros((d.size, 2 * K, 2 * K))
    R[:, k, k] = c                  # sin(k(theta+d)) = sin(k theta) cos(k d) + cos(k theta) sin(k d)
    R[:, K + k, k] = s
    R[:, k, K + k] = -s             # cos(k(theta+d)) = cos(k theta) cos(k d) - sin(k theta) sin(k d)
    R[:, K + k, K + k] = c
    return R


def wheel_phase_mix(deltas: np.ndarray, harmonics: int) -> np.ndarray:
    """Matrix (2 K n_runs, 2 K) turning the ``aligned`` wheel family's per-recording Fourier columns into one function.

    One function of the wheel angle with a phase offset per recording: ``f(theta + delta_r)``.

    The raw columns of recording r are ``sin(k theta), cos(k theta)`` (k = 1..K, in that order) and zero on
    the others, so the group's columns are the raw ones times the stacked blocks of :func:`phase_rotations`.

    Parameters
    ----------
    deltas : array_like (n_runs,)
        Phase offset per recording [rad].
    harmonics : int
        K.

    Returns
    -------
    ndarray (2 K n_runs, 2 K)
    """
    return phase_rotations(deltas, harmonics).reshape(-1, 2 * int(harmonics))


def align_wheel_phases(B: np.ndarray, r: np.ndarray, harmonics: int, n_runs: int) -> np.ndarray:
    """Phase offsets of the ``aligned`` wheel family that let one function of the wheel angle explain ``r`` best.

    A tyre's angle when a recording starts is not measured, so a function shared by the recordings is out of
    phase between them, and one free function per recording fits half-runs and predicts nothing. The first
    recording with data is the reference (offset 0). With several harmonics the fit is multimodal in the
    offsets, so each recording is first aligned with the reference alone (a global search on a grid of
    :data:`PHASE_GRID` offsets, the two recordings' columns only), then all are refined together, one at a
    time near their offsets (:data:`PHASE_SWEEPS` sweeps on a grid a tenth of the step).

    Parameters
    ----------
    B : ndarray (n, 2 K n_runs)
        The family's raw columns as they act on ``r`` (least squares).
    r : ndarray (n,)
    harmonics : int
        K.
    n_runs : int

    Returns
    -------
    ndarray (n_runs,)
        One offset per recording [rad] (all 0 with fewer than two recordings with data).
    """
    B = np.asarray(B, float)
    r = np.asarray(r, float)
    K = int(harmonics)
    w = 2 * K
    G = B.T @ B
    g = B.T @ r
    live = [q for q in range(n_runs) if np.any(np.diag(G)[q * w:(q + 1) * w] > 0)]
    deltas = np.zeros(n_runs)
    if len(live) < 2:
        return deltas
    ridge = 1e-12 * max(float(np.trace(G)), 1e-300) * np.eye(w)

    def blk(u, v):
        return G[u * w:(u + 1) * w, v * w:(v + 1) * w]

    # every product below is a function of the offsets it is made of: kept by their bits, so a scan that holds
    # the other recordings' offsets recomputes none of their products (the same operations on the same operands)
    memo: dict = {}

    def kept(key, make, *args):
        if key not in memo:
            memo[key] = make(*args)
        return memo[key]

    def outer(u, v, Ru, Rv):
        return Ru.T @ blk(u, v) @ Rv

    def scores(runs: list[int], q: int, grid: np.ndarray) -> np.ndarray:
        # M^T G M and M^T g with the other runs' rotations fixed and run q's over the grid
        others = [u for u in runs if u != q]
        d = {u: deltas[u].tobytes() for u in others}
        Ro = {u: kept(("R", d[u]), phase_rotations, deltas[u], K)[0] for u in others}
        C = sum(kept(("C", u, v, d[u], d[v]), outer, u, v, Ro[u], Ro[v]) for u in others for v in others)
        P = sum(kept(("P", q, v, d[v]), np.matmul, blk(q, v), Ro[v]) for v in others)
        c0 = sum(kept(("c", u, d[u]), np.matmul, Ro[u].T, g[u * w:(u + 1) * w]) for u in others)
        Rq = kept(("Rq", grid.tobytes()), phase_rotations, grid, K)                 # (m, w, w)
        RqT = Rq.transpose(0, 2, 1)
        RP = RqT @ P
        A = C + RP + RP.transpose(0, 2, 1) + RqT @ blk(q, q) @ Rq + ridge
        b = c0 + RqT @ g[q * w:(q + 1) * w]
        return np.einsum("mi,mi->m", b, np.linalg.solve(A, b[..., None])[..., 0])

    step = 2.0 * np.pi / PHASE_GRID
    coarse = np.arange(PHASE_GRID) * step
    ref = live[0]

    def refine(runs, q, around):
        fine = around + np.linspace(-step, step, 21)
        return float(np.mod(fine[int(np.argmax(scores(runs, q, fine)))], 2.0 * np.pi))

    for q in live[1:]:
        pair = [ref, q]
        deltas[q] = refine(pair, q, coarse[int(np.argmax(scores(pair, q, coarse)))])
    for _ in range(PHASE_SWEEPS):
        for q in live[1:]:
            deltas[q] = refine(live, q, deltas[q])
    return deltas
