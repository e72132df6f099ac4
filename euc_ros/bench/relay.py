"""Floor processes of the live benchmarks: bare rclpy nodes that do nothing but move messages.

``python -m euc_ros.bench.relay MODE [options]`` with MODE

``source``
    publishes ``mocap/frame`` (MocapFrame of ``--bodies`` bodies, the pipeline's body names) at
    ``--rate`` Hz for ``--frames`` frames with the scheduling of ``mocap_ingest``'s CSV replay: a
    timer of ``min(0.5 / rate, 5 ms)`` publishes every frame that is due, stamped with its scheduled
    time (``start + k / rate``). It waits for ``--wait-subscribers`` subscriptions, then
    ``--start-delay`` s; after the last frame it lingers ``--linger`` s and exits 0.
``hop --kind state|torque``
    relays ``mocap/frame`` -> ``rider/state`` (RiderState) or ``rider/state`` -> ``euc/torque``
    (TorqueEstimate): on every input (taken raw; the stamp read from its CDR header) it publishes a
    prebuilt message of the output type with the input's stamp (``filter_lag`` 0).
``blast``
    publishes the recorded pipeline's message mix per frame (1 MocapFrame, one PoseStamped per body,
    1 TFMessage of every body, 1 RiderState, 1 TorqueEstimate) at ``--frame-rate`` frames/s for
    ``--duration`` s, once every topic has a subscription; prints one JSON line ``{"sent": {topic:
    n}, "messages": N, "publish_s": s, "achieved_msgs_per_s": r, "wall_start": t, "wall_end": t}``.
    The messages are serialized once and published as CDR bytes with each frame's stamp patched
    in. ``--part K/N`` publishes only topics K, K+N, ... of the mix, so N processes share it;
    ``--qos best_effort`` publishes best effort (as a mocap driver does) instead of the pipeline's reliable QoS.
``lockstep-sim`` / ``lockstep-ctrl``
    a bare lockstep ping-pong with the unicycle's message types: the sim publishes UnicycleState
    ``k`` and waits for the SteeringCommand of step ``k`` (resending after 0.5 s), ``--steps`` times;
    the controller answers each state. The sim prints ``{"steps": n, "stepping_s": s}``.

All use the pipeline's QoS profiles (:mod:`euc_ros.ros.interfaces`). Message content is fixed;
only stamps, steps and counters change, so what is measured is the middleware and rclpy alone.
"""
from __future__ import annotations

import argparse
import json
import signal
import struct
import sys
import time

from euc_ros.sched import realtime_from_env

#: Rigid bodies of the benchmark frames: the EUC and the 13 rider segments (14 bodies).
BODY_NAMES = ("E", "H", "CHR", "CHL", "UAR", "UAL", "LAR", "LAL", "HR", "HL", "TR", "TL", "LR", "LL")


def mocap_frame(n_bodies: int):
    """A MocapFrame of ``n_bodies`` tracked bodies (names as the pipeline's), stamp 0."""
    from euc_msgs.msg import MocapFrame
    from geometry_msgs.msg import Pose

    names = list(BODY_NAMES[:n_bodies]) + [f"B{i}" for i in range(len(BODY_NAMES), n_bodies)]
    msg = MocapFrame()
    msg.header.frame_id = "world"
    msg.stamp_source = MocapFrame.STAMP_FILE_TIME
    msg.frame_number = 0
    msg.body_names = names
    poses = []
    for i in range(n_bodies):
        p = Pose()
        p.position.x, p.position.y, p.position.z = 0.1 * i, -0.05 * i, 1.0 + 0.01 * i
        p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w = 0.0, 0.0, 0.0, 1.0
        poses.append(p)
    msg.poses = poses
    msg.tracked = [True] * n_bodies
    msg.mean_marker_error = [0.0002] * n_bodies
    return msg


