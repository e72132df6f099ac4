"""Files of a simulated ride: the Motive CSV export, the session file and the truth.

The CSV follows the recording-format contract (Motive "Export Tracking Data", format 1.23):
a key/value metadata line, an empty line, the Type / Name / ID / component / axis header rows and one
row per exported frame with, per rigid body, the rotation quaternion (X, Y, Z, W), the position
(X, Y, Z) in metres and the mean marker error. The world is Motive's Y-up by default or Z-up;
occluded bodies are blank cells, dropped frames are missing rows.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from euc_ros.core.worldsim.body import EUC_BODY, SEGMENT_BODIES, poses, quat_from_rotvec, quat_mul

#: Mean marker error written for a tracked body [m] (a plausible value; readers keep it as quality).
MEAN_MARKER_ERROR_M = 0.0002


@dataclass(frozen=True)
class Capture:
    """How the motion-capture system sees the ride.

    Parameters
    ----------
    world_up : {"y", "z"}
        Up axis of the exported world (Motive's default is ``"y"``).
    noise_pos_mm : float
        Standard deviation of the position noise per axis [mm].
    noise_rot_deg : float
        Root-mean-square angle of the rotation noise [deg] (a rotation vector with
        ``noise_rot_deg / sqrt(3)`` per body axis, applied in the body frame).
    drop_rate : float
        Fraction of frames missing from the export (rows absent, the frame numbering skips them).
    occlusions : int
        Number of occlusion gaps (one body blank for a run of frames).
    occlusion_frames : (int, int)
        Range of the length of an occlusion gap [frames].
    decimals : int
        Digits after the decimal point of every value (Motive writes 6).
    flip_quaternion_signs : bool
        Negate the quaternion of random frames (the sign of a quaternion is arbitrary).
    take_name : str
        Take name of the CSV's metadata (and :func:`write_ride`'s default file stem).
    """

    world_up: str = "y"
    noise_pos_mm: float = 0.0
    noise_rot_deg: float = 0.0
    drop_rate: float = 0.0
    occlusions: int = 0
    occlusion_frames: tuple = (2, 20)
    decimals: int = 6
    flip_quaternion_signs: bool = False
    take_name: str = "worldsim"


def to_y_up(position, quat) -> tuple[np.ndarray, np.ndarray]:
    """Z-up (REP-103) positions and quaternions in Motive's Y-up world.

    Notes
    -----
    Motive's axes are ``(X, Y, Z) = (x, z, -y)``, a proper rotation ``P``; vectors map as ``P v`` and
    a rotation's quaternion axis as ``P u``: ``(qx, qy, qz, qw) -> (qx, qz, -qy, qw)``.

    Parameters
    ----------
    position : array_like (..., 3)
        Z-up positions [m].
    quat : array_like (..., 4)
        Z-up quaternions (x, y, z, w).

    Returns
    -------
    position, quat : numpy.ndarray
        The same shapes, in Motive's Y-up world.
    """
    position, quat = np.asarray(position, dtype=float), np.asarray(quat, dtype=float)
    pos = np.stack([position[..., 0], position[..., 2], -position[..., 1]], -1)
    q = np.stack([quat[..., 0], quat[..., 2], -quat[..., 1], quat[..., 3]], -1)
    return pos, q


def capture_poses(position, quat, capture: Capture, rng: np.random.Generator):
    """Add the capture's noise, dropped frames and occlusions to Z-up poses.

    Parameters
    ----------
    position : ndarray (b, n, 3)
    quat : ndarray (b, n, 4)
    capture : Capture
    rng : numpy.random.Generator

    Returns
    -------
    position, quat : ndarray
        Noisy poses, NaN where occluded.
    keep : ndarray (n,) of bool
        Frames present in the export.
    """
    b, n, _ = position.shape
    pos = position + rng.standard_normal(position.shape) * capture.noise_pos_mm * 1e-3
    sigma = np.radians(capture.noise_rot_deg) / np.sqrt(3.0)
    q = quat_mul(quat, quat_from_rotvec(rng.standard_normal(position.shape) * sigma)) if sigma > 0 else quat.copy()
    if capture.flip_quaternion_signs:
        q = q * np.where(rng.random((b, n, 1)) < 0.5, -1.0, 1.0)
    keep = np.ones(n, dtype=bool)
    if capture.drop_rate > 0:
        keep[1:-1] = rng.random(n - 2) >= capture.drop_rate
    lo, hi = capture.occlusion_frames
    for _ in range(capture.occlusions):
        k = int(rng.integers(b))
        length = int(rng.integers(lo, hi + 1))
        start = int(rng.integers(1, max(n - length - 1, 2)))
        pos[k, start:start + length] = np.nan
        q[k, start:start + length] = np.nan
    return pos, q, keep


def _format_column(values: np.ndarray, decimals: int) -> np.ndarray:
    """Fixed-point text of a float column, empty where NaN (vectorized)."""
    text = np.char.mod(f"%.{decimals}f", np.where(np.isfinite(values), values, 0.0))
    return np.where(np.isfinite(values), text, "")


def motive_csv_text(frames, rate_hz: float, bodies, position, quat, capture: Capture) -> str:
    """The text of a Motive 1.23 CSV export (rigid bodies only, quaternions, metres).

    Parameters
    ----------
    frames : ndarray (n,) of int
        Frame numbers of the exported rows.
    rate_hz : float
        Capture and export rate [Hz].
    bodies : sequence of str
        Rigid-body names (IDs are 1, 2, ... in this order).
    position : ndarray (b, n, 3)
        Positions in the export's world [m], NaN where occluded.
    quat : ndarray (b, n, 4)
        Quaternions (X, Y, Z, W) in the export's world, NaN where occluded.
    capture : Capture

    Returns
    -------
    str
        CRLF-free text ending in a newline.
    """
    frames = np.asarray(frames, dtype=np.int64)
    n_total = int(frames[-1] + 1) if frames.size else 0
    meta = ["Format Version", "1.23", "Take Name", capture.take_name, "Take Notes", "",
            "Capture Frame Rate", f"{rate_hz:.6f}", "Export Frame Rate", f"{rate_hz:.6f}",
            "Capture Start Time", "2024-05-02 10.15.00.000 AM", "Capture Start Frame", "0",
            "Total Frames in Take", str(n_total), "Total Exported Frames", str(frames.size),
            "Rotation Type", "Quaternion", "Length Units", "Meters", "Coordinate Space", "Global"]
    per = 8
    types, names, ids, comps, axes = ["", "Type"], ["", "Name"], ["", "ID"], ["", ""], ["Frame", "Time (Seconds)"]
    for k, name in enumerate(bodies):
        types += ["Rigid Body"] * per
        names += [name] * per
        ids += [str(k + 1)] * per
        comps += ["Rotation"] * 4 + ["Position"] * 3 + ["Mean Marker Error"]
        axes += ["X", "Y", "Z", "W", "X", "Y", "Z", ""]
    header = [",".join(meta), "", ",".join(types), ",".join(names), ",".join(ids), ",".join(comps), ",".join(axes)]
    d = capture.decimals
    cols = [frames.astype(str), _format_column(frames / rate_hz, 6)]
    for k in range(len(bodies)):
        tracked = np.isfinite(position[k]).all(-1) & np.isfinite(quat[k]).all(-1)
        for j in range(4):
            cols.append(_format_column(np.where(tracked, quat[k, :, j], np.nan), d))
        for j in range(3):
            cols.append(_format_column(np.where(tracked, position[k, :, j], np.nan), d))
        cols.append(_format_column(np.where(tracked, MEAN_MARKER_ERROR_M, np.nan), d))
    rows = cols[0]
    for c in cols[1:]:
        rows = np.char.add(np.char.add(rows, ","), c)
    return "\n".join(header) + "\n" + "\n".join(rows.tolist()) + "\n"


def session_text(ride, capture: Capture, rate_hz: float) -> str:
    """The session YAML of a ride (docs/session.md), written without a YAML library.

    The segment table and the EUC's values are the generator's own, so the weighted segment centres of
    mass give the model's G exactly (noise-free), and the EUC parameters are the truth.

    Parameters
    ----------
    ride : Ride
        The ride (its plant, rider and placement).
    capture : Capture
        Its ``world_up`` is written.
    rate_hz : float
        Frame rate written as ``rate_hz`` [Hz].

    Returns
    -------
    str
        The YAML text, ending in a newline.
    """
    p, rider, place = ride.spec.plant, ride.spec.rider, ride.spec.place

    def num(v: float) -> str:
        return repr(float(v))

    def vec(v) -> str:
        return "[" + ", ".join(num(x) for x in v) + "]"

    lines = ["# Session of a worldsim ride (independent generator); nominal values are the truth.",
             f"world_up: {capture.world_up}", f"rate_hz: {num(rate_hz)}", "rider:",
             f"  mass: {num(p.m)}          # kg", f"  inertia_pitch: {num(p.J)} # kg m^2, about the rider's CoG",
             "  segments:"]
    for k, name in enumerate(rider.bodies):
        lines.append(f"    {name}: {{mass_fraction: {num(rider.mass_fraction[k])}, "
                     f"com_offset: {vec(rider.com_offset[k])}}}")
    lines += ["euc:", f"  body: {EUC_BODY}", f"  wheel_radius: {num(p.R)}", f"  wheel_mass: {num(p.m_w)}",
              f"  body_mass: {num(p.m_0)}", f"  wheel_inertia: {num(p.J_w)}", f"  body_inertia: {num(p.J_0)}",
              f"  h0: {num(p.h_0)}", f"  l0: {num(p.l_0)}", f"  pivot_to_wheel_center: {vec(-place.euc_top)}"]
    return "\n".join(lines) + "\n"


def truth_dict(ride, frames=None) -> dict:
    """The truth of a ride as plain JSON types: parameters, draws and the state arrays (SI units).

    Parameters
    ----------
    ride : Ride
        The ride.
    frames : array_like of int, optional
        Sample indices to keep (default: all).

    Returns
    -------
    dict
        ``generator``, ``h_m`` [m], ``plant``, ``euc_loop``, ``rider_loop``, ``info``, ``force`` (None
        without a law), ``integrator`` (the ride's stats), ``t`` [s], ``frame`` and each truth array.
    """
    spec = ride.spec
    keep = slice(None) if frames is None else np.asarray(frames)
    arrays = {k: np.asarray(v)[keep].tolist() for k, v in ride.truth.items()}
    return {
        "generator": "euc_ros.core.worldsim",
        "h_m": spec.plant.h,
        "plant": {k: float(v) for k, v in vars(spec.plant).items()},
        "euc_loop": {k: float(v) for k, v in vars(spec.euc).items()},
        "rider_loop": {"K": spec.rider_loop.K.tolist(), "tau": spec.rider_loop.tau,
                       "weights": {k: float(v) for k, v in spec.rider_loop.weights.items()}},
        "info": spec.info,
        "force": spec.force.describe() if spec.force is not None else None,
        "integrator": ride.stats,
        "t": ride.t[keep].tolist(),
        "frame": (np.arange(ride.t.size)[keep]).tolist(),
        **arrays,
    }


def write_ride(ride, out_dir, capture: Capture = Capture(), *, seed: int = 0, name: str | None = None) -> dict:
    """Write ``<name>.csv``, ``session.yaml`` and ``<name>_truth.json`` of a ride into ``out_dir``.

    Parameters
    ----------
    ride : Ride
    out_dir : str or Path
        Created if missing.
    capture : Capture
    seed : int
        Seed of the capture's noise, drops and occlusions.
    name : str, optional
        File stem (default: the capture's take name).

    Returns
    -------
    dict
        Paths ``csv``, ``session``, ``truth``, and ``kept_frames`` (the frames exported).

    Raises
    ------
    ValueError
        ``capture.world_up`` is neither ``"y"`` nor ``"z"``.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    stem = name or capture.take_name
    spec = ride.spec
    rate = 1.0 / float(ride.t[1] - ride.t[0])
    rate = float(np.round(rate, 6))
    tr = ride.truth
    # the wheel starts at the placement's origin at the start of the warm-up; the recording starts after it, so
    # its lab positions are the integrator's travel (a law fixed in the lab is met where the recording says)
    x_lab = np.asarray(tr["x"], float) + float(ride.stats.get("x_offset_m", 0.0))
    pz = poses(x_lab, tr["gamma"], tr["phi"], spec.rider, spec.plant.R, spec.plant.l_0, spec.place)
    rng = np.random.default_rng([int(seed), 7])
    pos, quat, keep = capture_poses(pz["position"], pz["quat"], capture, rng)
    if capture.world_up == "y":
        pos, quat = to_y_up(pos, quat)
    elif capture.world_up != "z":
        raise ValueError(f"world_up must be 'y' or 'z', got {capture.world_up!r}")
    frames = np.flatnonzero(keep)
    text = motive_csv_text(frames, rate, pz["bodies"], pos[:, keep], quat[:, keep],
                           Capture(**{**vars(capture), "take_name": stem}))
    paths = {"csv": out / f"{stem}.csv", "session": out / "session.yaml", "truth": out / f"{stem}_truth.json"}
    paths["csv"].write_text(text, encoding="utf-8")
    paths["session"].write_text(session_text(ride, capture, rate), encoding="utf-8")
    truth = truth_dict(ride)
    truth["capture"] = {k: (list(v) if isinstance(v, tuple) else v) for k, v in vars(capture).items()}
    truth["kept_frames"] = frames.tolist()
    truth["G_world_z_up"] = pz["G"].tolist()
    paths["truth"].write_text(json.dumps(truth), encoding="utf-8")
    return {**paths, "kept_frames": frames}


__all__ = ["Capture", "capture_poses", "motive_csv_text", "session_text", "to_y_up", "truth_dict", "write_ride",
           "SEGMENT_BODIES"]
