"""NatNet UDP client for OptiTrack Motive: real sockets, no threads, poll-driven.

A node calls :meth:`NatNetClient.poll` from a timer; each call drains the sockets without blocking
longer than ``timeout_s`` and returns the decoded messages. Nothing here raises on bad input: a
packet that :func:`~euc_ros.core.io.natnet.parse_packet` rejects is dropped and counted in
:attr:`NatNetClient.stats`.

Session (see ``docs/natnet.md``)
--------------------------------
1. The client sends CONNECT from its command socket to ``server_ip:command_port`` (repeated every
   ``connect_retry_s`` until SERVERINFO arrives).
2. SERVERINFO gives the NatNet version (packet layout) and the clock frequency of the frame
   timestamps; the client then sends REQUEST_MODELDEF.
3. MODELDEF gives the rigid-body names. A frame flagged ``tracked_models_changed`` triggers a new
   REQUEST_MODELDEF.
4. Frames arrive on the data socket joined to the multicast group (multicast), or on the command
   socket (unicast: the server sends to the address the CONNECT came from). In unicast the client
   sends KEEPALIVE every ``keepalive_s`` so that the server keeps streaming.

Frames and MODELDEFs that arrive before SERVERINFO cannot be decoded (the layout depends on the
version): they are counted as ``dropped_no_version`` (MODELDEF is requested again after SERVERINFO).
"""
from __future__ import annotations

import dataclasses
import ipaddress
import select
import socket
import struct
import time
from collections.abc import Callable

from euc_ros.core.errors import ConfigError
from euc_ros.core.io.natnet import (
    NAT_CONNECT,
    NAT_FRAMEOFDATA,
    NAT_KEEPALIVE,
    NAT_MODELDEF,
    NAT_REQUEST_MODELDEF,
    FrameOfData,
    ModelDef,
    NatNetError,
    ServerInfo,
    parse_packet,
)

#: NatNet version the client announces in CONNECT (the server answers with the one it streams).
CLIENT_NATNET_VERSION = (4, 1, 0, 0)
#: Largest UDP datagram [bytes].
MAX_DATAGRAM = 65535
#: Receive buffer requested from the OS [bytes]: ~1 s of 240 Hz frames of 40 bodies.
RECV_BUFFER_BYTES = 4 * 1024 * 1024
#: Most datagrams handled in one poll (keeps a timer callback bounded).
MAX_PACKETS_PER_POLL = 10_000


def build_request(message_id: int, payload: bytes = b"") -> bytes:
    """A client packet: ``uint16`` id, ``uint16`` payload size, payload.

    Parameters
    ----------
    message_id : int
        The NatNet message id.
    payload : bytes
        The payload.

    Returns
    -------
    bytes
        The packet.
    """
    return struct.pack("<HH", message_id, len(payload)) + payload


def connect_payload(version=CLIENT_NATNET_VERSION) -> bytes:
    """The CONNECT payload (271 bytes, as the SDK sample sends it).

    ``'Ping'`` in a 265-byte NUL-padded name field, the requested NatNet version as 4 bytes at offset 265,
    then two NUL bytes.

    Parameters
    ----------
    version : sequence of int
        Requested NatNet version (major, minor, build, revision).

    Returns
    -------
    bytes
        The payload.
    """
    name = b"Ping".ljust(265, b"\0")
    return name + bytes(int(v) & 0xFF for v in version) + b"\0\0"


def _check_ip(value: str, key: str) -> str:
    try:
        ipaddress.IPv4Address(value)
    except ValueError:
        raise ConfigError(f"not an IPv4 address: {value!r}", key=key) from None
    return value


def _check_port(value: int, key: str) -> int:
    if not isinstance(value, int) or not 0 <= value <= 65535:
        raise ConfigError(f"not a UDP port: {value!r}", key=key)
    return value