def rider_state():
    """A RiderState with every field set (the pipeline's size: ``phi_definition`` ``hinge``)."""
    from euc_msgs.msg import RiderState

    m = RiderState()
    m.header.frame_id = "world"
    m.has_rider = True
    for i, k in enumerate(("x", "x_dot", "x_ddot", "gamma", "gamma_dot", "gamma_ddot", "phi", "phi_dot",
                           "phi_ddot", "phi_eq3", "phi_hinge", "psi", "theta")):
        setattr(m, k, 0.01 * (i + 1))
    m.phi_definition = "hinge"
    m.filter_lag = 0.0
    return m


def torque_estimate():
    """A TorqueEstimate with every field set (``model`` ``3dof``)."""
    from euc_msgs.msg import TorqueEstimate

    m = TorqueEstimate()
    m.valid = True
    m.m_d1, m.m_d2, m.m_d1_2dof, m.m_d2_2dof = 10.0, 10.1, 9.9, 10.2
    m.h, m.residual, m.rmse_window, m.window = 0.61, -0.1, 0.3, 5.0
    m.h_online, m.h_online_std = 0.6, 0.01
    m.model = "3dof"
    return m


def _ns_to_stamp(ns: int, stamp) -> None:
    stamp.sec, stamp.nanosec = divmod(int(ns), 1_000_000_000)


class _Done(Exception):
    pass


def _source(node, args) -> None:
    from euc_msgs.msg import MocapFrame
    from rclpy.serialization import serialize_message

    from euc_ros.ros import interfaces as itf

    pub = node.create_publisher(MocapFrame, itf.MOCAP_FRAME, itf.RELIABLE_QOS)
    msg = mocap_frame(args.bodies)
    msg.frame_number = 0x0102030405060708
    raw = bytearray(serialize_message(msg))
    number_at = bytes(raw).index((0x0102030405060708).to_bytes(8, "little"))
    period_ns = 1e9 / args.rate
    state = {"created": time.monotonic(), "matched": None, "t0": None, "stamp0": 0, "next": 0, "done": None}

    def tick() -> None:
        now = time.monotonic()
        if state["t0"] is None:
            if pub.get_subscription_count() < args.wait_subscribers:
                return
            if state["matched"] is None:
                state["matched"] = now
            if now < max(state["matched"] + 0.3, state["created"]) + args.start_delay:
                return
            state["t0"], state["stamp0"] = now, node.get_clock().now().nanoseconds
        if state["done"] is not None:
            if now >= state["done"] + args.linger:
                raise _Done
            return
        elapsed_ns = (now - state["t0"]) * 1e9
        while state["next"] < args.frames and state["next"] * period_ns <= elapsed_ns:
            k = state["next"]
            # pre-serialized bytes with the stamp and frame number patched in: the floor moves the
            # same bytes as mocap_ingest (which also publishes serialized frames) at the least cost
            sec, nsec = divmod(int(state["stamp0"] + round(k * period_ns)), 1_000_000_000)
            struct.pack_into("<iI", raw, 4, sec, nsec)
            struct.pack_into("<q", raw, number_at, k)
            pub.publish(bytes(raw))
            state["next"] += 1
        if state["next"] >= args.frames:
            state["done"] = now

    node.create_timer(min(0.5 / args.rate, 0.005), tick)


def _hop(node, args) -> None:
    from euc_msgs.msg import MocapFrame, RiderState, TorqueEstimate

    from euc_ros.ros import interfaces as itf

    if args.kind == "state":
        in_type, in_topic, out_type, out_topic, out = MocapFrame, itf.MOCAP_FRAME, RiderState, itf.RIDER_STATE, \
            rider_state()
    else:
        in_type, in_topic, out_type, out_topic, out = RiderState, itf.RIDER_STATE, TorqueEstimate, itf.TORQUE, \
            torque_estimate()
    pub = node.create_publisher(out_type, out_topic, itf.RELIABLE_QOS)
    out.header.frame_id = "world"

    def on_input(raw: bytes) -> None:
        # raw input, stamp read from the CDR header (as the pipeline's rider_state reads its frames raw)
        out.header.stamp.sec, out.header.stamp.nanosec = struct.unpack_from("<iI", raw, 4)
        pub.publish(out)

    node.create_subscription(in_type, in_topic, on_input, itf.RELIABLE_QOS, raw=True)


