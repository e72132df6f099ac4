"""The compiled segments geometry gives what the numpy ``frame_geometry`` gives, frame by frame.

Random poses over a large lab (positions up to 20 m, any orientation), with untracked, NaN and zero-norm
quaternion samples, an absent EUC body and an absent rider segment. The two compute the same formulas in
the same order; they may differ where the transcendental functions' implementations differ in the last bit,
so the tolerance is a few units in the last place of each quantity's scale (a chain of ~30 operations).
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from euc_ros.core.states.geometry import GEOMETRY_KEYS, _compiled_geometry, frame_geometry

#: Round-off of ~30 chained operations on quantities of size ``scale``: 64 units in the last place.
ULPS = 64 * np.finfo(float).eps


@pytest.fixture(scope="module")
def session(short_ride):
    from euc_ros.core.session import load_session

    out, _ = short_ride
    return load_session(out / "session.yaml")


def random_poses(rng, bodies, n):
    b = len(bodies)
    pos = rng.uniform(-20.0, 20.0, (b, n, 3))
    quat = rng.standard_normal((b, n, 4)) * rng.uniform(0.1, 3.0, (b, n, 1))     # any norm: normalised inside
    tracked = rng.random((b, n)) > 0.05
    pos[rng.random((b, n)) < 0.03] = np.nan
    quat[rng.random((b, n)) < 0.03] = np.nan
    quat[rng.random((b, n)) < 0.01] = 0.0
    return pos, quat, tracked


def check_equal(session, pos, quat, tracked, bodies):
    with np.errstate(invalid="ignore", divide="ignore"):       # the zero quaternions
        ref = frame_geometry(pos, quat, tracked, session, bodies)
    got = _compiled_geometry(pos, quat, tracked, session, list(bodies))
    for key in GEOMETRY_KEYS:
        a, b = np.asarray(ref[key]), np.asarray(got[key])
        assert a.shape == b.shape and a.dtype == b.dtype, key
        if a.dtype.kind != "f":
            np.testing.assert_array_equal(a, b, err_msg=key)
            continue
        np.testing.assert_array_equal(np.isnan(a), np.isnan(b), err_msg=key)
        scale = 40.0 if key in ("C", "G") else np.pi
        np.testing.assert_allclose(b, a, rtol=0.0, atol=ULPS * scale, err_msg=key)
    return ref


def test_compiled_geometry_equals_numpy_on_random_poses(session):
    rng = np.random.default_rng(20261127)
    names, _, _ = session.segment_arrays()
    bodies = [session.euc.body] + list(names)
    pos, quat, tracked = random_poses(rng, bodies, 5000)
    ref = check_equal(session, pos, quat, tracked, bodies)
    # the cases are all there: frames with and without the EUC and the rider
    assert 0 < ref["has_euc"].sum() < ref["has_euc"].size
    assert 0 < ref["has_rider"].sum() < ref["has_rider"].size


def test_compiled_geometry_without_the_euc_body_or_a_segment(session):
    rng = np.random.default_rng(7)
    names, fractions, _ = session.segment_arrays()
    weighted = [nm for nm, f in zip(names, fractions) if f > 0]
    # no EUC body: every angle NaN, the rider's G still there
    bodies = list(names)
    pos, quat, tracked = random_poses(rng, bodies, 500)
    ref = check_equal(session, pos, quat, tracked, bodies)
    assert not ref["has_euc"].any() and ref["has_rider"].any()
    # a weighted segment absent: no G anywhere
    bodies = [session.euc.body] + [nm for nm in names if nm != weighted[0]]
    pos, quat, tracked = random_poses(rng, bodies, 500)
    ref = check_equal(session, pos, quat, tracked, bodies)
    assert not ref["has_rider"].any()


def test_block_geometry_uses_the_compiled_path_with_the_recordings_numbers(session, short_ride):
    from euc_ros.core.io.motive_csv import read_motive_csv
    from euc_ros.core.states.geometry import block_geometry

    out, _ = short_ride
    series = read_motive_csv(next(out.glob("*.csv")), world_up="y")
    series = dataclasses.replace(series, position=series.position + np.array([7.5, -12.0, 0.0]))   # far from origin
    geo, _, _ = block_geometry(series, session, 0)
    ref = frame_geometry(series.position, series.quat, series.tracked, session, series.bodies)
    for key in ("phi_hinge", "gamma", "C", "G"):
        np.testing.assert_allclose(geo[key], ref[key], rtol=0.0, atol=ULPS * (40.0 if key in ("C", "G") else np.pi))


def test_link_vectors_are_the_pivot_difference_in_the_first_body_frame():
    from euc_ros.core.rotations import rotation_matrices
    from euc_ros.core.states.geometry_compiled import link_vectors

    rng = np.random.default_rng(9)
    pos = rng.uniform(-20.0, 20.0, (3, 4000, 3))
    quat = rng.standard_normal((3, 4000, 4))
    usable = rng.random((3, 4000)) > 0.1
    vector = np.array([0.1, -0.2, 0.45])
    d, both = link_vectors(pos, quat, usable, 2, 0, vector)
    np.testing.assert_array_equal(both, usable[2] & usable[0])
    # independent: the rotation matrix of body 2 transposed times the pivot difference
    R = rotation_matrices(quat[2])
    want = np.einsum("nji,nj->ni", R, pos[0] - pos[2]) - vector
    np.testing.assert_allclose(d[both], want[both], rtol=0, atol=ULPS * 80.0)
