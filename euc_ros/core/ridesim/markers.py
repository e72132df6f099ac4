"""Marker-level mocap: noisy markers on each rigid body and Motive-like rigid-body fits.

:func:`~euc_ros.core.ridesim.mocap_synth.corrupt` adds the noise to the poses directly (a small
rotation about the pivot plus independent position noise). Motive does not: it sees markers and
computes each rigid body's pose by a least-squares rigid fit of the body's marker layout. This
module does the same on a noise-free :class:`~euc_ros.core.mocap.series.MocapSeries`:

* each body gets a **marker layout**, the markers' positions in the body frame relative to the
  pivot (``(k, 3)``, 3-6 markers; :func:`random_layout` makes asymmetric ones of a given spread,
  their centroid where asked: at the pivot, as Motive creates a rigid body, or moved);
* the world markers of every frame, ``P + R m_i``, get i.i.d. Gaussian noise ``N(0, sigma^2)`` per
  axis, marker and frame;
* each frame's pose is recovered by the Kabsch/SVD fit (:func:`fit_poses`, vectorized over the
  frames, reflections excluded) and reported at the body's pivot: ``P = w_bar - R m_bar``.

Noise structure of the fit (small angles; ``r_i = m_i - m_bar`` the layout about its centroid):
the orientation error ``delta`` (``R_fit = R exp([delta]_x)``, body frame) has the covariance
``sigma^2 (sum_i |r_i|^2 I - r_i r_i^T)^-1`` (:func:`rotation_covariance`), the centroid the
covariance ``sigma^2 / k I``, and the two are uncorrelated (``sum_i r_i = 0``). So the rotation
noise turns the body about its markers' **centroid**; a pivot ``d = m_bar`` away from the centroid
carries ``R delta x (-d)`` of it on top of the centroid's noise.

Units: SI (m, rad). Pure numpy.
"""
from __future__ import annotations

import math

import numpy as np

from euc_ros.core.errors import ConfigError
from euc_ros.core.mocap.series import MocapSeries
from euc_ros.core.ridesim.mocap_synth import rotations_to_quats
from euc_ros.core.rotations import rotation_matrices


def random_layout(rng: np.random.Generator, n_markers: int = 4, spread_m: float = 0.1,
                  centroid=(0.0, 0.0, 0.0), aspect=(1.0, 0.8, 0.5), min_distance_gap: float = 0.01,
                  max_tries: int = 1000) -> np.ndarray:
    """An asymmetric marker layout ``(n_markers, 3)`` [m], body frame relative to the pivot.

    Points are drawn uniformly in a box of the given aspect (a body's markers are usually spread
    less in depth), centred on their centroid, scaled so that the largest inter-marker distance is
    ``spread_m``, and shifted so that their centroid is ``centroid``. A draw is kept only if every
    two inter-marker distances differ by at least ``min_distance_gap * spread_m`` and no two
    markers are closer than ``0.2 * spread_m`` (Motive needs distinct distances to identify the
    markers; the layout then has no symmetry).

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the points.
    n_markers : int
        Markers, 3 to 12.
    spread_m : float
        Largest inter-marker distance [m].
    centroid : array_like
        Centroid of the markers (3,), body frame [m].
    aspect : array_like
        Relative extents of the box (3,).
    min_distance_gap : float
        Smallest difference of two inter-marker distances, a fraction of ``spread_m``.
    max_tries : int
        Draws before giving up.

    Returns
    -------
    numpy.ndarray
        Marker positions (n_markers, 3) [m].

    Raises
    ------
    ConfigError
        For a marker count or spread out of range, or when no draw qualifies.
    """
    if not 3 <= n_markers <= 12:
        raise ConfigError(f"a rigid body needs 3-12 markers, got {n_markers}", key="n_markers")
    if not (math.isfinite(spread_m) and spread_m > 0):
        raise ConfigError(f"spread must be > 0 m, got {spread_m}", key="spread_m")
    iu = np.triu_indices(n_markers, 1)
    for _ in range(max_tries):
        pts = rng.uniform(-0.5, 0.5, (n_markers, 3)) * np.asarray(aspect, dtype=float)
        pts = pts - pts.mean(axis=0)
        dist = np.linalg.norm(pts[:, None] - pts[None], axis=-1)[iu]
        pts = pts * (spread_m / dist.max())
        dist = dist * (spread_m / dist.max())
        gaps = np.diff(np.sort(dist))
        if dist.min() >= 0.2 * spread_m and (gaps.size == 0 or gaps.min() >= min_distance_gap * spread_m):
            return pts + np.asarray(centroid, dtype=float)
    raise ConfigError(f"no asymmetric layout of {n_markers} markers found in {max_tries} draws",
                      key="n_markers")


