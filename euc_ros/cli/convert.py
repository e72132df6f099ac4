"""`euc-ros convert IN OUT`: Motive CSV -> rosbag2 bag, or bag -> Motive CSV.

CSV -> bag (docs/bags.md): one ``geometry_msgs/msg/PoseStamped`` per rigid body and tracked frame
on ``<prefix>/<Body>/pose`` (Z-up, ``frame_id`` world), optionally ``euc_msgs/msg/MocapFrame`` on
``--frame-topic`` (``--frames``). Header stamps and bag times are the capture times
``start + frame / rate``, where ``start`` is the file's ``Capture Start Time`` read as UTC
(``--start-ns`` overrides it). Such a bag replays into the live pipeline with ``euc-ros play`` and the
``mocap_ingest`` node on ``source: topics``.

Bag -> CSV: the bag's MocapFrame topic if it has one, else its PoseStamped topics (aligned on their
header stamps), written as a Motive CSV export (format 1.23, quaternions, metres) in the Motive
world of ``--world-up``; the capture start time is the one the bag was written with, or estimated
as ``stamp - frame / rate``.

Nothing half-written: the bag is built in a hidden temporary directory next to OUT and renamed
into place at the end, the CSV through a temporary file; on any error neither is left behind, and
an existing OUT is never overwritten.
"""
from __future__ import annotations

import argparse
import os
import re
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

from euc_ros.cli.outputs import Output, check_outputs
from euc_ros.core.errors import InputError
from euc_ros.core.io.bags import read_mocap_bag, write_mocap_bag
from euc_ros.core.mocap.capture_time import capture_start_ns, format_capture_start

HELP = "convert a Motive CSV export to a bag (PoseStamped per body, optional MocapFrame) and back"

#: Stamps must fit builtin_interfaces/Time (int32 seconds) [ns].
MAX_STAMP_NS = 2**31 * 10**9
#: A rigid-body name usable as one token of a ROS topic name.
_TOKEN = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``euc-ros convert``."""
    parser.add_argument("input", help="Motive CSV export (.csv) or rosbag2 bag (directory or .mcap)")
    parser.add_argument("output", help="bag directory to create (from a CSV) or .csv file to write (from a bag); "
                                       "must not exist")
    parser.add_argument("--world-up", choices=("y", "z"), default="y",
                        help="up axis of the Motive world of the CSV (Motive's default: y)")
    parser.add_argument("--prefix", default="/vrpn_mocap", help="PoseStamped topics are PREFIX/<Body>/pose")
    parser.add_argument("--frames", action="store_true",
                        help="CSV -> bag: also write euc_msgs/MocapFrame (keeps the marker errors and frame numbers)")
    parser.add_argument("--no-poses", action="store_true", help="CSV -> bag: no PoseStamped topics (implies --frames)")
    parser.add_argument("--frame-topic", default=None,
                        help="MocapFrame topic to write (default /mocap/frame) or to read (default: the bag's first)")
    parser.add_argument("--bodies", nargs="+", default=None, metavar="BODY", help="only these rigid bodies, in order")
    parser.add_argument("--start-ns", type=int, default=None, metavar="NS",
                        help="CSV -> bag: capture time of frame 0 [ns since the epoch] instead of the file's "
                             "Capture Start Time")
    parser.add_argument("--rate", type=float, default=None, metavar="HZ",
                        help="bag -> CSV: frame rate to write (default: from the bag)")
    parser.add_argument("--chunk-size", type=int, default=1 << 20, metavar="BYTES", help="MCAP chunk size")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")


class _Stages:
    """A progress bar over the conversion's stages (read, write), shown on a terminal after 0.5 s."""

    def __init__(self, args, names) -> None:
        from tqdm import tqdm

        self.bar = tqdm(total=len(names), desc=names[0], unit="step", file=sys.stderr, delay=0.5,
                        disable=True if getattr(args, "no_progress", False) else None)
        self.names = list(names)

    def next(self) -> None:
        self.bar.update(1)
        done = int(self.bar.n)
        if done < len(self.names):
            self.bar.set_description(self.names[done])

    def close(self) -> None:
        self.bar.close()


def _kind(path: Path) -> str:
    if path.is_dir() or path.suffix.lower() == ".mcap":
        return "bag"
    if path.suffix.lower() == ".csv":
        return "csv"
    raise InputError("cannot tell the input kind (expected a .csv file, a bag directory or an .mcap file)", path=path)


