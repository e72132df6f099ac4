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

That is rclpy's implementation level, reached only through :mod:`euc_ros.ros.rclpy_compat`; where
its guard refuses (another rclpy release, a private name missing, ``EUC_ROS_PUBLIC_EXECUTOR=1``),
this class is rclpy's public :class:`~rclpy.executors.SingleThreadedExecutor` (:attr:`LeanExecutor.public`).

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

from euc_ros.ros import rclpy_compat as compat

#: Longest wait, after a signal, for rclpy's signal thread to shut the context down [s].
SIGNAL_THREAD_S = 2.0
#: Longest single wait of the public executor [s]: it may miss the moment a signal shuts the context down
#: (it waits again after its signal guard condition woke it), so it looks at the context this often.
PUBLIC_WAIT_S = 0.1


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
    public : bool, optional
        True: run as rclpy's public SingleThreadedExecutor. Otherwise it does when
        :func:`~euc_ros.ros.rclpy_compat.private_api_problem` finds a reason to.

    Attributes
    ----------
    public : bool
        Whether this executor is rclpy's public one.
    public_reason : str or None
        Why (None when lean, or when asked for with ``public=True``).
    """

    #: Longest time between two listings of the nodes' entities [s] (they are listed again at once
    #: when rclpy wakes the executor, which it does on every create_* and destroy_*).
    RELIST_S = 0.5

    def __init__(self, *, context=None, batch: int = 64, public: bool | None = None) -> None:
        super().__init__(context=context)
        self.batch = int(batch)
        self.public_reason = None if public else (compat.private_api_problem() or compat.executor_problem(self))
        self.public = bool(public) or self.public_reason is not None
        self._ents: compat.KeptWaitSet | None = None
        self._dirty = True
        self._listed_at = 0.0
        self._closed = False

    def wake(self) -> None:
        """Called by rclpy when a node adds or destroys an entity: list them again next spin."""
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
        guards += compat.executor_guards(self)               # none once shut down
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
            self._ents = compat.KeptWaitSet(*got, self.context)
        return self._ents

    def _release(self) -> None:
        self._ents = None

    def add_node(self, node) -> bool:
        """Add ``node``; its entities are listed again on the next spin.

        Parameters
        ----------
        node : rclpy.node.Node

        Returns
        -------
        bool
            True when the node was added (rclpy's ``add_node``).
        """
        self._dirty = True
        return super().add_node(node)

    def remove_node(self, node) -> None:
        """Remove ``node`` and release the held entities.

        Parameters
        ----------
        node : rclpy.node.Node
        """
        self._release()
        super().remove_node(node)

    def shutdown(self, timeout_sec: float | None = None) -> bool:
        """Stop spinning, release the held entities and shut the executor down.

        Parameters
        ----------
        timeout_sec : float or None
            Seconds to wait for callbacks in progress (None: as long as they take).

        Returns
        -------
        bool
            True when the callbacks finished in time (rclpy's ``shutdown``).
        """
        self._closed = True
        self._release()
        return super().shutdown(timeout_sec)

    # -- spinning --------------------------------------------------------------------------------------------------
    def spin(self) -> None:
        """Run callbacks until the context shuts down or :meth:`shutdown` is called."""
        timeout = PUBLIC_WAIT_S if self.public else None
        while self.context.ok() and not self._closed:
            self.spin_once(timeout)

    def spin_once(self, timeout_sec: float | None = None) -> None:
        """Wait up to ``timeout_sec`` (forever if None) and run everything that became ready."""
        if self._closed:                                     # as rclpy's: nothing to do after shutdown()
            return
        if self.public or compat.has_pending_tasks(self):
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
            if self._closed:                                 # shut down from another thread while listing
                return
            ents.wait(self.context, timeout_sec)
            if self._closed:
                return
            if not self.context.ok():
                raise ExternalShutdownException()
            ready_waitables, timers, subs, services, guards = ents.ready()

        if any(compat.is_signal_guard(self, g) for g in guards):
            # a SIGINT/SIGTERM: rclpy's signal thread triggers this, then shuts the context down. Waiting
            # again meanwhile would wait forever (nothing wakes a wait set when the context shuts down):
            # wait for the shutdown instead (seen: a steering_controller left spinning after SIGTERM)
            if wait_for_context_shutdown(self.context):
                raise ExternalShutdownException()
        for waitable in ready_waitables:
            compat.adopt_futures(waitable, self)             # as rclpy does (e.g. an ActionClient's)
            self._run(waitable.execute(waitable.take_data()))
        for tmr in timers:
            if compat.fire_timer(tmr):
                self._run(tmr.callback())
        for sub in subs:
            self._take_all(sub)
        for gc in guards:
            if gc.callback is not None:
                self._run(gc.callback())
        for srv in services:
            got = compat.take_request(srv)
            if got is None:
                continue
            request, header = got
            response = srv.callback(request, srv.srv_type.Response())
            if inspect.iscoroutine(response):
                response = self._run(response)
            srv.send_response(response, header)

    def _take_all(self, sub) -> None:
        with_info = compat.takes_message_info(sub)
        callback, take = sub.callback, compat.take
        for _ in range(self.batch):
            try:
                got = take(sub)
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
