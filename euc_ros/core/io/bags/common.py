"""What the bag modules share.

Message type names, the MCAP magic, the bag directory and its metadata, the checks that make a reader
fail with one line naming the file (not a traceback), and the sequential MCAP scan of the structural
check, recovery and inspection.
"""
from __future__ import annotations

from pathlib import Path

import yaml

from euc_ros.core.errors import InputError

MCAP_MAGIC = b"\x89MCAP0\r\n"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
MOCAP_FRAME = "euc_msgs/msg/MocapFrame"
RIGID_BODIES = "mocap4r2_msgs/msg/RigidBodies"     # the MOCAP4ROS2 drivers: one message per frame


def bag_dir(path) -> Path:
    """The bag directory of a path: the parent of a ``.mcap`` file, else the path itself.

    Parameters
    ----------
    path : str or Path
        Bag directory or its .mcap file.

    Returns
    -------
    Path
        The bag directory.
    """
    p = Path(path)
    return p.parent if p.suffix == ".mcap" else p


def bag_info(bag: Path) -> dict:
    """metadata.yaml's ``rosbag2_bagfile_information`` mapping ({} when unreadable).

    Parameters
    ----------
    bag : Path
        The bag directory.

    Returns
    -------
    dict
        The mapping, or {} when metadata.yaml is missing or unreadable.
    """
    try:
        info = yaml.load((bag / "metadata.yaml").read_text(encoding="utf-8"),
                         Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))["rosbag2_bagfile_information"]
        return info if isinstance(info, dict) else {}
    except (OSError, yaml.YAMLError, KeyError, TypeError):
        return {}


def listed_in_metadata(mcap: Path) -> bool:
    """True when ``mcap`` sits in a bag directory whose metadata.yaml lists it.

    Parameters
    ----------
    mcap : Path
        The MCAP file.

    Returns
    -------
    bool
        Whether its directory's metadata.yaml lists it (True also for a metadata.yaml without the mapping).
    """
    meta = mcap.parent / "metadata.yaml"
    if not meta.is_file():
        return False
    info = bag_info(mcap.parent)
    return mcap.name in [Path(str(f)).name for f in (info.get("relative_file_paths") or [])] or not info


