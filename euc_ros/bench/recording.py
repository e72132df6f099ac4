"""Benchmark 4: recorder messages per second sustained into MCAP with no loss.

The ``recorder`` node (its defaults: 64 KiB chunks, queue depth 10000) records the pipeline's message
mix published by :data:`PUBLISHERS` bare rclpy processes sharing the topics (:mod:`euc_ros.bench.relay`
``blast --part``): per frame one 14-body MocapFrame, 14 PoseStamped, one TFMessage of 14
transforms, one RiderState and one TorqueEstimate (18 messages, 5.6 kB), on the pipeline's reliable
QoS, as pre-serialized CDR. The recorder runs with its own Fast DDS profile (a 65536-message
shared-memory port, :data:`euc_ros.ros.fastdds.RECORDER_PROFILE`); the publishers with
:data:`~euc_ros.ros.fastdds.FAST_PUBLISHER_PROFILE` (a 64 MiB segment: a publisher's default 512
KiB lets only 512 of its messages wait for a receiver, 5 ms at 100k msgs/s). The frame rate climbs
a ladder (each step a fresh recorder and bag), then bisects twice between the last lossless and the
first lossy rate; a step is lossless when every topic's count in the closed bag equals what was
published (a lossy step also says which frames each topic lost). The figure is the highest publish
rate (messages/s) of a lossless step, with the target (>= 100k msgs/s on one core, within 4x
of the floor); the ladder stops at the first loss or when the publishers cannot reach the rate
asked. A second, shorter ladder publishes the same mix best effort (a mocap driver's QoS): no
heartbeats or acknowledgements, somewhat less publisher CPU per message, and nothing lost can be
repaired.

The recorder's CPU (all its threads, sampled from ``/proc``) while the mix is published gives the
cores it used and a further figure: messages per CPU-second, what one core of recorder takes when
the publishers, not the recorder, are the limit. The publishers' CPU per message (with the recorder
matched) is reported beside a publisher alone (no subscriber): what offering the rate costs.

Floor: writing the same messages (CDR bytes serialized by rclpy) with rosbags' ``Writer``
directly, in one process, as fast as it goes (messages/s).
"""
from __future__ import annotations

import io
import json
import sys
import time
from pathlib import Path

import numpy as np
import yaml

from euc_ros.bench.common import BenchContext, BenchError, PeakRssSampler, figure
from euc_ros.bench.relay import BODY_NAMES, mocap_frame, rider_state, torque_estimate
from euc_ros.core.io.bags import read_bag
from euc_ros.core.io.msgdefs import make_typestore
from euc_ros.ros.launcher import Launcher, NodeSpec

#: Frame-rate ladders [frames/s] (x18 messages): full and --quick.
LADDER = {False: (480, 1920, 3840, 5760, 7680, 9600), True: (480, 5760)}
#: Frame rates of the best-effort ladder [frames/s] (x18 messages): full and --quick.
BEST_EFFORT_LADDER = {False: (5760, 7680, 9600), True: (5760,)}
#: Publishing time per step [s]: full and --quick.
STEP_S = {False: 5.0, True: 1.0}
#: Frames of the mix written by the floor and published by the publisher alone: full and --quick.
FLOOR_FRAMES = {False: 60000, True: 10000}
#: Bisection steps between the last lossless and the first lossy rate: full and --quick.
BISECT = {False: 2, True: 0}
#: A step whose publisher reached less than this fraction of the asked rate ends the ladder.
SATURATION = 0.8
#: Publisher processes sharing the mix (``relay blast --part``): one Python process publishes
#: 60-100k msgs/s to a recorder on this class of machine (~8-10 us of CPU a message with the
#: recorder matched, ~2.6 us alone).
PUBLISHERS = 2
#: The target: lossless at this rate [msgs/s] (on one core), within this factor of the floor.
TARGET_MSGS_PER_S = 100_000
TARGET_RATIO = 4.0
#: The recorder's CPU per message counts what it used until this long after the last publish [s].
DRAIN_S = 0.5


def blast_topics(n_bodies: int = 14) -> list[str]:
    """Topics of the blast mix (absolute names as the bag stores them)."""
    return ["/mocap/frame", *[f"/mocap/{b}/pose" for b in BODY_NAMES[:n_bodies]], "/tf", "/rider/state",
            "/euc/torque"]


def bag_counts(bag: Path) -> dict[str, int]:
    """Messages per topic of a closed bag, from its metadata.yaml."""
    meta = yaml.safe_load((bag / "metadata.yaml").read_text(encoding="utf-8"))["rosbag2_bagfile_information"]
    return {t["topic_metadata"]["name"]: int(t["message_count"]) for t in meta["topics_with_message_count"]}


