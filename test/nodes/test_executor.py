"""LeanExecutor (euc_ros.ros.executor) on a private rclpy context, against rclpy's own behaviour.

Covers: typed, raw and (message, MessageInfo) subscriptions receiving every message of a burst in
publish order, in few spins, and never more than ``batch`` messages per subscription in one spin;
timers firing repeatedly, cancelled timers (before spinning, from their own callback, by another
timer's callback in the same wake-up) not firing; guard conditions; a service and the node's
parameter services answering a client spun by a plain SingleThreadedExecutor in another thread;
entities changing between spins (a subscription created late, one destroyed between spins or by
another callback in the same wake-up, a node added late or destroyed while added, entities
destroyed with their own destroy(), a SubscriptionDrain that subscribes after the executor has
spun: the wait set is rebuilt when a waitable's entity counts grow); exceptions from subscription,
timer and resumed coroutine callbacks propagating out of spin_once (the executor still working
afterwards); rclpy's own path for a node with a client and for coroutine callbacks that await;
spin() ending on executor.shutdown() from another thread and on the context's shutdown, and
spin_once() after shutdown() returning quietly.

Every wait is a deadline loop of spin_once with a generous deadline (slow CI); nothing asserts on
timing (spin counts are bounded only where the executor's contract fixes them).
"""
from __future__ import annotations

import threading
import time

import pytest

pytest.importorskip("rclpy")

import rclpy  # noqa: E402
from rclpy.callback_groups import ReentrantCallbackGroup  # noqa: E402
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor  # noqa: E402
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from rclpy.serialization import deserialize_message  # noqa: E402
from rclpy.subscription import Subscription  # noqa: E402
from rclpy.task import Future  # noqa: E402
from std_msgs.msg import String  # noqa: E402
from std_srvs.srv import SetBool  # noqa: E402

from euc_ros.ros.drain import SubscriptionDrain  # noqa: E402
from euc_ros.ros.executor import LeanExecutor  # noqa: E402

pytestmark = pytest.mark.ros

N = 200                  # messages in a burst
DEADLINE_S = 10.0        # generous: CI machines are slow and may be busy


def qos(depth: int = N + 50) -> QoSProfile:
    """Reliable, keep-last deep enough that a whole burst (and the warm-up messages) fits the queue."""
    return QoSProfile(depth=depth, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE)


def spin_until(ex, cond, what: str = "the condition", timeout: float = DEADLINE_S) -> int:
    """spin_once(0.01) until ``cond()`` or the deadline; returns the number of spin_once calls made."""
    deadline = time.monotonic() + timeout
    spins = 0
    while time.monotonic() < deadline and not cond():
        ex.spin_once(timeout_sec=0.01)
        spins += 1
    assert cond(), f"timed out waiting for {what} ({spins} spins)"
    return spins


def spin_for(ex, spins: int) -> None:
    for _ in range(spins):
        ex.spin_once(timeout_sec=0.01)


def msg(text: str) -> String:
    return String(data=text)


class Env:
    """A LeanExecutor on the test's context, the nodes made for the test, background executors; closed at teardown."""

    def __init__(self, ctx) -> None:
        self.ctx = ctx
        self.ex = LeanExecutor(context=ctx)
        self.nodes: list = []
        self.drains: list[SubscriptionDrain] = []
        self.threads: list[tuple[SingleThreadedExecutor, threading.Thread]] = []

    def node(self, name: str, *, spin: bool = True):
        """A node on the context, added to the LeanExecutor unless ``spin=False``."""
        node = rclpy.create_node(name, context=self.ctx)
        self.nodes.append(node)
        if spin:
            self.ex.add_node(node)
        return node

    def background(self, node) -> SingleThreadedExecutor:
        """Spin ``node`` on a plain rclpy SingleThreadedExecutor in a daemon thread."""
        ex = SingleThreadedExecutor(context=self.ctx)
        ex.add_node(node)

        def run():
            try:
                ex.spin()
            except ExternalShutdownException:
                pass

        thread = threading.Thread(target=run, name=f"spin-{node.get_name()}", daemon=True)
        thread.start()
        self.threads.append((ex, thread))
        return ex

    def warm_up(self, pub, received, topic_msg=lambda: msg("warm")) -> None:
        """Publish until the subscriber side has matched and received one message (discovery is asynchronous)."""
        spin_until(self.ex, lambda: pub.get_subscription_count() > 0, "the publisher to match")

        def got_one():
            if not received():
                pub.publish(topic_msg())
                return False
            return True
        spin_until(self.ex, got_one, "a warm-up message")

    def close(self) -> None:
        for ex, thread in self.threads:
            ex.shutdown()
            thread.join(timeout=DEADLINE_S)
        self.ex.shutdown()
        for drain in self.drains:
            drain.destroy()
        for node in reversed(self.nodes):
            node.destroy_node()
        stuck = [t.name for _, t in self.threads if t.is_alive()]
        assert not stuck, f"background executors still spinning: {stuck}"


