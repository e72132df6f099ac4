"""Numpy quaternion helpers against scipy's Rotation (an independent implementation)."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from euc_ros.core.rotations import quat_conjugate, quat_from_rotvec, quat_multiply, rotvec_from_quat


def _same_rotation(a, b):
    # q and -q are the same rotation
    d = np.minimum(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1))
    return d


def test_against_scipy():
    rng = np.random.default_rng(4)
    a = Rotation.random(500, random_state=1)
    b = Rotation.random(500, random_state=2)
    assert np.max(_same_rotation(quat_multiply(a.as_quat(), b.as_quat()), (a * b).as_quat())) < 1e-14
    assert np.max(_same_rotation(quat_conjugate(a.as_quat()), a.inv().as_quat())) < 1e-15
    v = rng.normal(size=(500, 3)) * np.array([[1.0], [1e-3], [1e-9], [2.0], [3.0]]).repeat(100, axis=0)
    assert np.max(_same_rotation(quat_from_rotvec(v), Rotation.from_rotvec(v).as_quat())) < 1e-14
    q = Rotation.from_rotvec(v).as_quat()
    # round trip: rotation angles below pi come back as the same vector (relative to their size, and
    # to rounding of the unit quaternion, ~1e-16 rad)
    back = rotvec_from_quat(q)
    assert np.all(np.linalg.norm(back - Rotation.from_quat(q).as_rotvec(), axis=1) <= 1e-12 * (1 + np.linalg.norm(v, axis=1)))  # noqa: E501


@pytest.mark.parametrize("angle", [0.0, 1e-8, np.pi - 1e-6])
def test_rotvec_edges(angle):
    v = np.array([[0.0, 0.0, angle]])
    assert rotvec_from_quat(quat_from_rotvec(v)) == pytest.approx(v, abs=1e-12)


def test_rotation_matrices_and_yaw_tilt_pitch_match_scipy():
    from scipy.spatial.transform import Rotation

    from euc_ros.core.rotations import YAW_TILT_PITCH_SEQ, rotation_matrices, yaw_tilt_pitch_from_quat

    rng = np.random.default_rng(7)
    angles = np.column_stack([rng.uniform(-np.pi, np.pi, 500), rng.uniform(-1.4, 1.4, 500),
                              rng.uniform(-np.pi, np.pi, 500)])       # tilt within +-80 deg
    q = Rotation.from_euler(YAW_TILT_PITCH_SEQ, angles).as_quat() * rng.uniform(0.5, 2.0, (500, 1))  # not unit
    np.testing.assert_allclose(rotation_matrices(q), Rotation.from_quat(q).as_matrix(), atol=1e-14)
    # arcsin's conditioning at 80 deg tilt is 1/cos(80 deg) ~ 6: round-off 1e-16 x 6 x a few operations
    got = yaw_tilt_pitch_from_quat(q)
    np.testing.assert_allclose(got, angles, atol=1e-12)
    bad = np.array([[np.nan, 0, 0, 1.0], [0, 0, 0, 0.0]])
    assert np.isnan(rotation_matrices(bad)).all() and np.isnan(yaw_tilt_pitch_from_quat(bad)).all()
    assert yaw_tilt_pitch_from_quat(q.reshape(50, 10, 4)).shape == (50, 10, 3)
