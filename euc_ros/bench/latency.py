"""Benchmark 1: live latency of mocap_ingest -> rider_state -> torque_estimator (separate processes).

Measurement
-----------
``mocap_ingest`` replays a simulated 120 Hz recording of 14 rigid bodies (CSV source, rate 1,
``stamp_mode: replay``): each frame's header stamp is its scheduled replay time, i.e. the wall-clock
time at which it is due. A probe process (:mod:`euc_ros.bench.probe`) subscribes to the three
topics and notes the wall-clock arrival time of every message. Latencies, per frame:

* hop 1 ``mocap_ingest -> mocap/frame``: arrival of the frame minus its stamp (replay scheduling,
  conversion, publication and transport);
* hop 2 ``rider_state``: arrival of the RiderState minus the arrival of the frame that produced
  it. A state is stamped with the capture time of *its* frame but published ``filter_lag`` later
  (fixed-lag Savitzky-Golay), when the frame stamped ``stamp + filter_lag`` arrives: that frame is
  its trigger. The intended filter lag is therefore excluded (it is stated separately);
* hop 3 ``torque_estimator``: arrival of the TorqueEstimate minus the arrival of the state with the
  same stamp;
* end to end: arrival of the TorqueEstimate minus the stamp of the trigger frame (= the sum of the
  three hops).

Frames dropped: frames the source published that did not reach the probe, plus frames inside the
output span that produced no state, plus states that produced no torque. The first
``WARMUP_S`` seconds are excluded from the percentiles (not from the drop counts).

Floor
-----
The same measurement on a bare rclpy relay chain (:mod:`euc_ros.bench.relay`): a source
publishing prebuilt 14-body MocapFrames with the same scheduling, and two relays that answer each
input with a prebuilt RiderState / TorqueEstimate carrying the input's header (no filter lag), all
separate processes with the pipeline's QoS. Target: end-to-end p99 at most 2x the floor's, no frame
dropped.
"""
from __future__ import annotations

import io
import sys
import time
from pathlib import Path

import numpy as np

from euc_ros.bench.common import BenchContext, BenchError, figure, percentiles_ms, run_launched_sampled
from euc_ros.bench.data import ride_recording
from euc_ros.bench.probe import load
from euc_ros.ros.launcher import NodeSpec
from euc_ros.sched import REALTIME_ENV

#: Seconds at the start of a stream excluded from the percentiles (discovery, caches).
WARMUP_S = 1.0
#: Recording lengths [s]: full and --quick.
DURATION_S = {False: 60.0, True: 5.0}
#: Target: end-to-end p99 at most this multiple of the floor's.
TARGET_RATIO = 2.0
HOPS = ("mocap_ingest", "rider_state", "torque_estimator")


def _match(query: np.ndarray, ref: np.ndarray, tol_ns: float) -> np.ndarray:
    """Index into sorted ``ref`` of the element nearest each ``query`` within ``tol_ns``, else -1."""
    if ref.size == 0:
        return np.full(query.shape, -1, dtype=np.int64)
    i = np.clip(np.searchsorted(ref, query), 1, ref.size - 1) if ref.size > 1 else np.zeros(query.shape, np.int64)
    if ref.size > 1:
        left = ref[i - 1]
        i = np.where(np.abs(query - left) <= np.abs(ref[i] - query), i - 1, i)
    ok = np.abs(ref[i] - query) <= tol_ns
    return np.where(ok, i, -1)