@pytest.fixture
def env(ros_context):
    e = Env(ros_context)
    try:
        yield e
    finally:
        e.close()


# -- 1. subscriptions -----------------------------------------------------------------------------------------------
def test_typed_raw_and_info_subscriptions_get_a_burst_in_order_in_few_spins(env):
    sub_node = env.node("lean_sub")
    pub_node = env.node("lean_pub", spin=False)
    typed, raw, infos = [], [], []
    s_typed = sub_node.create_subscription(String, "burst", lambda m: typed.append(m.data), qos())
    s_raw = sub_node.create_subscription(String, "burst", lambda b: raw.append(b), qos(), raw=True)

    def with_info(m, info):                     # two positional parameters: rclpy passes MessageInfo
        infos.append((m.data, info))
    s_info = sub_node.create_subscription(String, "burst", with_info, qos())
    assert s_typed._callback_type is Subscription.CallbackType.MessageOnly
    assert s_raw._callback_type is Subscription.CallbackType.MessageOnly
    assert s_info._callback_type is Subscription.CallbackType.WithMessageInfo
    pub = pub_node.create_publisher(String, "burst", qos())
    spin_until(env.ex, lambda: pub.get_subscription_count() >= 3, "the publisher to match 3 subscriptions")
    env.warm_up(pub, lambda: typed and raw and infos)

    def burst():                                # what each subscription got, warm-up messages left out
        return ([t for t in typed if t != "warm"],
                [t for t in (deserialize_message(b, String).data for b in raw) if t != "warm"],
                [t for t, _ in infos if t != "warm"])

    want = [f"m{i}" for i in range(N)]
    for text in want:
        pub.publish(msg(text))
    spins = spin_until(env.ex, lambda: all(len(got) >= N for got in burst()), f"{N} messages on each subscription")
    spin_for(env.ex, 3)                         # nothing more arrives (no duplicates)

    assert burst() == (want, want, want)
    assert all(isinstance(b, bytes) for b in raw)
    for _, info in infos:
        assert isinstance(info["source_timestamp"], int) and info["source_timestamp"] > 0
        assert "received_timestamp" in info
    # each spin takes up to `batch` (64) messages per subscription: a burst needs a handful of spins
    print(f"{N} messages x 3 subscriptions in {spins} spins")
    assert spins < N / 4


