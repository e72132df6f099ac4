"""Benchmark 8: replay timing of ``euc-ros play`` (per message, against the recorded timing x rate).

A bag of ``N`` PoseStamped on ``/a`` with irregular spacing (3-20 ms, as a lossy mocap stream) is
played with ``--rate 1`` and ``--rate 2`` (``--realtime`` where the OS grants SCHED_FIFO) to a
receiving node in its own process (``python -m euc_ros.bench.play receive``, itself at SCHED_FIFO
when allowed, so that what is measured is the player and the transport). Per message:

* **publish error**: when the player's ``publish`` returned (its ``--timing-log``) minus when it was
  due (recorded offset / rate from the first message), the constant offset removed with the median;
* **arrival error**: the same for the arrival at the receiver (player + DDS + the receiving
  executor; both processes read the same CLOCK_MONOTONIC).

Figures: p99 of |error| for both, and the share of messages within 2 ms of their target (the
replay's contract). **Floor:** a bare loop in a fresh interpreter that waits for the same
schedule the same way (sleep until 1 ms before, spin the rest), at the player's priority, and does
nothing else: the scheduling jitter of the machine under its current load, which no player can beat.

These are timings, so they live here and not in the tests (the tests check that every message is
played, in order, with its recorded stamp and the computed schedule: ``test/integration/test_play.py``).
"""
from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from euc_ros.bench.common import BenchContext, BenchError, PeakRssSampler, figure
from euc_ros.core.io.bags import BagWriter, posestamped_cdr
from euc_ros.sched import set_realtime

#: Messages per played bag: full and --quick.
N_MESSAGES = {False: 1000, True: 100}
#: Rate factors played.
RATES = (1.0, 2.0)
#: The replay's per-message contract [s].
TOLERANCE_S = 0.002
#: Busy-wait margin of the floor loop [s] (the player's BUSY_WAIT_S).
FLOOR_SPIN_S = 0.001
T0_NS = 1_714_644_900 * 10**9


def write_bag(path: Path, n: int, seed: int = 8) -> np.ndarray:
    """The played bag: ``n`` PoseStamped on ``/a`` spaced 3-20 ms; returns their stamps [ns]."""
    rng = np.random.default_rng(seed)
    stamps = T0_NS + np.cumsum(np.concatenate([[0], rng.uniform(0.003, 0.020, n - 1)]) * 1e9).astype(np.int64)
    cdr = posestamped_cdr(stamps, np.arange(n)[:, None] * [1.0, 0, 0], np.tile([0, 0, 0, 1.0], (n, 1)))
    with BagWriter(path) as w:
        for s, c in zip(stamps.tolist(), cdr):
            w.write_raw("/a", "geometry_msgs/msg/PoseStamped", c, s)
    return stamps


def timing_errors(times_s: np.ndarray, stamps_ns: np.ndarray, rate: float) -> np.ndarray:
    """Offset of each time from the first minus the recorded offset / rate, minus the median [s]."""
    t = np.asarray(times_s, float)
    err = (t - t[0]) - (np.asarray(stamps_ns) - stamps_ns[0]) * 1e-9 / rate
    return err - np.median(err)


def summary_ms(err_s: np.ndarray) -> dict:
    """p50, p99, max of |error| [ms] and the fraction within :data:`TOLERANCE_S`."""
    a = np.abs(np.asarray(err_s, float))
    return {"p50": float(np.median(a) * 1e3), "p99": float(np.percentile(a, 99) * 1e3), "max": float(a.max() * 1e3),
            "within_2ms": float(np.mean(a < TOLERANCE_S)), "n": int(a.size)}


def measure_floor(stamps_ns: list[int], rate: float, realtime: bool = True) -> dict:
    """Wait for the schedule of ``stamps_ns`` / ``rate`` as the player does, publishing nothing.

    With ``realtime`` the loop asks for SCHED_FIFO as ``euc-ros play --realtime`` does (same priority).
    Returns the summary of the wake-up errors (:func:`summary_ms`) and ``priority``.
    """
    priority = set_realtime(10, "playing") if realtime else "normal priority"
    stamps = np.asarray(stamps_ns, dtype=np.int64)
    offsets = (stamps - stamps[0]) * 1e-9 / rate
    done = np.empty(stamps.size)
    t0 = time.perf_counter()
    for i, off in enumerate(offsets):
        target = t0 + off
        while True:
            remaining = target - time.perf_counter()
            if remaining <= 0:
                break
            if remaining > FLOOR_SPIN_S:
                time.sleep(remaining - FLOOR_SPIN_S)
        done[i] = time.perf_counter()
    return {**summary_ms(timing_errors(done, stamps, rate)), "priority": priority}


