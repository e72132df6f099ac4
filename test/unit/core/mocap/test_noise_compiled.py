"""The compiled re-noising gives what the rotation algebra gives: positions plus the scaled draws, and each
quaternion (normalised) times the quaternion of its scaled rotation-vector draw
(:func:`~euc_ros.core.rotations.quat_from_rotvec`, :func:`~euc_ros.core.rotations.quat_multiply`), with
non-finite quaternions and bodies not turned left as given."""
from __future__ import annotations

import numpy as np

from euc_ros.core.mocap.noise_compiled import perturb_poses
from euc_ros.core.rotations import quat_from_rotvec, quat_multiply


def test_perturb_poses_equals_the_rotation_algebra():
    rng = np.random.default_rng(5)
    b, m = 4, 3000
    position = rng.uniform(-15.0, 15.0, (b, m, 3))
    quat = rng.standard_normal((b, m, 4)) * 2.0
    quat[1, ::97] = np.nan
    z = rng.standard_normal((b, m, 6)).astype(np.float32)
    z[2, :50, 3:] *= 1e-9                                       # rotations below the small-angle branch's 1e-6
    pos_scale = np.array([2e-4, -2e-4, 1e-3, 0.0])
    rot_scale = np.array([0.01, -0.01, 0.2, 0.05])
    rotate = np.array([True, True, True, False])
    pos, q = perturb_poses(position, quat, z, pos_scale, rot_scale, rotate, 0)
    # frames further on: the same arithmetic on those frames
    pos2, q2 = perturb_poses(position, quat, z[:, 1000:], pos_scale, rot_scale, rotate, 1000)
    np.testing.assert_array_equal(pos2, pos[:, 1000:])
    np.testing.assert_array_equal(q2, q[:, 1000:])

    z64 = z.astype(float)
    np.testing.assert_array_equal(pos, position + pos_scale[:, None, None] * z64[..., :3])
    unit = quat / np.linalg.norm(quat, axis=-1, keepdims=True)
    want = quat_multiply(unit, quat_from_rotvec(rot_scale[:, None, None] * z64[..., 3:]))
    turned = np.isfinite(quat).all(-1) & rotate[:, None]
    # both are unit quaternions from ~20 operations: a few eps apart
    np.testing.assert_allclose(q[turned], want[turned], rtol=0, atol=32 * np.finfo(float).eps)
    np.testing.assert_array_equal(q[~turned], quat[~turned])
    assert (~turned).sum() == m + 31                           # the body not turned and the NaN quaternions
