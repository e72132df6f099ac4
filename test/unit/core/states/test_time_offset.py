"""The rider-to-EUC time offset measured from the ankles on the pedals, on two independent generators."""
from __future__ import annotations

from pathlib import Path

import pytest

from euc_ros.core.io.motive_csv import read_motive_csv
from euc_ros.core.ridesim import RideConfig, make_effects, simulate_ride, write_ride
from euc_ros.core.session import load_session
from euc_ros.core.states.time_offset import FLOOR_MS, measure_time_offset


def _ridesim(tmp_path: Path, dt_ms: float):
    eff = make_effects(["mocap_time_offset"], {"dt_ms": dt_ms})
    write_ride(simulate_ride(RideConfig(runs=2, seed=5, duration_s=7.0, effects=eff)), tmp_path)
    sess = load_session(next(tmp_path.rglob("session.yaml")))
    csvs = sorted(p for p in tmp_path.rglob("*.csv") if "truth" not in str(p))
    return measure_time_offset([read_motive_csv(c) for c in csvs], sess)


@pytest.mark.parametrize("dt_ms", [0.0, 0.6, 20.0, -12.0])
def test_the_projects_simulator_offset_is_measured(tmp_path, dt_ms):
    # the simulator stamps the rider's segments dt late (its own code path, not this measurement's)
    m = _ridesim(tmp_path, dt_ms)
    assert m is not None and set(m["links"]) == {"LL", "LR"}
    assert abs(m["dt_ms"] - dt_ms) <= 4 * m["se_ms"] + 0.05
    lo, hi = m["plausible_ms"]
    assert lo <= dt_ms <= hi and hi - lo >= 2 * FLOOR_MS


def test_the_independent_generator_without_offset_reads_zero(tmp_path):
    from euc_ros.core.worldsim import Capture
    from euc_ros.core.worldsim import simulate_ride as world_ride
    from euc_ros.core.worldsim import write_ride as world_write

    ride = world_ride(7, 120.0, duration=8.0)
    paths = world_write(ride, tmp_path, Capture(world_up="y", noise_pos_mm=0.2, noise_rot_deg=0.5), seed=3)
    sess = load_session(paths["session"])
    m = measure_time_offset([read_motive_csv(paths["csv"], world_up="y")], sess)
    assert m is not None
    assert abs(m["dt_ms"]) <= 4 * m["se_ms"] + 0.05
    lo, hi = m["plausible_ms"]
    # a speed-shaped force fitted as a time offset of a frame or more (8.3 ms at 120 Hz) is outside
    assert hi < 8.3 and lo > -8.3


def test_no_pedal_link_gives_no_measurement(tmp_path):
    from euc_ros.core.worldsim import Capture
    from euc_ros.core.worldsim import simulate_ride as world_ride
    from euc_ros.core.worldsim import write_ride as world_write

    ride = world_ride(7, 120.0, duration=4.0)
    paths = world_write(ride, tmp_path, Capture(world_up="y"), seed=3)
    sess = load_session(paths["session"])
    s = read_motive_csv(paths["csv"], world_up="y")
    keep = [i for i, b in enumerate(s.bodies) if b not in ("LR", "LL")]
    import dataclasses

    cut = dataclasses.replace(s, bodies=[s.bodies[i] for i in keep], position=s.position[keep], quat=s.quat[keep],
                              tracked=s.tracked[keep])
    assert measure_time_offset([cut], sess) is None
