"""Raw subscriptions taken in batches: one executor entity for many topics (recorder, monitor).

rclpy's Python executor costs one wait-set rebuild per callback (~0.1-0.3 ms on this class of
machine), which at 360 Hz frames, states and torques is most of a node's CPU. A node that does not
need each message the moment it arrives (the recorder writes them, the monitor counts them) takes
them through :class:`SubscriptionDrain` instead: one wake-up takes everything queued on every
topic, then it polls every ``POLL_S`` while messages keep coming.

The rcl subscriptions and the wait-set calls are rclpy's implementation level, reached only through
:mod:`euc_ros.ros.rclpy_compat`; where its guard refuses, each topic gets a public raw subscription
whose callback hands its one message to the sink (same messages, one executor cycle each).
"""
from __future__ import annotations

import time
from contextlib import ExitStack

from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.type_support import check_for_type_support
from rclpy.waitable import NumberOfEntities, Waitable

from euc_ros.ros import rclpy_compat as compat


class SubscriptionDrain(Waitable):
    """Raw subscriptions as one executor entity that, when any is ready, takes all they hold.

    ``subscribe`` creates an rcl subscription that is not an rclpy callback (the executor does not
    take its messages one by one); the executor waits on all of them through this waitable and, on
    a wake, :meth:`take_data` takes every message of every subscription until rcl has none left.
    :meth:`execute` hands them to ``sink([(topic, type name, datas), ...])``.

    Parameters
    ----------
    node : rclpy.node.Node
        Owner of the subscriptions (add the drain to it with ``node.add_waitable``).
    sink : callable
        ``sink([(topic, type name, [cdr bytes, ...]), ...])``.
    poll_s, max_poll_s : float, optional
        :attr:`POLL_S` and :attr:`MAX_POLL_S` of this drain.
    public : bool, optional
        True: public subscriptions, one message per callback. Otherwise they are public when
        :func:`~euc_ros.ros.rclpy_compat.private_api_problem` finds a reason to.
    """

    #: Poll period while messages flow [s]: they wait in the DDS queues (the subscription's depth).
    POLL_S = 0.002
    #: Longest polling stretch before the executor runs its other entities again [s].
    MAX_POLL_S = 0.05

    def __init__(self, node: Node, sink, *, poll_s: float | None = None, max_poll_s: float | None = None,
                 public: bool | None = None) -> None:
        super().__init__(node.default_callback_group)
        self._node = node
        self._sink = sink
        self.POLL_S = self.POLL_S if poll_s is None else float(poll_s)
        self.MAX_POLL_S = self.MAX_POLL_S if max_poll_s is None else float(max_poll_s)
        self.public = bool(public) or compat.private_api_problem() is not None
        self.subs: list[tuple[str, str, object, type]] = []    # (topic, type name, rcl handle, class)
        self._public_subs: list = []
        self._indices: list[int] = []
        self._stack: ExitStack | None = None

    def subscribe(self, topic: str, type_name: str, cls: type, qos: QoSProfile) -> None:
        """Subscribe ``topic`` (raw) and wait on it from the next executor cycle on."""
        check_for_type_support(cls)
        if self.public:
            def one(data, topic=topic, type_name=type_name):
                self._sink([(topic, type_name, [data])])
            self._public_subs.append(self._node.create_subscription(
                cls, topic, one, qos, raw=True,
                event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False)))
            return
        handle = compat.rcl_subscription(self._node, cls, topic, qos)
        self.subs.append((topic, type_name, handle, cls))
        compat.wake_executor(self._node)            # the executor's wait set must grow

    def take_all(self) -> list[tuple[str, str, list[bytes]]]:
        """Take every message each subscription holds: ``[(topic, type name, [cdr bytes...]), ...]``.

        Public subscriptions hand their messages over as they come: nothing is left to take.
        """
        out = []
        take = compat.take_raw
        for topic, type_name, handle, cls in self.subs:
            datas = []
            while (data := take(handle, cls)) is not None:
                datas.append(data)
            if datas:
                out.append((topic, type_name, datas))
        return out

    def publisher_counts(self) -> dict[str, int]:
        """Per subscribed topic, the publishers its subscription has matched."""
        out = {topic: compat.publisher_count(handle) for topic, _, handle, _ in self.subs}
        out.update({sub.topic_name: sub.get_publisher_count() for sub in self._public_subs})
        return out

    def destroy(self) -> None:
        """Destroy the subscriptions (after the last :meth:`take_all`)."""
        for _, _, handle, _ in self.subs:
            compat.destroy_handle(handle)
        self.subs = []
        for sub in self._public_subs:
            self._node.destroy_subscription(sub)
        self._public_subs = []

    # -- Waitable API (rclpy 7.1) ----------------------------------------------------------------------------------
    def __enter__(self):
        self._stack = ExitStack()
        for _, _, handle, _ in self.subs:
            self._stack.enter_context(handle)
        return self

    def __exit__(self, t, v, tb):
        if self._stack is not None:
            self._stack.close()
            self._stack = None

    def get_num_entities(self) -> NumberOfEntities:
        """The entities this waitable adds to a wait set: one per raw subscription.

        Returns
        -------
        NumberOfEntities
        """
        return NumberOfEntities(len(self.subs))

    def add_to_wait_set(self, wait_set) -> None:
        """Add the raw subscriptions to ``wait_set`` and remember their indices.

        Parameters
        ----------
        wait_set
            rclpy's wait set of this executor cycle.
        """
        self._indices = [compat.add_to_wait_set(wait_set, handle) for _, _, handle, _ in self.subs]

    def is_ready(self, wait_set) -> bool:
        """Whether a raw subscription of this drain is ready in ``wait_set``.

        Parameters
        ----------
        wait_set
            The wait set after the wait.

        Returns
        -------
        bool
        """
        return any(compat.subscription_ready(wait_set, i) for i in self._indices)

    def take_data(self):
        """Take every message the subscriptions hold (:meth:`take_all`).

        Returns
        -------
        list of tuple
            ``[(topic, type name, [cdr bytes...]), ...]``, handed to :meth:`execute`.
        """
        return self.take_all()

    async def execute(self, taken_data) -> None:
        """Hand what was taken to the sink; then, while messages keep coming, poll instead of waiting.

        Polling every :attr:`POLL_S` lets messages gather in the DDS queues and takes them in one
        pass without an executor cycle per pass; back to the executor (timers, services, shutdown)
        when a pass finds nothing, or after :attr:`MAX_POLL_S`.
        """
        self._sink(taken_data)
        context = self._node.context
        end = time.monotonic() + self.MAX_POLL_S
        while time.monotonic() < end and context.ok():
            time.sleep(self.POLL_S)
            taken_data = self.take_all()
            if not taken_data:
                break
            self._sink(taken_data)