def test_a_spin_takes_at_most_batch_messages_per_subscription(ros_context):
    ex = LeanExecutor(context=ros_context, batch=8)
    sub_node = rclpy.create_node("batch_sub", context=ros_context)
    pub_node = rclpy.create_node("batch_pub", context=ros_context)
    try:
        ex.add_node(sub_node)
        got: list[str] = []
        sub_node.create_subscription(String, "batched", lambda m: got.append(m.data), qos())
        pub = pub_node.create_publisher(String, "batched", qos())
        spin_until(ex, lambda: pub.get_subscription_count() > 0, "the publisher to match")

        def warm():
            if not got:
                pub.publish(msg("warm"))
            return bool(got)
        spin_until(ex, warm, "a warm-up message")
        start = len(got)
        for i in range(N):
            pub.publish(msg(f"m{i}"))
        per_spin = []
        deadline = time.monotonic() + DEADLINE_S
        while time.monotonic() < deadline and len(got) < start + N:
            before = len(got)
            ex.spin_once(timeout_sec=0.01)
            per_spin.append(len(got) - before)
        assert [t for t in got if t != "warm"] == [f"m{i}" for i in range(N)]
        assert max(per_spin) <= 8                       # never more than `batch` in one wake-up ...
        assert sum(1 for k in per_spin if k) >= N // 8   # ... so a burst of N needs at least N/batch spins
        assert max(per_spin) > 1                         # and messages queued together are taken together
    finally:
        ex.shutdown()
        sub_node.destroy_node()
        pub_node.destroy_node()


# -- 2. timers and guard conditions ---------------------------------------------------------------------------------
def test_timers_fire_repeatedly_and_cancelled_timers_do_not(env):
    node = env.node("lean_timers")
    counts = {"a": 0, "b": 0, "never": 0}

    def tick_a():
        counts["a"] += 1

    def tick_b():
        counts["b"] += 1
        if counts["b"] == 3:
            timer_b.cancel()                    # cancelled from its own callback, mid-stream

    node.create_timer(0.01, tick_a)
    timer_b = node.create_timer(0.01, tick_b)
    never = node.create_timer(0.01, lambda: counts.__setitem__("never", counts["never"] + 1))
    never.cancel()                              # cancelled before the executor ever spun
    spin_until(env.ex, lambda: counts["b"] >= 3, "timer b to fire 3 times")
    a_at_cancel = counts["a"]
    spin_until(env.ex, lambda: counts["a"] >= a_at_cancel + 10, "timer a to keep firing")
    assert timer_b.is_canceled() and never.is_canceled()
    assert counts["b"] == 3 and counts["never"] == 0

    # a cancelled timer reset fires again
    timer_b.reset()
    spin_until(env.ex, lambda: counts["b"] >= 5, "the reset timer to fire again")


def test_a_timer_cancelled_by_another_callback_in_the_same_wake_does_not_fire(env):
    node = env.node("lean_cancel_each_other")
    fired = []

    def make(name):
        def tick():
            fired.append(name)
            for other in timers.values():               # whichever runs first cancels both
                other.cancel()
        return tick
    timers = {}
    for name in ("x", "y"):
        timers[name] = node.create_timer(0.05, make(name))
    time.sleep(0.2)                                     # both are due before the first spin: one wake-up
    spin_until(env.ex, lambda: fired, "a timer to fire")
    spin_for(env.ex, 10)
    assert len(fired) == 1, fired                       # the other one was cancelled before its turn


def test_guard_condition_callback_runs_once_per_trigger(env):
    node = env.node("lean_guard")
    calls = []
    gc = node.create_guard_condition(lambda: calls.append(1))
    spin_for(env.ex, 3)
    assert calls == []
    gc.trigger()
    spin_until(env.ex, lambda: len(calls) == 1, "the guard condition callback")
    spin_for(env.ex, 5)
    assert len(calls) == 1
    gc.trigger()
    spin_until(env.ex, lambda: len(calls) == 2, "the guard condition callback again")


# -- 3. services ----------------------------------------------------------------------------------------------------
def test_service_and_parameter_services_answer_a_client_in_another_executor(env):
    from rcl_interfaces.srv import GetParameters

    server = env.node("lean_server")
    server.declare_parameter("answer", 42)
    requests = []

    def handle(request, response):
        requests.append(request.data)
        response.success = not request.data
        response.message = f"got {request.data}"
        return response
    server.create_service(SetBool, "flip", handle)

    client_node = env.node("plain_client", spin=False)
    flip = client_node.create_client(SetBool, "flip")
    params = client_node.create_client(GetParameters, "/lean_server/get_parameters")
    env.background(client_node)
    spin_until(env.ex, lambda: flip.service_is_ready() and params.service_is_ready(), "the services to be discovered")

    futures = [flip.call_async(SetBool.Request(data=v)) for v in (True, False, True)]
    spin_until(env.ex, lambda: all(f.done() for f in futures), "three responses")
    answers = [(f.result().success, f.result().message) for f in futures]
    assert answers == [(False, "got True"), (True, "got False"), (False, "got True")]
    assert requests == [True, False, True]

    fut = params.call_async(GetParameters.Request(names=["answer", "use_sim_time"]))
    spin_until(env.ex, fut.done, "the get_parameters response")
    values = fut.result().values
    assert values[0].integer_value == 42 and values[1].bool_value is False