class NatNetClient:
    """Poll-driven NatNet client over UDP (multicast, or unicast with keep-alives).

    Parameters
    ----------
    server_ip : str
        IPv4 address of the Motive host.
    local_ip : str
        Local interface address; ``'0.0.0.0'`` lets the OS choose (multicast joins on the default
        interface then).
    multicast : bool
        True: frames come to ``multicast_group:data_port``. False: unicast with keep-alives.
    multicast_group : str
        Multicast group of Motive's streaming settings.
    command_port : int
        Server command port (Motive default 1510).
    data_port : int
        Data port frames are sent to in multicast (Motive default 1511).
    keepalive_s : float
        Period of KEEPALIVE packets in unicast [s].
    connect_retry_s : float
        Period of CONNECT retries until SERVERINFO arrives [s].
    clock_ns : callable
        Clock giving ``receive_time_ns`` of frames and driving the keep-alive/retry periods [ns].

    Attributes
    ----------
    stats : dict of str to int
        ``received`` datagrams, ``frames``, ``malformed`` (dropped: undecodable), ``dropped_no_version``
        (frames and MODELDEFs before SERVERINFO), ``server_info``, ``model_def``, ``other`` messages,
        ``keepalives_sent``, ``connects_sent``, ``modeldef_requests``, ``send_errors``.
    last_error : str or None
        Message of the last dropped packet or send error.

    Raises
    ------
    ConfigError
        When ``multicast_group`` is not a multicast address or ``keepalive_s`` is negative.
    """

    def __init__(self, server_ip: str, local_ip: str = "0.0.0.0", multicast: bool = True,
                 multicast_group: str = "239.255.42.99", command_port: int = 1510, data_port: int = 1511,
                 keepalive_s: float = 1.0, *, connect_retry_s: float = 1.0,
                 clock_ns: Callable[[], int] = time.time_ns) -> None:
        self.server_ip = _check_ip(server_ip, "server_ip")
        self.local_ip = _check_ip(local_ip, "local_ip")
        self.multicast = bool(multicast)
        self.multicast_group = _check_ip(multicast_group, "multicast_group")
        if self.multicast and not ipaddress.IPv4Address(multicast_group).is_multicast:
            raise ConfigError(f"{multicast_group} is not a multicast address", key="multicast_group")
        self.command_port = _check_port(command_port, "command_port")
        self.data_port = _check_port(data_port, "data_port")
        if not keepalive_s >= 0:
            raise ConfigError(f"keepalive_s must be >= 0, got {keepalive_s!r}", key="keepalive_s")
        self.keepalive_s = float(keepalive_s)
        self.connect_retry_s = float(connect_retry_s)
        self._clock_ns = clock_ns

        self.server_info: ServerInfo | None = None
        self.model_def: ModelDef | None = None
        self.stats: dict[str, int] = dict.fromkeys(
            ("received", "frames", "malformed", "dropped_no_version", "server_info", "model_def", "other",
             "keepalives_sent", "connects_sent", "modeldef_requests", "send_errors"), 0)
        self.last_error: str | None = None
        self._last_keepalive_ns: int | None = None
        self._last_connect_ns: int | None = None

        self._command = self._open_command_socket()
        self._data = self._open_data_socket() if self.multicast else None
        self._send_connect()

    # -- sockets ---------------------------------------------------------------------------------------------------
    def _open_command_socket(self) -> socket.socket:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM, socket.IPPROTO_UDP)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECV_BUFFER_BYTES)
            sock.bind((self.local_ip, 0))
            sock.setblocking(False)
        except OSError as exc:
            sock.close()
            raise ConfigError(f"cannot open the NatNet command socket on {self.local_ip}: {exc}",
                              key="local_ip") from None
        return sock

    def _open_data_socket(self) -> socket.socket:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM, socket.IPPROTO_UDP)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            if hasattr(socket, "SO_REUSEPORT"):
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEPORT, 1)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECV_BUFFER_BYTES)
            sock.bind(("", self.data_port))
            mreq = socket.inet_aton(self.multicast_group) + socket.inet_aton(self.local_ip)
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, mreq)
            sock.setblocking(False)
        except OSError as exc:
            sock.close()
            self._command.close()
            raise ConfigError(f"cannot join multicast group {self.multicast_group} on port {self.data_port} "
                              f"(interface {self.local_ip}): {exc}", key="multicast_group") from None
        return sock

    @property
    def command_address(self) -> tuple[str, int]:
        """Local ``(ip, port)`` of the command socket (where unicast frames arrive)."""
        return self._command.getsockname()

    @property
    def version(self) -> tuple[int, int] | None:
        """NatNet ``(major, minor)`` of the stream, None before SERVERINFO."""
        return None if self.server_info is None else self.server_info.version

    @property
    def body_names(self) -> dict[int, str]:
        """Rigid-body id -> name from the last MODELDEF (empty before it)."""
        return {} if self.model_def is None else dict(self.model_def.rigid_bodies)

    # -- sending ---------------------------------------------------------------------------------------------------
    def _send(self, packet: bytes) -> bool:
        if self._command is None:
            return False
        try:
            self._command.sendto(packet, (self.server_ip, self.command_port))
            return True
        except OSError as exc:
            self.stats["send_errors"] += 1
            self.last_error = f"send to {self.server_ip}:{self.command_port} failed: {exc}"
            return False

    def _send_connect(self) -> None:
        self._last_connect_ns = self._clock_ns()
        if self._send(build_request(NAT_CONNECT, connect_payload())):
            self.stats["connects_sent"] += 1

    def request_model_def(self) -> None:
        """Send REQUEST_MODELDEF (the reply arrives through :meth:`poll`)."""
        if self._send(build_request(NAT_REQUEST_MODELDEF)):
            self.stats["modeldef_requests"] += 1

    def _housekeeping(self) -> None:
        now = self._clock_ns()
        if self.server_info is None and now - self._last_connect_ns >= self.connect_retry_s * 1e9:
            self._send_connect()
        if not self.multicast and (self._last_keepalive_ns is None
                                   or now - self._last_keepalive_ns >= self.keepalive_s * 1e9):
            self._last_keepalive_ns = now
            if self._send(build_request(NAT_KEEPALIVE)):
                self.stats["keepalives_sent"] += 1

    # -- receiving -------------------------------------------------------------------------------------------------
    def poll(self, timeout_s: float = 0.0) -> list:
        """Receive and decode every pending datagram, waiting at most ``timeout_s`` for the first.

        Parameters
        ----------
        timeout_s : float
            Longest wait for data when none is pending [s]; 0 returns at once.

        Returns
        -------
        list
            Decoded messages in arrival order (:class:`~euc_ros.core.io.natnet.ServerInfo`,
            :class:`~euc_ros.core.io.natnet.ModelDef`, :class:`~euc_ros.core.io.natnet.FrameOfData`
            with ``receive_time_ns`` set, ...). Malformed packets are counted, not returned.
        """
        self._housekeeping()
        socks = [s for s in (self._command, self._data) if s is not None]
        if not socks:
            return []
        try:
            readable, _, _ = select.select(socks, [], [], max(0.0, float(timeout_s)))
        except (OSError, ValueError):
            return []
        out: list = []
        for sock in readable:
            for _ in range(MAX_PACKETS_PER_POLL):
                try:
                    data = sock.recv(MAX_DATAGRAM)
                except (BlockingIOError, InterruptedError):
                    break
                except OSError as exc:   # e.g. ICMP port unreachable reported on the next recv
                    self.stats["send_errors"] += 1
                    self.last_error = f"receive failed: {exc}"
                    break
                message = self._handle(data, self._clock_ns())
                if message is not None:
                    out.append(message)
        return out

    def _handle(self, data: bytes, now_ns: int):
        self.stats["received"] += 1
        mid = int.from_bytes(data[:2], "little") if len(data) >= 2 else -1
        if mid in (NAT_FRAMEOFDATA, NAT_MODELDEF) and self.server_info is None:
            self.stats["dropped_no_version"] += 1
            return None
        try:
            message = parse_packet(data, self.version if self.version is not None else (4, 1))
        except NatNetError as exc:
            self.stats["malformed"] += 1
            self.last_error = str(exc)
            return None
        if isinstance(message, FrameOfData):
            self.stats["frames"] += 1
            if message.tracked_models_changed:
                self.request_model_def()
            return dataclasses.replace(message, receive_time_ns=now_ns)
        if isinstance(message, ServerInfo):
            self.stats["server_info"] += 1
            first = self.server_info is None
            self.server_info = message
            if first or self.model_def is None:
                self.request_model_def()
            return message
        if isinstance(message, ModelDef):
            self.stats["model_def"] += 1
            self.model_def = message
            return message
        self.stats["other"] += 1
        return message

    # -- lifetime --------------------------------------------------------------------------------------------------
    def close(self) -> None:
        """Close the sockets (idempotent)."""
        for sock in (self._command, self._data):
            if sock is not None:
                sock.close()
        self._command = self._data = None

    def __enter__(self) -> NatNetClient:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

