"""Benchmark: per-frame cost of the live skeleton CoG (``cog_method: skeleton``) at 14 bodies.

:class:`~euc_ros.core.states.skeleton.OnlineSkeleton` ``update`` (faults, the chain fit, G) called once per
frame, as ``rider_state`` calls it, on the 10 s figure-eight recording (14 rigid bodies, 120 Hz), with the
chain estimated from the first 240 frames (the live calibration's default) and frozen, so the figure is
the steady state after the calibration. The numpy reference of the same fit
(``skeleton_cog(..., method="reference")``) is measured beside it on the first frames. **Floor:** the
per-segment CoG of the same frames (``frame_geometry`` with ``cog_method="segments"``: what the live
estimator computes per frame without the chain). **Target:** at most 1 ms per frame, so that
``rider_state`` keeps up at 360 Hz (2.8 ms per frame) with the rest of its work.

Each measurement runs in a fresh interpreter pinned to one CPU after untimed warm-up frames (the compiled
kernel loaded from its cache), three times (per-frame median of each pass); the figure is the median.
"""
from __future__ import annotations

import statistics
import time
from pathlib import Path

from euc_ros.bench.common import BenchContext, figure, pinned_to_one_core

#: Timed frames per pass (full, --quick), and of the numpy reference (slow: a few per pass suffice).
FRAMES = {False: 900, True: 300}
REFERENCE_FRAMES = {False: 60, True: 20}
REPEATS = 3
CALIBRATION_FRAMES = 240
#: Per-frame target of the live skeleton CoG [ms].
TARGET_MS = 1.0


def measure(csv: str, session_file: str, method: str, frames: int, repeats: int = REPEATS) -> dict:
    """Per-frame wall time of one CoG method on one core: ``{"ms_per_frame": [...], "frames", "bodies"}``.

    ``method``: ``skeleton`` (OnlineSkeleton, compiled), ``reference`` (the numpy skeleton fit) or ``segments``
    (the per-segment CoG, the floor). Each pass times ``frames`` frames after the calibration frames.
    """
    import numpy as np

    from euc_ros.core.io.recordings import load_recording
    from euc_ros.core.session import load_session
    from euc_ros.core.states.geometry import frame_geometry
    from euc_ros.core.states.skeleton import OnlineSkeleton, SkeletonModel, skeleton_cog

    session = load_session(Path(session_file))
    s = load_recording(Path(csv), world_up=session.world_up)
    model = SkeletonModel.estimate(s, session, max_frames=CALIBRATION_FRAMES)
    live = OnlineSkeleton(session, model=model)
    bodies = list(s.bodies)
    if method == "skeleton":
        def one(k):
            live.update(s.position[:, k], s.quat[:, k], s.tracked[:, k], bodies)
    elif method == "reference":
        def one(k):
            skeleton_cog(s.position[:, k], s.quat[:, k], s.tracked[:, k], session, bodies, model, method="reference")
    else:
        def one(k):
            frame_geometry(s.position[:, k], s.quat[:, k], s.tracked[:, k], session, bodies)
    start = CALIBRATION_FRAMES
    if s.n_frames < start + frames + 5:
        raise ValueError(f"{s.n_frames} frames: {start + frames + 5} needed")
    for k in range(start - 5, start):           # warm-up: the kernel, the plan, the caches
        one(k)
    per_frame = []
    with pinned_to_one_core():
        for _ in range(repeats):
            t = np.empty(frames)
            for j, k in enumerate(range(start, start + frames)):
                t0 = time.perf_counter()
                one(k)
                t[j] = time.perf_counter() - t0
            per_frame.append(float(np.median(t)) * 1e3)
    return {"ms_per_frame": per_frame, "frames": frames, "bodies": len(bodies)}


def run(ctx: BenchContext) -> dict:
    """The live skeleton CoG benchmark (see the module docstring)."""
    from euc_ros.bench.data import ride_recording

    t_start = time.monotonic()
    rec = ride_recording(ctx.cache_dir, 10.0, log=ctx.log)
    n, n_ref = FRAMES[ctx.quick], REFERENCE_FRAMES[ctx.quick]
    ctx.log(f"  {n} frames x {REPEATS} passes")
    args = {"csv": str(rec["csv"]), "session_file": str(rec["session"])}
    fast = ctx.isolated("euc_ros.bench.skeleton:measure", method="skeleton", frames=n, **args)
    ref = ctx.isolated("euc_ros.bench.skeleton:measure", method="reference", frames=n_ref, **args)
    floor = ctx.isolated("euc_ros.bench.skeleton:measure", method="segments", frames=n, **args)
    med = {k: statistics.median(v["ms_per_frame"]) for k, v in (("fast", fast), ("ref", ref), ("floor", floor))}

    def spread(r):
        return f"{min(r['ms_per_frame']):.3f}-{max(r['ms_per_frame']):.3f} ms over {len(r['ms_per_frame'])} passes"

    figures = [
        figure(f"live skeleton CoG per frame ({fast['bodies']} bodies, compiled)", med["fast"], "ms",
               floor=med["floor"], target=f"<= {TARGET_MS:g} ms", met=med["fast"] <= TARGET_MS,
               note=f"median of per-frame medians, {spread(fast)}; per-segment CoG (floor) {spread(floor)}"),
        figure("skeleton CoG per frame, numpy reference", med["ref"], "ms", floor=med["floor"],
               note=f"{n_ref} frames per pass, {spread(ref)}; compiled {med['ref'] / med['fast']:.0f}x faster"),
    ]
    return {"name": "skeleton", "title": "Live skeleton CoG per frame (one core)", "figures": figures,
            "peak_rss_mb": {"compiled": fast["peak_rss_mb"], "reference": ref["peak_rss_mb"],
                            "segments (floor)": floor["peak_rss_mb"]},
            "details": {"compiled": fast, "reference": ref, "segments": floor},
            "wall_s": time.monotonic() - t_start}
