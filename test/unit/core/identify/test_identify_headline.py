"""identify's one headline h: the JSON's ``h_m`` is its best estimate with ``h_ci95_m`` beside it, and
other estimates are under ``diagnostics`` (the recording-format contract, section 5).

With the filter chosen from the data the headline is h corrected for the pose noise and the filter's
distortion, and the fit at the chosen filter is a diagnostic; with a fixed window it is the fit.
``identifiable`` judges the headline's interval.
"""
from __future__ import annotations

import json

import numpy as np
import pytest

from euc_ros.cli.main import main
from euc_ros.core.identify import cog_height
from euc_ros.core.identify.cog_height import identify_h
from euc_ros.core.identify.interval import MAX_CI_WIDTH_M
from euc_ros.core.identify.options import IntervalOptions
from euc_ros.core.identify.session_prior import Z95, split_levels
from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
from euc_ros.core.ridesim.writers import write_ride
from euc_ros.core.states.filter_choice import choose_filter
from euc_ros.core.states.kinematics import reconstruct_states
from euc_ros.core.states.settings import ReconstructionSettings

#: Top-level keys of identify's JSON that are a value of h, or its interval, std or range.
H_KEYS = {"h_m", "h_ci95_m", "h_std_m", "h_range_m"}


@pytest.fixture(scope="module")
def ride():
    """Three 7 s decelerations with the paper's noise (the truth: h = 0.61 m)."""
    return simulate_ride(RideConfig(runs=3, seed=5))


@pytest.fixture(scope="module")
def files(ride, tmp_path_factory):
    d = tmp_path_factory.mktemp("ride")
    write_ride(ride, d)
    return str(d / "session.yaml"), sorted(str(p) for p in d.glob("deceleration_0?.csv"))


def _identify(files, tmp_path, *options) -> dict:
    session, recordings = files
    out = tmp_path / "identify.json"
    assert main(["identify", session, *recordings, "--json", str(out), "--no-progress", "--no-sliding-bias",
                 *options]) == 0
    return json.loads(out.read_text())


@pytest.fixture(scope="module")
def chosen(files, tmp_path_factory):
    """identify's JSON with its default, the filter chosen from the data."""
    return _identify(files, tmp_path_factory.mktemp("auto"))


@pytest.fixture(scope="module")
def fixed(files, tmp_path_factory):
    """identify's JSON with a fixed 1.2 s window."""
    return _identify(files, tmp_path_factory.mktemp("fixed"), "--window-s", "1.2")


def _top_level_h(js: dict) -> set[str]:
    return {k for k in js if k.startswith("h_") and k.endswith("_m") and k != "h_grid_m"}


def test_one_h_with_its_interval_at_the_top(chosen):
    assert _top_level_h(chosen) == H_KEYS, _top_level_h(chosen)
    assert not any("corrected" in k or "chosen_filter" in k for k in chosen)
    assert "h_std_formal_m" not in chosen            # the fit's formal std is a diagnostic
    lo, hi = chosen["h_ci95_m"]
    assert lo < chosen["h_m"] < hi
    assert chosen["h_range_m"][0] < chosen["h_m"] < chosen["h_range_m"][1]


def test_diagnostics_hold_the_fit_at_the_chosen_filter(chosen):
    diag = chosen["diagnostics"]
    assert diag["h_at_chosen_filter_m"] == chosen["models"]["3dof"]["h_m"]     # the pooled fit, uncorrected
    lo, hi = diag["h_at_chosen_filter_ci95_m"]
    assert lo < diag["h_at_chosen_filter_m"] < hi
    assert diag["h_at_chosen_filter_std_m"] > diag["h_at_chosen_filter_std_formal_m"] > 0
    assert diag["h_at_chosen_filter_m"] != chosen["h_m"]
    # per_recording and models stay fits
    assert all(r["h_m"] == r_fit["h_m"] for r, r_fit in zip(chosen["per_recording"],
                                                           chosen["models"]["3dof"]["per_recording"]))


def test_the_data_give_the_corrected_h_and_the_headline_combines_it(chosen):
    """The data's h = (h - SIMEX bias) + the extrapolation's step to zero distortion, both measured at the chosen
    filter; the headline h_m combines it with the segments' geometric h (diagnostics.h_combined)."""
    u = chosen["uncertainty"]
    fit = chosen["diagnostics"]["h_at_chosen_filter_m"]
    comb = chosen["diagnostics"]["h_combined"]
    h_data = comb["h_from_data_m"]
    assert h_data == pytest.approx(fit - u["eiv_bias_m"] + u["distortion_correction_m"], abs=1e-12)
    lo, hi = comb["h_from_data_ci95_m"]
    assert lo < h_data < hi
    assert chosen["h_m"] == comb["h_m"] and chosen["h_ci95_m"] == comb["ci95_m"] and comb["consistent"]
    assert abs(chosen["h_m"] - 0.61) < 0.01
    assert u["method"].startswith("paired block bootstrap")
    # the corrected h is nearer the truth than the fit (noise and distortion both lower h)
    assert abs(h_data - 0.61) < abs(fit - 0.61)


def test_with_a_fixed_window_the_data_give_the_fit(fixed):
    assert fixed["diagnostics"]["h_combined"]["h_from_data_m"] == fixed["models"]["3dof"]["h_m"]
    assert set(fixed["diagnostics"]) == {"h_combined"}         # no corrected h: the combination's parts only
    assert _top_level_h(fixed) == H_KEYS | {"h_std_formal_m"}     # the formal std of the fit that h_m is
    lo, hi = fixed["h_ci95_m"]
    assert lo < fixed["h_m"] < hi


