"""The generator's files against the recording contract, read back by the project's own readers."""
# covers: euc_ros/core/worldsim/body.py
from __future__ import annotations

import json

import numpy as np
import pytest

from euc_ros.core.io.motive_csv import read_motive_csv
from euc_ros.core.session import load_session
from euc_ros.core.worldsim.body import poses
from euc_ros.core.worldsim.simulate import simulate_ride
from euc_ros.core.worldsim.writers import Capture, write_ride

DURATION = 2.0


@pytest.fixture(scope="module")
def ride():
    return simulate_ride(11, 120.0, duration=DURATION)


def _rot(q):
    """Rotation matrices of quaternions (x, y, z, w) (..., 4), written out for the test."""
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    x, y, z, w = np.moveaxis(q, -1, 0)
    return np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
                     np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
                     np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], -2)


@pytest.mark.parametrize("world_up", ["y", "z"])
def test_the_projects_reader_gives_back_the_poses(ride, tmp_path, world_up):
    cap = Capture(world_up=world_up, flip_quaternion_signs=True)
    paths = write_ride(ride, tmp_path, cap, seed=1, name="take")
    series = read_motive_csv(paths["csv"], world_up=world_up)
    tr = ride.truth
    sp = ride.spec
    # the recording's lab position is the integrator's travel: the warm-up's travel before the first frame too
    x_lab = tr["x"] + ride.stats["x_offset_m"]
    ref = poses(x_lab, tr["gamma"], tr["phi"], sp.rider, sp.plant.R, sp.plant.l_0, sp.place)
    assert list(series.bodies) == list(ref["bodies"])
    assert np.array_equal(series.frame, np.arange(ride.t.size))
    assert np.allclose(series.t, ride.t, rtol=0, atol=1e-12)
    half_digit = 0.5 * 10.0 ** -cap.decimals
    assert np.max(np.abs(series.position - ref["position"])) <= half_digit * (1 + 1e-9)
    # quaternions up to sign; rounding each of 4 components by half a digit, then normalized
    dot = np.abs(np.sum(series.quat * ref["quat"], axis=-1))
    assert np.max(1 - dot) <= 4 * half_digit
    assert series.tracked.all()


@pytest.mark.parametrize("rate", [100.0, 240.0, 360.0])
def test_rates_drops_and_occlusions(tmp_path, rate):
    r = simulate_ride(12, rate, duration=1.0)
    cap = Capture(world_up="y", drop_rate=0.05, occlusions=3, occlusion_frames=(3, 6))
    paths = write_ride(r, tmp_path, cap, seed=4)
    series = read_motive_csv(paths["csv"], world_up="y")
    assert series.rate_hz == pytest.approx(rate)
    assert np.array_equal(series.frame, paths["kept_frames"])
    assert np.allclose(series.t, series.frame / rate, rtol=0, atol=1e-12)
    assert 0 < (~series.tracked).sum() <= 3 * 6
    assert np.all(np.isnan(series.position[~series.tracked]))
    header = paths["csv"].read_text(encoding="utf-8").splitlines()[0].split(",")
    meta = dict(zip(header[::2], header[1::2], strict=False))
    assert meta["Format Version"] == "1.23" and meta["Rotation Type"] == "Quaternion"
    assert meta["Length Units"] == "Meters" and int(meta["Total Exported Frames"]) == series.frame.size


def test_session_cog_is_the_models_g_and_the_angles_are_the_truth(ride, tmp_path):
    """Noise-free: the session's weighted segment CoMs give G = A + h (sin phi, cos phi), and E gives gamma."""
    cap = Capture(world_up="y", decimals=9)
    paths = write_ride(ride, tmp_path, cap, seed=0)
    session = load_session(paths["session"])
    series = read_motive_csv(paths["csv"], world_up=session.world_up)
    names = list(session.rider.segments)
    f = np.array([session.rider.segments[k].mass_fraction for k in names])
    off = np.array([session.rider.segments[k].com_offset for k in names])
    idx = [series.bodies.index(k) for k in names]
    R = _rot(series.quat[idx])                                   # (13, n, 3, 3)
    com = series.position[idx] + np.einsum("knij,kj->kni", R, off)
    G = np.einsum("k,kni->ni", f, com) / f.sum()
    truth = json.loads(paths["truth"].read_text(encoding="utf-8"))
    G_true = np.array(truth["G_world_z_up"])
    # positions rounded to 1e-9 m, rotations to ~1e-9 rad over offsets below 0.3 m
    assert np.max(np.abs(G - G_true)) <= 2e-9
    # the model's geometry from the EUC's pose and the session: C, A, then the angle of A-G and gamma
    e = series.bodies.index(session.euc.body)
    RE = _rot(series.quat[e])
    C = series.position[e] + RE @ np.asarray(session.euc.pivot_to_wheel_center)
    A = C - session.euc.l0 * RE[:, :, 2]
    fwd = RE[:, :2, 0] / np.linalg.norm(RE[:, :2, 0], axis=1, keepdims=True)   # heading: the body x axis on the ground
    d = G - A
    phi = np.arctan2(d[:, 0] * fwd[:, 0] + d[:, 1] * fwd[:, 1], d[:, 2])
    gamma = np.arctan2(-RE[:, 2, 0], RE[:, 2, 2])
    assert np.max(np.abs(phi - ride.truth["phi"])) <= 1e-8
    assert np.max(np.abs(gamma - ride.truth["gamma"])) <= 1e-8
    assert truth["h_m"] == pytest.approx(ride.h)
    assert np.max(np.abs(np.linalg.norm(d, axis=1) - ride.h)) <= 1e-8


def test_reproducible_by_seed(tmp_path):
    a = simulate_ride(13, 120.0, duration=1.0)
    b = simulate_ride(13, 120.0, duration=1.0)
    c = simulate_ride(14, 120.0, duration=1.0)
    cap = Capture(noise_pos_mm=0.2, noise_rot_deg=0.5, drop_rate=0.02, occlusions=2)
    pa = write_ride(a, tmp_path / "a", cap, seed=5)
    pb = write_ride(b, tmp_path / "b", cap, seed=5)
    pc = write_ride(b, tmp_path / "c", cap, seed=6)
    assert pa["csv"].read_bytes() == pb["csv"].read_bytes()
    assert pa["truth"].read_bytes() == pb["truth"].read_bytes()
    assert pa["csv"].read_bytes() != pc["csv"].read_bytes()          # another capture seed
    assert not np.array_equal(a.truth["phi"], c.truth["phi"])          # another ride seed
