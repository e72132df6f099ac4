r"""Minimal, ROS-free MCAP reader for indexed files with uncompressed chunks, vectorized with numpy.

Reads what :func:`euc_ros.core.io.bags.read_mocap_bag` needs from a rosbag2 MCAP file without a
per-message Python loop: the summary section (schemas, channels, chunk indexes), then, per chunk,
the message index record of each wanted channel, which lists the offsets of that channel's message
records inside the chunk. Record headers are then read for all messages at once with numpy.

MCAP layout used (https://mcap.dev/spec): magic ``\x89MCAP0\r\n``; records ``opcode uint8,
length uint64, content``; the file ends with a Footer record (``summary_start uint64,
summary_offset_start uint64, summary_crc uint32``) and the magic. Opcodes: 0x03 Schema, 0x04
Channel, 0x05 Message (``channel_id uint16, sequence uint32, log_time uint64, publish_time uint64,
data``), 0x06 Chunk, 0x07 MessageIndex (``channel_id uint16, array of (log_time uint64, offset
uint64)``), 0x08 ChunkIndex. All integers little-endian.

Anything this reader does not handle (no summary, no chunk indexes, compressed chunks, chunks
without message indexes, inconsistent offsets) makes :func:`read_channels` return ``None``: the
caller falls back to a general reader (rosbags). Chunk CRCs are not verified (``check_bag`` does).

See ``docs/mcap_fast.md``.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

MAGIC = b"\x89MCAP0\r\n"
OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK, OP_MESSAGE_INDEX, OP_CHUNK_INDEX = 0x03, 0x04, 0x05, 0x06, 0x07, 0x08
#: Message record header: opcode (1) + record length (8) + channel_id (2) + sequence (4) + log_time (8)
#: + publish_time (8) [bytes].
MESSAGE_HEADER = 31


class _Unsupported(Exception):
    """The file needs the general reader."""


@dataclass(frozen=True)
class Channel:
    """An MCAP channel with its schema name (the ROS message type for ros2msg schemas).

    Parameters
    ----------
    id : int
        Channel id.
    topic : str
        Topic name.
    schema_name : str
        Schema name ("" when the channel has no schema).
    message_encoding : str
        Message encoding, e.g. ``cdr``.
    """

    id: int
    topic: str
    schema_name: str
    message_encoding: str


@dataclass(frozen=True)
class _ChunkIndex:
    start: int                  # file offset of the Chunk record
    length: int                 # Chunk record length incl. opcode and length field [bytes]
    index_offsets: dict         # channel id -> file offset of its MessageIndex record
    compression: str
    uncompressed_size: int


@dataclass
class Summary:
    """Channels and chunk indexes of an MCAP file (from its summary section).

    Parameters
    ----------
    channels : dict of int to Channel
        Channels by id.
    chunks : list
        Chunk indexes, by start offset.
    """

    channels: dict
    chunks: list


@dataclass
class Messages:
    """Messages of a set of channels, in the order rosbags yields them (log time, then file order).

    Parameters
    ----------
    buf : ndarray of uint8
        The file's bytes (read-only memory map).
    log_time : ndarray (n,) of int64
        MCAP log (receive) times [ns].
    channel : ndarray (n,) of int64
        Channel id of each message.
    offset : ndarray (n,) of int64
        File offset of each message's serialized data (the CDR bytes).
    length : ndarray (n,) of int64
        Length of each message's data [bytes].
    """

    buf: np.ndarray
    log_time: np.ndarray
    channel: np.ndarray
    offset: np.ndarray
    length: np.ndarray

    def __len__(self) -> int:
        return int(self.offset.shape[0])

    def rows(self, idx=None) -> np.ndarray:
        """Data of messages ``idx`` (default all), which must share one length, as an (m, L) uint8 copy.

        Parameters
        ----------
        idx : array_like of int, optional
            Message indices; default all.

        Returns
        -------
        numpy.ndarray
            The data (m, L), uint8.

        Raises
        ------
        ValueError
            When the messages differ in length.
        """
        off = self.offset if idx is None else self.offset[idx]
        lens = self.length if idx is None else self.length[idx]
        if off.size == 0:
            return np.zeros((0, 0), np.uint8)
        length = int(lens[0])
        if np.any(lens != length):
            raise ValueError("messages of different lengths")
        if length == 0:
            return np.zeros((off.size, 0), np.uint8)
        return sliding_window_view(self.buf, length)[off]

    def raw(self, i: int) -> bytes:
        """Data of message ``i``.

        Parameters
        ----------
        i : int
            Message index.

        Returns
        -------
        bytes
            Its serialized data.
        """
        o = int(self.offset[i])
        return self.buf[o:o + int(self.length[i])].tobytes()


def _string(data: bytes, pos: int) -> tuple[str, int]:
    (n,) = struct.unpack_from("<I", data, pos)
    return data[pos + 4:pos + 4 + n].decode("utf-8"), pos + 4 + n


def _parse_summary(buf: np.ndarray) -> Summary:
    size = buf.shape[0]
    if size < 2 * len(MAGIC) + 29 or bytes(buf[:8]) != MAGIC or bytes(buf[size - 8:]) != MAGIC:
        raise _Unsupported("no MCAP magic at both ends")
    footer = bytes(buf[size - 8 - 29:size - 8])
    if footer[0] != 0x02 or struct.unpack_from("<Q", footer, 1)[0] != 20:
        raise _Unsupported("no footer record")
    summary_start, summary_offset_start, _ = struct.unpack_from("<QQI", footer, 9)
    if summary_start == 0:
        raise _Unsupported("no summary section")
    end = summary_offset_start if summary_offset_start else size - 8 - 29
    if not len(MAGIC) <= summary_start <= end <= size:
        raise _Unsupported("summary offsets out of range")
    data = bytes(buf[summary_start:end])
    schemas: dict[int, str] = {}
    raw_channels = []
    chunks = []
    pos = 0
    while pos + 9 <= len(data):
        op, length = data[pos], struct.unpack_from("<Q", data, pos + 1)[0]
        body = pos + 9
        pos = body + length
        if pos > len(data):
            raise _Unsupported("truncated summary record")
        if op == OP_SCHEMA:
            (sid,) = struct.unpack_from("<H", data, body)
            schemas[sid] = _string(data, body + 2)[0]
        elif op == OP_CHANNEL:
            cid, sid = struct.unpack_from("<HH", data, body)
            topic, p = _string(data, body + 4)
            encoding, _ = _string(data, p)
            raw_channels.append((cid, sid, topic, encoding))
        elif op == OP_CHUNK_INDEX:
            _, _, start, clen, map_len = struct.unpack_from("<QQQQI", data, body)
            p = body + 36
            entries = np.frombuffer(data, np.uint8, map_len, p)
            p += map_len
            if map_len % 10:
                raise _Unsupported("bad message index offsets map")
            pairs = entries.reshape(-1, 10)
            cids = pairs[:, :2].copy().view("<u2")[:, 0].tolist()
            offs = pairs[:, 2:].copy().view("<u8")[:, 0].tolist()
            (index_len,) = struct.unpack_from("<Q", data, p)
            compression, p = _string(data, p + 8)
            _, uncompressed = struct.unpack_from("<QQ", data, p)
            if index_len == 0 and cids:
                raise _Unsupported("chunk without message index records")
            chunks.append(_ChunkIndex(int(start), int(clen), dict(zip(cids, offs)), compression, int(uncompressed)))
    channels = {cid: Channel(cid, topic, schemas.get(sid, ""), enc) for cid, sid, topic, enc in raw_channels}
    if not channels or not chunks:
        raise _Unsupported("summary without channels or chunk indexes")
    chunks.sort(key=lambda c: c.start)
    return Summary(channels, chunks)


def _u64_at(buf: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Little-endian uint64 at each file offset, as int64."""
    return sliding_window_view(buf, 8)[offsets].copy().view("<u8")[:, 0].astype(np.int64)


