"""`euc-ros demo`: the main job end to end, on a generated ride with an effect nobody declared.

1. simulate a ride (ride simulator; the effect is hidden in the truth file, not in the session);
2. stream one run live through the pipeline, each node its own process over DDS:
   mocap_ingest (CSV replay) -> rider_state -> torque_estimator -> monitor, all recorded by recorder;
3. read the bag back and summarise it;
4. run a steering maneuver of the autonomous unicycle in closed loop over topics;
5. identify h offline (Figs 6-8 style figures);
6. trace the residual M_d1 - M_d2 to the missing effect and report the error before and after;
7. identify again with the selected effect in the model, and replay the run live with the extended
   torque_estimator, so the live residual drops too.
"""
from __future__ import annotations

import argparse
import io
import json
import shutil
import time
from pathlib import Path

import numpy as np

from euc_ros.cli.main import main as cli_main
from euc_ros.cli.outputs import Output, check_outputs
from euc_ros.core.io.bags import check_bag, read_bag
from euc_ros.core.residual.names import library_effects
from euc_ros.ros.launcher import NodeSpec, run

HELP = "run the main job end to end: simulate, stream live, record, identify, trace the residual, steer"

DEFAULT_EFFECT = ("ground_slope", "alpha_deg=2.5")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``euc-ros demo``."""
    parser.add_argument("--out", default="demo_out", help="output directory (default: ./demo_out)")
    parser.add_argument("--effect", default=DEFAULT_EFFECT[0], help=f"hidden effect to simulate ({DEFAULT_EFFECT[0]})")
    parser.add_argument("--param", action="append", default=None, metavar="NAME=VALUE",
                        help=f"effect parameter (default {DEFAULT_EFFECT[1]})")
    parser.add_argument("--seed", type=int, default=7, help="random seed of the ride (7)")
    parser.add_argument("--runs", type=int, default=3, help="runs to simulate (3)")
    parser.add_argument("--rate-factor", type=float, default=2.0, help="live replay speed (2x real time)")
    parser.add_argument("--skip-live", action="store_true", help="skip the live pipeline steps")
    parser.add_argument("--skip-steer", action="store_true", help="skip the unicycle maneuver")


#: What the live replay waits for before its first frame, besides its 3 s ``start_delay``: the
#: subscriptions mocap/frame has matched (recorder, monitor, rider_state) and /tf has matched
#: (recorder), and the subscriptions the ROS graph lists on rider/state (torque_estimator, monitor,
#: recorder) and euc/torque (monitor, recorder). Start-up times vary by seconds on a loaded host: a
#: fixed delay alone loses the first messages of whichever node comes up last. How soon rider_state's
#: and torque_estimator's publishers match their subscribers is not visible to the replay: they match
#: within the ``start_delay`` when the nodes come up together; when one comes up seconds after the
#: others, the first states or torques may still be missed (frames never are).
LIVE_WAITS = {"wait_subscribers": 3, "wait_topics": ["/tf=1", "rider/state=3", "euc/torque=2"]}


def _step(n: int, text: str) -> None:
    print(f"\n=== [{n}] {text}", flush=True)


def _cli(argv: list[str]) -> int:
    print("$ euc-ros " + " ".join(argv), flush=True)
    code = cli_main(argv)
    if code != 0:
        raise SystemExit(f"demo: 'euc-ros {' '.join(argv)}' failed with exit code {code}")
    return code


def _live(out: Path, csv: Path, session: Path, h: float, rate_factor: float, extra: dict | None = None) -> Path:
    """Run the live pipeline on one CSV; returns the path of a bag that holds every frame of it.

    The replay starts once every consumer is there (:data:`LIVE_WAITS`) and ends once every subscriber
    has every frame; every node is required, so a node that dies ends the run with an error instead of
    leaving the replay waiting for it or a bag with a hole.
    """
    config = Path(__file__).resolve().parents[2] / "config"
    bag = out
    if bag.exists():
        shutil.rmtree(bag)
    te_params = {"session_file": str(session), "h": float(h)}
    te_params.update(extra or {})
    specs = [
        NodeSpec("recorder", params_file=str(config / "recorder.yaml"), parameters={"output": str(bag)}),
        NodeSpec("monitor", params_file=str(config / "monitor.yaml")),
        NodeSpec("torque_estimator", params_file=str(config / "torque_estimator.yaml"), parameters=te_params),
        NodeSpec("rider_state", params_file=str(config / "rider_state.yaml"),
                 parameters={"session_file": str(session)}),
        NodeSpec("mocap_ingest", params_file=str(config / "mocap_ingest.yaml"),
                 parameters={"csv_path": str(csv), "rate_factor": rate_factor, "exit_when_done": True,
                             "start_delay": 3.0, "linger": 1.5, **LIVE_WAITS}),
    ]
    log = io.StringIO()
    t0 = time.monotonic()
    code = run(specs, stream=log)
    lines = [ln for ln in log.getvalue().splitlines() if "[INFO]" in ln or "error" in ln.lower() or "closed" in ln]
    print("\n".join("  " + ln for ln in lines[-12:]))
    print(f"  live pipeline ran {time.monotonic() - t0:.1f} s, exit code {code}")
    if code != 0:
        raise SystemExit("demo: the live pipeline failed (see the log above)")
    return bag


def _bag_summary(bag: Path) -> dict:
    problems = check_bag(bag)
    counts: dict[str, int] = {}
    res, rmse = [], []
    for topic, _, _, msg in read_bag(bag):
        counts[topic] = counts.get(topic, 0) + 1
        if topic.endswith("euc/torque") and msg.valid:
            res.append(msg.residual)
            rmse.append(msg.rmse_window)
    summary = {"bag": str(bag), "structural_check": "OK" if not problems else problems, "counts": counts}
    if res:
        summary["live_residual_rms_nm"] = float(np.sqrt(np.mean(np.square(res))))
        summary["live_sliding_rmse_last_nm"] = float(rmse[-1])
    for k, v in summary.items():
        print(f"  {k}: {v}")
    return summary


def main(args: argparse.Namespace) -> int:
    """Run the demo; prints where every output is."""
    check_outputs([Output("--out", args.out, "dir")])
    out = Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    ride = out / "ride"
    params = args.param or [DEFAULT_EFFECT[1]] if args.effect == DEFAULT_EFFECT[0] else (args.param or [])
    t_start = time.monotonic()

    _step(1, f"simulate a ride with a hidden effect ({args.effect})")
    sim = ["simulate-ride", "--maneuver", "deceleration", "--runs", str(args.runs), "--seed", str(args.seed),
           "--out", str(ride), "--overwrite"]
    if args.effect and args.effect != "none":
        sim += ["--effect", args.effect] + [x for p in params for x in ("--param", p)]
    _cli(sim)
    session = ride / "session.yaml"
    csvs = sorted(ride.glob("deceleration_*.csv"))

    results: dict = {}
    if not args.skip_live:
        _step(2, "live: mocap_ingest -> rider_state -> torque_estimator -> monitor, recorded (separate processes)")
        bag = _live(out / "live_bag", csvs[0], session, 0.61, args.rate_factor)
        _step(3, "read the bag back")
        results["live_before"] = _bag_summary(bag)

    if not args.skip_steer:
        _step(4, "autonomous unicycle: lane change at 1 m/s in closed loop over topics")
        _cli(["steer", "--maneuver", "lane_change", "--speed", "1.0", "--out", str(out / "steer"), "--overwrite",
              "--json", str(out / "steer.json")])

    _step(5, "identify h offline (EUC paper Section 4)")
    _cli(["identify", str(session), *map(str, csvs), "--json", str(out / "identify.json"),
          "--plots", str(out / "identify"), "--no-progress"])

    _step(6, "trace the residual M_d1 - M_d2 to the missing effect")
    _cli(["residual", str(session), *map(str, csvs), "--json", str(out / "residual.json"),
          "--plots", str(out / "residual"), "--report", str(out / "residual" / "report.md"), "--no-progress"])
    residual = json.loads((out / "residual.json").read_text())
    truth = json.loads((ride / "truth" / "truth.json").read_text())
    print(f"  hidden truth: {truth['effect']} {truth['effect_parameters']}, h = {truth['h_m']} m")
    print(f"  found:        {residual['effect']} {residual['effect_parameters']}, h = {residual['h_after_m']:.3f} m")

    _step(7, "the extended model: identify again, and stream live with the effect configured")
    _cli(["identify", str(session), *map(str, csvs), "--from-residual", str(out / "residual.json"),
          "--json", str(out / "identify_extended.json"), "--no-progress"])
    effects = library_effects(residual["effect"])
    if not args.skip_live and effects:
        # the residual's JSON is the live model as it is: h, effects and parameters (model:=residual.json)
        print(f"$ euc-ros launch pipeline.launch.xml session:={session} model:={out / 'residual.json'} ...", flush=True)
        bag2 = _live(out / "live_bag_extended", csvs[0], session, 0.0, args.rate_factor,
                     {"model": str(out / "residual.json")})
        results["live_after"] = _bag_summary(bag2)

    print(f"\n=== done in {time.monotonic() - t_start:.0f} s. Outputs in {out}:")
    for p in sorted(out.rglob("*")):
        if p.suffix in (".png", ".json", ".md") or p.name == "metadata.yaml":
            print(f"  {p.relative_to(out)}")
    results["residual"] = {k: residual[k] for k in ("effect", "effect_parameters", "h_m", "h_after_m",
                                                     "rmse_before_nm", "rmse_after_nm")}
    results["truth"] = {"effect": truth["effect"], "effect_parameters": truth["effect_parameters"], "h_m": truth["h_m"]}
    (out / "demo_summary.json").write_text(json.dumps(results, indent=2, default=str) + "\n")
    print(f"\n=== closing the loop: hidden {truth['effect']} {truth['effect_parameters']}; found {residual['effect']} "
          f"{ {k: round(v, 4) for k, v in residual['effect_parameters'].items()} }")
    print(f"    held-out RMSE of M_d1 - M_d2: {residual['rmse_before_nm']:.2f} -> {residual['rmse_after_nm']:.2f} N m; "
          f"h {residual['h_m']:.3f} -> {residual['h_after_m']:.3f} m (true {truth['h_m']} m)")
    if "live_before" in results and "live_after" in results:
        print(f"    live residual RMS: {results['live_before'].get('live_residual_rms_nm', float('nan')):.2f} -> "
              f"{results['live_after'].get('live_residual_rms_nm', float('nan')):.2f} N m")
    return 0
