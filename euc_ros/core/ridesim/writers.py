"""Files of a simulated ride: Motive CSV (docs/motive_csv.md), session.yaml (docs/session.md), truth, MCAP bag.

Layout of ``write_ride(result, out_dir)``::

    out_dir/
      session.yaml                 nominal session (never the hidden truth), world_up: y
      <maneuver>_01.csv            Motive CSV 1.23, Y-up, one group of 8 columns per rigid body
      ...
      <maneuver>_01_bag/           (with bag=True) rosbag2 MCAP of geometry_msgs/PoseStamped, Z-up
      truth/                       the hidden truth, apart from the recordings (``*.csv`` globs stay safe)
        truth.json                 true h, effects and parameters, seed, per-run list (paths relative
                                   to out_dir)
        <maneuver>_01_truth.csv    true states, accelerations, inputs, h and effect signals per frame

:func:`prepare_ride_dir` refuses a folder that holds anything unless ``overwrite`` is given, and then
only clears a previous ride's own files.

The CSV writer is our own (it does not use the project's reader) and vectorized: the numeric block
is built with numpy and formatted in one pass; untracked samples are blank cells, dropped frames are
missing rows.
"""
from __future__ import annotations

import dataclasses
import io
import json
import shutil
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np

from euc_ros.core.errors import InputError
from euc_ros.core.mocap.series import MocapSeries
from euc_ros.core.ridesim.simulate import RideResult, RunResult
from euc_ros.core.rotations import z_up_to_y_up_position, z_up_to_y_up_quat
from euc_ros.core.session import save_session

#: Capture start of the first run (runs follow at 10 min intervals); also the bag's time base.
CAPTURE_START = datetime(2024, 5, 2, 10, 15, 0, tzinfo=timezone.utc)
#: Minutes between the capture starts of consecutive runs.
RUN_SPACING_MIN = 10
#: Topic prefix of the bag (vrpn_mocap driver convention, docs/bags.md).
TOPIC_PREFIX = "/vrpn_mocap"

TRUTH_COLUMNS = ("t", "frame", "x", "x_dot", "x_ddot", "gamma", "gamma_dot", "gamma_ddot", "phi", "phi_dot",
                 "phi_ddot", "psi", "theta", "M_d", "M_h", "h", "h_dot", "h_ddot", "psi_dot", "a_c", "g_x", "g_z",
                 "v_ref", "F_contact", "tau_wb", "F_aero_x", "F_aero_z", "dQ_x", "dQ_gamma", "dQ_phi",
                 "C_x", "C_y", "C_z", "G_x", "G_y", "G_z")


def _capture_start(index: int) -> datetime:
    return CAPTURE_START + timedelta(minutes=RUN_SPACING_MIN * index)


def _motive_time(dt: datetime) -> str:
    hour12 = dt.hour % 12 or 12
    return f"{dt:%Y-%m-%d} {hour12:02d}.{dt:%M.%S}.{dt.microsecond // 1000:03d} {'AM' if dt.hour < 12 else 'PM'}"


