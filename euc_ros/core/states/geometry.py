"""Frame geometry: from rigid-body poses to the EUC's and the rider's points and angles, per frame.

Per frame (:func:`frame_geometry`, vectorized over any number of frames, so the same code serves a
live frame and a whole recording):

* EUC pivot ``E`` and orientation ``R_E = Rz(psi) Rx(theta) Ry(gamma)`` (yaw, tilt, pitch, Fig. 2);
* wheel centre ``C = E + R_E @ pivot_to_wheel_center`` (docs/session.md, rigid bodies);
* ankle hinge ``A = C - l0 R_E e_z`` (``l0`` below C along the EUC body axis, Fig. 5);
* segment centres of mass ``pivot + R_body @ com_offset`` and the rider CoG
  ``G = sum_i f_i CoM_i`` (mass fractions ``f_i``, sum 1). A frame in which any segment of non-zero
  mass is untracked has no G (``has_rider`` False, NaN);
* the moving frame ``T = Rz(psi) Rx(theta)`` of eqs (1)-(2) (:func:`to_moving_frame`):
  ``r_CG = T^T (G - C)``, and ``phi_eq3 = arctan(x_CG / z_CG)`` (eq (3), the angle of G seen from the
  wheel centre C);
* ``phi_hinge``: the same angle seen from the ankle hinge A, ``r_AG = T^T (G - A)``. This is the
  model's own rider pitch (the line A-G of Fig. 5) and the default for identification.

Over a whole recording, :func:`block_geometry` bridges and evaluates :func:`frame_geometry` block by
block (:data:`~euc_ros.core.mocap.blocks.READ_FRAMES` frames, each read with ``max_gap + 1`` frames of
margin on both sides so every bridged gap sees both its ends) and keeps only the per-frame outputs
the states are made of. The peak memory is the outputs plus one block's working set, where bridging
and evaluating the whole recording at once cost a full copy of its poses plus the geometry's
temporaries (about three times the recording's arrays).
"""
from __future__ import annotations

import math

import numpy as np

from euc_ros.core.errors import ConfigError, InputError
from euc_ros.core.mocap import blocks
from euc_ros.core.mocap.blocks import pose_block
from euc_ros.core.mocap.bridging import bridge_series
from euc_ros.core.mocap.series import MocapSeries
from euc_ros.core.rotations import quat_rotate, rotation_matrices, yaw_tilt_pitch_from_quat
from euc_ros.core.states.skeleton import COG_METHODS, SkeletonModel, skeleton_cog

#: Outputs of :func:`frame_geometry` the states are made of.
GEOMETRY_KEYS = ("psi", "theta", "gamma", "phi_eq3", "phi_hinge", "C", "G", "has_euc", "has_rider", "n_faults")


def block_geometry(series, session, max_gap: int, *, block: int | None = None) -> tuple[dict, int, int]:
    """Bridged per-frame geometry of a whole recording (segments CoG), evaluated block by block.

    Parameters
    ----------
    series : MocapSeries
        The recording (Z-up).
    session : Session
        The session (bodies, EUC geometry, segments).
    max_gap : int
        Longest run of untracked frames of a body bridged [frames] (0: none).
    block : int, optional
        Frames per block; default :data:`~euc_ros.core.mocap.blocks.READ_FRAMES`.

    Returns
    -------
    geo : dict of ndarray
        :data:`GEOMETRY_KEYS` over all frames, as ``frame_geometry`` of the bridged recording gives them.
    bridged_samples, bridged_frames : int
        Body-frames bridged, and frames with at least one body bridged (as
        :func:`~euc_ros.core.mocap.bridging.bridge_series` reports them for the whole recording).
    """
    block = block or blocks.READ_FRAMES
    n = int(series.n_frames)
    margin = max(int(max_gap), 0) + 1
    frame = np.asarray(series.frame)
    out: dict[str, np.ndarray] = {}
    n_samples = n_frames = 0
    in_place = getattr(series, "pose_block", None) is None and all(
        np.asarray(v).flags.c_contiguous and np.asarray(v).dtype == dt
        for v, dt in ((series.position, float), (series.quat, float), (series.tracked, bool)))
    for a in range(0, max(n, 1), block):
        b = min(n, a + block)
        lo, hi = max(0, a - margin), min(n, b + margin)
        pos, quat, trk = pose_block(series, lo, hi)
        core = slice(a - lo, b - lo)
        bridged = None
        if max_gap > 0 and not _complete(pos, quat, trk):
            piece = MocapSeries(t=series.t[lo:hi], frame=frame[lo:hi], bodies=list(series.bodies), position=pos,
                                quat=quat, tracked=trk, mean_marker_error=np.empty((len(series.bodies), 0)))
            bridged_piece, bridged = bridge_series(piece, max_gap)
            geo = _compiled_geometry(bridged_piece.position, bridged_piece.quat, bridged_piece.tracked, session,
                                     list(series.bodies), core)
            del bridged_piece, piece
        elif in_place:
            # nothing to bridge, the recording's own contiguous arrays: the block's frames read where they are
            geo = _compiled_geometry(series.position, series.quat, series.tracked, session, list(series.bodies),
                                     slice(a, b))
        else:                                   # nothing to bridge: the block as read
            geo = _compiled_geometry(pos, quat, trk, session, list(series.bodies), core)
        del pos, quat, trk
        for key in GEOMETRY_KEYS:
            v = np.asarray(geo[key])
            if key not in out:
                out[key] = np.empty((n,) + v.shape[1:], dtype=v.dtype)
            out[key][a:b] = v
        if bridged is not None:
            n_samples += int(bridged[:, core].sum())
            n_frames += int(bridged[:, core].any(axis=0).sum())
    blocks.release(series)                      # a re-noised recording's kept noise blocks: not needed after
    return out, n_samples, n_frames


