"""The one module that uses rclpy's private API, behind a version guard with a public fallback.

The pipeline's executor (:mod:`euc_ros.ros.executor`) and its batch subscriptions
(:mod:`euc_ros.ros.drain`) work at the level rclpy's own executor works at, which is what saves
~0.4 ms per message (see the executor's module docstring). That level is rclpy's implementation,
not its API, and it changes between ROS distributions. Every use of it is in this module:

==================================  ==========================================================
private part of rclpy               used for
==================================  ==========================================================
``rclpy.impl.implementation_``      ``WaitSet``: a wait set kept across spins;
``singleton`` (the C extension)     ``Subscription``: an rcl subscription without an rclpy
                                    callback (the drain takes its messages itself)
methods of entity handles           ``take_message``, ``is_timer_ready``, ``call_timer``,
                                    ``service_take_request``, ``pointer``,
                                    ``destroy_when_not_in_use``; the wait set's methods
``Executor._guard``,                the guard conditions every wait includes (wake-ups, signals)
``Executor._sigint_gc``
``Executor._tasks``                 whether rclpy's task machinery has work pending
``Subscription._callback_type``     whether a callback takes a MessageInfo too
``Node._wake_executor``             wake the executor when a drain's wait set grows
``Waitable._futures``,              hand a waitable's futures to the executor, as rclpy does
``Future._set_executor``
==================================  ==========================================================

The guard: :func:`private_api_problem` returns why these must not be used, or None when they may:
the installed rclpy is outside :data:`SUPPORTED_RCLPY` (the releases this was written and tested
for: Jazzy's rclpy 7.x), a private name is missing, or the environment sets
``EUC_ROS_PUBLIC_EXECUTOR=1``. Then :class:`~euc_ros.ros.executor.LeanExecutor` runs as rclpy's
public :class:`~rclpy.executors.SingleThreadedExecutor` and
:class:`~euc_ros.ros.drain.SubscriptionDrain` subscribes with the public ``create_subscription``:
the same messages in the same order, at rclpy's cost per message.
"""
from __future__ import annotations

import functools
import importlib.metadata
import os
import re
from contextlib import ExitStack

from rclpy.exceptions import InvalidHandle
from rclpy.node import Node
from rclpy.subscription import Subscription
from rclpy.utilities import timeout_sec_to_nsec
from rclpy.waitable import NumberOfEntities

#: Environment variable that makes every executor and drain of the process use rclpy's public API (``1``).
PUBLIC_EXECUTOR_ENV = "EUC_ROS_PUBLIC_EXECUTOR"
#: rclpy releases the private use below was written for, ``[low, high)``: Jazzy's rclpy 7.x.
SUPPORTED_RCLPY = ((7, 0), (8, 0))
#: Names of the C extension used here.
_EXTENSION_NAMES = ("WaitSet", "Subscription")
#: Attributes every rclpy executor has after ``__init__`` that :class:`LeanExecutor` reads.
_EXECUTOR_NAMES = ("_guard", "_sigint_gc", "_tasks")


def rclpy_version() -> tuple[int, ...] | None:
    """The installed rclpy's version as integers (``(7, 1, 5)``), or None when no metadata says it."""
    try:
        text = importlib.metadata.version("rclpy")
    except importlib.metadata.PackageNotFoundError:
        return None
    m = re.match(r"^(\d+)\.(\d+)(?:\.(\d+))?", text)
    return tuple(int(g) for g in m.groups() if g is not None) if m else None


def _extension():
    """The rclpy C extension, or None when it cannot be reached the way this module knows."""
    try:
        from rclpy.impl.implementation_singleton import rclpy_implementation
    except ImportError:
        return None
    return rclpy_implementation


@functools.lru_cache(maxsize=1)
def _installed_problem() -> str | None:
    """What about the installed rclpy rules out the private API (version, names), or None."""
    version = rclpy_version()
    low, high = SUPPORTED_RCLPY
    if version is None:
        return "the rclpy version is unknown (no package metadata)"
    if not low <= version[:2] < high:
        return (f"rclpy {'.'.join(map(str, version))} is outside the releases the lean executor was written for "
                f"({low[0]}.{low[1]} <= version < {high[0]}.{high[1]})")
    ext = _extension()
    missing = ["rclpy.impl.implementation_singleton"] if ext is None else \
        [f"rclpy_implementation.{n}" for n in _EXTENSION_NAMES if not hasattr(ext, n)]
    if not hasattr(Node, "_wake_executor"):
        missing.append("Node._wake_executor")
    if missing:
        return f"rclpy {'.'.join(map(str, version))} lacks {', '.join(missing)}"
    return None