def motive_csv_text(series: MocapSeries, *, total_frames: int | None = None, start: datetime = CAPTURE_START) -> str:
    """A Motive CSV (format 1.23, quaternions, meters, global, Y-up, CRLF like Motive) of a Z-up series.

    Parameters
    ----------
    series : MocapSeries
        Z-up poses (NaN / ``tracked == False`` samples become blank cells).
    total_frames : int, optional
        ``Total Frames in Take`` (default: last frame + 1).
    start : datetime
        Capture start time written in the header.

    Returns
    -------
    str
        The file's text.
    """
    rate = series.rate_hz
    b, n = len(series.bodies), series.n_frames
    total = int(series.frame[-1]) + 1 if total_frames is None else int(total_frames)
    meta = ["Format Version", "1.23", "Take Name", series.name, "Take Notes", "",
            "Capture Frame Rate", f"{rate:.6f}", "Export Frame Rate", f"{rate:.6f}",
            "Capture Start Time", _motive_time(start), "Capture Start Frame", "0",
            "Total Frames in Take", str(total), "Total Exported Frames", str(n),
            "Rotation Type", "Quaternion", "Length Units", "Meters", "Coordinate Space", "Global"]
    groups = [("Rotation", a) for a in "XYZW"] + [("Position", a) for a in "XYZ"] + [("Mean Marker Error", "")]
    names = [f'"{nm}"' if ("," in nm or " " in nm) else nm for nm in series.bodies]
    lines = [",".join(meta), "",
             ",Type," + ",".join(["Rigid Body"] * (8 * b)),
             ",Name," + ",".join(nm for nm in names for _ in groups),
             ",ID," + ",".join(str(i + 1) for i in range(b) for _ in groups),
             ",," + ",".join(g for _ in range(b) for g, _a in groups),
             "Frame,Time (Seconds)," + ",".join(a for _ in range(b) for _g, a in groups)]
    ok = series.tracked[..., None]
    pos = np.where(ok, z_up_to_y_up_position(series.position), np.nan)
    quat = np.where(ok, z_up_to_y_up_quat(series.quat), np.nan)
    err = np.where(series.tracked, series.mean_marker_error, np.nan)
    block = np.concatenate([quat, pos, err[..., None]], axis=-1)  # (b, n, 8)
    data = np.concatenate([series.frame[:, None].astype(float), (series.frame / rate)[:, None],
                           block.transpose(1, 0, 2).reshape(n, 8 * b)], axis=1)
    buf = io.StringIO()
    np.savetxt(buf, data, fmt=["%d"] + ["%.6f"] * (data.shape[1] - 1), delimiter=",", newline="\r\n")
    body = buf.getvalue().replace("nan", "")
    return "\r\n".join(lines) + "\r\n" + body


def write_motive_csv(series: MocapSeries, path: str | Path, **kwargs) -> Path:
    """Write :func:`motive_csv_text` to ``path``; returns the path.

    Parameters
    ----------
    series : MocapSeries
        Z-up poses.
    path : str or Path
        File to write.
    **kwargs
        Passed to :func:`motive_csv_text`.

    Returns
    -------
    Path
        The path written.
    """
    p = Path(path)
    p.write_text(motive_csv_text(series, **kwargs), encoding="utf-8", newline="")
    return p


def truth_table(run: RunResult) -> tuple[tuple[str, ...], np.ndarray]:
    """Columns and (n, k) values of a run's truth CSV (every frame, including dropped ones).

    Parameters
    ----------
    run : RunResult
        The run.

    Returns
    -------
    columns : tuple of str
        Column names.
    values : numpy.ndarray
        Values (n, k), SI units, radians.
    """
    s = run.signals
    cols = {
        "t": run.t, "frame": run.frame.astype(float),
        "x": run.q[:, 0], "x_dot": run.q_dot[:, 0], "x_ddot": run.q_ddot[:, 0],
        "gamma": run.q[:, 1], "gamma_dot": run.q_dot[:, 1], "gamma_ddot": run.q_ddot[:, 1],
        "phi": run.q[:, 2], "phi_dot": run.q_dot[:, 2], "phi_ddot": run.q_ddot[:, 2],
        "psi": run.psi, "theta": run.theta, "M_d": run.M_d, "M_h": run.M_h,
        "h": run.h, "h_dot": run.h_dot, "h_ddot": run.h_ddot, "psi_dot": run.psi_dot,
        **{k: s[k] for k in ("a_c", "g_x", "g_z", "v_ref", "F_contact", "tau_wb", "F_aero_x", "F_aero_z",
                             "dQ_x", "dQ_gamma", "dQ_phi")},
        "C_x": run.C[:, 0], "C_y": run.C[:, 1], "C_z": run.C[:, 2],
        "G_x": run.G[:, 0], "G_y": run.G[:, 1], "G_z": run.G[:, 2],
    }
    assert tuple(cols) == TRUTH_COLUMNS
    return TRUTH_COLUMNS, np.column_stack([np.broadcast_to(np.asarray(v, float), run.t.shape) for v in cols.values()])


def write_truth_csv(run: RunResult, path: str | Path) -> Path:
    """Write a run's truth table as CSV (header row of column names, SI units, radians).

    Parameters
    ----------
    run : RunResult
        The run.
    path : str or Path
        File to write.

    Returns
    -------
    Path
        The path written.
    """
    cols, data = truth_table(run)
    p = Path(path)
    buf = io.StringIO()
    np.savetxt(buf, data, fmt="%.12g", delimiter=",", header=",".join(cols), comments="")
    p.write_text(buf.getvalue(), encoding="utf-8", newline="\n")
    return p