def csv_to_bag(src: Path, out: Path, args: argparse.Namespace) -> dict:
    """Convert a Motive CSV into a new bag at ``out`` (atomically); return messages per topic."""
    from euc_ros.core.io.motive_csv import read_motive_csv, require_rigid_bodies

    stages = _Stages(args, ["read CSV", "write bag"])
    series = read_motive_csv(src, world_up=args.world_up, bodies=args.bodies)
    require_rigid_bodies(series, src)
    stages.next()
    poses = not args.no_poses
    frame_topic = (args.frame_topic or "/mocap/frame") if (args.frames or args.no_poses) else None
    if poses:
        bad = [b for b in series.bodies if not _TOKEN.match(b)]
        if bad:
            raise InputError(f"rigid-body names {bad} cannot be ROS topic names ({args.prefix}/<Body>/pose); "
                             "use --no-poses (MocapFrame only) or rename them in Motive", path=src, key="bodies")
    start_ns = args.start_ns if args.start_ns is not None else capture_start_ns(series.meta.get("start_time"))
    if start_ns is None:
        print(f"convert: no readable Capture Start Time in {src}: stamps start at 0 (use --start-ns)")
        start_ns = 0
    end_ns = int(start_ns) + (int(np.ceil(series.t[-1] * 1e9)) if series.n_frames else 0)
    if not 0 <= start_ns or end_ns >= MAX_STAMP_NS:
        raise InputError(f"stamps must lie in [0, 2^31 s) (builtin_interfaces/Time), got start {start_ns} ns, "
                         f"end {end_ns} ns", key="--start-ns")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent))
    try:
        counts = write_mocap_bag(series, tmp / out.name, prefix=args.prefix.rstrip("/"), frame_topic=frame_topic,
                                 start_ns=int(start_ns), poses=poses, chunk_size=args.chunk_size)
        os.rename(tmp / out.name, out)
        stages.next()
    finally:
        stages.close()
        shutil.rmtree(tmp, ignore_errors=True)
    return counts


def bag_to_csv(src: Path, out: Path, args: argparse.Namespace) -> dict:
    """Convert a bag into a new Motive CSV at ``out`` (atomically); return a summary."""
    from euc_ros.core.io.motive_csv import write_motive_csv

    stages = _Stages(args, ["read bag", "write CSV"])
    series = read_mocap_bag(src, prefix=args.prefix.rstrip("/"), frame_topic=args.frame_topic, bodies=args.bodies)
    stages.next()
    if series.n_frames == 0:
        stages.close()
        raise InputError("no mocap frames in the bag", path=src)
    rate = args.rate
    if rate is None:
        rate = float(series.rate_hz)
        if abs(rate - round(rate)) < 1e-3 * rate:   # recorded live: jitter around a whole Motive rate
            rate = float(round(rate))
    if not (np.isfinite(rate) and rate > 0):
        raise InputError(f"cannot tell the frame rate of the bag (got {rate}); use --rate", path=src, key="--rate")
    series.meta["rate_hz"] = rate
    # capture start such that stamp = start + frame / rate (exact for bags written from a CSV)
    stamps = np.round(series.t * 1e9).astype(np.int64) + int(series.meta.get("start_ns", 0))
    start_ns = int(np.median(stamps - np.round(series.frame / rate * 1e9).astype(np.int64)))
    series.meta["start_time"] = format_capture_start(start_ns) if start_ns > 0 else ""
    write_motive_csv(series, out, world_up=args.world_up)
    stages.next()
    stages.close()
    return {"frames": series.n_frames, "bodies": list(series.bodies), "rate_hz": rate,
            "source": series.meta.get("source", "")}


def main(args: argparse.Namespace) -> int:
    """Run the conversion; 0 on success (errors raise InputError: one line, exit code 2)."""
    src, out = Path(args.input), Path(args.output)
    if not src.exists():
        raise InputError("no such file or directory", path=src)
    if out.exists():
        raise InputError("output exists already, not overwriting", path=out)

    check_outputs([Output("output", out, "file" if out.suffix.lower() == ".csv" else "dir")], [src])
    if _kind(src) == "csv":
        if out.suffix.lower() == ".csv":
            raise InputError("CSV -> bag: the output is a bag directory, not a .csv file", path=out)
        counts = csv_to_bag(src, out, args)
        print(f"convert: {src} -> {out}: {sum(counts.values())} messages "
              + ", ".join(f"{t}={n}" for t, n in counts.items()))
    else:
        if out.suffix.lower() != ".csv":
            raise InputError("bag -> CSV: the output must be a .csv file", path=out)
        info = bag_to_csv(src, out, args)
        print(f"convert: {src} -> {out}: {info['frames']} frames of {', '.join(info['bodies'])} "
              f"at {info['rate_hz']:g} Hz (from {info['source']})")
    return 0
