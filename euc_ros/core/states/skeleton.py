"""Skeleton-constrained rider CoG: a kinematic chain fitted to the 13 rider bodies and the EUC body E.

Markers sit on skin, so each rigid body slides against its bone by millimetres and degrees. The
per-segment CoG (``G = sum f_i (p_i + R_i o_i)``, :func:`~euc_ros.core.states.geometry.frame_geometry`)
takes every slide straight into G. The bones, however, are rigid and meet at joints: the pivot of one
body (docs/session.md, rigid bodies: helmet top, shoulder, elbow, wrist, hip, knee, ankle) is a fixed point of the
neighbouring bone. This module uses that redundancy.

Links
    A link ``a -> b`` states that body b's pivot is fixed in body a's frame:
    ``p_b = p_a + R_a u_ab`` (:data:`DEFAULT_LINKS`: the shank carries the knee, the thigh the hip, the
    forearm the elbow, the upper arm the shoulder, the chest halves each other and the hips, the pelvis
    bodies each other, the head both shoulders, and the EUC body both ankles: the feet stand on the
    pedals). Links whose bodies are absent are dropped.
Segment lengths
    ``u_ab`` is estimated once per session: the component-wise median over every usable frame of
    ``R_a^T (p_b - p_a)`` (:meth:`SkeletonModel.estimate`; robust to the few frames with a swap or
    a flip).
Fit
    Per frame, pivots ``p_i`` and orientations ``R_i`` of all rider bodies minimise (E is held at its
    measurement, a hard shell that does not slide)::

        sum_i  |p_i - p_i^m|^2 / s_p^2  +  |log(R_i^m^T R_i)|^2 / s_r^2      (measurements)
      + sum_ab |p_a + R_a u_ab - p_b|^2 / s_j^2                               (joints)

    with ``s_p, s_r`` the expected sliding per axis and ``s_j`` the joint's play (small: the chain is
    nearly rigid). Gauss-Newton on the rotation increments (one dense ``6 m x 6 m`` normal matrix per
    frame, ``m`` rider bodies), compiled (:mod:`~euc_ros.core.states.skeleton_compiled`: one loop over the
    frames, closed-form rotations, a Cholesky solve); :func:`fit_chain` is the numpy reference, batched over
    frames. A frame is fitted on its own, so the live version has no lag. G and phi come from the fitted
    chain: ``G = sum f_i (p_i + R_i o_i)``.
Faults
    A marker swap or a 180 deg flip makes a body's links jump by far more than any sliding
    (:func:`detect_faults`). Per frame and link, ``e_ab = |R_a^T (p_b - p_a) - u_ab|``; a link is bad
    above its threshold (median + ``fault_sigmas`` robust standard deviations of ``e_ab`` over the
    session, at least ``fault_floor_m``). A body whose links *into* it and *out of* it are all bad has a
    wrong pivot (a swap); a body whose links out of it are all bad, not explained by a wrong pivot at
    their other end, has a wrong orientation (a flip). Such a body's measurement gets zero weight in
    that frame: the chain predicts it from its neighbours (started from the median relative rotation
    to its first link partner), so it is never averaged into G; the frames are counted.

Limits: the chain cannot remove sliding that every body shares (a rigid rider's soft tissue following
the common acceleration moves all bodies alike) nor wrong CoM offsets in the session (the chain fixes
where the bones are, not where their masses sit). A flip about a link's own direction leaves that
link unchanged and is not detected (it moves the CoM only by the offset's part across the bone).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from euc_ros.core.errors import ConfigError

#: Chain links ``(a, b)``: body b's pivot is a fixed point of body a (docs/session.md, rigid bodies pivots).
DEFAULT_LINKS: tuple[tuple[str, str], ...] = (
    ("E", "LR"), ("E", "LL"),            # pedals carry the ankles
    ("LR", "TR"), ("LL", "TL"),          # shank: ankle -> knee
    ("TR", "HR"), ("TL", "HL"),          # thigh: knee -> hip
    ("HR", "HL"), ("HL", "HR"),          # pelvis
    ("CHR", "HR"), ("CHL", "HL"),        # trunk: shoulder -> hip
    ("CHR", "CHL"), ("CHL", "CHR"),      # chest: shoulder -> shoulder
    ("UAR", "CHR"), ("UAL", "CHL"),      # upper arm: elbow -> shoulder
    ("LAR", "UAR"), ("LAL", "UAL"),      # forearm: wrist -> elbow
    ("H", "CHR"), ("H", "CHL"),          # head: helmet top -> shoulders
)
#: CoG methods of :func:`~euc_ros.core.states.geometry.frame_geometry`.
COG_METHODS = ("segments", "skeleton")
_CHUNK = 512


@dataclass(frozen=True)
class SkeletonFitConfig:
    """Weights and fault thresholds of the chain fit (SI units).

    Parameters
    ----------
    pos_sigma_m : float
        Expected sliding of a pivot per axis [m] (weight ``1 / pos_sigma_m^2``).
    rot_sigma_deg : float
        Expected sliding of an orientation per axis [deg].
    joint_sigma_m : float
        Play of a joint [m] (small: the chain is nearly rigid).
    segment_weights : dict, optional
        Per-body factor on both measurement weights (e.g. ``{"H": 0.5}`` for a loose helmet).
    iterations : int
        Gauss-Newton iterations per frame.
    fault_sigmas : float
        A link is bad beyond its median deviation plus this many robust standard deviations.
    fault_floor_m : float
        Smallest fault threshold of a link [m].

    Raises
    ------
    ConfigError
        Naming the field: a sigma, ``fault_sigmas`` or ``fault_floor_m`` not finite and > 0, ``iterations``
        below 1, or a negative segment weight.
    """

    pos_sigma_m: float = 0.005
    rot_sigma_deg: float = 2.0
    joint_sigma_m: float = 0.002
    segment_weights: dict = field(default_factory=dict)
    iterations: int = 4
    fault_sigmas: float = 6.0
    fault_floor_m: float = 0.03

    def __post_init__(self) -> None:
        for k in ("pos_sigma_m", "rot_sigma_deg", "joint_sigma_m", "fault_sigmas", "fault_floor_m"):
            v = getattr(self, k)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"must be a finite number > 0, got {v}", key=k)
        if self.iterations < 1:
            raise ConfigError(f"must be >= 1, got {self.iterations}", key="iterations")
        for k, v in self.segment_weights.items():
            if not (math.isfinite(v) and v >= 0):
                raise ConfigError(f"weight of {k} must be >= 0, got {v}", key="segment_weights")


def _rotmats(quat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation matrices (..., 3, 3) of quaternions (..., 4) and a finiteness mask (identity where bad)."""
    flat = quat.reshape(-1, 4)
    ok = np.all(np.isfinite(flat), axis=1) & (np.linalg.norm(np.where(np.isfinite(flat), flat, 0.0), axis=1) > 0)
    out = np.broadcast_to(np.eye(3), (flat.shape[0], 3, 3)).copy()
    if ok.any():
        out[ok] = Rotation.from_quat(flat[ok]).as_matrix()
    return out.reshape(quat.shape[:-1] + (3, 3)), ok.reshape(quat.shape[:-1])