def private_api_problem(environ=None) -> str | None:
    """Why the private API must not be used in this process (the public executor is used), or None.

    Parameters
    ----------
    environ : mapping, optional
        Environment to read ``EUC_ROS_PUBLIC_EXECUTOR`` from (default: ``os.environ``).
    """
    env = os.environ if environ is None else environ
    if env.get(PUBLIC_EXECUTOR_ENV, "").strip() not in ("", "0"):
        return f"{PUBLIC_EXECUTOR_ENV}={env[PUBLIC_EXECUTOR_ENV]}"
    return _installed_problem()


def executor_problem(executor) -> str | None:
    """What the instance ``executor`` lacks of the private attributes read here, or None."""
    missing = [n for n in _EXECUTOR_NAMES if not hasattr(executor, n)]
    return f"rclpy's Executor lacks {', '.join(missing)}" if missing else None


# -- executor internals ------------------------------------------------------------------------------------------------
def executor_guards(executor) -> list:
    """The executor's own guard conditions (its wake-up and its signal guard), those not destroyed yet."""
    return [g for g in (executor._guard, executor._sigint_gc) if g is not None]


def is_signal_guard(executor, guard) -> bool:
    """Whether ``guard`` is the guard condition rclpy's signal thread triggers on SIGINT/SIGTERM."""
    return guard is not None and guard is executor._sigint_gc


def has_signal_guard(executor) -> bool:
    """Whether the executor still has its signal guard condition (destroyed by ``shutdown``)."""
    return executor._sigint_gc is not None


def has_pending_tasks(executor) -> bool:
    """Whether rclpy's task machinery holds work (a coroutine waiting on a future, a client's task)."""
    return bool(executor._tasks)


def adopt_futures(waitable, executor) -> None:
    """Hand the futures a waitable carries (e.g. an ActionClient's) to ``executor``, as rclpy's executor does."""
    for future in getattr(waitable, "_futures", ()):
        future._set_executor(executor)


def wake_executor(node) -> None:
    """Wake the executor ``node`` is added to, so it lists the node's entities again."""
    node._wake_executor()


def takes_message_info(subscription) -> bool:
    """Whether the subscription's callback takes ``(message, MessageInfo)``."""
    return subscription._callback_type is not Subscription.CallbackType.MessageOnly


# -- entities ----------------------------------------------------------------------------------------------------------
def take(subscription):
    """Take one message from an rclpy subscription: ``(message or bytes, info dict)`` or None.

    Raises :class:`~rclpy.exceptions.InvalidHandle` when the subscription was destroyed.
    """
    handle = subscription.handle
    with handle:
        return handle.take_message(subscription.msg_type, subscription.raw)


def fire_timer(timer) -> bool:
    """Mark a ready timer as called; False when it is not ready after all (cancelled meanwhile) or destroyed."""
    try:
        with timer.handle:
            if not timer.handle.is_timer_ready():      # cancelled after the wait (an rcl quirk)
                return False
            timer.handle.call_timer()
    except InvalidHandle:
        return False
    return True


def take_request(service):
    """Take one request from a service: ``(request, header)``, or None (none waiting, or destroyed)."""
    try:
        with service.handle:
            request, header = service.handle.service_take_request(service.srv_type.Request)
    except InvalidHandle:
        return None
    return None if header is None else (request, header)


def rcl_subscription(node, msg_class, topic: str, qos):
    """An rcl subscription on ``node`` that no rclpy callback serves (its owner takes the messages)."""
    with node.handle:
        return _extension().Subscription(node.handle, msg_class, topic, qos.get_c_qos_profile())


def take_raw(handle, msg_class):
    """Take one message's CDR bytes from an rcl subscription handle, or None."""
    got = handle.take_message(msg_class, True)
    return None if got is None else got[0]


def publisher_count(handle) -> int:
    """Publishers matched with an rcl subscription handle (DDS matches, not the graph's view)."""
    with handle:
        return int(handle.get_publisher_count())


def destroy_handle(handle) -> None:
    """Destroy an rcl subscription handle once nothing uses it."""
    handle.destroy_when_not_in_use()


