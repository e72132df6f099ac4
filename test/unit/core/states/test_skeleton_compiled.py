"""The compiled chain fit gives the numpy reference's faults and G, and its closed-form rotations are scipy's.

Rotations: ``rot_exp`` and ``rot_log`` against scipy's ``Rotation`` (an independent implementation) over
random rotation vectors of every angle up to just below 180 deg, and on both sides of the series threshold.
Each is a chain of some 30 floating-point operations on quantities of size <= pi, so they agree to 64 units
in the last place (the tolerance of ``test_geometry_compiled.py``).

Fit: two simulated rides (the ride simulator's pose noise plus the artefact generator's soft-tissue sliding
and coloured noise; the second also with marker swaps and 180 deg flips). The faulty bodies must be the same
(a rule on link deviations far from their thresholds). G: the fit stops after a fixed number of Gauss-Newton
iterations, so where it stops is known only to its convergence: the step one more iteration would take,
``|G_{K+1} - G_K|`` (of the reference). Two implementations of the same iteration may differ by round-off that
the normal matrix's conditioning amplifies (a faulty body's rotation about its only link is held by the
damping alone), and a further iteration moves G by that same amplified round-off; so per frame
``|G_compiled - G_reference| <= |G_{K+1} - G_K| + 64 eps |G|`` (the last term: the round-off of G's sum itself).
Seeds drawn once from ``default_rng(2026)`` over the tuning seeds 0-99 (not picked).

The live calibration's model, frame by frame, is ``SkeletonModel.from_poses`` of the frames seen so far.
"""
# covers: euc_ros/core/states/skeleton_compiled.py
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from euc_ros.core.errors import ConfigError
from euc_ros.core.ridesim.artefacts import SoftTissueArtefacts, apply_artefacts
from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
from euc_ros.core.states.skeleton import OnlineSkeleton, SkeletonModel, skeleton_cog
from euc_ros.core.states.skeleton_compiled import SERIES_BELOW, chain_cog, rot_exp, rot_log, warm_up

EPS = np.finfo(float).eps
#: ~30 chained operations on quantities of size <= pi
ULPS = 64 * EPS
#: (ride seed, artefact seed, swaps, flips): seeds drawn once from default_rng(2026) over 0-99
RIDES = ((85, 17, 0, 0), (2, 63, 4, 8))