def _collect(buf: np.ndarray, summary: Summary, channel_ids) -> Messages:
    wanted = [int(c) for c in channel_ids]
    size = buf.shape[0]
    parts = []
    for chunk in summary.chunks:
        if not any(c in chunk.index_offsets for c in wanted):
            continue
        if chunk.compression:
            raise _Unsupported(f"{chunk.compression} chunk")
        if chunk.start + chunk.length > size or buf[chunk.start] != OP_CHUNK:
            raise _Unsupported("chunk index does not point at a chunk")
        comp_len = int(struct.unpack_from("<I", buf, chunk.start + 9 + 28)[0])
        records = chunk.start + 9 + 32 + comp_len + 8
        (records_len,) = struct.unpack_from("<Q", buf, records - 8)
        if records_len != chunk.uncompressed_size or records + records_len > chunk.start + chunk.length:
            raise _Unsupported("chunk sizes inconsistent")
        for cid in wanted:
            mi = chunk.index_offsets.get(cid)
            if mi is None:
                continue
            if mi + 15 > size or buf[mi] != OP_MESSAGE_INDEX:
                raise _Unsupported("message index offset does not point at a message index")
            mcid, arr_len = struct.unpack_from("<HI", buf, mi + 9)
            if mcid != cid or arr_len % 16 or mi + 15 + arr_len > size:
                raise _Unsupported("bad message index record")
            pairs = np.frombuffer(buf, "<u8", arr_len // 8, mi + 15).reshape(-1, 2)
            rel = pairs[:, 1].astype(np.int64)
            if rel.size and (rel.min() < 0 or rel.max() + MESSAGE_HEADER > records_len):
                raise _Unsupported("message offsets outside the chunk")
            parts.append((records + rel, np.full(rel.size, cid, np.int64), records + records_len))
    if not parts:
        empty = np.zeros(0, np.int64)
        return Messages(buf, empty, empty.copy(), empty.copy(), empty.copy())
    rec = np.concatenate([p[0] for p in parts])
    chan = np.concatenate([p[1] for p in parts])
    limit = np.concatenate([np.full(p[0].size, p[2], np.int64) for p in parts])
    order = np.argsort(rec, kind="stable")                       # file order
    rec, chan, limit = rec[order], chan[order], limit[order]
    head = sliding_window_view(buf, MESSAGE_HEADER)[rec]         # (n, 31) record headers
    if np.any(head[:, 0] != OP_MESSAGE):
        raise _Unsupported("message index points at a non-message record")
    reclen = head[:, 1:9].copy().view("<u8")[:, 0].astype(np.int64)
    if np.any(head[:, 9:11].copy().view("<u2")[:, 0] != chan):
        raise _Unsupported("message record of another channel")
    length = reclen - (MESSAGE_HEADER - 9)
    offset = rec + MESSAGE_HEADER
    if np.any(length < 0) or np.any(offset + length > limit):
        raise _Unsupported("message record exceeds its chunk")
    log_time = head[:, 15:23].copy().view("<u8")[:, 0].astype(np.int64)
    order = np.argsort(log_time, kind="stable")                  # rosbags: by log time, ties in file order
    return Messages(buf, log_time[order], chan[order], offset[order], length[order])


class McapFile:
    """An MCAP file opened for fast reading (memory-mapped).

    Parameters
    ----------
    path : str or Path

    Attributes
    ----------
    summary : Summary or None
        None when the file needs the general reader (no summary, no chunk indexes...).
    """

    def __init__(self, path) -> None:
        self.path = Path(path)
        self.summary = None
        try:
            self.buf = np.memmap(self.path, dtype=np.uint8, mode="r")
        except (OSError, ValueError):               # unreadable or empty (numpy cannot map 0 bytes)
            self.buf = np.zeros(0, np.uint8)
            return
        try:
            self.summary = _parse_summary(self.buf)
        except (_Unsupported, struct.error, ValueError, UnicodeDecodeError):
            self.summary = None

    @property
    def channels(self) -> dict:
        """Channel id -> :class:`Channel` (empty without a summary)."""
        return {} if self.summary is None else dict(self.summary.channels)

    def messages(self, channel_ids) -> Messages | None:
        """Messages of ``channel_ids`` merged in rosbags' order, or None when unsupported here.

        Parameters
        ----------
        channel_ids : iterable of int
            The channels.

        Returns
        -------
        Messages or None
            The messages, or None.
        """
        if self.summary is None:
            return None
        try:
            return _collect(self.buf, self.summary, channel_ids)
        except (_Unsupported, struct.error, ValueError, IndexError):
            return None


def read_channels(path, channel_ids) -> Messages | None:
    """Messages of some channels of an MCAP file, or None when the file needs the general reader.

    Parameters
    ----------
    path : str or Path
        ``.mcap`` file.
    channel_ids : iterable of int

    Returns
    -------
    Messages or None
    """
    return McapFile(path).messages(channel_ids)