def lost_frames(bag: Path, parts: list[list[str]]) -> dict:
    """Where a lossy step lost, per topic: the runs of missing frames and the time of the first missing frame.

    The missing frames are ``[first, last, count]`` runs of frame indices (frame stamps of the publisher's
    other topics give the frames it sent); the time [ms] is that of the first missing frame after its
    publisher's first. ``parts``: the topics of each publisher.
    """
    store = make_typestore()
    stamps: dict[str, list[int]] = {}
    for topic, msgtype, _, raw in read_bag(bag, raw=True):
        msg = store.deserialize_cdr(raw, msgtype)
        head = msg.transforms[0].header if msgtype == "tf2_msgs/msg/TFMessage" else msg.header
        stamps.setdefault(topic, []).append(head.stamp.sec * 1_000_000_000 + head.stamp.nanosec)
    out = {}
    for topics in parts:
        frames = np.array(sorted(set().union(*[stamps.get(t, []) for t in topics])), dtype=np.int64)
        for t in topics:
            miss = np.flatnonzero(~np.isin(frames, stamps.get(t, [])))
            if miss.size:
                cuts = np.flatnonzero(np.diff(miss) > 1)
                starts, ends = np.r_[miss[0], miss[cuts + 1]], np.r_[miss[cuts], miss[-1]]
                out[t] = {"runs": [[int(a), int(b), int(b - a + 1)] for a, b in zip(starts, ends)][:10],
                          "first_ms": float((frames[miss[0]] - frames[0]) / 1e6), "frames_seen": int(frames.size)}
    return out


def _cpu_between(series: list, t0: float, t1: float) -> float | None:
    """CPU seconds a sampled process used between wall times ``t0`` and ``t1`` (interpolated samples)."""
    if len(series) < 2 or series[0][0] > t0 or series[-1][0] < t1:
        return None
    t, cpu = np.array(series, dtype=float).T
    return float(np.interp(t1, t, cpu) - np.interp(t0, t, cpu))


def fast_publisher_env() -> dict:
    """Environment of the blast publishers: :data:`~euc_ros.ros.fastdds.FAST_PUBLISHER_PROFILE`."""
    from euc_ros.ros.fastdds import FAST_PUBLISHER_PROFILE

    return {"FASTRTPS_DEFAULT_PROFILES_FILE": str(FAST_PUBLISHER_PROFILE)}


