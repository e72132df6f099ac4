"""Live ROS topics to Foxglove over its WebSocket protocol, with no ROS tool on the viewing side.

:class:`FoxgloveBridge` subscribes to the pipeline's topics with raw (serialized) subscriptions and
logs each message's CDR bytes, unchanged, on a ``foxglove-sdk`` channel of the same name. Each
channel carries the ROS 2 message encoding (``cdr``) and a ``ros2msg`` schema: the message
definition with its dependencies, in the text form rosbag2 writes into MCAP files. Foxglove then
decodes the messages itself, as it decodes a recorded bag, and the project's layout
(``config/foxglove/``) shows live data and bags alike.

Topics viewed
-------------
The fixed topics of :data:`VIEW_TOPICS` and every per-body pose ``mocap/<body>/pose``, taken from
the ROS graph as their publishers appear (:meth:`FoxgloveBridge.discover`, called periodically).
A topic is bridged with the type its publishers announce; one whose publishers disagree on the
type, or whose type has no definition or no Python message class here, is reported and skipped.

Subscriptions are best effort with a shallow queue (:data:`VIEW_QOS`): they match reliable and
best-effort publishers alike, and a slow viewer never holds a publisher back.

The address rule
----------------
The server listens on the loopback interface unless an address is given
(:func:`is_local_address` tells which addresses keep the data on this machine).
"""
from __future__ import annotations

import importlib
import ipaddress
import re
import socket
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from euc_ros.core.errors import ConfigError
from euc_ros.ros import interfaces as itf

#: Message encoding of every channel: ROS 2 serialized messages, forwarded as rclpy takes them.
MESSAGE_ENCODING = "cdr"
#: Schema encoding: ROS 2 ``.msg`` text with dependencies, as rosbag2 writes into MCAP.
SCHEMA_ENCODING = "ros2msg"
#: Default address: the loopback interface only.
DEFAULT_ADDRESS = "127.0.0.1"
#: Default port of the Foxglove WebSocket protocol.
DEFAULT_PORT = 8765
#: Period of the ROS graph look-ups that find new topics [s].
DISCOVERY_PERIOD_S = 1.0
#: Depth of each viewing subscription's queue: ~0.4 s of a 240 Hz topic (a viewer wants the latest).
VIEW_QUEUE_DEPTH = 100

#: The pipeline's topics shown besides the per-body poses (absolute names, as Foxglove lists them).
VIEW_TOPICS = tuple("/" + t.lstrip("/") for t in (
    itf.MOCAP_FRAME, itf.RIDER_STATE, itf.TORQUE, itf.DIAGNOSTICS, itf.TF,
    itf.UNICYCLE_STATE, itf.UNICYCLE_POSE, itf.STEERING_COMMAND,
))

_prefix, _suffix = itf.MOCAP_BODY_POSE.split("{name}")
#: Per-body pose topics (``/mocap/<body>/pose``), one path level for the body.
BODY_POSE_PATTERN = re.compile("^/" + re.escape(_prefix.lstrip("/")) + r"[^/]+" + re.escape(_suffix) + "$")


def _view_qos():
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=VIEW_QUEUE_DEPTH,
                      reliability=ReliabilityPolicy.BEST_EFFORT, durability=DurabilityPolicy.VOLATILE)


def is_viewed(topic: str) -> bool:
    """Whether ``topic`` (an absolute ROS name) is one that ``euc-ros view`` shows.

    Parameters
    ----------
    topic : str
        Absolute topic name, e.g. ``/mocap/H/pose``.

    Returns
    -------
    bool
        True for the topics of :data:`VIEW_TOPICS` and the per-body poses.

    Examples
    --------
    >>> is_viewed("/mocap/H/pose"), is_viewed("/euc/torque"), is_viewed("/mocap/a/b/pose")
    (True, True, False)
    """
    return topic in VIEW_TOPICS or BODY_POSE_PATTERN.match(topic) is not None


