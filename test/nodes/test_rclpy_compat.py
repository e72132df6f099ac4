"""rclpy's private API in one module (euc_ros.ros.rclpy_compat): the guard, the public fallback, nowhere else.

* The guard refuses the private API for ``EUC_ROS_PUBLIC_EXECUTOR=1``, an rclpy outside 7.x, unknown
  versions and missing private names, and accepts the installed Jazzy rclpy.
* Forced public (by the environment, as a node process would be, and by the parameter), a LeanExecutor is
  rclpy's SingleThreadedExecutor and a SubscriptionDrain makes public subscriptions: typed, raw and
  drained messages of a burst all arrive, in order, and a timer fires.
* No module of the package but rclpy_compat names a private part of rclpy.
"""
from __future__ import annotations

import re
import time
from pathlib import Path

import pytest

pytest.importorskip("rclpy")

import rclpy  # noqa: E402
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from rclpy.serialization import deserialize_message  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from euc_ros.ros import rclpy_compat as compat  # noqa: E402
from euc_ros.ros.drain import SubscriptionDrain  # noqa: E402
from euc_ros.ros.executor import LeanExecutor  # noqa: E402

pytestmark = pytest.mark.ros

PACKAGE = Path(__file__).resolve().parents[2] / "euc_ros"
N = 50
DEADLINE_S = 10.0

#: Private parts of rclpy (names, the C extension's handle methods) that only rclpy_compat may use.
PRIVATE = ("_rclpy", "implementation_singleton", "_sigint_gc", "_tasks", "_is_shutdown", "rclpy._",
           "_wake_executor", "_callback_type", "_set_executor", "_futures", "._guard", "take_message(",
           "call_timer(", "is_timer_ready(", "service_take_request(", "WaitSet", "destroy_when_not_in_use",
           "get_c_qos_profile")


# -- the guard ---------------------------------------------------------------------------------------------------------
@pytest.fixture
def fresh_guard():
    compat._installed_problem.cache_clear()
    yield
    compat._installed_problem.cache_clear()


def test_the_installed_jazzy_rclpy_passes_the_guard(fresh_guard):
    assert compat.rclpy_version()[0] == 7
    assert compat.private_api_problem(environ={}) is None


@pytest.mark.parametrize("value, public", [("1", True), ("yes", True), ("0", False), ("", False)])
def test_the_environment_forces_the_public_api(fresh_guard, value, public):
    problem = compat.private_api_problem(environ={compat.PUBLIC_EXECUTOR_ENV: value})
    assert (problem is not None) == public
    if public:
        assert compat.PUBLIC_EXECUTOR_ENV in problem


@pytest.mark.parametrize("version, ok", [((7, 0, 0), True), ((7, 9, 3), True), ((6, 2, 0), False),
                                         ((8, 0, 0), False), ((10, 1, 0), False), (None, False)])
def test_versions_outside_7x_fall_back(fresh_guard, monkeypatch, version, ok):
    monkeypatch.setattr(compat, "rclpy_version", lambda: version)
    problem = compat.private_api_problem(environ={})
    assert (problem is None) == ok, problem
    if version is not None and not ok:
        assert "outside" in problem and ".".join(map(str, version)) in problem


def test_missing_private_names_fall_back(fresh_guard, monkeypatch):
    monkeypatch.setattr(compat, "_extension", lambda: type("Ext", (), {"Subscription": object})())
    problem = compat.private_api_problem(environ={})
    assert problem is not None and "WaitSet" in problem


def test_an_executor_without_the_private_attributes_is_public(ros_context, monkeypatch):
    monkeypatch.setattr(compat, "_EXECUTOR_NAMES", ("_guard", "_no_such_attribute"))
    ex = LeanExecutor(context=ros_context)
    try:
        assert ex.public and "_no_such_attribute" in ex.public_reason
    finally:
        ex.shutdown()


# -- the public fallback runs a node -----------------------------------------------------------------------------------
def _spin_until(ex, cond, what):
    deadline = time.monotonic() + DEADLINE_S
    while time.monotonic() < deadline and not cond():
        ex.spin_once(timeout_sec=0.01)
    assert cond(), f"timed out waiting for {what}"


