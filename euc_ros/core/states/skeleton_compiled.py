"""The skeleton chain fit of many frames in one compiled loop (numba).

What :func:`~euc_ros.core.states.skeleton.skeleton_cog` computes with ``method="compiled"``: per frame the
chain arrays (pivots, rotation matrices, usable flags), the links' deviations and the faulty bodies
(:func:`~euc_ros.core.states.skeleton.detect_faults`' rules), the Gauss-Newton chain fit
(:func:`~euc_ros.core.states.skeleton.fit_chain`'s objective, start, damping and iterations) and G of the
fitted chain. The numpy reference builds the same ``6 m x 6 m`` normal matrices with array calls on
``(frames, 3, 3)`` blocks and scipy's rotations; on one frame (the live path) those calls, not the
arithmetic, are its cost. Here a frame is computed in scalar loops with closed-form rotations:

* ``exp(w) = I + A [w]x + B [w]x^2``, ``A = sin(t) / t``, ``B = 2 sin^2(t / 2) / t^2`` (``t = |w|``; no
  cancellation), their Taylor series through ``t^4`` below ``t = 1e-3`` (the next terms are below 1e-19);
* ``log(R)`` through the unit quaternion of ``R`` (Shepperd's choice of the largest of the trace and the
  diagonal, so it holds up to 180 deg), ``w = v t / sin(t / 2)``, ``t = 2 atan2(|v|, q_w)`` with ``q_w >= 0``, and
  the series ``2 + t^2 / 12 + 7 t^4 / 2880`` below ``t = 1e-3`` (scipy's rule);
* the normal equations solved by a Cholesky factorisation (the matrix is symmetric positive definite: the
  measurement and joint terms are sums of ``J^T W J``, plus the damping on the diagonal).

The results equal the numpy reference's up to round-off amplified by the normal matrix's conditioning
(``test_skeleton_compiled.py`` states and checks the bound). Compiled on first use and cached on disk
(numba ``cache=True``, next to this file).
"""
from __future__ import annotations

import math
import time

import numba
import numpy as np

_jit = numba.njit(cache=True, nogil=True, error_model="numpy")

#: Below this rotation angle [rad] exp and log use their Taylor series.
SERIES_BELOW = 1e-3


@_jit
def rot_exp(wx, wy, wz, out):
    """Rotation matrix ``exp([w]x)`` of the rotation vector ``(wx, wy, wz)`` [rad] into ``out`` (3, 3)."""
    t2 = wx * wx + wy * wy + wz * wz
    t = math.sqrt(t2)
    if t < SERIES_BELOW:
        a = 1.0 - t2 / 6.0 + t2 * t2 / 120.0
        b = 0.5 - t2 / 24.0 + t2 * t2 / 720.0
    else:
        a = math.sin(t) / t
        s = math.sin(0.5 * t)
        b = 2.0 * s * s / t2
    xx, yy, zz, xy, xz, yz = wx * wx, wy * wy, wz * wz, wx * wy, wx * wz, wy * wz
    out[0, 0] = 1.0 - b * (yy + zz)
    out[0, 1] = -a * wz + b * xy
    out[0, 2] = a * wy + b * xz
    out[1, 0] = a * wz + b * xy
    out[1, 1] = 1.0 - b * (xx + zz)
    out[1, 2] = -a * wx + b * yz
    out[2, 0] = -a * wy + b * xz
    out[2, 1] = a * wx + b * yz
    out[2, 2] = 1.0 - b * (xx + yy)