#: builtin_interfaces/Time in CDR (little endian): sec int32, nanosec uint32.
_STAMP = struct.Struct("<iI")
#: A stamp no real message carries: its CDR bytes mark where a template's stamps are.
_MARK_SEC, _MARK_NSEC = 0x7A5B3C1D, 987654321


def _stamped_template(msg, tf: bool) -> tuple[bytearray, list[int]]:
    """``msg`` serialized with a marker stamp in every header: (CDR bytes, offsets of the stamps)."""
    from rclpy.serialization import serialize_message

    for m in (msg.transforms if tf else [msg]):
        m.header.stamp.sec, m.header.stamp.nanosec = _MARK_SEC, _MARK_NSEC
    buf = bytearray(serialize_message(msg))
    mark = _STAMP.pack(_MARK_SEC, _MARK_NSEC)
    offsets, i = [], buf.find(mark)
    while i >= 0:
        offsets.append(i)
        i = buf.find(mark, i + 1)
    if len(offsets) != (len(msg.transforms) if tf else 1):
        raise RuntimeError(f"relay blast: {len(offsets)} stamps found in a {type(msg).__name__} template")
    return buf, offsets


def blast_mix(n_bodies: int) -> list[tuple]:
    """The pipeline's message mix of one frame, ``[(topic, message class, message), ...]``.

    A MocapFrame of ``n_bodies``, one PoseStamped per body, a TFMessage of their transforms, a RiderState, a
    TorqueEstimate (stamps left at 0: a publisher sets them per frame).
    """
    from euc_msgs.msg import MocapFrame, RiderState, TorqueEstimate
    from geometry_msgs.msg import PoseStamped, TransformStamped
    from tf2_msgs.msg import TFMessage

    from euc_ros.ros import interfaces as itf

    frame = mocap_frame(n_bodies)
    names = list(frame.body_names)
    mix = [(itf.MOCAP_FRAME, MocapFrame, frame)]
    for i, name in enumerate(names):
        ps = PoseStamped()
        ps.header.frame_id = "world"
        ps.pose = frame.poses[i]
        mix.append((itf.body_pose_topic(name), PoseStamped, ps))
    tf = TFMessage()
    for i, name in enumerate(names):
        t = TransformStamped()
        t.header.frame_id = "world"
        t.child_frame_id = name
        p = frame.poses[i]
        t.transform.translation.x, t.transform.translation.y, t.transform.translation.z = (
            p.position.x, p.position.y, p.position.z)
        t.transform.rotation = p.orientation
        tf.transforms.append(t)
    return mix + [(itf.TF, TFMessage, tf), (itf.RIDER_STATE, RiderState, rider_state()),
                  (itf.TORQUE, TorqueEstimate, torque_estimate())]