def test_the_console_gives_one_headline_and_the_fit_as_a_diagnostic(files, tmp_path, capsys):
    _identify(files, tmp_path)
    text = capsys.readouterr().out
    js = json.loads((tmp_path / "identify.json").read_text())
    lo, hi = js["h_ci95_m"]
    assert f"h = {js['h_m']:.3f} m, 95 % interval [{lo:.3f}, {hi:.3f}] m: the one to use" in text
    comb = js["diagnostics"]["h_combined"]
    dlo, dhi = comb["h_from_data_ci95_m"]
    assert (f"from the data: h = {comb['h_from_data_m']:.3f} m, 95 % interval [{dlo:.3f}, {dhi:.3f}] m (corrected "
            "for the pose noise and the filter's distortion)") in text
    assert text.index("the one to use") < text.index("from the data: h =")      # the headline first
    diag = js["diagnostics"]
    assert f"diagnostic, not for use: h at the chosen filter, uncorrected = {diag['h_at_chosen_filter_m']:.3f} m" \
        in text
    assert text.count("the one to use") == 1


def _states(ride):
    series = [r.mocap for r in ride.runs]
    choice = choose_filter(series, ride.session)
    out = []
    for s in series:
        st = reconstruct_states(s, ride.session, window_s=choice.window_s, polyorder=choice.polyorder)
        st.meta["series"] = s
        out.append(st)
    return out, choice


def test_the_library_result_is_the_headline(ride):
    states, choice = _states(ride)
    ident = identify_h(states, ride.session, filter_choice=choice,
                       uncertainty=IntervalOptions(with_budget=False, sliding=False))
    data = ident.to_dict()
    assert ident.corrected and ident.h == data["h_m"] and ident.identifiable is data["identifiable"]
    assert list(ident.interval) == data["h_ci95_m"]
    assert ident.h_at_filter == data["diagnostics"]["h_at_chosen_filter_m"] == ident.fits.pooled["3dof"].h_m
    assert list(ident.interval_at_filter) == data["diagnostics"]["h_at_chosen_filter_ci95_m"]
    # a fixed window (what residual's base model uses): no corrected h, the uncertainty keys are the fit's
    plain = identify_h(states, ride.session,
                       reconstruction=ReconstructionSettings().with_filter(choice.window_s, choice.polyorder),
                       uncertainty=IntervalOptions(with_budget=False, sliding=False))
    assert not plain.corrected and plain.combined.h_data_m == plain.h_at_filter == plain.fits.pooled["3dof"].h_m
    assert "h_m" not in plain.uncertainty and "diagnostics" not in plain.uncertainty
    assert plain.combined.h_data_ci95_m == plain.interval_at_filter       # the data's interval is the fit's


def test_identifiable_judges_the_headline_interval(ride, monkeypatch):
    """A corrected h whose interval is too wide is not identifiable, though the fit's interval is narrow."""
    states, choice = _states(ride)
    real = cog_height.distortion_corrected

    def widened(*args, **kwargs):
        out = real(*args, **kwargs)
        h0 = out["h_corrected_m"]
        out["h_corrected_ci95_m"] = (h0 - MAX_CI_WIDTH_M, h0 + MAX_CI_WIDTH_M)
        return out

    monkeypatch.setattr(cog_height, "distortion_corrected", widened)
    ident = identify_h(states, ride.session, filter_choice=choice,
                       uncertainty=IntervalOptions(with_budget=False, sliding=False))
    lo, hi = ident.interval_at_filter
    assert ident.corrected and hi - lo < MAX_CI_WIDTH_M
    assert ident.identifiable is False and "interval is 30 cm wide" in ident.reason, ident.reason
    data = ident.to_dict()
    assert data["identifiable"] is False and data["identifiability_reason"] == ident.reason
    assert data["uncertainty"]["excitation"]["record_more_s"] == 0.0     # only its bias terms would narrow it


def test_an_unbounded_headline_interval_is_not_identifiable(ride, monkeypatch):
    states, choice = _states(ride)
    real = cog_height.distortion_corrected

    def unbounded(*args, **kwargs):
        out = real(*args, **kwargs)
        out["h_corrected_ci95_m"] = (out["h_corrected_ci95_m"][0], np.inf)
        return out

    monkeypatch.setattr(cog_height, "distortion_corrected", unbounded)
    ident = identify_h(states, ride.session, filter_choice=choice,
                       uncertainty=IntervalOptions(with_budget=False, sliding=False))
    assert ident.identifiable is False and "the data do not bound h" in ident.reason
    data = ident.to_dict()
    comb = data["diagnostics"]["h_combined"]
    assert comb["h_from_data_ci95_m"][1] is None       # the data bound h below only ...
    lo, hi = data["h_ci95_m"]                           # ... the geometric h bounds it above, at its level
    s_lo = (comb["h_from_data_m"] - comb["h_from_data_ci95_m"][0]) / Z95
    z_g = split_levels(s_lo, comb["u_geometric_m"])[1]
    assert Z95 < z_g and hi == pytest.approx(comb["h_geometric_m"] + z_g * comb["u_geometric_m"])