@_jit
def rot_log(r, out):
    """Rotation vector ``log(R)`` [rad] (angle in [0, pi]) of the rotation matrix ``r`` (3, 3) into ``out`` (3,)."""
    tr = r[0, 0] + r[1, 1] + r[2, 2]
    if tr >= r[0, 0] and tr >= r[1, 1] and tr >= r[2, 2]:
        w = 0.5 * math.sqrt(max(0.0, 1.0 + tr))
        f = 0.25 / w
        x, y, z = (r[2, 1] - r[1, 2]) * f, (r[0, 2] - r[2, 0]) * f, (r[1, 0] - r[0, 1]) * f
    elif r[0, 0] >= r[1, 1] and r[0, 0] >= r[2, 2]:
        x = 0.5 * math.sqrt(max(0.0, 1.0 + r[0, 0] - r[1, 1] - r[2, 2]))
        f = 0.25 / x
        w, y, z = (r[2, 1] - r[1, 2]) * f, (r[0, 1] + r[1, 0]) * f, (r[0, 2] + r[2, 0]) * f
    elif r[1, 1] >= r[2, 2]:
        y = 0.5 * math.sqrt(max(0.0, 1.0 - r[0, 0] + r[1, 1] - r[2, 2]))
        f = 0.25 / y
        w, x, z = (r[0, 2] - r[2, 0]) * f, (r[0, 1] + r[1, 0]) * f, (r[1, 2] + r[2, 1]) * f
    else:
        z = 0.5 * math.sqrt(max(0.0, 1.0 - r[0, 0] - r[1, 1] + r[2, 2]))
        f = 0.25 / z
        w, x, y = (r[1, 0] - r[0, 1]) * f, (r[0, 2] + r[2, 0]) * f, (r[1, 2] + r[2, 1]) * f
    n = math.sqrt(w * w + x * x + y * y + z * z)
    if w < 0.0:
        n = -n
    w, x, y, z = w / n, x / n, y / n, z / n
    s = math.sqrt(x * x + y * y + z * z)
    t = 2.0 * math.atan2(s, w)
    if t < SERIES_BELOW:
        t2 = t * t
        k = 2.0 + t2 / 12.0 + 7.0 * t2 * t2 / 2880.0
    else:
        k = t / math.sin(0.5 * t)
    out[0], out[1], out[2] = k * x, k * y, k * z


@_jit
def _gather(position, quat, tracked, rows, j, P, R, ok):
    """Frame ``j``'s chain arrays: pivots ``P`` (c, 3), rotations ``R`` (c, 3, 3), usable ``ok`` (c,).

    An unusable pose (absent, untracked, a non-finite pivot or quaternion, a zero quaternion) is the zero pivot
    with the identity rotation.
    """
    for i in range(rows.shape[0]):
        b = rows[i]
        good = False
        if b >= 0:
            px, py, pz = position[b, j, 0], position[b, j, 1], position[b, j, 2]
            x, y, z, w = quat[b, j, 0], quat[b, j, 1], quat[b, j, 2], quat[b, j, 3]
            n2 = x * x + y * y + z * z + w * w
            good = (tracked[b, j] and math.isfinite(px) and math.isfinite(py) and math.isfinite(pz)
                    and math.isfinite(x) and math.isfinite(y) and math.isfinite(z) and math.isfinite(w)
                    and n2 > 0.0 and math.isfinite(n2))
        ok[i] = good
        for a in range(3):
            for c in range(3):
                R[i, a, c] = 1.0 if a == c else 0.0
        P[i, 0] = P[i, 1] = P[i, 2] = 0.0
        if good:
            P[i, 0], P[i, 1], P[i, 2] = px, py, pz
            s = 2.0 / n2
            xx, yy, zz, xy, xz, yz = s * x * x, s * y * y, s * z * z, s * x * y, s * x * z, s * y * z
            wx, wy, wz = s * w * x, s * w * y, s * w * z
            R[i, 0, 0], R[i, 0, 1], R[i, 0, 2] = 1.0 - (yy + zz), xy - wz, xz + wy
            R[i, 1, 0], R[i, 1, 1], R[i, 1, 2] = xy + wz, 1.0 - (xx + zz), yz - wx
            R[i, 2, 0], R[i, 2, 1], R[i, 2, 2] = xz - wy, yz + wx, 1.0 - (xx + yy)