@pytest.mark.parametrize("how", ["environment", "parameter"])
def test_the_public_fallback_delivers_every_message(ros_context, monkeypatch, how):
    if how == "environment":
        monkeypatch.setenv(compat.PUBLIC_EXECUTOR_ENV, "1")
        ex, make_drain = LeanExecutor(context=ros_context), lambda n, s: SubscriptionDrain(n, s)
    else:
        monkeypatch.delenv(compat.PUBLIC_EXECUTOR_ENV, raising=False)
        ex = LeanExecutor(context=ros_context, public=True)
        make_drain = lambda n, s: SubscriptionDrain(n, s, public=True)   # noqa: E731
    qos = QoSProfile(depth=N + 50, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE)
    node = rclpy.create_node("compat_fallback", context=ros_context)
    typed, raw, drained, ticks = [], [], [], []
    drain = make_drain(node, lambda batch: drained.extend(
        deserialize_message(d, String).data for _, _, datas in batch for d in datas))
    try:
        assert ex.public and drain.public
        if how == "environment":
            assert compat.PUBLIC_EXECUTOR_ENV in ex.public_reason
        pub = node.create_publisher(String, "compat/chatter", qos)
        node.create_subscription(String, "compat/chatter", lambda m: typed.append(m.data), qos)
        node.create_subscription(String, "compat/chatter", lambda b: raw.append(deserialize_message(b, String).data),
                                 qos, raw=True)
        drain.subscribe("/compat/chatter", "std_msgs/msg/String", String, qos)
        node.add_waitable(drain)
        node.create_timer(0.01, lambda: ticks.append(1))
        ex.add_node(node)
        _spin_until(ex, lambda: pub.get_subscription_count() >= 3, "three subscriptions to match")
        _spin_until(ex, lambda: len(ticks) >= 3, "the timer")
        for i in range(N):
            pub.publish(String(data=f"m{i}"))
        want = [f"m{i}" for i in range(N)]
        _spin_until(ex, lambda: len(typed) >= N and len(raw) >= N and len(drained) >= N, "every message")
        assert typed == want and raw == want and drained == want
        assert drain.take_all() == []           # public subscriptions leave nothing to take
    finally:
        ex.shutdown()
        drain.destroy()
        node.destroy_node()


# -- nowhere else ------------------------------------------------------------------------------------------------------
def _code_lines(path: Path):
    """Lines of a module outside strings and comments (docstrings may name what the code avoids)."""
    import io
    import tokenize

    tokens = tokenize.generate_tokens(io.StringIO(path.read_text(encoding="utf-8")).readline)
    lines: dict[int, str] = {}
    for tok in tokens:
        if tok.type in (tokenize.STRING, tokenize.COMMENT):
            continue
        lines[tok.start[0]] = lines.get(tok.start[0], "") + " " + tok.string
    return lines


def _normalize(line: str) -> str:
    """Tokens as written, without the spaces around ``.`` and before ``(`` that tokenizing puts there."""
    return re.sub(r"\s*([.(])\s*", r"\1", line).strip()


def _pattern(name: str) -> re.Pattern:
    """``name`` as a whole identifier (``_tasks`` but not ``has_pending_tasks``)."""
    end = r"(?![A-Za-z0-9_])" if name[-1].isalnum() else ""
    start = r"(?<![A-Za-z0-9_])" if name[0].isalnum() or name[0] == "_" else ""
    return re.compile(start + re.escape(name) + end)


def test_no_module_but_rclpy_compat_uses_private_rclpy():
    patterns = [(name, _pattern(name)) for name in PRIVATE]
    offenders = []
    for path in sorted(PACKAGE.rglob("*.py")):
        if path.name == "rclpy_compat.py" and path.parent.name == "ros":
            continue
        for number, line in _code_lines(path).items():
            compact = _normalize(line)
            for name, pattern in patterns:
                if pattern.search(compact):
                    offenders.append(f"{path.relative_to(PACKAGE.parent)}:{number}: {name}")
    assert not offenders, "\n".join(offenders)


def test_the_scan_finds_what_it_looks_for(tmp_path):
    probe = tmp_path / "probe.py"
    probe.write_text('"""_rclpy in a docstring is fine."""\nfrom rclpy.impl.implementation_singleton import '
                     'rclpy_implementation as _rclpy  # x\nex._sigint_gc = None\n', encoding="utf-8")
    joined = _normalize(" ".join(_code_lines(probe).values()))
    assert _pattern("implementation_singleton").search(joined) and _pattern("_sigint_gc").search(joined)
    assert _pattern("_rclpy").search(joined) and '"""' not in joined
    assert not _pattern("_tasks").search("has_pending_tasks(ex)") and not _pattern("WaitSet").search("KeptWaitSet")
    assert _pattern("rclpy._").search("rclpy._rclpy_pybind11") and _pattern("take_message(").search("h.take_message(")
    assert _pattern("._guard").search("(self._guard, x)") and not _pattern("._guard").search("self._guards")
