"""CDR bytes of flat messages without message objects: the live path's RiderState and TorqueEstimate at up to 500 Hz.

A flat message is a header, then booleans, float64s, strings and nested float64 structs.

Publishing a message object through rclpy converts every field from Python to C and then serializes it;
for a RiderState that costs about twice a publication of the same message as bytes (measured on this
machine class with a subscriber in another process), and the object's construction (one checked
``setattr`` per field) comes on top. The layout of these messages is simple, so :class:`FlatEncoder`
writes it directly with the shared primitives of :mod:`.cdr` (OMG CDR version 1, little endian, as
rmw_fastrtps writes it; alignment counted from the end of the 4-byte encapsulation header ``00 01 00 00``)::

    std_msgs/Header   int32 sec, uint32 nanosec, string frame_id
    bool              1 byte
    float64           8-aligned, little endian
    string            4-aligned uint32 length including the NUL, UTF-8 bytes, NUL

The field list is a message definition's ``(name, type)`` pairs, with nested float64-only structs
(``geometry_msgs/Point``) already expanded into their fields (the node layer reads both from the
generated class, :func:`euc_ros.ros.convert.flat_fields`). Tested byte for byte against rclpy's
serializer (``test/unit/core/io/test_cdr_flat.py``) and rosbags' (``test/unit/core/io/test_cdr_rosbags.py``).
"""
from __future__ import annotations

import struct
from typing import Sequence

from euc_ros.core.io.cdr import ENCAPSULATION_LE, header_bytes, write_string

_KINDS = ("bool", "float64", "string")


class FlatEncoder:
    r"""Serialize one flat message type from field values given in definition order.

    Parameters
    ----------
    fields : sequence of (name, kind)
        The fields after the header, in the message's order; ``kind`` is ``"bool"``, ``"float64"`` or
        ``"string"``.

    Examples
    --------
    >>> enc = FlatEncoder([("ok", "bool"), ("a", "float64"), ("b", "float64"), ("s", "string")])
    >>> raw = enc.encode(1_500_000_000, "world", (True, 1.0, 2.0, "hi"))
    >>> len(raw), raw[:4]
    (51, b'\x00\x01\x00\x00')
    """

    def __init__(self, fields: Sequence[tuple[str, str]]) -> None:
        self.names = tuple(name for name, _ in fields)
        ops: list[tuple[str, int, int, struct.Struct | None]] = []   # (kind, first index, count, packer)
        for i, (name, kind) in enumerate(fields):
            if kind not in _KINDS:
                raise ValueError(f"field {name!r}: kind {kind!r} is not one of {_KINDS}")
            if kind == "float64" and ops and ops[-1][0] == "float64":
                k, first, count, _ = ops[-1]
                ops[-1] = (k, first, count + 1, None)
            else:
                ops.append((kind, i, 1, None))
        self._ops = [(k, first, count, struct.Struct(f"<{count}d") if k == "float64" else None)
                     for k, first, count, _ in ops]
        self.n_fields = len(self.names)

    def encode(self, stamp_ns: int, frame_id: str, values: Sequence) -> bytes:
        """The CDR bytes: header, then ``values`` in the order of the fields.

        The header holds ``stamp_ns`` [ns], clamped at 0, and ``frame_id``; floats are written as float64, NaN
        kept; booleans as 0/1.

        Parameters
        ----------
        stamp_ns : int
            Header stamp [ns].
        frame_id : str
            Header frame id.
        values : sequence
            One value per field.

        Returns
        -------
        bytes
            The message, encapsulation header included.

        Raises
        ------
        ValueError
            When the number of values is not the number of fields.
        """
        if len(values) != self.n_fields:
            raise ValueError(f"expected {self.n_fields} values ({', '.join(self.names)}), got {len(values)}")
        out = header_bytes(stamp_ns, frame_id)
        for kind, first, count, packer in self._ops:
            if kind == "float64":
                out += b"\x00" * ((-len(out)) % 8)
                out += packer.pack(*values[first:first + count])
            elif kind == "bool":
                out.append(1 if values[first] else 0)
            else:
                write_string(out, values[first])
        return ENCAPSULATION_LE + bytes(out)