def is_local_address(address: str) -> bool:
    """Whether a server bound to ``address`` is reachable from this machine only.

    Parameters
    ----------
    address : str
        IP address or host name to listen on.

    Returns
    -------
    bool
        True when every address ``address`` stands for is a loopback address (``127.0.0.0/8``,
        ``::1``, ``localhost``). False for the wildcard addresses (``0.0.0.0``, ``::``), which
        listen on every interface, and for any other interface's address.

    Raises
    ------
    ConfigError
        When ``address`` is neither an IP address nor a host name that resolves.

    Examples
    --------
    >>> is_local_address("127.0.0.1"), is_local_address("::1"), is_local_address("0.0.0.0")
    (True, True, False)
    """
    try:
        return ipaddress.ip_address(address).is_loopback
    except ValueError:
        pass
    try:
        infos = socket.getaddrinfo(address, None)
    except (socket.gaierror, UnicodeError) as exc:
        raise ConfigError(f"cannot resolve {address!r} ({exc}); give an IP address of this machine, e.g. "
                          f"{DEFAULT_ADDRESS} (this machine only) or 0.0.0.0 (every interface)",
                          key="--address") from None
    return bool(infos) and all(ipaddress.ip_address(info[4][0].split("%")[0]).is_loopback for info in infos)


def websocket_url(address: str, port: int) -> str:
    """The ``ws://`` URL of a server on ``address`` and ``port`` (IPv6 addresses in brackets).

    Examples
    --------
    >>> websocket_url("127.0.0.1", 8765), websocket_url("::1", 8765)
    ('ws://127.0.0.1:8765', 'ws://[::1]:8765')
    """
    host = f"[{address}]" if ":" in address else address
    return f"ws://{host}:{port}"


class SchemaBook:
    """``ros2msg`` schema texts of message types, from a rosbags typestore.

    Parameters
    ----------
    typestore : rosbags.typesys.store.Typestore, optional
        Where the definitions come from; default :func:`euc_ros.core.io.msgdefs.make_typestore`
        (the ROS 2 Jazzy types plus the project's ``msg_defs/msg``).
    """

    def __init__(self, typestore=None) -> None:
        if typestore is None:
            from euc_ros.core.io.msgdefs import make_typestore

            typestore = make_typestore()
        self.typestore = typestore
        self._texts: dict[str, str] = {}

    def text(self, type_name: str) -> str:
        """The ``ros2msg`` text of ``type_name`` with its dependencies.

        Parameters
        ----------
        type_name : str
            Full type name, e.g. ``geometry_msgs/msg/PoseStamped``.

        Returns
        -------
        str
            The definition, then each dependency after a line of ``=`` and ``MSG: pkg/Name``.

        Raises
        ------
        KeyError
            When the typestore does not know ``type_name`` or one of its dependencies.
        """
        text = self._texts.get(type_name)
        if text is None:
            if type_name not in self.typestore.types:
                raise KeyError(type_name)
            text, _ = self.typestore.generate_msgdef(type_name, ros_version=2)
            self._texts[type_name] = text
        return text


def message_class(type_name: str):
    """The Python message class of ``type_name`` (``pkg/msg/Name``), for rclpy's type support.

    Raises
    ------
    ImportError, AttributeError, ValueError
        When the interface package is not installed or the name is malformed.
    """
    pkg, kind, name = type_name.split("/")
    return getattr(importlib.import_module(f"{pkg}.{kind}"), name)


@dataclass
class BridgedTopic:
    """One topic forwarded to Foxglove: its type, channel, subscription and message count."""

    topic: str
    type_name: str
    channel: object
    subscription: object
    forwarded: int = 0


