"""NatNet depacketizer: OptiTrack Motive's UDP streaming protocol, versions 3.0, 3.1, 4.0 and 4.1.

Pure functions on bytes, no sockets (the socket side is :mod:`euc_ros.core.io.natnet_client`).
Written from the protocol as the NatNet SDK samples lay it out (PacketClient.cpp and the Python
sample NatNetClient.py of SDK 4.0/4.1), not copied from them; see ``docs/natnet.md``.

Packet
------
Every packet starts with ``uint16 message_id, uint16 payload_size`` (little endian), then the payload.
All numbers are little endian; strings are NUL-terminated UTF-8; floats are IEEE-754 single precision
unless noted.

Versions (what changes between the four we handle)
--------------------------------------------------
* 3.0 and 3.1: identical layouts. Rigid bodies in frames carry no marker lists (removed in 3.0);
  the frame suffix has the three uint64 high-resolution timestamps.
* 4.0: rigid-body descriptions in MODELDEF also carry one name per marker. Frames as 3.x.
* 4.1: every frame section count is followed by an ``int32`` byte count of that section; an asset
  section (count, byte count, assets) sits between skeletons and labeled markers; the frame suffix
  gains the precision timestamp (``uint32`` seconds, ``uint32`` fractional seconds) after the
  transmit timestamp; every MODELDEF dataset gains an ``int32`` byte count after its type.
  Later 4.x minors are read with the 4.1 layout, skipping sections other than rigid bodies by their
  byte counts.

Errors
------
Malformed or truncated input raises :class:`NatNetError` (an :class:`~euc_ros.core.errors.InputError`)
naming the byte offset and the field being read; no ``IndexError`` or ``struct.error`` escapes.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass, field

import numpy as np

from euc_ros.core.errors import InputError

# Message ids (client <-> server).
NAT_CONNECT = 0
NAT_SERVERINFO = 1
NAT_REQUEST = 2
NAT_RESPONSE = 3
NAT_REQUEST_MODELDEF = 4
NAT_MODELDEF = 5
NAT_REQUEST_FRAMEOFDATA = 6
NAT_FRAMEOFDATA = 7
NAT_MESSAGESTRING = 8
NAT_DISCONNECT = 9
NAT_KEEPALIVE = 10
NAT_UNRECOGNIZED_REQUEST = 100

MESSAGE_NAMES = {
    NAT_CONNECT: "CONNECT", NAT_SERVERINFO: "SERVERINFO", NAT_REQUEST: "REQUEST", NAT_RESPONSE: "RESPONSE",
    NAT_REQUEST_MODELDEF: "REQUEST_MODELDEF", NAT_MODELDEF: "MODELDEF",
    NAT_REQUEST_FRAMEOFDATA: "REQUEST_FRAMEOFDATA", NAT_FRAMEOFDATA: "FRAMEOFDATA",
    NAT_MESSAGESTRING: "MESSAGESTRING", NAT_DISCONNECT: "DISCONNECT", NAT_KEEPALIVE: "KEEPALIVE",
    NAT_UNRECOGNIZED_REQUEST: "UNRECOGNIZED_REQUEST",
}

#: Message ids a client sends (parsed into :class:`Request`).
CLIENT_REQUEST_IDS = (NAT_CONNECT, NAT_REQUEST, NAT_REQUEST_MODELDEF, NAT_REQUEST_FRAMEOFDATA,
                      NAT_DISCONNECT, NAT_KEEPALIVE)

#: Versions whose layout is verified by this module's golden-frame tests.
SUPPORTED_VERSIONS = ((3, 0), (3, 1), (4, 0), (4, 1))

#: SERVERINFO payload: 256-byte name, app version [4], NatNet version [4] (sSender) ...
SENDER_SIZE = 256 + 4 + 4
#: ... then uint64 clock frequency, uint16 data port, uint8 multicast flag, 4-byte group (sSender_Server).
SENDER_SERVER_SIZE = SENDER_SIZE + 8 + 2 + 1 + 4

# Sizes of fixed records [bytes].
RIGID_BODY_SIZE = 4 + 12 + 16 + 4 + 2       # id, pos xyz, quat xyzw, mean error, params
LABELED_MARKER_SIZE = 4 + 12 + 4 + 2 + 4    # id, pos, size, params, residual (3.0+)
ASSET_MARKER_SIZE = 4 + 12 + 4 + 2 + 4      # id, pos, size, params, residual
#: Plausibility cap on any element count (a corrupted count must not drive a huge loop).
MAX_COUNT = 100_000


class NatNetError(InputError):
    """A NatNet packet that cannot be decoded.

    Parameters
    ----------
    offset : int or None
        Byte offset in the packet (header included) where decoding failed.
    field : str or None
        Field being decoded, e.g. ``'rigid_bodies[2].quat'``.
    message_id : int or None
        Message id from the packet header, when it could be read.
    message : str
        What is wrong.
    """

    def __init__(self, message: str, *, offset: int | None = None, field: str | None = None,
                 message_id: int | None = None) -> None:
        self.offset = offset
        self.field = field
        self.message_id = message_id
        where = []
        if message_id is not None:
            where.append(f"NatNet {MESSAGE_NAMES.get(message_id, f'message {message_id}')}")
        else:
            where.append("NatNet packet")
        if offset is not None:
            where.append(f"byte {offset}")
        super().__init__(f"{', '.join(where)}: {message}", key=field)


# ---------------------------------------------------------------------------------------------------------------------
# Messages
# ---------------------------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ServerInfo:
    """SERVERINFO (reply to CONNECT): who the server is and how it streams.

    Parameters
    ----------
    app_name : str
        Server application, e.g. ``'Motive'``.
    app_version : tuple of 4 int
        Application version (major, minor, build, revision).
    natnet_version : tuple of 4 int
        NatNet stream version the server uses; decides the packet layout.
    high_res_clock_frequency : int or None
        Ticks per second of the server clock behind the frame-suffix timestamps [Hz]; None when
        the server sent only the short (pre-3.0) form.
    connection_multicast : bool or None
        True when the server streams frames to a multicast group.
    multicast_address : str or None
        Dotted multicast group address.
    data_port : int or None
        UDP port the server streams frames to.
    """

    app_name: str
    app_version: tuple
    natnet_version: tuple
    high_res_clock_frequency: int | None
    connection_multicast: bool | None
    multicast_address: str | None
    data_port: int | None

    @property
    def version(self) -> tuple[int, int]:
        """``(major, minor)`` of the NatNet stream, the key of :func:`parse_packet`."""
        return (int(self.natnet_version[0]), int(self.natnet_version[1]))


@dataclass(frozen=True)
class ModelDef:
    """MODELDEF (data descriptions): names of what the server streams.

    Parameters
    ----------
    rigid_bodies : dict of int to str
        Rigid-body streaming id -> name.
    parents : dict of int to int
        Rigid-body id -> parent id (-1: none).
    offsets : dict of int to ndarray (3,)
        Rigid-body id -> offset from its parent [m].
    marker_sets : list of str
        Marker-set names.
    skeletons : dict of int to str
        Skeleton id -> name.
    assets : dict of int to str
        Asset id -> name (4.1+).
    n_force_plates, n_devices, n_cameras : int
        Counts of the other descriptions (skipped).
    """

    rigid_bodies: dict
    parents: dict = field(default_factory=dict)
    offsets: dict = field(default_factory=dict)
    marker_sets: list = field(default_factory=list)
    skeletons: dict = field(default_factory=dict)
    assets: dict = field(default_factory=dict)
    n_force_plates: int = 0
    n_devices: int = 0
    n_cameras: int = 0


@dataclass(frozen=True)
class RigidBodyData:
    """One rigid body in a frame, exactly as streamed (Motive's world axes, usually Y-up).

    Parameters
    ----------
    id : int
        Streaming id (name via :attr:`ModelDef.rigid_bodies`).
    position : ndarray (3,)
        Pivot position [m].
    quat : ndarray (4,)
        Orientation quaternion (x, y, z, w), body to world.
    mean_error : float
        Mean marker error [m].
    tracking_valid : bool
        Bit 0x01 of the rigid body's params: tracked in this frame. When False the pose is stale or
        zero and must be treated as a gap.
    """

    id: int
    position: np.ndarray
    quat: np.ndarray
    mean_error: float
    tracking_valid: bool


@dataclass(frozen=True)
class FrameOfData:
    """FRAMEOFDATA: one motion-capture frame.

    Parameters
    ----------
    frame_number : int
        Motive frame number.
    rigid_bodies : list of RigidBodyData
    timecode, timecode_sub : int
        SMPTE timecode and subframe (0 without a timecode generator).
    timestamp : float
        Server software timestamp [s] since Motive started.
    camera_mid_exposure : int
        Server clock at the middle of the camera exposure [ticks]; 0 when unavailable.
    camera_data_received : int
        Server clock when the camera data arrived [ticks].
    transmit_timestamp : int
        Server clock just before the frame was sent [ticks].
    precision_timestamp_sec, precision_timestamp_frac : int
        Precision (e.g. PTP) timestamp, whole seconds and the raw fractional field (4.1+; 0 otherwise).
    is_recording : bool
        Frame params bit 0x01: Motive is recording.
    tracked_models_changed : bool
        Frame params bit 0x02: the tracked model list changed, request MODELDEF again.
    n_marker_sets, n_skeletons, n_assets, n_labeled_markers, n_force_plates, n_devices : int
        Counts of the skipped sections (for diagnostics).
    receive_time_ns : int or None
        Client clock when the datagram arrived [ns]; set by :class:`~euc_ros.core.io.natnet_client.NatNetClient`,
        None from :func:`parse_packet`.
    """

    frame_number: int
    rigid_bodies: list
    timecode: int = 0
    timecode_sub: int = 0
    timestamp: float = 0.0
    camera_mid_exposure: int = 0
    camera_data_received: int = 0
    transmit_timestamp: int = 0
    precision_timestamp_sec: int = 0
    precision_timestamp_frac: int = 0
    is_recording: bool = False
    tracked_models_changed: bool = False
    n_marker_sets: int = 0
    n_skeletons: int = 0
    n_assets: int = 0
    n_labeled_markers: int = 0
    n_force_plates: int = 0
    n_devices: int = 0
    receive_time_ns: int | None = None


@dataclass(frozen=True)
class MessageString:
    """MESSAGESTRING: free text from the server.

    Parameters
    ----------
    text : str
        The text.
    """

    text: str


@dataclass(frozen=True)
class Response:
    """RESPONSE to a REQUEST: a 4-byte integer result code, or text (e.g. ``'Bitstream,4.1'``).

    Parameters
    ----------
    code : int or None
        The result code (None for a text response).
    text : str or None
        The text (None for a code).
    """

    code: int | None
    text: str | None


@dataclass(frozen=True)
class UnrecognizedRequest:
    """UNRECOGNIZED_REQUEST: the server did not understand a request."""


@dataclass(frozen=True)
class Request:
    """A client-to-server packet (CONNECT, REQUEST, REQUEST_MODELDEF, ..., KEEPALIVE), kept raw.

    Parameters
    ----------
    message_id : int
        The NatNet message id.
    payload : bytes
        The payload.
    """

    message_id: int
    payload: bytes


# ---------------------------------------------------------------------------------------------------------------------
# Byte reader
# ---------------------------------------------------------------------------------------------------------------------

class _Reader:
    """Bounds-checked little-endian reader over one packet; every failure is a NatNetError."""

    __slots__ = ("buf", "pos", "end", "message_id")

    def __init__(self, buf: bytes, pos: int, end: int, message_id: int) -> None:
        self.buf = buf
        self.pos = pos
        self.end = end
        self.message_id = message_id

    def error(self, message: str, what: str, at: int | None = None) -> NatNetError:
        return NatNetError(message, offset=self.pos if at is None else at, field=what, message_id=self.message_id)

    def need(self, n: int, what: str) -> None:
        if self.pos + n > self.end:
            raise self.error(f"truncated reading '{what}': need {n} bytes, {self.end - self.pos} left", what)

    def unpack(self, fmt: struct.Struct, what: str) -> tuple:
        self.need(fmt.size, what)
        values = fmt.unpack_from(self.buf, self.pos)
        self.pos += fmt.size
        return values

    def i32(self, what: str) -> int:
        return self.unpack(_I32, what)[0]

    def count(self, what: str, min_item_size: int) -> int:
        """Read an int32 element count, rejecting negative or implausible values."""
        at = self.pos
        n = self.i32(what)
        if n < 0 or n > MAX_COUNT or n * min_item_size > self.end - self.pos:
            raise self.error(f"implausible count {n} for '{what}' ({self.end - self.pos} bytes left)", what, at)
        return n

    def skip(self, n: int, what: str) -> None:
        self.need(n, what)
        self.pos += n

    def cstring(self, what: str) -> str:
        nul = self.buf.find(b"\0", self.pos, self.end)
        if nul < 0:
            raise self.error(f"unterminated string '{what}'", what)
        raw = self.buf[self.pos:nul]
        self.pos = nul + 1
        return raw.decode("utf-8", errors="replace")

    def section_size(self, has_sizes: bool, what: str) -> int | None:
        """Read the 4.1+ byte count that follows a section count (None before 4.1)."""
        if not has_sizes:
            return None
        at = self.pos
        n = self.i32(what)
        if n < 0 or n > self.end - self.pos:
            raise self.error(f"byte count {n} of '{what}' exceeds the {self.end - self.pos} bytes left", what, at)
        return n

    def check_section(self, start: int, size: int | None, what: str) -> None:
        """Check a parsed 4.1+ section against its declared byte count."""
        if size is not None and self.pos - start != size:
            raise self.error(f"section '{what}' declares {size} bytes but its content spans {self.pos - start}",
                             what, start)


_I16 = struct.Struct("<h")
_I32 = struct.Struct("<i")
_HDR = struct.Struct("<HH")
_RB = struct.Struct("<i3f4ffh")
_SUFFIX_TS = struct.Struct("<IIdQQQ")
_PREC = struct.Struct("<II")
_RB_DESC_HEAD = struct.Struct("<ii3f")
_CAMERA = struct.Struct("<3f4f")


def _check_version(version, message_id: int) -> tuple[int, int]:
    try:
        major, minor = (int(version[0]), int(version[1]))
    except (TypeError, ValueError, IndexError):
        raise NatNetError(f"invalid NatNet version {version!r}: expected (major, minor)",
                          message_id=message_id) from None
    if major < 3 or major > 4:
        raise NatNetError(f"NatNet version {major}.{minor} is not supported (3.0 to 4.x)", message_id=message_id)
    return major, minor


def _has_sizes(major: int, minor: int) -> bool:
    return (major, minor) >= (4, 1)


# ---------------------------------------------------------------------------------------------------------------------
# Public API
# ---------------------------------------------------------------------------------------------------------------------

def message_id(data: bytes) -> int:
    """The message id of a packet (first two bytes); NatNetError if too short.

    Parameters
    ----------
    data : bytes
        The packet.

    Returns
    -------
    int
        The message id.

    Raises
    ------
    NatNetError
        When the packet has fewer than two bytes.
    """
    if len(data) < 2:
        raise NatNetError(f"packet of {len(data)} bytes has no header", offset=0, field="header")
    return int.from_bytes(data[:2], "little")


def parse_packet(data: bytes, version=(4, 1)):
    """Decode one NatNet packet.

    Parameters
    ----------
    data : bytes
        The UDP datagram: 4-byte header (``uint16`` id, ``uint16`` payload size) and payload.
    version : tuple of int
        NatNet ``(major, minor)`` of the stream, from :attr:`ServerInfo.version`. SERVERINFO itself
        does not need it.

    Returns
    -------
    ServerInfo, ModelDef, FrameOfData, MessageString, Response, UnrecognizedRequest or Request

    Raises
    ------
    NatNetError
        Truncated or malformed packet, unknown message id or unsupported version; the message names
        the byte offset and the field.
    """
    data = bytes(data)
    if len(data) < 4:
        raise NatNetError(f"packet of {len(data)} bytes is shorter than the 4-byte header", offset=0,
                          field="header")
    mid, size = _HDR.unpack_from(data, 0)
    if mid in CLIENT_REQUEST_IDS:
        return Request(mid, data[4:4 + size])
    if 4 + size > len(data):
        raise NatNetError(f"truncated: header declares {size} payload bytes, {len(data) - 4} present",
                          offset=len(data), field="payload", message_id=mid)
    r = _Reader(data, 4, 4 + size, mid)
    if mid == NAT_SERVERINFO:
        return _parse_server_info(r)
    if mid == NAT_MESSAGESTRING:
        return MessageString(r.cstring("text") if size else "")
    if mid == NAT_RESPONSE:
        if size == 4:
            return Response(r.i32("code"), None)
        return Response(None, r.cstring("text") if b"\0" in data[4:4 + size] else
                        data[4:4 + size].decode("utf-8", errors="replace"))
    if mid == NAT_UNRECOGNIZED_REQUEST:
        return UnrecognizedRequest()
    if mid == NAT_MODELDEF:
        return _parse_modeldef(r, *_check_version(version, mid))
    if mid == NAT_FRAMEOFDATA:
        return _parse_frame(r, *_check_version(version, mid))
    raise NatNetError(f"unknown message id {mid}", offset=0, field="message_id", message_id=mid)


def latency_s(frame: FrameOfData, server_info: ServerInfo) -> float:
    """The system latency of a frame [s]: camera mid-exposure to transmission.

    ``(transmit_timestamp - camera_mid_exposure) / high_res_clock_frequency`` (server clock ticks).
    This is Motive's "system latency"; the network transit to the client is not included (the server
    and client clocks are not synchronised; on a LAN it is well under a millisecond).
    The ingest node stamps capture time = receive time - this latency.

    Parameters
    ----------
    frame : FrameOfData
    server_info : ServerInfo

    Returns
    -------
    float
        Latency [s]; NaN when it cannot be known: no clock frequency (short SERVERINFO), no
        mid-exposure stamp (``0``: camera system without latency measurement), or a transmit stamp
        earlier than the exposure (corrupted). Callers test ``np.isfinite``.
    """
    freq = server_info.high_res_clock_frequency
    if not freq or frame.camera_mid_exposure == 0:
        return float("nan")
    ticks = frame.transmit_timestamp - frame.camera_mid_exposure
    if ticks < 0:
        return float("nan")
    return ticks / float(freq)


# ---------------------------------------------------------------------------------------------------------------------
# SERVERINFO
# ---------------------------------------------------------------------------------------------------------------------

def _parse_server_info(r: _Reader) -> ServerInfo:
    r.need(SENDER_SIZE, "sender")
    name_raw = r.buf[r.pos:r.pos + 256]
    app_name = name_raw.split(b"\0", 1)[0].decode("utf-8", errors="replace")
    r.pos += 256
    app_version = tuple(r.buf[r.pos:r.pos + 4])
    natnet_version = tuple(r.buf[r.pos + 4:r.pos + 8])
    r.pos += 8
    freq = multicast = group = port = None
    if r.end - r.pos >= SENDER_SERVER_SIZE - SENDER_SIZE:
        freq, port, mc = struct.unpack_from("<QHB", r.buf, r.pos)
        r.pos += 11
        group = ".".join(str(b) for b in r.buf[r.pos:r.pos + 4])
        r.pos += 4
        multicast = bool(mc)
    elif r.end != r.pos:
        raise r.error(f"SERVERINFO payload of {r.end - 4} bytes: expected {SENDER_SIZE} or {SENDER_SERVER_SIZE}",
                      "connection_info")
    return ServerInfo(app_name, app_version, natnet_version, freq, multicast, group, port)


# ---------------------------------------------------------------------------------------------------------------------
# MODELDEF
# ---------------------------------------------------------------------------------------------------------------------

def _rigid_body_description(r: _Reader, major: int, what: str) -> tuple[str, int, int, tuple]:
    name = r.cstring(f"{what}.name")
    rb_id, parent, ox, oy, oz = r.unpack(_RB_DESC_HEAD, f"{what}.id/parent/offset")
    n = r.count(f"{what}.n_markers", 16)
    r.skip(16 * n, f"{what}.marker_offsets_and_labels")
    if major >= 4:
        for k in range(n):
            r.cstring(f"{what}.marker_names[{k}]")
    return name, rb_id, parent, (ox, oy, oz)


def _skip_named_channels(r: _Reader, what: str) -> None:
    n = r.count(f"{what}.n_channels", 1)
    for k in range(n):
        r.cstring(f"{what}.channel_names[{k}]")


def _parse_modeldef(r: _Reader, major: int, minor: int) -> ModelDef:
    has_sizes = _has_sizes(major, minor)
    rigid, parents, offsets, skeletons, assets, marker_sets = {}, {}, {}, {}, {}, []
    n_fp = n_dev = n_cam = 0
    n = r.count("n_datasets", 4)
    for i in range(n):
        what = f"datasets[{i}]"
        dtype = r.i32(f"{what}.type")
        size = r.section_size(has_sizes, f"{what}.size")
        start = r.pos
        if dtype == 0:      # marker set
            marker_sets.append(r.cstring(f"{what}.name"))
            for k in range(r.count(f"{what}.n_markers", 1)):
                r.cstring(f"{what}.marker_names[{k}]")
        elif dtype == 1:    # rigid body
            name, rb_id, parent, off = _rigid_body_description(r, major, what)
            rigid[rb_id] = name
            parents[rb_id] = parent
            offsets[rb_id] = np.array(off)
        elif dtype == 2:    # skeleton
            name = r.cstring(f"{what}.name")
            sk_id = r.i32(f"{what}.id")
            for k in range(r.count(f"{what}.n_bones", 24)):
                _rigid_body_description(r, major, f"{what}.bones[{k}]")
            skeletons[sk_id] = name
        elif dtype == 3:    # force plate
            r.i32(f"{what}.id")
            r.cstring(f"{what}.serial")
            r.skip(4 * (2 + 3 + 144 + 12) + 8, f"{what}.geometry")
            _skip_named_channels(r, what)
            n_fp += 1
        elif dtype == 4:    # device
            r.i32(f"{what}.id")
            r.cstring(f"{what}.name")
            r.cstring(f"{what}.serial")
            r.skip(8, f"{what}.types")
            _skip_named_channels(r, what)
            n_dev += 1
        elif dtype == 5:    # camera
            r.cstring(f"{what}.name")
            r.unpack(_CAMERA, f"{what}.pose")
            n_cam += 1
        elif dtype == 6 and has_sizes:  # asset (4.1+)
            name = r.cstring(f"{what}.name")
            r.i32(f"{what}.asset_type")
            asset_id = r.i32(f"{what}.id")
            for k in range(r.count(f"{what}.n_rigid_bodies", 24)):
                _rigid_body_description(r, major, f"{what}.rigid_bodies[{k}]")
            for k in range(r.count(f"{what}.n_markers", 23)):
                r.cstring(f"{what}.markers[{k}].name")
                r.skip(4 + 12 + 4 + 2, f"{what}.markers[{k}]")
            assets[asset_id] = name
        elif size is not None:          # unknown type: skip by its byte count
            r.skip(size, f"{what}.unknown_type_{dtype}")
        else:
            raise r.error(f"unknown data description type {dtype} (cannot skip before NatNet 4.1)",
                          f"{what}.type", start - 4)
        r.check_section(start, size, what)
    return ModelDef(rigid, parents, offsets, marker_sets, skeletons, assets, n_fp, n_dev, n_cam)


# ---------------------------------------------------------------------------------------------------------------------
# FRAMEOFDATA
# ---------------------------------------------------------------------------------------------------------------------

def _rigid_body(r: _Reader, what: str) -> RigidBodyData:
    rb_id, x, y, z, qx, qy, qz, qw, err, params = r.unpack(_RB, what)
    return RigidBodyData(rb_id, np.array([x, y, z]), np.array([qx, qy, qz, qw]), float(err), bool(params & 0x01))


def _parse_frame(r: _Reader, major: int, minor: int) -> FrameOfData:
    has_sizes = _has_sizes(major, minor)
    skip_by_size = (major, minor) > (4, 1)
    frame_number = r.i32("frame_number")

    def section(name: str, min_item: int, walker) -> int:
        n = r.count(f"{name}.count", min_item)
        size = r.section_size(has_sizes, f"{name}.size")
        start = r.pos
        if skip_by_size and size is not None:
            r.skip(size, name)
        else:
            walker(n, name)
            r.check_section(start, size, name)
        return n

    def walk_marker_sets(n: int, name: str) -> None:
        for i in range(n):
            r.cstring(f"{name}[{i}].name")
            r.skip(12 * r.count(f"{name}[{i}].n_markers", 12), f"{name}[{i}].markers")

    def walk_points(n: int, name: str) -> None:
        r.skip(12 * n, name)

    def walk_skeletons(n: int, name: str) -> None:
        for i in range(n):
            r.i32(f"{name}[{i}].id")
            r.skip(RIGID_BODY_SIZE * r.count(f"{name}[{i}].n_bones", RIGID_BODY_SIZE), f"{name}[{i}].bones")

    def walk_assets(n: int, name: str) -> None:
        for i in range(n):
            r.i32(f"{name}[{i}].id")
            r.skip(RIGID_BODY_SIZE * r.count(f"{name}[{i}].n_rigid_bodies", RIGID_BODY_SIZE),
                   f"{name}[{i}].rigid_bodies")
            r.skip(ASSET_MARKER_SIZE * r.count(f"{name}[{i}].n_markers", ASSET_MARKER_SIZE),
                   f"{name}[{i}].markers")

    def walk_labeled(n: int, name: str) -> None:
        r.skip(LABELED_MARKER_SIZE * n, name)

    n_sets = section("marker_sets", 5, walk_marker_sets)
    section("other_markers", 12, walk_points)

    # Rigid bodies: always parsed, and checked against the 4.1 byte count.
    n_rb = r.count("rigid_bodies.count", RIGID_BODY_SIZE)
    rb_size = r.section_size(has_sizes, "rigid_bodies.size")
    rb_start = r.pos
    bodies = [_rigid_body(r, f"rigid_bodies[{i}]") for i in range(n_rb)]
    r.check_section(rb_start, rb_size, "rigid_bodies")

    n_skel = section("skeletons", 8, walk_skeletons)
    n_assets = section("assets", 12, walk_assets) if has_sizes else 0
    n_lab = section("labeled_markers", LABELED_MARKER_SIZE, walk_labeled)
    n_fp = section("force_plates", 8, lambda n, name: _skip_analog_n(r, n, name))
    n_dev = section("devices", 8, lambda n, name: _skip_analog_n(r, n, name))

    timecode, timecode_sub, timestamp, mid, received, transmit = r.unpack(_SUFFIX_TS, "suffix.timestamps")
    prec_s = prec_f = 0
    if has_sizes:
        prec_s, prec_f = r.unpack(_PREC, "suffix.precision_timestamp")
    (params,) = r.unpack(_I16, "suffix.params")
    left = r.end - r.pos
    if left == 4:
        r.i32("suffix.end_of_data_tag")
    elif left != 0:
        raise r.error(f"{left} unexpected bytes after the frame params (expected 0 or a 4-byte end tag); "
                      f"wrong NatNet version {major}.{minor}?", "suffix.end_of_data_tag")
    return FrameOfData(
        frame_number=frame_number, rigid_bodies=bodies, timecode=timecode, timecode_sub=timecode_sub,
        timestamp=timestamp, camera_mid_exposure=mid, camera_data_received=received, transmit_timestamp=transmit,
        precision_timestamp_sec=prec_s, precision_timestamp_frac=prec_f,
        is_recording=bool(params & 0x01), tracked_models_changed=bool(params & 0x02),
        n_marker_sets=n_sets, n_skeletons=n_skel, n_assets=n_assets, n_labeled_markers=n_lab,
        n_force_plates=n_fp, n_devices=n_dev)


def _skip_analog_n(r: _Reader, n: int, what: str) -> None:
    """Skip ``n`` force plates or devices (the count was already read)."""
    for i in range(n):
        r.i32(f"{what}[{i}].id")
        for c in range(r.count(f"{what}[{i}].n_channels", 4)):
            nf = r.count(f"{what}[{i}].channels[{c}].n_frames", 4)
            r.skip(4 * nf, f"{what}[{i}].channels[{c}].values")