def _complete(position, quat, tracked) -> bool:
    """Every pose of the block tracked and finite (nothing to bridge)."""
    return bool(tracked.all() and np.isfinite(position).all() and np.isfinite(quat).all())


def _compiled_geometry(position, quat, tracked, session, bodies: list, frames: slice | None = None) -> dict:
    """:func:`frame_geometry` (``segments``) of the frames ``frames`` (default all) of (b, n) poses.

    Only the :data:`GEOMETRY_KEYS`, in one compiled loop:
    :func:`~euc_ros.core.states.geometry_compiled.segments_geometry` (the same formulas, equal to round-off).
    """
    first, stop, _ = (frames or slice(None)).indices(np.shape(position)[1])
    idx, frac, off, total, complete = _segment_table(session, tuple(bodies))
    euc = session.euc
    from euc_ros.core.states.geometry_compiled import segments_geometry  # numba: not for the live nodes

    # contiguous inputs: one compiled specialisation
    psi, theta, gamma, eq3, hinge, C, G, has_euc, has_rider = segments_geometry(
        np.ascontiguousarray(position, dtype=float), np.ascontiguousarray(quat, dtype=float),
        np.ascontiguousarray(tracked, dtype=bool),
        bodies.index(euc.body) if euc.body in bodies else -1, np.asarray(euc.pivot_to_wheel_center, dtype=float),
        float(euc.l0), np.asarray(idx, dtype=np.int64), frac, off, float(total), bool(complete), first, stop)
    return {"psi": psi, "theta": theta, "gamma": gamma, "phi_eq3": eq3, "phi_hinge": hinge, "C": C, "G": G,
            "has_euc": has_euc, "has_rider": has_rider, "n_faults": np.zeros(psi.shape[0], dtype=int)}


def to_moving_frame(v, psi, theta) -> np.ndarray:
    """Express world vectors in the moving frame of eqs (1)-(2): ``T_theta^T T_psi^T v``.

    Parameters
    ----------
    v : array_like (..., 3)
        World (Z-up) vectors [m].
    psi, theta : array_like (...)
        Yaw and tilt [rad].

    Returns
    -------
    numpy.ndarray (..., 3)
        The vectors in the moving frame [m].
    """
    v = np.asarray(v, dtype=float)
    cp, sp = np.cos(psi), np.sin(psi)
    ct, st = np.cos(theta), np.sin(theta)
    x1 = cp * v[..., 0] + sp * v[..., 1]
    y1 = -sp * v[..., 0] + cp * v[..., 1]
    z1 = v[..., 2]
    return np.stack([x1, ct * y1 + st * z1, -st * y1 + ct * z1], axis=-1)


