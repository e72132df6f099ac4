"""State reconstruction: from rigid-body poses to the planar model's states (EUC paper, Section 2).

Per frame (:func:`frame_geometry`, vectorized over any number of frames, so the same code serves a
live frame and a whole recording):

* EUC pivot ``E`` and orientation ``R_E = Rz(psi) Rx(theta) Ry(gamma)`` (yaw, tilt, pitch, Fig. 2);
* wheel centre ``C = E + R_E @ pivot_to_wheel_center`` (spec section 3);
* ankle hinge ``A = C - l0 R_E e_z`` (``l0`` below C along the EUC body axis, Fig. 5);
* segment centres of mass ``pivot + R_body @ com_offset`` and the rider CoG
  ``G = sum_i f_i CoM_i`` (mass fractions ``f_i``, sum 1). A frame in which any segment of non-zero
  mass is untracked has no G (``has_rider`` False, NaN);
* the moving frame ``T = Rz(psi) Rx(theta)`` of eqs (1)-(2): ``r_CG = T^T (G - C)``, and
  ``phi_eq3 = arctan(x_CG / z_CG)`` (eq (3), the angle of G seen from the wheel centre C);
* ``phi_hinge``: the same angle seen from the ankle hinge A, ``r_AG = T^T (G - A)``. This is the
  model's own rider pitch (the line A-G of Fig. 5) and the default for identification.

Over a recording (:func:`reconstruct_states`), the pitch angles and the wheel centre are smoothed and
differentiated with the Savitzky-Golay filter (:mod:`euc_ros.core.filters.derivatives`), split on
occlusion gaps. The longitudinal speed and acceleration follow the paper: ``v_C`` and ``a_C`` are the
ground-frame derivatives of ``R_C``, and ``x_dot = e_x . v_C``, ``x_ddot = e_x . a_C`` with the
moving frame's forward axis ``e_x = T e_1 = (cos psi, sin psi, 0)`` (the tilt rotates about e_x, so
only the yaw matters). Note that ``x_ddot`` so defined is the longitudinal component of ``a_C``, not
the time derivative of ``x_dot``: they differ by ``psi_dot (e_y . v_C)``, which vanishes when C moves
along the heading; we follow the paper.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from euc_ros.core.errors import ConfigError, InputError
from euc_ros.core.bridging import bridge_series
from euc_ros.core.euc.blockwise import block_geometry, materialize
from euc_ros.core.filters.derivatives import DEFAULT_MAX_GAP, savgol_derivatives, trim_edges
from euc_ros.core.euc.skeleton_fit import COG_METHODS, SkeletonModel, skeleton_cog
from euc_ros.core.rotations import rotation_matrices, yaw_tilt_pitch_from_quat

#: Default Savitzky-Golay window [s] and polynomial order, chosen by measurement on simulated rides
#: with the paper's noise level (0.2 mm, 0.5 deg per frame), on the interior samples of each stretch:
#: the bias of h and of inertia-type parameters against the window is tabulated in
#: docs/identification.md.
DEFAULT_WINDOW_S = 1.2
DEFAULT_SG_POLYORDER = 6
#: Rider pitch definitions: about the ankle hinge A (the model's) or about the wheel centre C (eq (3)).
PHI_DEFINITIONS = ("hinge", "eq3")


def to_moving_frame(v, psi, theta) -> np.ndarray:
    """Express world vectors in the moving frame of eqs (1)-(2): ``T_theta^T T_psi^T v``.

    Parameters
    ----------
    v : array_like (..., 3)
        World (Z-up) vectors [m].
    psi, theta : array_like (...)
        Yaw and tilt [rad].
    """
    v = np.asarray(v, dtype=float)
    cp, sp = np.cos(psi), np.sin(psi)
    ct, st = np.cos(theta), np.sin(theta)
    x1 = cp * v[..., 0] + sp * v[..., 1]
    y1 = -sp * v[..., 0] + cp * v[..., 1]
    z1 = v[..., 2]
    return np.stack([x1, ct * y1 + st * z1, -st * y1 + ct * z1], axis=-1)


def _rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate the body vectors ``v`` (..., 3) by quaternions ``q`` (..., 4) (x, y, z, w), normalised here.

    ``v' = v + 2 w (u x v) + 2 u x (u x v)`` with ``u = (x, y, z)``; NaN quaternions give NaN. The
    cross products are written out (``np.cross`` costs more than the arithmetic on one frame).
    """
    q = q / np.sqrt(np.einsum("...i,...i->...", q, q))[..., None]
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    vx, vy, vz = v[..., 0], v[..., 1], v[..., 2]
    tx, ty, tz = 2.0 * (y * vz - z * vy), 2.0 * (z * vx - x * vz), 2.0 * (x * vy - y * vx)
    return np.stack([vx + w * tx + (y * tz - z * ty), vy + w * ty + (z * tx - x * tz),
                     vz + w * tz + (x * ty - y * tx)], axis=-1)


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
        the kinematic chain fitted to the poses (:mod:`~euc_ros.core.euc.skeleton_fit`); bodies
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
    if shape == () and cog_method == "segments" and position.shape == (len(bodies), 3) \
            and quat.shape == (len(bodies), 4):
        return _one_frame_geometry(position, quat, tracked, session, bodies)
    tracked = None if tracked is None else np.asarray(tracked, dtype=bool)

    def usable(i: int) -> np.ndarray:
        ok = np.isfinite(position[i]).all(-1) & np.isfinite(quat[i]).all(-1)
        return ok if tracked is None else ok & tracked[i]

    nan3 = np.full(shape + (3,), np.nan)

    euc = session.euc
    if euc.body in bodies:
        i = bodies.index(euc.body)
        has_euc = usable(i)
        E = np.where(has_euc[..., None], position[i], np.nan)
        qE = np.where(has_euc[..., None], quat[i], np.nan)
    else:
        has_euc = np.zeros(shape, dtype=bool)
        E, qE = nan3.copy(), np.full(shape + (4,), np.nan)
    R_E = rotation_matrices(qE)
    ang = yaw_tilt_pitch_from_quat(qE)
    psi, theta, gamma = ang[..., 0], ang[..., 1], ang[..., 2]
    C = E + R_E @ np.asarray(euc.pivot_to_wheel_center, dtype=float)
    A = C - euc.l0 * R_E[..., :, 2]

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
        com = pos_k + _rotate(quat_k, off)
        w = frac.reshape((-1,) + (1,) * (len(shape) + 1))
        G = np.where(ok_k[..., None], w * com, 0.0).sum(axis=0)
        has_rider &= ok_k.all(axis=0)
    G = np.where(has_rider[..., None], G / fractions[fractions > 0].sum(), np.nan)
    n_faults = np.zeros(shape, dtype=int)
    if cog_method == "skeleton":
        if skeleton is None:
            skeleton = SkeletonModel.from_poses([position.reshape(len(bodies), -1, 3)],
                                                [quat.reshape(len(bodies), -1, 4)],
                                                [None if tracked is None else tracked.reshape(len(bodies), -1)],
                                                bodies, session)
        sk = skeleton_cog(position, quat, tracked, session, bodies, skeleton, threshold_m=fault_threshold_m)
        G, has_rider, n_faults = sk["G"], sk["has_rider"], sk["n_faults"]
        per_body = sk["faults"].reshape(len(skeleton.bodies), -1).sum(axis=1)
        linked = {b for link in skeleton.links for b in link}
        extra = {"cog_fault_bodies": {nm: int(c) for nm, c in zip(skeleton.bodies, per_body) if c},
                 "cog_unlinked_bodies": [nm for nm in skeleton.bodies if nm not in linked]}
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


