"""`euc-ros view`: the live topics in Foxglove, over its WebSocket protocol, without ROS tools.

Starts a Foxglove WebSocket server (``foxglove-sdk``) and a ROS node that subscribes to the
pipeline's topics as their publishers appear: the per-body poses ``/mocap/<body>/pose``, ``/tf``,
``/mocap/frame``, ``/rider/state``, ``/euc/torque`` (the torques and their residual),
``/diagnostics`` and the unicycle's state, pose and command. Each message is forwarded as the
CDR bytes it arrived in, on a channel with its ``ros2msg`` schema, so Foxglove decodes it natively
(:mod:`euc_ros.ros.foxglove_bridge`).

The server listens on ``127.0.0.1`` unless ``--address`` is given, and prints one line on start
saying where it listens and whether live data can leave this machine. SIGINT (Ctrl-C) or SIGTERM
stop it cleanly (exit code 0). See ``docs/viewing_live.md``.
"""
from __future__ import annotations

import argparse
import time

from euc_ros.cli.stop import StopSignals
from euc_ros.core.errors import ConfigError

HELP = "serve the live topics to Foxglove over WebSocket (this machine only unless --address is given)"

#: Longest wait of one executor spin, so a stop request is seen promptly [s].
SPIN_TIMEOUT_S = 0.1
#: Name of the viewer's ROS node.
NODE_NAME = "euc_view"

EPILOG = """\
Open Foxglove (desktop app or web), choose "Open connection" -> "Foxglove WebSocket" and enter the URL
printed on start; then import the layout config/foxglove/euc_pipeline.json.

The server listens on 127.0.0.1 (this machine only) unless --address is given. Live data leave this
machine only when --address names a non-local address: 0.0.0.0 (every interface) or one interface's
address. The server has no authentication: anyone who can reach that address and port sees the data.

Topics appear in Foxglove as their publishers appear on the ROS graph (ROS_DOMAIN_ID as for any node).

examples:
  euc-ros view                                # ws://127.0.0.1:8765, this machine only
  euc-ros view --address 0.0.0.0 --port 9000  # every interface: other machines can connect
"""


def port_number(text: str) -> int:
    """Parse a TCP port for ``--port``: 0 (any free port) to 65535."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a port number: {text!r} (give 0-65535; 0 picks a free port)") \
            from None
    if not 0 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"port {value} is out of range (give 0-65535; 0 picks a free port)")
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``euc-ros view``."""
    from euc_ros.ros.foxglove_bridge import DEFAULT_ADDRESS, DEFAULT_PORT

    parser.epilog = EPILOG
    parser.add_argument("--address", default=DEFAULT_ADDRESS, metavar="ADDR",
                        help=f"address to listen on (default {DEFAULT_ADDRESS}: this machine only; 0.0.0.0: every "
                             "interface, so live data can leave this machine)")
    parser.add_argument("--port", type=port_number, default=DEFAULT_PORT,
                        help=f"TCP port to listen on (default {DEFAULT_PORT}, Foxglove's; 0 picks a free one)")


def start_line(address: str, port: int, local: bool) -> str:
    """The one line printed on start: where the server listens and whether data can leave the machine.

    Parameters
    ----------
    address : str
        Address the server listens on.
    port : int
        Port it listens on.
    local : bool
        Whether ``address`` is a loopback address (:func:`~euc_ros.ros.foxglove_bridge.is_local_address`).

    Returns
    -------
    str
    """
    from euc_ros.ros.foxglove_bridge import websocket_url

    url = websocket_url(address, port)
    if local:
        return (f"view: Foxglove WebSocket server at {url}, this machine only (live data leave this machine "
                f"only when --address names a non-local address)")
    return (f"view: Foxglove WebSocket server at {url}, reachable from other machines: live data can leave "
            f"this machine (--address {address} is not a loopback address)")




def _start_server(address: str, port: int, context):
    import foxglove

    try:
        return foxglove.start_server(name="euc_ros", host=address, port=port, context=context)
    except RuntimeError as exc:
        text = str(exc)
        if "in use" in text:
            hint = "another server (a second `euc-ros view`?) holds it; stop that one or choose --port"
        elif "assign" in text:
            hint = "it is not an address of this machine; give one of its addresses, 127.0.0.1 or 0.0.0.0"
        else:
            hint = "check --address and --port"
        raise ConfigError(f"cannot listen on {address} port {port} ({text}): {hint}", key="--address/--port") \
            from None


def main(args: argparse.Namespace) -> int:
    """Serve until SIGINT or SIGTERM; returns 0."""
    import foxglove
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    from euc_ros.ros.executor import LeanExecutor
    from euc_ros.ros.foxglove_bridge import DISCOVERY_PERIOD_S, FoxgloveBridge, is_local_address

    local = is_local_address(args.address)
    with StopSignals() as stop:
        context = foxglove.Context()
        server = _start_server(args.address, args.port, context)
        node = executor = bridge = None
        try:
            print(start_line(args.address, server.port, local), flush=True)
            rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
            node = rclpy.create_node(NODE_NAME)
            bridge = FoxgloveBridge(node, context, report=lambda line: print(line, flush=True))
            executor = LeanExecutor()
            executor.add_node(node)
            next_discovery = 0.0
            while not stop.is_set():
                now = time.monotonic()
                if now >= next_discovery:
                    bridge.discover()
                    next_discovery = now + DISCOVERY_PERIOD_S
                executor.spin_once(timeout_sec=SPIN_TIMEOUT_S)
            forwarded = sum(t.forwarded for t in bridge.topics.values())
            print(f"view: stopped; forwarded {forwarded} messages on {len(bridge.topics)} topics", flush=True)
        finally:
            if bridge is not None:
                bridge.close()
            if executor is not None:
                executor.shutdown(timeout_sec=0.0)
            if node is not None:
                node.destroy_node()
            rclpy.try_shutdown()
            server.stop()
    return 0
