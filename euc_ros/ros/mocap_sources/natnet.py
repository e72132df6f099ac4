"""Source ``natnet``: live Motive over NatNet 3.x/4.x (multicast, or unicast with keep-alives).

Frames are stamped with the capture time: receive time minus the latency the server reports
(``stamp_source`` CAPTURE_TIME; RECEIVE_TIME for frames without a usable latency). Body names come
from Motive's MODELDEF; frames before it are dropped and counted (names are never guessed).

A server that sends nothing is said on the console, not only in the diagnostics: a WARN after
:data:`NO_DATA_WARN_S` without frames (again every :data:`NO_DATA_REPEAT_S`), naming the server, the
ports, the transmission type and what to check; an INFO when frames arrive.
"""
from __future__ import annotations

import time

from euc_msgs.msg import MocapFrame

from euc_ros.core.errors import EucError
from euc_ros.core.mocap.message_frames import frame_from_natnet, natnet_capture_stamp
from euc_ros.core.mocap.silence import SilenceWatch
from euc_ros.ros.mocap_sources.base import MocapSource

#: Time without frames before the console is told [s] (the diagnostics say STALE after 1 s).
NO_DATA_WARN_S = 3.0
#: Period of that warning while no frames arrive [s].
NO_DATA_REPEAT_S = 15.0
#: Period of the check [s].
SILENCE_CHECK_S = 0.5


