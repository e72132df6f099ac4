"""Recordings the benchmarks run on, generated once by the ride simulator and cached.

A recording is one figure-eight run of the given length (14 rigid bodies: the EUC and 13 rider
segments, 120 Hz, the simulator's default measurement noise) written as a Motive CSV with its
``session.yaml`` and, on request, as a rosbag2 MCAP bag (``write_mocap_bag``: one MocapFrame and
one PoseStamped per tracked body per frame). The cache directory is keyed by maneuver, length and
seed; a partly written entry is never used (it is built in a temporary directory and renamed).
"""
from __future__ import annotations

import shutil
from pathlib import Path

from euc_ros.core.io.bags import write_mocap_bag

#: Bump when the generated content changes so stale caches are not reused.
CACHE_VERSION = 1
#: Seed of every benchmark recording.
SEED = 11


def ride_recording(cache_dir: Path, duration_s: float, *, bag: bool = False, maneuver: str = "figure_eight",
                   log=None) -> dict[str, Path]:
    """Return ``{"dir", "csv", "session", "bag"?}`` of a cached simulated recording, generating it if needed.

    Parameters
    ----------
    cache_dir : Path
        Cache root.
    duration_s : float
        Recording length [s].
    bag : bool
        Also provide the recording as a bag (``write_mocap_bag``).
    maneuver : str
        Ride simulator maneuver.
    """
    root = Path(cache_dir) / f"{maneuver}_{int(round(duration_s))}s_seed{SEED}_v{CACHE_VERSION}"
    csv = root / f"{maneuver}_01.csv"
    session = root / "session.yaml"
    if not csv.exists():
        if log:
            log(f"  generating a {duration_s:g} s {maneuver} recording into {root} (once)")
        from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
        from euc_ros.core.ridesim.writers import write_ride

        tmp = root.with_name(root.name + ".partial")
        shutil.rmtree(tmp, ignore_errors=True)
        ride = simulate_ride(RideConfig(maneuver=maneuver, runs=1, seed=SEED, duration_s=float(duration_s)))
        write_ride(ride, tmp)
        shutil.rmtree(root, ignore_errors=True)
        tmp.rename(root)
    out = {"dir": root, "csv": csv, "session": session}
    if bag:
        bag_dir = root / "bag"
        if not (bag_dir / "metadata.yaml").exists():
            if log:
                log(f"  converting {csv.name} to a bag (once)")
            from euc_ros.core.io.motive_csv import read_motive_csv

            shutil.rmtree(bag_dir, ignore_errors=True)   # metadata.yaml is written last: complete when present
            write_mocap_bag(read_motive_csv(csv, world_up="y"), bag_dir)
        out["bag"] = bag_dir
    return out
