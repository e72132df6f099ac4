"""The up-axis check on a live stream: frames pushed one at a time give the offline verdict.

The frames come from the ride simulator's Y-up Motive export and a Z-up export of the same frames,
read as the live sources read them (converted with the configured ``world_up``).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from euc_ros.core.errors import ConfigError, InputError
from euc_ros.core.io.motive_csv import read_motive_csv
from euc_ros.core.mocap.up_axis_watch import UpAxisWatch
from euc_ros.core.session import load_session

CHECKS = (1.0, 2.0)


@pytest.fixture(scope="module")
def ride(short_ride, up_axis_csvs):
    src, _ = short_ride
    return up_axis_csvs, load_session(src / "session.yaml")


def _feed(watch: UpAxisWatch, series, until_s: float | None = None) -> list[str]:
    """Push frames as a live source does; run the check whenever it is due; return its warnings."""
    warnings = []
    stamps = np.round(series.t * 1e9).astype(np.int64)
    for k in range(series.n_frames):
        if until_s is not None and series.t[k] - series.t[0] > until_s:
            break
        watch.push(int(stamps[k]), series.position[:, k], series.quat[:, k], series.tracked[:, k])
        if watch.due():
            warnings += watch.check()
    return warnings


@pytest.mark.parametrize("up", ["y", "z"])
def test_the_right_axis_passes(ride, up):
    files, session = ride
    series = read_motive_csv(files[up], world_up=up)
    watch = UpAxisWatch(series.bodies, up, replace(session, world_up=up), check_after_s=CHECKS)
    assert _feed(watch, series) == []
    assert watch.done and watch.result["inferred"] == up and watch.result["conclusive"]


@pytest.mark.parametrize("up, wrong", [("y", "z"), ("z", "y")])
def test_the_wrong_axis_is_a_config_error_naming_the_right_one(ride, up, wrong):
    files, session = ride
    series = read_motive_csv(files[up], world_up=wrong)      # what a live source reads with the wrong world_up
    watch = UpAxisWatch(series.bodies, wrong, replace(session, world_up=wrong), check_after_s=CHECKS,
                        label="natnet://10.0.0.2")
    with pytest.raises(ConfigError, match=f"world_up is '{wrong}'.*suggest '{up}'.*set world_up: {up}") as err:
        _feed(watch, series)
    assert err.value.key == "world_up" and "natnet://10.0.0.2" in str(err.value)


def test_a_z_up_source_with_y_up_data_is_an_input_error(ride):
    files, session = ride
    series = read_motive_csv(files["y"], world_up="z")       # Y-up poses on a topic that promises Z-up
    watch = UpAxisWatch(series.bodies, None, session, check_after_s=CHECKS)
    with pytest.raises(InputError, match="not Z-up"):
        _feed(watch, series)


def test_without_a_session_a_contradiction_is_only_a_warning(ride):
    files, _ = ride
    series = read_motive_csv(files["z"], world_up="y")
    watch = UpAxisWatch(series.bodies, "y", None, check_after_s=CHECKS)
    warnings = _feed(watch, series)
    assert len(warnings) == 1 and "session_file" in warnings[0] and "z axis" in warnings[0]
    assert watch.done


def test_too_little_data_gives_up_with_a_warning(ride):
    files, session = ride
    series = read_motive_csv(files["y"], world_up="y")
    # a lone body: no upright-rider test; EUC tests need the EUC, which is absent: floor only, never conclusive
    lone = series.select([b for b in series.bodies if b != session.euc.body][:1])
    watch = UpAxisWatch(lone.bodies, "y", session, check_after_s=CHECKS)
    warnings = _feed(watch, lone)
    assert watch.done and len(warnings) == 1 and "could not be checked" in warnings[0]


def test_frames_are_thinned_and_nothing_is_kept_once_done(ride):
    files, session = ride
    series = read_motive_csv(files["y"], world_up="y")
    watch = UpAxisWatch(series.bodies, "y", session, check_after_s=(60.0,), keep_rate_hz=30.0)
    _feed(watch, series)
    span = series.t[-1] - series.t[0]
    # one kept frame per 1/30 s at most (120 Hz source): the first, then every 4th
    assert len(watch._t) == pytest.approx(span * 30 + 1, abs=1)
    watch.check()   # the last check gives up or concludes; either way the buffer is released
    assert watch.done and watch._t == []


def test_frames_of_another_body_count_are_ignored_and_reset_restarts(ride):
    files, session = ride
    series = read_motive_csv(files["y"], world_up="y")
    watch = UpAxisWatch(series.bodies[:2], "y", session, check_after_s=CHECKS)
    watch.push(0, series.position[:, 0], series.quat[:, 0], series.tracked[:, 0])
    assert watch._t == []
    watch.reset(series.bodies)
    assert _feed(watch, series) == [] and watch.done