class NatNetSource(MocapSource):
    """Frames from Motive over NatNet.

    Configured by the parameters ``server_ip``, ``local_ip``, ``multicast``, ``multicast_group``,
    ``command_port``, ``data_port``, ``keepalive_period``, ``max_latency``, ``poll_period``, ``bodies``.

    Attributes
    ----------
    client : NatNetClient
    names_by_id : dict of int to str
        Rigid-body names of the last MODELDEF.
    no_names_dropped : int
        Frames dropped because no MODELDEF had named the bodies yet.
    silence : SilenceWatch
        Time since the last frame, for the console.
    """

    stamp_source = MocapFrame.STAMP_CAPTURE_TIME

    @property
    def hardware_id(self) -> str:
        """The capture system: ``natnet://<server_ip>``."""
        return f"natnet://{self.config['server_ip']}"

    def setup(self) -> None:
        """Open the NatNet client and start its polling and silence timers."""
        from euc_ros.core.io.natnet_client import NatNetClient

        node, cfg = self.node, self.config
        self._configured_bodies = list(node.bodies)
        self.names_by_id: dict[int, str] = {}
        self.no_names_dropped = 0
        self.client = NatNetClient(cfg["server_ip"], local_ip=cfg["local_ip"], multicast=cfg["multicast"],
                                   multicast_group=cfg["multicast_group"], command_port=cfg["command_port"],
                                   data_port=cfg["data_port"], keepalive_s=cfg["keepalive_period"],
                                   clock_ns=lambda: node.get_clock().now().nanoseconds)
        self.silence = SilenceWatch(NO_DATA_WARN_S, NO_DATA_REPEAT_S)
        self.silence.start(time.monotonic())
        self._frames_seen = 0
        node.create_timer(cfg["poll_period"], self._tick)
        node.create_timer(SILENCE_CHECK_S, self._check_silence)
        node.get_logger().info(f"NatNet: connecting to {cfg['server_ip']}:{cfg['command_port']} ({self.mode()})")

    def mode(self) -> str:
        """The transmission type as configured: ``multicast 239.255.42.99`` or ``unicast``."""
        return "multicast " + self.config["multicast_group"] if self.config["multicast"] else "unicast"

    def _tick(self) -> None:
        from euc_ros.core.io import natnet

        node = self.node
        try:
            messages = self.client.poll(0.0)
        except EucError as exc:    # the client does not raise on input (it counts malformed packets); be safe anyway
            node.input_error(exc)
            return
        except Exception:          # a bug: logged with its traceback; the node never dies on input
            node.unexpected_error()
            return
        for m in messages:
            node.received += 1
            try:
                if isinstance(m, natnet.ServerInfo):
                    node.get_logger().info(f"NatNet: {m.app_name} {'.'.join(map(str, m.app_version))}, "
                                           f"NatNet {m.version[0]}.{m.version[1]}")
                elif isinstance(m, natnet.ModelDef):
                    self._on_model_def(m)
                elif isinstance(m, natnet.FrameOfData):
                    self._on_frame(m)
            except EucError as exc:
                node.input_error(exc)
            except Exception:      # a bug: logged with its traceback; the node never dies on input
                node.unexpected_error()

    def _on_model_def(self, m) -> None:
        node = self.node
        self.names_by_id = {int(i): str(n) for i, n in m.rigid_bodies.items()}
        names = list(self.names_by_id.values())
        if self._configured_bodies:
            missing = [b for b in self._configured_bodies if b not in names]
            if missing:
                node.get_logger().warning(f"NatNet MODELDEF lacks configured bodies {missing} (has {names})")
            node.set_bodies(self._configured_bodies)
        else:
            node.set_bodies(names)
        node.get_logger().info(f"NatNet MODELDEF: rigid bodies {self.names_by_id}")

    def _on_frame(self, m) -> None:
        from euc_ros.core.io.natnet import latency_s

        node = self.node
        if not self.names_by_id or not node.bodies:
            self.no_names_dropped += 1      # no MODELDEF yet: names unknown, do not guess
            return
        receive = m.receive_time_ns if m.receive_time_ns is not None else node.get_clock().now().nanoseconds
        latency = latency_s(m, self.client.server_info) if self.client.server_info is not None else float("nan")
        stamp, corrected = natnet_capture_stamp(receive, latency, self.config["max_latency"])
        frame = frame_from_natnet(m, self.names_by_id, node.bodies, stamp, node.world_up)
        node.publish_frame(frame, MocapFrame.STAMP_CAPTURE_TIME if corrected else MocapFrame.STAMP_RECEIVE_TIME)

    # -- the console when nothing arrives ------------------------------------------------------------------------------
    def _check_silence(self) -> None:
        now = time.monotonic()
        frames = self.client.stats["frames"]
        if frames != self._frames_seen:
            self._frames_seen = frames
            silent = self.silence.data(now)
            if silent is not None:
                self.node.get_logger().info(f"NatNet: frames arriving from {self.config['server_ip']} ({self.mode()})"
                                            + (f" after {silent:.0f} s without" if silent >= NO_DATA_WARN_S else ""))
            return
        silent = self.silence.check(now)
        if silent is not None:
            self.node.get_logger().warning(self.no_data_message(silent))

    def no_data_message(self, silent_s: float) -> str:
        """What the console says after ``silent_s`` seconds without frames: what arrived, and what to check."""
        cfg, client = self.config, self.client
        server = f"{cfg['server_ip']}:{cfg['command_port']}"
        where = (f"multicast group {cfg['multicast_group']} port {cfg['data_port']} on interface {cfg['local_ip']}"
                 if cfg["multicast"] else f"unicast from {cfg['server_ip']} (keep-alives sent)")
        firewall = f"a firewall letting UDP ports {cfg['command_port']} and {cfg['data_port']} in"
        if client.server_info is None and client.stats["dropped_no_version"]:
            what = (f"NatNet: frames arrive ({where}) but Motive does not answer at {server} for {silent_s:.0f} s; "
                    f"check server_ip is Motive's address and {firewall}")
        elif client.server_info is None:
            what = (f"NatNet: no answer from Motive at {server} for {silent_s:.0f} s ({where}); check that Motive runs "
                    "with streaming on (Settings > Streaming: Broadcast Frame Data, Local Interface on this host's "
                    f"network), that server_ip and local_ip are the addresses on that network, and {firewall}")
        else:
            info = client.server_info
            what = (f"NatNet: {info.app_name} at {server} answers but no frames for {silent_s:.0f} s ({where}); "
                    "check Motive's streaming (Broadcast Frame Data on, Transmission Type "
                    f"{'Multicast' if cfg['multicast'] else 'Unicast'} as here, Rigid Bodies streamed), "
                    f"local_ip is the interface that reaches Motive, and {firewall}")
        return what

    def counters(self) -> dict:
        """The NatNet client's counters for the stream diagnostics.

        Returns
        -------
        dict
            ``malformed_dropped``, ``dropped_before_serverinfo``, ``dropped_before_modeldef``, ``natnet_version``,
            ``send_errors``.
        """
        client = self.client
        cs = client.stats
        return {"malformed_dropped": cs["malformed"], "dropped_before_serverinfo": cs["dropped_no_version"],
                "dropped_before_modeldef": self.no_names_dropped,
                "natnet_version": "?" if client.version is None else f"{client.version[0]}.{client.version[1]}",
                "send_errors": cs["send_errors"]}

    def close(self) -> None:
        """Close the NatNet client's sockets."""
        client = getattr(self, "client", None)
        if client is not None:
            client.close()
