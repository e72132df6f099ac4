"""A single-threaded executor with a low fixed cost per wake-up, for the pipeline's nodes.

rclpy's :class:`~rclpy.executors.SingleThreadedExecutor` rebuilds its wait set, enters every
entity's handle, and wraps every callback in a coroutine and a :class:`~rclpy.task.Task` on each
spin: ~0.45 ms per message on this class of machine, on top of ~0.1 ms that the middleware and the
take itself cost (measured with a 360 Hz raw publisher and a subscriber doing nothing: 612 us per
message through ``rclpy.spin``, 168 us with a reused wait set). At 360 Hz frames, states and
torques that is most of a pipeline node's CPU.

:class:`LeanExecutor` does the same work with less Python in between:

- the wait set is kept while the nodes' entities stay the same (rebuilt when one is added or
  destroyed);
- a ready subscription is taken until empty (at most :attr:`LeanExecutor.batch` messages) in one
  wake-up, oldest first, each message handed to its callback as rclpy would (raw bytes or a
  message; with :class:`~rclpy.subscription.MessageInfo` when the callback takes two arguments);
- timers, services, guard conditions and waitables (e.g. :class:`~euc_ros.ros.drain.SubscriptionDrain`
  and QoS event handlers) run as rclpy runs them.

Everything that needs rclpy's task machinery (service clients, coroutine callbacks, futures,
callback groups that refuse to run) goes through :class:`~rclpy.executors.SingleThreadedExecutor`'s
own path: this class is a subclass and falls back to it whenever a node has a client or a task is
pending. Exceptions from callbacks propagate out of :meth:`spin_once`, as with rclpy's.
"""
from __future__ import annotations

import inspect
import time
from contextlib import ExitStack

from rclpy.exceptions import InvalidHandle
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.subscription import Subscription
from rclpy.utilities import timeout_sec_to_nsec
from rclpy.waitable import NumberOfEntities


#: Longest wait, after a signal, for rclpy's signal thread to shut the context down [s].
SIGNAL_THREAD_S = 2.0


def wait_for_context_shutdown(context, timeout_s: float = SIGNAL_THREAD_S) -> bool:
    """After SIGINT/SIGTERM, wait until rclpy's signal thread has shut ``context`` down; True if it has.

    rclpy (Jazzy) handles a signal on a thread of its own: it triggers every executor's signal guard
    condition, **then** shuts the contexts down. So a context that is no longer ok means the signal
    thread is done with the guard conditions, and an executor (and its guard condition) may be
    destroyed; before that, destroying it is a use after free (SIGSEGV at exit), and waiting again
    may never wake (the shutdown itself wakes no wait set).
    """
    deadline = time.monotonic() + timeout_s
    while context.ok():
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.002)
    return True


