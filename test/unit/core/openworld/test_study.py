"""The open-world study's rides: their random streams, the filter's view of a law, calibration, the task
list, a ride's row and results.csv."""
from __future__ import annotations

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from euc_ros.core.errors import ConfigError
from euc_ros.core.openworld import study as st
from euc_ros.core.worldsim import forces as F


# -- the ride's draws ---------------------------------------------------------------------------------------------
def test_study_draws_respect_their_ranges():
    draws = np.array([[r.uniform(*st.ARTEFACT_MM), r.uniform(*F.RATIO_RANGE)]
                      for r in (st.ride_rng(s, f) for s in range(100) for f in st.FAMILIES)])
    assert draws[:, 0].min() >= 0 and draws[:, 0].max() <= 10 and draws[:, 0].max() > 9
    assert draws[:, 1].min() >= 0.2 and draws[:, 1].max() <= 0.5


def test_ride_stream_is_a_function_of_seed_and_family():
    a, b = st.ride_rng(7, "drift").uniform(size=3), st.ride_rng(7, "drift").uniform(size=3)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, st.ride_rng(7, "wheel").uniform(size=3))
    assert not np.array_equal(a, st.ride_rng(8, "drift").uniform(size=3))
    with pytest.raises(ConfigError, match="family"):
        st.ride_rng(7, "magnetic")


def test_seen_effect_passes_slow_laws_and_damps_fast_ones():
    t = np.arange(0.0, 10.0, 1.0 / st.RATE_HZ)
    slow, fast = np.sin(2 * np.pi * 0.2 * t), np.sin(2 * np.pi * 15.0 * t)
    assert F.rms(st.seen_effect(slow, st.RATE_HZ)) == pytest.approx(F.rms(slow), rel=1e-3)
    assert F.rms(st.seen_effect(fast, st.RATE_HZ)) < 0.1 * F.rms(fast)
    short = np.arange(5.0)                           # shorter than the filter's window: as it is
    assert np.array_equal(st.seen_effect(short, st.RATE_HZ), short)


# -- calibration ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("family,seed", [("speed", 3), ("dynamic", 5)])
def test_calibration_gives_the_target_ratio_along_the_ride_with_the_law(family, seed, tmp_path):
    """With a given floor, the law's effect along the ride with it gives the target ratio within the stated bound.

    The law is scaled along the ride without it, then corrected once along the ride with it (the controllers
    respond to the law): ``study.RATIO_TOLERANCE``, measured on tuning seeds.
    """
    r = st.make_ride(seed, family, tmp_path, duration=6.0, floor_fn=lambda *_: 0.4)
    # the first run is the one calibrated along; the others carry the same law over their own profiles
    assert abs(F.ratio_of(0.4, st._seen_rms([r["ride"]], st.RATE_HZ)) - r["ratio_target"]) <= st.RATIO_TOLERANCE
    assert len(r["csvs"]) == st.RUNS and len(r["rides"]) == st.RUNS
    assert all(rd.spec.force == r["law"] for rd in r["rides"])
    assert len({float(rd.truth["x_dot"][0]) for rd in r["rides"]}) == st.RUNS      # profiles of their own
    truth = json.loads(r["truth"].read_text(encoding="utf-8"))
    assert truth["force"]["family"] == family and len(truth["effect"]) == len(truth["t"])


# -- tasks and rows -------------------------------------------------------------------------------------------------
def test_tasks_take_the_first_seeds_of_the_set_per_family():
    got = st.tasks("report", 2, ("none", "drift"), duration=8.0)
    assert [(name, seed) for name, seed, _ in got] == [("none_001000", 1000), ("none_001001", 1001),
                                                       ("drift_001000", 1000), ("drift_001001", 1001)]
    assert got[-1][2] == {"family": "drift", "duration_s": 8.0, "rate_hz": st.RATE_HZ, "rtol": st.RTOL,
                          "design": "classic"}
    assert st.tasks("held-out", 1, ("none",))[0][2]["design"] == "lab"          # the next table is a lab's
    for kwargs, key in (({"seed_set": "mine", "per_family": 1}, "--seeds"),
                        ({"seed_set": "tuning", "per_family": 0}, "--per-family"),
                        ({"seed_set": "tuning", "per_family": 1, "families": ("wind",)}, "--families"),
                        ({"seed_set": "tuning", "per_family": 1, "rtol": 2.0}, "--duration"),
                        ({"seed_set": "tuning", "per_family": 1, "design": "field"}, "--design")):
        with pytest.raises(ConfigError, match=key):
            st.tasks(**kwargs)


def test_a_task_that_fails_is_a_row_with_its_error():
    row = st.run_task(SimpleNamespace(name="wind_000001", seed=1, simulate={"family": "wind"}))
    assert tuple(row) == st.COLUMNS
    assert row["status"] == "failed" and row["error"].startswith("ConfigError") and "family" in row["error"]
    assert (row["task"], row["family"], row["seed"]) == ("wind_000001", "wind", 1) and row["seconds"] >= 0


def test_rows_come_back_from_results_csv_with_their_types(tmp_path):
    row = dict.fromkeys(st.COLUMNS)
    row.update(task="drift_000003", family="drift", seed=3, status="ok", seconds=1.5, artefact_mm=0.25,
               point=json.dumps({"kind": "cog_z"}), law=json.dumps({"kind": "ramp"}), effect="ground_slope",
               library_names=["ground_slope"], discovered=[], covered=True, false_name=False, width_mm=math.inf,
               h_after_lo_m=None)
    path = st.write_rows([row], tmp_path / "out" / "results.csv")
    (back,) = st.read_rows(path)
    assert back == row
