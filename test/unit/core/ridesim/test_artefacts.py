"""The soft-tissue artefact generator, measured from its output.

Every amplitude, band and fault is measured on the returned series against the clean one (the
generator's settings are not read back). Tolerances: the sliding is scaled to its RMS exactly, so the
only slack is the coloured noise added on top (switched off where the sliding itself is measured).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from euc_ros.core.errors import ConfigError
from euc_ros.core.ridesim.artefacts import SoftTissueArtefacts, apply_artefacts, perturb_session
from euc_ros.core.ridesim.mocap_synth import MocapNoise
from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
from euc_ros.core.session import default_session


@pytest.fixture(scope="module")
def clean():
    ride = simulate_ride(RideConfig(maneuver="acceleration", runs=1, seed=5, duration_s=4.0,
                                    noise=MocapNoise.none()))
    return ride.runs[0].mocap_clean


def _body_frame_slide(out, clean):
    rot = Rotation.from_quat(clean.quat.reshape(-1, 4)).as_matrix().reshape(clean.quat.shape[:2] + (3, 3))
    return np.einsum("bnji,bnj->bni", rot, out.position - clean.position)


def _angles(out, clean):
    r = Rotation.from_quat(clean.quat.reshape(-1, 4)).inv() * Rotation.from_quat(out.quat.reshape(-1, 4))
    return r.magnitude().reshape(clean.quat.shape[:2])


NO_NOISE = dict(noise_pos_rms_m=0.0, noise_rot_rms_deg=0.0)


@pytest.mark.parametrize("rms_m", [0.002, 0.008, 0.015])
def test_sliding_rms_and_band(clean, rms_m):
    out, events = apply_artefacts(clean, SoftTissueArtefacts(slide_rms_m=rms_m, slide_rot_rms_deg=2.0, **NO_NOISE),
                                  np.random.default_rng(1))
    assert events == []
    d = _body_frame_slide(out, clean)
    rider = [i for i, b in enumerate(clean.bodies) if b != "E"]
    e = clean.bodies.index("E")
    rms = np.sqrt(np.mean(np.sum(d ** 2, -1), axis=1))
    np.testing.assert_allclose(rms[rider], rms_m, rtol=1e-9)
    assert rms[e] == 0.0
    # all power within 0.3-3 Hz (the band limitation is exact on the run's Fourier grid)
    f = np.fft.rfftfreq(clean.n_frames, 1.0 / clean.rate_hz)
    p = np.sum(np.abs(np.fft.rfft(d[rider], axis=1)) ** 2, axis=(0, 2))
    inside = (f >= 0.3) & (f <= 3.0)
    assert p[inside].sum() / p.sum() > 1 - 1e-9
    # smooth: the frame-to-frame step is far below the amplitude (3 Hz at 120 Hz: 2 pi 3/120 of it)
    step = np.sqrt(np.mean(np.sum(np.diff(d[rider], axis=1) ** 2, -1)))
    assert step < 2 * math.pi * 3.0 / clean.rate_hz * rms_m
    ang = _angles(out, clean)
    np.testing.assert_allclose(np.sqrt(np.mean(ang[rider] ** 2, axis=1)), math.radians(2.0), rtol=1e-6)


def test_sliding_follows_the_acceleration(clean):
    """With accel_share c the slide correlates with -a (band-limited, body frame) by about sqrt(c)."""
    rot = Rotation.from_quat(clean.quat.reshape(-1, 4)).as_matrix().reshape(clean.quat.shape[:2] + (3, 3))
    dt = 1.0 / clean.rate_hz
    acc = np.gradient(np.gradient(clean.position, dt, axis=1), dt, axis=1)
    acc_b = np.einsum("bnji,bnj->bni", rot, acc)
    f = np.fft.rfftfreq(clean.n_frames, dt)
    A = np.fft.rfft(acc_b - acc_b.mean(1, keepdims=True), axis=1) * ((f >= 0.3) & (f <= 3.0))[None, :, None]
    acc_band = np.fft.irfft(A, n=clean.n_frames, axis=1)
    rider = [i for i, b in enumerate(clean.bodies) if b != "E"]

    def corr(share, seed):
        out, _ = apply_artefacts(clean, SoftTissueArtefacts(slide_rms_m=0.01, accel_share=share, **NO_NOISE),
                                 np.random.default_rng(seed))
        d = _body_frame_slide(out, clean)[rider]
        x, y = d.reshape(len(rider), -1), -acc_band[rider].reshape(len(rider), -1)
        # per body (each body's sliding is scaled to its own RMS), then averaged
        return float(np.mean(np.sum(x * y, 1) / np.sqrt(np.sum(x * x, 1) * np.sum(y * y, 1))))

    full = corr(1.0, 2)
    assert full > 0.99
    half = np.mean([corr(0.5, s) for s in range(4)])
    assert 0.5 < half < 0.9          # sqrt(0.5) = 0.71, the random part is not exactly orthogonal
    assert abs(np.mean([corr(0.0, s) for s in range(4)])) < 0.25


def test_coloured_noise(clean):
    out, _ = apply_artefacts(clean, SoftTissueArtefacts(slide_rms_m=0.0, slide_rot_rms_deg=0.0,
                                                        noise_pos_rms_m=2e-4, noise_rot_rms_deg=0.5,
                                                        noise_corner_hz=5.0), np.random.default_rng(3))
    e = out.position - clean.position
    rms = np.sqrt(np.mean(np.sum(e ** 2, -1), axis=1))
    np.testing.assert_allclose(rms, 2e-4, rtol=1e-9)
    # coloured: neighbouring frames are correlated (white noise: ~0); a 5 Hz first-order low-pass
    # sampled at 120 Hz has a lag-1 autocorrelation near exp(-2 pi 5/120) = 0.77
    x = e - e.mean(1, keepdims=True)
    r1 = np.sum(x[:, 1:] * x[:, :-1]) / np.sum(x * x)
    assert 0.6 < r1 < 0.9
    ang = _angles(out, clean)
    np.testing.assert_allclose(np.sqrt(np.mean(ang ** 2, axis=1)), math.radians(0.5), rtol=0.05)


def test_swaps_and_flips_where_stated(clean):
    art = SoftTissueArtefacts(slide_rms_m=0.0, slide_rot_rms_deg=0.0, swaps=3, flips=3, **NO_NOISE)
    out, events = apply_artefacts(clean, art, np.random.default_rng(7))
    assert [e.kind for e in events] == ["swap"] * 3 + ["flip"] * 3
    ang = np.degrees(_angles(out, clean))
    jump = np.linalg.norm(out.position - clean.position, axis=-1)
    faulty = np.zeros(ang.shape, bool)
    for e in events:
        i = clean.bodies.index(e.body)
        assert e.body != "E"
        faulty[i, e.start:e.stop] = True
        if e.kind == "flip":
            assert 1 <= e.stop - e.start <= 5
            # a flip on top of a swap of the same body would compose: only check clean flips
            np.testing.assert_allclose(ang[i, e.start:e.stop], 180.0, atol=1e-6)
            assert np.all(jump[i, e.start:e.stop] < 1e-12)
        else:
            assert np.all((jump[i, e.start:e.stop] >= 0.02 - 1e-12) & (jump[i, e.start:e.stop] <= 0.05 + 1e-12))
            assert np.all((ang[i, e.start:e.stop] >= 25 - 1e-6) & (ang[i, e.start:e.stop] <= 40 + 1e-6))
    # nothing outside the stated frames
    assert np.all(ang[~faulty] < 1e-6) and np.all(jump[~faulty] < 1e-12)
    assert out.meta["artefacts"]["events"][0]["kind"] == "swap"


def test_seeded(clean):
    art = SoftTissueArtefacts(slide_rms_m=0.01, swaps=1, flips=1)
    a, ea = apply_artefacts(clean, art, np.random.default_rng(11))
    b, eb = apply_artefacts(clean, art, np.random.default_rng(11))
    c, _ = apply_artefacts(clean, art, np.random.default_rng(12))
    assert ea == eb
    np.testing.assert_array_equal(a.position, b.position)
    np.testing.assert_array_equal(a.quat, b.quat)
    assert not np.allclose(a.position, c.position)


def test_perturbed_session_offsets():
    s = default_session("z")
    head = s.rider.segments["H"].com_offset
    p = perturb_session(s, np.random.default_rng(0), offset_error_m=(0.01, 0.03))
    names, fr, off = s.segment_arrays()
    names2, fr2, off2 = p.segment_arrays()
    assert names == names2
    np.testing.assert_array_equal(fr, fr2)
    d = np.linalg.norm(off2 - off, axis=1)
    assert np.all((d >= 0.01 - 1e-12) & (d <= 0.03 + 1e-12))
    assert p.euc == s.euc
    assert s.rider.segments["H"].com_offset == head != p.rider.segments["H"].com_offset   # the original is untouched


def test_bad_settings():
    with pytest.raises(ConfigError, match="band_hz"):
        SoftTissueArtefacts(band_hz=(3.0, 0.3))
    with pytest.raises(ConfigError, match="accel_share"):
        SoftTissueArtefacts(accel_share=1.5)


def test_joint_angle_sliding_is_the_gain_times_the_angle_change():
    """A thigh that swings 6 deg against a still shank and EUC: its pivot moves by the gain (0.4 mm/deg,
    scaled by joint_mm_per_deg) times the angle's change from its median, in a fixed direction; the still
    bodies do not move (their angles to the EUC do not change)."""
    from euc_ros.core.mocap.series import MocapSeries
    from euc_ros.core.ridesim.artefacts import JOINT_GAIN_MM_PER_DEG

    n, rate = 600, 120.0
    t = np.arange(n) / rate
    theta = np.deg2rad(6.0) * np.sin(2 * np.pi * 0.4 * t)
    quat = np.zeros((3, n, 4))
    quat[:, :, 3] = 1.0
    quat[0] = Rotation.from_rotvec(np.outer(theta, [0.0, 1.0, 0.0])).as_quat()
    pos = np.zeros((3, n, 3))
    pos[:, :, 2] = [[0.9], [0.5], [0.3]]
    clean = MocapSeries(t=t, frame=np.arange(n), bodies=["TR", "LR", "E"], position=pos, quat=quat,
                        tracked=np.ones((3, n), bool), mean_marker_error=np.zeros((3, n)), name="swing", meta={})
    art = SoftTissueArtefacts(slide_rms_m=0.0, slide_rot_rms_deg=0.0, noise_pos_rms_m=0.0, noise_rot_rms_deg=0.0,
                              joint_mm_per_deg=2.0)
    out, _ = apply_artefacts(clean, art, np.random.default_rng(3))
    moved = np.linalg.norm(out.position - pos, axis=-1)
    change_deg = np.rad2deg(np.abs(theta - np.median(theta)))
    np.testing.assert_allclose(moved[0], 2.0 * JOINT_GAIN_MM_PER_DEG["TR"] * 1e-3 * change_deg, atol=1e-12)
    np.testing.assert_array_equal(moved[1:], 0.0)
    # in the thigh's own frame (where the skin slides) the direction is one, and its opposite
    d = np.einsum("nji,nj->ni", Rotation.from_quat(quat[0]).as_matrix(), out.position[0] - pos[0])
    big = moved[0] > 0.5 * moved[0].max()
    directions = d[big] / moved[0][big, None]
    assert np.ptp(np.abs(directions), axis=0).max() < 1e-9


def test_perturbed_session_fractions_and_masses():
    s = default_session("z")
    rng_draws = [perturb_session(s, np.random.default_rng(k), fraction_sd=0.1, mass_error_kg=0.5) for k in range(200)]
    base = perturb_session(s, np.random.default_rng(0))
    _, fr, off = s.segment_arrays()
    _, fr0, off0 = rng_draws[0].segment_arrays()
    np.testing.assert_allclose(off0, base.segment_arrays()[2])       # the offsets drawn first, as without the rest
    rel = []
    for p in rng_draws:
        _, f2, _ = p.segment_arrays()
        assert f2.sum() == pytest.approx(fr.sum(), rel=1e-12)
        rel.append(f2[fr > 0] / fr[fr > 0] - 1)
        assert abs(p.rider.mass - s.rider.mass) <= 0.5 and abs(p.euc.body_mass - s.euc.body_mass) <= 0.5
    # the relative moves scatter by the stated 0.1, less the rescaling's share (about 1/sqrt(segments)):
    # their standard deviation over 200 sessions lies within 0.07-0.11
    assert 0.07 < float(np.std(np.concatenate(rel))) < 0.11
    with pytest.raises(ConfigError, match="fraction_sd"):
        perturb_session(s, np.random.default_rng(0), fraction_sd=-0.1)
