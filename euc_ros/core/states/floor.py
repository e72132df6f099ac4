"""The floor under the wheel, measured from the wheel's contact path and what it says about the rolling radius.

The wheel touches the floor at ``P = C - R (z - (z.a) a) / cos(theta)`` (wheel centre C, radius R,
axle a tilted by theta from the horizontal): its height is ``C_z - R cos(theta)`` in the mocap world.
Over a ride those points trace the floor. Fitted here: a plane ``z = b0 + bx x + by y`` (robustly), a
smooth deviation from it along the path (a bump, a step: the running median over
:data:`DEVIATION_WINDOW_M` of path), and the scatter left after both (pose noise, tyre).

What the fit can say, and what it cannot:

* a floor **tilted in the mocap frame** (a ramp in a level-calibrated lab) shows as a plane slope, known
  without any dynamics (``slope_along_travel_rad``, signed: positive uphill);
* a **mocap frame tilted against gravity** (Motive's ground plane set on a sloped floor) leaves the
  floor flat at z = 0 in the data: geometry sees nothing, it stays a dynamic candidate;
* a **wheel-radius error** lifts every contact point by the same amount, indistinguishable from the
  ground plane set a little high or low; it is inferred only from a floor that is flat (no slope
  and no deviation beyond the scatter) and whose scatter is small against the offset
  (:func:`rolling_radius_from_floor`). A radius is never inferred from a floor the fit cannot explain.

:func:`floor_from_states` fits the contact path of reconstructed runs; a radius measured so enters the
residual analysis' model with its parameter given, not fitted
(:class:`~euc_ros.core.residual.analysis.MeasuredWheelRadius`).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Sequence

import numpy as np
from scipy import ndimage

from euc_ros.core.states.kinematics import RiderStates

#: Length of path over which the smooth deviation from the plane is the running median [m].
DEVIATION_WINDOW_M = 0.5
#: Baseline of the direction of travel [m] (each side of a sample).
HEADING_BASELINE_M = 0.05
#: Least path length and contact points for a floor fit.
MIN_EXTENT_M = 1.0
MIN_SAMPLES = 50
#: Spread of the path (std along a principal axis) below which the floor's slope along that axis is not
#: fitted [m] (runs along a line say nothing about the slope across it).
MIN_CROSS_SPREAD_M = 0.1
#: A floor is flat when its plane rises less than this many scatters over the path, and its smooth
#: deviation stays within this many scatters.
FLAT_SIGMAS = 3.0
#: Floor features below this are flat whatever the scatter (tyre compression, marker placement) [m].
FLAT_FLOOR_M = 0.002
#: A rolling radius is inferred only when the floor offset exceeds this many scatters.
RADIUS_SIGMAS = 3.0


@dataclass
class FloorFit:
    """The floor under a ride (every length in m, angles in rad).

    Parameters
    ----------
    samples : int
        Contact points fitted.
    extent_m : float
        Horizontal length of the contact path, end to end of its span [m].
    plane : tuple of float
        ``(b0, bx, by)`` of the plane ``z = b0 + bx x + by y`` [m, -, -].
    offset_m : float
        Median contact height over ``cos(theta)`` [m] (0 on the calibrated floor at the nominal radius).
    slope_rad : float
        Steepest slope of the plane [rad].
    slope_along_travel_rad : float
        Mean slope along the direction of travel [rad], positive uphill.
    rise_m : float
        Height the plane rises over the path [m].
    deviation_m : float
        Largest smooth deviation from the plane (bump, step) [m].
    scatter_m : float
        Robust standard deviation of what is left (noise) [m].
    flat : bool
        No slope and no deviation beyond the scatter.
    """

    samples: int
    extent_m: float                 # horizontal length of the contact path (end to end of its span)
    plane: tuple[float, float, float]   # b0, bx, by of z = b0 + bx x + by y
    offset_m: float                 # median contact height / cos(theta) (0 on the calibrated floor at R)
    slope_rad: float                # steepest slope of the plane
    slope_along_travel_rad: float   # mean slope along the direction of travel, positive uphill
    rise_m: float                   # height the plane rises over the path
    deviation_m: float              # largest smooth deviation from the plane (bump, step)
    scatter_m: float                # robust std of what is left (noise)
    flat: bool                      # no slope and no deviation beyond the scatter

    def as_dict(self) -> dict:
        """The fit as a plain mapping, with the angles also in degrees.

        Returns
        -------
        dict
            The fields, ``plane`` as a list, ``slope_deg`` and ``slope_along_travel_deg``.
        """
        d = asdict(self)
        d["plane"] = list(self.plane)
        d["slope_deg"] = math.degrees(self.slope_rad)
        d["slope_along_travel_deg"] = math.degrees(self.slope_along_travel_rad)
        return d


def contact_heights(C: np.ndarray, theta: np.ndarray, radius: float) -> np.ndarray:
    """The height of the wheel's contact point: ``C_z - R cos(theta)`` (theta: the wheel's tilt).

    Parameters
    ----------
    C : array_like (n, 3)
        Wheel centre [m], Z-up mocap world.
    theta : array_like (n,)
        Wheel tilt [rad].
    radius : float
        Wheel radius R [m].

    Returns
    -------
    numpy.ndarray (n,)
        Contact height [m].
    """
    return np.asarray(C, float)[:, 2] - float(radius) * np.cos(np.asarray(theta, float))


def _robust_std(r: np.ndarray) -> float:
    return float(1.4826 * np.median(np.abs(r - np.median(r))))


def _soft_l1_fit(A: np.ndarray, z: np.ndarray, b0: np.ndarray, f_scale: float, *, max_iter: int = 200,
                 rtol: float = 1e-12) -> np.ndarray:
    """The linear fit ``A b ~ z`` under scipy's ``soft_l1`` loss by iteratively reweighted least squares.

    The loss is ``rho(s) = 2 (sqrt(1 + s) - 1)``, ``s = (r / f_scale)^2``.

    The loss is convex, and its minimum solves ``sum w_i r_i a_i = 0`` with ``w = rho'(s) = 1 / sqrt(1 + s)``:
    each step solves the weighted normal equations (a few columns) with the weights of the last
    residuals, which decreases the loss monotonically. The same minimum as
    ``scipy.optimize.least_squares(loss="soft_l1")``, to within its tolerances, with the memory of a few
    sample arrays (its trust-region solver kept several (n, k) Jacobian copies: ~100 MB on a 60-minute
    recording).
    """
    b = np.asarray(b0, dtype=float).copy()
    for _ in range(max_iter):
        r = A @ b - z
        r /= f_scale
        r *= r
        r += 1.0
        w = 1.0 / np.sqrt(r)                          # rho'(s)
        del r
        Aw = A * w[:, None]
        b_new = np.linalg.solve(Aw.T @ A, Aw.T @ z)
        del Aw, w
        done = np.max(np.abs(b_new - b)) <= rtol * (1.0 + np.max(np.abs(b_new)))
        b = b_new
        if done:
            break
    return b


def fit_floor(C: np.ndarray, theta: np.ndarray, valid: np.ndarray, radius: float,
              segments: np.ndarray | None = None) -> FloorFit | None:
    """Fit the floor to the contact points of one or more runs; None when the path is too short.

    Parameters
    ----------
    C : ndarray (n, 3)
        Wheel centre [m], Z-up mocap world.
    theta : ndarray (n,)
        Wheel tilt [rad].
    valid : ndarray (n,) of bool
    radius : float
        Nominal wheel radius [m].
    segments : ndarray (n,) of int, optional
        Run index of each sample (the path is continuous within a run only).

    Returns
    -------
    FloorFit or None
        None with fewer than :data:`MIN_SAMPLES` valid contact points or a path shorter than
        :data:`MIN_EXTENT_M`.
    """
    C = np.asarray(C, float)
    seg = np.zeros(len(C), int) if segments is None else np.asarray(segments)
    z = contact_heights(C, theta, radius)
    ok = np.asarray(valid, bool) & np.all(np.isfinite(C), axis=1) & np.isfinite(z)
    if ok.sum() < MIN_SAMPLES:
        return None
    xy, z, seg = C[ok, :2], z[ok], seg[ok]
    cos_theta = np.cos(np.asarray(theta, float)[ok])
    extent = float(np.linalg.norm(xy.max(axis=0) - xy.min(axis=0)))
    if extent < MIN_EXTENT_M:
        return None
    centre = xy.mean(axis=0)
    # principal axes of the path: a slope across a path that is nearly a line is not measured (it is
    # set to 0 rather than fitted to whatever the floor does along the line)
    _, sv, axes = np.linalg.svd(xy - centre, full_matrices=False)
    spread = sv / math.sqrt(len(xy))
    keep = [k for k in range(2) if spread[k] >= MIN_CROSS_SPREAD_M]
    uv = (xy - centre) @ axes[keep].T
    A = np.column_stack([np.ones(len(z)), uv])
    # robust plane: soft-L1 loss with the noise scale from a first least-squares pass
    b_ls = np.linalg.lstsq(A, z, rcond=None)[0]
    f_scale = max(_robust_std(z - A @ b_ls), 1e-5)
    b_uv = _soft_l1_fit(A, z, b_ls, f_scale)
    resid = z - A @ b_uv
    b = np.concatenate([[b_uv[0]], b_uv[1:] @ axes[keep] if keep else np.zeros(2)])
    # smooth deviation along each run's path: running median over DEVIATION_WINDOW_M of path length
    smooth = np.zeros_like(resid)
    for s in np.unique(seg):
        m = seg == s
        step = np.linalg.norm(np.diff(xy[m], axis=0), axis=1)
        ds = float(np.median(step[step > 0])) if np.any(step > 0) else 0.0
        if ds <= 0:
            continue
        size = max(3, int(round(DEVIATION_WINDOW_M / ds)) | 1)
        smooth[m] = ndimage.median_filter(resid[m], size=min(size, max(3, (m.sum() // 2) | 1)), mode="nearest")
    scatter = _robust_std(resid - smooth)
    grad = b[1:]
    # direction of travel, sample by sample; the slope along it, averaged over the path
    # (over HEADING_BASELINE_M of path: per-sample differences of noisy positions would bias the cosine)
    heading = np.zeros_like(xy)
    for s in np.unique(seg):
        m = np.flatnonzero(seg == s)
        if len(m) < 3:
            continue
        step = np.linalg.norm(np.diff(xy[m], axis=0), axis=1)
        ds = float(np.median(step)) if step.size else 0.0
        k = int(np.clip(round(HEADING_BASELINE_M / ds), 1, (len(m) - 1) // 2)) if ds > 0 else 1
        idx = np.arange(len(m))
        heading[m] = xy[m[np.minimum(idx + k, len(m) - 1)]] - xy[m[np.maximum(idx - k, 0)]]
    norm = np.linalg.norm(heading, axis=1)
    moving = norm > 0
    along = float(np.mean(heading[moving] @ grad / norm[moving])) if moving.any() else float("nan")
    pred = (xy - centre) @ grad
    rise = float(pred.max() - pred.min())
    deviation = float(np.max(np.abs(smooth)))
    limit = max(FLAT_SIGMAS * scatter, FLAT_FLOOR_M)
    return FloorFit(samples=int(len(z)), extent_m=extent, plane=(float(b[0] - grad @ centre), float(grad[0]),
                                                                float(grad[1])),
                    offset_m=float(np.median(z / cos_theta)), slope_rad=float(math.atan(np.linalg.norm(grad))),
                    slope_along_travel_rad=float(math.atan(along)), rise_m=rise, deviation_m=deviation,
                    scatter_m=scatter, flat=bool(rise <= limit and deviation <= limit))


def rolling_radius_from_floor(fit: FloorFit | None, radius: float, tolerance: float) -> tuple[float, bool, str]:
    """The rolling radius a floor fit implies: ``(radius [m] or NaN, significant, reason)``.

    Only a flat floor (Motive's ground plane on it, z = 0) measures the radius: a contact path lying
    ``d`` above z = 0 everywhere means a rolling radius ``R + d``. A floor that slopes or is uneven
    explains any offset as well, so it is reported as the floor, never as a radius (NaN). An offset
    within ``tolerance`` or :data:`RADIUS_SIGMAS` scatters is measured but not significant.

    Parameters
    ----------
    fit : FloorFit or None
        The floor (None: no fit).
    radius : float
        Nominal wheel radius [m].
    tolerance : float
        Offset below which the radius is not significant [m].

    Returns
    -------
    radius : float
        The rolling radius [m], NaN without a fit or on a floor that is not flat.
    significant : bool
        The offset exceeds ``tolerance`` and :data:`RADIUS_SIGMAS` scatters.
    reason : str
        What the floor showed, in words.
    """
    if fit is None:
        return float("nan"), False, "path too short for a floor fit"
    if not fit.flat:
        return float("nan"), False, (
            f"floor not flat (rises {fit.rise_m * 1e3:.1f} mm over {fit.extent_m:.1f} m, slope "
            f"{math.degrees(fit.slope_along_travel_rad):+.2f} deg along travel, deviation {fit.deviation_m * 1e3:.1f} "
            f"mm, scatter {fit.scatter_m * 1e3:.1f} mm): no radius inferred from it")
    significant = abs(fit.offset_m) > max(tolerance, RADIUS_SIGMAS * fit.scatter_m)
    return radius + fit.offset_m, significant, (
        f"flat floor, contact path {fit.offset_m * 1e3:+.1f} mm from z = 0 (scatter {fit.scatter_m * 1e3:.1f} mm)")


def slope_along_path(C: np.ndarray, theta: np.ndarray, psi: np.ndarray, valid: np.ndarray, radius: float,
                     fit: FloorFit) -> np.ndarray:
    """Slope of the floor under the wheel along its heading, sample by sample [rad] (positive uphill).

    The plane's slope along the heading ``psi`` plus the slope of the smooth deviation along the
    path: the deviation (running median over :data:`DEVIATION_WINDOW_M` of path) resampled on a 1 cm
    grid of path length and differentiated by a Savitzky-Golay filter over the same length (so a
    wheel at rest keeps the slope of where it stands). One run per call; NaN where invalid.

    Parameters
    ----------
    C : array_like (n, 3)
        Wheel centre [m], Z-up mocap world.
    theta : array_like (n,)
        Wheel tilt [rad].
    psi : array_like (n,)
        Heading (yaw) [rad].
    valid : array_like of bool (n,)
        Samples to use.
    radius : float
        Nominal wheel radius [m].
    fit : FloorFit
        The floor fit of the ride.

    Returns
    -------
    numpy.ndarray (n,)
        Slope [rad], positive uphill; the plane's alone when the run is shorter than :data:`MIN_SAMPLES`
        samples or twice :data:`DEVIATION_WINDOW_M` of path.
    """
    from scipy.signal import savgol_filter

    C = np.asarray(C, float)
    psi = np.asarray(psi, float)
    bx, by = fit.plane[1], fit.plane[2]
    out = np.arctan(bx * np.cos(psi) + by * np.sin(psi))
    z = contact_heights(C, theta, radius) - (fit.plane[0] + bx * C[:, 0] + by * C[:, 1])
    ok = np.asarray(valid, bool) & np.all(np.isfinite(C), axis=1) & np.isfinite(z) & np.isfinite(psi)
    idx = np.flatnonzero(ok)
    if idx.size < MIN_SAMPLES:
        return np.where(ok, out, np.nan)
    step = np.linalg.norm(np.diff(C[idx, :2], axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(step)])
    grid_ds = 0.01
    if s[-1] < 2 * DEVIATION_WINDOW_M:
        return np.where(ok, out, np.nan)
    ds = float(np.median(step[step > 0])) if np.any(step > 0) else grid_ds
    size = max(3, int(round(DEVIATION_WINDOW_M / ds)) | 1)
    dev = ndimage.median_filter(z[idx], size=min(size, max(3, (idx.size // 2) | 1)), mode="nearest")
    grid = np.arange(0.0, s[-1] + grid_ds, grid_ds)
    keep = np.concatenate([[True], np.diff(s) > 0])
    dev_g = np.interp(grid, s[keep], dev[keep])
    win = max(5, int(round(DEVIATION_WINDOW_M / grid_ds)) | 1)
    ddev = savgol_filter(dev_g, window_length=min(win, grid.size - 1 + grid.size % 2), polyorder=2, deriv=1,
                         delta=grid_ds, mode="interp")
    # the deviation's slope is along the path; travel along the heading (forward riding)
    slope_dev = np.interp(s, grid, ddev)
    res = np.full(len(C), np.nan)
    res[idx] = np.arctan(np.tan(out[idx]) + slope_dev)
    return res


#: A measured rolling radius (wheel-centre height over the floor) this far from the nominal one is a
#: wheel_radius_error found by geometry [m] (tyre and ground-plane tolerances are a few mm).
RADIUS_TOL_M = 0.005


def floor_from_states(states: Sequence[RiderStates], radius: float):
    """The floor fit (:func:`euc_ros.core.states.floor.fit_floor`) of the contact path of every run.

    Parameters
    ----------
    states : sequence of RiderStates
        The runs (``C``, ``theta``, ``valid``).
    radius : float
        Nominal wheel radius [m].

    Returns
    -------
    FloorFit or None
        None without states or when :func:`fit_floor` finds the path too short.
    """
    if not states:
        return None
    C = np.concatenate([st.C for st in states])
    theta = np.concatenate([st.theta for st in states])
    valid = np.concatenate([st.valid for st in states])
    seg = np.concatenate([np.full(len(st.t), i) for i, st in enumerate(states)])
    return fit_floor(C, theta, valid, radius, seg)