#: CDR (little endian) layout of a geometry_msgs/msg/PoseStamped with frame_id "world": encapsulation
#: header, stamp, string length + "world\0", padding to the 8-byte alignment of the float64 fields
#: (offsets count from the end of the 4-byte encapsulation header), position xyz, orientation xyzw.
_POSE_CDR = np.dtype([("encap", "<u4"), ("sec", "<i4"), ("nanosec", "<u4"), ("len", "<u4"), ("frame_id", "S6"),
                      ("pad", "S6"), ("values", "<f8", (7,))])


def posestamped_cdr_block(stamp_ns: np.ndarray, position: np.ndarray, quat: np.ndarray) -> np.ndarray:
    """Serialized PoseStamped messages (k, 84) uint8 for k stamps [ns], positions and quaternions.

    Vectorized equivalent of ``typestore.serialize_cdr`` for frame_id ``world`` (checked in the tests).

    Parameters
    ----------
    stamp_ns : numpy.ndarray
        Stamps (k,) [ns].
    position : numpy.ndarray
        Positions (k, 3) [m].
    quat : numpy.ndarray
        Quaternions (k, 4), (x, y, z, w).

    Returns
    -------
    numpy.ndarray
        Messages (k, 84), uint8.
    """
    k = stamp_ns.shape[0]
    rec = np.zeros(k, _POSE_CDR)
    rec["encap"] = 0x00000100  # bytes 00 01 00 00: CDR little endian
    rec["sec"] = stamp_ns // 1_000_000_000
    rec["nanosec"] = stamp_ns % 1_000_000_000
    rec["len"] = 6
    rec["frame_id"] = b"world\0"
    rec["values"] = np.concatenate([position, quat], axis=1)
    return rec.view(np.uint8).reshape(k, _POSE_CDR.itemsize)


