"""Benchmark 4: recorder messages per second sustained into MCAP with no loss.

The ``recorder`` node (its defaults: 1 MiB chunks, queue depth 1000) records the pipeline's message
mix published by a bare rclpy process (:mod:`euc_ros.bench.relay` ``blast``): per frame one
14-body MocapFrame, 14 PoseStamped, one TFMessage of 14 transforms, one RiderState and one
TorqueEstimate (18 messages, 5.6 kB), on the pipeline's reliable QoS. The frame rate climbs a ladder
(each step a fresh recorder and bag), then bisects twice between the last lossless and the first
lossy rate; a step is lossless when every topic's count in the closed bag equals what was
published. The figure is the highest publish rate (messages/s) of a lossless
step; the ladder stops at the first loss or when the publisher cannot reach the rate asked.

Floor: writing the same messages (CDR bytes serialized by rclpy) with rosbags' ``Writer``
directly, in one process, as fast as it goes (messages/s).
"""
from __future__ import annotations

import io
import json
import sys
import time
from pathlib import Path

from euc_ros.bench.common import BenchContext, BenchError, figure, run_launched

#: Frame-rate ladders [frames/s] (x18 messages): full and --quick.
LADDER = {False: (120, 240, 480, 960, 1920, 3840), True: (240, 960)}
#: Publishing time per step [s]: full and --quick.
STEP_S = {False: 5.0, True: 2.5}
#: Bisection steps between the last lossless and the first lossy rate: full and --quick.
BISECT = {False: 2, True: 0}
#: A step whose publisher reached less than this fraction of the asked rate ends the ladder.
SATURATION = 0.8


def blast_topics(n_bodies: int = 14) -> list[str]:
    """Topics of the blast mix (absolute names as the bag stores them)."""
    from euc_ros.bench.relay import BODY_NAMES

    return ["/mocap/frame", *[f"/mocap/{b}/pose" for b in BODY_NAMES[:n_bodies]], "/tf", "/rider/state",
            "/euc/torque"]


def _bag_counts(bag: Path) -> dict[str, int]:
    import yaml

    meta = yaml.safe_load((bag / "metadata.yaml").read_text(encoding="utf-8"))["rosbag2_bagfile_information"]
    return {t["topic_metadata"]["name"]: int(t["message_count"]) for t in meta["topics_with_message_count"]}


def measure_step(frame_rate: float, duration_s: float, out_dir: Path, timeout_s: float = 120.0) -> dict:
    """One ladder step: recorder + blaster; returns sent, recorded, lost, rate and the recorder's peak RSS."""
    from euc_ros.launch import NodeSpec

    bag = out_dir / f"bag_{int(frame_rate)}"
    result = out_dir / f"blast_{int(frame_rate)}.json"
    topics = blast_topics()
    specs = [
        NodeSpec("recorder", parameters={"output": str(bag), "topics": topics}, required=False),
        NodeSpec(sys.executable, name="blast", ros_args=False,
                 args=["-m", "euc_ros.bench.relay", "blast", "--frame-rate", str(frame_rate), "--duration",
                       str(duration_s), "--start-delay", "0.5", "--linger", "1.0", "--result", str(result)]),
    ]
    log = io.StringIO()
    launcher, finished, peaks = run_launched(specs, timeout_s, log)
    tail = " | ".join(log.getvalue().strip().splitlines()[-6:])
    if not finished or not result.exists() or launcher.exit_codes.get("blast") != 0:
        raise BenchError(f"recorder step at {frame_rate:g} frames/s failed: {tail}")
    if launcher.exit_codes.get("recorder") != 0 or not (bag / "metadata.yaml").exists():
        raise BenchError(f"the recorder did not close its bag (exit {launcher.exit_codes.get('recorder')}): {tail}")
    blast = json.loads(result.read_text(encoding="utf-8"))
    counts = _bag_counts(bag)
    sent = {("/" + t.lstrip("/")): n for t, n in blast["sent"].items()}
    lost = {t: n - counts.get(t, 0) for t, n in sent.items() if n != counts.get(t, 0)}
    size = sum(f.stat().st_size for f in bag.glob("*.mcap"))
    return {"frame_rate": frame_rate, "asked_msgs_per_s": frame_rate * len(sent),
            "achieved_msgs_per_s": blast["achieved_msgs_per_s"], "sent": blast["messages"],
            "recorded": sum(counts.values()), "lost": lost, "lossless": not lost, "bag_mb": size / 1e6,
            "peak_rss_mb": peaks}