def measure_step(frame_rate: float, duration_s: float, out_dir: Path, timeout_s: float = 120.0,
                 publishers: int = 1, recorder_env: dict | None = None, publisher_env: dict | None = None,
                 qos: str = "reliable") -> dict:
    """One ladder step: recorder + ``publishers`` blast processes sharing the mix.

    ``qos``: ``reliable``, the pipeline's, or ``best_effort``, a mocap driver's; the recorder matches it.

    ``publisher_env`` defaults to :func:`fast_publisher_env` (pass ``{}`` for Fast DDS' defaults). Returns
    sent, recorded, lost, the achieved rate, the recorder's CPU while the mix was published (seconds,
    cores, microseconds per message), the publishers' CPU per message and the peak RSS of every process.
    """
    if publisher_env is None:
        publisher_env = fast_publisher_env()

    tag = f"{int(frame_rate)}" if qos == "reliable" else f"{qos}_{int(frame_rate)}"
    bag = out_dir / f"bag_{tag}"
    results = [out_dir / f"blast_{tag}_{k}.json" for k in range(publishers)]
    topics = blast_topics()
    specs = [NodeSpec("recorder", parameters={"output": str(bag), "topics": topics}, required=False,
                      env=dict(recorder_env or {}))]
    names = [f"blast{k}" if publishers > 1 else "blast" for k in range(publishers)]
    for k, (name, result) in enumerate(zip(names, results)):
        specs.append(NodeSpec(sys.executable, name=name, ros_args=False, env=dict(publisher_env or {}),
                              required=False,
                              args=["-m", "euc_ros.bench.relay", "blast", "--frame-rate", str(frame_rate),
                                    "--duration", str(duration_s), "--start-delay", "0.5", "--linger", "1.0",
                                    "--part", f"{k}/{publishers}", "--qos", qos, "--result", str(result)]))
    log = io.StringIO()
    launcher = Launcher(specs, stream=log)
    with PeakRssSampler(0.1) as sampler:
        with launcher:               # until every publisher is done (the first one done stops nothing)
            for label, proc in launcher.procs.items():
                sampler.add(label, proc.pid)
            finished = launcher.wait(timeout=timeout_s, until=lambda: all(launcher.procs[n].poll() is not None
                                                                          for n in names))
            for n in names:
                launcher.exit_codes.setdefault(n, launcher.procs[n].returncode)
    peaks = sampler.peaks_mb()
    tail = " | ".join(log.getvalue().strip().splitlines()[-6:])
    if not finished or not all(r.exists() for r in results) or any(launcher.exit_codes.get(n) != 0 for n in names):
        codes = ", ".join(f"{n} exit {launcher.exit_codes.get(n)}" for n in names)
        missing = [r.name for r in results if not r.exists()]
        raise BenchError(f"recorder step at {frame_rate:g} frames/s failed ({'finished' if finished else 'timed out'}; "
                         f"{codes}; results missing: {missing or 'none'}): {tail}")
    if launcher.exit_codes.get("recorder") != 0 or not (bag / "metadata.yaml").exists():
        raise BenchError(f"the recorder did not close its bag (exit {launcher.exit_codes.get('recorder')}): {tail}")
    blasts = [json.loads(r.read_text(encoding="utf-8")) for r in results]
    counts = bag_counts(bag)
    sent = {("/" + t.lstrip("/")): n for b in blasts for t, n in b["sent"].items()}
    lost = {t: n - counts.get(t, 0) for t, n in sent.items() if n != counts.get(t, 0)}
    size = sum(f.stat().st_size for f in bag.glob("*.mcap"))
    t0, t1 = min(b["wall_start"] for b in blasts), max(b["wall_end"] for b in blasts)
    n_sent = sum(b["messages"] for b in blasts)
    cpu = _cpu_between(sampler.cpu.get("recorder", []), t0, t1)
    drained = _cpu_between(sampler.cpu.get("recorder", []), t0, t1 + DRAIN_S)   # with what it still took after
    pub_cpu = [_cpu_between(sampler.cpu.get(n, []), b["wall_start"], b["wall_end"]) for n, b in zip(names, blasts)]
    pub_us = None if any(c is None for c in pub_cpu) else 1e6 * sum(pub_cpu) / n_sent
    # a frame lost on every topic of its publisher is not seen at all: such losses show only as counts
    where = lost_frames(bag, [topics[k::publishers] for k in range(publishers)]) if lost else {}
    return {"frame_rate": frame_rate, "qos": qos, "asked_msgs_per_s": frame_rate * len(sent), "publishers": publishers,
            "achieved_msgs_per_s": n_sent / (t1 - t0), "sent": n_sent,
            "recorded": sum(counts.values()), "lost": lost, "lost_where": where, "lossless": not lost,
            "bag_mb": size / 1e6,
            "recorder_cpu_s": cpu, "recorder_cores": None if cpu is None else cpu / (t1 - t0),
            "recorder_us_per_msg": None if drained is None else 1e6 * drained / n_sent,
            "publisher_us_per_msg": pub_us, "peak_rss_mb": peaks}


def measure_publisher_alone(n_frames: int, out_dir: Path, timeout_s: float = 60.0) -> dict:
    """One blast process with no subscriber publishing ``n_frames`` frames of the mix as fast as it goes.

    Returns its CPU per message [us] and rate.
    """
    result = out_dir / "blast_alone.json"
    spec = NodeSpec(sys.executable, name="blast", ros_args=False, env=fast_publisher_env(), required=False,
                    args=["-m", "euc_ros.bench.relay", "blast", "--frame-rate", "1000000", "--duration",
                          str(n_frames / 1e6), "--wait-subscribers", "0", "--start-delay", "0.2", "--linger", "0.5",
                          "--result", str(result)])
    log = io.StringIO()
    with PeakRssSampler(0.1) as sampler:
        with Launcher([spec], stream=log) as launcher:
            sampler.add("blast", launcher.procs["blast"].pid)
            finished = launcher.wait(timeout=timeout_s)
    if not finished or not result.exists():
        raise BenchError(f"the publisher alone failed: {' | '.join(log.getvalue().strip().splitlines()[-4:])}")
    b = json.loads(result.read_text(encoding="utf-8"))
    cpu = _cpu_between(sampler.cpu.get("blast", []), b["wall_start"], b["wall_end"])
    return {"messages": b["messages"], "msgs_per_s": b["achieved_msgs_per_s"],
            "us_per_msg": None if cpu is None else 1e6 * cpu / b["messages"]}


