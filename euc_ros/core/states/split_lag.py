"""Low-lag states that follow the structure of the mocap noise (the "split" estimator).

Why. A rigid body's orientation noise (0.5 deg per frame) is one small rotation about its pivot,
shared by everything derived from that body; its position noise (0.2 mm) is 40x smaller in the
quantities the torques need. The EUC body's pitch noise reaches the wheel centre ``C = E + R_E p``
through the 0.45 m lever ``p`` (2.3 mm per frame) and the rider pitch through the ankle hinge
``A = E + R_E (p - l0 e_z)`` (4 mrad per frame over the 0.61 m of A-G). Filtering gamma, phi and C
as three coordinates with one filter mixes the clean pivot positions with the noisy lever arms. Here
each per-frame quantity is split into a sum of pieces by where its noise comes from, each piece is
smoothed by the fixed-lag Kalman smoother (:mod:`euc_ros.core.filters.causal`) with a smoothing
time of its own, and the states are composed from the smoothed pieces and their derivatives.

Pieces (per frame, from the rigid-body poses; see :func:`split_pieces`):

* ``pos``: the pivot ``E`` (x, y) and ``r_pos = T^T (G_pos - E)`` (x, z) with
  ``G_pos = sum f_i P_i / sum f_i`` the mass-weighted segment pivots (position noise only);
* ``seg``: ``r_seg = T^T G_rot`` (x, z), ``G_rot = sum f_i R_i c_i / sum f_i`` (the segments'
  CoM offsets ``c_i`` rotated: the segments' orientation noise over 0.12-0.22 m);
* ``euc``: EUC pitch ``gamma``, the forward component ``u_f`` of ``u = R_E p`` in the heading
  frame and ``r_euc = -T^T R_E (p - l0 e_z)`` (x, z) (the EUC body's orientation noise over the
  lever arms);
* ``yaw``: the heading ``psi`` (unwrapped by whole turns, :func:`unwrap_turns`);
* ``lat``: the lateral component ``u_l`` of ``u`` in the heading frame (the EUC's lean).

``T = Rz(psi) Rx(theta)`` is the moving frame of eqs (1)-(2), so ``r_pos + r_seg + r_euc = r_AG``
and ``E + u = C`` exactly (the geometry of :func:`~euc_ros.core.states.geometry.frame_geometry`).

Composition (:func:`compose`), with the smoothed pieces and their first two derivatives:

* ``phi = atan2(r_x, r_z)`` with ``r = r_pos + r_seg + r_euc`` and its derivatives by the chain rule
  (``rho^2 = r_x^2 + r_z^2``)::

      phi_dot  = (r_z r_x' - r_x r_z') / rho^2
      phi_ddot = (r_z r_x'' - r_x r_z'') / rho^2 - 2 phi_dot (r_x r_x' + r_z r_z') / rho^2

* the longitudinal motion of C (``e_x = (cos psi, sin psi)``, ``u_h = (u_f, u_l)`` the lever in
  the heading frame, which turns at ``psi_dot``)::

      x_dot  = e_x . E' + u_f' - psi' u_l
      x_ddot = e_x . E'' + u_f'' - 2 psi' u_l' - psi'' u_l - psi'^2 u_f

  (``x_ddot = e_x . C''``, the paper's definition, as in :mod:`~euc_ros.core.states.kinematics`).

Every piece of a group goes through the same FIR weights (:func:`~euc_ros.core.filters.causal.kalman_weights`,
one smoothing time per group, the same lag), so polynomials up to degree 3 in every piece are
reproduced exactly, and the composition is exact on them. With one smoothing time for every group
and a constant heading, ``x_ddot`` is exactly the one filter applied to ``C`` (linearity).

Two paths, equal to round-off: :func:`split_derivatives` (offline, vectorized, stretch by stretch)
and :class:`StreamingSplit` (one frame at a time, one
:class:`~euc_ros.core.filters.causal.StreamingKalman` per group). A frame where any piece is missing
(an untracked EUC or a rider segment with mass) is missing for every group, so all groups share
their stretches and gap bridging.

The smoothing times (:data:`SPLIT_SMOOTHING`) were chosen on simulated rides (seeds 1-2, the
paper's noise, 120 Hz, studies/lag_curve.py) at a lag of 0.1 s; with the truncation :data:`SPLIT_TOL`
the ``euc`` group's 0.25 s gives the filter a memory of about 3.1 s (a stretch's first state comes
that late).

Units: SI, radians.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from euc_ros.core.errors import ConfigError
from euc_ros.core.filters.causal import StreamingKalman, fir_derivatives, kalman_weights, lag_frames
from euc_ros.core.filters.derivatives import DEFAULT_MAX_GAP
from euc_ros.core.rotations import quat_rotate
from euc_ros.core.states.geometry import frame_geometry, to_moving_frame

#: Lag [s] the smoothing times were chosen for.
SPLIT_LAG_S = 0.1
#: Smoothing time [s] of each group (constant-jerk model, lag 0.1 s; chosen on simulated rides).
SPLIT_SMOOTHING = {"pos": 0.065, "seg": 0.16, "euc": 0.25, "yaw": 0.1, "lat": 0.065}
#: Truncation of each group's impulse response (relative weight left out; the cubic-exactness
#: correction follows): 1e-2 gives the ``euc`` group a 3.1 s memory instead of 6.2 s at 1e-4, and a
#: slightly lower torque error on the tuning seeds (1.40x against 1.56x the default at 0.1 s).
SPLIT_TOL = 1e-2
#: The pieces of each group, in column order.
GROUPS = {"pos": ("E_x", "E_y", "rpos_x", "rpos_z"), "seg": ("rseg_x", "rseg_z"),
          "euc": ("gamma", "u_f", "reuc_x", "reuc_z"), "yaw": ("psi",), "lat": ("u_l",)}


def unwrap_turns(psi_wrapped, turns_before: int = 0, last_wrapped: float | None = None):
    """Unwrap an angle by whole turns, exactly: ``psi + 2 pi m`` with integer ``m``.

    ``m`` changes by ``-round(diff / 2 pi)`` between consecutive finite samples, so the offline
    (whole array) and the streaming (one sample, ``turns_before`` and ``last_wrapped`` carried)
    results are bitwise equal. NaN samples stay NaN and do not break the count.

    Parameters
    ----------
    psi_wrapped : float or array_like (n,)
        Wrapped angle [rad].
    turns_before : int
        Turns ``m`` carried from the samples before.
    last_wrapped : float, optional
        The last finite wrapped sample before [rad] (None: the first sample starts the count).

    Returns
    -------
    psi_unwrapped : numpy.ndarray (n,)
        The unwrapped angle [rad] (at least one-dimensional).
    turns_after : int
        ``m`` of the last finite sample (``turns_before`` when none is finite).
    last_wrapped_after : float or None
        The last finite wrapped sample [rad] (``last_wrapped`` when none is finite).
    """
    p = np.atleast_1d(np.asarray(psi_wrapped, dtype=float))
    out = np.full(p.shape, np.nan)
    fin = np.flatnonzero(np.isfinite(p))
    if fin.size == 0:
        return out, turns_before, last_wrapped
    seq = p[fin]
    prev = np.concatenate([[seq[0] if last_wrapped is None else last_wrapped], seq[:-1]])
    m = turns_before - np.cumsum(np.round((seq - prev) / (2.0 * np.pi)).astype(np.int64))
    out[fin] = seq + (2.0 * np.pi) * m
    return out, int(m[-1]), float(seq[-1])


def split_pieces(position, quat, tracked, session, bodies, *, geo: dict | None = None,
                 euc_center=(0.0, 0.0, 0.0)) -> dict[str, np.ndarray]:
    """Per-frame pieces of the split estimator (module docstring), from rigid-body poses.

    Parameters
    ----------
    position : array_like (b, n, 3)
        Pivot positions [m], Z-up world.
    quat : array_like (b, n, 4)
        Body-to-world quaternions (x, y, z, w).
    tracked : array_like (b, n) of bool, optional
    session : Session
    bodies : sequence of str
    geo : dict, optional
        :func:`~euc_ros.core.states.geometry.frame_geometry` of the same poses (``segments`` CoG), if
        already computed.
    euc_center : array_like (3,)
        Where the EUC body's orientation noise does not move the position, in the EUC body's frame
        relative to its pivot [m]: the pivot itself (default; the simulator's noise, and Motive's
        when the pivot is at the markers' centroid) or the markers' centroid. The split is made
        there: ``E`` is that point, the lever arms start from it.

    Returns
    -------
    dict of ndarray (n,)
        One entry per piece name of :data:`GROUPS` (``psi`` wrapped, in (-pi, pi]) and ``theta``.
        A frame missing any piece is NaN in every piece.
    """
    position = np.asarray(position, dtype=float)
    quat = np.asarray(quat, dtype=float)
    bodies = list(bodies)
    if geo is None:
        geo = frame_geometry(position, quat, tracked, session, bodies)
    psi, theta = geo["psi"], geo["theta"]
    E = geo["E"]
    center = np.asarray(euc_center, dtype=float)
    if np.any(center != 0.0):
        i = bodies.index(session.euc.body)
        E = E + quat_rotate(quat[i], np.broadcast_to(center, quat[i].shape[:-1] + (3,)))
    u = geo["C"] - E
    v = geo["A"] - E
    names, fractions, offsets = session.segment_arrays()
    shape = position.shape[1:-1]
    Gp = np.zeros(shape + (3,))
    Gr = np.zeros(shape + (3,))
    for name, f, off in zip(names, fractions, offsets):
        if f <= 0.0:
            continue
        if name not in bodies:
            Gp = Gp + np.nan
            continue
        i = bodies.index(name)
        Gp = Gp + f * position[i]
        Gr = Gr + f * quat_rotate(quat[i], np.broadcast_to(np.asarray(off, dtype=float), shape + (3,)))
    total = fractions[fractions > 0].sum()
    Gp, Gr = Gp / total, Gr / total
    r_pos = to_moving_frame(Gp - E, psi, theta)
    r_seg = to_moving_frame(Gr, psi, theta)
    r_euc = to_moving_frame(-v, psi, theta)
    c, s = np.cos(psi), np.sin(psi)
    out = {"E_x": E[..., 0], "E_y": E[..., 1], "rpos_x": r_pos[..., 0], "rpos_z": r_pos[..., 2],
           "rseg_x": r_seg[..., 0], "rseg_z": r_seg[..., 2], "gamma": geo["gamma"],
           "u_f": c * u[..., 0] + s * u[..., 1], "reuc_x": r_euc[..., 0], "reuc_z": r_euc[..., 2],
           "psi": psi, "u_l": -s * u[..., 0] + c * u[..., 1], "theta": theta}
    ok = geo["has_euc"] & geo["has_rider"]
    for k in out:
        ok = ok & np.isfinite(out[k])
    return {k: np.where(ok, v_, np.nan) for k, v_ in out.items()}


@dataclass
class SplitStates:
    """States composed from the smoothed pieces (arrays, or floats on the streaming path).

    Parameters
    ----------
    gamma, gamma_dot, gamma_ddot : numpy.ndarray
        EUC body pitch and its rates [rad, rad/s, rad/s^2].
    phi, phi_dot, phi_ddot : numpy.ndarray
        Rider pitch about the ankle hinge and its rates [rad, rad/s, rad/s^2].
    x_dot, x_ddot : numpy.ndarray
        Longitudinal speed and acceleration of the wheel centre [m/s, m/s^2].
    psi : numpy.ndarray
        Heading, unwrapped [rad].
    """

    gamma: np.ndarray
    gamma_dot: np.ndarray
    gamma_ddot: np.ndarray
    phi: np.ndarray
    phi_dot: np.ndarray
    phi_ddot: np.ndarray
    x_dot: np.ndarray
    x_ddot: np.ndarray
    psi: np.ndarray


def compose(d: dict) -> SplitStates:
    """States from ``d[group] = (y, y_dot, y_ddot)``, each ``(..., k)`` with the columns of :data:`GROUPS`.

    Parameters
    ----------
    d : dict of tuple of numpy.ndarray
        Per group of :data:`GROUPS`, the smoothed pieces and their first and second derivatives (SI, rad).

    Returns
    -------
    SplitStates
        The composed states, of shape ``(...)``.
    """
    P, S, U, Y, L = (d[g] for g in ("pos", "seg", "euc", "yaw", "lat"))
    rx = [P[j][..., 2] + S[j][..., 0] + U[j][..., 2] for j in range(3)]
    rz = [P[j][..., 3] + S[j][..., 1] + U[j][..., 3] for j in range(3)]
    rho2 = rx[0] * rx[0] + rz[0] * rz[0]
    phi = np.arctan2(rx[0], rz[0])
    phi_dot = (rz[0] * rx[1] - rx[0] * rz[1]) / rho2
    phi_ddot = (rz[0] * rx[2] - rx[0] * rz[2]) / rho2 - 2.0 * phi_dot * (rx[0] * rx[1] + rz[0] * rz[1]) / rho2
    psi, psi_d, psi_dd = Y[0][..., 0], Y[1][..., 0], Y[2][..., 0]
    c, s = np.cos(psi), np.sin(psi)
    uf, uf_d, uf_dd = U[0][..., 1], U[1][..., 1], U[2][..., 1]
    ul, ul_d = L[0][..., 0], L[1][..., 0]
    x_dot = c * P[1][..., 0] + s * P[1][..., 1] + uf_d - psi_d * ul
    x_ddot = (c * P[2][..., 0] + s * P[2][..., 1] + uf_dd - 2.0 * psi_d * ul_d - psi_dd * ul
              - psi_d * psi_d * uf)
    return SplitStates(gamma=U[0][..., 0], gamma_dot=U[1][..., 0], gamma_ddot=U[2][..., 0], phi=phi,
                       phi_dot=phi_dot, phi_ddot=phi_ddot, x_dot=x_dot, x_ddot=x_ddot, psi=psi)


def _smoothing(smoothing: dict | None) -> dict:
    out = dict(SPLIT_SMOOTHING)
    if smoothing:
        unknown = set(smoothing) - set(GROUPS)
        if unknown:
            raise ConfigError(f"unknown groups {sorted(unknown)}; expected {list(GROUPS)}", key="smoothing")
        out.update({k: float(v) for k, v in smoothing.items()})
    return out


def split_weights(dt: float, lag: int, smoothing: dict | None = None, tol: float = SPLIT_TOL) -> dict[str, np.ndarray]:
    """FIR weights (3, window) of each group (:func:`~euc_ros.core.filters.causal.kalman_weights`).

    Parameters
    ----------
    dt : float
        Frame period [s].
    lag : int
        Output delay [frames].
    smoothing : dict, optional
        Smoothing times [s] of some groups (default :data:`SPLIT_SMOOTHING`).
    tol : float
        Truncation of the impulse responses.

    Returns
    -------
    dict of numpy.ndarray
        Per group, the weights of the value and its first and second derivatives.

    Raises
    ------
    ConfigError
        Naming ``smoothing`` for a group not in :data:`GROUPS`, or bad filter settings.
    """
    return {g: kalman_weights(dt, lag, smoothing_s=t, tol=tol) for g, t in _smoothing(smoothing).items()}


def group_columns(pieces: dict) -> dict[str, np.ndarray]:
    """Stack the pieces of each group: ``(..., k)`` arrays, ``psi`` unwrapped by whole turns.

    Parameters
    ----------
    pieces : dict of array_like
        :func:`split_pieces` (every name of :data:`GROUPS`).

    Returns
    -------
    dict of numpy.ndarray
        Per group, its pieces as columns, in the order of :data:`GROUPS`.
    """
    out = {}
    for g, names in GROUPS.items():
        cols = []
        for nm in names:
            v = np.asarray(pieces[nm], dtype=float)
            if nm == "psi":
                v = unwrap_turns(v)[0].reshape(v.shape)
            cols.append(v)
        out[g] = np.stack(cols, axis=-1)
    return out


def split_derivatives(dt: float, pieces: dict, *, lag_s: float = SPLIT_LAG_S, smoothing: dict | None = None,
                      frame=None, max_gap: int = DEFAULT_MAX_GAP) -> SplitStates:
    """Offline (vectorized) split estimate of a recording: the states of each frame, ``lag_s`` late.

    Parameters
    ----------
    dt : float
        Frame period [s].
    pieces : dict of ndarray (n,)
        :func:`split_pieces` of the recording.
    lag_s : float
        Output delay [s] (rounded to frames).
    smoothing : dict, optional
        Smoothing times [s] of some groups (default :data:`SPLIT_SMOOTHING`).
    frame : array_like of int (n,), optional
        Frame numbers (gaps in them are missing frames).
    max_gap : int
        Longest run of missing frames bridged.

    Returns
    -------
    SplitStates
        Arrays (n,), aligned with the frames they describe; NaN where a group has no output (a
        stretch's first ``window - lag`` frames of the longest filter, its last ``lag`` frames).
    """
    lag = lag_frames(lag_s, dt)
    weights = split_weights(dt, lag, smoothing)
    cols = group_columns(pieces)
    d = {}
    for g, w in weights.items():
        r = fir_derivatives(dt, cols[g], w, lag, max_gap=max_gap, frame=frame)
        d[g] = (r.y, r.y_dot, r.y_ddot)
    return compose(d)


class StreamingSplit:
    """Online split estimator: push one frame's pieces, get the composed states ``lag`` frames back.

    One :class:`~euc_ros.core.filters.causal.StreamingKalman` per group, fed the same frames; a
    frame's states are composed once every group has given its output for it. Equal to
    :func:`split_derivatives` to round-off.

    Parameters
    ----------
    dt : float
        Frame period [s].
    lag_s : float
        Output delay [s] (rounded to frames).
    smoothing : dict, optional
        Smoothing times [s] of some groups (default :data:`SPLIT_SMOOTHING`).
    max_gap : int
        Longest run of missing frames bridged.

    Attributes
    ----------
    lag : int
        Output delay [frames].
    window : int
        Longest group memory [samples]: a stretch gives its first state after this many frames.
    """

    def __init__(self, dt: float, *, lag_s: float = SPLIT_LAG_S, smoothing: dict | None = None,
                 max_gap: int = DEFAULT_MAX_GAP) -> None:
        self.dt = float(dt)
        self.smoothing = _smoothing(smoothing)
        self.filters = {g: StreamingKalman(dt, lag_s=lag_s, smoothing_s=t, max_gap=max_gap, tol=SPLIT_TOL)
                        for g, t in self.smoothing.items()}
        self.lag = next(iter(self.filters.values())).lag
        self.lag_s = self.lag * self.dt
        self.window = max(f.window for f in self.filters.values())
        self._pending: dict[int, dict] = {}
        self._turns = 0
        self._last_psi: float | None = None

    def reset(self) -> None:
        """Start a new stretch in every group (the heading's turn count is kept)."""
        for f in self.filters.values():
            f.reset()
        self._pending.clear()

    def push(self, pieces: dict, frame: int | None = None) -> list[tuple[int, SplitStates, bool]]:
        """Add one frame's pieces (floats, :func:`split_pieces` of one frame; NaN: missing).

        Parameters
        ----------
        pieces : dict of float
            One frame's pieces (every name of :data:`GROUPS`); any NaN makes the frame missing.
        frame : int, optional
            Its frame number (default: the frame after the previous push).

        Returns
        -------
        list of tuple
            ``(frame, states, filled)`` (int, :class:`SplitStates` of floats, bool): usually zero or one, more
            after a bridged gap.
        """
        row = {}
        for g, names in GROUPS.items():
            vals = []
            for nm in names:
                v = float(np.asarray(pieces[nm], dtype=float).reshape(()))
                if nm == "psi":
                    u, self._turns, self._last_psi = unwrap_turns(v, self._turns, self._last_psi)
                    v = float(u[0])
                vals.append(v)
            row[g] = np.array(vals)
        if not all(np.all(np.isfinite(r)) for r in row.values()):
            row = {g: np.full(r.shape, np.nan) for g, r in row.items()}
        out = []
        for g, f in self.filters.items():
            for s in f.push(row[g], frame=frame):
                self._pending.setdefault(s.frame, {})[g] = s
        done = sorted(k for k, v in self._pending.items() if len(v) == len(self.filters))
        for k in done:
            samples = self._pending.pop(k)
            d = {g: (np.asarray(s.y), np.asarray(s.y_dot), np.asarray(s.y_ddot)) for g, s in samples.items()}
            out.append((k, compose(d), any(s.filled for s in samples.values())))
        # outputs of frames older than a completed one can no longer complete (a shorter filter's
        # output from before the longest filter's first): drop them
        if done:
            for k in [k for k in self._pending if k < done[-1]]:
                del self._pending[k]
        return out
