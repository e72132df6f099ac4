"""Session values checked at load time: plausible SI ranges with unit hints, duplicate keys."""
# covers: euc_ros/core/errors.py
# covers: euc_ros/core/yamlfile.py
from __future__ import annotations

import pytest
import yaml

from euc_ros.cli.main import main
from euc_ros.core.errors import ConfigError
from euc_ros.core.session import PLAUSIBLE, default_session, load_session, parse_session, save_session
from euc_ros.core.yamlfile import load_yaml, parse_yaml


def _with(dotted: str, value) -> dict:
    d = default_session("y").to_dict()
    *parents, last = dotted.split(".")
    node = d
    for p in parents:
        node = node[p]
    node[last] = value
    return d


def _write(tmp_path, d: dict):
    path = tmp_path / "session.yaml"
    path.write_text(yaml.safe_dump(d, sort_keys=False))
    return path


# The examples, and one slip per kind of unit
UNIT_SLIPS = [
    ("euc.wheel_radius", 200, "wheel_radius = 200 m is not plausible (expected 0.05-0.5 m); "
                              "the value looks like millimetres: 0.2"),
    ("rider.mass", 65000, "mass = 65000 kg is not plausible (expected 20-250 kg); the value looks like grams: 65"),
    ("euc.pivot_to_wheel_center", [0, 0, -450], "pivot_to_wheel_center = [0, 0, -450] m is not plausible "
                                                "(expected a length of at most 2 m); the value looks like "
                                                "millimetres: [0, 0, -0.45]"),
    ("euc.wheel_radius", 20, "the value looks like centimetres: 0.2"),
    ("euc.body_mass", 13000, "the value looks like grams: 13"),
    ("euc.wheel_mass", 3000, "the value looks like grams: 3"),
    ("rider.inertia_pitch", 16600, "the value looks like g m^2: 16.6"),
    ("euc.wheel_inertia", 120000, "kg mm^2: 0.12"),
    ("euc.h0", 75, "millimetres: 0.075"),
    ("euc.l0", 50, "millimetres: 0.05"),
    ("rider.segments.H.com_offset", [0, 0, -120], "millimetres: [0, 0, -0.12]"),
    ("rate_hz", 0.12, "the value looks like kHz: 120"),
]


@pytest.mark.parametrize("dotted, value, message", UNIT_SLIPS)
def test_a_value_1000x_off_names_the_key_and_the_unit(tmp_path, dotted, value, message):
    path = _write(tmp_path, _with(dotted, value))
    with pytest.raises(ConfigError) as info:
        load_session(path)
    assert info.value.key == dotted and info.value.path == str(path)
    assert message in str(info.value)
    assert str(info.value).startswith(f"{path}, key '{dotted}': ")


@pytest.mark.parametrize("dotted, value", [
    ("rider.mass", 5.0), ("rider.mass", 400.0), ("euc.wheel_radius", 0.9), ("euc.body_mass", 0.013),
    ("euc.body_inertia", 50.0), ("euc.pivot_to_wheel_center", [0.0, 0.0, -3.0]), ("rate_hz", 50000.0),
])
def test_out_of_range_without_a_unit_explanation_says_the_range_only(dotted, value):
    with pytest.raises(ConfigError) as info:
        parse_session(_with(dotted, value), "s.yaml")
    msg = str(info.value)
    assert info.value.key == dotted and "is not plausible (expected " in msg and "looks like" not in msg


@pytest.mark.parametrize("dotted, value", [
    # ranges generous for any real EUC and rider: a 25 kg child, a 140 kg rider, a 24" wheel, a 14" wheel,
    # a heavy EUC, a CoG below the axle, a 2-DoF session (h0 = l0 = 0), a pivot mounted 1 m up the mast
    ("rider.mass", 25.0), ("rider.mass", 140.0), ("euc.wheel_radius", 0.305), ("euc.wheel_radius", 0.178),
    ("euc.body_mass", 45.0), ("euc.wheel_mass", 15.0), ("euc.h0", -0.05), ("euc.h0", 0.0), ("euc.l0", 0.0),
    ("euc.pivot_to_wheel_center", [0.05, 0.0, -1.0]), ("rider.inertia_pitch", 40.0), ("rate_hz", 1000.0),
])
def test_real_values_are_accepted(dotted, value):
    parse_session(_with(dotted, value), "s.yaml")


def test_every_session_quantity_has_a_range():
    """Every number in a session file (leaf key) has a plausible range; the defaults lie inside them."""
    d = default_session("y").to_dict()
    numeric = {k for k, v in d.items() if isinstance(v, float)}
    numeric |= {k for k, v in d["rider"].items() if isinstance(v, float)}
    numeric |= {k for k, v in d["euc"].items() if isinstance(v, (float, list))}
    numeric |= {"com_offset"}
    assert numeric <= set(PLAUSIBLE), numeric - set(PLAUSIBLE)
    parse_session(d, "s.yaml")


def test_cli_refuses_an_implausible_session_in_one_line(short_ride, tmp_path, capsys):
    src, _ = short_ride
    d = load_session(src / "session.yaml").to_dict()
    d["euc"]["wheel_radius"] = 200
    path = _write(tmp_path, d)
    assert main(["identify", str(path), str(src / "deceleration_01.csv"), "--no-progress"]) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert err == [f"euc-ros identify: error: {path}, key 'euc.wheel_radius': wheel_radius = 200 m is not "
                   "plausible (expected 0.05-0.5 m); the value looks like millimetres: 0.2"]