# -- 4. entities changing between spins -----------------------------------------------------------------------------
def test_subscription_created_late_and_destroyed_between_spins(env):
    node = env.node("lean_changing")
    pub = env.node("changing_pub", spin=False).create_publisher(String, "changing", qos())
    keeper = []
    node.create_subscription(String, "changing", lambda m: keeper.append(m.data), qos())
    env.warm_up(pub, lambda: keeper)
    spin_for(env.ex, 5)

    late = []
    late_sub = node.create_subscription(String, "changing", lambda m: late.append(m.data), qos())

    def late_got_one():
        pub.publish(msg("for late"))
        return bool(late)
    spin_until(env.ex, late_got_one, "the late subscription to receive")

    node.destroy_subscription(late_sub)
    n_late, n_keep = len(late), len(keeper)

    def keeper_got_more():
        pub.publish(msg("after destroy"))
        return len(keeper) >= n_keep + 20
    spin_until(env.ex, keeper_got_more, "messages to keep flowing")   # nothing raises ...
    assert len(late) == n_late                                          # ... and the destroyed one got none

    # a node added after the executor has spun is served too
    other = []
    env.node("lean_late_node").create_subscription(String, "changing", lambda m: other.append(m.data), qos())

    def other_got_one():
        pub.publish(msg("for the late node"))
        return bool(other)
    spin_until(env.ex, other_got_one, "the late node's subscription to receive")


def test_a_node_destroyed_while_added_leaves_the_others_served(env):
    keep = env.node("lean_keep")
    gone = env.node("lean_gone")
    ticks = []
    keep.create_timer(0.01, lambda: ticks.append(1))
    gone.create_timer(0.01, lambda: None)
    gone.create_subscription(String, "gone", lambda m: None, qos())
    spin_until(env.ex, lambda: len(ticks) >= 3, "the timer to fire")
    gone.destroy_node()                                  # without executor.remove_node
    env.nodes.remove(gone)
    n = len(ticks)
    spin_until(env.ex, lambda: len(ticks) >= n + 5, "the other node's timer to keep firing")


def test_entities_destroyed_with_their_own_destroy_are_left_out(env):
    """Timer/Subscription.destroy() (public rclpy API) leaves the entity in its node's lists: it is skipped,
    the others are served, and the executor still sleeps in its wait (no busy loop on the dead timer)."""
    node = env.node("lean_direct_destroy")
    pub = env.node("direct_pub", spin=False).create_publisher(String, "direct", qos())
    ticks, got, dead = [], [], []
    node.create_timer(0.05, lambda: ticks.append(1))
    victim_timer = node.create_timer(0.01, lambda: dead.append("timer"))
    victim_sub = node.create_subscription(String, "direct", lambda m: dead.append(m.data), qos())
    node.create_subscription(String, "direct", lambda m: got.append(m.data), qos())
    env.warm_up(pub, lambda: got and dead)
    spin_until(env.ex, lambda: len(ticks) >= 2, "the timer to fire")
    victim_timer.destroy()                               # not node.destroy_timer(...)
    victim_sub.destroy()                                 # not node.destroy_subscription(...)
    dead.clear()
    n_ticks = len(ticks)
    # with nothing else ready, spin_once(1 s) returns once per 50 ms tick: a few spins for 3 ticks, not thousands
    deadline, spins = time.monotonic() + DEADLINE_S, 0
    while time.monotonic() < deadline and len(ticks) < n_ticks + 3:
        env.ex.spin_once(timeout_sec=1.0)
        spins += 1
    assert len(ticks) >= n_ticks + 3
    assert spins < 30, f"{spins} spins for 3 ticks: the executor does not wait"
    pub.publish(msg("after"))
    spin_until(env.ex, lambda: "after" in got, "a message on the live subscription")
    assert dead == []