def measure_rosbags(n_frames: int, out: str) -> dict:
    """Floor: the blast mix written with rosbags' Writer directly; ``{"messages", "wall_s", "msgs_per_s"}``."""
    from geometry_msgs.msg import PoseStamped, TransformStamped
    from rclpy.serialization import serialize_message
    from rosbags.rosbag2 import StoragePlugin, Writer
    from tf2_msgs.msg import TFMessage

    frame = mocap_frame(14)
    msgs = [("/mocap/frame", "euc_msgs/msg/MocapFrame", frame)]
    tf = TFMessage()
    for i, name in enumerate(frame.body_names):
        ps = PoseStamped()
        ps.header.frame_id = "world"
        ps.pose = frame.poses[i]
        msgs.append((f"/mocap/{name}/pose", "geometry_msgs/msg/PoseStamped", ps))
        t = TransformStamped()
        t.header.frame_id = "world"
        t.child_frame_id = name
        t.transform.rotation = frame.poses[i].orientation
        tf.transforms.append(t)
    msgs += [("/tf", "tf2_msgs/msg/TFMessage", tf), ("/rider/state", "euc_msgs/msg/RiderState", rider_state()),
             ("/euc/torque", "euc_msgs/msg/TorqueEstimate", torque_estimate())]
    raws = [(topic, msgtype, serialize_message(m)) for topic, msgtype, m in msgs]
    store = make_typestore()
    writer = Writer(Path(out), version=9, storage_plugin=StoragePlugin.MCAP)
    writer.open()
    conns = [(writer.add_connection(topic, msgtype, typestore=store), raw) for topic, msgtype, raw in raws]
    stamp = time.time_ns()
    t0 = time.perf_counter()
    for k in range(n_frames):
        t = stamp + k * 1_000_000
        for conn, raw in conns:
            writer.write(conn, t, raw)
    writer.close()
    wall = time.perf_counter() - t0
    n = n_frames * len(conns)
    return {"messages": n, "wall_s": wall, "msgs_per_s": n / wall}


def _ladder(ctx: BenchContext, out: Path, rates, bisect: int, qos: str) -> list[dict]:
    """Steps up ``rates`` until a loss or the publishers' saturation, then bisects.

    ``bisect`` steps between the last lossless and the first lossy rate.
    """
    steps = []

    def step(rate: int, why: str) -> dict:
        ctx.log(f"  recorder at {rate} frames/s ({rate * 18} msgs/s asked, {PUBLISHERS} {qos} publishers{why})")
        s = measure_step(rate, STEP_S[ctx.quick], out, publishers=PUBLISHERS, qos=qos)
        ctx.log(f"    achieved {s['achieved_msgs_per_s']:.0f} msgs/s, lost {sum(s['lost'].values())}, "
                f"recorder {_fmt(s['recorder_cores'], '.2f')} cores, {_fmt(s['recorder_us_per_msg'], '.1f')} us/msg; "
                f"publishers {_fmt(s['publisher_us_per_msg'], '.1f')} us/msg")
        steps.append(s)
        return s

    for rate in rates:
        s = step(rate, "")
        if not s["lossless"] or s["achieved_msgs_per_s"] < SATURATION * s["asked_msgs_per_s"]:
            break
    for _ in range(bisect):
        ok = [s["frame_rate"] for s in steps if s["lossless"]]
        bad = [s["frame_rate"] for s in steps if not s["lossless"]]
        if not ok or not bad:
            break
        rate = int(round((max(ok) + min(bad)) / 2))
        if rate in (max(ok), min(bad)):
            break
        step(rate, ", bisecting")
    return steps