def frame_geometry(position, quat, tracked, session, bodies, *, cog_method: str = "segments",
                   skeleton: SkeletonModel | None = None, fault_threshold_m=None) -> dict[str, np.ndarray]:
    """Wheel centre, hinge, rider CoG and the EUC/rider angles of one or many frames.

    Parameters
    ----------
    position : array_like (b, ..., 3)
        Pivot positions of the rigid bodies [m], Z-up world.
    quat : array_like (b, ..., 4)
        Body-to-world quaternions (x, y, z, w).
    tracked : array_like (b, ...) of bool, optional
        Tracking flags; ``None`` means "tracked where finite".
    session : Session
        Segment mass fractions and CoM offsets, EUC geometry (``body``, ``l0``,
        ``pivot_to_wheel_center``).
    bodies : sequence of str
        Names of the ``b`` rows.
    cog_method : {"segments", "skeleton"}
        ``segments``: ``G = sum f_i CoM_i`` of the measured poses (the default). ``skeleton``: G of
        the kinematic chain fitted to the poses (:mod:`~euc_ros.core.states.skeleton`); bodies
        with a swap or a flip are excluded and predicted by the chain.
    skeleton : SkeletonModel, optional
        The session's chain for ``skeleton`` (default: estimated from the frames given, which needs
        many frames to be meaningful).
    fault_threshold_m : array_like (k,), optional
        Fault thresholds of the chain's links overriding the model's (live calibration).

    Returns
    -------
    dict of ndarray
        ``E, C, A, G`` (..., 3) [m]; ``r_CG, r_AG`` (..., 3) [m] in the moving frame (eq (1));
        ``psi, theta, gamma`` (...) [rad] (yaw, tilt, pitch of E); ``phi_eq3`` (eq (3)) and
        ``phi_hinge`` (...) [rad]; ``has_euc`` and ``has_rider`` (...) bool; ``n_faults`` (...) int,
        the rider bodies excluded from G (always 0 for ``segments``), and for ``skeleton``
        ``cog_fault_bodies``, a dict body -> excluded frames (bodies with none left out). Quantities that need an
        untracked body are NaN; nothing raises for missing data.
    """
    if cog_method not in COG_METHODS:
        raise ConfigError(f"cog method must be one of {COG_METHODS}, got {cog_method!r}", key="cog_method")
    position = np.asarray(position, dtype=float)
    quat = np.asarray(quat, dtype=float)
    bodies = list(bodies)
    if position.shape[0] != len(bodies) or quat.shape[0] != len(bodies):
        raise InputError(f"{len(bodies)} body names for position {position.shape} and quat {quat.shape}",
                         key="bodies")
    shape = position.shape[1:-1]
    if shape == () and position.shape == (len(bodies), 3) and quat.shape == (len(bodies), 4):
        if cog_method == "segments":
            return _one_frame_geometry(position, quat, tracked, session, bodies)
        if skeleton is not None:
            G, has_rider, n_faults, extra = _skeleton_geometry_cog(position, quat, tracked, session, bodies, skeleton,
                                                                   fault_threshold_m)
            return {**_one_frame_geometry(position, quat, tracked, session, bodies, cog=(G, has_rider)),
                    "n_faults": n_faults, **extra}
    tracked = None if tracked is None else np.asarray(tracked, dtype=bool)
    has_euc, E, C, A, psi, theta, gamma = _euc_geometry(position, quat, tracked, session, bodies)
    G, has_rider = _segments_cog(position, quat, tracked, session, bodies)
    n_faults = np.zeros(shape, dtype=int)
    if cog_method == "skeleton":
        G, has_rider, n_faults, extra = _skeleton_geometry_cog(position, quat, tracked, session, bodies, skeleton,
                                                               fault_threshold_m)
    else:
        extra = {}

    r_CG = to_moving_frame(G - C, psi, theta)
    r_AG = to_moving_frame(G - A, psi, theta)
    return {
        "E": E, "C": C, "A": A, "G": G, "r_CG": r_CG, "r_AG": r_AG,
        "psi": psi, "theta": theta, "gamma": gamma,
        "phi_eq3": np.arctan2(r_CG[..., 0], r_CG[..., 2]),
        "phi_hinge": np.arctan2(r_AG[..., 0], r_AG[..., 2]),
        "has_euc": has_euc, "has_rider": has_rider, "n_faults": n_faults, **extra,
    }


def _euc_geometry(position: np.ndarray, quat: np.ndarray, tracked, session, bodies: list) -> tuple:
    """:func:`frame_geometry`'s EUC part: ``(has_euc, E, C, A, psi, theta, gamma)`` (NaN where E is not usable)."""
    shape = position.shape[1:-1]
    euc = session.euc
    if euc.body in bodies:
        i = bodies.index(euc.body)
        has_euc = np.isfinite(position[i]).all(-1) & np.isfinite(quat[i]).all(-1)
        if tracked is not None:
            has_euc = has_euc & tracked[i]
        E = np.where(has_euc[..., None], position[i], np.nan)
        qE = np.where(has_euc[..., None], quat[i], np.nan)
    else:
        has_euc = np.zeros(shape, dtype=bool)
        E, qE = np.full(shape + (3,), np.nan), np.full(shape + (4,), np.nan)
    R_E = rotation_matrices(qE)
    ang = yaw_tilt_pitch_from_quat(qE)
    psi, theta, gamma = ang[..., 0], ang[..., 1], ang[..., 2]
    C = E + R_E @ np.asarray(euc.pivot_to_wheel_center, dtype=float)
    A = C - euc.l0 * R_E[..., :, 2]
    return has_euc, E, C, A, psi, theta, gamma