def test_subscription_destroyed_by_another_callback_in_the_same_wake(env):
    node = env.node("lean_destroyer")
    pub = env.node("destroyer_pub", spin=False).create_publisher(String, "victim", qos())
    victim_got, killer_got = [], []
    subs = {}

    def killer(m):
        killer_got.append(m.data)
        if m.data == "kill" and "victim" in subs:
            node.destroy_subscription(subs.pop("victim"))

    node.create_subscription(String, "victim", killer, qos())
    subs["victim"] = node.create_subscription(String, "victim", lambda m: victim_got.append(m.data), qos())
    env.warm_up(pub, lambda: killer_got and victim_got)
    # both subscriptions hold these messages when the killer runs: whichever the executor takes first,
    # the victim's handle is destroyed mid-wake and must not take anything after the "kill"
    for text in ("kill", "x1", "x2", "x3"):
        pub.publish(msg(text))
    spin_until(env.ex, lambda: killer_got[-1:] == ["x3"], "the killer to take the burst")
    spin_for(env.ex, 5)
    assert "victim" not in subs
    assert all(t in ("warm", "kill", "x1", "x2", "x3") for t in victim_got)
    n_victim = len(victim_got)

    def killer_more():
        pub.publish(msg("later"))
        return killer_got.count("later") >= 10
    spin_until(env.ex, killer_more, "messages after the destroy")
    assert len(victim_got) == n_victim and "later" not in victim_got


def test_subscription_drain_subscribing_after_the_executor_spun_receives(env):
    """Regression: the kept wait set was sized before subscribe(); rcl raised 'subscriptions set is full'."""
    node = env.node("lean_drain")
    taken: dict[str, list[str]] = {}

    def sink(batch):
        for topic, type_name, datas in batch:
            assert type_name == "std_msgs/msg/String"
            taken.setdefault(topic, []).extend(deserialize_message(d, String).data for d in datas)

    drain = SubscriptionDrain(node, sink, poll_s=0.001, max_poll_s=0.01)
    env.drains.append(drain)
    node.add_waitable(drain)
    node.create_subscription(String, "drain_other", lambda m: None, qos())   # the wait set is not empty
    pub_node = env.node("drain_pub", spin=False)
    pub_a = pub_node.create_publisher(String, "drain_a", qos())
    pub_b = pub_node.create_publisher(String, "drain_b", qos())
    spin_for(env.ex, 5)                             # the wait set exists, sized for a drain of 0 topics

    drain.subscribe("/drain_a", "std_msgs/msg/String", String, qos())

    def a_received():
        pub_a.publish(msg("a"))
        return bool(taken.get("/drain_a"))
    spin_until(env.ex, a_received, "the drain's first topic")

    drain.subscribe("/drain_b", "std_msgs/msg/String", String, qos())   # grows again

    def b_received():
        pub_b.publish(msg("b"))
        pub_a.publish(msg("a"))
        return bool(taken.get("/drain_b")) and len(taken["/drain_a"]) >= 5
    spin_until(env.ex, b_received, "the drain's second topic")
    assert set(taken["/drain_a"]) == {"a"} and set(taken["/drain_b"]) == {"b"}

    # a burst in order through the drain
    start = len(taken["/drain_b"])
    for i in range(N):
        pub_b.publish(msg(f"b{i}"))
    spin_until(env.ex, lambda: len(taken["/drain_b"]) >= start + N, f"{N} messages through the drain")
    assert [t for t in taken["/drain_b"][start:] if t != "b"] == [f"b{i}" for i in range(N)]