def analyze(data: dict, n_sent: int, rate_hz: float, warmup_s: float = WARMUP_S) -> dict:
    """Latency per hop and end to end, and drops, from a probe file's arrays.

    Parameters
    ----------
    data : dict
        :func:`euc_ros.bench.probe.load` output (``mocap__frame``, ``rider__state``, ``euc__torque``).
    n_sent : int
        Frames the source published.
    rate_hz : float
        Frame rate (matching tolerance: a quarter period).

    Returns
    -------
    dict
        ``hops`` {name: {p50, p99, max, n} [ms]}, ``end_to_end`` {...}, ``filter_lag_s``,
        ``frames_sent``, ``frames_received``, ``frames_lost_in_transport``, ``frames_without_state``,
        ``states_without_torque``, ``frames_dropped``, ``nan_torques``.
    """
    tol = 0.25e9 / rate_hz
    fr, st, tq = data["mocap__frame"], data["rider__state"], data["euc__torque"]
    order = np.argsort(fr["stamp_ns"], kind="stable")
    f_stamp, f_arr = fr["stamp_ns"][order], fr["arrival_ns"][order]
    s_order = np.argsort(st["stamp_ns"], kind="stable")
    s_stamp, s_arr, s_lag = st["stamp_ns"][s_order], st["arrival_ns"][s_order], st["extra"][s_order]
    t_stamp, t_arr, t_md1 = tq["stamp_ns"], tq["arrival_ns"], tq["extra"]

    # trigger frame of each state: the frame stamped stamp + filter_lag
    trig = _match(s_stamp + np.round(s_lag * 1e9).astype(np.int64), f_stamp, tol)
    # state of each torque: same stamp
    t_state = _match(t_stamp, s_stamp, tol)
    start = f_stamp[0] + int(warmup_s * 1e9) if f_stamp.size else 0

    hop1 = f_arr - f_stamp
    hop1 = hop1[f_stamp >= start]
    ok_s = trig >= 0
    hop2_all = s_arr[ok_s] - f_arr[trig[ok_s]]
    hop2 = hop2_all[f_stamp[trig[ok_s]] >= start]
    ok_t = t_state >= 0
    ok_t[ok_t] = trig[t_state[ok_t]] >= 0
    ti, si = np.flatnonzero(ok_t), t_state[ok_t]
    fi = trig[si]
    keep = f_stamp[fi] >= start
    hop3 = (t_arr[ti] - s_arr[si])[keep]
    e2e = (t_arr[ti] - f_stamp[fi])[keep]

    # drops: frames inside the span of outputs that produced no state, states without torque
    lag_ns = int(np.round(np.median(s_lag) * 1e9)) if s_lag.size else 0
    if s_stamp.size:
        inside = (f_stamp >= s_stamp[0]) & (f_stamp <= s_stamp[-1])
        has_state = _match(f_stamp[inside], s_stamp, tol) >= 0
        frames_without_state = int((~has_state).sum())
    else:
        frames_without_state = int(f_stamp.size)
    if t_stamp.size and s_stamp.size:
        t_sorted = np.sort(t_stamp)
        in_t = s_stamp >= t_sorted[0]      # every state from the first torque on must have its torque
        states_without_torque = int((_match(s_stamp[in_t], t_sorted, tol) < 0).sum())
    else:
        states_without_torque = int(s_stamp.size)
    lost = max(int(n_sent) - int(f_stamp.size), 0)
    return {
        "hops": {HOPS[0]: percentiles_ms(hop1), HOPS[1]: percentiles_ms(hop2), HOPS[2]: percentiles_ms(hop3)},
        "end_to_end": percentiles_ms(e2e),
        "filter_lag_s": lag_ns * 1e-9,
        "frames_sent": int(n_sent), "frames_received": int(f_stamp.size), "states": int(s_stamp.size),
        "torques": int(t_stamp.size), "frames_lost_in_transport": lost,
        "frames_without_state": frames_without_state, "states_without_torque": states_without_torque,
        "frames_dropped": lost + frames_without_state + states_without_torque,
        "nan_torques": int(np.count_nonzero(~np.isfinite(t_md1))),
    }


def rt_env(realtime: int | None) -> dict:
    """Environment of a latency-critical process: SCHED_FIFO ``realtime`` (:mod:`euc_ros.sched`) or nothing."""
    return {} if realtime is None else {REALTIME_ENV: str(int(realtime))}


def probe_spec(out: Path, realtime: int | None = None):
    """The probe process of a latency chain (:mod:`euc_ros.bench.probe`).

    Parameters
    ----------
    out : Path
        The probe's output file.
    realtime : int or None
        SCHED_FIFO priority (:func:`rt_env`); None: none.

    Returns
    -------
    NodeSpec
    """
    return NodeSpec(sys.executable, name="probe", args=["-m", "euc_ros.bench.probe", "--out", str(out)],
                    ros_args=False, required=False, env=rt_env(realtime))


def run_chain(specs, probe_out: Path, timeout_s: float, log: io.StringIO):
    """Run the processes until the source (required) exits; return the sampler (peak RSS, CPU series)."""
    launcher, finished, sampler = run_launched_sampled(specs, timeout_s, log)
    tail = " | ".join(log.getvalue().strip().splitlines()[-8:])
    if not finished:
        raise BenchError(f"the chain did not finish within {timeout_s:g} s: {tail}")
    bad = {k: v for k, v in launcher.exit_codes.items() if v not in (0, None)}
    if bad or not probe_out.exists():
        raise BenchError(f"a process failed ({bad}) or the probe wrote nothing: {tail}")
    return sampler


