"""Frame-by-frame estimators behind the ``rider_state`` and ``torque_estimator`` nodes (ROS-free).

A node only converts messages and calls these (functional core, imperative shell):

* :class:`RiderStateEstimator`: one mocap frame in (pivot positions and quaternions of the rigid
  bodies), the planar model's states with their derivatives out, ``lag`` frames later. It does the
  per-frame geometry of :func:`~euc_ros.core.euc.kinematics.frame_geometry`, then runs two fixed-lag
  Savitzky-Golay filters (:class:`~euc_ros.core.filters.derivatives.StreamingSavgol`): one on the EUC
  (``gamma`` and the wheel centre C) and one on the rider pitch ``phi``, so that a missing rider
  segment does not cost the EUC its state. With the same settings its outputs equal
  :func:`~euc_ros.core.euc.kinematics.reconstruct_states` on the interior of every gap-free stretch.
* :class:`TorqueEstimator`: one state in, ``M_d1``/``M_d2`` of both models, the sliding-window RMSE
  of ``M_d1 - M_d2`` and the online h estimate out. It returns ``None`` for a state that is not
  usable, so a NaN never reaches a published torque.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from euc_ros.core.errors import ConfigError
from euc_ros.core.euc.kinematics import DEFAULT_SG_POLYORDER, DEFAULT_WINDOW_S, PHI_DEFINITIONS, frame_geometry
from euc_ros.core.euc.model import EucParams
from euc_ros.core.euc.online import OnlineHEstimator, SlidingRmse
from euc_ros.core.euc.torque import torques, torques_2dof
from euc_ros.core.filters.derivatives import DEFAULT_MAX_GAP, StreamingSavgol, window_samples


@dataclass(frozen=True)
class RiderStateSample:
    """The planar model's state of one mocap frame (fields as the RiderState message), SI units, radians.

    ``t`` is the capture time of ``frame`` (the output arrives ``filter_lag_s`` later). ``valid`` is
    True when every state and derivative is a measurement (rider present, nothing filled across a
    gap). ``x`` is the forward distance integrated from ``x_dot`` since the EUC filter last started.
    """

    frame: int
    t: float
    valid: bool
    has_rider: bool
    x: float
    x_dot: float
    x_ddot: float
    gamma: float
    gamma_dot: float
    gamma_ddot: float
    phi: float
    phi_dot: float
    phi_ddot: float
    phi_eq3: float
    phi_hinge: float
    phi_definition: str
    psi: float
    theta: float
    C: np.ndarray
    G: np.ndarray
    filter_lag_s: float


class RiderStateEstimator:
    """Frame-by-frame state reconstruction with fixed-lag derivatives (see the module docstring).

    Parameters
    ----------
    session : Session
        Segments, EUC geometry.
    dt : float
        Frame period [s] (1 / rate).
    phi_definition : {"hinge", "eq3"}
        Which rider pitch ``phi`` holds.
    window_s : float
        Savitzky-Golay window [s]; the lag is half of it.
    polyorder : int
        Savitzky-Golay order.
    max_gap : int
        Longest run of missing frames bridged (bridged frames give no output).
    """

    def __init__(self, session, dt: float, *, phi_definition: str = "hinge", window_s: float = DEFAULT_WINDOW_S,
                 polyorder: int = DEFAULT_SG_POLYORDER, max_gap: int = DEFAULT_MAX_GAP) -> None:
        if phi_definition not in PHI_DEFINITIONS:
            raise ConfigError(f"phi definition must be one of {PHI_DEFINITIONS}, got {phi_definition!r}",
                              key="phi_definition")
        self.session = session
        self.dt = float(dt)
        self.phi_definition = phi_definition
        window = window_samples(self.dt, window_s=window_s, polyorder=polyorder)
        self._euc = StreamingSavgol(window, polyorder, self.dt, max_gap=max_gap)
        self._rider = StreamingSavgol(window, polyorder, self.dt, max_gap=max_gap)
        self._raw: dict[int, tuple] = {}
        self._x = 0.0
        self._last: tuple[int, float] | None = None  # (frame, x_dot) of the previous output

    @property
    def lag_s(self) -> float:
        """Output delay [s]."""
        return self._euc.lag_s

    def reset(self) -> None:
        """Forget everything (e.g. on a jump back in time)."""
        self._euc.reset()
        self._rider.reset()
        self._raw.clear()
        self._x = 0.0
        self._last = None

    def update(self, frame: int, t: float, position, quat, tracked, bodies: Sequence[str]) -> list[RiderStateSample]:
        """Add one mocap frame and return the states that became available (usually 0 or 1).

        Parameters
        ----------
        frame : int
            Frame number (gaps in the numbering are missing frames).
        t : float
            Capture time of the frame [s].
        position : array_like (b, 3)
            Pivot positions [m], Z-up world.
        quat : array_like (b, 4)
            Body-to-world quaternions (x, y, z, w).
        tracked : array_like (b,) of bool, optional
        bodies : sequence of str
            Names of the b rows.
        """
        geo = frame_geometry(position, quat, tracked, self.session, bodies)
        phi_raw = geo["phi_hinge"] if self.phi_definition == "hinge" else geo["phi_eq3"]
        frame = int(frame)
        self._raw[frame] = (float(t), float(geo["psi"]), float(geo["theta"]), float(geo["phi_eq3"]),
                            float(geo["phi_hinge"]), np.asarray(geo["G"], float), bool(geo["has_rider"]))
        euc_out = self._euc.push(np.concatenate([[geo["gamma"]], geo["C"]]), frame=frame)
        rider_out = {s.frame: s for s in self._rider.push(float(phi_raw), frame=frame)}
        out = []
        for s in euc_out:
            raw = self._raw.get(s.frame)
            if s.filled or raw is None:
                continue
            t_f, psi, theta, phi_eq3, phi_hinge, G, has_rider = raw
            c, s_ = np.cos(psi), np.sin(psi)
            x_dot = c * s.y_dot[1] + s_ * s.y_dot[2]
            x_ddot = c * s.y_ddot[1] + s_ * s.y_ddot[2]
            if self._last is not None and s.frame - self._last[0] <= self._euc.max_gap + 1:
                self._x += 0.5 * (x_dot + self._last[1]) * (s.frame - self._last[0]) * self.dt
            else:
                self._x = 0.0
            self._last = (s.frame, x_dot)
            r = rider_out.get(s.frame)
            phi = (r.y, r.y_dot, r.y_ddot) if r is not None and not r.filled else (np.nan, np.nan, np.nan)
            vals = (x_dot, x_ddot, s.y[0], s.y_dot[0], s.y_ddot[0], *phi)
            valid = bool(np.all(np.isfinite(vals)))
            out.append(RiderStateSample(
                frame=s.frame, t=t_f, valid=valid, has_rider=has_rider, x=self._x, x_dot=float(x_dot),
                x_ddot=float(x_ddot), gamma=float(s.y[0]), gamma_dot=float(s.y_dot[0]),
                gamma_ddot=float(s.y_ddot[0]), phi=float(phi[0]), phi_dot=float(phi[1]), phi_ddot=float(phi[2]),
                phi_eq3=phi_eq3, phi_hinge=phi_hinge, phi_definition=self.phi_definition, psi=psi, theta=theta,
                C=np.asarray(s.y[1:4], float), G=G, filter_lag_s=self.lag_s))
        # Raw geometry is needed until its frame leaves the filter: drop what is older than the window.
        oldest = frame - self._euc.window - self._euc.max_gap - 1
        for k in [k for k in self._raw if k <= oldest or (out and k <= out[-1].frame)]:
            del self._raw[k]
        return out


@dataclass(frozen=True)
class TorqueSample:
    """Driving torque estimate of one state (fields as the TorqueEstimate message).

    Attributes
    ----------
    frame : int
    t : float
        Capture time of the state [s].
    M_d1, M_d2 : float
        3-DoF driving torque from eq (9) and eq (10) at ``h_m`` [N m] (always finite).
    M_d1_2dof, M_d2_2dof : float
        Reduced model, eq (13) [N m] (always finite).
    h_m : float
        CoG height used [m].
    residual_nm : float
        ``M_d1 - M_d2`` [N m].
    rmse_window_nm : float
        Sliding-window RMSE of the residual [N m].
    window_s : float
        Length of that window [s].
    h_online_m, h_online_std_m : float
        Online estimate of h and its standard deviation [m] (NaN until enough excitation).
    model : str
        ``"3dof"``, or ``"3dof+extra"`` with an extra generalized force.
    """

    frame: int
    t: float
    M_d1: float
    M_d2: float
    M_d1_2dof: float
    M_d2_2dof: float
    h_m: float
    residual_nm: float
    rmse_window_nm: float
    window_s: float
    h_online_m: float
    h_online_std_m: float
    model: str = "3dof"
    extra: dict = field(default_factory=dict)


class TorqueEstimator:
    """Torques of both models, sliding RMSE and online h from one state at a time.

    Parameters
    ----------
    params : EucParams
        Nominal parameters with the CoG height ``h`` to evaluate the torques at [m].
    dt : float
        Sample period [s].
    rmse_window_s : float
        Sliding RMSE window [s].
    h_window_s : float
        Window of the online h estimate [s].
    h_update_every : int
        Re-estimate h every this many samples.
    correlation_samples : float, optional
        Variance inflation of the online h (default: one Savitzky-Golay window of 0.9 s in samples).
    min_sensitivity : float
        Excitation needed before the online h is given [N m/m].
    extra_Q : callable, optional
        ``extra_Q(state) -> (3,)`` additional generalized force [N, N m, N m] (model extensions).
    """

    def __init__(self, params: EucParams, dt: float, *, rmse_window_s: float = 5.0, h_window_s: float = 30.0,
                 h_update_every: int = 12, correlation_samples: float | None = None, min_sensitivity: float = 5.0,
                 extra_Q: Callable | None = None) -> None:
        if not (dt > 0 and rmse_window_s > 0 and h_window_s > 0):
            raise ConfigError("dt, rmse_window_s and h_window_s must be > 0", key="rmse_window_s")
        self.params = params
        self.dt = float(dt)
        self.extra_Q = extra_Q
        n_rmse = max(1, int(round(rmse_window_s / self.dt)))
        self.window_s = n_rmse * self.dt
        self._rmse = SlidingRmse(n_rmse)
        k = window_samples(self.dt, window_s=DEFAULT_WINDOW_S) if correlation_samples is None else correlation_samples
        self._h = OnlineHEstimator(params, max(3, int(round(h_window_s / self.dt))), update_every=h_update_every,
                                   correlation_samples=k, min_sensitivity=min_sensitivity)

    def update(self, state) -> TorqueSample | None:
        """Process one state (any object with the RiderStateSample fields).

        Returns
        -------
        TorqueSample or None
            None when the state is not valid or any torque would not be finite (the sliding windows
            still age by one sample).
        """
        args = tuple(float(getattr(state, k)) for k in ("gamma", "phi", "gamma_dot", "phi_dot", "x_ddot",
                                                          "gamma_ddot", "phi_ddot"))
        ok = bool(getattr(state, "valid", True)) and all(np.isfinite(args))
        extra = None
        if ok and self.extra_Q is not None:
            extra = np.asarray(self.extra_Q(state), dtype=float)
            ok = bool(np.all(np.isfinite(extra)))
        if not ok:
            self._rmse.push(np.nan)
            self._h.update(*([np.nan] * 7))
            return None
        d1, d2 = (float(v) for v in torques(*args, self.params, extra_Q=extra))
        e1, e2 = (float(v) for v in torques_2dof(args[1], args[3], args[4], args[6], self.params))
        if not all(np.isfinite((d1, d2, e1, e2))):
            self._rmse.push(np.nan)
            self._h.update(*([np.nan] * 7))
            return None
        rmse = self._rmse.push(d1 - d2)
        est = self._h.update(*args)
        return TorqueSample(frame=int(getattr(state, "frame", -1)), t=float(getattr(state, "t", np.nan)),
                            M_d1=d1, M_d2=d2, M_d1_2dof=e1, M_d2_2dof=e2, h_m=float(self.params.h),
                            residual_nm=d1 - d2, rmse_window_nm=rmse, window_s=self.window_s,
                            h_online_m=est.h_m, h_online_std_m=est.h_std_m,
                            model="3dof" if self.extra_Q is None else "3dof+extra")