def _blast(node, args) -> dict:
    from euc_ros.ros import interfaces as itf

    mix = blast_mix(args.bodies)
    part, parts = (int(x) for x in args.part.split("/"))
    if not 0 <= part < parts:
        raise SystemExit(f"relay blast: --part {args.part}: expected K/N with 0 <= K < N")
    qos = itf.RELIABLE_QOS if args.qos == "reliable" else itf.MOCAP_INPUT_QOS   # MOCAP_INPUT_QOS: best effort
    pubs = [(topic, node.create_publisher(cls, topic, qos), msg) for topic, cls, msg in mix[part::parts]]

    import rclpy

    deadline = time.monotonic() + args.match_timeout
    while any(p.get_subscription_count() < args.wait_subscribers for _, p, _ in pubs):
        rclpy.spin_once(node, timeout_sec=0.05)
        if time.monotonic() > deadline:
            missing = [t for t, p, _ in pubs if p.get_subscription_count() < args.wait_subscribers]
            raise SystemExit(f"relay blast: no subscription on {missing} after {args.match_timeout:g} s")
    settle = time.monotonic() + args.start_delay
    while time.monotonic() < settle:
        rclpy.spin_once(node, timeout_sec=0.02)

    # Pre-serialized CDR (Publisher.publish(bytes)): serializing in Python costs more than publishing,
    # and a blast measures the subscriber. Each frame's stamp is patched into the bytes where the
    # template holds its marker stamp (every header of the message).
    templates = [(topic, pub, *_stamped_template(msg, topic == itf.TF)) for topic, pub, msg in pubs]
    sent = {t: 0 for t, _, _ in pubs}
    n_frames = int(round(args.frame_rate * args.duration))
    period = 1.0 / args.frame_rate
    clock = node.get_clock()
    pack_into = _STAMP.pack_into
    wall0 = time.time()
    t0 = time.monotonic()
    for k in range(n_frames):
        due = t0 + k * period
        delay = due - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        sec, nsec = divmod(clock.now().nanoseconds, 1_000_000_000)
        for topic, pub, buf, offsets in templates:
            for off in offsets:
                pack_into(buf, off, sec, nsec)
            pub.publish(bytes(buf))
            sent[topic] += 1
    publish_s = time.monotonic() - t0
    linger = time.monotonic() + args.linger
    while time.monotonic() < linger:
        rclpy.spin_once(node, timeout_sec=0.05)
    total = sum(sent.values())
    return {"sent": sent, "messages": total, "frames": n_frames, "publish_s": publish_s, "wall_start": wall0,
            "wall_end": wall0 + publish_s,
            "achieved_msgs_per_s": total / publish_s if publish_s > 0 else float("nan")}


def _lockstep_sim(node, args) -> dict:
    import rclpy
    from euc_msgs.msg import SteeringCommand, UnicycleState

    from euc_ros.ros import interfaces as itf

    pub = node.create_publisher(UnicycleState, itf.UNICYCLE_STATE, itf.LOCKSTEP_QOS)
    state = UnicycleState()
    state.header.frame_id = "world"
    state.status = "ok"
    got = {"step": -1}

    def on_command(msg) -> None:
        got["step"] = max(got["step"], int(msg.step))

    sub = node.create_subscription(SteeringCommand, itf.STEERING_COMMAND, on_command, itf.LOCKSTEP_QOS)
    deadline = time.monotonic() + args.match_timeout
    while pub.get_subscription_count() < 1 or node.count_publishers(itf.STEERING_COMMAND) < 1:
        rclpy.spin_once(node, timeout_sec=0.05)
        if time.monotonic() > deadline:
            raise SystemExit("relay lockstep-sim: the controller did not appear")
    settle = time.monotonic() + 0.3
    while time.monotonic() < settle:
        rclpy.spin_once(node, timeout_sec=0.02)
    del sub
    t0 = None
    for k in range(args.steps):
        state.step = k
        _ns_to_stamp(round(k * args.dt * 1e9), state.header.stamp)
        state.x_g = k * args.dt
        pub.publish(state)
        sent = time.monotonic()
        while got["step"] < k:
            rclpy.spin_once(node, timeout_sec=0.1)
            if time.monotonic() - sent > 0.5:
                pub.publish(state)
                sent = time.monotonic()
        if k == 0:
            t0 = time.monotonic()   # stepping time from the first answered state on, as run_steer measures it
    stepping = time.monotonic() - t0 if t0 is not None else float("nan")
    state.status = "done"
    pub.publish(state)
    return {"steps": args.steps, "stepping_s": stepping, "steps_per_s": (args.steps - 1) / stepping}


def _lockstep_ctrl(node, args) -> None:
    from euc_msgs.msg import SteeringCommand, UnicycleState

    from euc_ros.ros import interfaces as itf

    pub = node.create_publisher(SteeringCommand, itf.STEERING_COMMAND, itf.LOCKSTEP_QOS)
    cmd = SteeringCommand()
    cmd.maneuver = "lane_change"
    cmd.reference = [0.0, 0.0]

    def on_state(msg) -> None:
        if msg.status == "done":
            raise _Done
        cmd.header = msg.header
        cmd.step = msg.step
        cmd.u = 0.0
        pub.publish(cmd)

    node.create_subscription(UnicycleState, itf.UNICYCLE_STATE, on_state, itf.LOCKSTEP_QOS)