def _lossless_figure(metric: str, steps: list[dict], floor: dict, extra: str) -> tuple[dict, dict | None]:
    """The figure of a ladder: its best lossless rate against the floor, with the target."""
    lossless = [s for s in steps if s["lossless"]]
    best = max(lossless, key=lambda s: s["achieved_msgs_per_s"]) if lossless else None
    value = best["achieved_msgs_per_s"] if best else 0.0
    lossy = [s for s in steps if not s["lossless"]]
    last = min(lossy, key=lambda s: s["frame_rate"]) if lossy else steps[-1]
    if not last["lossless"]:
        why = (f"loss at {last['asked_msgs_per_s']:.0f} msgs/s asked ({sum(last['lost'].values())} of "
               f"{last['sent']} lost)")
    elif last["achieved_msgs_per_s"] < SATURATION * last["asked_msgs_per_s"]:
        why = (f"the {PUBLISHERS} publishers saturated at {last['achieved_msgs_per_s']:.0f} of "
               f"{last['asked_msgs_per_s']:.0f} asked")
    else:
        why = "top of the ladder reached without loss"
    cores = best["recorder_cores"] if best else None
    # "on one core": the recorder's every thread together used at most one core at that step
    met = bool(value >= TARGET_MSGS_PER_S and floor["msgs_per_s"] / value <= TARGET_RATIO
               and cores is not None and cores <= 1.0) if value > 0 else False
    return figure(metric, value, "msgs/s", floor=floor["msgs_per_s"], lower_is_better=False,
                  target=f">= {TARGET_MSGS_PER_S} msgs/s on one core, <= {TARGET_RATIO:g}x floor", met=met,
                  note=f"{extra}ladder ended: {why}; the recorder used {_fmt(cores, '.2f')} cores at its best "
                       f"lossless step; floor: rosbags Writer alone"), best


def run(ctx: BenchContext) -> dict:
    """Benchmark 4 (see the module docstring)."""
    t_start = time.monotonic()
    out = ctx.tmp_dir / "recording"
    out.mkdir(parents=True, exist_ok=True)
    steps = _ladder(ctx, out, LADDER[ctx.quick], BISECT[ctx.quick], "reliable")
    # the same mix from best-effort publishers (a mocap driver's QoS): no heartbeats or
    # acknowledgements, less publisher CPU per message; nothing lost can be repaired
    be_steps = _ladder(ctx, out, BEST_EFFORT_LADDER[ctx.quick], 0, "best_effort")
    n_floor = FLOOR_FRAMES[ctx.quick]   # 180k / 1.08M messages: long enough to time
    floor = ctx.isolated("euc_ros.bench.recording:measure_rosbags", n_frames=n_floor, out=str(out / "floor_bag"))
    fig, best = _lossless_figure("recorder, lossless", steps, floor, "")
    figures = [fig]
    fig, be_best = _lossless_figure("recorder, lossless, best-effort publishers", be_steps, floor,
                                    "the mix published best effort; ")
    figures.append(fig)
    # What one core of recorder would take: messages per CPU-second it spent (all its threads: the
    # Fast DDS receive thread, the takes, the writes) at its most loaded lossless step.
    busiest = max((b for b in (best, be_best) if b and b["recorder_us_per_msg"]),
                  key=lambda s: s["achieved_msgs_per_s"], default=None)
    if busiest:
        per_cpu_s = 1e6 / busiest["recorder_us_per_msg"]
        figures.append(figure("recorder, messages per CPU-second", per_cpu_s, "msgs/s", floor=floor["msgs_per_s"],
                              lower_is_better=False,
                              note=f"{busiest['recorder_us_per_msg']:.1f} us of recorder CPU (every thread) per "
                                   f"message at {busiest['achieved_msgs_per_s']:.0f} msgs/s ({busiest['qos']} "
                                   f"publishers): one core's capacity"))
    # What offering the rate costs: a publisher's CPU per message with the recorder matched (the
    # busiest lossless step) and alone (no subscriber: Fast DDS keeps the sample, delivers nothing).
    alone = measure_publisher_alone(FLOOR_FRAMES[ctx.quick], out)
    for b in (best, be_best):
        if b and b["publisher_us_per_msg"]:
            figures.append(figure(f"publisher CPU per message, recorder matched ({b['qos']})",
                                  b["publisher_us_per_msg"], "us", floor=alone["us_per_msg"],
                                  note=f"relay blast (pre-serialized CDR, Fast DDS shared memory, synchronous) at "
                                       f"{b['achieved_msgs_per_s']:.0f} msgs/s from {PUBLISHERS} processes; floor: "
                                       f"the same publisher with no subscriber ({alone['msgs_per_s']:.0f} msgs/s)"))
    rss = {"recorder (best step)": best["peak_rss_mb"].get("recorder") if best else None,
           "blast publisher": max(v for s in steps + be_steps for k, v in s["peak_rss_mb"].items()
                                  if k.startswith("blast")),
           "rosbags writer (floor)": floor["peak_rss_mb"]}
    return {"name": "recording", "title": "Recorder into MCAP: messages per second with no loss",
            "figures": figures, "peak_rss_mb": rss,
            "details": {"steps": steps, "best_effort_steps": be_steps, "floor": floor, "publisher_alone": alone},
            "wall_s": time.monotonic() - t_start}


def _fmt(x, spec: str) -> str:
    return "?" if x is None else format(x, spec)