def _segments_cog(position: np.ndarray, quat: np.ndarray, tracked, session, bodies: list) -> tuple:
    """:func:`frame_geometry`'s ``segments`` G: ``(G, has_rider)`` (G NaN where a weighted segment is not usable)."""
    shape = position.shape[1:-1]
    names, fractions, offsets = session.segment_arrays()
    # every weighted segment at once: (k, ..., 3) CoMs, weighted and summed over k
    weighted = [(name, frac, off) for name, frac, off in zip(names, fractions, offsets) if frac > 0.0]
    present = [(bodies.index(n), f, o) for n, f, o in weighted if n in bodies]
    has_rider = np.full(shape, len(present) == len(weighted) and len(present) > 0)
    G = np.zeros(shape + (3,))
    if present:
        idx = np.array([j for j, _, _ in present])
        frac = np.array([f for _, f, _ in present])
        off = np.array([o for _, _, o in present], dtype=float).reshape((len(present),) + (1,) * len(shape) + (3,))
        pos_k, quat_k = position[idx], quat[idx]
        ok_k = np.isfinite(pos_k).all(-1) & np.isfinite(quat_k).all(-1)
        if tracked is not None:
            ok_k &= tracked[idx]
        com = pos_k + quat_rotate(quat_k, off)
        w = frac.reshape((-1,) + (1,) * (len(shape) + 1))
        G = np.where(ok_k[..., None], w * com, 0.0).sum(axis=0)
        has_rider &= ok_k.all(axis=0)
    G = np.where(has_rider[..., None], G / fractions[fractions > 0].sum(), np.nan)
    return G, has_rider


def _skeleton_geometry_cog(position: np.ndarray, quat: np.ndarray, tracked, session, bodies: list,
                           skeleton: SkeletonModel | None, fault_threshold_m) -> tuple:
    """:func:`frame_geometry`'s ``skeleton`` G: ``(G, has_rider, n_faults, extra)`` (``extra``: the fault counts)."""
    if skeleton is None:
        skeleton = SkeletonModel.from_poses([position.reshape(len(bodies), -1, 3)],
                                            [quat.reshape(len(bodies), -1, 4)],
                                            [None if tracked is None else tracked.reshape(len(bodies), -1)],
                                            bodies, session)
    sk = skeleton_cog(position, quat, tracked, session, bodies, skeleton, threshold_m=fault_threshold_m)
    per_body = sk["faults"].reshape(len(skeleton.bodies), -1).sum(axis=1)
    linked = {b for link in skeleton.links for b in link}
    extra = {"cog_fault_bodies": {nm: int(c) for nm, c in zip(skeleton.bodies, per_body) if c},
             "cog_unlinked_bodies": [nm for nm in skeleton.bodies if nm not in linked]}
    return sk["G"], sk["has_rider"], sk["n_faults"], extra


