"""A unit slip is refused before any analysis: the span of the rider on the EUC tells the unit."""
from __future__ import annotations

import dataclasses
import shutil

import numpy as np
import pytest

from euc_ros.cli.main import main
from euc_ros.core.errors import InputError
from euc_ros.core.io.motive_csv import read_motive_csv, write_motive_csv
from euc_ros.core.mocap.length_scale import check_length_scale, median_span
from euc_ros.core.session import load_session


@pytest.fixture(scope="module")
def ride(short_ride):
    src, _ = short_ride
    return read_motive_csv(src / "deceleration_01.csv", world_up="y"), load_session(src / "session.yaml"), src


def _scaled(series, k):
    return dataclasses.replace(series, position=series.position * k)


def test_the_simulated_rider_spans_what_a_rider_spans(ride):
    series, session, _ = ride
    bodies = [*session.rider.segments, session.euc.body]
    # independent: the helmet top to the lowest pivot (the EUC's top or an ankle) in the first frame
    p = series.position[:, 0]
    rows = [series.bodies.index(b) for b in bodies]
    brute = float(np.linalg.norm(np.nanmax(p[rows], 0) - np.nanmin(p[rows], 0)))
    assert 1.0 < brute < 2.2
    assert median_span(series, bodies) == pytest.approx(brute, rel=0.1)
    assert check_length_scale(series, session) == []


@pytest.mark.parametrize("k, unit", [(1000.0, "millimetres"), (100.0, "centimetres")])
def test_a_unit_slip_is_an_error_naming_the_unit(ride, k, unit):
    series, session, _ = ride
    with pytest.raises(InputError, match=f"look like {unit}") as err:
        check_length_scale(_scaled(series, k), session, path="ride.csv")
    assert err.value.key == "Length Units" and "ride.csv" in str(err.value)


def test_a_size_no_unit_explains_is_a_warning(ride):
    series, session, _ = ride
    warnings = check_length_scale(_scaled(series, 7.0), session)
    assert len(warnings) == 1 and "length unit" in warnings[0]


def test_identify_refuses_millimetres_labelled_as_metres_before_any_work(ride, tmp_path, capsys):
    series, _, src = ride
    csv = write_motive_csv(_scaled(series, 1000.0), tmp_path / "mm_as_m.csv", world_up="y")
    shutil.copy(src / "session.yaml", tmp_path / "session.yaml")
    assert main(["identify", str(tmp_path / "session.yaml"), str(csv), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "millimetres" in err[0] and "mm_as_m.csv" in err[0], err
