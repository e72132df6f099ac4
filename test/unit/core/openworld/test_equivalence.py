"""Statistical equivalence of two versions: the statistics by hand, the files both studies write, the tool."""
from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from euc_ros.core.openworld.equivalence import Ride, binomial_se, compare, identify_rides, load_rides, markdown
from euc_ros.core.openworld.study import COLUMNS, write_rows

REPO = Path(__file__).resolve().parents[4]


def _rides(n=20, shift_se=0.0, seed=0):
    """``n`` rides with a 20 mm interval (se = 10.2 mm); h moved by ``shift_se`` of it."""
    rng = np.random.default_rng(seed)
    out = {}
    for i in range(n):
        h = 0.6 + rng.normal(0, 0.01)
        se = 0.02 / 1.959963984540054
        out[f"r{i}"] = Ride(h + shift_se * se, h - 0.02, h + 0.02, 0.6, ("ok",))
    return out


def test_identical_versions_pass_with_zero_change():
    a = _rides()
    rep = compare(a, dict(a))
    assert rep["passed"] and rep["h"]["median_abs_z"] == 0.0 and rep["flips"]["share"] == 0.0


@pytest.mark.parametrize("shift, median_ok, max_ok", [(0.2, True, True), (0.3, False, True), (0.6, False, False)])
def test_the_change_of_h_in_its_own_standard_errors(shift, median_ok, max_ok):
    rep = compare(_rides(), _rides(shift_se=shift))
    assert rep["h"]["median_abs_z"] == pytest.approx(shift, rel=1e-9)
    assert rep["checks"]["median_abs_z"] is median_ok and rep["checks"]["max_abs_z"] is max_ok
    assert rep["passed"] is (median_ok and max_ok)


def test_binomial_standard_error_by_hand():
    p = 0.5 / 51
    assert binomial_se(0, 50) == pytest.approx(math.sqrt(p * (1 - p) / 50))
    assert binomial_se(45, 50) == pytest.approx(math.sqrt((45.5 / 51) * (5.5 / 51) / 50))
    assert math.isnan(binomial_se(0, 0))


@pytest.mark.parametrize("k_new, within", [(44, True), (46, True), (40, False)])
def test_a_rate_moves_by_at_most_one_binomial_standard_error(k_new, within):
    """Base 45/50 covered: se = 0.044, so one ride (0.02) is within and five (0.10) are not."""
    base = {f"r{i}": Ride(0.6, 0.5, 0.7, 0.6 if i < 45 else 0.9) for i in range(50)}
    new = {f"r{i}": Ride(0.6, 0.5, 0.7, 0.6 if i < k_new else 0.9) for i in range(50)}
    base = {k: Ride(r.h, r.lo, r.hi, r.truth, (), {"covered": r.covered}) for k, r in base.items()}
    new = {k: Ride(r.h, r.lo, r.hi, r.truth, (), {"covered": r.covered}) for k, r in new.items()}
    rep = compare(base, new)
    assert rep["rates"]["covered"]["base"]["k"] == 45 and rep["rates"]["covered"]["new"]["k"] == k_new
    assert rep["rates"]["covered"]["within"] is within and rep["passed"] is within


def test_verdict_flips_over_five_percent_fail():
    a = _rides(n=20)
    b = dict(a)
    b["r3"] = Ride(a["r3"].h, a["r3"].lo, a["r3"].hi, 0.6, ("refused",))
    rep = compare(a, b)
    assert rep["flips"]["keys"] == ["r3"] and rep["checks"]["flips"]          # 1 of 20 = 5 %
    b["r4"] = Ride(a["r4"].h, a["r4"].lo, a["r4"].hi, 0.6, ("refused",))
    assert not compare(a, b)["checks"]["flips"]                                 # 2 of 20


def test_an_unbounded_base_interval_is_listed_not_scored():
    a = {"x": Ride(0.6, None, 0.7, 0.6), "y": Ride(0.6, 0.58, 0.62, 0.6)}
    b = {"x": Ride(0.9, None, 0.7, 0.6), "y": Ride(0.6, 0.58, 0.62, 0.6)}
    rep = compare(a, b)
    assert rep["h"]["unscored"] == ["x"] and rep["h"]["n"] == 1
    assert "not scored" in markdown(rep)


def test_an_unbounded_end_is_a_miss():
    assert Ride(0.6, None, 0.7, 0.6).covered is False and Ride(0.6, 0.5, 0.7, 0.6).covered is True


def _write(folder: Path, rr_rows: list, ow_rows: list) -> None:
    (folder / "rr").mkdir(parents=True)
    (folder / "rr" / "rows.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rr_rows), encoding="utf-8")
    write_rows(ow_rows, folder / "ow" / "results.csv")


def _rr(seed, h, lo, hi):
    return {"seed": seed, "h_true_m": 0.8, "perturbed_session": {"h_m": h, "h_ci95_m": [lo, hi], "identifiable": True}}


def _ow(task, family, explained, covered, h):
    row = {c: None for c in COLUMNS}
    row.update(task=task, family=family, seed=1, status="ok", effect="none", explained=explained, false_name=False,
               covered=covered, h_true_m=0.8, h_after_m=h, h_after_lo_m=h - 0.05, h_after_hi_m=h + 0.05)
    return row


def test_the_studies_files_are_read_and_the_tool_compares_them(tmp_path):
    _write(tmp_path / "a", [_rr(100, 0.80, 0.78, 0.82), _rr(101, 0.79, 0.76, 0.83)],
           [_ow("lab_field_000001", "lab_field", True, True, 0.8), _ow("none_000001", "none", None, True, 0.81)])
    _write(tmp_path / "b", [_rr(100, 0.801, 0.78, 0.82), _rr(101, 0.79, 0.76, 0.83)],
           [_ow("lab_field_000001", "lab_field", True, True, 0.8), _ow("none_000001", "none", None, True, 0.81)])
    rides = load_rides(tmp_path / "a")
    assert set(rides) == {"identify/100", "identify/101", "residual/lab_field_000001", "residual/none_000001"}
    assert rides["residual/lab_field_000001"].rates == {"covered": True, "explained": True, "false_name": False}
    assert "explained" not in rides["residual/none_000001"].rates          # a control has nothing to explain
    done = subprocess.run([sys.executable, str(REPO / "tools" / "equivalence.py"), "--compare", str(tmp_path / "a"),
                           str(tmp_path / "b"), "--out", str(tmp_path / "eq")], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    rep = json.loads((tmp_path / "eq" / "equivalence.json").read_text())
    assert rep["passed"] and rep["h"]["n"] == 4 and "passed" in (tmp_path / "eq" / "equivalence.md").read_text()
    # a failed ride in the new version is a flip
    _write(tmp_path / "c", [{"seed": 100, "h_true_m": 0.8, "perturbed_session": {"error": "boom"}},
                            _rr(101, 0.79, 0.76, 0.83)], [])
    assert identify_rides([{"seed": 100, "h_true_m": 0.8, "perturbed_session": {"error": "x"}}])[
        "identify/100"].verdict == ("failed",)
    done = subprocess.run([sys.executable, str(REPO / "tools" / "equivalence.py"), "--compare", str(tmp_path / "a"),
                           str(tmp_path / "c"), "--out", str(tmp_path / "eq2")], capture_output=True, text=True)
    assert done.returncode == 1 and "identify/100" in done.stdout