def rotation_covariance(layout, sigma_m: float) -> np.ndarray:
    """Small-angle covariance (3, 3) [rad^2] of a fitted orientation, body frame.

    ``sigma^2 (sum_i |r_i|^2 I - r_i r_i^T)^-1`` with ``r_i`` the markers about their centroid.

    Parameters
    ----------
    layout : array_like
        Marker positions (k, 3), body frame [m].
    sigma_m : float
        Marker noise per axis [m].

    Returns
    -------
    numpy.ndarray
        The covariance (3, 3) [rad^2].
    """
    r = np.asarray(layout, dtype=float)
    r = r - r.mean(axis=0)
    inertia = np.einsum("ij,ij->", r, r) * np.eye(3) - r.T @ r
    return sigma_m ** 2 * np.linalg.inv(inertia)


def rms_angle_deg(layout, sigma_m: float) -> float:
    """RMS rotation angle [deg] of a fitted orientation (small angles): ``sqrt(trace(cov))``.

    Parameters
    ----------
    layout : array_like
        Marker positions (k, 3), body frame [m].
    sigma_m : float
        Marker noise per axis [m].

    Returns
    -------
    float
        The RMS angle [deg].
    """
    return math.degrees(math.sqrt(np.trace(rotation_covariance(layout, sigma_m))))


def sigma_for_angle(layout, angle_deg: float) -> float:
    """Marker noise [m] that gives the layout an RMS orientation error of ``angle_deg``.

    Parameters
    ----------
    layout : array_like
        Marker positions (k, 3), body frame [m].
    angle_deg : float
        RMS orientation error [deg].

    Returns
    -------
    float
        Marker noise per axis [m].
    """
    return angle_deg / rms_angle_deg(layout, 1.0)


def marker_positions(position, quat, layout) -> np.ndarray:
    """World markers ``(..., k, 3)`` of poses ``position (..., 3)``, ``quat (..., 4)`` (x, y, z, w).

    Parameters
    ----------
    position : array_like
        Pivot positions (..., 3) [m].
    quat : array_like
        Quaternions (..., 4), (x, y, z, w).
    layout : array_like
        Marker positions (k, 3), body frame [m].

    Returns
    -------
    numpy.ndarray
        World marker positions (..., k, 3) [m].
    """
    R = rotation_matrices(quat)
    m = np.asarray(layout, dtype=float)
    return np.asarray(position, dtype=float)[..., None, :] + np.einsum("...ij,kj->...ki", R, m)