@_jit
def _faults(P, R, ok, links, m, bad, known, pos_fault, faults):
    """Frame's faulty rider bodies into ``faults`` (m,): :func:`~euc_ros.core.states.skeleton.detect_faults`."""
    src, dst, vectors, _, thr = links
    k_links = src.shape[0]
    for k in range(k_links):
        a, b = src[k], dst[k]
        known[k] = ok[a] and ok[b]
        bad[k] = False
        if known[k]:
            e2 = 0.0
            for c in range(3):
                v = (R[a, 0, c] * (P[b, 0] - P[a, 0]) + R[a, 1, c] * (P[b, 1] - P[a, 1])
                     + R[a, 2, c] * (P[b, 2] - P[a, 2])) - vectors[k, c]
                e2 += v * v
            bad[k] = math.sqrt(e2) > thr[k]
    for i in range(m + 1):
        pos_fault[i] = False
        if i == m or not ok[i]:
            continue
        n_out = n_in = 0
        out_all, out_any, in_all, in_any = True, False, True, False
        for k in range(k_links):
            if src[k] == i:
                n_out += 1
                out_all = out_all and (bad[k] or not known[k])
                out_any = out_any or known[k]
            if dst[k] == i:
                n_in += 1
                in_all = in_all and (bad[k] or not known[k])
                in_any = in_any or known[k]
        if n_out == 0 and n_in == 0:
            continue
        pos_fault[i] = (n_out == 0 or (out_all and out_any)) and (n_in == 0 or (in_all and in_any))
    for i in range(m):
        f = pos_fault[i]
        if ok[i] and not f:
            n_out = 0
            all_bad, any_rest, all_expl = True, False, True
            for k in range(k_links):
                if src[k] != i:
                    continue
                n_out += 1
                expl = pos_fault[dst[k]]
                all_bad = all_bad and (bad[k] or not known[k])
                any_rest = any_rest or (bad[k] and not expl)
                all_expl = all_expl and (expl or not known[k])
            f = n_out > 0 and all_bad and any_rest and not all_expl
        faults[i] = f


@_jit
def _cholesky_solve(H, g, N):
    """Solve ``H x = g`` in place (x into g) for a symmetric positive definite ``H`` (N, N) (overwritten)."""
    for j in range(N):
        s = H[j, j]
        for k in range(j):
            s -= H[j, k] * H[j, k]
        d = math.sqrt(s)
        H[j, j] = d
        for i in range(j + 1, N):
            s = H[i, j]
            for k in range(j):
                s -= H[i, k] * H[j, k]
            H[i, j] = s / d
    for i in range(N):
        s = g[i]
        for k in range(i):
            s -= H[i, k] * g[k]
        g[i] = s / H[i, i]
    for i in range(N - 1, -1, -1):
        s = g[i]
        for k in range(i + 1, N):
            s -= H[k, i] * g[k]
        g[i] = s / H[i, i]


@_jit
def _link_terms(H, g, w, pa, Ra, pb, u, ia, ib, m, J, offs):
    """Add a link's ``w J^T J`` to ``H`` and ``-w J^T r`` to ``g`` (``r = p_a + R_a u - p_b``)."""
    r = np.empty(3)
    for c in range(3):
        r[c] = pa[c] + Ra[c, 0] * u[0] + Ra[c, 1] * u[1] + Ra[c, 2] * u[2] - pb[c]
    nb = 0
    if ia < m:
        offs[nb] = 6 * ia
        for a in range(3):
            for c in range(3):
                J[nb, a, c] = 1.0 if a == c else 0.0
        nb += 1
        offs[nb] = 6 * ia + 3
        for a in range(3):                       # -R_a [u]x
            J[nb, a, 0] = -(Ra[a, 1] * u[2] - Ra[a, 2] * u[1])
            J[nb, a, 1] = -(Ra[a, 2] * u[0] - Ra[a, 0] * u[2])
            J[nb, a, 2] = -(Ra[a, 0] * u[1] - Ra[a, 1] * u[0])
        nb += 1
    if ib < m:
        offs[nb] = 6 * ib
        for a in range(3):
            for c in range(3):
                J[nb, a, c] = -1.0 if a == c else 0.0
        nb += 1
    for p in range(nb):
        o1 = offs[p]
        for i in range(3):
            g[o1 + i] -= w * (J[p, 0, i] * r[0] + J[p, 1, i] * r[1] + J[p, 2, i] * r[2])
        for q in range(nb):
            o2 = offs[q]
            for i in range(3):
                for j in range(3):
                    H[o1 + i, o2 + j] += w * (J[p, 0, i] * J[q, 0, j] + J[p, 1, i] * J[q, 1, j]
                                             + J[p, 2, i] * J[q, 2, j])


