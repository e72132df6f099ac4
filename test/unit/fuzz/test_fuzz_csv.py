"""Fast fuzz corpus for the Motive CSV reader: no crash, every rejection an InputError naming the file
and a line (or key), and what is accepted is a plausible series.

Inputs come from hypothesis (derandomized): mutations of valid exports (quaternion with an occluded
block, Euler XYZ in millimetres, CRLF with a BOM), cells replaced by hostile text, header values
replaced, and raw random bytes. ``euc-ros bench`` runs the long job with the same mutators, and it is
there that slow inputs are found (a time limit per input, exceeded = a hang): a wall-clock bound has
no place in a test, which must pass on a loaded machine; a true hang here is stopped by the test
timeout.

Tolerances: a quaternion the reader normalised has unit norm to a few ulps (atol 1e-9).
"""
from __future__ import annotations

import random
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from euc_ros.bench.fuzz import check_csv, csv_seeds, fuzz, mutate_csv
from euc_ros.core.errors import InputError
from euc_ros.core.io.motive_csv import read_motive_csv

FAST = settings(max_examples=250, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
SEEDS = csv_seeds()
_DIR = tempfile.TemporaryDirectory(prefix="euc_fuzz_test_")
PATH = Path(_DIR.name) / "take.csv"


def read_checked(data: bytes, world_up: str = "y"):
    """Read ``data`` as a CSV file; a rejection must name the file and a line or key."""
    PATH.write_bytes(data)
    try:
        s = read_motive_csv(PATH, world_up=world_up)
    except InputError as exc:
        assert exc.path == str(PATH) and str(PATH) in str(exc), str(exc)
        assert exc.line is not None or exc.key is not None, str(exc)
        if exc.line is not None:
            assert 1 <= exc.line <= data.count(b"\n") + 2 and f"line {exc.line}" in str(exc), str(exc)
        return None
    # accepted: strictly increasing frames and times, finite unit quaternions with w >= 0 where tracked
    assert np.all(np.isfinite(s.t)) and np.all(np.diff(s.frame) > 0) and np.all(np.diff(s.t) > 0)
    tr = s.tracked
    assert np.all(np.isfinite(s.position[tr])) and np.all(np.isfinite(s.quat[tr]))
    np.testing.assert_allclose(np.linalg.norm(s.quat[tr], axis=-1), 1.0, atol=1e-9)
    assert np.all(s.quat[tr][..., 3] >= 0)
    assert np.all(np.isnan(s.position[~tr]))   # untracked: NaN, never a zero pose
    return s


def test_seed_corpus_reads():
    for data in SEEDS:
        s = read_checked(data)
        assert s is not None and s.n_frames == 10 and s.bodies == ["E", "H", "TL"]
    assert not read_checked(SEEDS[0]).tracked[1, 4]   # the occluded block


@FAST
@given(index=st.integers(0, len(SEEDS) - 1), rnd=st.randoms(use_true_random=False), z_up=st.booleans())
def test_mutated_files(index, rnd, z_up):
    read_checked(mutate_csv(SEEDS[index], rnd, SEEDS), "z" if z_up else "y")


@FAST
@given(index=st.integers(0, len(SEEDS) - 1), line=st.integers(0, 16), cell=st.integers(0, 40),
       text=st.text(alphabet=st.characters(blacklist_categories=("Cs",)), max_size=24))
def test_any_cell_replaced_by_any_text(index, line, cell, text):
    lines = SEEDS[index].split(b"\n")
    cells = lines[line % len(lines)].split(b",")
    cells[cell % len(cells)] = text.encode("utf-8")
    lines[line % len(lines)] = b",".join(cells)
    read_checked(b"\n".join(lines))


@FAST
@given(data=st.binary(max_size=2000))
def test_random_bytes(data):
    read_checked(data)


@FAST
@given(prefix=st.integers(0, 4000))
def test_every_truncation(prefix):
    data = SEEDS[prefix % 3][: prefix]
    read_checked(data)


def test_rejections_name_line_and_column_of_a_bad_cell():
    lines = SEEDS[0].split(b"\n")
    cells = lines[9].split(b",")
    cells[5] = b"abc"
    lines[9] = b",".join(cells)
    PATH.write_bytes(b"\n".join(lines))
    with pytest.raises(InputError) as info:
        read_motive_csv(PATH)
    assert (info.value.line, info.value.column) == (10, 6) and "non-numeric" in str(info.value)


def test_subnormal_frame_rate_is_rejected():
    """A fuzzer finding: a sub-normal Export Frame Rate (1e-320 Hz) once gave t = inf; now a located error."""
    data = SEEDS[0].replace(b"Export Frame Rate,120.000000", b"Export Frame Rate,1e-320")
    PATH.write_bytes(data)
    with pytest.raises(InputError) as info:
        read_motive_csv(PATH)
    assert info.value.line == 1 and "Export Frame Rate" in str(info.value)


def test_the_bench_fuzzer_finds_no_failure_on_a_short_run():
    # every input runs (no wall-clock budget); "hang" = an input still parsing after 30 s, a timeout
    r = fuzz("csv", 1500, seed=4, time_budget_s=float("inf"), per_input_timeout_s=30.0)
    assert r["inputs"] == 1500
    assert r["crash"] == r["hang"] == r["unclear"] == r["invalid"] == 0, r["failures"][:3]
    assert r["accepted"] > 0 and r["rejected"] > 500 and r["rejection_classes"] >= 10


def test_check_csv_classifies():
    path = Path(_DIR.name) / "c.csv"
    assert check_csv(SEEDS[1], path) == ("accepted", None)
    outcome, cls = check_csv(b"Format Version,1.23\n", path)
    assert outcome == "rejected" and cls
    rng = random.Random(0)
    for _ in range(200):
        data = mutate_csv(SEEDS[0], rng, SEEDS)
        assert check_csv(data, path)[0] in ("accepted", "rejected"), data[:300]