def fit_poses(markers, layout) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares rigid fit (Kabsch) of ``layout`` (k, 3) to world ``markers`` (..., k, 3).

    Minimizes ``sum_i |P + R m_i - w_i|^2`` over rotations ``R`` (det +1: a reflection, which the
    plain SVD solution gives for noisy or planar layouts, is turned into the nearest rotation by
    flipping the smallest singular direction) and the pivot ``P``.

    Returns ``(P (..., 3), R (..., 3, 3))``; NaN for frames with a non-finite marker.

    Parameters
    ----------
    markers : array_like
        World marker positions (..., k, 3) [m].
    layout : array_like
        Marker positions (k, 3), body frame [m].

    Returns
    -------
    P : numpy.ndarray
        Pivots (..., 3) [m].
    R : numpy.ndarray
        Rotations (..., 3, 3).
    """
    w = np.asarray(markers, dtype=float)
    m = np.asarray(layout, dtype=float)
    shape = w.shape[:-2]
    w = w.reshape((-1,) + w.shape[-2:])
    ok = np.all(np.isfinite(w), axis=(1, 2))
    P = np.full((w.shape[0], 3), np.nan)
    R = np.full((w.shape[0], 3, 3), np.nan)
    if ok.any():
        wk = w[ok]
        m_bar = m.mean(axis=0)
        w_bar = wk.mean(axis=1)
        a = m - m_bar                                   # (k, 3)
        b = wk - w_bar[:, None, :]                      # (n, k, 3)
        H = np.einsum("ki,nkj->nij", a, b)              # sum_i a_i b_i^T
        U, _, Vt = np.linalg.svd(H)
        V = np.swapaxes(Vt, -1, -2)
        d = np.sign(np.linalg.det(V @ np.swapaxes(U, -1, -2)))
        d[d == 0] = 1.0
        D = np.broadcast_to(np.eye(3), H.shape).copy()
        D[:, 2, 2] = d
        Rk = V @ D @ np.swapaxes(U, -1, -2)             # R a_i ~ b_i
        R[ok] = Rk
        P[ok] = w_bar - Rk @ m_bar
    return P.reshape(shape + (3,)), R.reshape(shape + (3, 3))


def synthesize(clean: MocapSeries, layouts: dict, sigma_m: float, rng: np.random.Generator) -> MocapSeries:
    """Marker-level recording of ``clean``: markers of each body's layout, noise, rigid fits.

    Parameters
    ----------
    clean : MocapSeries
        Noise-free poses (pivot positions and orientations).
    layouts : dict
        Body name -> layout ``(k, 3)`` [m] (body frame, relative to the pivot); every body of
        ``clean`` needs one.
    sigma_m : float
        Marker noise [m] per axis (i.i.d. per marker, axis and frame).
    rng : numpy.random.Generator
        Draws in body order, one ``(n, k, 3)`` block per body.

    Returns
    -------
    MocapSeries
        The fitted poses at the pivots (canonical quaternions), ``tracked`` as in ``clean``, and
        ``mean_marker_error`` the mean distance of the markers from the fitted layout (as Motive
        reports it).

    Raises
    ------
    ConfigError
        When the marker noise is negative or not finite, or a body has no marker layout.
    """
    if not (math.isfinite(sigma_m) and sigma_m >= 0):
        raise ConfigError(f"marker noise must be a finite number >= 0, got {sigma_m}", key="sigma_m")
    missing = [b for b in clean.bodies if b not in layouts]
    if missing:
        raise ConfigError(f"no marker layout for bodies {missing}", key="layouts")
    b, n = clean.position.shape[:2]
    pos = np.full((b, n, 3), np.nan)
    quat = np.full((b, n, 4), np.nan)
    err = np.full((b, n), np.nan)
    for j, body in enumerate(clean.bodies):
        lay = np.asarray(layouts[body], dtype=float)
        w = marker_positions(clean.position[j], clean.quat[j], lay)
        w = w + rng.normal(0.0, 1.0, w.shape) * sigma_m
        P, R = fit_poses(w, lay)
        ok = np.asarray(clean.tracked[j], bool) & np.all(np.isfinite(P), axis=-1)
        if not ok.any():
            continue
        pos[j, ok] = P[ok]
        quat[j, ok] = rotations_to_quats(R[ok])
        fitted = P[ok][:, None, :] + np.einsum("nij,kj->nki", R[ok], lay)
        err[j, ok] = np.linalg.norm(w[ok] - fitted, axis=-1).mean(axis=-1)
    meta = dict(clean.meta)
    meta["marker_sigma_m"] = float(sigma_m)
    return MocapSeries(t=clean.t.copy(), frame=clean.frame.copy(), bodies=list(clean.bodies), position=pos,
                       quat=quat, tracked=np.asarray(clean.tracked, bool) & np.all(np.isfinite(pos), axis=-1),
                       mean_marker_error=err, name=clean.name, meta=meta)
