"""Shared fixtures of the core tests: the short ride's Motive export with either up axis."""
from __future__ import annotations

import shutil

import pytest

from euc_ros.core.io.motive_csv import read_motive_csv, write_motive_csv


@pytest.fixture(scope="module")
def up_axis_csvs(short_ride, tmp_path_factory):
    """``{"y": path, "z": path}``: the simulated Y-up CSV (Motive's default) and a Z-up export of the same
    frames, in a folder of the test module's own."""
    src, _ = short_ride
    d = tmp_path_factory.mktemp("up_axis")
    yup = d / "ride_yup.csv"
    shutil.copy(src / "deceleration_01.csv", yup)
    return {"y": yup, "z": write_motive_csv(read_motive_csv(yup, world_up="y"), d / "ride_zup.csv", world_up="z")}
