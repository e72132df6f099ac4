"""The open-world study's seed sets: fixed, disjoint, named as the command takes them
(euc_ros.core.worldsim.open_world_seeds)."""
from __future__ import annotations

from euc_ros.core.worldsim.open_world_seeds import FAMILIES, HELD_OUT_SEEDS, REPORT_SEEDS, SEED_SETS, TUNING_SEEDS


def test_the_sets_are_disjoint_so_held_out_seeds_were_never_tuned_on():
    assert not set(TUNING_SEEDS) & set(REPORT_SEEDS)
    assert not set(TUNING_SEEDS) & set(HELD_OUT_SEEDS)
    assert not set(REPORT_SEEDS) & set(HELD_OUT_SEEDS)


def test_the_sets_are_the_fixed_ranges():
    assert (TUNING_SEEDS[0], TUNING_SEEDS[-1], len(TUNING_SEEDS)) == (0, 99, 100)
    assert (REPORT_SEEDS[0], REPORT_SEEDS[-1], len(REPORT_SEEDS)) == (1000, 1999, 1000)
    assert (HELD_OUT_SEEDS[0], HELD_OUT_SEEDS[-1], len(HELD_OUT_SEEDS)) == (20_000, 20_999, 1000)
    for seeds in SEED_SETS.values():
        assert len(set(seeds)) == len(seeds)


def test_seed_sets_by_command_name():
    assert SEED_SETS == {"tuning": TUNING_SEEDS, "report": REPORT_SEEDS, "held-out": HELD_OUT_SEEDS}


def test_families_include_the_no_effect_control_once():
    assert FAMILIES[0] == "none"
    assert len(set(FAMILIES)) == len(FAMILIES) == 6