def _link_samples(P, Q, T, ia: int, ib: int, block: int = 1 << 14) -> tuple[np.ndarray, np.ndarray]:
    """A link's samples over the frames where both bodies are usable.

    ``R_a^T (p_b - p_a)`` (m, 3) and ``R_a^T R_b`` (m, 3, 3), computed block by block (no rotation matrices of
    the whole recording).
    """
    def usable(i):
        okq = _rotmats_ok(Q[i])
        return okq & np.all(np.isfinite(P[i]), -1) & (True if T is None else T[i])

    m = usable(ia) & usable(ib)
    count = int(m.sum())
    v = np.empty((count, 3))
    rel = np.empty((count, 3, 3))
    at = 0
    for lo in range(0, m.size, block):
        mb = m[lo:lo + block]
        k = int(mb.sum())
        if not k:
            continue
        Ra = _rotmats(Q[ia, lo:lo + block][mb])[0]
        Rb = _rotmats(Q[ib, lo:lo + block][mb])[0]
        v[at:at + k] = np.einsum("nji,nj->ni", Ra, P[ib, lo:lo + block][mb] - P[ia, lo:lo + block][mb])
        rel[at:at + k] = np.einsum("nji,njk->nik", Ra, Rb)
        at += k
    return v, rel


def _rotmats_ok(quat: np.ndarray) -> np.ndarray:
    """The finiteness mask of :func:`_rotmats` alone."""
    flat = quat.reshape(-1, 4)
    ok = np.all(np.isfinite(flat), axis=1) & (np.linalg.norm(np.where(np.isfinite(flat), flat, 0.0), axis=1) > 0)
    return ok.reshape(quat.shape[:-1])


def _skew(v: np.ndarray) -> np.ndarray:
    z = np.zeros(v.shape[:-1])
    return np.stack([np.stack([z, -v[..., 2], v[..., 1]], -1), np.stack([v[..., 2], z, -v[..., 0]], -1),
                     np.stack([-v[..., 1], v[..., 0], z], -1)], -2)


def _project_so3(m: np.ndarray) -> np.ndarray:
    """Nearest rotation to each (.., 3, 3) matrix (SVD)."""
    u, _, vt = np.linalg.svd(m)
    d = np.sign(np.linalg.det(u @ vt))
    u[..., :, 2] *= d[..., None]
    return u @ vt