def _read_timing_log(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    stamps = np.genfromtxt(path, delimiter=",", skip_header=1, usecols=(0,), dtype=np.int64, ndmin=1)
    data = np.genfromtxt(path, delimiter=",", skip_header=1, usecols=(2, 3), dtype=np.float64, ndmin=2)
    return stamps, data[:, 0], data[:, 1]


def measure_rate(bag: Path, stamps: np.ndarray, rate: float, out_dir: Path, timeout_s: float = 120.0) -> dict:
    """Play ``bag`` at ``rate`` to a receiver process; returns publish and arrival summaries and peak RSS."""
    log, arrivals_csv = out_dir / f"timing_{rate:g}.csv", out_dir / f"arrivals_{rate:g}.csv"
    rx = subprocess.Popen([sys.executable, "-m", "euc_ros.bench.play", "receive", "/a", str(stamps.size),
                           str(arrivals_csv)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    player = None
    try:
        with PeakRssSampler() as rss:
            rss.add("receiver", rx.pid)
            ready = rx.stdout.readline()
            if not ready.startswith("ready"):
                raise BenchError(f"play receiver did not start: {ready}{rx.stdout.read()}")
            player = subprocess.Popen([sys.executable, "-m", "euc_ros.cli.main", "play", str(bag), "--rate", str(rate),
                                       "--topics", "/a", "--timing-log", str(log), "--realtime"],
                                      stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
            rss.add("euc-ros play", player.pid)
            out, _ = player.communicate(timeout=timeout_s)
            rx_out, _ = rx.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        raise BenchError(f"play at rate {rate:g} did not finish within {timeout_s:g} s") from None
    finally:
        for p in (player, rx):
            if p is not None and p.poll() is None:
                p.kill()
                p.communicate()
    if player.returncode != 0 or not log.exists() or not arrivals_csv.exists():
        raise BenchError(f"play at rate {rate:g} failed (exit {player.returncode}): {out.strip()[-300:]} "
                         f"{rx_out.strip()[-300:]}")
    log_stamps, target, published = _read_timing_log(log)
    rows = np.loadtxt(arrivals_csv, delimiter=",", dtype=np.float64, ndmin=2)
    got = np.loadtxt(arrivals_csv, delimiter=",", usecols=(1,), dtype=np.int64, ndmin=1)
    if log_stamps.tolist() != stamps.tolist() or got.tolist() != stamps.tolist():
        raise BenchError(f"play at rate {rate:g}: {got.size} of {stamps.size} messages received, "
                         f"{log_stamps.size} published (or out of order)")
    arrivals = rows[:, 0]
    slope = float(np.polyfit((stamps - stamps[0]) * 1e-9, arrivals - arrivals[0], 1)[0])
    return {"rate": rate, "realtime_player": "SCHED_FIFO" in out, "realtime_receiver": "realtime" in ready,
            "publish": summary_ms(timing_errors(published, stamps, rate)),
            "arrival": summary_ms(timing_errors(arrivals, stamps, rate)),
            "rate_error": slope * rate - 1.0, "peak_rss_mb": rss.peaks_mb()}


def run(ctx: BenchContext) -> dict:
    """Benchmark 8 (see the module docstring)."""
    t_start = time.monotonic()
    n = N_MESSAGES[ctx.quick]
    bag = ctx.tmp_dir / "play_bag"
    stamps = write_bag(bag, n)
    figures, details, peaks = [], {}, {}
    for rate in RATES:
        ctx.log(f"[bench] play: rate {rate:g}, {n} messages")
        res = measure_rate(bag, stamps, rate, ctx.tmp_dir)
        floor = ctx.isolated("euc_ros.bench.play:measure_floor", stamps_ns=stamps.tolist(), rate=rate,
                             realtime=res["realtime_player"])
        pub, arr = res["publish"], res["arrival"]
        rt = f"player {'SCHED_FIFO' if res['realtime_player'] else 'normal priority'}, receiver " \
             f"{'SCHED_FIFO' if res['realtime_receiver'] else 'normal priority'}"
        figures += [
            figure(f"x{rate:g} publish timing error p99", pub["p99"], "ms", floor=floor["p99"],
                   note=f"p50 {pub['p50']:.3f} ms, max {pub['max']:.2f} ms ({rt}); floor: a bare wait loop on the "
                        f"same schedule, max {floor['max']:.2f} ms"),
            figure(f"x{rate:g} arrival timing error p99", arr["p99"], "ms", floor=floor["p99"],
                   note=f"p50 {arr['p50']:.3f} ms, max {arr['max']:.2f} ms; rate error {res['rate_error']:+.1e}"),
            figure(f"x{rate:g} arrivals within 2 ms", 100.0 * arr["within_2ms"], "%", target="100 %",
                   met=arr["within_2ms"] == 1.0,
                   note=f"{n} messages, all received in order; publish within 2 ms: {100 * pub['within_2ms']:.1f} %"),
        ]
        details[f"x{rate:g}"] = {**res, "floor": floor}
        peaks.update({f"{k} x{rate:g}": v for k, v in res["peak_rss_mb"].items()})
        peaks[f"floor loop x{rate:g}"] = floor["peak_rss_mb"]
    return {"name": "play", "title": "Replay timing of euc-ros play (per message, recorded timing x rate)",
            "figures": figures, "peak_rss_mb": peaks, "details": details, "wall_s": time.monotonic() - t_start}


#: The receiving node (``python -m euc_ros.bench.play receive TOPIC N OUT``): SCHED_FIFO when allowed, set
#: before rclpy starts its threads so the DDS threads inherit it; writes ``perf_counter,stamp_ns`` per message.
def _receive(topic: str, n: int, out: str, timeout_s: float = 60.0) -> int:
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(10))
        rt = "realtime"
    except (AttributeError, OSError):
        rt = "normal"
    import rclpy
    from geometry_msgs.msg import PoseStamped
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    rclpy.init()
    node = rclpy.create_node("play_timing_receiver")
    got = []
    node.create_subscription(PoseStamped, topic, lambda raw: got.append((time.perf_counter(), raw[4:12])),
                             QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE), raw=True)
    print("ready", rt, flush=True)
    deadline = time.monotonic() + timeout_s
    while len(got) < n and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.05)
    with open(out, "w", encoding="utf-8") as fh:
        for t, b in got:
            sec, nsec = int.from_bytes(b[:4], "little", signed=True), int.from_bytes(b[4:], "little")
            fh.write(f"{t:.9f},{sec * 10**9 + nsec}\n")
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    if len(sys.argv) == 5 and sys.argv[1] == "receive":
        sys.exit(_receive(sys.argv[2], int(sys.argv[3]), sys.argv[4]))
    print("usage: python -m euc_ros.bench.play receive TOPIC N OUT", file=sys.stderr)
    sys.exit(2)