class _Entities:
    """The entities of the executor's nodes, and a wait set sized for them (kept across spins)."""

    __slots__ = ("key", "subs", "timers", "services", "guards", "waitables", "wait_set",
                 "sub_by_ptr", "timer_by_ptr", "srv_by_ptr", "gc_by_ptr")

    def __init__(self, key, subs, timers, services, guards, waitables, context) -> None:
        """List the live entities. One already destroyed (e.g. by its own ``destroy()``, which leaves
        it in its node's list) is left out, as rclpy's executor leaves it out."""
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
            self.wait_set = _rclpy.WaitSet(count.num_subscriptions, count.num_guard_conditions, count.num_timers,
                                           count.num_clients, count.num_services, count.num_events, context.handle)

    def enter(self, stack: ExitStack) -> bool:
        """Mark every handle in use for this spin (False when one was destroyed since listing: rebuild).

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

    def fill(self) -> None:
        """Put every entity into the (cleared) wait set."""
        ws = self.wait_set
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


def _sizes(waitable) -> tuple:
    n = waitable.get_num_entities()
    return n.num_subscriptions, n.num_guard_conditions, n.num_timers, n.num_clients, n.num_services, n.num_events


class LeanExecutor(SingleThreadedExecutor):
    """Single-threaded executor with a reused wait set and subscriptions taken in batches.

    Parameters
    ----------
    context : rclpy.Context, optional
    batch : int
        Most messages taken from one subscription per wake-up before the other entities run.
    """

    #: Longest time between two listings of the nodes' entities [s] (they are listed again at once
    #: when rclpy wakes the executor, which it does on every create_* and destroy_*).
    RELIST_S = 0.5

    def __init__(self, *, context=None, batch: int = 64) -> None:
        super().__init__(context=context)
        self.batch = int(batch)
        self._ents: _Entities | None = None
        self._dirty = True
        self._listed_at = 0.0

    def wake(self) -> None:
        """rclpy calls this when a node adds or destroys an entity: list them again next spin."""
        self._dirty = True
        super().wake()

    # -- entity bookkeeping ----------------------------------------------------------------------------------------
    def _collect(self):
        nodes = self.get_nodes()
        subs, timers, services, guards, waitables = [], [], [], [], []
        for node in nodes:
            if next(iter(node.clients), None) is not None:
                return None                                  # a client: rclpy's own path
            subs.extend(node.subscriptions)
            timers.extend(node.timers)
            services.extend(node.services)
            guards.extend(node.guards)
            waitables.extend(node.waitables)
        guards += [g for g in (self._guard, self._sigint_gc) if g is not None]   # None once shut down
        # a waitable may grow (the recorder's drain subscribes topics as they appear): its counts are in the key
        sizes = [(id(w), *_sizes(w)) for w in waitables]
        key = (tuple(map(id, subs)), tuple(map(id, timers)), tuple(map(id, services)), tuple(map(id, guards)),
               tuple(sizes))
        return key, subs, timers, services, guards, waitables

    def _entities(self):
        """The current entities, held (None: use rclpy's path)."""
        ents = self._ents
        if ents is not None and not self._dirty and time.monotonic() - self._listed_at < self.RELIST_S:
            sizes = ents.key[-1]
            if all(_sizes(w) == size[1:] for w, size in zip(ents.waitables, sizes)):
                return ents
        self._dirty = False
        self._listed_at = time.monotonic()
        got = self._collect()
        if got is None:                                      # rclpy's path: hold nothing meanwhile
            self._release()
            return None
        key = got[0]
        if self._ents is None or self._ents.key != key:
            self._release()
            self._ents = _Entities(*got, self._context)
        return self._ents

    def _release(self) -> None:
        self._ents = None

    def add_node(self, node) -> bool:
        self._dirty = True
        return super().add_node(node)

    def remove_node(self, node) -> None:
        self._release()
        super().remove_node(node)

    def shutdown(self, timeout_sec: float | None = None) -> bool:
        self._release()
        return super().shutdown(timeout_sec)

    # -- spinning --------------------------------------------------------------------------------------------------
    def spin_once(self, timeout_sec: float | None = None) -> None:
        """Wait up to ``timeout_sec`` (forever if None) and run everything that became ready."""
        if self._is_shutdown:                                # as rclpy's: nothing to do after shutdown()
            return
        if self._tasks:
            return super().spin_once(timeout_sec)
        ents = self._entities()
        if ents is None:
            return super().spin_once(timeout_sec)
        with ExitStack() as stack:
            if not ents.enter(stack):                        # destroyed since listed: list again, once
                stack.close()
                self._ents = None
                ents = self._entities()
                if ents is None or not ents.enter(stack):
                    return super().spin_once(timeout_sec)
            if self._is_shutdown:                            # shut down from another thread while listing
                return
            ws = ents.wait_set
            with self._context.handle:
                ents.fill()
                ws.wait(timeout_sec_to_nsec(timeout_sec))
            if self._is_shutdown:
                return
            if not self._context.ok():
                raise ExternalShutdownException()
            ready_waitables = [w for w in ents.waitables if w.is_ready(ws)]
            timers = [ents.timer_by_ptr[p] for p in ws.get_ready_entities("timer") if p in ents.timer_by_ptr]
            subs = [ents.sub_by_ptr[p] for p in ws.get_ready_entities("subscription") if p in ents.sub_by_ptr]
            services = [ents.srv_by_ptr[p] for p in ws.get_ready_entities("service") if p in ents.srv_by_ptr]
            guards = [ents.gc_by_ptr[p] for p in ws.get_ready_entities("guard_condition") if p in ents.gc_by_ptr]

        if self._sigint_gc is not None and any(g is self._sigint_gc for g in guards):
            # a SIGINT/SIGTERM: rclpy's signal thread triggers this, then shuts the context down. Waiting
            # again meanwhile would wait forever (nothing wakes a wait set when the context shuts down):
            # wait for the shutdown instead (seen: a steering_controller left spinning after SIGTERM)
            if wait_for_context_shutdown(self._context):
                raise ExternalShutdownException()
        for waitable in ready_waitables:
            for future in getattr(waitable, "_futures", ()):   # as rclpy does (e.g. an ActionClient's)
                future._set_executor(self)
            self._run(waitable.execute(waitable.take_data()))
        for tmr in timers:
            try:
                with tmr.handle:
                    if not tmr.handle.is_timer_ready():      # cancelled meanwhile (rcl quirk)
                        continue
                    tmr.handle.call_timer()
            except InvalidHandle:
                continue
            self._run(tmr.callback())
        for sub in subs:
            self._take_all(sub)
        for gc in guards:
            if gc.callback is not None:
                self._run(gc.callback())
        for srv in services:
            try:
                with srv.handle:
                    request, header = srv.handle.service_take_request(srv.srv_type.Request)
            except InvalidHandle:
                continue
            if header is None:
                continue
            response = srv.callback(request, srv.srv_type.Response())
            if inspect.iscoroutine(response):
                response = self._run(response)
            srv.send_response(response, header)

    def _take_all(self, sub) -> None:
        with_info = sub._callback_type is not Subscription.CallbackType.MessageOnly
        callback, msg_type, raw = sub.callback, sub.msg_type, sub.raw
        for _ in range(self.batch):
            try:
                with sub.handle:
                    got = sub.handle.take_message(msg_type, raw)
            except InvalidHandle:                            # destroyed by an earlier callback
                return
            if got is None:
                return
            result = callback(*got) if with_info else callback(got[0])
            if result is not None and inspect.iscoroutine(result):
                self._run(result)

    def _run(self, result):
        """Finish a callback's coroutine here when it never waits; otherwise hand it to rclpy's tasks."""
        if not inspect.iscoroutine(result):
            return result
        try:
            result.send(None)
        except StopIteration as stop:
            return stop.value
        self.create_task(result)         # it awaits something (a future): rclpy's task machinery finishes it
        return None