@dataclass(frozen=True)
class SkeletonModel:
    """A session's chain: bodies, links, their fixed vectors and fault thresholds.

    Parameters
    ----------
    bodies : tuple of str
        Rider bodies of the chain (the session's segment bodies, session order).
    euc_body : str
        The EUC's rigid body (held at its measurement).
    links : tuple of (str, str)
        Links ``(a, b)`` used (``a`` may be the EUC body).
    vectors : ndarray (k, 3)
        ``u_ab``: b's pivot in a's body frame [m].
    rel_rot : ndarray (k, 3, 3)
        Median ``R_a^T R_b`` (to start a faulty body's fit from its link partner).
    threshold_m : ndarray (k,)
        Fault threshold of each link [m].
    frames : int
        Frames the estimate used (the most of any link).
    config : SkeletonFitConfig
        The fit's weights and fault thresholds.
    """

    bodies: tuple[str, ...]
    euc_body: str
    links: tuple[tuple[str, str], ...]
    vectors: np.ndarray
    rel_rot: np.ndarray
    threshold_m: np.ndarray
    frames: int
    config: SkeletonFitConfig = field(default_factory=SkeletonFitConfig)

    @classmethod
    def estimate(cls, series_list, session, *, config: SkeletonFitConfig | None = None,
                 links=DEFAULT_LINKS, max_frames: int | None = None) -> "SkeletonModel":
        """Estimate the link vectors (segment lengths) once per session from recordings.

        Parameters
        ----------
        series_list : MocapSeries or sequence of MocapSeries
            Z-up recordings of the session (every usable frame counts; ``max_frames`` keeps the
            first frames only, as the live estimator's calibration does).
        session : Session
            Segment bodies and the EUC body.
        config : SkeletonFitConfig, optional
            Weights and fault thresholds (default: :class:`SkeletonFitConfig`'s).
        links : sequence of (str, str)
            Candidate links; those whose bodies are not in the session are dropped.
        max_frames : int, optional
            Frames used from the start of each recording (default: all).

        Returns
        -------
        SkeletonModel
            The chain of the links seen.

        Raises
        ------
        ConfigError
            If no link has a frame with both of its bodies tracked (links never seen are left out).
        """
        if not isinstance(series_list, (list, tuple)):
            series_list = [series_list]
        pos = [s.position for s in series_list]
        quat = [s.quat for s in series_list]
        trk = [s.tracked for s in series_list]
        return cls.from_poses(pos, quat, trk, series_list[0].bodies if series_list else [], session,
                              config=config, links=links, max_frames=max_frames,
                              other_bodies=[s.bodies for s in series_list])

    @classmethod
    def from_poses(cls, positions, quats, tracked, bodies, session, *, config=None, links=DEFAULT_LINKS,
                   max_frames=None, other_bodies=None) -> "SkeletonModel":
        """As :meth:`estimate`, from arrays: lists of (b, n, 3) positions, (b, n, 4) quaternions, (b, n) tracked.

        Parameters
        ----------
        positions : list of array_like (b, n, 3)
            Per recording, the bodies' pivots [m] (Z-up).
        quats : list of array_like (b, n, 4)
            Per recording, the bodies' orientations (quaternions).
        tracked : list of (array_like of bool (b, n) or None) or None
            Per recording, the tracked flags (None: every pose counts when finite).
        bodies : sequence of str
            Body names of the arrays' first axis.
        session : Session
            Segment bodies and the EUC body.
        config : SkeletonFitConfig, optional
            Weights and fault thresholds (default: :class:`SkeletonFitConfig`'s).
        links : sequence of (str, str)
            Candidate links; those whose bodies are not in the session are dropped.
        max_frames : int, optional
            Frames used from the start of each recording (default: all).
        other_bodies : list of sequence of str, optional
            Per recording, its body names (default: ``bodies`` for every one).

        Returns
        -------
        SkeletonModel
            The chain of the links seen.

        Raises
        ------
        ConfigError
            Naming ``cog_method``: no link between the session's bodies, or none seen with both bodies usable.
        """
        config = config or SkeletonFitConfig()
        names, _, _ = session.segment_arrays()
        euc = session.euc.body
        known = set(names) | {euc}
        used = tuple((a, b) for a, b in links if a in known and b in known and a != b)
        if not used:
            raise ConfigError("no chain link between the session's bodies", key="cog_method")
        recs = []
        for j, (P, Q) in enumerate(zip(positions, quats)):
            bl = list(other_bodies[j]) if other_bodies is not None else list(bodies)
            P = np.asarray(P, float)
            Q = np.asarray(Q, float)
            if max_frames is not None:
                P, Q = P[:, :max_frames], Q[:, :max_frames]
            T = None if tracked is None or tracked[j] is None else np.asarray(tracked[j], bool)[:, :P.shape[1]]
            recs.append((P, Q, T, bl))
        # link by link, so only one link's samples exist at a time (each recording's arrays are read in place)
        kept, vecs, rels, thrs = [], [], [], []
        n_frames = 0
        for a, b in used:
            parts = [_link_samples(P, Q, T, bl.index(a), bl.index(b)) for P, Q, T, bl in recs
                     if a in bl and b in bl]
            if sum(len(v) for v, _ in parts) == 0:
                continue                                # links never seen together are left out
            v = np.concatenate([v for v, _ in parts]) if len(parts) > 1 else parts[0][0]
            r = np.concatenate([r for _, r in parts]) if len(parts) > 1 else parts[0][1]
            del parts
            n_frames = max(n_frames, v.shape[0])
            vk = np.median(v, axis=0)
            rels.append(_project_so3(np.median(r, axis=0)))
            del r
            e = np.linalg.norm(v - vk, axis=1)
            med = float(np.median(e))
            mad = float(np.median(np.abs(e - med)))
            thrs.append(max(config.fault_floor_m, med + config.fault_sigmas * 1.4826 * mad))
            vecs.append(vk)
            kept.append((a, b))
        if not kept:
            raise ConfigError("no chain link has a frame with both of its bodies tracked", key="cog_method")
        used = tuple(kept)
        vec = np.array(vecs, dtype=float).reshape(len(used), 3)
        rel = np.array(rels, dtype=float).reshape(len(used), 3, 3)
        thr = np.array(thrs, dtype=float)
        return cls(tuple(names), euc, used, vec, rel, thr, n_frames, config)

    def to_dict(self) -> dict:
        """A JSON-friendly summary: links with their lengths and thresholds.

        Returns
        -------
        dict
            ``links`` (``from``, ``to``, ``vector_m``, ``length_m``, ``fault_threshold_m`` [m] each) and ``frames``.
        """
        return {"links": [{"from": a, "to": b, "vector_m": [float(x) for x in v], "length_m": float(np.linalg.norm(v)),
                           "fault_threshold_m": float(t)}
                          for (a, b), v, t in zip(self.links, self.vectors, self.threshold_m)],
                "frames": self.frames}