class FoxgloveBridge:
    """Forward the viewed ROS topics of ``node``'s graph to the Foxglove channels of ``context``.

    Parameters
    ----------
    node : rclpy.node.Node
        Node whose graph is searched and that holds the subscriptions.
    context : foxglove.Context
        Foxglove context the channels are created in (the server's).
    schemas : SchemaBook, optional
        Message definitions (default: a new :class:`SchemaBook`).
    select : callable, optional
        ``select(topic) -> bool`` over absolute topic names (default :func:`is_viewed`).
    report : callable, optional
        Called with one line of text per topic bridged or skipped (default: nothing).

    Attributes
    ----------
    topics : dict of str to BridgedTopic
        The topics bridged so far.
    skipped : dict of str to str
        Selected topics not bridged, and bridged topics that publishers of another type joined, with
        the reason.
    """

    def __init__(self, node, context, *, schemas: SchemaBook | None = None,
                 select: Callable[[str], bool] = is_viewed, report: Callable[[str], None] | None = None) -> None:
        self.node = node
        self.context = context
        self.schemas = SchemaBook() if schemas is None else schemas
        self.select = select
        self.report = report if report is not None else (lambda _line: None)
        self.topics: dict[str, BridgedTopic] = {}
        self.skipped: dict[str, str] = {}

    def discover(self) -> list[str]:
        """Bridge every selected topic of the graph that is not bridged yet; return the new ones.

        Returns
        -------
        list of str
            Topics bridged by this call.
        """
        new = []
        for topic, types in self.node.get_topic_names_and_types():
            if topic in self.topics:
                self._check_type(topic, types)
                continue
            if not self.select(topic):
                continue
            reason = self._bridge(topic, types)
            if reason is None:
                new.append(topic)
                self.skipped.pop(topic, None)
                self.report(f"view: {topic} ({self.topics[topic].type_name})")
            elif self.skipped.get(topic) != reason:
                self.skipped[topic] = reason
                self.report(f"view: skipping {topic}: {reason}")
        return new

    def _check_type(self, topic: str, types: Iterable[str]) -> None:
        """Say once when publishers of another type join a bridged topic (they do not match its subscription)."""
        others = sorted(set(types) - {self.topics[topic].type_name})
        reason = f"publishers of {', '.join(others)} are not shown (bridged as {self.topics[topic].type_name})"
        if others and self.skipped.get(topic) != reason:
            self.skipped[topic] = reason
            self.report(f"view: {topic}: {reason}")

    def _bridge(self, topic: str, types: Iterable[str]) -> str | None:
        """Create the channel and the subscription of ``topic``; return why not, or None."""
        import foxglove

        types = sorted(set(types))
        if len(types) != 1:
            return f"its publishers disagree on the type ({', '.join(types)}); give every publisher one type"
        type_name = types[0]
        try:
            text = self.schemas.text(type_name)
        except KeyError as exc:
            return (f"no message definition for {exc.args[0]} (install its interface package, or add its .msg "
                    f"files to msg_defs/msg if it is one of ours)")
        try:
            cls = message_class(type_name)
        except (ImportError, AttributeError, ValueError) as exc:
            return f"no Python message class for {type_name} ({exc}); install its interface package"
        schema = foxglove.Schema(name=type_name, encoding=SCHEMA_ENCODING, data=text.encode("utf-8"))
        channel = foxglove.Channel(topic, schema=schema, message_encoding=MESSAGE_ENCODING, context=self.context)
        entry = BridgedTopic(topic, type_name, channel, None)
        log = channel.base.log

        def forward(data: bytes) -> None:
            entry.forwarded += 1
            log(data)

        entry.subscription = self.node.create_subscription(cls, topic, forward, _view_qos(), raw=True,
                                                           event_callbacks=itf.sub_events())
        self.topics[topic] = entry
        return None

    def close(self) -> None:
        """Close every channel (clients see them unadvertised) and destroy the subscriptions."""
        for entry in self.topics.values():
            entry.channel.close()
            self.node.destroy_subscription(entry.subscription)
        self.topics.clear()
