"""In-process delivery between nodes of one process (:mod:`euc_ros.nodes.container`)."""
from __future__ import annotations


class LocalFanout:
    """A publisher that also hands each message to in-process handlers, after the middleware.

    ``publish(msg, local=None)`` publishes ``msg`` to DDS (other processes), then calls every handler
    with ``local`` if given (a richer in-process form, e.g. the core Frame a MocapFrame was
    serialized from) or ``msg``. Everything else (``topic_name``, ``handle``...) is the wrapped
    publisher's; ``get_subscription_count`` counts the in-process subscribers too.
    """

    def __init__(self, publisher, handlers=()) -> None:
        self._pub = publisher
        self.handlers = list(handlers)

    def publish(self, msg, local=None) -> None:
        """Publish to DDS, then call every in-process handler, in order."""
        self._pub.publish(msg)
        arg = msg if local is None else local
        for handler in self.handlers:
            handler(arg)

    def get_subscription_count(self) -> int:
        """Matched DDS subscriptions plus the in-process subscribers."""
        return self._pub.get_subscription_count() + len(self.handlers)

    def __getattr__(self, name):
        return getattr(self._pub, name)