def _rotvecs(rng, n):
    axis = rng.standard_normal((n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    angle = np.concatenate([rng.uniform(0.0, np.pi - 1e-6, n - 8),
                            SERIES_BELOW * np.array([0.5, 0.999, 1.001, 2.0]), [0.0, 1e-12, 1e-8, np.pi - 1e-9]])
    return axis * angle[:, None]


def test_closed_form_rotations_equal_scipy():
    rng = np.random.default_rng(0)
    for w in _rotvecs(rng, 400):
        R = np.empty((3, 3))
        rot_exp(w[0], w[1], w[2], R)
        np.testing.assert_allclose(R, Rotation.from_rotvec(w).as_matrix(), rtol=0, atol=ULPS)
        back = np.empty(3)
        rot_log(Rotation.from_rotvec(w).as_matrix(), back)
        np.testing.assert_allclose(back, w, rtol=0, atol=ULPS * np.pi)
    # a relative rotation of 180 deg (an undetected flip): |log| = pi, about the flip's axis up to sign
    back = np.empty(3)
    rot_log(Rotation.from_rotvec([np.pi, 0.0, 0.0]).as_matrix(), back)
    np.testing.assert_allclose(np.abs(back), [np.pi, 0.0, 0.0], rtol=0, atol=ULPS * np.pi)


@pytest.fixture(scope="module", params=RIDES, ids=lambda r: f"ride{r[0]}-art{r[1]}-swaps{r[2]}-flips{r[3]}")
def ride(request):
    seed, art_seed, swaps, flips = request.param
    res = simulate_ride(RideConfig(maneuver="deceleration", runs=1, seed=seed, duration_s=3.0))
    series, events = apply_artefacts(res.runs[0].mocap, SoftTissueArtefacts(swaps=swaps, flips=flips),
                                     np.random.default_rng(art_seed))
    return series, res.session, events


def test_compiled_fit_equals_the_reference(ride):
    s, session, events = ride
    model = SkeletonModel.estimate(s, session)
    one_more = dataclasses.replace(model, config=dataclasses.replace(model.config,
                                                                     iterations=model.config.iterations + 1))
    args = (s.position, s.quat, s.tracked, session, s.bodies)
    fast = skeleton_cog(*args, model)
    ref = skeleton_cog(*args, model, method="reference")
    more = skeleton_cog(*args, one_more, method="reference")
    np.testing.assert_array_equal(fast["faults"], ref["faults"])
    np.testing.assert_array_equal(fast["has_rider"], ref["has_rider"])
    assert (fast["n_faults"].sum() > 0) == bool(events)           # the swaps and flips are found at all
    np.testing.assert_array_equal(np.isfinite(fast["G"]), np.isfinite(ref["G"]))
    ok = ref["has_rider"]
    assert ok.sum() > 0.9 * s.n_frames
    diff = np.linalg.norm(fast["G"][ok] - ref["G"][ok], axis=-1)
    tol = np.linalg.norm(more["G"][ok] - ref["G"][ok], axis=-1) + 64 * EPS * np.linalg.norm(ref["G"][ok], axis=-1)
    assert np.all(diff <= tol), (diff.max(), tol[np.argmax(diff / tol)])


def test_live_frames_equal_the_batch(ride):
    """One frame per call (the live path, the kernel's plan cached) gives the batch's G and faults exactly: the same
    arithmetic per frame (the damping, 1e-9 of the largest weight, is the joints' in both: s_j < s_p)."""
    s, session, _ = ride
    model = SkeletonModel.estimate(s, session)
    batch = skeleton_cog(s.position, s.quat, s.tracked, session, s.bodies, model)
    live = OnlineSkeleton(session, model=model)
    frames = np.arange(0, s.n_frames, 7)
    out = [live.update(s.position[:, k], s.quat[:, k], s.tracked[:, k], s.bodies) for k in frames]
    np.testing.assert_array_equal(np.array([o["G"] for o in out]), batch["G"][frames])
    np.testing.assert_array_equal(np.array([o["faults"] for o in out]).T, batch["faults"][:, frames])
    assert sum(live.fault_counts.values()) == int(batch["faults"][:, frames].sum())


def test_unknown_method():
    with pytest.raises(ConfigError, match="method"):
        skeleton_cog(np.zeros((1, 3)), np.array([[0, 0, 0, 1.0]]), None, None, ["X"], None, method="fast")


def test_live_calibration_model_is_from_poses_of_the_frames_so_far(ride):
    """After every calibration frame the live model is :meth:`SkeletonModel.from_poses` of the frames up to its last
    refresh: every frame of the first 32, then whenever the frames grew by 1/16, and the last (the same samples and
    order statistics; gaps in one body make the links' sample counts differ). The samples are sums of 3 products of
    numbers <= |v|, so they agree to 8 eps |v|."""
    s, session, _ = ride
    tracked = s.tracked.copy()
    tracked[s.bodies.index("UAL"), 10:25] = False
    n_cal = 120
    live = OnlineSkeleton(session, calibration_frames=n_cal)
    built, refreshes = 0, []
    for k in range(n_cal):
        live.calibrate(s.position[:, k], s.quat[:, k], tracked[:, k], s.bodies)
        n = k + 1
        if n <= 32 or n - built >= n // 16 or n == n_cal:     # the refresh rule, written out
            built = n
            refreshes.append(n)
        if k % 7 and k != n_cal - 1:
            continue
        ref = SkeletonModel.from_poses([s.position[:, :built]], [s.quat[:, :built]], [tracked[:, :built]], s.bodies,
                                       session)
        assert live.model.links == ref.links and live.model.frames == ref.frames
        scale = 8 * EPS * np.abs(ref.vectors).max()
        np.testing.assert_allclose(live.model.vectors, ref.vectors, rtol=0, atol=scale)
        np.testing.assert_allclose(live.model.rel_rot, ref.rel_rot, rtol=0, atol=8 * EPS)
        np.testing.assert_allclose(live.model.threshold_m, ref.threshold_m, rtol=0, atol=scale)
    assert live.calibrated
    assert len(refreshes) < 0.6 * n_cal and refreshes[-1] == n_cal    # bounded: not a model per frame


def test_warm_up_compiles_the_signature_of_the_live_and_batch_calls(ride):
    """After :func:`warm_up` neither a live frame nor a batch adds a compiled signature: the node pays the
    compilation at its start, not on its first frame."""
    s, session, _ = ride
    assert warm_up() >= 0.0
    signatures = list(chain_cog.signatures)
    assert signatures, "warm_up compiled nothing"
    model = SkeletonModel.estimate(s, session)
    OnlineSkeleton(session, model=model).update(s.position[:, 0], s.quat[:, 0], s.tracked[:, 0], s.bodies)
    skeleton_cog(s.position, s.quat, s.tracked, session, s.bodies, model)
    assert list(chain_cog.signatures) == signatures