def measure_rosbags(n_frames: int, out: str) -> dict:
    """Floor: the blast mix written with rosbags' Writer directly; ``{"messages", "wall_s", "msgs_per_s"}``."""
    from rclpy.serialization import serialize_message
    from rosbags.rosbag2 import StoragePlugin, Writer

    from euc_ros.bench.relay import mocap_frame, rider_state, torque_estimate
    from euc_ros.core.io.msgdefs import make_typestore

    from geometry_msgs.msg import PoseStamped, TransformStamped
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


def run(ctx: BenchContext) -> dict:
    """Benchmark 4 (see the module docstring)."""
    t_start = time.monotonic()
    out = ctx.tmp_dir / "recording"
    out.mkdir(parents=True, exist_ok=True)
    steps = []
    for rate in LADDER[ctx.quick]:
        ctx.log(f"  recorder at {rate} frames/s ({rate * 18} msgs/s asked)")
        step = measure_step(rate, STEP_S[ctx.quick], out)
        steps.append(step)
        if not step["lossless"] or step["achieved_msgs_per_s"] < SATURATION * step["asked_msgs_per_s"]:
            break
    # bisect between the last lossless rate and the first lossy one
    for _ in range(BISECT[ctx.quick]):
        ok = [s["frame_rate"] for s in steps if s["lossless"]]
        bad = [s["frame_rate"] for s in steps if not s["lossless"]]
        if not ok or not bad:
            break
        rate = int(round((max(ok) + min(bad)) / 2))
        if rate in (max(ok), min(bad)):
            break
        ctx.log(f"  recorder at {rate} frames/s ({rate * 18} msgs/s asked, bisecting)")
        steps.append(measure_step(rate, STEP_S[ctx.quick], out))
    lossless = [s for s in steps if s["lossless"]]
    best = max(lossless, key=lambda s: s["achieved_msgs_per_s"]) if lossless else None
    n_floor = 20000 if ctx.quick else 60000   # 360k / 1.08M messages: long enough to time
    floor = ctx.isolated("euc_ros.bench.recording:measure_rosbags", n_frames=n_floor, out=str(out / "floor_bag"))
    value = best["achieved_msgs_per_s"] if best else 0.0
    lossy = [s for s in steps if not s["lossless"]]
    last = min(lossy, key=lambda s: s["frame_rate"]) if lossy else steps[-1]
    if not last["lossless"]:
        why = (f"loss at {last['asked_msgs_per_s']:.0f} msgs/s asked ({sum(last['lost'].values())} of "
               f"{last['sent']} lost)")
    elif last["achieved_msgs_per_s"] < SATURATION * last["asked_msgs_per_s"]:
        why = f"the publisher saturated at {last['achieved_msgs_per_s']:.0f} of {last['asked_msgs_per_s']:.0f} asked"
    else:
        why = "top of the ladder reached without loss"
    figures = [figure("recorder, lossless", value, "msgs/s", floor=floor["msgs_per_s"], lower_is_better=False,
                      note=f"ladder ended: {why}; floor: rosbags Writer alone")]
    rss = {"recorder (best step)": best["peak_rss_mb"].get("recorder") if best else None,
           "blast publisher": max(s["peak_rss_mb"].get("blast", 0) for s in steps),
           "rosbags writer (floor)": floor["peak_rss_mb"]}
    return {"name": "recording", "title": "Recorder into MCAP: messages per second with no loss",
            "figures": figures, "peak_rss_mb": rss, "details": {"steps": steps, "floor": floor},
            "wall_s": time.monotonic() - t_start}