def _one_frame_geometry(position: np.ndarray, quat: np.ndarray, tracked, session, bodies: list,
                        cog: tuple | None = None) -> dict:
    """:func:`frame_geometry` of one frame with ``segments`` G (or ``cog``: G, has_rider), in scalar arithmetic.

    The same formulas as the vectorized path (tested equal to round-off): a live node calls this
    per frame, where ~40 numpy calls on 3-vectors cost ~10x the arithmetic.
    """
    sin, cos = math.sin, math.cos
    nan = math.nan
    euc = session.euc
    i = bodies.index(euc.body) if euc.body in bodies else -1
    has_euc = False
    if i >= 0:
        e, q = position[i], quat[i]
        has_euc = bool(np.isfinite(e).all() and np.isfinite(q).all() and (tracked is None or tracked[i]))
    if has_euc:
        ex, ey, ez = float(e[0]), float(e[1]), float(e[2])
        x, y, z, w = float(q[0]), float(q[1]), float(q[2]), float(q[3])
        n2 = x * x + y * y + z * z + w * w
        s2 = 2.0 / n2 if n2 > 0.0 else nan
        xx, yy, zz, xy, xz, yz = s2 * x * x, s2 * y * y, s2 * z * z, s2 * x * y, s2 * x * z, s2 * y * z
        wx, wy, wz = s2 * w * x, s2 * w * y, s2 * w * z
        r00, r01, r02 = 1.0 - (yy + zz), xy - wz, xz + wy
        r10, r11, r12 = xy + wz, 1.0 - (xx + zz), yz - wx
        r20, r21, r22 = xz - wy, yz + wx, 1.0 - (xx + yy)
        theta = math.asin(min(1.0, max(-1.0, r21))) if r21 == r21 else nan
        gamma = math.atan2(-r20, r22)
        psi = math.atan2(-r01, r11)
    else:
        ex = ey = ez = nan
        r00 = r01 = r02 = r10 = r11 = r12 = r20 = r21 = r22 = nan
        psi = theta = gamma = nan
    px, py, pz = (float(v) for v in euc.pivot_to_wheel_center)
    cx = ex + r00 * px + r01 * py + r02 * pz
    cy = ey + r10 * px + r11 * py + r12 * pz
    cz = ez + r20 * px + r21 * py + r22 * pz
    l0 = float(euc.l0)
    ax, ay, az = cx - l0 * r02, cy - l0 * r12, cz - l0 * r22

    idx, frac, off, total, complete = _segment_table(session, tuple(bodies))
    has_rider = complete
    gx = gy = gz = nan
    if cog is not None:
        has_rider = bool(cog[1])
        gx, gy, gz = (float(v) for v in np.asarray(cog[0], dtype=float).reshape(3))
    elif complete:
        pos_k, quat_k = position[idx], quat[idx]
        ok = np.isfinite(pos_k).all(-1) & np.isfinite(quat_k).all(-1)
        if tracked is not None:
            ok &= np.asarray(tracked, dtype=bool)[idx]
        has_rider = bool(ok.all())
        if has_rider:
            g = (frac[:, None] * (pos_k + quat_rotate(quat_k, off))).sum(axis=0) / total
            gx, gy, gz = float(g[0]), float(g[1]), float(g[2])
    cp, sp, ct, st = cos(psi), sin(psi), cos(theta), sin(theta)

    def moving(vx, vy, vz):
        x1, y1 = cp * vx + sp * vy, -sp * vx + cp * vy
        return x1, ct * y1 + st * vz, -st * y1 + ct * vz

    r_cg = moving(gx - cx, gy - cy, gz - cz)
    r_ag = moving(gx - ax, gy - ay, gz - az)
    f64 = np.float64
    return {
        "E": np.array([ex, ey, ez]), "C": np.array([cx, cy, cz]), "A": np.array([ax, ay, az]),
        "G": np.array([gx, gy, gz]), "r_CG": np.array(r_cg), "r_AG": np.array(r_ag),
        "psi": f64(psi), "theta": f64(theta), "gamma": f64(gamma),
        "phi_eq3": f64(math.atan2(r_cg[0], r_cg[2])), "phi_hinge": f64(math.atan2(r_ag[0], r_ag[2])),
        "has_euc": np.bool_(has_euc), "has_rider": np.bool_(has_rider), "n_faults": np.int64(0),
    }


#: Per session and body list, the segments' table (:func:`_segment_table`), kept for the live path's single frames.
_SEGMENT_TABLES: dict = {}


def _segment_table(session, bodies: tuple):
    """The weighted segments in ``bodies``: rows, mass fractions, CoM offsets, the fractions' sum, completeness.

    Completeness: whether every weighted segment is among ``bodies``. Cached per session object and body list.
    """
    key = (id(session), bodies)
    hit = _SEGMENT_TABLES.get(key)
    if hit is not None and hit[0] is session:
        return hit[1]
    names, fractions, offsets = session.segment_arrays()
    weighted = [(n, f, o) for n, f, o in zip(names, fractions, offsets) if f > 0.0]
    present = [(bodies.index(n), f, o) for n, f, o in weighted if n in bodies]
    table = (np.array([j for j, _, _ in present], dtype=int), np.array([f for _, f, _ in present], dtype=float),
             np.array([o for _, _, o in present], dtype=float).reshape(-1, 3), float(fractions[fractions > 0].sum()),
             len(present) == len(weighted) and len(present) > 0)
    if len(_SEGMENT_TABLES) > 64:
        _SEGMENT_TABLES.clear()
    _SEGMENT_TABLES[key] = (session, table)
    return table