@_jit
def _start(Pm, Rm, ok, use, links, Pc, Rc):
    """Starting chain: the measurements; a body without a usable one from its first usable link partner."""
    src, dst, vectors, rel_rot, _ = links
    m = Pc.shape[0]
    for i in range(m):
        for a in range(3):
            Pc[i, a] = Pm[i, a]
            for c in range(3):
                Rc[i, a, c] = Rm[i, a, c]
        if use[i]:
            continue
        for k in range(src.shape[0]):
            j = dst[k]
            if src[k] != i or not ok[j] or (j < m and not use[j]):
                continue
            for a in range(3):                   # R_j rel^T
                for c in range(3):
                    Rc[i, a, c] = Rm[j, a, 0] * rel_rot[k, c, 0] + Rm[j, a, 1] * rel_rot[k, c, 1] \
                        + Rm[j, a, 2] * rel_rot[k, c, 2]
            for a in range(3):
                Pc[i, a] = Pm[j, a] - (Rc[i, a, 0] * vectors[k, 0] + Rc[i, a, 1] * vectors[k, 1]
                                       + Rc[i, a, 2] * vectors[k, 2])
            break


@_jit
def _fit_frame(Pm, Rm, ok, use, links, wp, wr, gn, Pc, Rc):
    """One frame's Gauss-Newton chain fit into ``Pc`` (m, 3), ``Rc`` (m, 3, 3); ``gn``: joint weight, damping, steps."""
    src, dst, vectors, _, _ = links
    wj, damp, iterations = gn
    m = Pc.shape[0]
    N = 6 * m
    H = np.empty((N, N))
    g = np.empty(N)
    J = np.empty((3, 3, 3))
    offs = np.empty(3, np.int64)
    rr = np.empty(3)
    M = np.empty((3, 3))
    E = np.empty((3, 3))
    T = np.empty((3, 3))
    _start(Pm, Rm, ok, use, links, Pc, Rc)
    for _ in range(iterations):
        H[:, :] = 0.0
        g[:] = 0.0
        for i in range(m):
            p0, r0 = 6 * i, 6 * i + 3
            for a in range(3):
                H[p0 + a, p0 + a] += wp[i]
                H[r0 + a, r0 + a] += wr[i]
            if wp[i] != 0.0:
                for a in range(3):
                    g[p0 + a] -= wp[i] * (Pc[i, a] - Pm[i, a])
            if wr[i] != 0.0:
                for a in range(3):           # R_m^T R_c
                    for c in range(3):
                        M[a, c] = Rm[i, 0, a] * Rc[i, 0, c] + Rm[i, 1, a] * Rc[i, 1, c] + Rm[i, 2, a] * Rc[i, 2, c]
                rot_log(M, rr)
                for a in range(3):
                    g[r0 + a] -= wr[i] * rr[a]
        for k in range(src.shape[0]):
            ia, ib = src[k], dst[k]
            if not ((ok[ia] or ia < m) and (ok[ib] or ib < m)):
                continue                         # a link from or to an untracked E does nothing
            pa = Pc[ia] if ia < m else Pm[ia]
            Ra = Rc[ia] if ia < m else Rm[ia]
            pb = Pc[ib] if ib < m else Pm[ib]
            _link_terms(H, g, wj, pa, Ra, pb, vectors[k], ia, ib, m, J, offs)
        for a in range(N):
            H[a, a] += damp
        _cholesky_solve(H, g, N)
        for i in range(m):
            for a in range(3):
                Pc[i, a] += g[6 * i + a]
            rot_exp(g[6 * i + 3], g[6 * i + 4], g[6 * i + 5], E)
            for a in range(3):
                for c in range(3):
                    T[a, c] = Rc[i, a, 0] * E[0, c] + Rc[i, a, 1] * E[1, c] + Rc[i, a, 2] * E[2, c]
            Rc[i, :, :] = T


