"""NatNetClient against a small fake Motive server: real UDP sockets on 127.0.0.1, no threads, no sleeps.

The fake server answers CONNECT with SERVERINFO and REQUEST_MODELDEF with MODELDEF and streams
frames, all built by the independent encoder of test_natnet.py.
"""
from __future__ import annotations

import importlib.util
import itertools
import select
import socket
import struct
from pathlib import Path

import numpy as np
import pytest

from euc_ros.core.errors import ConfigError
from euc_ros.core.io.natnet import FrameOfData, ModelDef, ServerInfo
from euc_ros.core.io.natnet_client import NatNetClient

_spec = importlib.util.spec_from_file_location("natnet_encoder", Path(__file__).with_name("test_natnet.py"))
enc = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(enc)

VERSION = (4, 1)


class FakeMotive:
    """A NatNet server on 127.0.0.1: a command socket; frames go unicast to clients or to a multicast group."""

    def __init__(self, version=VERSION, multicast_group: str | None = None, data_port: int = 0) -> None:
        self.version = version
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.port = self.sock.getsockname()[1]
        self.multicast_group = multicast_group
        self.data_port = data_port
        self.requests: list[tuple[int, tuple]] = []
        if multicast_group:
            self.mc = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            self.mc.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton("127.0.0.1"))
            self.mc.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP, 1)

    def receive(self, timeout_s: float = 1.0) -> list[tuple[int, tuple]]:
        """Return the (message id, client address) of every request that arrives within the timeout."""
        got = []
        while select.select([self.sock], [], [], timeout_s if not got else 0.0)[0]:
            data, addr = self.sock.recvfrom(65535)
            got.append((struct.unpack_from("<H", data)[0], addr))
        self.requests += got
        return got

    def wait_for(self, message_id: int, timeout_s: float = 2.0) -> tuple:
        for _ in range(int(timeout_s / 0.1)):
            for mid, addr in self.receive(0.1):
                if mid == message_id:
                    return addr
        raise AssertionError(f"fake server: no request {message_id} arrived")

    def count(self, message_id: int) -> int:
        return sum(1 for mid, _ in self.requests if mid == message_id)

    def send(self, data: bytes, addr) -> None:
        self.sock.sendto(data, addr)

    def stream(self, data: bytes, addr) -> None:
        if self.multicast_group:
            self.mc.sendto(data, (self.multicast_group, self.data_port))
        else:
            self.sock.sendto(data, addr)

    def close(self) -> None:
        self.sock.close()
        if self.multicast_group:
            self.mc.close()


def poll_until(client: NatNetClient, predicate, timeout_s: float = 2.0) -> list:
    """Poll (each poll waits up to 50 ms for data) until predicate(all messages so far) holds."""
    out: list = []
    for _ in range(int(timeout_s / 0.05)):
        out += client.poll(0.05)
        if predicate(out):
            return out
    raise AssertionError(f"condition not met; got {out!r}, stats {client.stats}")


def counting_clock(start_ns: int = 1_700_000_000_000_000_000, step_ns: int = 1_000_000):
    counter = itertools.count()
    return lambda: start_ns + step_ns * next(counter)


def frames_of(messages) -> list[FrameOfData]:
    return [m for m in messages if isinstance(m, FrameOfData)]


