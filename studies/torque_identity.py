"""The live pipeline's torques from two source trees, compared message by message on one recording.

Each tree runs the same input through its own nodes (separate processes over DDS, on a ROS domain of
their own) with ``PYTHONPATH`` set to the tree, so the node console scripts of the shared environment
run that tree's code:

* ``--bag``: the bag's ``/mocap/frame`` replayed through the tree's ``launch/replay.yaml`` (player ->
  rider_state -> torque_estimator, monitor, recorder);
* ``--csv``: a Motive CSV through the whole live pipeline (mocap_ingest with ``source: csv`` and
  ``stamp_mode: file``, so the frames' stamps do not depend on the wall clock -> rider_state ->
  torque_estimator, recorder).

The recorded messages are compared as their CDR bytes: equal bytes are equal stamps, frame ids,
strings and float64 values bit for bit.

Usage::

    python studies/torque_identity.py --bag RIDE_BAG --session session.yaml --out DIR \\
        --tree before=/path/to/old/tree --tree after=. [--tree after_public=.:EUC_ROS_PUBLIC_EXECUTOR=1]
    python studies/torque_identity.py --csv RIDE.csv --session session.yaml --out DIR --tree ... --tree ...

The first tree is the reference. Exit code 0 when every tree's torques equal the reference's.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

TOPICS = ("/euc/torque", "/rider/state")
#: Compared too when the CSV goes through mocap_ingest.
CSV_TOPICS = ("/euc/torque", "/rider/state", "/mocap/frame", "/tf")
TIMEOUT_S = 600


def parse_tree(text: str) -> tuple[str, Path, dict]:
    """``label=path[:VAR=value...]`` -> (label, path, extra environment)."""
    label, _, rest = text.partition("=")
    path, *assignments = rest.split(":")
    env = dict(a.split("=", 1) for a in assignments)
    return label, Path(path).resolve(), env


def pipeline_yaml(tree: Path, csv: Path, session: Path, out: Path) -> Path:
    """A launch YAML of the tree's live pipeline on a CSV (file stamps), recording into ``out``."""
    import json

    cfg = tree / "config"
    nodes = [
        {"executable": "recorder", "required": False, "params_file": str(cfg / "recorder.yaml"),
         "parameters": {"output": str(out), "topics": list(CSV_TOPICS)}},
        {"executable": "torque_estimator", "required": False, "params_file": str(cfg / "torque_estimator.yaml"),
         "parameters": {"session_file": str(session)}},
        {"executable": "rider_state", "required": False, "params_file": str(cfg / "rider_state.yaml"),
         "parameters": {"session_file": str(session)}},
        {"executable": "mocap_ingest", "params_file": str(cfg / "mocap_ingest.yaml"),
         "parameters": {"source": "csv", "csv_path": str(csv), "session_file": str(session), "stamp_mode": "file",
                        "wait_subscribers": 2, "start_delay": 2.0, "exit_when_done": True, "linger": 3.0}},
    ]
    path = out.parent / f"{out.name}.launch.yaml"
    path.write_text(json.dumps({"nodes": nodes}, indent=1), encoding="utf-8")   # JSON is YAML
    return path


def run_tree(tree: Path, extra_env: dict, session: Path, out: Path, domain: int, *, bag: Path | None = None,
             csv: Path | None = None) -> float:
    """Run the bag (replay) or the CSV (live pipeline) through the tree, recording into ``out``; the wall time [s]."""
    exe = Path(sys.executable).parent / "euc-ros"
    env = dict(os.environ)
    env.pop("EUC_ROS_PUBLIC_EXECUTOR", None)          # only a tree's own setting applies
    env.update(PYTHONPATH=str(tree), ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", **extra_env)
    if bag is not None:
        cmd = [str(exe), "launch", str(tree / "launch" / "replay.yaml"), f"in_bag:={bag}", f"session:={session}",
               f"bag:={out}"]
    else:
        cmd = [str(exe), "launch", str(pipeline_yaml(tree, csv, session, out))]
    t0 = time.monotonic()
    run = subprocess.run(cmd, env=env, cwd=tree, capture_output=True, text=True, timeout=TIMEOUT_S)
    (out.parent / f"{out.name}.log").write_text(run.stdout + run.stderr, encoding="utf-8")
    if run.returncode != 0:
        raise RuntimeError(f"run in {tree} failed ({run.returncode}); log {out.parent / (out.name + '.log')}")
    return time.monotonic() - t0


def messages(bag: Path, topic: str) -> list[bytes]:
    """The CDR bytes of ``topic`` in the bag, in recorded order."""
    from euc_ros.core.io.bags import read_bag

    return [m for _, _, _, m in read_bag(bag, topics=[topic], raw=True)]


def compare(ref: list[bytes], got: list[bytes]) -> dict:
    """Count, equal messages and the first difference of two message lists."""
    same = sum(a == b for a, b in zip(ref, got))
    first = next((i for i, (a, b) in enumerate(zip(ref, got)) if a != b), None)
    return {"reference": len(ref), "messages": len(got), "bit_identical": same, "first_difference": first,
            "identical": len(ref) == len(got) and same == len(ref)}


def main(argv: list[str] | None = None) -> int:
    """Replay the bag through every tree and compare their torques with the first tree's."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    source = p.add_mutually_exclusive_group(required=True)
    source.add_argument("--bag", type=Path, help="bag with /mocap/frame, replayed into rider_state")
    source.add_argument("--csv", type=Path, help="Motive CSV, through mocap_ingest (file stamps)")
    p.add_argument("--session", type=Path, required=True, help="session YAML of the bag")
    p.add_argument("--tree", action="append", required=True, type=parse_tree,
                   help="label=path[:VAR=value...]; the first is the reference")
    p.add_argument("--out", type=Path, required=True, help="folder for the recorded bags and logs")
    args = p.parse_args(argv)
    topics = CSV_TOPICS if args.csv else TOPICS
    from domain_coordinator import domain_id

    args.out.mkdir(parents=True, exist_ok=True)
    recorded = {}
    with domain_id() as domain:
        for label, tree, extra in args.tree:
            out = args.out / label
            wall = run_tree(tree, extra, args.session.resolve(), out, int(domain),
                            bag=args.bag.resolve() if args.bag else None, csv=args.csv.resolve() if args.csv else None)
            recorded[label] = {t: messages(out, t) for t in topics}
            print(f"{label}: {tree}{' ' + str(extra) if extra else ''}: ran in {wall:.1f} s, "
                  + ", ".join(f"{t} {len(v)}" for t, v in recorded[label].items()), flush=True)
    (ref_label, *_), *others = args.tree
    ok = True
    for label, _, _ in others:
        for topic in topics:
            c = compare(recorded[ref_label][topic], recorded[label][topic])
            print(f"{label} vs {ref_label} {topic}: {c['bit_identical']}/{c['reference']} messages bit-identical"
                  f" ({c['messages']} recorded){'' if c['identical'] else ', first difference at ' + str(c['first_difference'])}")
            ok &= c["identical"] or topic != "/euc/torque"
    print("torques bit-identical" if ok else "torques DIFFER")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