def spin_until_signal(node, stop, executor=None) -> None:
    """Spin ``node`` until ``stop()`` is true, polling every 0.1 s (signals are handled in Python).

    One executor for the whole run (rclpy's SingleThreadedExecutor unless given): ``rclpy.spin_once``
    would add and remove the node on the global executor at every call, a cost of the loop, not of
    rclpy, that the floor must not carry.
    """
    from rclpy.executors import SingleThreadedExecutor

    executor = executor if executor is not None else SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    try:
        while not stop():
            executor.spin_once(timeout_sec=0.1)
    finally:
        executor.remove_node(node)


def install_stop_handlers() -> "callable":
    """SIGINT/SIGTERM set a flag instead of going through rclpy's handlers; returns ``stop()``.

    rclpy's own handlers shut the context down from the signal, which can race a callback that is
    publishing; a flag checked between ``spin_once`` calls cannot.
    """
    flag = {"stop": False}

    def handler(signum, frame):
        flag["stop"] = True

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
    return lambda: flag["stop"]


def main(argv: list[str] | None = None) -> int:
    """Run one floor process (see the module docstring)."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    parser = argparse.ArgumentParser(prog="python -m euc_ros.bench.relay", description=__doc__.splitlines()[0])
    parser.add_argument("mode", choices=("source", "hop", "blast", "lockstep-sim", "lockstep-ctrl"))
    parser.add_argument("--kind", choices=("state", "torque"), default="state", help="hop: which hop")
    parser.add_argument("--rate", type=float, default=120.0, help="source: frame rate [Hz]")
    parser.add_argument("--frames", type=int, default=1200, help="source: frames to publish")
    parser.add_argument("--bodies", type=int, default=14, help="bodies per MocapFrame")
    parser.add_argument("--wait-subscribers", type=int, default=1, help="subscriptions to wait for")
    parser.add_argument("--start-delay", type=float, default=1.0, help="wait after the match [s]")
    parser.add_argument("--linger", type=float, default=1.0, help="keep running after the end [s]")
    parser.add_argument("--frame-rate", type=float, default=120.0, help="blast: frames per second")
    parser.add_argument("--duration", type=float, default=5.0, help="blast: publishing time [s]")
    parser.add_argument("--part", default="0/1", help="blast: publish topics K, K+N, K+2N... of the mix (K/N): "
                        "the mix shared by N processes")
    parser.add_argument("--qos", choices=("reliable", "best_effort"), default="reliable",
                        help="blast: the pipeline's reliable QoS, or best effort (a mocap driver's)")
    parser.add_argument("--match-timeout", type=float, default=30.0, help="give up waiting for peers [s]")
    parser.add_argument("--steps", type=int, default=1000, help="lockstep-sim: steps")
    parser.add_argument("--dt", type=float, default=0.01, help="lockstep-sim: simulated step [s]")
    parser.add_argument("--result", default=None, help="also write the JSON result to this file")
    args, ros_args = parser.parse_known_args(sys.argv[1:] if argv is None else argv)

    realtime_from_env("relay")
    rclpy.init(args=["relay", *ros_args], signal_handler_options=SignalHandlerOptions.NO)
    stop = install_stop_handlers()
    node = rclpy.create_node(f"bench_{args.mode.replace('-', '_')}" + (f"_{args.kind}" if args.mode == "hop" else ""))
    result = None
    try:
        if args.mode in ("blast", "lockstep-sim"):
            result = (_blast if args.mode == "blast" else _lockstep_sim)(node, args)
        else:
            {"source": _source, "hop": _hop, "lockstep-ctrl": _lockstep_ctrl}[args.mode](node, args)
            spin_until_signal(node, stop)
    except (KeyboardInterrupt, _Done):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    if result is not None:
        line = json.dumps(result)
        print(line, flush=True)
        if args.result:
            with open(args.result, "w", encoding="utf-8") as f:
                f.write(line + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
