"""The live pipeline's torques from two source trees, compared message by message on one recording.

Each tree runs the same input through its own nodes (separate processes over DDS, on a ROS domain of
their own) with ``PYTHONPATH`` set to the tree, so the node console scripts of the shared environment
run that tree's code:

* ``--bag``: the bag's ``/mocap/frame`` replayed (``euc-ros play``) into rider_state ->
  torque_estimator, with a recorder (the nodes of ``launch/replay.yaml`` but the monitor);
* ``--csv``: a Motive CSV through the whole live pipeline (mocap_ingest with ``source: csv`` and
  ``stamp_mode: file``, so the frames' stamps do not depend on the wall clock -> rider_state ->
  torque_estimator, recorder).

The producer (player or mocap_ingest) starts once the other nodes are up, so that a slow start on a
loaded host cannot cost the first frames (``launch/replay.yaml`` starts everything at once and waits
for two of the three subscriptions of ``mocap/frame``).

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
import signal
import subprocess
import sys
import time
from pathlib import Path

TOPICS = ("/euc/torque", "/rider/state", "/mocap/frame")
#: Compared too when the CSV goes through mocap_ingest.
CSV_TOPICS = ("/euc/torque", "/rider/state", "/mocap/frame", "/tf")
TIMEOUT_S = 600


def parse_tree(text: str) -> tuple[str, Path, dict]:
    """``label=path[:VAR=value...]`` -> (label, path, extra environment)."""
    label, _, rest = text.partition("=")
    path, *assignments = rest.split(":")
    env = dict(a.split("=", 1) for a in assignments)
    return label, Path(path).resolve(), env


def consumers_yaml(tree: Path, session: Path, out: Path, topics) -> Path:
    """A launch YAML of the tree's recorder, torque_estimator and rider_state, recording ``topics`` into ``out``."""
    import json

    cfg = tree / "config"
    nodes = [
        {"executable": "recorder", "required": False, "params_file": str(cfg / "recorder.yaml"),
         "parameters": {"output": str(out), "topics": list(topics)}},
        {"executable": "torque_estimator", "required": False, "params_file": str(cfg / "torque_estimator.yaml"),
         "parameters": {"session_file": str(session)}},
        {"executable": "rider_state", "required": False, "params_file": str(cfg / "rider_state.yaml"),
         "parameters": {"session_file": str(session)}},
    ]
    path = out.parent / f"{out.name}.launch.yaml"
    path.write_text(json.dumps({"nodes": nodes}, indent=1), encoding="utf-8")   # JSON is YAML
    return path


#: What each consumer logs once its subscriptions exist.
READY = (("[rider_state]", "session "), ("[torque_estimator]", "model "), ("[recorder]", "recording to"))


def run_tree(tree: Path, extra_env: dict, session: Path, out: Path, domain: int, *, bag: Path | None = None,
             csv: Path | None = None) -> float:
    """Run the bag (player) or the CSV (mocap_ingest, file stamps) into the tree's nodes, recording into ``out``.

    The consumers start first; the producer starts once each has logged that it is up and waits for the
    recorder's and rider_state's subscriptions (then 2 s), so no frame is missed by a slow start.
    Returns the wall time [s].
    """
    env = dict(os.environ)
    env.pop("EUC_ROS_PUBLIC_EXECUTOR", None)          # only a tree's own setting applies
    env.update(PYTHONPATH=str(tree), ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", **extra_env)
    bindir = Path(sys.executable).parent
    log_path = out.parent / f"{out.name}.log"
    t0 = time.monotonic()
    with open(log_path, "w", encoding="utf-8") as log:
        launch = subprocess.Popen([str(bindir / "euc-ros"), "launch",
                                   str(consumers_yaml(tree, session, out, CSV_TOPICS if csv else TOPICS))],
                                  env=env, cwd=tree, stdout=log, stderr=subprocess.STDOUT, text=True)
        try:
            deadline = time.monotonic() + 120
            while not all(any(n in line and w in line for line in log_path.read_text().splitlines()) for n, w in READY):
                if launch.poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError(f"the nodes of {tree} did not start; log {log_path}")
                time.sleep(0.2)
            if bag is not None:
                cmd = [str(bindir / "euc-ros"), "play", str(bag), "--topics", "mocap/frame", "--wait-subscribers", "2",
                       "--delay", "2.0", "--linger", "3.0"]
            else:
                cfg = tree / "config"
                cmd = [str(bindir / "mocap_ingest"), "--ros-args", "--params-file", str(cfg / "mocap_ingest.yaml"),
                       "-p", "source:=csv", "-p", f"csv_path:={csv}", "-p", f"session_file:={session}",
                       "-p", "stamp_mode:=file", "-p", "wait_subscribers:=2", "-p", "start_delay:=0.0",
                       "-p", "exit_when_done:=true", "-p", "linger:=3.0"]
            producer = subprocess.run(cmd, env=env, cwd=tree, capture_output=True, text=True, timeout=TIMEOUT_S)
            log.write(producer.stdout + producer.stderr)
            if producer.returncode != 0:
                raise RuntimeError(f"{cmd[1]} in {tree} failed ({producer.returncode}); log {log_path}")
        finally:
            launch.send_signal(signal.SIGINT)
            launch.wait(timeout=60)
    if launch.returncode != 0:
        raise RuntimeError(f"the nodes of {tree} exited with {launch.returncode}; log {log_path}")
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
            differs = "" if c["identical"] else f", first difference at {c['first_difference']}"
            print(f"{label} vs {ref_label} {topic}: {c['bit_identical']}/{c['reference']} messages bit-identical"
                  f" ({c['messages']} recorded){differs}")
            ok &= c["identical"] or topic != "/euc/torque"
    print("torques bit-identical" if ok else "torques DIFFER")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
