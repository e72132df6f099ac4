"""In-process delivery between nodes of one process (:mod:`euc_ros.nodes.container`).

The links, and the publisher that hands its messages to in-process handlers before the middleware.
"""
from __future__ import annotations


class LocalFanout:
    """A publisher that also hands each message to in-process handlers, before the middleware.

    ``publish(msg, local=None)`` calls every handler with ``local`` if given (a richer in-process form,
    e.g. the core Frame a MocapFrame was serialized from) or ``msg``, then publishes ``msg`` to DDS
    (other processes). In-process delivery first, as rclcpp's publisher does it: the chain a frame
    starts (state, then torque) is computed and its last output published before the middleware
    carries the frame and the state to other processes (a DDS write with three readers costs
    ~0.1-0.4 ms here, twice on the way to the torque otherwise). Everything else (``topic_name``,
    ``handle``...) is the wrapped publisher's; ``get_subscription_count`` counts the in-process
    subscribers too.
    """

    def __init__(self, publisher, handlers=()) -> None:
        self._pub = publisher
        self.handlers = list(handlers)

    def publish(self, msg, local=None) -> None:
        """Call every in-process handler, in order, then publish to DDS."""
        arg = msg if local is None else local
        try:
            for handler in self.handlers:
                handler(arg)
        finally:                       # a handler's failure never keeps the message from the middleware
            self._pub.publish(msg)

    def get_subscription_count(self) -> int:
        """Matched DDS subscriptions plus the in-process subscribers."""
        return self._pub.get_subscription_count() + len(self.handlers)

    def __getattr__(self, name):
        return getattr(self._pub, name)


#: In-process links: (publisher node, publisher attribute, subscriber node, DDS subscription
#: attribute, handler attribute taking one message as the subscription's callback would).
LINKS = (
    ("mocap_ingest", "frame_pub", "rider_state", "_frame_sub", "_on_frame_local"),
    ("rider_state", "state_pub", "torque_estimator", "_state_sub", "_on_state"),
)


def link(nodes) -> list[str]:
    """Make the :data:`LINKS` whose both ends are among ``nodes`` (by node name) in-process.

    Returns one line per link made (``mocap_ingest -> rider_state on /mocap/frame``). A link is made
    only when the publisher's topic and the subscription's resolve to the same name (remaps and
    namespaces respected).
    """
    by_name = {}
    for node in nodes:
        by_name.setdefault(getattr(type(node), "NAME", node.get_name()), node)
    made = []
    for pub_name, pub_attr, sub_name, sub_attr, handler_attr in LINKS:
        pub_node, sub_node = by_name.get(pub_name), by_name.get(sub_name)
        if pub_node is None or sub_node is None:
            continue
        pub, sub = getattr(pub_node, pub_attr), getattr(sub_node, sub_attr, None)
        if sub is None:
            continue
        if pub.topic_name != sub.topic_name:
            continue
        if not isinstance(pub, LocalFanout):
            pub = LocalFanout(pub)
            setattr(pub_node, pub_attr, pub)
        pub.handlers.append(getattr(sub_node, handler_attr))
        sub_node.destroy_subscription(sub)
        setattr(sub_node, sub_attr, None)
        made.append(f"{pub_node.get_name()} -> {sub_node.get_name()} on {pub.topic_name}")
    return made
