"""With coloured noise (soft-tissue sliding the links show) identify's headline is the fit at the chosen filter,
not the h extrapolated to no filter distortion: between the chosen and the probe filter h moves by the distortion
and by the sliding's own filter-dependent bias, which the extrapolation cannot tell apart.

A ride of the independent generator (three 10 s runs, the paper's pose noise, 2-4 mm of sliding), its seed drawn
at random from the tuning seeds by a fixed generator (not picked), identified with its session's CoM offsets moved
by 1-2 cm: the headline is the fit, the extrapolated h is reported beside it with the reason, and the headline's
interval holds the truth. On 18 such rides (``studies/real_ride_identify.py``, seeds 100-117) the fit erred by
+0.4 +- 17 mm (at most 36 mm) and the extrapolation by +48 +- 119 mm (up to 414 mm).
"""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.identify.cog_height import NOT_HEADLINE, coloured_noise
from euc_ros.core.identify.pipeline import identify_recordings
from euc_ros.core.openworld import study as S
from euc_ros.core.ridesim.artefacts import perturb_session
from euc_ros.core.session import load_session, save_session

pytestmark = pytest.mark.slow

#: The ride's seed, drawn once from the tuning seeds (0-99) by a fixed generator.
SEED = int(np.random.default_rng(20261129).integers(0, 100))


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    rng = np.random.default_rng([SEED, 777])
    sliding_mm = float(rng.uniform(2.0, 4.0))
    out = tmp_path_factory.mktemp("coloured")
    paths = S.lawless_ride(SEED, out, sliding_mm)
    session = out / "session_perturbed.yaml"
    save_session(perturb_session(load_session(paths["session"]), rng, offset_error_m=(0.01, 0.02)), session)
    return identify_recordings(session, paths["csvs"]), paths["h_true_m"]


def test_the_headline_under_sliding_is_the_fit_with_the_extrapolation_beside_it(run):
    result, h_true = run
    data = result.data
    choice = result.states[0].meta["filter"]
    assert coloured_noise(choice) and data["filter"]["noise_model"] == "coloured"
    assert not result.identification.corrected and set(data["diagnostics"]) == {"h_combined"}
    # the data's h is the fit at the chosen filter
    assert data["diagnostics"]["h_combined"]["h_from_data_m"] == result.identification.fits.pooled["3dof"].h_m
    u = data["uncertainty"]
    assert u["h_corrected_not_headline"] == NOT_HEADLINE and np.isfinite(u["h_corrected_m"])
    lo, hi = data["h_ci95_m"]
    assert lo is not None and hi is not None and lo <= h_true <= hi, (lo, h_true, hi)


def test_without_a_choice_or_with_white_noise_nothing_is_coloured():
    class White:
        noise_model = "white"
    assert not coloured_noise(None) and not coloured_noise(White())