def require_readable_bag(path) -> Path:
    """The bag directory of ``path``, checked for what makes readers fail with a traceback.

    Raises a one-line InputError naming the file and the command that helps: no metadata.yaml, a
    metadata.yaml that is not valid YAML or lacks ``rosbag2_bagfile_information``, a listed MCAP file
    that is missing or truncated (no end magic: the writer was killed).

    Parameters
    ----------
    path : str or Path
        The bag directory or a file in it.

    Returns
    -------
    Path
        The bag directory.

    Raises
    ------
    InputError
        For each of the damages above.
    """
    bag = bag_dir(path)
    meta = bag / "metadata.yaml"
    if not meta.is_file():
        raise InputError(f"no metadata.yaml (the recorder was killed?): `euc-ros recover {bag}` rebuilds a bag from "
                         "the MCAP's complete chunks", path=bag)
    try:
        doc = yaml.safe_load(meta.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        raise InputError(f"not valid YAML ({getattr(exc, 'problem', None) or exc}): `euc-ros recover {bag}` "
                         "rebuilds the bag and its metadata from the MCAP file",
                         path=meta, line=None if mark is None else mark.line + 1) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read: {exc}", path=meta) from None
    info = doc.get("rosbag2_bagfile_information") if isinstance(doc, dict) else None
    if not isinstance(info, dict):
        raise InputError(f"no rosbag2_bagfile_information mapping: `euc-ros recover {bag}` rebuilds the bag and "
                         "its metadata from the MCAP file", path=meta, key="rosbag2_bagfile_information")
    files = info.get("relative_file_paths") or [f.name for f in sorted(bag.glob("*.mcap"))]
    for name in files if isinstance(files, list) else []:
        f = bag / str(name)
        if not f.is_file():
            raise InputError("listed in metadata.yaml but missing", path=f)
        if f.suffix.lower() == ".mcap" and not has_end_magic(f):
            raise InputError(f"truncated MCAP (no footer: the recorder was killed?): `euc-ros recover {bag}` "
                             "rebuilds a bag from its complete chunks", path=f)
    return bag


def has_end_magic(file: Path) -> bool:
    """True when ``file`` ends with the MCAP magic (the writer closed it with a footer).

    Parameters
    ----------
    file : Path
        MCAP file.

    Returns
    -------
    bool
        False when the file is shorter than two magics, lacks the end magic, or cannot be read.
    """
    try:
        with open(file, "rb") as f:
            f.seek(0, 2)
            if f.tell() < 2 * len(MCAP_MAGIC):
                return False
            f.seek(-len(MCAP_MAGIC), 2)
            return f.read(len(MCAP_MAGIC)) == MCAP_MAGIC
    except OSError:
        return False


class McapScan:
    """What a sequential pass over an MCAP file found (possibly truncated)."""

    def __init__(self) -> None:
        self.schemas: dict[int, object] = {}
        self.channels: dict[int, object] = {}
        self.counts: dict[int, int] = {}
        self.span_ns: dict[int, list[int]] = {}       # channel -> [first, last] log time
        self.first_ns: int | None = None
        self.last_ns: int | None = None
        self.n_chunks = 0
        self.n_messages = 0
        self.footer = False
        self.statistics = None
        self.error: str | None = None


def scan_mcap(path: Path, *, keep_messages: bool = False, validate_crcs: bool = True):
    """Parse every record (and every record inside every chunk) of an MCAP file, stopping at damage.

    Returns ``(scan, messages)``; ``messages`` holds ``(channel_id, log_time, data)`` of messages in
    complete chunks when ``keep_messages``.

    Parameters
    ----------
    path : Path
        The MCAP file.
    keep_messages : bool
        Keep the messages of complete chunks.
    validate_crcs : bool
        Check the CRCs of chunks and the data section.

    Returns
    -------
    scan : McapScan
        Schemas, channels, message counts and time spans, and where the damage begins.
    messages : list of tuple
        ``(channel_id, log_time, data)``; empty unless ``keep_messages``.
    """
    from mcap.records import Channel, Chunk, Footer, Message, Schema, Statistics
    from mcap.stream_reader import StreamReader, breakup_chunk

    scan, messages = McapScan(), []

    def take(rec) -> None:
        if isinstance(rec, Schema):
            scan.schemas[rec.id] = rec
        elif isinstance(rec, Channel):
            scan.channels[rec.id] = rec
        elif isinstance(rec, Message):
            scan.n_messages += 1
            scan.counts[rec.channel_id] = scan.counts.get(rec.channel_id, 0) + 1
            span = scan.span_ns.get(rec.channel_id)
            if span is None:
                scan.span_ns[rec.channel_id] = [rec.log_time, rec.log_time]
            elif rec.log_time < span[0]:
                span[0] = rec.log_time
            elif rec.log_time > span[1]:
                span[1] = rec.log_time
            scan.first_ns = rec.log_time if scan.first_ns is None else min(scan.first_ns, rec.log_time)
            scan.last_ns = rec.log_time if scan.last_ns is None else max(scan.last_ns, rec.log_time)
            if keep_messages:
                messages.append((rec.channel_id, rec.log_time, rec.data))

    with open(path, "rb") as f:
        reader = StreamReader(f, emit_chunks=True, validate_crcs=validate_crcs)
        try:
            for rec in reader.records:
                if isinstance(rec, Chunk):
                    inner = breakup_chunk(rec, validate_crc=validate_crcs)   # whole chunk first: all or nothing
                    scan.n_chunks += 1
                    for r in inner:
                        take(r)
                elif isinstance(rec, Statistics):
                    scan.statistics = rec
                elif isinstance(rec, Footer):
                    scan.footer = True
                else:
                    take(rec)
        except Exception as exc:  # mcap raises EndOfFile, struct.error, ValueError... on damaged input
            scan.error = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__
    return scan, messages