def write_bag(series: MocapSeries, path: str | Path, start: datetime = CAPTURE_START) -> Path:
    """Write a rosbag2 MCAP directory of ``geometry_msgs/msg/PoseStamped`` on ``/vrpn_mocap/<Body>/pose``.

    Stamps are capture times (``start`` + frame / rate); frame_id ``world``; Z-up; untracked samples
    are not published. Messages are written in time order.

    Parameters
    ----------
    series : MocapSeries
        Z-up poses.
    path : str or Path
        Bag directory to write.
    start : datetime
        Capture start time.

    Returns
    -------
    Path
        The bag directory.

    Raises
    ------
    InputError
        When ``path`` exists and is not a bag directory.
    """
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    p = Path(path)
    if p.exists():
        if (p / "metadata.yaml").exists():
            shutil.rmtree(p)
        else:
            raise InputError("exists and is not a bag directory; remove it or choose another --out", path=p)
    ts = get_typestore(Stores.ROS2_JAZZY)
    msgtype = "geometry_msgs/msg/PoseStamped"
    base_ns = int(start.timestamp()) * 1_000_000_000
    stamps = base_ns + np.round(series.frame * (1e9 / series.rate_hz)).astype(np.int64)
    # (frame, body) pairs in time order, tracked only
    tracked = series.tracked.T  # (n, b)
    k_idx, b_idx = np.nonzero(tracked)
    raw = posestamped_cdr_block(stamps[k_idx], series.position[b_idx, k_idx], series.quat[b_idx, k_idx])
    with Writer(p, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conns = [writer.add_connection(f"{TOPIC_PREFIX}/{b}/pose", msgtype, typestore=ts) for b in series.bodies]
        for row, (k, b) in enumerate(zip(k_idx.tolist(), b_idx.tolist())):
            writer.write(conns[b], int(stamps[k]), raw[row].tobytes())
    return p


#: Folder of the truth files inside a ride folder.
TRUTH_DIR = "truth"


def _ride_files(out: Path) -> list[Path]:
    """The files and folders of a previous ride in ``out`` (what ``write_ride`` writes)."""
    found = [p for p in (out / "session.yaml", out / TRUTH_DIR, out / "truth.json") if p.exists()]
    found += [p for p in out.glob("*.csv") if p.is_file()]
    found += [p for p in out.glob("*_bag") if p.is_dir() and (p / "metadata.yaml").exists()]
    return found


def prepare_ride_dir(out_dir: str | Path, *, overwrite: bool = False, dry_run: bool = False) -> Path:
    """Make ``out_dir`` ready for :func:`write_ride`, never losing files that are not a ride's.

    With ``dry_run`` only the checks run (nothing is deleted or created).

    Parameters
    ----------
    out_dir : str or Path
        The output folder.
    overwrite : bool
        Replace a previous ride.
    dry_run : bool
        Only check.

    Returns
    -------
    Path
        The folder.

    Raises
    ------
    InputError
        ``out_dir`` is a file; or it holds files and ``overwrite`` is False; or, with ``overwrite``,
        it holds files that are not a previous ride's (the message names one).
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError("output path exists and is not a directory", path=out)
    if out.is_dir() and any(out.iterdir()):
        if not overwrite:
            raise InputError("output folder is not empty: give an empty or new folder, or --overwrite to replace "
                             "a previous simulated ride there", path=out)
        ours = _ride_files(out)
        if not (out / "session.yaml").exists() or not ((out / TRUTH_DIR / "truth.json").exists()
                                                       or (out / "truth.json").exists()):
            raise InputError("--overwrite replaces only a previous simulated ride (session.yaml and truth/), "
                             "and this folder is not one: choose another folder", path=out)
        other = sorted(set(out.iterdir()) - set(ours))
        if other:
            raise InputError(f"--overwrite would leave {other[0].name} (not written by simulate-ride) beside the "
                             "new ride: move it or choose another folder", path=out)
        if dry_run:
            return out
        for p in ours:
            shutil.rmtree(p) if p.is_dir() else p.unlink()
    if not dry_run:
        out.mkdir(parents=True, exist_ok=True)
    return out


def write_ride(result: RideResult, out_dir: str | Path, *, bag: bool = False, overwrite: bool = False,
               progress=None) -> list[Path]:
    """Write a simulated ride to ``out_dir`` (created if missing); returns the written paths.

    Writes ``session.yaml`` (nominal values, ``world_up: y``), per run the Motive CSV, with
    ``bag=True`` one MCAP bag directory per run, and the truth (``truth/truth.json``, per run
    ``truth/<run>_truth.csv``). ``out_dir`` must be new or empty, or hold a previous ride and
    ``overwrite`` be given (:func:`prepare_ride_dir`). ``progress(iterable)`` wraps the runs.

    Parameters
    ----------
    result : RideResult
        The ride.
    out_dir : str or Path
        The output folder.
    bag : bool
        Also write a bag per run.
    overwrite : bool
        Replace a previous ride.
    progress : callable, optional
        Wraps the iterable of runs (a progress bar).

    Returns
    -------
    list of Path
        The paths written.

    Raises
    ------
    InputError
        When ``out_dir`` cannot be used (:func:`prepare_ride_dir`).
    """
    out = prepare_ride_dir(out_dir, overwrite=overwrite)
    (out / TRUTH_DIR).mkdir()
    written = []
    session = dataclasses.replace(result.session, world_up="y")
    save_session(session, out / "session.yaml")
    written.append(out / "session.yaml")
    runs = list(enumerate(result.runs))
    for k, run in (progress(runs) if progress else runs):
        start = _capture_start(k)
        written.append(write_motive_csv(run.mocap, out / f"{run.name}.csv", total_frames=run.t.size, start=start))
        written.append(write_truth_csv(run, out / TRUTH_DIR / f"{run.name}_truth.csv"))
        if bag:
            written.append(write_bag(run.mocap, out / f"{run.name}_bag", start=start))
    truth = result.truth_dict()
    truth["capture_start_utc"] = [_capture_start(k).isoformat() for k in range(len(result.runs))]
    truth["truth_columns"] = list(TRUTH_COLUMNS)
    (out / TRUTH_DIR / "truth.json").write_text(json.dumps(truth, indent=2) + "\n", encoding="utf-8")
    written.append(out / TRUTH_DIR / "truth.json")
    return written