# ----------------------------------------------------------------------------------------------- duplicate keys
def test_duplicate_key_in_a_session_names_file_line_and_key(tmp_path):
    path = tmp_path / "session.yaml"
    save_session(default_session("y"), path)
    lines = path.read_text().splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.strip().startswith("wheel_radius:"))
    lines.insert(i + 2, "  wheel_radius: 0.25")          # the second occurrence, two lines further down
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ConfigError) as info:
        load_session(path)
    e = info.value
    assert (e.path, e.line, e.column, e.key) == (str(path), i + 3, 3, "euc.wheel_radius")
    assert f"first at line {i + 1}" in str(e)


def test_cli_refuses_a_duplicated_key_in_one_line(short_ride, tmp_path, capsys):
    src, _ = short_ride
    text = (src / "session.yaml").read_text().splitlines()
    i = next(k for k, ln in enumerate(text) if ln.strip().startswith("mass:"))
    text.insert(i + 1, text[i].replace("mass:", "mass: 80.0 #"))     # rider.mass given again
    path = tmp_path / "session.yaml"
    path.write_text("\n".join(text) + "\n")
    assert main(["residual", str(path), str(src / "deceleration_01.csv"), "--json", str(tmp_path / "r.json"),
                 "--no-progress"]) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(err) == 1 and f"{path}, line {i + 2}, column" in err[0] and "key 'rider.mass'" in err[0], err
    assert "given twice" in err[0] and not (tmp_path / "r.json").exists()


@pytest.mark.parametrize("text, line, key", [
    ("a: 1\nb: 2\na: 3\n", 3, "a"),
    ("x:\n  y: 1\n  z: 2\n  y: 4\n", 4, "x.y"),
    ("- {a: 1, a: 2}\n", 1, "[0].a"),
    ("1: a\n01: b\n", 2, "01"),                       # the same integer key written twice
    ("on: 1\ntrue: 2\n", 2, "true"),                   # YAML 1.1: both are the boolean true
])
def test_duplicate_keys_anywhere(text, line, key):
    with pytest.raises(ConfigError) as info:
        parse_yaml(text, "f.yaml")
    assert (info.value.line, info.value.key) == (line, key)


def test_merge_keys_may_be_overridden_and_aliases_are_not_duplicates():
    assert parse_yaml("base: &b {r: 1, m: 2}\nd:\n  <<: *b\n  r: 3\ne: *b\n") == \
        {"base": {"r": 1, "m": 2}, "d": {"r": 3, "m": 2}, "e": {"r": 1, "m": 2}}


def test_syntax_errors_and_empty_files_unchanged(tmp_path):
    empty = tmp_path / "empty.yaml"
    empty.write_text("")
    assert load_yaml(empty) is None
    bad = tmp_path / "bad.yaml"
    bad.write_text("a: [1,\n")
    with pytest.raises(ConfigError, match="not valid YAML") as info:
        load_yaml(bad)
    assert info.value.line == 2 and str(bad) in str(info.value)
    two = tmp_path / "two.yaml"
    two.write_text("a: 1\n---\nb: 2\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_yaml(two)


@pytest.mark.ros
def test_duplicate_key_in_a_node_params_file(tmp_path):
    pytest.importorskip("rclpy")
    from euc_ros.ros.params import ParamSpec, validate_params_file

    path = tmp_path / "params.yaml"
    path.write_text("rider_state:\n  ros__parameters:\n    window_s: 0.9\n    window_s: 0.5\n")
    specs = [ParamSpec("window_s", 0.9, "")]
    with pytest.raises(ConfigError) as info:
        validate_params_file(str(path), "rider_state", specs)
    assert (info.value.line, info.value.key) == (4, "rider_state.ros__parameters.window_s")
    assert str(path) in str(info.value)


def test_the_documented_ranges_are_the_code_s():
    """docs/session.md must stay true: its table of ranges is PLAUSIBLE."""
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[3] / "docs" / "session.md").read_text(encoding="utf-8")
    rows = {}
    for line in doc.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 5 and cells[0].startswith("`") and " to " in cells[1]:
            leaf = cells[0].strip("`").split(".")[-1]
            lo, hi = cells[1].removeprefix("length ").split(" to ")
            tlo, thi = cells[3].split(" to ")
            rows[leaf] = (float(lo), float(hi), cells[2], (float(tlo), float(thi)),
                          [u.strip() for u in cells[4].split(",")])
    assert set(rows) == set(PLAUSIBLE)
    for leaf, r in PLAUSIBLE.items():
        assert rows[leaf] == (r.lo, r.hi, r.unit, r.typical, [name for _, name in r.slips]), leaf


def test_a_session_with_numpy_values_is_saved_as_plain_numbers(tmp_path):
    import dataclasses

    import numpy as np

    s = default_session("y")
    name, seg = next(iter(s.rider.segments.items()))
    moved = dataclasses.replace(s, rider=dataclasses.replace(s.rider, segments={
        **s.rider.segments, name: dataclasses.replace(seg, com_offset=tuple(np.add(seg.com_offset, 0.006)))}))
    save_session(moved, tmp_path / "s.yaml")
    back = load_session(tmp_path / "s.yaml")
    assert back.rider.segments[name].com_offset == pytest.approx(np.add(seg.com_offset, 0.006), abs=0)
    assert "numpy" not in (tmp_path / "s.yaml").read_text()