def test_unicast_session_names_frames_keepalives_and_malformed():
    server = FakeMotive()
    client = NatNetClient("127.0.0.1", local_ip="127.0.0.1", multicast=False, command_port=server.port,
                          keepalive_s=0.0, clock_ns=counting_clock())
    try:
        addr = server.wait_for(0)                                   # CONNECT
        assert addr == client.command_address

        server.send(enc.enc_frame(VERSION), addr)                   # before SERVERINFO: undecodable
        server.send(enc.enc_modeldef(VERSION), addr)
        poll_until(client, lambda _: client.stats["dropped_no_version"] == 2)
        assert client.model_def is None

        server.send(enc.enc_server_info(natnet=(4, 1, 0, 0), freq=enc.FREQ), addr)
        msgs = poll_until(client, lambda m: any(isinstance(x, ServerInfo) for x in m))
        assert client.version == (4, 1) and client.server_info.high_res_clock_frequency == enc.FREQ

        server.wait_for(4)                                          # REQUEST_MODELDEF, sent by the client itself
        server.send(enc.enc_modeldef(VERSION), addr)
        msgs = poll_until(client, lambda m: any(isinstance(x, ModelDef) for x in m))
        assert client.body_names == {1: "E", 2: "H", 7: "TL"}

        quiet = dict(enc.SUFFIX, params=0x00)
        for k in range(5):
            server.stream(enc.enc_frame(VERSION, suffix=quiet, frame_number=100 + k), addr)
            if k == 2:
                server.stream(enc.enc_frame(VERSION)[:-30], addr)  # truncated frame
                server.stream(b"\x07\x00\xff", addr)               # garbage
        msgs = poll_until(client, lambda m: len(frames_of(m)) == 5)
        frames = frames_of(msgs)
        assert [f.frame_number for f in frames] == [100, 101, 102, 103, 104]
        assert client.stats["malformed"] == 2 and client.last_error
        stamps = [f.receive_time_ns for f in frames]
        assert all(s is not None for s in stamps) and stamps == sorted(stamps)
        np.testing.assert_array_equal(frames[0].rigid_bodies[1].position, np.float32([0.05, 1.75, 0.01]))
        assert [b.tracking_valid for b in frames[0].rigid_bodies] == [True, True, False]

        # the models-changed flag makes the client ask for MODELDEF again
        n_md = server.count(4)
        server.stream(enc.enc_frame(VERSION, suffix=dict(enc.SUFFIX, params=0x02)), addr)
        poll_until(client, lambda m: len(frames_of(m)) == 1)
        server.wait_for(4)
        assert server.count(4) == n_md + 1

        assert client.stats["keepalives_sent"] >= 3 and server.count(10) >= 1
        assert client.stats["frames"] == 6 and client.stats["send_errors"] == 0
    finally:
        client.close()
        server.close()
    assert client.poll(0.0) == []                                    # closed: quiet, no exception


def test_connect_is_retried_until_server_info():
    server = FakeMotive()
    client = NatNetClient("127.0.0.1", local_ip="127.0.0.1", multicast=False, command_port=server.port,
                          keepalive_s=10.0, connect_retry_s=0.0)
    try:
        server.wait_for(0)
        client.poll(0.0)
        server.wait_for(0)                                           # a second CONNECT
        assert client.stats["connects_sent"] >= 2
        assert client.stats["keepalives_sent"] == 1                  # first one at once, then every 10 s
    finally:
        client.close()
        server.close()


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("", 0))
        return s.getsockname()[1]


def test_multicast_frames():
    group, port = "239.255.42.99", _free_udp_port()
    server = FakeMotive(version=(3, 1), multicast_group=group, data_port=port)
    try:
        client = NatNetClient("127.0.0.1", local_ip="127.0.0.1", multicast=True, multicast_group=group,
                              command_port=server.port, data_port=port)
    except ConfigError as exc:
        server.close()
        pytest.skip(f"multicast not available here: {exc}")
    try:
        addr = server.wait_for(0)
        server.send(enc.enc_server_info(natnet=(3, 1, 0, 0), multicast=True, port=port), addr)
        poll_until(client, lambda _: client.version == (3, 1))
        server.wait_for(4)
        server.send(enc.enc_modeldef((3, 1)), addr)
        for k in range(3):
            server.stream(enc.enc_frame((3, 1), frame_number=k), None)
        msgs = poll_until(client, lambda m: len(frames_of(m)) == 3 and client.model_def is not None)
        assert [f.frame_number for f in frames_of(msgs)] == [0, 1, 2]
        assert client.stats["keepalives_sent"] == 0                  # multicast needs none
        assert client.body_names[7] == "TL"
    finally:
        client.close()
        server.close()


@pytest.mark.parametrize("kwargs, key", [
    (dict(server_ip="motive.local"), "server_ip"),
    (dict(server_ip="127.0.0.1", multicast_group="10.0.0.1"), "multicast_group"),
    (dict(server_ip="127.0.0.1", command_port=70000), "command_port"),
    (dict(server_ip="127.0.0.1", keepalive_s=-1.0), "keepalive_s"),
])
def test_config_errors_name_the_key(kwargs, key):
    with pytest.raises(ConfigError, match=key):
        NatNetClient(**kwargs)
