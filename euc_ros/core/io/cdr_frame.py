"""``euc_msgs/MocapFrame`` <-> CDR bytes with numpy: the live path's per-frame message, without Python objects.

Building a MocapFrame through the generated Python class costs one ``geometry_msgs/Pose`` object per
body (about 250 us for 14 bodies, more than a 360 Hz frame period's share), and reading one back costs
as much. The message's serialized form is simple, so this module writes and reads it directly:
the publisher sends the bytes (``Publisher.publish(bytes)``), the subscriber takes them raw.

Layout (OMG CDR version 1, little endian, as rmw_fastrtps writes it; alignment counted from the end
of the 4-byte encapsulation header ``00 01 00 00``)::

    int32 sec, uint32 nanosec             header.stamp
    string frame_id                       uint32 length incl. NUL, bytes, NUL
    uint8 stamp_source
    int64 frame_number                    8-aligned
    sequence<string> body_names           uint32 count (4-aligned), strings as above (4-aligned)
    sequence<Pose> poses                  uint32 count, then 7 float64 per pose (8-aligned)
    sequence<bool> tracked                uint32 count, 1 byte each
    sequence<float32> mean_marker_error   uint32 count, float32 each (4-aligned)

:func:`decode` reads little-endian CDR of exactly this layout and raises :class:`CdrError` on
anything else (big endian, truncated, inconsistent counts), so a caller can fall back to the
generic deserializer. Both directions are tested against rclpy's serializer
(``test/unit/core/io/test_cdr_frame.py``) and rosbags' (``test/unit/core/io/test_cdr_rosbags.py``); the primitives
(encapsulation, alignment, strings, header) are those of :mod:`.cdr`.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

from euc_ros.core.io.cdr import ENCAPSULATION_LE, HEAD, header_bytes, pad, write_string


class CdrError(ValueError):
    """The bytes are not a little-endian CDR MocapFrame this module can read."""



@dataclass(frozen=True)
class _Template:
    """The constant part of a frame for one (frame_id, bodies): the bytes and where the variable fields go."""

    data: bytes
    stamp_source_at: int
    frame_number_at: int
    poses_at: int
    tracked_at: int
    error_at: int


class FrameEncoder:
    """Serialize frames of a fixed body list (cached per ``(frame_id, bodies)``).

    Examples
    --------
    >>> import numpy as np
    >>> enc = FrameEncoder()
    >>> raw = enc.encode(1_500_000_000, "world", 1, 7, ["E"], np.zeros((1, 3)), np.array([[0, 0, 0, 1.0]]),
    ...                  np.array([True]), np.array([0.0002]))
    >>> decode(raw).frame_number, decode(raw).bodies
    (7, ['E'])
    """

    def __init__(self) -> None:
        self._key: tuple | None = None
        self._t: _Template | None = None

    def _template(self, frame_id: str, bodies: list[str]) -> _Template:
        key = (frame_id, tuple(bodies))
        if key != self._key:
            body = bytearray(8)                          # stamp, written per frame
            write_string(body, frame_id)
            stamp_source_at = len(body)
            body += b"\x00"
            body += b"\x00" * ((-len(body)) % 8)
            frame_number_at = len(body)
            body += b"\x00" * 8
            body += struct.pack("<I", len(bodies))
            for name in bodies:
                write_string(body, name)
            body += b"\x00" * ((-len(body)) % 4)
            body += struct.pack("<I", len(bodies))
            body += b"\x00" * ((-len(body)) % 8)
            poses_at = len(body)
            body += b"\x00" * (56 * len(bodies))
            body += struct.pack("<I", len(bodies))
            tracked_at = len(body)
            body += b"\x00" * len(bodies)
            body += b"\x00" * ((-len(body)) % 4)
            body += struct.pack("<I", len(bodies))
            error_at = len(body)
            body += b"\x00" * (4 * len(bodies))
            self._key, self._t = key, _Template(bytes(body), stamp_source_at, frame_number_at, poses_at,
                                                tracked_at, error_at)
        return self._t

    def encode(self, stamp_ns: int, frame_id: str, stamp_source: int, frame_number: int, bodies, position,
               quat, tracked, mean_marker_error) -> bytes:
        """The CDR bytes of one MocapFrame (NaN poses stay NaN; negative stamps clamp to 0).

        Parameters
        ----------
        stamp_ns : int
            Header stamp [ns].
        frame_id : str
        stamp_source : int
            One of the message's ``STAMP_*`` constants.
        frame_number : int
        bodies : sequence of str
        position : array_like (n, 3)
        quat : array_like (n, 4)
            x, y, z, w.
        tracked : array_like (n,) of bool
        mean_marker_error : array_like (n,)

        Returns
        -------
        bytes
            The message, encapsulation header included.
        """
        bodies = list(bodies)
        t = self._template(frame_id, bodies)
        n = len(bodies)
        buf = bytearray(t.data)
        sec, nsec = divmod(max(int(stamp_ns), 0), 1_000_000_000)
        struct.pack_into("<iI", buf, 0, sec, nsec)
        buf[t.stamp_source_at] = int(stamp_source) & 0xFF
        struct.pack_into("<q", buf, t.frame_number_at, int(frame_number))
        poses = np.empty((n, 7), dtype="<f8")
        poses[:, :3] = np.asarray(position, dtype=float).reshape(n, 3)
        poses[:, 3:] = np.asarray(quat, dtype=float).reshape(n, 4)
        buf[t.poses_at:t.poses_at + 56 * n] = poses.tobytes()
        buf[t.tracked_at:t.tracked_at + n] = np.asarray(tracked, dtype=bool).reshape(n).astype(np.uint8).tobytes()
        buf[t.error_at:t.error_at + 4 * n] = np.asarray(mean_marker_error, dtype="<f4").reshape(n).tobytes()
        return ENCAPSULATION_LE + bytes(buf)


@dataclass
class DecodedFrame:
    """A MocapFrame's fields as arrays.

    Parameters
    ----------
    stamp_ns : int
        Header stamp [ns].
    frame_id : str
        Header frame id.
    stamp_source : int
        One of the message's ``STAMP_*`` constants.
    frame_number : int
        Frame number (-1: unknown).
    bodies : list of str
        Body names.
    position : numpy.ndarray
        Pivot positions (n, 3) [m].
    quat : numpy.ndarray
        Quaternions (n, 4), (x, y, z, w).
    tracked : numpy.ndarray
        Tracked flags (n,).
    mean_marker_error : numpy.ndarray
        Mean marker errors (n,) [m].
    """

    stamp_ns: int
    frame_id: str
    stamp_source: int
    frame_number: int
    bodies: list[str]
    position: np.ndarray        # (n, 3)
    quat: np.ndarray            # (n, 4)
    tracked: np.ndarray         # (n,) bool
    mean_marker_error: np.ndarray  # (n,) float


class _Reader:
    def __init__(self, raw: bytes) -> None:
        self.raw = raw
        self.pos = 0          # counted after the encapsulation header

    def need(self, n: int) -> int:
        at = HEAD + self.pos
        if n < 0 or at + n > len(self.raw):
            raise CdrError(f"truncated MocapFrame: {n} bytes wanted at byte {at} of {len(self.raw)}")
        self.pos += n
        return at

    def align(self, a: int) -> None:
        self.pos = pad(self.pos, a)

    def u32(self) -> int:
        self.align(4)
        return struct.unpack_from("<I", self.raw, self.need(4))[0]

    def string(self) -> str:
        n = self.u32()
        if n == 0:
            raise CdrError("string without its terminating NUL")
        at = self.need(n)
        if self.raw[at + n - 1] != 0:
            raise CdrError("string without its terminating NUL")
        return self.raw[at:at + n - 1].decode("utf-8")

    def count(self, item_size: int) -> int:
        n = self.u32()
        if n * item_size > len(self.raw):
            raise CdrError(f"sequence of {n} items is longer than the message")
        return n


_NAMES_CACHE: dict[bytes, list[str]] = {}


def decode(raw: bytes) -> DecodedFrame:
    """Read the CDR bytes of a MocapFrame (see the module docstring); raises :class:`CdrError`.

    Parameters
    ----------
    raw : bytes
        The serialized message, encapsulation header included.

    Returns
    -------
    DecodedFrame
        Its fields.
    """
    raw = bytes(raw)
    if raw[:2] != ENCAPSULATION_LE[:2]:
        raise CdrError(f"not little-endian CDR (encapsulation {raw[:4].hex()})")
    r = _Reader(raw)
    sec, nsec = struct.unpack_from("<iI", raw, r.need(8))
    frame_id = r.string()
    stamp_source = raw[r.need(1)]
    r.align(8)
    frame_number = struct.unpack_from("<q", raw, r.need(8))[0]
    names_start = HEAD + r.pos
    n_names = r.count(5)
    for _ in range(n_names):
        r.string()
    key = raw[names_start:HEAD + r.pos]
    bodies = _NAMES_CACHE.get(key)
    if bodies is None:
        rr = _Reader(raw)
        rr.pos = names_start - HEAD
        bodies = [rr.string() for _ in range(rr.count(5))]
        if len(_NAMES_CACHE) > 64:
            _NAMES_CACHE.clear()
        _NAMES_CACHE[key] = bodies
    n_poses = r.count(56)
    r.align(8)
    poses = np.frombuffer(raw, dtype="<f8", count=7 * n_poses, offset=r.need(56 * n_poses)).reshape(n_poses, 7)
    n_tracked = r.count(1)
    tracked = np.frombuffer(raw, dtype=np.uint8, count=n_tracked, offset=r.need(n_tracked)).astype(bool)
    n_err = r.count(4)
    err = np.frombuffer(raw, dtype="<f4", count=n_err, offset=r.need(4 * n_err)).astype(float)
    return DecodedFrame(sec * 1_000_000_000 + nsec, frame_id, int(stamp_source), int(frame_number), list(bodies),
                        poses[:, :3].astype(float), poses[:, 3:].astype(float), tracked, err)


def pose_stamped(stamp_ns: int, frame_id: str, position, quat) -> bytes:
    """CDR bytes of one ``geometry_msgs/PoseStamped`` (position (3,), quaternion (4,) x, y, z, w).

    Parameters
    ----------
    stamp_ns : int
        Header stamp [ns].
    frame_id : str
        Header frame id.
    position : array_like
        Position (3,) [m].
    quat : array_like
        Quaternion (4,), (x, y, z, w).

    Returns
    -------
    bytes
        The message, encapsulation header included.
    """
    body = header_bytes(stamp_ns, frame_id)
    body += b"\x00" * ((-len(body)) % 8)
    body += np.concatenate([np.asarray(position, dtype="<f8").reshape(3),
                            np.asarray(quat, dtype="<f8").reshape(4)]).tobytes()
    return ENCAPSULATION_LE + bytes(body)


def tf_message(stamp_ns: int, parent: str, children, position, quat) -> bytes:
    """CDR bytes of one ``tf2_msgs/TFMessage``: ``parent`` -> each child at positions (k, 3), quaternions (k, 4).

    Parameters
    ----------
    stamp_ns : int
        Stamp of every transform [ns].
    parent : str
        Parent frame id.
    children : sequence of str
        Child frame ids (k).
    position : array_like
        Translations (k, 3) [m].
    quat : array_like
        Rotations (k, 4), (x, y, z, w).

    Returns
    -------
    bytes
        The message, encapsulation header included.
    """
    children = list(children)
    position = np.asarray(position, dtype="<f8").reshape(len(children), 3)
    quat = np.asarray(quat, dtype="<f8").reshape(len(children), 4)
    sec, nsec = divmod(max(int(stamp_ns), 0), 1_000_000_000)
    body = bytearray(struct.pack("<I", len(children)))
    for i, child in enumerate(children):
        body += b"\x00" * ((-len(body)) % 4)
        body += struct.pack("<iI", sec, nsec)
        write_string(body, parent)
        write_string(body, child)
        body += b"\x00" * ((-len(body)) % 8)
        body += position[i].tobytes() + quat[i].tobytes()
    return ENCAPSULATION_LE + bytes(body)