@_jit
def chain_cog(position, quat, tracked, rows, links, weights, segments):
    """Faults, fitted chain and G of every frame of ``position`` (b, n, 3), ``quat`` (b, n, 4), ``tracked`` (b, n).

    ``rows`` (m + 1,): the chain's bodies (rider bodies then E) as rows of the arrays (-1: absent). ``links``:
    ``(src, dst, vectors, rel_rot, thr)``, the links as chain indices (k,), (k,) and the model's (k, 3),
    (k, 3, 3), (k,). ``weights``: ``(sw, pos_w, rot_w, wj, iterations)``, the per-body weight factors (m,), the
    measurement and joint weights and the Gauss-Newton steps. ``segments``: ``(seg_idx, seg_frac, seg_off,
    seg_total, complete)``, the weighted segments as chain indices (s,) with their fractions (s,) and CoM offsets
    (s, 3), the fractions' sum, and whether every weighted segment is a chain body.

    Returns ``G`` (n, 3), ``has_rider`` (n,), ``faults`` (m, n), ``P_fit`` (m, n, 3), ``R_fit`` (m, n, 3, 3).
    The damping is ``1e-9`` times the largest weight over all frames (as the reference's, per call).
    """
    sw, pos_w, rot_w, wj, iterations = weights
    seg_idx, seg_frac, seg_off, seg_total, complete = segments
    c = rows.shape[0]
    m = c - 1
    n = position.shape[1]
    k_links = links[0].shape[0]
    P = np.empty((c, 3))
    R = np.empty((c, 3, 3))
    ok = np.empty(c, np.bool_)
    bad = np.empty(k_links, np.bool_)
    known = np.empty(k_links, np.bool_)
    pos_fault = np.empty(c, np.bool_)
    fl = np.empty(m, np.bool_)
    faults = np.empty((m, n), np.bool_)
    w_max = wj
    for j in range(n):
        _gather(position, quat, tracked, rows, j, P, R, ok)
        _faults(P, R, ok, links, m, bad, known, pos_fault, fl)
        for i in range(m):
            faults[i, j] = fl[i]
            if ok[i] and not fl[i]:
                w_max = max(w_max, sw[i] * pos_w, sw[i] * rot_w)
    gn = (wj, 1e-9 * w_max, iterations)
    G = np.empty((n, 3))
    has_rider = np.empty(n, np.bool_)
    P_fit = np.empty((m, n, 3))
    R_fit = np.empty((m, n, 3, 3))
    use = np.empty(m, np.bool_)
    wp = np.empty(m)
    wr = np.empty(m)
    Pc = np.empty((m, 3))
    Rc = np.empty((m, 3, 3))
    for j in range(n):
        _gather(position, quat, tracked, rows, j, P, R, ok)
        for i in range(m):
            use[i] = ok[i] and not faults[i, j]
            wp[i] = sw[i] * pos_w if use[i] else 0.0
            wr[i] = sw[i] * rot_w if use[i] else 0.0
        _fit_frame(P, R, ok, use, links, wp, wr, gn, Pc, Rc)
        hr = complete
        gx = gy = gz = 0.0
        for s in range(seg_idx.shape[0]):
            i = seg_idx[s]
            f = seg_frac[s]
            o = seg_off[s]
            gx += f * (Pc[i, 0] + (Rc[i, 0, 0] * o[0] + Rc[i, 0, 1] * o[1] + Rc[i, 0, 2] * o[2]))
            gy += f * (Pc[i, 1] + (Rc[i, 1, 0] * o[0] + Rc[i, 1, 1] * o[1] + Rc[i, 1, 2] * o[2]))
            gz += f * (Pc[i, 2] + (Rc[i, 2, 0] * o[0] + Rc[i, 2, 1] * o[1] + Rc[i, 2, 2] * o[2]))
            hr = hr and ok[i]
        if hr:
            G[j, 0], G[j, 1], G[j, 2] = gx / seg_total, gy / seg_total, gz / seg_total
        else:
            G[j, 0] = G[j, 1] = G[j, 2] = math.nan
        has_rider[j] = hr
        P_fit[:, j, :] = Pc
        R_fit[:, j, :, :] = Rc
    return G, has_rider, faults, P_fit, R_fit