def add_to_wait_set(wait_set, handle) -> int:
    """Add an rcl subscription handle to a wait set; returns its index there."""
    return wait_set.add_subscription(handle)


def subscription_ready(wait_set, index: int) -> bool:
    """Whether the subscription at ``index`` of the wait set has data."""
    return wait_set.is_ready("subscription", index)


# -- a wait set kept across spins --------------------------------------------------------------------------------------
class KeptWaitSet:
    """The entities of an executor's nodes and a wait set sized for them, kept across spins.

    rclpy's executor builds a wait set per spin; this one is built once per listing of the entities
    and refilled on each wait.

    Parameters
    ----------
    key : hashable
        What the listing was made from (the executor compares it to decide on a new one).
    subs, timers, services, guards, waitables : list
        The entities. One already destroyed (e.g. by its own ``destroy()``, which leaves it in its
        node's list) is left out, as rclpy's executor leaves it out.
    context : rclpy.Context
    """

    __slots__ = ("key", "subs", "timers", "services", "guards", "waitables", "wait_set",
                 "sub_by_ptr", "timer_by_ptr", "srv_by_ptr", "gc_by_ptr")

    def __init__(self, key, subs, timers, services, guards, waitables, context) -> None:
        self.key = key
        with ExitStack() as probe:
            def live(entities, of=lambda e: e.handle):
                out = []
                for e in entities:
                    try:
                        probe.enter_context(of(e))
                    except InvalidHandle:
                        continue
                    out.append(e)
                return out

            self.subs, self.timers = live(subs), live(timers)
            self.services, self.guards = live(services), live(guards)
            self.waitables = live(waitables, of=lambda w: w)
            count = NumberOfEntities(len(self.subs), len(self.guards), len(self.timers), 0, len(self.services))
            for waitable in self.waitables:
                count += waitable.get_num_entities()
            self.sub_by_ptr = {s.handle.pointer: s for s in self.subs}
            self.timer_by_ptr = {t.handle.pointer: t for t in self.timers}
            self.srv_by_ptr = {s.handle.pointer: s for s in self.services}
            self.gc_by_ptr = {g.handle.pointer: g for g in self.guards}
        with context.handle:
            self.wait_set = _extension().WaitSet(count.num_subscriptions, count.num_guard_conditions,
                                                 count.num_timers, count.num_clients, count.num_services,
                                                 count.num_events, context.handle)

    def enter(self, stack) -> bool:
        """Mark every handle in use for this spin (False when one was destroyed since listing: list again).

        In use, a handle is not destroyed under the wait set; the callbacks run after the handles
        are let go, so a ``destroy`` from a callback takes effect at once (a later take from the
        destroyed entity in the same spin is skipped).
        """
        enter = stack.enter_context
        try:
            for group in (self.subs, self.timers, self.services, self.guards):
                for entity in group:
                    enter(entity.handle)
            for waitable in self.waitables:
                enter(waitable)
        except InvalidHandle:
            return False
        return True

    def wait(self, context, timeout_sec: float | None) -> None:
        """Put every entity into the (cleared) wait set and wait up to ``timeout_sec`` (forever if None)."""
        ws = self.wait_set
        with context.handle:
            ws.clear_entities()
            for s in self.subs:
                ws.add_subscription(s.handle)
            for t in self.timers:
                ws.add_timer(t.handle)
            for s in self.services:
                ws.add_service(s.handle)
            for g in self.guards:
                ws.add_guard_condition(g.handle)
            for w in self.waitables:
                w.add_to_wait_set(ws)
            ws.wait(timeout_sec_to_nsec(timeout_sec))

    def ready(self) -> tuple[list, list, list, list, list]:
        """What the last wait found ready: ``(waitables, timers, subscriptions, services, guards)``."""
        ws = self.wait_set
        return ([w for w in self.waitables if w.is_ready(ws)],
                [self.timer_by_ptr[p] for p in ws.get_ready_entities("timer") if p in self.timer_by_ptr],
                [self.sub_by_ptr[p] for p in ws.get_ready_entities("subscription") if p in self.sub_by_ptr],
                [self.srv_by_ptr[p] for p in ws.get_ready_entities("service") if p in self.srv_by_ptr],
                [self.gc_by_ptr[p] for p in ws.get_ready_entities("guard_condition") if p in self.gc_by_ptr])
