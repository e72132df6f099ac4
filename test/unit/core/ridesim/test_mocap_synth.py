"""Synthesized mocap: segments reproduce the true CoG, E the wheel centre; noise, gaps and drops.

Tolerances: synthesized poses against the truth they were built from: a handful of rotations and
additions of <= 1 m vectors (one ulp 2.2e-16): atol 1e-12 is ~4500 ulps; angles recovered through
arcsin/atan2 of such entries: atol 1e-9.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from euc_ros.core.rotations import rotate, yaw_tilt_pitch_from_quat
from euc_ros.core.session import SEGMENT_BODIES


def _cog_from_segments(series, session):
    """CoG the way an analysis reconstructs it: sum f_i (pivot_i + R_i com_offset_i) (docs/session.md, rigid bodies)."""
    names, fr, off = session.segment_arrays()
    idx = [series.bodies.index(n) for n in names]
    com = series.position[idx] + rotate(series.quat[idx], off[:, None, :])
    return np.einsum("b,bni->ni", fr, com)


def _wheel_centre(series, session):
    i = series.bodies.index(session.euc.body)
    return series.position[i] + rotate(series.quat[i], np.asarray(session.euc.pivot_to_wheel_center))


def test_bodies_are_table_2(ride_decel):
    assert ride_decel.runs[0].mocap.bodies == list(SEGMENT_BODIES) + ["E"]


def test_noise_free_cog_from_segments_is_the_true_g(ride_decel, ride_fig8):
    for ride in (ride_decel, ride_fig8):
        for run in ride.runs:
            G = _cog_from_segments(run.mocap_clean, ride.session)
            assert np.abs(G - run.G).max() < 1e-9
            np.testing.assert_allclose(np.linalg.norm(run.G - run.A, axis=1), run.h, atol=1e-12)


def test_wheel_centre_from_e_is_the_true_c_and_e_has_the_yaw_tilt_pitch(ride_decel, ride_fig8):
    for ride in (ride_decel, ride_fig8):
        for run in ride.runs:
            C = _wheel_centre(run.mocap_clean, ride.session)
            assert np.abs(C - run.C).max() < 1e-12
            # C sits at the rolling radius above the floor along the tilted wheel plane
            np.testing.assert_allclose(C[:, 2], ride.params_true.R * np.cos(run.theta), atol=1e-12)
            ang = yaw_tilt_pitch_from_quat(run.mocap_clean.quat[-1])
            d_psi = np.angle(np.exp(1j * (ang[:, 0] - run.psi)))
            assert np.abs(d_psi).max() < 1e-9
            np.testing.assert_allclose(ang[:, 1], run.theta, atol=1e-9)
            np.testing.assert_allclose(ang[:, 2], run.q[:, 1], atol=1e-9)


def test_planar_coordinates_are_recovered_in_the_moving_frame(ride_fig8):
    """In Rz(psi) Rx(theta), A - C = l0 (-sin gamma, -cos gamma) and G - A = h (sin phi, cos phi)."""
    ride = ride_fig8
    run = ride.runs[0]
    Rm = Rotation.from_euler("ZX", np.column_stack([run.psi, run.theta])).as_matrix()
    ca = np.einsum("nji,nj->ni", Rm, run.A - run.C)
    ag = np.einsum("nji,nj->ni", Rm, run.G - run.A)
    l0 = ride.params_true.l0
    np.testing.assert_allclose(ca[:, 0], -l0 * np.sin(run.q[:, 1]), atol=1e-12)
    np.testing.assert_allclose(ca[:, 2], -l0 * np.cos(run.q[:, 1]), atol=1e-12)
    np.testing.assert_allclose(ag[:, 0], run.h * np.sin(run.q[:, 2]), atol=1e-12)
    np.testing.assert_allclose(ag[:, 2], run.h * np.cos(run.q[:, 2]), atol=1e-12)
    assert np.abs(ca[:, 1]).max() < 1e-12 and np.abs(ag[:, 1]).max() < 1e-12


def test_noise_has_the_papers_magnitude(ride_noisy):
    run = ride_noisy.runs[0]
    rec, clean = run.mocap, run.mocap_clean
    idx = np.searchsorted(clean.frame, rec.frame)
    ok = rec.tracked
    dp = (rec.position - clean.position[:, idx])[ok]
    assert abs(dp.std() - 0.2e-3) < 0.02e-3 and abs(dp.mean()) < 0.02e-3
    r_rec = Rotation.from_quat(rec.quat[ok])
    r_clean = Rotation.from_quat(clean.quat[:, idx][ok])
    ang = (r_clean.inv() * r_rec).magnitude()
    assert abs(np.degrees(np.sqrt(np.mean(ang**2))) - 0.5) < 0.05
    # the reconstructed CoG stays within the noise (a few mm), not off by a modelling error
    G = _cog_from_segments(rec, ride_noisy.session)
    all_tracked = ok.all(axis=0)
    err = np.linalg.norm(G[all_tracked] - run.G[idx][all_tracked], axis=1)
    assert 1e-4 < np.median(err) < 5e-3


def test_occlusion_gaps_are_nan_and_dropped_frames_are_missing(ride_noisy):
    run = ride_noisy.runs[0]
    rec = run.mocap
    assert not rec.tracked.all()
    assert np.isnan(rec.position[~rec.tracked]).all() and np.isnan(rec.quat[~rec.tracked]).all()
    assert np.isfinite(rec.position[rec.tracked]).all()
    n = run.t.size
    assert 0 < n - rec.n_frames < 0.06 * n
    assert rec.frame[0] == 0 and rec.frame[-1] == n - 1
    assert np.diff(rec.frame).max() > 1 and np.all(np.diff(rec.frame) >= 1)
    np.testing.assert_allclose(rec.t, rec.frame / 120.0)
    # gaps are contiguous stretches of one body
    stretches = sum(int(np.sum(np.diff(np.r_[0, (~tr).astype(int), 0]) == 1)) for tr in rec.tracked)
    assert 1 <= stretches <= 3  # gaps of one body may merge


def test_numpy_rotation_conversions_are_scipys():
    """rotations_to_quats and rotvec_to_quats compute scipy's from_matrix and from_rotvec (to a few ulps), on every
    branch of Shepperd's method and on both sides of the rotation-vector series."""
    from euc_ros.core.ridesim.mocap_synth import rotations_to_quats, rotvec_to_quats
    from euc_ros.core.rotations import canonical_quat

    rng = np.random.default_rng(3)
    rots = Rotation.random(400, random_state=4)
    flips = Rotation.from_rotvec(np.pi * np.eye(3))      # near-180 deg turns: x, y, z largest
    all_rots = Rotation.concatenate([rots, flips, Rotation.identity(1)])
    R = all_rots.as_matrix()
    np.testing.assert_allclose(rotations_to_quats(R), canonical_quat(Rotation.from_matrix(R).as_quat()), atol=4e-16)
    assert rotations_to_quats(R[:6].reshape(3, 2, 3, 3)).shape == (3, 2, 4)
    rv = rng.normal(size=(500, 3)) * np.repeat([1e-5, 1e-3, 0.5, 3.0], 125)[:, None]
    np.testing.assert_allclose(rotvec_to_quats(rv), Rotation.from_rotvec(rv).as_quat(), atol=4e-16)


def test_yaw_tilt_pitch_matrices_are_the_quaternions_rotations():
    from euc_ros.core.ridesim.simulate import yaw_tilt_pitch_matrices
    from euc_ros.core.rotations import quat_from_yaw_tilt_pitch, rotation_matrices

    rng = np.random.default_rng(5)
    a = rng.uniform(-3, 3, (3, 50))
    np.testing.assert_allclose(yaw_tilt_pitch_matrices(*a), rotation_matrices(quat_from_yaw_tilt_pitch(*a)),
                               atol=1e-15)