def _gather(model: SkeletonModel, position, quat, tracked, bodies):
    """Chain arrays (m, n, ...) of the rider bodies plus E, with usable masks (frames flattened)."""
    bodies = list(bodies)
    position = np.asarray(position, float)
    quat = np.asarray(quat, float)
    shape = position.shape[1:-1]
    n = int(np.prod(shape)) if shape else 1
    P = position.reshape(len(bodies), n, 3)
    Q = quat.reshape(len(bodies), n, 4)
    T = None if tracked is None else np.asarray(tracked, bool).reshape(len(bodies), n)
    chain = list(model.bodies) + [model.euc_body]
    Pc = np.zeros((len(chain), n, 3))
    Rc = np.broadcast_to(np.eye(3), (len(chain), n, 3, 3)).copy()
    ok = np.zeros((len(chain), n), bool)
    for i, nm in enumerate(chain):
        if nm not in bodies:
            continue
        j = bodies.index(nm)
        R, okq = _rotmats(Q[j])
        okj = okq & np.all(np.isfinite(P[j]), -1) & (True if T is None else T[j])
        Pc[i] = np.where(okj[:, None], P[j], 0.0)
        Rc[i] = np.where(okj[:, None, None], R, np.eye(3))
        ok[i] = okj
    return Pc, Rc, ok, shape


