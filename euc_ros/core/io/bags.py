"""rosbag2 bags with MCAP storage, without rosbag2_py: write, read, check, recover, mocap series.

ROS-free (rosbags + mcap + mcap-ros2-support + numpy). The layout is rosbag2's: a directory holding
``metadata.yaml`` (version 9, as ROS 2 Jazzy writes and reads it) and one ``<name>.mcap`` file with
a ``ros2msg`` schema per type and CDR messages. The project's own types (euc_msgs) are registered
from their ``.msg`` files (:mod:`euc_ros.core.io.msgdefs`), so their RIHS01 hashes equal rclpy's.

Contents
--------
* :class:`BagWriter` - lazy connections, raw or message writes, always closes what it wrote.
* :func:`read_bag` - iterate ``(topic, msgtype, stamp_ns, msg)`` through rosbags' AnyReader.
* :func:`check_bag` - structural check (metadata.yaml as Jazzy's decoder reads it, MCAP magic,
  summary, every record of every chunk, counts, decoding with mcap-ros2-support).
* :func:`recover_bag` - rebuild a valid bag from the complete chunks of a truncated MCAP.
* :func:`inspect_bag` - what a bag holds, with the check's problems.
* :func:`read_mocap_bag`, :func:`write_mocap_bag` - :class:`~euc_ros.core.mocap.series.MocapSeries` from/to
  ``euc_msgs/msg/MocapFrame`` and/or one ``geometry_msgs/msg/PoseStamped`` per body (docs/bags.md).

See ``docs/bags.md``.
"""
from __future__ import annotations

import io
import logging
import os
import re
import struct
import sys
import tempfile
from collections import defaultdict
from collections.abc import Iterator
from itertools import chain
from pathlib import Path

import numpy as np
import yaml

from euc_ros.core.errors import InputError
from euc_ros.core.io.cdr import ENCAPSULATION_LE, HEAD, pad, split_stamp
from euc_ros.core.io.mcap_fast import McapFile
from euc_ros.core.io.msgdefs import make_typestore
from euc_ros.core.mocap.message_frames import frame_from_named_poses
from euc_ros.core.mocap.series import MocapSeries

log = logging.getLogger(__name__)

#: rosbag2 metadata version written (ROS 2 Jazzy's).
METADATA_VERSION = 9
#: Newest metadata version ROS 2 Jazzy decodes.
JAZZY_MAX_VERSION = 9
#: Default MCAP chunk size [bytes]; rosbags 0.11.9 closes a chunk past 1 MiB whatever is asked.
DEFAULT_CHUNK_SIZE = 1 << 20
MCAP_MAGIC = b"\x89MCAP0\r\n"
#: rosbags 0.11.9 closes a chunk once it holds more than this [bytes].
_ROSBAGS_CHUNK_LIMIT = 1 << 20
#: MCAP Message record head: opcode, record length, channel id, sequence, log time, publish time.
_MESSAGE_RECORD = struct.Struct("<BQHIQQ")
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
MOCAP_FRAME = "euc_msgs/msg/MocapFrame"
RIGID_BODIES = "mocap4r2_msgs/msg/RigidBodies"     # the MOCAP4ROS2 drivers: one message per frame
#: MocapFrame.stamp_source value for offline data (capture start + frame / rate).
STAMP_FILE_TIME = 1
#: custom_data keys write_mocap_bag stores in metadata.yaml to make the round trip exact.
CUSTOM_START_NS = "euc_ros.start_ns"
CUSTOM_RATE_HZ = "euc_ros.rate_hz"
CUSTOM_NAME = "euc_ros.name"


def _bag_dir(path) -> Path:
    p = Path(path)
    return p.parent if p.suffix == ".mcap" else p


# =====================================================================================================================
# Writing
# =====================================================================================================================

