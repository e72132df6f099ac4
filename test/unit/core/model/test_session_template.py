"""The commented session file written from the rider's and the EUC's measurements
(euc_ros.core.model.session_template).

Known answers: de Leva (1996) Table 4 mass fractions for a male rider, and the round trip through
parse_session (the file must read back as the values it was written from).
"""
from __future__ import annotations

import pytest

from euc_ros.core.errors import ConfigError
from euc_ros.core.model.session_template import EUC_HOWTO, NameMap, RiderMeasures, render_session
from euc_ros.core.session import parse_session
from euc_ros.core.yamlfile import parse_yaml

RIDER = RiderMeasures(70.0, 1.75, "male")


def _parse(text: str):
    return parse_session(parse_yaml(text, "session.yaml"))


def test_the_rendered_file_reads_back_with_the_given_values():
    euc = {"body": "Wheel", "wheel_radius": 0.2032, "body_mass": 21.5, "pivot_to_wheel_center": [0.01, 0.0, -0.5]}
    s = _parse(render_session(RIDER, euc, names={"H": "Helmet", "CHR": "RShoulder"}, world_up="z",
                              rate_hz=240.0))
    assert s.world_up == "z" and s.rate_hz == 240.0
    assert s.rider.mass == 70.0
    assert s.euc.body == "Wheel"
    assert s.euc.wheel_radius == pytest.approx(0.2032)
    assert s.euc.body_mass == pytest.approx(21.5)
    assert tuple(s.euc.pivot_to_wheel_center) == pytest.approx((0.01, 0.0, -0.5))
    # renamed bodies appear under their Motive names, the others under their own
    assert "Helmet" in s.rider.segments and "RShoulder" in s.rider.segments
    assert "H" not in s.rider.segments and "CHR" not in s.rider.segments and "CHL" in s.rider.segments


def test_segment_fractions_are_de_levas_male_table_and_sum_to_one():
    segs = _parse(render_session(RIDER)).rider.segments
    assert sum(seg.mass_fraction for seg in segs.values()) == pytest.approx(1.0, abs=1e-4)
    # de Leva (1996) Table 4, male: head 6.94 %, trunk 43.46 % (two halves), thigh 14.16 %,
    # upper arm 2.71 %, forearm 1.62 % + hand 0.61 %, shank 4.33 % + foot 1.37 %
    expected = {"H": 0.0694, "CHR": 0.4346 / 2, "CHL": 0.4346 / 2, "TR": 0.1416, "TL": 0.1416,
                "UAR": 0.0271, "UAL": 0.0271, "LAR": 0.0223, "LAL": 0.0223, "LR": 0.0570, "LL": 0.0570,
                "HR": 0.0, "HL": 0.0}
    assert {b: seg.mass_fraction for b, seg in segs.items()} == pytest.approx(expected, abs=1e-5)


def test_every_euc_key_has_its_howto_and_defaults_say_they_are_the_papers():
    text = render_session(RIDER, {"wheel_radius": 0.21})
    lines = text.splitlines()
    for key, howto in EUC_HOWTO.items():
        i = next(k for k, line in enumerate(lines) if line.startswith(f"  {key}:"))
        comment = lines[i - 1]
        assert comment.startswith(f"  # {howto}")
        if key == "wheel_radius":
            assert "measure yours" not in comment          # measured: no note
        elif key == "body":
            assert comment.endswith("; E by default")
        else:
            assert "EUC paper's value" in comment and "measure yours" in comment
    assert _parse(text).euc.wheel_radius == pytest.approx(0.21)


@pytest.mark.parametrize("kwargs, key, word", [
    ({"names": {"XX": "Foo"}}, "names", "'XX'"),                  # unknown rider body
    ({"names": {"H": "CHR"}}, "names", "'CHR'"),                  # CHR's own name given to H as well
    ({"euc": {"tyre_pressure": 2.5}}, "euc", "'tyre_pressure'"),  # unknown EUC key
    ({"world_up": "x"}, "world_up", "'x'"),
])
def test_bad_arguments_raise_config_errors_naming_the_key(kwargs, key, word):
    with pytest.raises(ConfigError) as err:
        render_session(RIDER, **kwargs)
    assert err.value.key == key
    assert f"key '{key}'" in str(err.value) and word in str(err.value)


def test_name_map_parses_body_name_pairs():
    assert NameMap.parse(["H=Helmet", " CHR = RShoulder "]).names == {"H": "Helmet", "CHR": "RShoulder"}
    assert NameMap.parse([]).names == {}


@pytest.mark.parametrize("item", ["Helmet", "H=", "=Helmet", " = "])
def test_name_map_rejects_a_malformed_item_naming_it(item):
    with pytest.raises(ConfigError) as err:
        NameMap.parse(["CHR=RShoulder", item])
    assert err.value.key == "--name"
    assert repr(item) in str(err.value)