def compiled_skeleton_cog(position, quat, tracked, session, bodies, model, threshold_m=None) -> dict:
    """Rider CoG from the fitted chain through :func:`chain_cog`: :func:`~euc_ros.core.states.skeleton.skeleton_cog`.

    Parameters
    ----------
    position, quat, tracked, bodies
        As :func:`~euc_ros.core.states.geometry.frame_geometry`: (b, ..., 3) [m], (b, ..., 4), (b, ...) or None.
    session : Session
        Mass fractions and CoM offsets.
    model : SkeletonModel
        The session's chain.
    threshold_m : ndarray (k,), optional
        Fault thresholds overriding the model's [m].

    Returns
    -------
    dict
        :func:`~euc_ros.core.states.skeleton.skeleton_cog`'s keys.
    """
    plan = _kernel_plan(model, session, tuple(bodies))
    b = len(plan[0]) - 1
    position = np.asarray(position, float)
    shape = position.shape[1:-1]
    n = int(np.prod(shape)) if shape else 1
    P = np.ascontiguousarray(position.reshape(-1, n, 3))
    Q = np.ascontiguousarray(np.asarray(quat, float).reshape(-1, n, 4))
    T = (np.ones(P.shape[:2], bool) if tracked is None
         else np.ascontiguousarray(np.asarray(tracked, bool).reshape(-1, n)))
    rows, src, dst, sw, segments = plan
    thr = model.threshold_m if threshold_m is None else np.asarray(threshold_m, float)
    cfg = model.config
    links = (src, dst, np.ascontiguousarray(model.vectors, float), np.ascontiguousarray(model.rel_rot, float),
             np.ascontiguousarray(thr, float))
    weights = (sw, 1.0 / cfg.pos_sigma_m ** 2, 1.0 / math.radians(cfg.rot_sigma_deg) ** 2, 1.0 / cfg.joint_sigma_m ** 2,
               int(cfg.iterations))
    G, has_rider, faults, Pf, Rf = chain_cog(P, Q, T, rows, links, weights, segments)
    return {"G": G.reshape(shape + (3,)), "has_rider": has_rider.reshape(shape),
            "faults": faults.reshape((b,) + shape), "n_faults": faults.sum(0).reshape(shape),
            "P_fit": Pf.reshape((b,) + shape + (3,)), "R_fit": Rf.reshape((b,) + shape + (3, 3))}


def warm_up() -> float:
    """Seconds taken to make :func:`chain_cog` ready: compiled, or loaded from numba's cache.

    The call :func:`compiled_skeleton_cog` makes, on a two-body chain of one frame, with the same array types
    and layouts, so a live node pays the compilation before its first frame instead of stalling on it.

    Returns
    -------
    float
        Wall time of the call [s].
    """
    t0 = time.perf_counter()
    P = np.zeros((2, 1, 3))
    P[1, 0, 2] = 0.5
    Q = np.zeros((2, 1, 4))
    Q[:, 0, 3] = 1.0
    T = np.ones((2, 1), bool)
    links = (np.array([0], np.int64), np.array([1], np.int64), np.ascontiguousarray([[0.0, 0.0, -0.5]]),
             np.ascontiguousarray(np.eye(3)[None]), np.array([0.05]))
    weights = (np.ones(1), 1.0e4, 1.0e2, 1.0e4, 2)
    segments = (np.array([0], np.int64), np.array([1.0]), np.zeros((1, 3)), 1.0, True)
    chain_cog(P, Q, T, np.array([0, 1], np.int64), links, weights, segments)
    return time.perf_counter() - t0


#: Per model, session and body list, the compiled kernel's index arrays (:func:`_kernel_plan`).
_PLANS: dict = {}


def _kernel_plan(model, session, bodies: tuple) -> tuple:
    """The kernel's index and weight arrays of a model, session and body list (cached per objects and bodies).

    ``rows`` (m + 1,) chain bodies as rows of the input (-1 absent), ``src, dst`` (k,) links as chain indices,
    ``sw`` (m,) weight factors, and the segments' tuple of
    :func:`~euc_ros.core.states.skeleton_compiled.chain_cog` (the weighted segments as chain indices).
    """
    key = (id(model), id(session), bodies)
    hit = _PLANS.get(key)
    if hit is not None and hit[0] is model and hit[1] is session:
        return hit[2]
    chain = list(model.bodies) + [model.euc_body]
    rows = np.array([bodies.index(nm) if nm in bodies else -1 for nm in chain], np.int64)
    src = np.array([chain.index(a) for a, _ in model.links], np.int64)
    dst = np.array([chain.index(b) for _, b in model.links], np.int64)
    sw = np.array([model.config.segment_weights.get(b, 1.0) for b in model.bodies], float)
    names, fractions, offsets = session.segment_arrays()
    segs = [(model.bodies.index(nm), f, o) for nm, f, o in zip(names, fractions, offsets)
            if f > 0 and nm in model.bodies]
    complete = all(nm in model.bodies for nm, f in zip(names, fractions) if f > 0)
    plan = (rows, src, dst, sw, (np.array([i for i, _, _ in segs], np.int64), np.array([f for _, f, _ in segs], float),
                                 np.array([o for _, _, o in segs], float).reshape(-1, 3),
                                 max(float(sum(f for _, f, _ in segs)), 1e-300), bool(complete)))
    if len(_PLANS) > 64:
        _PLANS.clear()
    _PLANS[key] = (model, session, plan)
    return plan