def measure_pipeline(csv: Path, session: Path, out_dir: Path, timeout_s: float) -> dict:
    """Run the real pipeline on ``csv`` with the probe; returns :func:`analyze` plus ``peak_rss_mb``."""
    from euc_ros.core.io.motive_csv import read_motive_csv

    probe_out = out_dir / "pipeline_probe.npz"
    series = read_motive_csv(csv)
    n_frames, rate_hz = series.n_frames, float(series.rate_hz)
    specs = [
        probe_spec(probe_out),
        NodeSpec("torque_estimator", parameters={"session_file": str(session), "h": 0.61}, required=False),
        NodeSpec("rider_state", parameters={"session_file": str(session)}, required=False),
        NodeSpec("mocap_ingest", parameters={"csv_path": str(csv), "rate_factor": 1.0, "exit_when_done": True,
                                             "wait_subscribers": 2, "start_delay": 1.0, "linger": 2.0}),
    ]
    log = io.StringIO()
    rss = run_chain(specs, probe_out, timeout_s, log).peaks_mb()
    res = analyze(load(probe_out), n_frames, rate_hz)
    res["peak_rss_mb"] = rss
    return res


def measure_floor(n_frames: int, rate_hz: float, n_bodies: int, out_dir: Path, timeout_s: float,
                  realtime: int | None = None) -> dict:
    """Run the bare relay chain with the probe; returns :func:`analyze` plus ``peak_rss_mb``.

    ``realtime``: SCHED_FIFO priority of every process of the chain (as the pipeline's critical ones).
    """
    probe_out = out_dir / "floor_probe.npz"
    relay = ["-m", "euc_ros.bench.relay"]
    env = rt_env(realtime)
    specs = [
        probe_spec(probe_out, realtime),
        NodeSpec(sys.executable, name="relay_torque", args=[*relay, "hop", "--kind", "torque"], ros_args=False,
                 required=False, env=env),
        NodeSpec(sys.executable, name="relay_state", args=[*relay, "hop", "--kind", "state"], ros_args=False,
                 required=False, env=env),
        NodeSpec(sys.executable, name="relay_source",
                 args=[*relay, "source", "--rate", str(rate_hz), "--frames", str(n_frames), "--bodies", str(n_bodies),
                       "--wait-subscribers", "2", "--start-delay", "1.0", "--linger", "2.0"], ros_args=False, env=env),
    ]
    log = io.StringIO()
    rss = run_chain(specs, probe_out, timeout_s, log).peaks_mb()
    res = analyze(load(probe_out), n_frames, rate_hz)
    res["peak_rss_mb"] = rss
    return res


def run(ctx: BenchContext) -> dict:
    """Benchmark 1 (see the module docstring)."""
    duration = DURATION_S[ctx.quick]
    rec = ride_recording(ctx.cache_dir, duration, log=ctx.log)
    out = ctx.tmp_dir / "latency"
    out.mkdir(parents=True, exist_ok=True)
    timeout = duration + 90.0
    ctx.log(f"  pipeline: {duration:g} s at 120 Hz, 14 bodies")
    t0 = time.monotonic()
    pipe = measure_pipeline(rec["csv"], rec["session"], out, timeout)
    ctx.log(f"  floor: bare rclpy relay chain, {pipe['frames_sent']} frames")
    floor = measure_floor(pipe["frames_sent"], 120.0, 14, out, timeout)
    figures = []
    for hop in HOPS:
        p, f = pipe["hops"][hop], floor["hops"][hop]
        figures.append(figure(f"{hop} hop p99", p["p99"], "ms", floor=f["p99"],
                              note=f"p50 {p['p50']:.2f} ms (floor {f['p50']:.2f}), max {p['max']:.1f} ms "
                                   f"(floor {f['max']:.1f})"))
    e, fe = pipe["end_to_end"], floor["end_to_end"]
    ok = e["p99"] <= TARGET_RATIO * fe["p99"]
    figures.append(figure("end-to-end p99 (filter lag excluded)", e["p99"], "ms", floor=fe["p99"],
                          target=f"<= {TARGET_RATIO:g}x floor", met=ok,
                          note=f"p50 {e['p50']:.2f} ms (floor {fe['p50']:.2f}), max {e['max']:.1f} ms "
                               f"(floor {fe['max']:.1f}); filter lag {pipe['filter_lag_s'] * 1e3:.0f} ms on top"))
    figures.append(figure("frames dropped", pipe["frames_dropped"], "frames", floor=floor["frames_dropped"],
                          target="0", met=pipe["frames_dropped"] == 0,
                          note=f"of {pipe['frames_sent']} sent; NaN torques {pipe['nan_torques']}"))
    return {"name": "latency", "title": "Live latency mocap_ingest -> rider_state -> torque_estimator",
            "figures": figures, "peak_rss_mb": {**{f"pipeline {k}": v for k, v in pipe["peak_rss_mb"].items()},
                                                **{f"floor {k}": v for k, v in floor["peak_rss_mb"].items()}},
            "details": {"duration_s": duration, "rate_hz": 120.0, "bodies": 14, "warmup_excluded_s": WARMUP_S,
                        "pipeline": pipe, "floor": floor},
            "wall_s": time.monotonic() - t0}
