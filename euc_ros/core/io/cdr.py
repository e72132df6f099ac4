"""The CDR primitives every hand-written codec of the project shares.

OMG CDR version 1 (XCDR1), little endian, as rmw_fastrtps writes it: a 4-byte encapsulation header
``00 01 00 00`` (:data:`ENCAPSULATION_LE`), then the message body, whose alignment is counted from the
end of that header (:data:`HEAD`). Primitives are aligned to their own size; a string is a 4-aligned
``uint32`` length including the terminating NUL, the UTF-8 bytes and the NUL; ``std_msgs/Header`` is
``int32 sec, uint32 nanosec, string frame_id``.

The codecs built on these: :mod:`.cdr_flat` (flat messages: RiderState, TorqueEstimate), :mod:`.cdr_frame`
(MocapFrame both ways, PoseStamped, TFMessage) and the vectorized PoseStamped and MocapFrame codecs of
:mod:`.bags`. All of them are checked byte for byte against rosbags' serializer
(``test/unit/core/io/test_cdr_rosbags.py``).
"""
from __future__ import annotations

import struct

import numpy as np

#: Encapsulation header of little-endian CDR (``CDR_LE``, options 0).
ENCAPSULATION_LE = b"\x00\x01\x00\x00"
#: Bytes of the encapsulation header; body offsets (and alignment) count from after them.
HEAD = 4


def pad(offset: int, align: int) -> int:
    """``offset`` (counted after the encapsulation header) rounded up to a multiple of ``align``.

    Parameters
    ----------
    offset : int
        Byte offset after the header.
    align : int
        Alignment [bytes].

    Returns
    -------
    int
        The aligned offset.
    """
    return offset + (-offset) % align


def write_string(out: bytearray, text: str) -> None:
    """Append a CDR string to a message body: 4-aligned ``uint32`` length including the NUL, UTF-8, NUL.

    Parameters
    ----------
    out : bytearray
        The message body, appended to.
    text : str
        The string.
    """
    raw = str(text).encode("utf-8") + b"\x00"
    out += b"\x00" * ((-len(out)) % 4)
    out += struct.pack("<I", len(raw)) + raw


def header_bytes(stamp_ns: int, frame_id: str) -> bytearray:
    """``std_msgs/Header`` at the start of a message body: the stamp [ns] (clamped at 0) and ``frame_id``.

    Parameters
    ----------
    stamp_ns : int
        Header stamp [ns].
    frame_id : str
        Header frame id.

    Returns
    -------
    bytearray
        The header's CDR bytes.
    """
    sec, nsec = divmod(max(int(stamp_ns), 0), 1_000_000_000)
    out = bytearray(struct.pack("<iI", sec, nsec))
    write_string(out, frame_id)
    return out


def split_stamp(stamp_ns: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``builtin_interfaces/Time`` from int64 ns, vectorized: (sec, nanosec), floor division.

    Parameters
    ----------
    stamp_ns : numpy.ndarray
        Stamps [ns], int64.

    Returns
    -------
    sec, nanosec : numpy.ndarray
        Whole seconds and the remaining nanoseconds.
    """
    stamp_ns = np.asarray(stamp_ns, dtype=np.int64)
    return np.floor_divide(stamp_ns, 10**9), np.mod(stamp_ns, 10**9)