# -- 5. exceptions --------------------------------------------------------------------------------------------------
def test_exceptions_from_callbacks_propagate_out_of_spin_once(env):
    node = env.node("lean_raiser")
    pub = env.node("raiser_pub", spin=False).create_publisher(String, "raise", qos())
    got = []

    def callback(m):
        got.append(m.data)
        if m.data == "boom":
            raise RuntimeError("boom from a subscription")

    node.create_subscription(String, "raise", callback, qos())
    env.warm_up(pub, lambda: got)
    pub.publish(msg("boom"))
    with pytest.raises(RuntimeError, match="boom from a subscription"):
        spin_until(env.ex, lambda: False, "the callback to raise")
    assert got[-1] == "boom"

    # the executor goes on working after the exception
    pub.publish(msg("after"))
    spin_until(env.ex, lambda: got[-1] == "after", "a message after the exception")

    # from a timer callback too
    def tick():
        timer.cancel()
        raise ValueError("boom from a timer")
    timer = node.create_timer(0.01, tick)
    with pytest.raises(ValueError, match="boom from a timer"):
        spin_until(env.ex, lambda: False, "the timer to raise")


# -- 6. rclpy's own path: clients and coroutines --------------------------------------------------------------------
def test_node_with_a_client_is_served_and_coroutine_callbacks_complete(env):
    server = env.node("fallback_server", spin=False)
    server.create_service(SetBool, "fallback_flip",
                          lambda req, resp: SetBool.Response(success=not req.data, message="served"))
    env.background(server)

    node = env.node("lean_with_client")
    # a client: LeanExecutor uses rclpy's path. Its own callback group: the awaiting subscription callback
    # holds the default (mutually exclusive) group until the response is in, as with rclpy's executor
    client = node.create_client(SetBool, "fallback_flip", callback_group=ReentrantCallbackGroup())
    plain, answers = [], []
    node.create_subscription(String, "fallback_plain", lambda m: plain.append(m.data), qos())

    async def ask(m):                                           # awaits a service response
        response = await client.call_async(SetBool.Request(data=m.data == "yes"))
        answers.append((m.data, response.success, response.message))
    node.create_subscription(String, "fallback_ask", ask, qos())

    pub_node = env.node("fallback_pub", spin=False)
    pub_plain = pub_node.create_publisher(String, "fallback_plain", qos())
    pub_ask = pub_node.create_publisher(String, "fallback_ask", qos())
    spin_until(env.ex, client.service_is_ready, "the service to be discovered")
    env.warm_up(pub_plain, lambda: plain)
    # a call made outside any callback: only the client's own response wakes the executor
    fut = client.call_async(SetBool.Request(data=True))
    spin_until(env.ex, fut.done, "a response taken by the client node's executor")
    assert (fut.result().success, fut.result().message) == (False, "served")
    env.warm_up(pub_ask, lambda: answers)

    start = len(plain)
    for i in range(50):
        pub_plain.publish(msg(f"p{i}"))
    spin_until(env.ex, lambda: len(plain) >= start + 50, "50 messages on the client node")
    assert [t for t in plain if t != "warm"] == [f"p{i}" for i in range(50)]

    pub_ask.publish(msg("yes"))
    pub_ask.publish(msg("no"))
    spin_until(env.ex, lambda: ("no", True, "served") in answers, "both coroutine callbacks to finish")
    assert [a for a in answers if a[0] != "warm"] == [("yes", False, "served"), ("no", True, "served")]


