"""State reconstruction: from rigid-body poses to the planar model's states (EUC paper, Section 2).

The per-frame geometry (:func:`~euc_ros.core.states.geometry.frame_geometry`: the EUC's pivot,
orientation, wheel centre, ankle hinge, the rider CoG and the pitch angles) is evaluated over the
recording block by block (:func:`~euc_ros.core.states.geometry.block_geometry`).
Over a recording (:func:`reconstruct_states`), the pitch angles and the wheel centre are smoothed and
differentiated with the Savitzky-Golay filter (:mod:`euc_ros.core.filters.derivatives`), split on
occlusion gaps. The longitudinal speed and acceleration follow the paper: ``v_C`` and ``a_C`` are the
ground-frame derivatives of ``R_C``, and ``x_dot = e_x . v_C``, ``x_ddot = e_x . a_C`` with the
moving frame's forward axis ``e_x = T e_1 = (cos psi, sin psi, 0)`` (the tilt rotates about e_x, so
only the yaw matters). Note that ``x_ddot`` so defined is the longitudinal component of ``a_C``, not
the time derivative of ``x_dot``: they differ by ``psi_dot (e_y . v_C)``, which vanishes when C moves
along the heading; we follow the paper.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from euc_ros.core.errors import ConfigError, InputError
from euc_ros.core.filters.derivatives import DEFAULT_MAX_GAP, savgol_derivatives, trim_edges
from euc_ros.core.mocap.blocks import materialize
from euc_ros.core.mocap.bridging import bridge_series
from euc_ros.core.states.geometry import block_geometry, frame_geometry
from euc_ros.core.states.skeleton import COG_METHODS, SkeletonModel

#: Default Savitzky-Golay window [s] and polynomial order, chosen by measurement on simulated rides
#: with the paper's noise level (0.2 mm, 0.5 deg per frame), on the interior samples of each stretch:
#: the bias of h and of inertia-type parameters against the window is tabulated in
#: docs/identification.md.
DEFAULT_WINDOW_S = 1.2
DEFAULT_SG_POLYORDER = 6
#: Rider pitch definitions: about the ankle hinge A (the model's) or about the wheel centre C (eq (3)).
PHI_DEFINITIONS = ("hinge", "eq3")


@dataclass
class RiderStates:
    """States of the planar model over a recording, with their derivatives (SI units, radians).

    Parameters
    ----------
    name : str
        Recording name.
    t : ndarray (n,)
        Time [s].
    frame : ndarray (n,) of int
        Frame numbers.
    x, x_dot, x_ddot : ndarray (n,)
        Forward distance travelled by C [m] (integral of ``x_dot``), longitudinal speed [m/s] and
        acceleration [m/s^2] of C (Section 2: longitudinal components of ``v_C``, ``a_C``).
    gamma, gamma_dot, gamma_ddot : ndarray (n,)
        EUC body pitch (smoothed) and its derivatives [rad, rad/s, rad/s^2].
    phi, phi_dot, phi_ddot : ndarray (n,)
        Rider pitch of the chosen definition (smoothed) and its derivatives [rad, rad/s, rad/s^2].
    phi_eq3, phi_hinge : ndarray (n,)
        Both rider pitch definitions, unsmoothed [rad].
    psi, theta : ndarray (n,)
        EUC yaw (unwrapped) and tilt [rad], unsmoothed.
    C, G : ndarray (n, 3)
        Wheel centre (smoothed) and rider CoG (unsmoothed) [m], Z-up world.
    has_euc, has_rider : ndarray (n,) of bool
        E tracked; all rider segments of non-zero mass tracked.
    valid : ndarray (n,) of bool
        Every state and derivative finite and measured (not filled across a short gap), and either at
        least half a filter window inside its gap-free stretch, or, nearer a stretch's end (beside a gap,
        or at the take's own ends), where a least-squares fit through the recorded samples of the window
        (:func:`~euc_ros.core.filters.masked_savgol.masked_savgol`: one-sided at the take's ends) has a
        second derivative within 4 times the variance of the full window's (the online fixed-lag filter
        gives no state within half a window of a stretch's end).
    phi_definition : str
        ``"hinge"`` or ``"eq3"``.
    cog_method : str
        ``"segments"`` or ``"skeleton"`` (see :func:`frame_geometry`); with ``skeleton``,
        ``meta["cog_faults"]`` counts the body-frames excluded from G and ``meta["cog_fault_bodies"]``
        splits them per body.
    window, polyorder : int
        Savitzky-Golay window [samples] and order used.
    dt : float
        Sample spacing [s].
    meta : dict
        Notes of the reconstruction (e.g. the skeleton's ``cog_faults``).
    """

    name: str
    t: np.ndarray
    frame: np.ndarray
    x: np.ndarray
    x_dot: np.ndarray
    x_ddot: np.ndarray
    gamma: np.ndarray
    gamma_dot: np.ndarray
    gamma_ddot: np.ndarray
    phi: np.ndarray
    phi_dot: np.ndarray
    phi_ddot: np.ndarray
    phi_eq3: np.ndarray
    phi_hinge: np.ndarray
    psi: np.ndarray
    theta: np.ndarray
    C: np.ndarray
    G: np.ndarray
    has_euc: np.ndarray
    has_rider: np.ndarray
    valid: np.ndarray
    phi_definition: str = "hinge"
    cog_method: str = "segments"
    window: int = 0
    polyorder: int = DEFAULT_SG_POLYORDER
    dt: float = float("nan")
    meta: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.t.shape[0])

    def torque_args(self, mask=None) -> tuple[np.ndarray, ...]:
        """Return ``(gamma, phi, gamma_dot, phi_dot, x_ddot, gamma_ddot, phi_ddot)`` for :func:`~.torque.torques`.

        Parameters
        ----------
        mask : ndarray of bool, optional
            Samples to keep (default: all, including invalid ones as NaN).

        Returns
        -------
        tuple of numpy.ndarray
            The seven arrays [rad, rad, rad/s, rad/s, m/s^2, rad/s^2, rad/s^2], ``mask`` applied.
        """
        arrs = (self.gamma, self.phi, self.gamma_dot, self.phi_dot, self.x_ddot, self.gamma_ddot, self.phi_ddot)
        return arrs if mask is None else tuple(a[mask] for a in arrs)


def reconstruct_states(series, session, *, phi_definition: str = "hinge", window_s: float = DEFAULT_WINDOW_S,
                       polyorder: int = DEFAULT_SG_POLYORDER, max_gap: int = DEFAULT_MAX_GAP,
                       cog_method: str = "segments", skeleton: SkeletonModel | None = None,
                       lean: bool = False) -> RiderStates:
    """Reconstruct the planar model's states and derivatives from a motion-capture recording.

    Parameters
    ----------
    series : MocapSeries
        Z-up poses of the EUC body and the rider segments.
    session : Session
        The recording's session file.
    phi_definition : {"hinge", "eq3"}
        Rider pitch about the ankle hinge A (the model's definition, default) or about the wheel
        centre C (eq (3) of the paper).
    window_s : float
        Savitzky-Golay window [s].
    polyorder : int
        Savitzky-Golay polynomial order.
    max_gap : int
        Longest run of missing frames bridged by interpolation (those samples stay invalid).
    cog_method : {"segments", "skeleton"}
        Rider CoG from the measured segments or from the fitted chain (:func:`frame_geometry`).
    skeleton : SkeletonModel, optional
        The session's chain (default: estimated from this recording).
    lean : bool
        Only what the model's residual reads (the pitch angles, their derivatives, ``x_dot``, ``x_ddot``
        and ``valid``, the same numbers): ``x``, ``psi``, ``theta``, ``C``, ``G``, ``has_euc``,
        ``has_rider`` and the unused pitch definition are left empty (for a caller that reduces the
        states to the residual's coefficients at once, e.g. a SIMEX replicate), and let go before the
        pitch angles are filtered.

    Returns
    -------
    RiderStates

    Raises
    ------
    InputError
        If the recording lacks the EUC body or a rider segment of non-zero mass altogether.
    ConfigError
        For an unknown ``phi_definition`` or bad filter settings.
    """
    _check(series, session, phi_definition, cog_method)
    geo = _geometry(series, session, max_gap=max_gap, cog_method=cog_method, skeleton=skeleton)
    return _filtered_states(series, geo, phi_definition=phi_definition, window_s=window_s, polyorder=polyorder,
                            max_gap=max_gap, cog_method=cog_method, consume=True, lean=lean)


def reconstruct_states_filters(series, session, filters, *, phi_definition: str = "hinge",
                               max_gap: int = DEFAULT_MAX_GAP, cog_method: str = "segments",
                               skeleton: SkeletonModel | None = None) -> list[RiderStates]:
    """:func:`reconstruct_states` with several Savitzky-Golay filters, from one evaluation of the geometry.

    The per-frame geometry (poses to angles, wheel centre and CoG) does not depend on the filter, so a
    recording analysed at several filters (a chosen filter and its probe; the re-noised recordings of
    SIMEX at both) needs it once. The states are those :func:`reconstruct_states` gives for each
    filter, number for number.

    Parameters
    ----------
    series, session, phi_definition, max_gap, cog_method, skeleton
        As for :func:`reconstruct_states` (validated alike).
    filters : sequence of (float, int)
        ``(window_s, polyorder)`` of each filter.

    Returns
    -------
    list of RiderStates
        One per filter, in order.
    """
    return list(iter_states_filters(series, session, filters, phi_definition=phi_definition, max_gap=max_gap,
                                    cog_method=cog_method, skeleton=skeleton))


def iter_states_filters(series, session, filters, *, phi_definition: str = "hinge", max_gap: int = DEFAULT_MAX_GAP,
                        cog_method: str = "segments", skeleton: SkeletonModel | None = None,
                        shared: bool = False, lean: bool = False):
    """:func:`reconstruct_states_filters` one filter at a time.

    A generator of the states of each filter, in order, each made when asked for (a caller that reduces each
    before asking for the next never holds two filters' states). The geometry is evaluated once, when the
    first is asked for. ``shared``: the states of the filters but the last share the geometry's arrays they
    keep (G, the pitch angles, the heading...) instead of copies, for a caller that only reads them. ``lean``:
    as for :func:`reconstruct_states`.

    Parameters
    ----------
    series, session, phi_definition, max_gap, cog_method, skeleton, lean
        As for :func:`reconstruct_states` (validated alike).
    filters : sequence of (float, int)
        ``(window_s, polyorder)`` of each filter.
    shared : bool
        The states of the filters but the last share the geometry's arrays.

    Yields
    ------
    RiderStates
        The states of each filter, in order.

    Raises
    ------
    InputError
        If the recording lacks the EUC body or a rider segment of non-zero mass altogether.
    ConfigError
        For an unknown ``phi_definition`` or ``cog_method``, or bad filter settings.
    """
    filters = [(float(w), int(p)) for w, p in filters]
    if not filters:
        return
    if len(filters) == 1:
        (w, p), = filters
        yield reconstruct_states(series, session, phi_definition=phi_definition, window_s=w, polyorder=p,
                                 max_gap=max_gap, cog_method=cog_method, skeleton=skeleton, lean=lean)
        return
    _check(series, session, phi_definition, cog_method)
    geo = _geometry(series, session, max_gap=max_gap, cog_method=cog_method, skeleton=skeleton)
    for k, (w, p) in enumerate(filters):
        last = k == len(filters) - 1
        yield _filtered_states(series, geo if last or not shared else dict(geo), phi_definition=phi_definition,
                               window_s=w, polyorder=p, max_gap=max_gap, cog_method=cog_method,
                               consume=last or shared, lean=lean)


def _check(series, session, phi_definition: str, cog_method: str) -> None:
    """The refusals of :func:`reconstruct_states` (settings, and bodies the session needs)."""
    if phi_definition not in PHI_DEFINITIONS:
        raise ConfigError(f"phi definition must be one of {PHI_DEFINITIONS}, got {phi_definition!r}",
                          key="phi_definition")
    if cog_method not in COG_METHODS:
        raise ConfigError(f"cog method must be one of {COG_METHODS}, got {cog_method!r}", key="cog_method")
    src = series.meta.get("path", series.name or None)
    if session.euc.body not in series.bodies:
        raise InputError(f"EUC rigid body {session.euc.body!r} not in recording (has: {', '.join(series.bodies)})",
                         path=src)
    names, fractions, _ = session.segment_arrays()
    absent = [nm for nm, f in zip(names, fractions) if f > 0 and nm not in series.bodies]
    if absent:
        extra = [b for b in series.bodies if b not in names and b != session.euc.body]
        hint = (f"; bodies the session does not name: {', '.join(extra)} (rename the segment keys of "
                f"rider.segments to the recording's Motive names)") if extra else ""
        raise InputError(f"rider segment(s) {', '.join(absent)} of the session not in recording (has: "
                         f"{', '.join(series.bodies)}){hint}", path=src, key="rider.segments")


def _geometry(series, session, *, max_gap: int, cog_method: str, skeleton) -> dict:
    """The bridged per-frame geometry of a recording, with the bridging counts under ``_bridged``."""
    # each body's short gaps are bridged before any geometry (as the live estimator does); for the
    # segments CoG block by block (blockwise.block_geometry: no copy of the whole recording)
    if cog_method == "skeleton":
        bridged_series, bridged = bridge_series(materialize(series), max_gap)
        if skeleton is None:
            skeleton = SkeletonModel.estimate([bridged_series], session)
        geo = frame_geometry(bridged_series.position, bridged_series.quat, bridged_series.tracked, session,
                             bridged_series.bodies, cog_method=cog_method, skeleton=skeleton)
        geo["_bridged"] = (int(bridged.sum()), int(bridged.any(axis=0).sum()))
        return geo
    geo, n_bridged, n_bridged_frames = block_geometry(series, session, max_gap)
    geo["_bridged"] = (n_bridged, n_bridged_frames)
    return geo


def _across_gaps(frame: np.ndarray, valid: np.ndarray, geo: dict, phi_raw: np.ndarray, psi: np.ndarray,
                 dt: float, window: int, polyorder: int):
    """The states the Savitzky-Golay stretches leave out at their ends, from fits through the gaps.

    A gap longer than the bridged ``max_gap`` frames ends a stretch, and the half-windows at every stretch's
    ends are trimmed (the recording's own first and last ones too); at those recorded samples the local
    least-squares polynomials through the samples that are there
    (:func:`~euc_ros.core.filters.masked_savgol.masked_savgol`) give the states, where their second
    derivatives' variance stays within :data:`~euc_ros.core.filters.masked_savgol.MAX_INFLATION` of the full
    window's. Beside a gap the window is centred and sees across it; at the recording's ends it is the first
    or last whole window, evaluated off its centre (one-sided). Only those samples' fits are solved.

    Returns
    -------
    tuple or None
        ``(rows, fields)``: the sample rows and their ``x_dot, x_ddot, gamma, gamma_dot, gamma_ddot, phi,
        phi_dot, phi_ddot``; None when nothing is gained.
    """
    from euc_ros.core.filters.masked_savgol import masked_savgol

    n = frame.size
    if n < window:
        return None
    k = frame - frame[0]
    cols = np.column_stack([geo["C_raw"], geo["gamma_raw"], phi_raw])
    recorded = np.all(np.isfinite(cols), axis=1) & np.isfinite(psi)
    want = np.flatnonzero(recorded & ~valid)
    if want.size == 0:
        return None
    grid = np.full((int(k[-1]) + 1, cols.shape[1]), np.nan)
    grid[k[recorded]] = cols[recorded]
    fit = masked_savgol(grid, window, polyorder, dt, rows=k[want])
    rows, use = want[fit.usable], fit.usable
    if rows.size == 0:
        return None
    c, s_ = np.cos(psi[rows]), np.sin(psi[rows])
    x_dot = c * fit.y_dot[use, 0] + s_ * fit.y_dot[use, 1]
    x_ddot = c * fit.y_ddot[use, 0] + s_ * fit.y_ddot[use, 1]
    return rows, (x_dot, x_ddot, fit.y[use, 3], fit.y_dot[use, 3], fit.y_ddot[use, 3], fit.y[use, 4],
                  fit.y_dot[use, 4], fit.y_ddot[use, 4])


def _filtered_states(series, geo: dict, *, phi_definition: str, window_s: float, polyorder: int, max_gap: int,
                     cog_method: str, consume: bool, lean: bool = False) -> RiderStates:
    """The states of one Savitzky-Golay filter from the geometry of :func:`_geometry`.

    ``consume``: its arrays may be dropped as they are filtered; else ``geo`` is left as given; ``lean``: as
    for :func:`reconstruct_states`.
    """
    src = series.meta.get("path", series.name or None)
    # without ``consume`` the states get arrays of their own (another filter's states share none)
    geo = geo if consume else {k: v.copy() if isinstance(v, np.ndarray) else v for k, v in geo.items()}
    n_bridged, n_bridged_frames = geo["_bridged"]
    dt = 1.0 / series.rate_hz
    frame = np.asarray(series.frame, dtype=np.int64)
    sg = dict(window_s=window_s, polyorder=polyorder, max_gap=max_gap, frame=frame)
    # Order for memory: each filter input is dropped from ``geo`` once filtered (those the states do not
    # keep) and the wheel centre's derivatives once reduced to x_dot and x_ddot, so the working set
    # beyond the states is at most one filter's. The numbers are those of any other order.
    n_faults = int(geo.pop("n_faults").sum())
    if lean:            # what the residual does not read, let go before the filtering (empty in the states)
        for key in ("G", "theta", "has_euc", "has_rider", "phi_eq3" if phi_definition == "hinge" else "phi_hinge"):
            geo[key] = np.empty((0, 3) if key == "G" else 0, dtype=geo[key].dtype)
    geo["C_raw"] = geo["C"]
    d_C = savgol_derivatives(dt, geo.pop("C"), **sg)
    psi = geo["psi"].copy()
    fin = np.isfinite(psi)
    if fin.any():
        psi[fin] = np.unwrap(psi[fin])
    # Heading of the bridged frames (a body missing for at most max_gap frames): interpolated like the
    # filter interpolates gamma and C, so a blank frame costs that frame only (as live), not the
    # half-windows on both sides of a NaN that would split the stretch.
    psi_x = geo["psi"].copy()
    gap = ~fin & d_C.filled
    if gap.any() and fin.sum() >= 2:
        psi_x[gap] = np.interp(frame[gap], frame[fin], psi[fin])
    del gap, fin
    cx, sx = np.cos(psi_x), np.sin(psi_x)          # e_x = (cos psi, sin psi)
    del psi_x
    x_dot = cx * d_C.y_dot[:, 0] + sx * d_C.y_dot[:, 1]
    x_ddot = cx * d_C.y_ddot[:, 0] + sx * d_C.y_ddot[:, 1]
    del cx, sx
    C, filled = d_C.y, d_C.filled.copy()
    del d_C                                        # its (n, 3) y_dot and y_ddot
    t = np.asarray(series.t, dtype=float)
    if lean:                                       # what the residual does not read: left empty
        C, x, psi = np.empty((0, 3)), np.empty(0), np.empty(0)
    else:
        xd0 = np.where(np.isfinite(x_dot), x_dot, 0.0)
        x = np.concatenate(([0.0], np.cumsum(0.5 * (xd0[1:] + xd0[:-1]) * np.diff(t)))) if t.size else t.copy()
        del xd0
        x[~np.isfinite(x_dot)] = np.nan
    geo["gamma_raw"] = geo["gamma"]
    d_gamma = savgol_derivatives(dt, geo.pop("gamma"), **sg)
    phi_raw = geo["phi_hinge"] if phi_definition == "hinge" else geo["phi_eq3"]
    d_phi = savgol_derivatives(dt, phi_raw, **sg)
    filled |= d_gamma.filled
    filled |= d_phi.filled
    fields_ = (x_dot, x_ddot, d_gamma.y, d_gamma.y_dot, d_gamma.y_ddot, d_phi.y, d_phi.y_dot, d_phi.y_ddot)
    # measured samples at least half a window inside their stretch (where the SG fit interpolates; those
    # nearer a stretch's end come from _across_gaps); the fields' finiteness and-ed one at a time (no (8, n)
    # stack of the fields)
    finite = np.isfinite(fields_[0])
    for f in fields_[1:]:
        finite &= np.isfinite(f)
    valid = trim_edges(finite, d_gamma.window // 2, frame, max_gap) & ~filled
    across = _across_gaps(frame, valid, geo, phi_raw, geo["psi"], dt, d_gamma.window, polyorder)
    del geo["C_raw"], geo["gamma_raw"]
    if across is not None:          # the samples the stretches' ends cost: least-squares fits through the gaps
        rows, f = across
        for field_, fitted in zip(fields_, f):
            field_[rows] = fitted
        valid[rows] = True
    return RiderStates(
        name=series.name, t=t, frame=frame, x=x, x_dot=x_dot, x_ddot=x_ddot,
        gamma=d_gamma.y, gamma_dot=d_gamma.y_dot, gamma_ddot=d_gamma.y_ddot,
        phi=d_phi.y, phi_dot=d_phi.y_dot, phi_ddot=d_phi.y_ddot,
        phi_eq3=geo["phi_eq3"], phi_hinge=geo["phi_hinge"], psi=psi, theta=geo["theta"],
        C=C, G=geo["G"], has_euc=geo["has_euc"], has_rider=geo["has_rider"], valid=valid,
        phi_definition=phi_definition, cog_method=cog_method, window=d_gamma.window, polyorder=polyorder, dt=dt,
        meta={"source": src, "bridged_samples": n_bridged,
              "bridged_frames": n_bridged_frames, "cog_faults": n_faults,
              **({"cog_fault_bodies": geo["cog_fault_bodies"]} if "cog_fault_bodies" in geo else {}),
              **({"cog_unlinked_bodies": geo["cog_unlinked_bodies"]} if geo.get("cog_unlinked_bodies") else {})},
    )