def _ensure_type(typestore, msgtype: str, msgdef: str | None = None) -> None:
    """Make ``msgtype`` known to ``typestore``: from ``msgdef`` text, or from an installed ``.msg`` file.

    Installed definitions are looked up as ``<prefix>/share/<pkg>/msg/<Name>.msg`` for ``sys.prefix``
    and every ``AMENT_PREFIX_PATH`` entry; their dependencies are resolved the same way.
    """
    from rosbags.typesys import get_types_from_msg

    if msgtype in typestore.types:
        return
    if msgdef is not None:
        typestore.register(get_types_from_msg(msgdef, msgtype))
        return
    pending, seen = [msgtype], set()
    while pending:
        name = pending.pop()
        if name in typestore.types or name in seen:
            continue
        seen.add(name)
        parts = name.split("/")
        if len(parts) != 3:
            raise InputError(f"not a full message type name: {name!r} (expected pkg/msg/Name)", key="msgtype")
        pkg, kind, base = parts
        prefixes = [sys.prefix] + [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
        for prefix in prefixes:
            f = Path(prefix) / "share" / pkg / kind / f"{base}.msg"
            if f.is_file():
                types = get_types_from_msg(f.read_text(encoding="utf-8"), name)
                typestore.register(types)
                for _, fields in types.values():
                    pending += _nested_type_names(fields)
                break
        else:
            raise InputError(f"no definition for message type {name} (not in the Jazzy typestore, not installed "
                             f"under {', '.join(prefixes)})", key="msgtype")


def _nested_type_names(fields) -> list[str]:
    """Full type names referenced by rosbags field definitions (for dependency resolution)."""
    out = []
    for _, (kind, spec) in fields:
        inner = spec
        if kind.name in ("ARRAY", "SEQUENCE"):
            inner = spec[0]
        if isinstance(inner, tuple) and getattr(inner[0], "name", "") == "NAME":
            out.append(inner[1])
        elif isinstance(inner, str):
            out.append(inner)
    return out


class BagWriter:
    """Write a rosbag2 bag (metadata v9, MCAP storage) through rosbags.

    Connections are registered lazily, one per ``(topic, msgtype)``, with the definition and RIHS01
    hash from the typestore (the Jazzy store plus euc_msgs by default; other installed packages are
    looked up under ``share/<pkg>/msg``).

    The writer never aborts: on an exception inside ``with BagWriter(...)``, what was written is
    closed into a valid bag and the exception propagates. (rosbags' own ``Writer.__exit__`` aborts,
    leaving a headless .mcap and no metadata.yaml.)

    Parameters
    ----------
    path : str or Path
        Bag directory to create; must not exist.
    typestore : rosbags Typestore, optional
        Default: :func:`euc_ros.core.io.msgdefs.make_typestore`.
    chunk_size : int
        Close the current MCAP chunk once it holds this many bytes [bytes]. Completed chunks are
        flushed to the OS, so a recorder killed with SIGKILL loses at most one chunk (plus the
        summary, which :func:`recover_bag` rebuilds). Smaller chunks lose less but cost an index
        record per chunk and per channel (~100 bytes) and compress worse. rosbags 0.11.9 closes
        chunks past 1 MiB on its own, so larger values act as 1 MiB.
    custom_data : dict of str to str, optional
        Stored in metadata.yaml ``custom_data``.

    Attributes
    ----------
    counts : dict of str to int
        Messages written per topic.
    """

    def __init__(self, path, typestore=None, *, chunk_size: int = DEFAULT_CHUNK_SIZE,
                 custom_data: dict | None = None) -> None:
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.rosbag2.errors import WriterError

        self.path = Path(path)
        if self.path.exists():
            raise InputError("bag exists already, not overwriting (choose a new output path)", path=self.path)
        if int(chunk_size) <= 0:
            raise InputError(f"chunk_size must be > 0, got {chunk_size}", key="chunk_size")
        self.chunk_size = int(chunk_size)
        self.typestore = typestore if typestore is not None else make_typestore()
        self.counts: dict[str, int] = {}
        self._connections: dict[tuple[str, str], object] = {}
        self._writer = Writer(self.path, version=METADATA_VERSION, storage_plugin=StoragePlugin.MCAP)
        for key, value in (custom_data or {}).items():
            self._writer.set_custom_data(str(key), str(value))
        try:
            self._writer.open()
        except (WriterError, OSError) as exc:
            raise InputError(f"cannot create bag: {exc}", path=self.path) from None
        self._closed = False
        self._n_chunks = 0
        self._fast: bool | None = None
        storage = self._writer.storage
        self._chunk_control = all(hasattr(storage, a) for a in ("chunk", "chunks", "close_chunk", "bio"))
        if not self._chunk_control:
            log.warning("rosbags MCAP writer internals changed: chunk_size %d ignored", self.chunk_size)

    # -- connections -----------------------------------------------------------------------------------------------
    def connection(self, topic: str, msgtype: str, *, msgdef: str | None = None, rihs01: str | None = None,
                   offered_qos_profiles=()):
        """Return the connection of ``(topic, msgtype)``, adding it on first use.

        Parameters
        ----------
        topic, msgtype : str
        msgdef : str, optional
            ``ros2msg`` definition text (with dependencies) for types the typestore does not know.
        rihs01 : str, optional
            Type hash to store with ``msgdef``; computed from the typestore when omitted.
        offered_qos_profiles : sequence of rosbags Qos
        """
        key = (topic, msgtype)
        conn = self._connections.get(key)
        if conn is None:
            if self._closed:
                raise InputError("bag is closed", path=self.path)
            _ensure_type(self.typestore, msgtype, msgdef)
            if msgdef is not None and rihs01 is None:
                rihs01 = self.typestore.hash_rihs01(msgtype)
            conn = self._writer.add_connection(topic, msgtype, typestore=self.typestore, msgdef=msgdef,
                                               rihs01=rihs01, offered_qos_profiles=list(offered_qos_profiles))
            self._connections[key] = conn
            self.counts.setdefault(topic, 0)
        return conn

    # -- writing ---------------------------------------------------------------------------------------------------
    def write_raw(self, topic: str, msgtype: str, data: bytes, stamp_ns: int) -> None:
        """Write one serialized (CDR) message with receive time ``stamp_ns`` [ns since the epoch]."""
        conn = self.connection(topic, msgtype)
        self._writer.write(conn, int(stamp_ns), data)
        self.counts[topic] += 1
        if self._chunk_control:
            storage = self._writer.storage
            if storage.chunk.bio.tell() >= self.chunk_size:
                _close_chunk(storage) if self._fast_batch() else storage.close_chunk()
            if len(storage.chunks) != self._n_chunks:   # a chunk completed (here or in rosbags): to the OS
                self._n_chunks = len(storage.chunks)
                storage.bio.flush()

    def write_raw_many(self, topic: str, msgtype: str, datas, stamp_ns) -> None:
        """Write several serialized (CDR) messages of one topic, in order: the bytes :meth:`write_raw` writes.

        ``stamp_ns`` is one receive time for all [ns since the epoch] or a sequence of one per message.
        The same file as that many :meth:`write_raw` calls (records, message indexes, chunk boundaries
        and statistics), at a fraction of the cost per message: the MCAP message records are packed
        here instead of through rosbags' per-message writer (~4x faster; a recorder's batch).
        """
        conn = self.connection(topic, msgtype)
        stamps = [int(stamp_ns)] * len(datas) if isinstance(stamp_ns, (int, np.integer)) else \
            [int(s) for s in stamp_ns]
        if len(stamps) != len(datas):
            raise ValueError(f"{len(datas)} messages but {len(stamps)} stamps")
        if self._closed or not self._fast_batch():
            for data, stamp in zip(datas, stamps):
                self.write_raw(topic, msgtype, data, stamp)
            return
        writer, storage, cid = self._writer, self._writer.storage, conn.id
        limit = min(self.chunk_size, _ROSBAGS_CHUNK_LIMIT + 1)   # rosbags closes past 1 MiB: the first of both
        pack = _MESSAGE_RECORD.pack
        i, n = 0, len(datas)
        while i < n:
            chunk = storage.chunk
            bio, index = chunk.bio, chunk.msgs[cid]
            start = i
            pos = bio.tell()
            while i < n:
                data, stamp = datas[i], stamps[i]
                index.append((stamp, pos))
                bio.write(pack(0x05, 22 + len(data), cid, 0, stamp, stamp))
                bio.write(data)
                pos += 31 + len(data)
                i += 1
                if pos >= limit:
                    break
            lo, hi = min(stamps[start:i]), max(stamps[start:i])
            chunk.message_start_time = min(lo, chunk.message_start_time)
            chunk.message_end_time = max(hi, chunk.message_end_time)
            storage.message_start_time = min(lo, storage.message_start_time)
            storage.message_end_time = max(hi, storage.message_end_time)
            writer.min_timestamp = min(lo, writer.min_timestamp)
            writer.max_timestamp = max(hi, writer.max_timestamp)
            storage.channel_stats[cid] += i - start
            writer.counts[cid] += i - start
            self.counts[topic] += i - start
            if pos >= limit:
                _close_chunk(storage)
                self._n_chunks = len(storage.chunks)
                storage.bio.flush()                     # a chunk completed: to the OS

    def _fast_batch(self) -> bool:
        """True when rosbags' writer internals are the ones :meth:`write_raw_many` packs records for."""
        if self._fast is None:
            from rosbags.rosbag2.enums import CompressionMode

            w = self._writer
            st = w.storage
            self._fast = bool(
                self._chunk_control and w.compression_mode != CompressionMode.MESSAGE
                and getattr(st, "compression", None) == ""
                and all(hasattr(st, a) for a in ("channel_stats", "message_start_time", "message_end_time"))
                and all(hasattr(st.chunk, a) for a in ("msgs", "message_start_time", "message_end_time"))
                and all(hasattr(w, a) for a in ("counts", "min_timestamp", "max_timestamp")))
        return self._fast

    def write(self, topic: str, msgtype: str, msg, stamp_ns: int) -> None:
        """Serialize a rosbags message object to CDR and write it (see :meth:`write_raw`)."""
        _ensure_type(self.typestore, msgtype)
        self.write_raw(topic, msgtype, self.typestore.serialize_cdr(msg, msgtype), stamp_ns)

    def set_custom_data(self, key: str, value: str) -> None:
        """Set a metadata.yaml ``custom_data`` entry (before :meth:`close`)."""
        self._writer.set_custom_data(str(key), str(value))

    @property
    def closed(self) -> bool:
        """True after :meth:`close`."""
        return self._closed

    def close(self) -> None:
        """Write the MCAP summary and metadata.yaml; idempotent. The bag is complete afterwards."""
        if self._closed:
            return
        self._closed = True
        self._writer.close()
        _set_ros_distro(self.path / "metadata.yaml")

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        self.close()   # also on exceptions: keep what was recorded
        return False


def _close_chunk(storage) -> None:
    """Close rosbags' pending MCAP chunk: the bytes of its ``close_chunk``, packed with struct at once.

    Writes the Chunk record (uncompressed: ``compression`` is ""), one MessageIndex record per
    channel, and keeps the ChunkIndex record for the summary, as the MCAP specification lays them
    out; rosbags packs every integer through its own BytesIO write (~1 us per message).
    """
    chunk = storage.chunk
    body = chunk.bio.getbuffer()
    size = len(body)
    out = storage.bio
    chunk_start = out.tell()
    out.write(struct.pack("<BQQQQIIQ", 0x06, 8 * 3 + 4 + 4 + 8 + size, chunk.message_start_time,
                          chunk.message_end_time, size, 0, 0, size))
    out.write(body)
    del body
    chunk_end = out.tell()
    offsets = []
    for cid, msgs in chunk.msgs.items():
        offsets.append((cid, out.tell()))
        n = len(msgs)
        out.write(struct.pack(f"<BQHI{2 * n}Q", 0x07, 2 + 4 + 16 * n, cid, 16 * n, *chain.from_iterable(msgs)))
    index = io.BytesIO()
    index.write(struct.pack("<QQQQI", chunk.message_start_time, chunk.message_end_time, chunk_start,
                            chunk_end - chunk_start, 10 * len(offsets)))
    for cid, offset in offsets:
        index.write(struct.pack("<HQ", cid, offset))
    index.write(struct.pack("<QIQQ", out.tell() - chunk_end, 0, size, size))
    storage.chunks.append(index)
    storage.chunk = type(chunk)(2**63 - 1, 0, io.BytesIO(), defaultdict(list))


#: The distribution rosbag2 names in ``ros_distro`` (it writes the ROS_DISTRO it runs on).
ROS_DISTRO = "jazzy"


def _set_ros_distro(meta: Path) -> None:
    """rosbags writes ``ros_distro: rosbags``; rosbag2 writes the distribution: say ``jazzy`` (atomically)."""
    try:
        text = meta.read_text(encoding="utf-8")
    except OSError:
        return
    new = text.replace("\n  ros_distro: rosbags\n", f"\n  ros_distro: {ROS_DISTRO}\n", 1)
    if new != text:
        tmp = meta.with_name(meta.name + ".tmp")
        tmp.write_text(new, encoding="utf-8")
        os.replace(tmp, meta)


# =====================================================================================================================
# Reading
# =====================================================================================================================

def _listed_in_metadata(mcap: Path) -> bool:
    """True when ``mcap`` sits in a bag directory whose metadata.yaml lists it."""
    meta = mcap.parent / "metadata.yaml"
    if not meta.is_file():
        return False
    info = _bag_info(mcap.parent)
    return mcap.name in [Path(str(f)).name for f in (info.get("relative_file_paths") or [])] or not info


def _require_readable_bag(path) -> Path:
    """The bag directory of ``path``, checked for what makes readers fail with a traceback.

    Raises a one-line InputError naming the file and the command that helps: no metadata.yaml, a
    metadata.yaml that is not valid YAML or lacks ``rosbag2_bagfile_information``, a listed MCAP file
    that is missing or truncated (no end magic: the writer was killed).
    """
    bag = _bag_dir(path)
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
        if f.suffix.lower() == ".mcap" and not _has_end_magic(f):
            raise InputError(f"truncated MCAP (no footer: the recorder was killed?): `euc-ros recover {bag}` "
                             "rebuilds a bag from its complete chunks", path=f)
    return bag


def _has_end_magic(file: Path) -> bool:
    try:
        with open(file, "rb") as f:
            f.seek(0, 2)
            if f.tell() < 2 * len(MCAP_MAGIC):
                return False
            f.seek(-len(MCAP_MAGIC), 2)
            return f.read(len(MCAP_MAGIC)) == MCAP_MAGIC
    except OSError:
        return False


class readable_bag:
    """Context manager: the bag directory to read for ``path``, checked (:func:`_require_readable_bag`).

    A standalone ``.mcap`` file (no metadata.yaml listing it) is rebuilt into a temporary bag that
    lives until the block ends.

    Examples
    --------
    >>> with readable_bag("ride/run_bag") as bag:   # doctest: +SKIP
    ...     reader = AnyReader([bag])
    """

    def __init__(self, path) -> None:
        self.path = Path(path)
        self._tmp = None

    def __enter__(self) -> Path:
        p = self.path
        if p.suffix.lower() == ".mcap" and p.is_file() and not _listed_in_metadata(p):
            if not _has_end_magic(p):
                raise InputError(f"truncated MCAP (no footer): `euc-ros recover {p}` rebuilds a bag from its "
                                 "complete chunks", path=p)
            self._tmp = tempfile.TemporaryDirectory(prefix="euc_mcap_")
            recover_bag(p, Path(self._tmp.name) / p.stem)
            return Path(self._tmp.name) / p.stem
        return _require_readable_bag(p)

    def __exit__(self, *exc) -> bool:
        if self._tmp is not None:
            self._tmp.cleanup()
        return False


def _read_standalone_mcap(file: Path, **kw) -> MocapSeries:
    """Read an .mcap file without a bag directory: rebuilt into a temporary bag, then read."""
    if not _has_end_magic(file):
        raise InputError(f"truncated MCAP (no footer): `euc-ros recover {file}` rebuilds a bag from its complete "
                         "chunks", path=file)
    with tempfile.TemporaryDirectory(prefix="euc_mcap_") as tmp:
        recover_bag(file, Path(tmp) / "bag")
        series = read_mocap_bag(Path(tmp) / "bag", **kw)
    series.meta["path"] = str(file)
    if not series.name or series.name == "bag":
        series.name = file.stem
    return series


def _require_bag(path) -> Path:
    bag = _bag_dir(path)
    if not (bag / "metadata.yaml").is_file():
        raise InputError("not a complete rosbag2 bag: no metadata.yaml (recorder killed? try recover_bag)",
                         path=bag)
    return bag


def read_bag(path, topics=None, *, raw: bool = False) -> Iterator[tuple]:
    """Iterate the messages of a bag in time order.

    Parameters
    ----------
    path : str or Path
        Bag directory (or its .mcap file).
    topics : iterable of str, optional
        Only these topics (all by default).
    raw : bool
        Yield the CDR bytes instead of deserialized messages.

    Yields
    ------
    tuple
        ``(topic, msgtype, stamp_ns, msg)``: the bag's receive time [ns] and a rosbags message object
        (types auto-registered from the bag) or bytes.
    """
    from rosbags.highlevel import AnyReader

    bag = _require_bag(path)
    try:
        reader = AnyReader([bag], default_typestore=make_typestore())
        reader.open()
    except Exception as exc:  # rosbags raises its own error types for unreadable bags
        raise InputError(f"cannot open bag: {exc}", path=bag) from None
    try:
        wanted = None if topics is None else set(topics)
        conns = [c for c in reader.connections if wanted is None or c.topic in wanted]
        for conn, stamp, data in reader.messages(connections=conns):
            yield (conn.topic, conn.msgtype, stamp, bytes(data) if raw else reader.deserialize(data, conn.msgtype))
    finally:
        reader.close()


# =====================================================================================================================
# Structural check
# =====================================================================================================================

def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_scalar(v) -> bool:
    """yaml-cpp ``as<std::string>()`` accepts any scalar (not null, not a sequence or map)."""
    return isinstance(v, (str, int, float, bool)) and v is not None


_QOS_KEYS = ("history", "depth", "reliability", "durability", "deadline", "lifespan", "liveliness",
             "liveliness_lease_duration", "avoid_ros_namespace_conventions")


class _Meta:
    """Walk metadata.yaml the way rosbag2 Jazzy's YAML decoder does, collecting problems."""

    def __init__(self, problems: list[str]) -> None:
        self.problems = problems

    def get(self, node, key: str, where: str, kind: str):
        path = f"{where}.{key}" if where else key
        if not isinstance(node, dict) or key not in node:
            self.problems.append(f"metadata.yaml: missing key '{path}'")
            return None
        v = node[key]
        ok = {"int": _is_int(v), "uint": _is_int(v) and v >= 0, "scalar": _is_scalar(v),
              "seq": isinstance(v, list), "map": isinstance(v, dict),
              "map_or_null": v is None or isinstance(v, dict)}[kind]
        if not ok:
            want = {"int": "an integer", "uint": "a non-negative integer", "scalar": "a string",
                    "seq": "a list", "map": "a mapping", "map_or_null": "a mapping"}[kind]
            self.problems.append(f"metadata.yaml: '{path}' must be {want}, got {type(v).__name__} {v!r:.60}")
            return None
        return v

    def nanoseconds(self, node, key: str, where: str, field: str):
        sub = self.get(node, key, where, "map")
        return None if sub is None else self.get(sub, field, f"{where}.{key}" if where else key, "uint")


#: rosbag2 Jazzy's QoS policy words (rosbag2_storage/qos.cpp decodes these, or their rmw numbers).
_QOS_POLICIES = {
    "history": ("system_default", "keep_last", "keep_all", "unknown"),
    "reliability": ("system_default", "reliable", "best_effort", "unknown", "best_available"),
    "durability": ("system_default", "transient_local", "volatile", "unknown", "best_available"),
    "liveliness": ("system_default", "automatic", "manual_by_node", "manual_by_topic", "unknown", "best_available"),
}


def _check_qos(q: dict, where: str, problems: list[str]) -> None:
    """One ``offered_qos_profiles`` entry as the Jazzy decoder reads it (policy word or number, int depth,
    {sec, nsec} durations, bool)."""
    for key, words in _QOS_POLICIES.items():
        v = q.get(key)
        if v is not None and not (_is_int(v) or v in words):
            problems.append(f"metadata.yaml: '{where}.{key}' is {v!r}, not one of {', '.join(words)}")
    if "depth" in q and not _is_int(q["depth"]):
        problems.append(f"metadata.yaml: '{where}.depth' must be an integer")
    for key in ("deadline", "lifespan", "liveliness_lease_duration"):
        v = q.get(key)
        if v is not None and not (isinstance(v, dict) and all(_is_int(v.get(f)) and v.get(f) >= 0
                                                                  for f in ("sec", "nsec"))):
            problems.append(f"metadata.yaml: '{where}.{key}' must be {{sec, nsec}} (unsigned integers)")
    v = q.get("avoid_ros_namespace_conventions")
    if v is not None and not isinstance(v, bool):
        problems.append(f"metadata.yaml: '{where}.avoid_ros_namespace_conventions' must be true or false")


def _check_metadata(bag: Path, problems: list[str]) -> dict | None:
    """Validate metadata.yaml; return the information block (or None when unusable)."""
    meta_file = bag / "metadata.yaml"
    if not meta_file.is_file():
        problems.append("metadata.yaml missing: the bag was not closed (recorder killed?); "
                        "recover_bag can rebuild it from the complete chunks")
        return None
    try:
        doc = yaml.safe_load(meta_file.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        problems.append(f"metadata.yaml: not valid YAML: {exc}")
        return None
    m = _Meta(problems)
    info = m.get(doc, "rosbag2_bagfile_information", "", "map")
    if info is None:
        return None
    w = "rosbag2_bagfile_information"
    version = m.get(info, "version", w, "int")
    if version is None:
        return None
    if version > JAZZY_MAX_VERSION:
        problems.append(f"metadata.yaml: version {version} is newer than ROS 2 Jazzy reads ({JAZZY_MAX_VERSION})")
    storage = m.get(info, "storage_identifier", w, "scalar")
    if storage is not None and storage != "mcap":
        problems.append(f"metadata.yaml: storage_identifier is {storage!r}, expected 'mcap'")
    m.nanoseconds(info, "duration", w, "nanoseconds")
    m.nanoseconds(info, "starting_time", w, "nanoseconds_since_epoch")
    m.get(info, "message_count", w, "uint")
    topics = m.get(info, "topics_with_message_count", w, "seq") or []
    for i, t in enumerate(topics):
        tw = f"{w}.topics_with_message_count[{i}]"
        tm = m.get(t, "topic_metadata", tw, "map")
        m.get(t, "message_count", tw, "uint")
        if tm is None:
            continue
        tmw = f"{tw}.topic_metadata"
        for key in ("name", "type", "serialization_format"):
            m.get(tm, key, tmw, "scalar")
        if version >= 9:
            profiles = m.get(tm, "offered_qos_profiles", tmw, "seq") or []
            for k, q in enumerate(profiles):
                if not isinstance(q, dict):
                    problems.append(f"metadata.yaml: '{tmw}.offered_qos_profiles[{k}]' must be a mapping")
                    continue
                missing = [key for key in _QOS_KEYS if key not in q]
                if missing:
                    problems.append(f"metadata.yaml: '{tmw}.offered_qos_profiles[{k}]' lacks {', '.join(missing)}")
                _check_qos(q, f"{tmw}.offered_qos_profiles[{k}]", problems)
        elif version >= 4:
            m.get(tm, "offered_qos_profiles", tmw, "scalar")
        if version >= 7:
            m.get(tm, "type_description_hash", tmw, "scalar")
    paths = m.get(info, "relative_file_paths", w, "seq") or []
    for k, p in enumerate(paths):
        if not _is_scalar(p):
            problems.append(f"metadata.yaml: '{w}.relative_file_paths[{k}]' must be a string")
    if version >= 3:
        m.get(info, "compression_format", w, "scalar")
        m.get(info, "compression_mode", w, "scalar")
    if version >= 5:
        files = m.get(info, "files", w, "seq") or []
        for k, f in enumerate(files):
            fw = f"{w}.files[{k}]"
            m.get(f, "path", fw, "scalar")
            m.nanoseconds(f, "starting_time", fw, "nanoseconds_since_epoch")
            m.nanoseconds(f, "duration", fw, "nanoseconds")
            m.get(f, "message_count", fw, "uint")
    if version >= 6:
        custom = m.get(info, "custom_data", w, "map_or_null")
        for k, v in (custom or {}).items():
            if not (_is_scalar(k) and _is_scalar(v)):
                problems.append(f"metadata.yaml: custom_data entry {k!r}: {v!r} is not string: string")
    if version >= 8:
        m.get(info, "ros_distro", w, "scalar")
    # Internal consistency.
    counts = [t.get("message_count") for t in topics if isinstance(t, dict)]
    total = info.get("message_count")
    if _is_int(total) and all(_is_int(c) for c in counts) and sum(counts) != total:
        problems.append(f"metadata.yaml: topic message counts sum to {sum(counts)}, message_count is {total}")
    return info


class _Scan:
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


def _scan_mcap(path: Path, *, keep_messages: bool = False, validate_crcs: bool = True):
    """Parse every record (and every record inside every chunk) of an MCAP file, stopping at damage.

    Returns ``(scan, messages)``; ``messages`` holds ``(channel_id, log_time, data)`` of messages in
    complete chunks when ``keep_messages``.
    """
    from mcap.records import Channel, Chunk, Footer, Message, Schema, Statistics
    from mcap.stream_reader import StreamReader, breakup_chunk

    scan, messages = _Scan(), []

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


def _check_mcap(file: Path, info: dict | None, problems: list[str]) -> _Scan | None:
    size = file.stat().st_size
    with open(file, "rb") as f:
        head = f.read(len(MCAP_MAGIC))
        f.seek(max(0, size - len(MCAP_MAGIC)))
        tail = f.read(len(MCAP_MAGIC))
    if head != MCAP_MAGIC:
        problems.append(f"{file.name}: no MCAP magic at the start: not an MCAP file")
        return None
    scan, _ = _scan_mcap(file)
    truncated = tail != MCAP_MAGIC or not scan.footer
    if truncated:
        problems.append(f"{file.name}: truncated ({size} bytes, no footer/end magic): the recorder was killed "
                        f"before closing; {scan.n_messages} messages in {scan.n_chunks} complete chunks are "
                        f"recoverable with recover_bag")
        return scan
    if scan.error:
        problems.append(f"{file.name}: record parse failed: {scan.error}")
        return scan
    from mcap.reader import make_reader

    try:
        with open(file, "rb") as f:
            summary = make_reader(f).get_summary()
    except Exception as exc:  # damaged summary section
        summary = None
        problems.append(f"{file.name}: summary section unreadable: {exc}")
    if summary is None:
        problems.append(f"{file.name}: no summary section")
    elif summary.statistics is None:
        problems.append(f"{file.name}: summary has no statistics record")
    else:
        st = summary.statistics
        if st.message_count != scan.n_messages:
            problems.append(f"{file.name}: statistics say {st.message_count} messages, records hold {scan.n_messages}")
        # a channel registered (a subscription matched) but never written is counted 0 by the writer
        # and has no message records: that is a legal, complete bag
        stated = {k: v for k, v in st.channel_message_counts.items() if v}
        if stated != {k: v for k, v in scan.counts.items() if v}:
            problems.append(f"{file.name}: per-channel statistics {dict(st.channel_message_counts)} disagree with "
                            f"the records {scan.counts}")
        if st.chunk_count != scan.n_chunks or len(summary.chunk_indexes) != scan.n_chunks:
            problems.append(f"{file.name}: {scan.n_chunks} chunks in the data, statistics say {st.chunk_count}, "
                            f"{len(summary.chunk_indexes)} chunk indexes")
    if info is not None:
        by_topic: dict[str, int] = {}
        types: dict[str, str] = {}
        for cid, ch in scan.channels.items():
            by_topic[ch.topic] = by_topic.get(ch.topic, 0) + scan.counts.get(cid, 0)
            schema = scan.schemas.get(ch.schema_id)
            types[ch.topic] = schema.name if schema is not None else "?"
        meta_topics = {}
        for t in info.get("topics_with_message_count") or []:
            tm = t.get("topic_metadata") if isinstance(t, dict) else None
            if isinstance(tm, dict) and "name" in tm:
                meta_topics[tm["name"]] = (tm.get("type"), t.get("message_count"))
        for topic, (mtype, count) in meta_topics.items():
            if topic not in by_topic:
                problems.append(f"metadata.yaml lists topic {topic} which has no channel in {file.name}")
                continue
            if count != by_topic[topic]:
                problems.append(f"message count of {topic}: metadata.yaml says {count}, {file.name} holds "
                                f"{by_topic[topic]}")
            if mtype != types[topic]:
                problems.append(f"type of {topic}: metadata.yaml says {mtype}, {file.name} schema is {types[topic]}")
        for topic in sorted(set(by_topic) - set(meta_topics)):
            problems.append(f"topic {topic} is in {file.name} but not in metadata.yaml")
        if _is_int(info.get("message_count")) and info["message_count"] != scan.n_messages:
            problems.append(f"message_count: metadata.yaml says {info['message_count']}, {file.name} holds "
                            f"{scan.n_messages}")
    # Decode everything with the independent ROS 2 reader of the mcap project.
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    try:
        with open(file, "rb") as f:
            n = sum(1 for _ in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages())
        if n != scan.n_messages:
            problems.append(f"{file.name}: mcap-ros2-support decoded {n} of {scan.n_messages} messages")
    except Exception as exc:  # any decoder failure is a finding, not a crash
        problems.append(f"{file.name}: mcap-ros2-support cannot decode: {type(exc).__name__}: {exc}")
    return scan


def check_bag(path) -> list[str]:
    """Check a bag's structure; return the problems found (empty list: OK).

    Checks, in order: metadata.yaml keys and YAML types as ROS 2 Jazzy's decoder reads them
    (``rosbag2_storage/yaml.hpp``, metadata version 9: ``offered_qos_profiles`` is a list), the
    internal consistency of its counts; for each listed file: MCAP magic at start and end, the footer
    and summary (statistics, chunk indexes), every record of every chunk parses (CRCs validated when
    present), per-channel counts agree with the statistics and with metadata.yaml, topic types agree,
    and every message decodes with mcap-ros2-support. A truncated file (recorder killed: no
    summary, no footer) is reported as such with the number of recoverable messages.

    Parameters
    ----------
    path : str or Path
        Bag directory (or its .mcap file).

    Returns
    -------
    list of str
        One line per problem.
    """
    bag = _bag_dir(path)
    if not bag.is_dir():
        return [f"{bag}: no such bag directory"]
    problems: list[str] = []
    info = _check_metadata(bag, problems)
    if info is not None and isinstance(info.get("relative_file_paths"), list):
        files = [bag / str(p) for p in info["relative_file_paths"]]
    else:
        files = sorted(bag.glob("*.mcap"))
    if not files:
        problems.append("no .mcap file in the bag")
    for file in files:
        if not file.is_file():
            problems.append(f"{file.name}: listed in metadata.yaml but missing")
            continue
        _check_mcap(file, info if len(files) == 1 else None, problems)
    return problems


# =====================================================================================================================
# Recovery
# =====================================================================================================================

def recover_bag(path, out=None) -> dict:
    """Rebuild a valid bag from what can be read of a truncated MCAP (messages in complete chunks).

    Parameters
    ----------
    path : str or Path
        Damaged bag directory (or its .mcap file), e.g. from a recorder killed with SIGKILL.
    out : str or Path, optional
        New bag directory; default ``<bag>_recovered`` next to the input.

    Returns
    -------
    dict
        ``output`` (Path), ``messages`` recovered, ``topics`` {topic: count}, ``chunks`` complete
        chunks read, ``stopped_at`` (why reading stopped, None if the file was complete).

    Raises
    ------
    InputError
        No MCAP file, or not a single complete message to recover.
    """
    bag = _bag_dir(path)
    mcaps = [Path(path)] if Path(path).suffix == ".mcap" else sorted(bag.glob("*.mcap"))
    if not mcaps:
        raise InputError("no .mcap file to recover", path=bag)
    dest = Path(out) if out is not None else bag.with_name(bag.name + "_recovered")
    total, topics, chunks, stopped = 0, {}, 0, None
    scans = []
    for file in mcaps:
        with open(file, "rb") as f:
            if f.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
                raise InputError("not an MCAP file (no magic)", path=file)
        scan, messages = _scan_mcap(file, keep_messages=True, validate_crcs=False)
        scans.append((scan, messages))
        chunks += scan.n_chunks
        stopped = stopped or scan.error
    if not any(messages for _, messages in scans):
        raise InputError(f"nothing to recover: no complete chunk ({stopped or 'empty file'})", path=bag)
    with BagWriter(dest) as writer:
        for scan, messages in scans:
            for cid, stamp, data in sorted(messages, key=lambda m: m[1]):
                ch = scan.channels.get(cid)
                schema = scan.schemas.get(ch.schema_id) if ch is not None else None
                if schema is None:
                    continue
                msgdef = schema.data.decode("utf-8")
                writer.connection(ch.topic, schema.name, msgdef=msgdef)
                writer.write_raw(ch.topic, schema.name, data, stamp)
                total += 1
                topics[ch.topic] = topics.get(ch.topic, 0) + 1
    return {"output": dest, "messages": total, "topics": topics, "chunks": chunks, "stopped_at": stopped}


# =====================================================================================================================
# Inspection
# =====================================================================================================================

def inspect_bag(path) -> dict:
    """Describe a bag: topics, types, counts, time span, storage, and the problems of :func:`check_bag`.

    Parameters
    ----------
    path : str or Path
        Bag directory (or its .mcap file).

    Returns
    -------
    dict
        ``path``, ``storage``, ``metadata_version``, ``ros_distro``, ``files`` [{name, bytes}],
        ``topics`` [{name, type, count, rate_hz}], ``message_count``, ``start_ns``, ``end_ns``,
        ``duration_s``, ``problems`` (list of str; empty when the bag is sound). For a bag without
        metadata.yaml the figures come from what the MCAP scan could read. A topic's ``rate_hz`` is
        ``(count - 1)`` over the span from its own first to its last message (log time), None with
        fewer than two messages; ``duration_s`` is the bag's span over all topics.
    """
    bag = _bag_dir(path)
    if not bag.is_dir():
        raise InputError("no such bag directory", path=bag)
    problems = check_bag(bag)
    info = None
    meta_file = bag / "metadata.yaml"
    if meta_file.is_file():
        try:
            info = (yaml.safe_load(meta_file.read_text(encoding="utf-8")) or {}).get("rosbag2_bagfile_information")
        except (yaml.YAMLError, AttributeError):
            info = None
    files = sorted(bag.glob("*.mcap"))
    out = {"path": str(bag), "storage": "mcap", "metadata_version": None, "ros_distro": None,
           "files": [{"name": f.name, "bytes": f.stat().st_size} for f in files], "topics": [],
           "message_count": 0, "start_ns": None, "end_ns": None, "duration_s": 0.0, "problems": problems}
    topics: dict[str, dict] = {}
    spans: dict[str, tuple[int, int]] = {}      # topic -> (first, last) log time [ns]
    first = last = None
    for file in files:
        scan, _ = _scan_mcap(file, validate_crcs=False)
        for cid, ch in scan.channels.items():
            schema = scan.schemas.get(ch.schema_id)
            entry = topics.setdefault(ch.topic, {"name": ch.topic, "type": schema.name if schema else "?",
                                                 "count": 0})
            entry["count"] += scan.counts.get(cid, 0)
            if cid in scan.span_ns:
                lo, hi = scan.span_ns[cid]
                seen = spans.get(ch.topic)
                spans[ch.topic] = (lo, hi) if seen is None else (min(seen[0], lo), max(seen[1], hi))
        if scan.first_ns is not None:
            first = scan.first_ns if first is None else min(first, scan.first_ns)
            last = scan.last_ns if last is None else max(last, scan.last_ns)
    if isinstance(info, dict):
        out["storage"] = info.get("storage_identifier", "mcap")
        out["metadata_version"] = info.get("version")
        out["ros_distro"] = info.get("ros_distro")
    duration = (last - first) * 1e-9 if first is not None else 0.0
    for entry in topics.values():      # each topic over its own span: topics start and end at different times
        lo, hi = spans.get(entry["name"], (0, 0))
        entry["rate_hz"] = (entry["count"] - 1) / ((hi - lo) * 1e-9) if hi > lo and entry["count"] > 1 else None
    out.update(topics=sorted(topics.values(), key=lambda e: e["name"]),
               message_count=sum(e["count"] for e in topics.values()), start_ns=first, end_ns=last,
               duration_s=duration)
    return out


# =====================================================================================================================
# Mocap series <-> bag
# =====================================================================================================================


def posestamped_cdr(stamp_ns, position, quat, frame_id: str = "world") -> list[bytes]:
    """Serialize PoseStamped messages to little-endian CDR, vectorized.

    Layout (XCDR1, alignment relative to the byte after the 4-byte encapsulation header):
    ``00 01 00 00``; ``int32 sec``; ``uint32 nanosec``; ``uint32 len(frame_id)+1``; frame_id, NUL;
    padding to 8; 7 ``float64`` (position x y z, orientation x y z w).

    Parameters
    ----------
    stamp_ns : array (n,) of int
        Header stamps [ns].
    position : array (n, 3)
        [m].
    quat : array (n, 4)
        (x, y, z, w).
    frame_id : str

    Returns
    -------
    list of bytes
        One CDR message per sample.
    """
    stamp_ns = np.atleast_1d(np.asarray(stamp_ns, dtype=np.int64))
    n = stamp_ns.shape[0]
    fid = frame_id.encode("utf-8") + b"\0"
    body_start = 12 + len(fid)                     # relative to the encapsulation end
    pose_rel = pad(body_start, 8)
    length = HEAD + pose_rel + 56
    buf = np.zeros((n, length), dtype=np.uint8)
    buf[:, :HEAD] = np.frombuffer(ENCAPSULATION_LE, np.uint8)
    sec, nsec = split_stamp(stamp_ns)
    buf[:, 4:8] = sec.astype("<i4")[:, None].view(np.uint8)
    buf[:, 8:12] = nsec.astype("<u4")[:, None].view(np.uint8)
    buf[:, 12:16] = np.frombuffer(np.uint32(len(fid)).astype("<u4").tobytes(), np.uint8)
    buf[:, 16:16 + len(fid)] = np.frombuffer(fid, np.uint8)
    values = np.concatenate([np.asarray(position, float).reshape(n, 3), np.asarray(quat, float).reshape(n, 4)],
                            axis=1).astype("<f8")
    buf[:, HEAD + pose_rel:] = values.view(np.uint8).reshape(n, 56)
    return [row.tobytes() for row in buf]


def posestamped_arrays(raws: list[bytes]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Parse little-endian CDR PoseStamped messages, vectorized per message length.

    Parameters
    ----------
    raws : list of bytes

    Returns
    -------
    stamp_ns : ndarray (n,) of int64
    position : ndarray (n, 3)
    quat : ndarray (n, 4)

    Raises
    ------
    InputError
        Big-endian or malformed data (use :func:`read_bag` for those).
    """
    n = len(raws)
    stamp = np.zeros(n, np.int64)
    vals = np.zeros((n, 7))
    lengths = np.fromiter((len(r) for r in raws), dtype=np.int64, count=n)
    for length in np.unique(lengths):
        idx = np.flatnonzero(lengths == length)
        arr = np.frombuffer(b"".join(raws[i] for i in idx), dtype=np.uint8).reshape(len(idx), int(length))
        stamp[idx], vals[idx] = _posestamped_rows(arr)
    return stamp, vals[:, :3], vals[:, 3:]


def _posestamped_rows(arr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Stamps [ns] and (position, quaternion) values (m, 7) of PoseStamped CDR rows of one length (m, L)."""
    m, length = arr.shape
    if length < 16 or np.any(arr[:, 1] != 1) or np.any(arr[:, 0] != 0):
        raise InputError("PoseStamped CDR is not little-endian XCDR1 or is too short", key=POSE_STAMPED)
    slen = arr[:, 12:16].copy().view("<u4")[:, 0].astype(np.int64)
    pose_rel = (12 + slen + 7) // 8 * 8
    if np.any(4 + pose_rel + 56 > length):
        raise InputError("PoseStamped CDR shorter than its frame_id length implies", key=POSE_STAMPED)
    sec = arr[:, 4:8].copy().view("<i4")[:, 0].astype(np.int64)
    nsec = arr[:, 8:12].copy().view("<u4")[:, 0].astype(np.int64)
    vals = np.zeros((m, 7))
    for start in np.unique(pose_rel):
        rows = np.flatnonzero(pose_rel == start)
        block = arr[rows, 4 + int(start):4 + int(start) + 56].copy()
        vals[rows] = block.view("<f8").reshape(len(rows), 7)
    return sec * 10**9 + nsec, vals


def write_mocap_bag(series: MocapSeries, path, *, prefix: str = "/vrpn_mocap", frame_topic: str | None = "/mocap/frame",
                    start_ns: int | None = None, frame_id: str = "world", poses: bool = True,
                    chunk_size: int = DEFAULT_CHUNK_SIZE) -> dict:
    """Write a mocap series as a bag: PoseStamped per body and/or MocapFrame messages.

    Stamps (header and bag receive time) are capture times ``start_ns + round(t * 1e9)``.

    Parameters
    ----------
    series : MocapSeries
        Z-up world, SI units.
    path : str or Path
        New bag directory.
    prefix : str
        PoseStamped topics are ``<prefix>/<Body>/pose`` (docs/bags.md).
    frame_topic : str or None
        Topic of ``euc_msgs/msg/MocapFrame`` messages (one per frame, every body, untracked ones
        with ``tracked=false`` and a NaN pose); None writes none.
    start_ns : int, optional
        Capture time of ``t = 0`` [ns since the epoch]; default ``series.meta['start_ns']`` or 0.
    frame_id : str
        World frame name in the headers.
    poses : bool
        Write the PoseStamped topics (untracked samples are skipped: gaps, never zeros).
    chunk_size : int
        MCAP chunk size [bytes] (see :class:`BagWriter`).

    Returns
    -------
    dict
        Messages written per topic.
    """
    if start_ns is None:
        start_ns = int(series.meta.get("start_ns", 0))
    n, b = series.n_frames, len(series.bodies)
    if series.position.shape != (b, n, 3) or series.quat.shape != (b, n, 4) or series.tracked.shape != (b, n):
        raise InputError(f"inconsistent MocapSeries shapes: position {series.position.shape}, quat "
                         f"{series.quat.shape}, tracked {series.tracked.shape} for {b} bodies x {n} frames")
    stamps = int(start_ns) + np.round(np.asarray(series.t, float) * 1e9).astype(np.int64)
    custom = {CUSTOM_START_NS: str(int(start_ns)), CUSTOM_NAME: series.name or ""}
    if "rate_hz" in series.meta:
        custom[CUSTOM_RATE_HZ] = repr(float(series.meta["rate_hz"]))
    tracked = np.asarray(series.tracked, bool)
    with BagWriter(path, chunk_size=chunk_size, custom_data=custom) as writer:
        ts = writer.typestore
        pose_cdr = []
        if poses:
            for j, body in enumerate(series.bodies):
                sel = np.flatnonzero(tracked[j])
                pose_cdr.append((f"{prefix}/{body}/pose", sel,
                                 posestamped_cdr(stamps[sel], series.position[j, sel], series.quat[j, sel], frame_id)))
        cursors = [0] * len(pose_cdr)
        if frame_topic:
            T = ts.types
            Frame, Header, Time = T[MOCAP_FRAME], T["std_msgs/msg/Header"], T["builtin_interfaces/msg/Time"]
            Pose, Point, Quaternion = T["geometry_msgs/msg/Pose"], T["geometry_msgs/msg/Point"], \
                T["geometry_msgs/msg/Quaternion"]
            sec, nsec = split_stamp(stamps)
            pos = np.where(tracked[..., None], series.position, np.nan)
            quat = np.where(tracked[..., None], series.quat, np.nan)
            err = np.asarray(series.mean_marker_error, float)
            stamp_source = int(series.meta.get("stamp_source", STAMP_FILE_TIME))
        for i in range(n):
            for k, (topic, sel, cdrs) in enumerate(pose_cdr):
                c = cursors[k]
                if c < len(sel) and sel[c] == i:
                    writer.write_raw(topic, POSE_STAMPED, cdrs[c], stamps[i])
                    cursors[k] = c + 1
            if frame_topic:
                msg = Frame(
                    header=Header(stamp=Time(sec=int(sec[i]), nanosec=int(nsec[i])), frame_id=frame_id),
                    stamp_source=stamp_source, frame_number=int(series.frame[i]), body_names=list(series.bodies),
                    poses=[Pose(position=Point(x=p[0], y=p[1], z=p[2]),
                                orientation=Quaternion(x=q[0], y=q[1], z=q[2], w=q[3]))
                           for p, q in zip(pos[:, i].tolist(), quat[:, i].tolist())],
                    tracked=tracked[:, i].copy(), mean_marker_error=err[:, i].astype(np.float32))
                writer.write(frame_topic, MOCAP_FRAME, msg, stamps[i])
        return dict(writer.counts)


def _bag_info(bag: Path) -> dict:
    """metadata.yaml's ``rosbag2_bagfile_information`` mapping ({} when unreadable)."""
    try:
        info = yaml.load((bag / "metadata.yaml").read_text(encoding="utf-8"),
                         Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))["rosbag2_bagfile_information"]
        return info if isinstance(info, dict) else {}
    except (OSError, yaml.YAMLError, KeyError, TypeError):
        return {}


def _custom_data(bag: Path, info: dict | None = None) -> dict:
    info = _bag_info(bag) if info is None else info
    try:
        return dict(info.get("custom_data") or {})
    except (TypeError, ValueError):
        return {}


def read_mocap_bag(path, *, prefix: str = "/vrpn_mocap", frame_topic: str | None = None, bodies=None,
                   merge_tolerance: float = 0.25) -> MocapSeries:
    """Read mocap from a bag into a :class:`~euc_ros.core.mocap.series.MocapSeries`.

    Source, in order: ``frame_topic`` (``euc_msgs/msg/MocapFrame``); else the first MocapFrame topic
    of the bag; else one ``geometry_msgs/msg/PoseStamped`` per body on ``<prefix>/<Body>/pose``
    (docs/bags.md), aligned on their header stamps.

    Parameters
    ----------
    path : str or Path
        Bag directory (or its .mcap file).
    prefix : str
        PoseStamped topic prefix.
    frame_topic : str, optional
        MocapFrame topic to use.
    bodies : list of str, optional
        Bodies to return, in this order (default: all, in the bag's order).
    merge_tolerance : float
        PoseStamped stamps closer than ``merge_tolerance / rate`` are one frame [frame periods].

    Returns
    -------
    MocapSeries
        ``t`` = header stamp minus ``start_ns`` [s], where ``start_ns`` is the one
        :func:`write_mocap_bag` stored in metadata.yaml, else the first stamp; ``meta['start_ns']``
        holds it. Frame numbers from MocapFrame (``-1`` ones, and PoseStamped data, get
        ``round(t * rate)``). Samples without data are NaN with ``tracked == False``.

    Notes
    -----
    Bags with one uncompressed, indexed MCAP file are read by :mod:`euc_ros.core.io.mcap_fast`
    (message indexes, no per-message Python work) and, when every MocapFrame has the same CDR
    layout (same length, body names, counts), decoded with numpy at fixed offsets: ~0.15 s instead
    of ~6 s for 10 min x 14 bodies at 120 Hz. Anything else (several files, compression, varying
    body names...) takes the general rosbags route; both give identical series (see ``docs/mcap_fast.md``).
    """
    p = Path(path)
    if p.suffix.lower() == ".mcap" and p.is_file() and not _listed_in_metadata(p):
        return _read_standalone_mcap(p, prefix=prefix, frame_topic=frame_topic, bodies=bodies,
                                     merge_tolerance=merge_tolerance)
    bag = _require_readable_bag(path)
    info = _bag_info(bag)
    custom = _custom_data(bag, info)
    try:
        series = _read_mocap_fast(bag, info, prefix, frame_topic, merge_tolerance)
        if series is None:
            series = _read_mocap_rosbags(bag, prefix, frame_topic, merge_tolerance)
    except InputError:
        raise
    except Exception as exc:   # a damaged bag the checks above did not catch: one line, what to do
        raise InputError(f"cannot read the bag ({type(exc).__name__}: {exc}); `euc-ros inspect {bag}` lists its "
                         f"problems, `euc-ros recover {bag}` rebuilds what can be read", path=bag) from None
    start_ns = series.meta.pop("_first_ns")
    if CUSTOM_START_NS in custom:
        try:
            start_ns = int(custom[CUSTOM_START_NS])
        except ValueError:
            pass
    series.t = (series.meta.pop("_stamps") - start_ns) * 1e-9
    series.meta["start_ns"] = start_ns
    if CUSTOM_RATE_HZ in custom:
        series.meta["rate_hz"] = float(custom[CUSTOM_RATE_HZ])
    if custom.get(CUSTOM_NAME):
        series.name = custom[CUSTOM_NAME]
    rate = series.rate_hz if series.n_frames > 1 else np.nan
    unknown = series.frame < 0
    if unknown.any():
        frame = series.frame.copy()       # a new array: the series measures its rate again from it
        frame[unknown] = (np.round(series.t[unknown] * rate).astype(np.int64) if np.isfinite(rate)
                          else np.flatnonzero(unknown))
        series.frame = frame
    if bodies is not None:
        series = series.select(list(bodies))
    return series


def _read_mocap_rosbags(bag: Path, prefix: str, frame_topic: str | None, merge_tolerance: float) -> MocapSeries:
    """The general route of :func:`read_mocap_bag`: rosbags' reader and deserializer (any bag rosbags reads)."""
    from rosbags.highlevel import AnyReader

    with AnyReader([bag], default_typestore=make_typestore()) as reader:
        conns = reader.connections
        frame_conns = [c for c in conns if c.msgtype == MOCAP_FRAME]
        if frame_topic is not None:
            chosen = [c for c in frame_conns if c.topic == frame_topic]
            if not chosen:
                have = ", ".join(sorted({c.topic for c in frame_conns})) or "none"
                raise InputError(f"no {MOCAP_FRAME} topic {frame_topic} in the bag (MocapFrame topics: {have})",
                                 path=bag, key="frame_topic")
            frame_conns = chosen[:1]
        rigid = [c for c in conns if c.msgtype == RIGID_BODIES]
        if frame_conns:
            series = _series_from_frames(reader, frame_conns[0], bag)
        elif rigid:
            series = _series_from_rigid_bodies(reader, rigid[0], bag)
        else:
            series = _series_from_poses(reader, conns, prefix, bag, merge_tolerance)
    return series


def _series_from_frames(reader, conn, bag: Path) -> MocapSeries:
    stamps, numbers, names_per, pos_per, quat_per, trk_per, err_per = [], [], [], [], [], [], []
    for _, _, data in reader.messages(connections=[conn]):
        m = reader.deserialize(data, conn.msgtype)
        stamps.append(int(m.header.stamp.sec) * 10**9 + int(m.header.stamp.nanosec))
        numbers.append(int(m.frame_number))
        names_per.append(list(m.body_names))
        pos_per.append([(p.position.x, p.position.y, p.position.z) for p in m.poses])
        quat_per.append([(p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w) for p in m.poses])
        trk_per.append(np.asarray(m.tracked, bool))
        err_per.append(np.asarray(m.mean_marker_error, float))
    if not stamps:
        raise InputError(f"topic {conn.topic} holds no messages", path=bag)
    bodies: list[str] = []
    for names in names_per:
        for name in names:
            if name not in bodies:
                bodies.append(name)
    order = np.argsort(np.asarray(stamps, np.int64), kind="stable")
    n, b = len(stamps), len(bodies)
    col = {name: k for k, name in enumerate(bodies)}
    position, quat = np.full((b, n, 3), np.nan), np.full((b, n, 4), np.nan)
    tracked, err = np.zeros((b, n), bool), np.full((b, n), np.nan)
    for i, src in enumerate(order):
        names = names_per[src]
        rows = np.array([col[x] for x in names], dtype=np.int64)
        k = len(names)
        if not (len(pos_per[src]) == len(trk_per[src]) == k):
            raise InputError(f"MocapFrame {numbers[src]}: {k} names but {len(pos_per[src])} poses and "
                             f"{len(trk_per[src])} tracked flags", path=bag, key=conn.topic)
        trk = trk_per[src]
        position[rows, i] = np.where(trk[:, None], np.asarray(pos_per[src], float).reshape(k, 3), np.nan)
        quat[rows, i] = np.where(trk[:, None], np.asarray(quat_per[src], float).reshape(k, 4), np.nan)
        tracked[rows, i] = trk
        if len(err_per[src]) == k:
            err[rows, i] = err_per[src]
    stamps_arr = np.asarray(stamps, np.int64)[order]
    return MocapSeries(np.zeros(n), np.asarray(numbers, np.int64)[order], bodies, position, quat, tracked, err,
                       name=bag.name, meta={"path": str(bag), "source": f"{MOCAP_FRAME} {conn.topic}",
                                            "_stamps": stamps_arr, "_first_ns": int(stamps_arr[0])})


def _series_from_rigid_bodies(reader, conn, bag: Path) -> MocapSeries:
    """mocap4r2_msgs/RigidBodies (one message per frame, bodies by name) as stored: the driver's axes.

    Bodies are taken in order of first appearance; a body missing from a message, or with a pose that
    is not finite with a unit quaternion, is a gap (NaN, untracked)."""
    msgs = [reader.deserialize(data, conn.msgtype) for _, _, data in reader.messages(connections=[conn])]
    if not msgs:
        raise InputError(f"topic {conn.topic} holds no messages", path=bag)
    per = []
    for m in msgs:
        names = [b.rigid_body_name for b in m.rigidbodies]
        pos = np.array([(b.pose.position.x, b.pose.position.y, b.pose.position.z) for b in m.rigidbodies],
                       float).reshape(-1, 3)
        quat = np.array([(b.pose.orientation.x, b.pose.orientation.y, b.pose.orientation.z, b.pose.orientation.w)
                         for b in m.rigidbodies], float).reshape(-1, 4)
        per.append((int(m.header.stamp.sec) * 10**9 + int(m.header.stamp.nanosec), int(m.frame_number),
                    names, pos, quat))
    bodies = list(dict.fromkeys(name for p in per for name in p[2]))
    order = np.argsort(np.array([p[0] for p in per], np.int64), kind="stable")
    n, b = len(per), len(bodies)
    position, quat = np.full((b, n, 3), np.nan), np.full((b, n, 4), np.nan)
    tracked = np.zeros((b, n), bool)
    for i, src in enumerate(order):
        frame, _ = frame_from_named_poses(per[src][0], per[src][1], per[src][2], per[src][3], per[src][4], bodies,
                                          world_up="z")
        position[:, i], quat[:, i], tracked[:, i] = frame.position, frame.quat, frame.tracked
    stamps = np.array([per[k][0] for k in order], np.int64)
    numbers = np.array([per[k][1] for k in order], np.int64)
    return MocapSeries(np.zeros(n), numbers, bodies, position, quat, tracked, np.full((b, n), np.nan),
                       name=bag.name, meta={"path": str(bag), "source": f"{RIGID_BODIES} {conn.topic}",
                                            "_stamps": stamps, "_first_ns": int(stamps[0])})


def _series_from_poses(reader, conns, prefix: str, bag: Path, merge_tolerance: float) -> MocapSeries:
    pattern = re.compile("^" + re.escape(prefix.rstrip("/")) + r"/([^/]+)/pose$")
    body_conns: dict[str, list] = {}
    for c in conns:
        mt = pattern.match(c.topic)
        if mt and c.msgtype == POSE_STAMPED:
            body_conns.setdefault(mt.group(1), []).append(c)
    if not body_conns:
        topics = ", ".join(sorted({c.topic for c in conns})) or "none"
        raise InputError(f"no {MOCAP_FRAME} topic and no {POSE_STAMPED} topics {prefix}/<Body>/pose "
                         f"(bag has: {topics})", path=bag)
    bodies = list(body_conns)
    per_body = []
    for name in bodies:
        raws = [bytes(data) for _, _, data in reader.messages(connections=body_conns[name])]
        try:
            stamp, pos, quat = posestamped_arrays(raws)
        except InputError:   # big-endian or odd encodings: the slow, general route
            msgs = [reader.deserialize(r, POSE_STAMPED) for r in raws]
            stamp = np.array([m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in msgs], np.int64)
            pos = np.array([(m.pose.position.x, m.pose.position.y, m.pose.position.z) for m in msgs]).reshape(-1, 3)
            quat = np.array([(m.pose.orientation.x, m.pose.orientation.y, m.pose.orientation.z,
                              m.pose.orientation.w) for m in msgs]).reshape(-1, 4)
        per_body.append((stamp, pos, quat))
    return _merge_poses(bodies, per_body, prefix, bag, merge_tolerance)


def _merge_poses(bodies: list, per_body: list, prefix: str, bag: Path, merge_tolerance: float) -> MocapSeries:
    """Align per-body PoseStamped ``(stamp_ns, position, quat)`` arrays on their header stamps."""
    all_stamps = np.unique(np.concatenate([s for s, _, _ in per_body]))
    # Merge stamps of one frame that differ by jitter: new frame where the gap exceeds the tolerance.
    periods = [np.median(np.diff(np.unique(s))) for s, _, _ in per_body if np.unique(s).size > 1]
    if all_stamps.size > 1 and periods:
        period = float(np.median(periods))         # per body: one body's stamps are one per frame
        gaps = np.diff(all_stamps) > merge_tolerance * period
        group = np.concatenate([[0], np.cumsum(gaps)])
    else:
        group = np.zeros(all_stamps.size, np.int64)
    starts = np.flatnonzero(np.concatenate([[True], np.diff(group) > 0]))
    frame_stamps = all_stamps[starts]
    n, b = frame_stamps.size, len(bodies)
    position, quat = np.full((b, n, 3), np.nan), np.full((b, n, 4), np.nan)
    tracked = np.zeros((b, n), bool)
    for j, (stamp, pos, q) in enumerate(per_body):
        cols = group[np.searchsorted(all_stamps, stamp)]
        position[j, cols], quat[j, cols], tracked[j, cols] = pos, q, True
    return MocapSeries(np.zeros(n), np.full(n, -1, np.int64), bodies, position, quat, tracked,
                       np.full((b, n), np.nan), name=bag.name,
                       meta={"path": str(bag), "source": f"{POSE_STAMPED} {prefix}/<Body>/pose",
                             "_stamps": frame_stamps, "_first_ns": int(frame_stamps[0])})


# -- fast path: MCAP summary + message indexes, fixed-layout CDR decoded with numpy ---------------------------------

def _align(pos: int, n: int) -> int:
    return (pos + n - 1) // n * n


def _mocapframe_layout(msg: bytes) -> dict | None:
    """CDR layout of one little-endian ``euc_msgs/msg/MocapFrame`` message, or None if unsupported.

    Offsets are row offsets (the 4-byte encapsulation header included); CDR alignment is relative to
    the byte after that header. ``const`` lists the bytes that fix the layout (length and count
    fields, body names): equal in every message, they make all messages share these offsets.
    """
    base = 4
    if len(msg) < base + 12 or msg[0] != 0 or msg[1] != 1:
        return None
    const = [1, 0]                                 # encapsulation kind (checked separately), then fields

    def u32(rel: int) -> int:
        const.extend(range(base + rel, base + rel + 4))
        return struct.unpack_from("<I", msg, base + rel)[0]

    try:
        flen = u32(8)                              # header.stamp sec @0, nanosec @4; frame_id length @8
        pos = 12 + flen
        out = {"stamp_source": base + pos}
        pos = _align(pos + 1, 8)
        out["frame_number"] = base + pos
        pos = _align(pos + 8, 4)
        k = u32(pos)
        pos += 4
        names = []
        for _ in range(k):
            pos = _align(pos, 4)
            n = u32(pos)
            const.extend(range(base + pos + 4, base + pos + 4 + n))
            names.append(msg[base + pos + 4:base + pos + 4 + n].rstrip(b"\0").decode("utf-8"))
            pos += 4 + n
        pos = _align(pos, 4)
        if u32(pos) != k or k == 0:
            return None
        pos = _align(pos + 4, 8)
        out["poses"] = base + pos
        pos = _align(pos + 56 * k, 4)
        if u32(pos) != k:
            return None
        out["tracked"] = base + pos + 4
        pos = _align(pos + 4 + k, 4)
        n_err = u32(pos)
        if n_err not in (0, k):
            n_err = 0                              # the general route ignores errors of another length
            out["err"] = None
        else:
            out["err"] = base + pos + 4 if n_err else None
        pos += 4 + 4 * n_err
    except (struct.error, UnicodeDecodeError):
        return None
    if base + pos > len(msg) or len(set(names)) != k:
        return None
    out.update(k=k, names=names, const=np.asarray(const[2:], np.int64))
    return out


def _frames_fast(msgs, topic: str, bag: Path) -> MocapSeries | None:
    """MocapSeries from MocapFrame messages of one fixed layout (else None: use the general route)."""
    if len(msgs) == 0:
        return None
    lengths = msgs.length
    if np.any(lengths != lengths[0]):
        return None
    lay = _mocapframe_layout(msgs.raw(0))
    if lay is None:
        return None
    rows = msgs.rows()                                         # (n, L) uint8
    const = lay["const"]
    if np.any(rows[:, 0] != 0) or np.any(rows[:, 1] != 1) or np.any(rows[:, const] != rows[0, const]):
        return None
    n, k = rows.shape[0], lay["k"]
    rows = np.ascontiguousarray(rows)
    flat = rows.reshape(-1)

    def field(start: int, dtype: str, shape: tuple = (), strides: tuple = ()) -> np.ndarray:
        # the field of every message, read in place: a strided view of the messages' bytes (no copy)
        return np.ndarray((n,) + shape, dtype=dtype, buffer=flat, offset=start, strides=(rows.shape[1],) + strides)

    sec = field(4, "<i4").astype(np.int64)
    nsec = field(8, "<u4").astype(np.int64)
    stamps = sec * 10**9 + nsec
    numbers = field(lay["frame_number"], "<i8").astype(np.int64)
    vals = field(lay["poses"], "<f8", (k, 7), (56, 8))          # (n, k, 7) view
    trk = rows[:, lay["tracked"]:lay["tracked"] + k] != 0
    err = field(lay["err"], "<f4", (k,), (4,)).astype(float) if lay["err"] is not None else np.full((n, k), np.nan)
    if n > 1 and np.any(stamps[1:] < stamps[:-1]):              # out of order: sorted (stable) by stamp
        order = np.argsort(stamps, kind="stable")
        stamps, numbers, vals, trk, err = stamps[order], numbers[order], vals[order], trk[order], err[order]
    trk_t = np.ascontiguousarray(trk.T)                         # (k, n)
    vals_t = vals.transpose(1, 0, 2)                            # (k, n, 7)
    # C-ordered (body, frame, component) like every other reader's arrays (the analyses read them by block);
    # each written once from the messages' bytes, NaN where a body is not tracked
    untracked = ~trk_t
    position = np.empty((k, n, 3))
    np.copyto(position, vals_t[..., :3])
    position[untracked] = np.nan
    quat = np.empty((k, n, 4))
    np.copyto(quat, vals_t[..., 3:])
    quat[untracked] = np.nan
    del vals, vals_t
    return MocapSeries(np.zeros(n), numbers, list(lay["names"]), position, quat, trk_t,
                       np.ascontiguousarray(err.T), name=bag.name,
                       meta={"path": str(bag), "source": f"{MOCAP_FRAME} {topic}",
                             "_stamps": stamps, "_first_ns": int(stamps[0])})


def _poses_fast(mcap, conns: list, prefix: str, bag: Path, merge_tolerance: float) -> MocapSeries | None:
    """MocapSeries from PoseStamped topics read through the fast MCAP reader (None: use the general route)."""
    pattern = re.compile("^" + re.escape(prefix.rstrip("/")) + r"/([^/]+)/pose$")
    body_cids: dict[str, list] = {}
    for topic, msgtype, cids in conns:
        mt = pattern.match(topic)
        if mt and msgtype == POSE_STAMPED:
            body_cids.setdefault(mt.group(1), []).extend(cids)
    if not body_cids:
        return None                                            # the general route raises the error
    bodies = list(body_cids)
    per_body = []
    for name in bodies:
        msgs = mcap.messages(body_cids[name])
        if msgs is None:
            return None
        n = len(msgs)
        stamp, vals = np.zeros(n, np.int64), np.zeros((n, 7))
        try:
            for length in np.unique(msgs.length):
                idx = np.flatnonzero(msgs.length == length)
                stamp[idx], vals[idx] = _posestamped_rows(msgs.rows(idx))
        except InputError:
            return None
        per_body.append((stamp, vals[:, :3], vals[:, 3:]))
    return _merge_poses(bodies, per_body, prefix, bag, merge_tolerance)


def _read_mocap_fast(bag: Path, info: dict, prefix: str, frame_topic: str | None,
                     merge_tolerance: float) -> MocapSeries | None:
    """:func:`read_mocap_bag` through :mod:`euc_ros.core.io.mcap_fast`; None when the bag needs rosbags.

    Handles one uncompressed, indexed MCAP file whose MocapFrame messages share one CDR layout (or
    PoseStamped topics). Topics are taken in metadata.yaml order, as rosbags lists its connections.
    """
    try:
        files = info.get("relative_file_paths") or []
        topics = info.get("topics_with_message_count") or []
        if len(files) != 1 or (info.get("compression_mode") or "").lower() not in ("", "none") or \
                (info.get("storage_identifier") or "mcap") != "mcap":
            return None
        meta_conns = [(t["topic_metadata"]["name"], t["topic_metadata"]["type"],
                       t["topic_metadata"].get("serialization_format", "cdr")) for t in topics]
    except (AttributeError, KeyError, TypeError):
        return None
    if any(fmt != "cdr" for _, _, fmt in meta_conns):
        return None
    file = bag / str(files[0])
    if not file.is_file():
        return None
    mcap = McapFile(file)
    if mcap.summary is None:
        return None
    channels = mcap.channels.values()
    conns = [(topic, msgtype, [c.id for c in channels if c.topic == topic and c.schema_name == msgtype])
             for topic, msgtype, _ in meta_conns]
    frame_conns = [c for c in conns if c[1] == MOCAP_FRAME]
    if frame_topic is not None:
        frame_conns = [c for c in frame_conns if c[0] == frame_topic][:1]
        if not frame_conns:
            return None                                        # the general route raises the error
    if frame_conns:
        topic, _, cids = frame_conns[0]
        msgs = mcap.messages(cids)
        return None if msgs is None else _frames_fast(msgs, topic, bag)
    if any(c[1] == RIGID_BODIES for c in conns):
        return None                                            # driver messages: the general route
    return _poses_fast(mcap, conns, prefix, bag, merge_tolerance)