def link_deviations(model: SkeletonModel, P: np.ndarray, R: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """The links' deviations ``e_ab = |R_a^T (p_b - p_a) - u_ab|`` for chain arrays.

    Parameters
    ----------
    model : SkeletonModel
        The chain.
    P : numpy.ndarray (m+1, n, 3)
        Pivots [m], rider bodies then E.
    R : numpy.ndarray (m+1, n, 3, 3)
        Rotations, the same order.
    ok : numpy.ndarray of bool (m+1, n)
        Usable poses.

    Returns
    -------
    numpy.ndarray (k, n)
        Per link and frame [m]; NaN where a body is unusable.
    """
    chain = list(model.bodies) + [model.euc_body]
    e = np.full((len(model.links), P.shape[1]), np.nan)
    for k, (a, b) in enumerate(model.links):
        ia, ib = chain.index(a), chain.index(b)
        v = np.einsum("nji,nj->ni", R[ia], P[ib] - P[ia])
        e[k] = np.where(ok[ia] & ok[ib], np.linalg.norm(v - model.vectors[k], axis=-1), np.nan)
    return e


def detect_faults(model: SkeletonModel, P: np.ndarray, R: np.ndarray, ok: np.ndarray,
                  threshold_m: np.ndarray | None = None) -> np.ndarray:
    """Bodies (m, n) whose pose the chain cannot follow in a frame (swap: wrong pivot; flip: wrong orientation).

    See the module docstring. Unusable bodies are not faults (they are untracked).

    Parameters
    ----------
    model : SkeletonModel
        The chain.
    P, R, ok : numpy.ndarray
        Chain arrays (rider bodies then E): pivots (m+1, n, 3) [m], rotations (m+1, n, 3, 3), usable (m+1, n).
    threshold_m : array_like (k,), optional
        Fault threshold of each link [m] (default: the model's).

    Returns
    -------
    numpy.ndarray of bool (m, n)
        Faulty rider bodies per frame.
    """
    thr = model.threshold_m if threshold_m is None else np.asarray(threshold_m, float)
    e = link_deviations(model, P, R, ok)
    bad = e > thr[:, None]                      # NaN compares False: a link with an untracked end is not bad
    known = np.isfinite(e)
    chain = list(model.bodies) + [model.euc_body]
    m, n = len(model.bodies), P.shape[1]
    src = np.array([chain.index(a) for a, _ in model.links])
    dst = np.array([chain.index(b) for _, b in model.links])

    def all_bad(idx_links):
        """Every known link of the set is bad and at least one is known: (n,) bool."""
        if idx_links.size == 0:
            return np.ones(n, bool)
        kb, kk = bad[idx_links], known[idx_links]
        return np.all(kb | ~kk, axis=0) & np.any(kk, axis=0)

    pos_fault = np.zeros((len(chain), n), bool)
    for i in range(m):
        out_i, in_i = np.flatnonzero(src == i), np.flatnonzero(dst == i)
        if out_i.size == 0 and in_i.size == 0:
            continue                             # a body on no link: the chain says nothing about it
        pos_fault[i] = all_bad(out_i) & (all_bad(in_i) if in_i.size else True) & ok[i]
    explained = pos_fault[dst]                   # a bad link into a body with a wrong pivot
    rest = bad & ~explained
    faults = pos_fault[:m].copy()
    for i in range(m):
        out_i = np.flatnonzero(src == i)
        if out_i.size == 0:
            continue
        kb, kk, ke = bad[out_i], known[out_i], explained[out_i]
        faults[i] |= np.all(kb | ~kk, axis=0) & np.any(rest[out_i], axis=0) & ok[i] & ~np.all(ke | ~kk, axis=0)
    return faults


def _exp(rv: np.ndarray) -> np.ndarray:
    return Rotation.from_rotvec(rv.reshape(-1, 3)).as_matrix().reshape(rv.shape[:-1] + (3, 3))


def _log(Rm: np.ndarray) -> np.ndarray:
    return Rotation.from_matrix(Rm.reshape(-1, 3, 3)).as_rotvec().reshape(Rm.shape[:-2] + (3,))


def fit_chain(model: SkeletonModel, P: np.ndarray, R: np.ndarray, ok: np.ndarray,
              exclude: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares chain poses (pivots (m, n, 3), rotations (m, n, 3, 3)) of the rider bodies.

    Parameters
    ----------
    model : SkeletonModel
        The chain (its links and fit weights).
    P, R, ok : ndarray
        Chain arrays (rider bodies then E): pivots (m+1, n, 3), rotations (m+1, n, 3, 3), usable (m+1, n).
    exclude : ndarray (m, n) of bool, optional
        Measurements given zero weight (faults); the chain predicts those bodies.

    Returns
    -------
    P_fit : numpy.ndarray (m, n, 3)
        Fitted pivots [m].
    R_fit : numpy.ndarray (m, n, 3, 3)
        Fitted rotations.
    """
    cfg = model.config
    chain = list(model.bodies) + [model.euc_body]
    m, n = len(model.bodies), P.shape[1]
    sw = np.array([cfg.segment_weights.get(b, 1.0) for b in model.bodies], float)
    use = ok[:m] & (True if exclude is None else ~exclude)
    wp = (sw[:, None] * use) / cfg.pos_sigma_m ** 2                      # (m, n)
    wr = (sw[:, None] * use) / math.radians(cfg.rot_sigma_deg) ** 2
    wj = 1.0 / cfg.joint_sigma_m ** 2
    damp = 1e-9 * max(wj, float(wp.max(initial=0.0)), float(wr.max(initial=0.0)))
    Pm, Rm = P[:m], R[:m]
    Pf, Rf = Pm.copy(), Rm.copy()
    # bodies without a usable measurement start from their first link partner (median relative rotation)
    start = ~use
    if start.any():
        for i in range(m):
            ks = [k for k, (a, b) in enumerate(model.links) if chain.index(a) == i]
            for k in ks:
                j = chain.index(model.links[k][1])
                s = start[i] & ok[j] & (use[j] if j < m else True)
                if not s.any():
                    continue
                Ri = np.einsum("nij,kj->nik", R[j][s], model.rel_rot[k])
                Rf[i, s] = Ri
                Pf[i, s] = P[j][s] - np.einsum("nij,j->ni", Ri, model.vectors[k])
                start[i] &= ~s
    links = [(chain.index(a), chain.index(b), model.vectors[k]) for k, (a, b) in enumerate(model.links)]
    link_ok = [ok[ia] | (ia < m) for ia, _, _ in links]     # a link from an untracked E does nothing
    link_ok = [lo & (ok[ib] | (ib < m)) for lo, (_, ib, _) in zip(link_ok, links)]
    N = 6 * m
    for s0 in range(0, n, _CHUNK):
        sl = slice(s0, min(n, s0 + _CHUNK))
        c = sl.stop - sl.start
        Pc, Rc = Pf[:, sl].copy(), Rf[:, sl].copy()
        PE, RE = P[m, sl], R[m, sl]
        for _ in range(cfg.iterations):
            H = np.zeros((c, N, N))
            g = np.zeros((c, N))
            eye = np.eye(3)
            for i in range(m):
                p0, r0 = 6 * i, 6 * i + 3
                rp = Pc[i] - Pm[i, sl]
                rr = _log(np.einsum("nji,njk->nik", Rm[i, sl], Rc[i]))
                H[:, p0:p0 + 3, p0:p0 + 3] += wp[i, sl, None, None] * eye
                H[:, r0:r0 + 3, r0:r0 + 3] += wr[i, sl, None, None] * eye
                g[:, p0:p0 + 3] -= wp[i, sl, None] * rp
                g[:, r0:r0 + 3] -= wr[i, sl, None] * rr
            for (ia, ib, u), lok in zip(links, link_ok):
                w = wj * lok[sl]
                pa = Pc[ia] if ia < m else PE
                Ra = Rc[ia] if ia < m else RE
                pb = Pc[ib] if ib < m else PE
                r = pa + Ra @ u - pb                                     # (c, 3)
                blocks = []                                              # (column offset, Jacobian (c, 3, 3))
                if ia < m:
                    blocks.append((6 * ia, np.broadcast_to(eye, (c, 3, 3))))
                    blocks.append((6 * ia + 3, -Ra @ _skew(u)))
                if ib < m:
                    blocks.append((6 * ib, np.broadcast_to(-eye, (c, 3, 3))))
                for o1, J1 in blocks:
                    g[:, o1:o1 + 3] -= w[:, None] * np.einsum("nji,nj->ni", J1, r)
                    for o2, J2 in blocks:
                        H[:, o1:o1 + 3, o2:o2 + 3] += w[:, None, None] * np.einsum("nki,nkj->nij", J1, J2)
            H[:, np.arange(N), np.arange(N)] += damp
            dx = np.linalg.solve(H, g[..., None])[..., 0].reshape(c, m, 6)
            Pc += dx[..., :3].transpose(1, 0, 2)
            Rc = Rc @ _exp(dx[..., 3:].transpose(1, 0, 2))
        Pf[:, sl], Rf[:, sl] = Pc, Rc
    return Pf, Rf


def skeleton_cog(position, quat, tracked, session, bodies, model: SkeletonModel,
                 threshold_m: np.ndarray | None = None, method: str = "compiled") -> dict[str, np.ndarray]:
    """Rider CoG from the fitted chain, for one or many frames.

    Parameters
    ----------
    position, quat, tracked, bodies
        As :func:`~euc_ros.core.states.geometry.frame_geometry`: (b, ..., 3), (b, ..., 4), (b, ...).
    session : Session
        Mass fractions and CoM offsets.
    model : SkeletonModel
        The session's chain (:meth:`SkeletonModel.estimate`).
    threshold_m : ndarray (k,), optional
        Fault thresholds overriding the model's (the live estimator's calibration).
    method : {"compiled", "reference"}
        ``compiled`` (default): every frame in one compiled loop
        (:func:`~euc_ros.core.states.skeleton_compiled.chain_cog`); ``reference``: :func:`detect_faults` and
        :func:`fit_chain` in numpy. The same fit; they agree to round-off amplified by the normal matrix's
        conditioning.

    Returns
    -------
    dict
        ``G`` (..., 3) [m]; ``has_rider`` (...) every body of non-zero mass tracked (faulty ones
        included: the chain predicts them); ``faults`` (m, ...) bool (bodies excluded);
        ``n_faults`` (...) int; ``P_fit`` (m, ..., 3) and ``R_fit`` (m, ..., 3, 3) the fitted chain.

    Raises
    ------
    ConfigError
        Naming ``method`` when it is neither.
    """
    if method == "compiled":
        from euc_ros.core.states.skeleton_compiled import compiled_skeleton_cog  # numba: loaded on first use

        return compiled_skeleton_cog(position, quat, tracked, session, bodies, model, threshold_m)
    if method != "reference":
        raise ConfigError(f"must be 'compiled' or 'reference', got {method!r}", key="method")
    P, R, ok, shape = _gather(model, position, quat, tracked, bodies)
    m = len(model.bodies)
    faults = detect_faults(model, P, R, ok, threshold_m)
    Pf, Rf = fit_chain(model, P, R, ok, faults)
    names, fractions, offsets = session.segment_arrays()
    has_rider = np.ones(P.shape[1], bool)
    G = np.zeros((P.shape[1], 3))
    wsum = 0.0
    for nm, f, o in zip(names, fractions, offsets):
        if f <= 0:
            continue
        if nm not in model.bodies:
            has_rider[:] = False
            continue
        i = model.bodies.index(nm)
        G += f * (Pf[i] + Rf[i] @ o)
        has_rider &= ok[i]
        wsum += f
    G = np.where(has_rider[:, None], G / max(wsum, 1e-300), np.nan)
    return {"G": G.reshape(shape + (3,)), "has_rider": has_rider.reshape(shape),
            "faults": faults.reshape((m,) + shape), "n_faults": faults.sum(0).reshape(shape),
            "P_fit": Pf.reshape((m,) + shape + (3,)), "R_fit": Rf.reshape((m,) + shape + (3, 3))}


def _masked_median(x: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Per row, the median (:func:`numpy.median`'s value) of ``x`` (k, c, n) over the frames where ``mask`` (k, n)."""
    cnt = mask.sum(axis=1)
    out = np.full(x.shape[:2], np.nan)
    for c in np.unique(cnt[cnt > 0]):           # rows of one count share their order statistics
        rows = np.flatnonzero(cnt == c)
        lo, hi = (c - 1) // 2, c // 2
        xr = x[rows] if c == x.shape[2] else np.where(mask[rows, None, :], x[rows], np.inf)
        part = np.partition(xr, (lo, hi), axis=-1)
        out[rows] = (part[..., lo] + part[..., hi]) / 2
    return out


class _CalibrationFrames:
    """The live calibration's link samples, frame by frame, and the model they give.

    :meth:`SkeletonModel.from_poses` of the frames so far (the same samples, medians and thresholds), with each
    frame's link samples made once, when it arrives, and the medians of all links at once. A model costs time in
    proportion to the frames: it is rebuilt (:meth:`due`) on each of the first :attr:`EVERY_UNTIL` frames, then
    when the frames have grown by ``1 / GROWTH`` since the last one, so the cost per frame stays bounded at any rate.
    """

    EVERY_UNTIL, GROWTH = 32, 16

    def __init__(self, bodies: list, capacity: int, session) -> None:
        names, _, _ = session.segment_arrays()
        known = set(names) | {session.euc.body}
        used = [(a, b) for a, b in DEFAULT_LINKS if a in known and b in known and a != b]
        if not used:
            raise ConfigError("no chain link between the session's bodies", key="cog_method")
        self.links = tuple((a, b) for a, b in used if a in bodies and b in bodies)
        self.ia = [bodies.index(a) for a, _ in self.links]
        self.ib = [bodies.index(b) for _, b in self.links]
        self.bodies, self.names, self.euc, self.n, self.built = bodies, tuple(names), session.euc.body, 0, 0
        self.v = np.zeros((len(self.links), 3, capacity))           # R_a^T (p_b - p_a)
        self.rel = np.zeros((len(self.links), 9, capacity))         # R_a^T R_b
        self.both = np.zeros((len(self.links), capacity), bool)

    def add(self, position, quat, tracked) -> None:
        """Append one frame: ``position`` (b, 3) [m], ``quat`` (b, 4), ``tracked`` (b,) or None."""
        P = np.asarray(position, float)
        R, ok = _rotmats(np.asarray(quat, float))
        ok = ok & np.all(np.isfinite(P), -1) & (True if tracked is None else np.asarray(tracked, bool))
        P = np.where(ok[:, None], P, 0.0)
        Ra = R[self.ia]
        self.v[:, :, self.n] = np.einsum("kji,kj->ki", Ra, P[self.ib] - P[self.ia])
        self.rel[:, :, self.n] = np.einsum("kji,kjl->kil", Ra, R[self.ib]).reshape(-1, 9)
        self.both[:, self.n] = ok[self.ia] & ok[self.ib]
        self.n += 1

    def due(self) -> bool:
        """Whether the frames so far call for a new model (see the class)."""
        return self.n <= self.EVERY_UNTIL or self.n - self.built >= self.n // self.GROWTH

    def model(self, config: SkeletonFitConfig) -> SkeletonModel:
        """The chain of the frames so far (:meth:`SkeletonModel.from_poses`'s, its errors alike)."""
        n = self.built = self.n
        keep = self.both[:, :n].any(axis=1)
        if not keep.any():
            raise ConfigError("no chain link has a frame with both of its bodies tracked", key="cog_method")
        both, v = self.both[keep, :n], self.v[keep, :, :n]
        vk = _masked_median(v, both)
        rel = _project_so3(_masked_median(self.rel[keep, :, :n], both).reshape(-1, 3, 3))
        e = np.linalg.norm(v - vk[:, :, None], axis=1)[:, None, :]
        med = _masked_median(e, both)
        mad = _masked_median(np.abs(e - med[:, :, None]), both)
        thr = np.maximum(config.fault_floor_m, (med + config.fault_sigmas * 1.4826 * mad)[:, 0])
        links = tuple(lk for lk, k in zip(self.links, keep) if k)
        return SkeletonModel(self.names, self.euc, links, vk, rel, thr, int(both.sum(axis=1).max()), config)


class OnlineSkeleton:
    """Live chain fit: lengths from the first ``calibration_frames`` frames, then frozen; no lag.

    Until the calibration is complete, each frame uses the medians over the frames seen so far (refreshed as
    :class:`_CalibrationFrames` says) and the fault threshold ``calibration_floor_m`` (no robust scale yet);
    afterwards the session model estimated from the calibration frames (or the ``model`` given) is used unchanged.

    Parameters
    ----------
    session : Session
    calibration_frames : int
        Frames used to estimate the link vectors.
    model : SkeletonModel, optional
        A model estimated offline for the session (then no calibration).
    config : SkeletonFitConfig, optional
    calibration_floor_m : float
        Fault threshold of every link during the calibration [m].
    """

    #: Output delay of the CoG [s]: every frame is fitted on its own.
    lag_s = 0.0

    def __init__(self, session, *, calibration_frames: int = 240, model: SkeletonModel | None = None,
                 config: SkeletonFitConfig | None = None, calibration_floor_m: float = 0.08) -> None:
        if calibration_frames < 1:
            raise ConfigError(f"must be >= 1, got {calibration_frames}", key="calibration_frames")
        self.session = session
        self.config = config or (model.config if model is not None else SkeletonFitConfig())
        self.calibration_frames = int(calibration_frames)
        self.calibration_floor_m = float(calibration_floor_m)
        self.model = model
        self._cal: _CalibrationFrames | None = None
        #: Body-frames excluded so far, per body.
        self.fault_counts: dict[str, int] = {}

    @property
    def calibrated(self) -> bool:
        """True once the link vectors are frozen."""
        return self.model is not None and self._cal is None

    def reset(self) -> None:
        """Forget the fault counts (the calibration is kept: the rider is the same)."""
        self.fault_counts.clear()

    def calibrate(self, position, quat, tracked, bodies) -> tuple[SkeletonModel, np.ndarray | None]:
        """Take one frame into the calibration (while it lasts).

        Parameters
        ----------
        position : array_like (b, 3)
            The bodies' pivots [m] (Z-up).
        quat : array_like (b, 4)
            The bodies' orientations (quaternions).
        tracked : array_like of bool (b,) or None
            Tracked flags (None: all tracked).
        bodies : sequence of str
            Body names; a change of the set starts the calibration afresh.

        Returns
        -------
        model : SkeletonModel
            The model to fit this frame with.
        threshold_m : numpy.ndarray (k,) or None
            The fault thresholds to use for this frame [m] (None: the model's own).

        Raises
        ------
        ConfigError
            Naming ``cog_method`` when no link can be estimated from the frames seen.
        """
        if self.model is not None and self._cal is None:
            return self.model, None
        bodies = list(bodies)
        if self._cal is None or self._cal.bodies != bodies:
            self._cal = _CalibrationFrames(bodies, self.calibration_frames, self.session)   # afresh: new body set
        self._cal.add(position, quat, tracked)
        last = self._cal.n >= self.calibration_frames
        if last or self.model is None or self._cal.due():
            self.model = self._cal.model(self.config)
        model = self.model
        if last:
            self._cal = None
            return model, None
        return model, np.full(len(model.links), self.calibration_floor_m)

    def update(self, position, quat, tracked, bodies) -> dict[str, np.ndarray]:
        """Fit one frame and count its faulty bodies in :attr:`fault_counts`.

        Parameters
        ----------
        position : array_like (b, 3)
            The bodies' pivots [m] (Z-up).
        quat : array_like (b, 4)
            The bodies' orientations (quaternions).
        tracked : array_like of bool (b,) or None
            Tracked flags (None: all tracked).
        bodies : sequence of str
            Body names.

        Returns
        -------
        dict
            :func:`skeleton_cog`'s dict of the frame.
        """
        model, thr = self.calibrate(position, quat, tracked, bodies)
        out = skeleton_cog(position, quat, tracked, self.session, bodies, model, threshold_m=thr)
        for nm, f in zip(model.bodies, np.asarray(out["faults"]).reshape(len(model.bodies))):
            if f:
                self.fault_counts[nm] = self.fault_counts.get(nm, 0) + 1
        return out