def test_coroutine_callbacks_on_a_lean_node(env):
    node = env.node("lean_coro")
    pub_node = env.node("coro_pub", spin=False)
    pub_wait = pub_node.create_publisher(String, "coro_wait", qos())
    pub_other = pub_node.create_publisher(String, "coro_other", qos())
    gate = Future()
    events, other, quick, warm = [], [], [], []

    async def waits(m):
        if m.data == "warm":
            warm.append(m.data)
            return
        events.append(("start", m.data))
        value = await gate                                  # pending: a task, rclpy's path meanwhile
        events.append(("done", m.data, value))
        if m.data == "raise":
            raise KeyError("boom from a coroutine")

    async def never_awaits(m):                              # finishes inside the lean path
        quick.append(m.data)

    node.create_subscription(String, "coro_wait", waits, qos())
    node.create_subscription(String, "coro_other", lambda m: other.append(m.data), qos())
    node.create_subscription(String, "coro_other", never_awaits, qos())
    env.warm_up(pub_wait, lambda: warm)
    env.warm_up(pub_other, lambda: other and quick)

    pub_wait.publish(msg("first"))
    spin_until(env.ex, lambda: ("start", "first") in events, "the coroutine to start")
    # while it waits, other subscriptions are still served
    for i in range(20):
        pub_other.publish(msg(f"o{i}"))
    spin_until(env.ex, lambda: "o19" in other and "o19" in quick, "messages while a coroutine waits")
    assert [t for t in other if t != "warm"] == [f"o{i}" for i in range(20)] == [t for t in quick if t != "warm"]
    assert ("done", "first", 7) not in events
    gate.set_result(7)
    spin_until(env.ex, lambda: ("done", "first", 7) in events, "the coroutine to finish")

    # an exception raised after the await propagates out of spin_once as well
    pub_wait.publish(msg("raise"))
    with pytest.raises(KeyError, match="boom from a coroutine"):
        spin_until(env.ex, lambda: False, "the resumed coroutine to raise")
    assert ("done", "raise", 7) in events


# -- 7. shutdown ----------------------------------------------------------------------------------------------------
def _spin_in_thread(ex):
    outcome = {}

    def run():
        try:
            ex.spin()
            outcome["returned"] = True
        except BaseException as exc:  # noqa: BLE001 - reported by the test
            outcome["raised"] = exc

    thread = threading.Thread(target=run, name="lean-spin", daemon=True)
    thread.start()
    return thread, outcome


def test_executor_shutdown_from_another_thread_ends_spin(env):
    node = env.node("lean_shutdown")
    woke = threading.Event()
    gc = node.create_guard_condition(woke.set)
    thread, outcome = _spin_in_thread(env.ex)
    gc.trigger()                                            # spin() is running (and back to waiting after this)
    assert woke.wait(DEADLINE_S), "spin() did not run the guard condition callback"
    time.sleep(0.05)
    assert env.ex.shutdown(timeout_sec=DEADLINE_S)
    thread.join(timeout=DEADLINE_S)
    ended = not thread.is_alive()
    if not ended:                                   # don't leave a thread inside rcl_wait: wake it, then fail
        gc.trigger()
        thread.join(timeout=DEADLINE_S)
    assert ended, "spin() did not return after executor.shutdown()"
    assert outcome == {"returned": True}


def test_context_shutdown_ends_spin(env, ros_context):
    node = env.node("lean_ctx_shutdown")
    woke = threading.Event()
    gc = node.create_guard_condition(woke.set)
    thread, outcome = _spin_in_thread(env.ex)
    gc.trigger()
    assert woke.wait(DEADLINE_S), "spin() did not run the guard condition callback"
    time.sleep(0.05)
    ros_context.try_shutdown()
    thread.join(timeout=DEADLINE_S)
    ended = not thread.is_alive()
    if not ended:
        gc.trigger()
        thread.join(timeout=DEADLINE_S)
    assert ended, "spin() did not return after the context's shutdown"
    # rclpy's SingleThreadedExecutor raises ExternalShutdownException here; returning is fine too
    assert outcome.get("returned") or isinstance(outcome.get("raised"), ExternalShutdownException), outcome


def test_spin_once_after_shutdown_returns_quietly(env):
    """As rclpy's SingleThreadedExecutor (an earlier LeanExecutor read None.handle of the destroyed guards)."""
    env.node("lean_after_shutdown")
    spin_for(env.ex, 2)
    assert env.ex.shutdown(timeout_sec=DEADLINE_S)
    env.ex.spin_once(timeout_sec=0.01)