def _one_frame_geometry(position: np.ndarray, quat: np.ndarray, tracked, session, bodies: list) -> dict:
    """:func:`frame_geometry` of one frame with ``segments`` G, in scalar arithmetic.

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
    if complete:
        pos_k, quat_k = position[idx], quat[idx]
        ok = np.isfinite(pos_k).all(-1) & np.isfinite(quat_k).all(-1)
        if tracked is not None:
            ok &= np.asarray(tracked, dtype=bool)[idx]
        has_rider = bool(ok.all())
        if has_rider:
            g = (frac[:, None] * (pos_k + _rotate(quat_k, off))).sum(axis=0) / total
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


_SEGMENT_TABLES: dict = {}


def _segment_table(session, bodies: tuple):
    """Rows, mass fractions, CoM offsets of the weighted segments in ``bodies``, the fractions' sum,
    and whether every weighted segment is among ``bodies`` (cached per session object and body list)."""
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


@dataclass
class RiderStates:
    """States of the planar model over a recording, with their derivatives (SI units, radians).

    Attributes
    ----------
    name : str
        Recording name.
    t : ndarray (n,)
        Time [s].
    frame : ndarray (n,) of int
        Frame numbers.
    x, x_dot, x_ddot : ndarray (n,)
        Forward distance travelled by C [m] (integral of ``x_dot``), longitudinal speed [m/s] and
        acceleration [m/s^2] of C (Section 2: longitudinal components of ``v_C``, ``a_C``).
    gamma, gamma_dot, gamma_ddot : ndarray (n,)
        EUC body pitch (smoothed) and its derivatives [rad, rad/s, rad/s^2].
    phi, phi_dot, phi_ddot : ndarray (n,)
        Rider pitch of the chosen definition (smoothed) and its derivatives.
    phi_eq3, phi_hinge : ndarray (n,)
        Both rider pitch definitions, unsmoothed [rad].
    psi, theta : ndarray (n,)
        EUC yaw (unwrapped) and tilt [rad], unsmoothed.
    C, G : ndarray (n, 3)
        Wheel centre (smoothed) and rider CoG (unsmoothed) [m], Z-up world.
    has_euc, has_rider : ndarray (n,) of bool
        E tracked; all rider segments of non-zero mass tracked.
    valid : ndarray (n,) of bool
        Every state and derivative finite and measured (not filled across a short gap), and at least
        half a filter window inside its gap-free stretch (the Savitzky-Golay ends extrapolate; the
        online fixed-lag filter gives no state there either).
    phi_definition : str
        ``"hinge"`` or ``"eq3"``.
    cog_method : str
        ``"segments"`` or ``"skeleton"`` (see :func:`frame_geometry`); with ``skeleton``,
        ``meta["cog_faults"]`` counts the body-frames excluded from G and ``meta["cog_fault_bodies"]``
        splits them per body.
    window, polyorder : int
        Savitzky-Golay window [samples] and order used.
    dt : float
        Sample spacing [s].
    """

    name: str
    t: np.ndarray
    frame: np.ndarray
    x: np.ndarray
    x_dot: np.ndarray
    x_ddot: np.ndarray
    gamma: np.ndarray
    gamma_dot: np.ndarray
    gamma_ddot: np.ndarray
    phi: np.ndarray
    phi_dot: np.ndarray
    phi_ddot: np.ndarray
    phi_eq3: np.ndarray
    phi_hinge: np.ndarray
    psi: np.ndarray
    theta: np.ndarray
    C: np.ndarray
    G: np.ndarray
    has_euc: np.ndarray
    has_rider: np.ndarray
    valid: np.ndarray
    phi_definition: str = "hinge"
    cog_method: str = "segments"
    window: int = 0
    polyorder: int = DEFAULT_SG_POLYORDER
    dt: float = float("nan")
    meta: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.t.shape[0])

    def torque_args(self, mask=None) -> tuple[np.ndarray, ...]:
        """Return ``(gamma, phi, gamma_dot, phi_dot, x_ddot, gamma_ddot, phi_ddot)`` for :func:`~.torque.torques`.

        Parameters
        ----------
        mask : ndarray of bool, optional
            Samples to keep (default: all, including invalid ones as NaN).
        """
        arrs = (self.gamma, self.phi, self.gamma_dot, self.phi_dot, self.x_ddot, self.gamma_ddot, self.phi_ddot)
        return arrs if mask is None else tuple(a[mask] for a in arrs)


def reconstruct_states(series, session, *, phi_definition: str = "hinge", window_s: float = DEFAULT_WINDOW_S,
                       polyorder: int = DEFAULT_SG_POLYORDER, max_gap: int = DEFAULT_MAX_GAP,
                       cog_method: str = "segments", skeleton: SkeletonModel | None = None) -> RiderStates:
    """Reconstruct the planar model's states and derivatives from a motion-capture recording.

    Parameters
    ----------
    series : MocapSeries
        Z-up poses of the EUC body and the rider segments.
    session : Session
        The recording's session file.
    phi_definition : {"hinge", "eq3"}
        Rider pitch about the ankle hinge A (the model's definition, default) or about the wheel
        centre C (eq (3) of the paper).
    window_s : float
        Savitzky-Golay window [s].
    polyorder : int
        Savitzky-Golay polynomial order.
    max_gap : int
        Longest run of missing frames bridged by interpolation (those samples stay invalid).
    cog_method : {"segments", "skeleton"}
        Rider CoG from the measured segments or from the fitted chain (:func:`frame_geometry`).
    skeleton : SkeletonModel, optional
        The session's chain (default: estimated from this recording).

    Returns
    -------
    RiderStates

    Raises
    ------
    InputError
        If the recording lacks the EUC body or a rider segment of non-zero mass altogether.
    ConfigError
        For an unknown ``phi_definition`` or bad filter settings.
    """
    if phi_definition not in PHI_DEFINITIONS:
        raise ConfigError(f"phi definition must be one of {PHI_DEFINITIONS}, got {phi_definition!r}",
                          key="phi_definition")
    if cog_method not in COG_METHODS:
        raise ConfigError(f"cog method must be one of {COG_METHODS}, got {cog_method!r}", key="cog_method")
    src = series.meta.get("path", series.name or None)
    if session.euc.body not in series.bodies:
        raise InputError(f"EUC rigid body {session.euc.body!r} not in recording (has: {', '.join(series.bodies)})",
                         path=src)
    names, fractions, _ = session.segment_arrays()
    absent = [nm for nm, f in zip(names, fractions) if f > 0 and nm not in series.bodies]
    if absent:
        extra = [b for b in series.bodies if b not in names and b != session.euc.body]
        hint = (f"; bodies the session does not name: {', '.join(extra)} (rename the segment keys of "
                f"rider.segments to the recording's Motive names)") if extra else ""
        raise InputError(f"rider segment(s) {', '.join(absent)} of the session not in recording (has: "
                         f"{', '.join(series.bodies)}){hint}", path=src, key="rider.segments")
    dt = 1.0 / series.rate_hz
    # each body's short gaps are bridged before any geometry (as the live estimator does); for the
    # segments CoG block by block (blockwise.block_geometry: no copy of the whole recording)
    if cog_method == "skeleton":
        series, bridged = bridge_series(materialize(series), max_gap)
        if skeleton is None:
            skeleton = SkeletonModel.estimate([series], session)
        geo = frame_geometry(series.position, series.quat, series.tracked, session, series.bodies,
                             cog_method=cog_method, skeleton=skeleton)
        n_bridged, n_bridged_frames = int(bridged.sum()), int(bridged.any(axis=0).sum())
    else:
        geo, n_bridged, n_bridged_frames = block_geometry(series, session, max_gap)
    frame = np.asarray(series.frame, dtype=np.int64)
    sg = dict(window_s=window_s, polyorder=polyorder, max_gap=max_gap, frame=frame)
    # Order for memory: each filter input is dropped from ``geo`` once filtered (those the states do not
    # keep) and the wheel centre's derivatives once reduced to x_dot and x_ddot, so the working set
    # beyond the states is at most one filter's. The numbers are those of any other order.
    n_faults = int(geo.pop("n_faults").sum())
    d_C = savgol_derivatives(dt, geo.pop("C"), **sg)
    psi = geo["psi"].copy()
    fin = np.isfinite(psi)
    if fin.any():
        psi[fin] = np.unwrap(psi[fin])
    # Heading of the bridged frames (a body missing for at most max_gap frames): interpolated like the
    # filter interpolates gamma and C, so a blank frame costs that frame only (as live), not the
    # half-windows on both sides of a NaN that would split the stretch.
    psi_x = geo["psi"].copy()
    gap = ~fin & d_C.filled
    if gap.any() and fin.sum() >= 2:
        psi_x[gap] = np.interp(frame[gap], frame[fin], psi[fin])
    del gap, fin
    cx, sx = np.cos(psi_x), np.sin(psi_x)          # e_x = (cos psi, sin psi)
    del psi_x
    x_dot = cx * d_C.y_dot[:, 0] + sx * d_C.y_dot[:, 1]
    x_ddot = cx * d_C.y_ddot[:, 0] + sx * d_C.y_ddot[:, 1]
    del cx, sx
    C, filled = d_C.y, d_C.filled.copy()
    del d_C                                        # its (n, 3) y_dot and y_ddot
    t = np.asarray(series.t, dtype=float)
    xd0 = np.where(np.isfinite(x_dot), x_dot, 0.0)
    x = np.concatenate(([0.0], np.cumsum(0.5 * (xd0[1:] + xd0[:-1]) * np.diff(t)))) if t.size else t.copy()
    del xd0
    x[~np.isfinite(x_dot)] = np.nan
    d_gamma = savgol_derivatives(dt, geo.pop("gamma"), **sg)
    phi_raw = geo["phi_hinge"] if phi_definition == "hinge" else geo["phi_eq3"]
    d_phi = savgol_derivatives(dt, phi_raw, **sg)
    filled |= d_gamma.filled
    filled |= d_phi.filled
    fields_ = (x_dot, x_ddot, d_gamma.y, d_gamma.y_dot, d_gamma.y_ddot, d_phi.y, d_phi.y_dot, d_phi.y_ddot)
    # measured samples at least half a window inside their stretch (where the SG fit interpolates);
    # the fields' finiteness and-ed one at a time (no (8, n) stack of the fields)
    finite = np.isfinite(fields_[0])
    for f in fields_[1:]:
        finite &= np.isfinite(f)
    valid = trim_edges(finite, d_gamma.window // 2, frame, max_gap) & ~filled
    return RiderStates(
        name=series.name, t=t, frame=frame, x=x, x_dot=x_dot, x_ddot=x_ddot,
        gamma=d_gamma.y, gamma_dot=d_gamma.y_dot, gamma_ddot=d_gamma.y_ddot,
        phi=d_phi.y, phi_dot=d_phi.y_dot, phi_ddot=d_phi.y_ddot,
        phi_eq3=geo["phi_eq3"], phi_hinge=geo["phi_hinge"], psi=psi, theta=geo["theta"],
        C=C, G=geo["G"], has_euc=geo["has_euc"], has_rider=geo["has_rider"], valid=valid,
        phi_definition=phi_definition, cog_method=cog_method, window=d_gamma.window, polyorder=polyorder, dt=dt,
        meta={"source": src, "bridged_samples": n_bridged,
              "bridged_frames": n_bridged_frames, "cog_faults": n_faults,
              **({"cog_fault_bodies": geo["cog_fault_bodies"]} if "cog_fault_bodies" in geo else {}),
              **({"cog_unlinked_bodies": geo["cog_unlinked_bodies"]} if geo.get("cog_unlinked_bodies") else {})},
    )
