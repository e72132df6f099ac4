"""Frame-by-frame estimators behind the ``rider_state`` and ``torque_estimator`` nodes (ROS-free).

A node only converts messages and calls these (functional core, imperative shell):

* :class:`RiderStateEstimator`: one mocap frame in (pivot positions and quaternions of the rigid
  bodies), the planar model's states with their derivatives out, ``lag`` frames later. It does the
  per-frame geometry of :func:`~euc_ros.core.states.geometry.frame_geometry`, then runs two fixed-lag
  Savitzky-Golay filters (:class:`~euc_ros.core.filters.derivatives.StreamingSavgol`): one on the EUC
  (``gamma`` and the wheel centre C) and one on the rider pitch ``phi``, so that a missing rider
  segment does not cost the EUC its state. With the same settings its outputs equal
  :func:`~euc_ros.core.states.kinematics.reconstruct_states` on the interior of every gap-free stretch.
* :class:`TorqueEstimator`: one state in, ``M_d1``/``M_d2`` of both models, the sliding-window RMSE
  of ``M_d1 - M_d2`` and the online h estimate out. It returns ``None`` for a state that is not
  usable, so a NaN never reaches a published torque. It ages its windows over missing states and
  resets on a jump back in time; optionally it evaluates the model extended with the effects the
  residual analysis selected (:class:`~euc_ros.core.model.extended.Model`).
* :class:`FrameSequencer`: frame numbers for the state estimator from a live stream (repeated and
  out-of-order frames dropped, restarts detected, numbers made from stamps when the source has none).
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from typing import Callable, Iterable, Iterator, Sequence

import numpy as np

from euc_ros.core.errors import ConfigError
from euc_ros.core.filters.causal import STATE_ESTIMATORS, streaming_filter
from euc_ros.core.filters.derivatives import StreamingSavgol, window_samples
from euc_ros.core.mocap.bridging import PoseBridge
from euc_ros.core.model.extended import Model, parse_effect_assignments
from euc_ros.core.model.terms import EucParams
from euc_ros.core.model.torque import torques, torques_2dof, torques_one
from euc_ros.core.online.window import OnlineHEstimator, SlidingRmse
from euc_ros.core.states.geometry import frame_geometry
from euc_ros.core.states.kinematics import DEFAULT_WINDOW_S
from euc_ros.core.states.settings import ReconstructionSettings
from euc_ros.core.states.skeleton import OnlineSkeleton
from euc_ros.core.states.split_lag import SPLIT_LAG_S, StreamingSplit, split_pieces


@dataclass(frozen=True)
class RiderStateSample:
    """The planar model's state of one mocap frame (fields as the RiderState message), SI units, radians.

    ``t`` is the capture time of ``frame`` (the output arrives ``filter_lag_s`` later). ``valid`` is
    True when every state and derivative is a measurement (rider present, nothing filled across a
    gap). ``x`` is the forward distance integrated from ``x_dot`` since the EUC filter last started.

    Parameters
    ----------
    frame : int
        Mocap frame number.
    t : float
        Capture time of the frame [s].
    valid, has_rider : bool
        Every state and derivative is a measurement; the rider's bodies were tracked.
    x, x_dot, x_ddot, gamma, gamma_dot, gamma_ddot : float
        Forward distance [m], speed [m/s] and acceleration [m/s^2] of the wheel centre; EUC body pitch
        [rad] and its rates [rad/s, rad/s^2].
    phi, phi_dot, phi_ddot : float
        Rider pitch of ``phi_definition`` [rad] and its rates [rad/s, rad/s^2].
    phi_eq3, phi_hinge, psi, theta : float
        Rider pitch from the wheel centre (eq (3)) and from the ankle hinge, EUC yaw and tilt [rad], unfiltered.
    phi_definition : str
        ``"hinge"`` or ``"eq3"``: which of the two ``phi`` holds.
    C, G : numpy.ndarray
        Wheel centre and rider CoG (3,), Z-up world [m].
    filter_lag_s : float
        Delay of the output behind ``t`` [s].
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
    settings : ReconstructionSettings, optional
        The filter (a window in seconds; the lag is half of it), the pitch definition ``phi``
        holds, the CoG method and the longest run of missing frames bridged (bridged frames give
        no output). Default: the offline defaults with a :data:`DEFAULT_WINDOW_S` window.
        ``cog_method`` ``skeleton`` fits the chain to each frame
        (:class:`~euc_ros.core.states.skeleton.OnlineSkeleton`: no lag, ``cog_lag_s`` = 0; swapped or
        flipped bodies excluded and counted in ``cog_faults``).
    estimator : {"savgol", "kalman", "split"}
        Derivative filter (:func:`~euc_ros.core.filters.causal.streaming_filter`): the Savitzky-Golay
        filter (default) or the low-lag Kalman fixed-lag smoother; or ``split``
        (:mod:`~euc_ros.core.states.split_lag`: pivot positions and orientation-borne pieces smoothed
        separately, then composed; half the M_d1 and a quarter of the M_d2 error of ``kalman`` at
        0.1 s, but a 3 s start-up, ``phi_definition`` hinge and ``cog_method`` segments only, a
        frame without the rider gives no EUC state either, and ``C`` is the frame's unsmoothed
        wheel centre).
    lag_s : float, optional
        Output delay [s]: default half the Savitzky-Golay window, or 0.1 s for ``kalman`` and ``split``.
    smoothing_s : float, optional
        Smoothing time of the ``kalman`` estimator [s] (default: measured per lag).
    skeleton : SkeletonModel, optional
        The session's chain estimated offline; default: calibrated on the first
        ``skeleton_calibration_frames`` frames.
    skeleton_calibration_frames : int
        Frames of the live calibration of the chain's link vectors.
    split_euc_center : array_like (3,)
        ``split`` only: where the EUC body's orientation noise leaves the position unmoved, in its
        body frame from its pivot [m] (:func:`~euc_ros.core.states.split_lag.split_pieces`): the pivot
        (default) or the markers' centroid when the pivot was placed elsewhere.

    Raises
    ------
    ConfigError
        For a window chosen from the data (``"auto"``: a live filter needs it in seconds), or an
        unknown or inconsistent ``estimator`` or ``split_euc_center``.
    """

    def __init__(self, session, dt: float, *, settings: ReconstructionSettings | None = None,
                 estimator: str = "savgol", lag_s: float | None = None, smoothing_s: float | None = None,
                 skeleton=None, skeleton_calibration_frames: int = 240,
                 split_euc_center=(0.0, 0.0, 0.0)) -> None:
        settings = ReconstructionSettings(window_s=DEFAULT_WINDOW_S) if settings is None else settings
        if settings.is_auto:
            raise ConfigError("a live filter needs its window in seconds, not 'auto'", key="window_s")
        phi_definition, cog_method, max_gap = settings.phi_definition, settings.cog_method, settings.max_gap
        window_s, polyorder = settings.window_s, settings.polyorder
        self.session = session
        self.dt = float(dt)
        self.phi_definition = phi_definition
        self.estimator = estimator
        self.cog_method = cog_method
        self._skeleton = (OnlineSkeleton(session, calibration_frames=skeleton_calibration_frames, model=skeleton)
                          if cog_method == "skeleton" else None)
        #: Rider body-frames excluded from G so far (swaps, flips), and per body.
        self.cog_faults = 0
        self.cog_fault_bodies: dict[str, int] = {}
        if estimator not in STATE_ESTIMATORS:
            raise ConfigError(f"estimator must be one of {STATE_ESTIMATORS}, got {estimator!r}", key="estimator")
        self._split = None
        if estimator == "split":
            if phi_definition != "hinge" or cog_method != "segments":
                raise ConfigError("the split estimator needs phi_definition 'hinge' and cog_method 'segments'",
                                  key="estimator")
            self._split = StreamingSplit(self.dt, lag_s=SPLIT_LAG_S if lag_s is None else lag_s, max_gap=max_gap)
            self._euc = self._rider = None
            center = np.asarray(split_euc_center, dtype=float)
            if center.shape != (3,) or not np.isfinite(center).all():
                raise ConfigError(f"split_euc_center must be 3 finite numbers [m], got {list(np.ravel(center))}",
                                  key="split_euc_center")
            self._split_center = tuple(float(v) for v in center)
        else:
            make = dict(window_s=window_s, polyorder=polyorder, max_gap=max_gap, lag_s=lag_s, smoothing_s=smoothing_s)
            self._euc = streaming_filter(estimator, self.dt, **make)
            self._rider = streaming_filter(estimator, self.dt, **make)
        # each body's short gaps are bridged before the geometry, max_gap frames late (as offline)
        self._bridge = PoseBridge(max_gap)
        #: Body samples bridged so far.
        self.bridged_samples = 0
        self._raw: dict[int, tuple] = {}
        self._x = 0.0
        self._last: tuple[int, float] | None = None  # (frame, x_dot) of the previous output

    @property
    def lag_s(self) -> float:
        """Output delay [s]: the filter's centred lag.

        Right after a body's gap of k frames the bridge adds up to k frames once.
        """
        return self._split.lag_s if self._split is not None else self._euc.lag_s

    @property
    def cog_lag_s(self) -> float:
        """Delay the CoG method adds [s]: 0 (both methods work on each frame alone)."""
        return 0.0 if self._skeleton is None else self._skeleton.lag_s

    def reset(self) -> None:
        """Forget everything (e.g. on a jump back in time)."""
        if self._split is not None:
            self._split.reset()
        else:
            self._euc.reset()
            self._rider.reset()
        self._bridge.reset()
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

        Returns
        -------
        list of RiderStateSample
            The states of earlier frames that left the filter's lag, oldest first.
        """
        out = []
        for f, t_f, pos, q, trk, bridged in self._bridge.push(frame, t, position, quat, tracked, bodies):
            self.bridged_samples += int(bridged.sum())
            out += self._update_bridged(f, t_f, pos, q, trk, bodies)
        return out

    def update_series(self, series, frames: Iterable[int] | None = None) -> Iterator[tuple[int, RiderStateSample]]:
        """Feed the frames of a recording one at a time, as a live stream (:meth:`update` on each).

        Parameters
        ----------
        series : MocapSeries
            The recording (Z-up world).
        frames : iterable of int, optional
            Indices of the frames to feed, in order (default: all).

        Yields
        ------
        k : int
            Index of the newest frame fed.
        state : RiderStateSample
            A state that became available with it.
        """
        for k in range(series.n_frames) if frames is None else frames:
            for state in self.update(int(series.frame[k]), float(series.t[k]), series.position[:, k],
                                     series.quat[:, k], series.tracked[:, k], series.bodies):
                yield k, state

    def _update_bridged(self, frame: int, t: float, position, quat, tracked, bodies) -> list[RiderStateSample]:
        if self._skeleton is None:
            geo = frame_geometry(position, quat, tracked, self.session, bodies)
        else:
            model, thr = self._skeleton.calibrate(position, quat, tracked, bodies)
            geo = frame_geometry(position, quat, tracked, self.session, bodies, cog_method="skeleton",
                                 skeleton=model, fault_threshold_m=thr)
            self.cog_faults += int(geo["n_faults"])
            for nm, c in geo.get("cog_fault_bodies", {}).items():
                self.cog_fault_bodies[nm] = self.cog_fault_bodies.get(nm, 0) + c
        if self._split is not None:
            return self._update_split(int(frame), t, position, quat, tracked, bodies, geo)
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

    def _update_split(self, frame: int, t: float, position, quat, tracked, bodies, geo) -> list[RiderStateSample]:
        pieces = split_pieces(position, quat, tracked, self.session, bodies, geo=geo, euc_center=self._split_center)
        self._raw[frame] = (float(t), float(geo["psi"]), float(geo["theta"]), float(geo["phi_eq3"]),
                            float(geo["phi_hinge"]), np.asarray(geo["G"], float), bool(geo["has_rider"]),
                            np.asarray(geo["C"], float))
        out = []
        for f, st, filled in self._split.push(pieces, frame=frame):
            raw = self._raw.get(f)
            if filled or raw is None:
                continue
            t_f, psi, theta, phi_eq3, phi_hinge, G, has_rider, C = raw
            x_dot, x_ddot = float(st.x_dot), float(st.x_ddot)
            if self._last is not None and f - self._last[0] <= self._split.filters["pos"].max_gap + 1:
                self._x += 0.5 * (x_dot + self._last[1]) * (f - self._last[0]) * self.dt
            else:
                self._x = 0.0
            self._last = (f, x_dot)
            vals = (x_dot, x_ddot, st.gamma, st.gamma_dot, st.gamma_ddot, st.phi, st.phi_dot, st.phi_ddot)
            out.append(RiderStateSample(
                frame=f, t=t_f, valid=bool(np.all(np.isfinite(vals))), has_rider=has_rider, x=self._x,
                x_dot=x_dot, x_ddot=x_ddot, gamma=float(st.gamma), gamma_dot=float(st.gamma_dot),
                gamma_ddot=float(st.gamma_ddot), phi=float(st.phi), phi_dot=float(st.phi_dot),
                phi_ddot=float(st.phi_ddot), phi_eq3=phi_eq3, phi_hinge=phi_hinge, phi_definition=self.phi_definition,
                psi=psi, theta=theta, C=C, G=G, filter_lag_s=self.lag_s))
        oldest = frame - self._split.window - self._split.filters["pos"].max_gap - 1
        for k in [k for k in self._raw if k <= oldest or (out and k <= out[-1].frame)]:
            del self._raw[k]
        return out


class FrameSequencer:
    """Frame numbers for the live state estimator: order checks and restarts of the mocap source.

    A :class:`RiderStateEstimator` needs increasing frame numbers (gaps are missing frames). Live
    streams may repeat or reorder frames, restart their numbering (a looping replay, a restarted
    Motive) or carry no frame number at all (``-1``: frames assembled from pose topics). This class
    decides, frame by frame, what the estimator does with each one.

    Rules, with ``dstamp`` the stamp difference to the last accepted frame:

    * no frame number (``< 0``): the number is ``round((stamp - origin) * rate)`` with ``origin`` the
      stamp of the first frame after a (re)start;
    * ``dstamp < -restart_jump_s``: the source restarted (time jumped back): ``"restart"``;
    * a frame number not above the last one with a *later* stamp: the numbering restarted:
      ``"restart"``;
    * otherwise a frame number not above the last one, or a stamp not after the last one: a repeated or
      out-of-order frame: ``"drop"``;
    * else ``"ok"`` (``"start"`` for the very first frame).

    Parameters
    ----------
    rate_hz : float
        Nominal frame rate [Hz] (for frames without a number).
    restart_jump_s : float
        A jump back in time longer than this is a restart [s].

    Raises
    ------
    ConfigError
        When the rate is not positive (key ``rate_hz``).

    Examples
    --------
    >>> s = FrameSequencer(100.0)
    >>> [s.accept(f, t)[0] for f, t in ((5, 0), (6, 10_000_000), (6, 10_000_000), (1, 20_000_000))]
    ['start', 'ok', 'drop', 'restart']
    """

    def __init__(self, rate_hz: float, restart_jump_s: float = 1.0) -> None:
        if not (np.isfinite(rate_hz) and rate_hz > 0):
            raise ConfigError(f"rate must be > 0, got {rate_hz!r}", key="rate_hz")
        self.period_ns = 1e9 / float(rate_hz)
        self.restart_jump_ns = int(round(float(restart_jump_s) * 1e9))
        self._last: tuple[int, int] | None = None   # (frame, stamp_ns) of the last accepted frame
        self._origin_ns = 0
        self.restarts = 0
        self.dropped = 0

    def reset(self) -> None:
        """Forget the stream (the next frame is a start)."""
        self._last = None

    def accept(self, frame_number: int, stamp_ns: int) -> tuple[str, int]:
        """Classify one frame; returns ``(action, frame)`` with action start, ok, restart or drop.

        Parameters
        ----------
        frame_number : int
            The frame's number, or a negative value for none.
        stamp_ns : int
            The frame's capture stamp [ns].

        Returns
        -------
        tuple of (str, int)
            The action, and the frame number to use (computed from the stamp for frames without one).
        """
        frame_number, stamp_ns = int(frame_number), int(stamp_ns)
        if self._last is None:
            return self._start("start", frame_number, stamp_ns)
        last_frame, last_stamp = self._last
        dstamp = stamp_ns - last_stamp
        if dstamp < -self.restart_jump_ns:
            self.restarts += 1
            return self._start("restart", frame_number, stamp_ns)
        frame = frame_number if frame_number >= 0 else int(round((stamp_ns - self._origin_ns) / self.period_ns))
        if frame_number >= 0 and frame <= last_frame and dstamp > 0:
            self.restarts += 1
            return self._start("restart", frame_number, stamp_ns)
        if frame <= last_frame or dstamp <= 0:
            self.dropped += 1
            return "drop", frame
        self._last = (frame, stamp_ns)
        return "ok", frame

    def _start(self, action: str, frame_number: int, stamp_ns: int) -> tuple[str, int]:
        self._origin_ns = stamp_ns
        frame = frame_number if frame_number >= 0 else 0
        self._last = (frame, stamp_ns)
        return action, frame


@dataclass(frozen=True)
class TorqueSample:
    """Driving torque estimate of one state (fields as the TorqueEstimate message).

    Parameters
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
    h_online_status : str
        ``"ok"``, or ``"not yet (...)"`` saying what is missing (time of valid states, excitation).
    model : str
        ``"3dof"``, or ``"3dof+extra"`` with an extra generalized force.
    extra : dict
        Further values by name (an extended model adds ``rmse_base_nm``, the base model's sliding RMSE [N m]).
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
    h_online_status: str = ""


#: Default period of the online h re-estimate [s] (:class:`TorqueEstimator`).
H_UPDATE_S = 0.1


class TorqueEstimator:
    """Torques of both models, sliding RMSE and online h from one state at a time.

    The states must arrive in time order, one per frame. The estimator watches their capture times
    ``state.t``: a run of missing states ages the sliding windows by the number of missing frames (so
    the RMSE always covers the last ``rmse_window_s`` of time), a gap at least as long as the RMSE
    window or a jump back in time (a restarted source) resets everything, and a repeated time is
    dropped. Nothing from before a reset reaches a later output.

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
    h_update_every : int, optional
        Re-estimate h every this many samples (default: every :data:`H_UPDATE_S` of samples, 12 at
        120 Hz, so that the cost per state does not grow with the frame rate).
    correlation_samples : float, optional
        Variance inflation of the online h (default: one Savitzky-Golay window of 0.9 s in samples).
    min_sensitivity : float
        Excitation needed before the online h is given [N m/m].
    extra_Q : callable, optional
        ``extra_Q(state) -> (3,)`` additional generalized force [N, N m, N m] (model extensions).
    model : Model, optional
        The 3-DoF model extended with effects of the residual analysis
        (:class:`~euc_ros.core.model.extended.Model`, built with ``online=True``): when
        given, ``M_d1``, ``M_d2``, the residual and its RMSE are the extended model's, evaluated at
        ``params.h``, and ``model`` of each sample is its name (``"3dof+ground_slope"``). The 2-DoF
        torques and the online h stay those of the paper's models.
    psi_rate_window_s : float
        Window of the causal yaw-rate estimate some effects need (``tilt_gravity``) [s]: a cubic
        Savitzky-Golay fit of the unwrapped yaw, evaluated at the newest state (no lag; the states
        themselves carry no yaw rate). Its first window of states after a (re)start gives no output.
    base_h : float, optional
        With ``model``: the h of the 3-DoF model the effects extend (the analysis' base model) [m]. The
        base model's residual is then tracked too, over the same window (``extra["rmse_base_nm"]`` of
        each sample), so that a model whose effects do not belong to the ride shows as fitting worse.

    Raises
    ------
    ConfigError
        When a period or window is not positive, or both an extended model and ``extra_Q`` are given.
    """

    def __init__(self, params: EucParams, dt: float, *, rmse_window_s: float = 5.0, h_window_s: float = 30.0,
                 h_update_every: int | None = None, correlation_samples: float | None = None,
                 min_sensitivity: float = 5.0,
                 extra_Q: Callable | None = None, model: Model | None = None,
                 psi_rate_window_s: float = 0.3, base_h: float | None = None) -> None:
        if not (dt > 0 and rmse_window_s > 0 and h_window_s > 0):
            raise ConfigError("dt, rmse_window_s and h_window_s must be > 0", key="rmse_window_s")
        if model is not None and extra_Q is not None:
            raise ConfigError("give either an extended model or extra_Q, not both", key="effects")
        self.params = params
        self.dt = float(dt)
        self.extra_Q = extra_Q
        self.model = model
        n_rmse = max(1, int(round(rmse_window_s / self.dt)))
        self.window_s = n_rmse * self.dt
        self._rmse = SlidingRmse(n_rmse)
        self._base = (replace(params, h=float(base_h)), SlidingRmse(n_rmse)) \
            if model is not None and base_h is not None and np.isfinite(base_h) and base_h > 0 else None
        k = window_samples(self.dt, window_s=DEFAULT_WINDOW_S) if correlation_samples is None else correlation_samples
        if not h_update_every:
            h_update_every = max(1, int(round(H_UPDATE_S / self.dt)))
        self._h = OnlineHEstimator(params, max(3, int(round(h_window_s / self.dt))), update_every=h_update_every,
                                   correlation_samples=k, min_sensitivity=min_sensitivity)
        names = {c.name for c in (model.effects if model is not None else ())}
        self._needs_psi_rate = "tilt_gravity" in names
        self._psi_rate = (StreamingSavgol(window_samples(self.dt, window_s=max(psi_rate_window_s, 6 * self.dt),
                                                         polyorder=3), 3, self.dt, lag=0)
                          if self._needs_psi_rate else None)
        self._last_t: float | None = None
        self._t0: float | None = None
        self._psi_prev: float | None = None
        self._psi_unwrapped = 0.0
        self._frame = 0
        #: Counters: states seen, samples returned, states not usable, resets, repeated times dropped,
        #: frames missing between states.
        self.counts = {"states": 0, "outputs": 0, "invalid": 0, "resets": 0, "repeated": 0, "missing": 0}

    @property
    def model_name(self) -> str:
        """``"3dof"``, ``"3dof+extra"`` or the extended model's name."""
        if self.model is not None:
            return self.model.label
        return "3dof" if self.extra_Q is None else "3dof+extra"

    def reset(self) -> None:
        """Forget every window (a new stream starts with the next state)."""
        self._rmse.reset()
        if self._base is not None:
            self._base[1].reset()
        self._h.reset()
        if self._psi_rate is not None:
            self._psi_rate.reset()
        self._last_t = None
        self._t0 = None
        self._psi_prev = None
        self._frame = 0
        self.counts["resets"] += 1

    @property
    def _scalar_params(self) -> bool:
        """True when every model parameter is a scalar (then one sample goes through torques_one)."""
        p = self.params
        if getattr(self, "_scalar_for", None) is not p:
            self._scalar_for = p
            self._scalar = all(np.ndim(getattr(p, f.name)) == 0 for f in fields(p))
        return self._scalar

    def set_h(self, h: float) -> None:
        """Use ``h`` [m] from the next state on (a value identified while the stream runs).

        The sliding RMSE starts again: residuals under two values of h do not mix.

        Parameters
        ----------
        h : float
            CoG height above the ankle hinge [m], positive.

        Raises
        ------
        ConfigError
            For an extended model (its parameters, h among them, are fitted together: restart with them).
        """
        if self.model is not None:
            raise ConfigError(f"h of the extended model {self.model.label} is fitted with its effects; restart the "
                              "node with the new h and effect_parameters", key="h")
        if not (np.isfinite(h) and h > 0):
            raise ConfigError(f"h must be a positive length in m, got {h!r}", key="h")
        self.params = replace(self.params, h=float(h))
        self._rmse.reset()

    def _age(self, n: int) -> None:
        for _ in range(n):
            self._rmse.push(np.nan)
            if self._base is not None:
                self._base[1].push(np.nan)
            self._h.update(*([np.nan] * 7))

    def _continuity(self, t: float) -> bool:
        """Handle gaps and jumps in the state times; False when the state must be dropped."""
        if not np.isfinite(t):
            return True
        if self._last_t is not None:
            step = (t - self._last_t) / self.dt
            if step <= -0.5:
                self.reset()
            elif step < 0.5:
                self.counts["repeated"] += 1
                return False
            else:
                missing = int(round(step)) - 1
                if missing >= self._rmse.window:
                    self.reset()
                elif missing > 0:
                    self.counts["missing"] += missing
                    self._age(missing)
                    self._frame += missing
        if self._t0 is None:
            self._t0 = t
        self._last_t = t
        return True

    def _yaw_rate(self, state) -> float:
        psi = float(getattr(state, "psi", np.nan))
        if self._psi_rate is None:
            return 0.0
        if not np.isfinite(psi):
            return np.nan
        if self._psi_prev is None:
            self._psi_unwrapped = psi
        else:
            self._psi_unwrapped += (psi - self._psi_prev + np.pi) % (2 * np.pi) - np.pi
        self._psi_prev = psi
        out = self._psi_rate.push(self._psi_unwrapped, frame=self._frame)
        return float(out[-1].y_dot) if out else np.nan

    def update(self, state) -> TorqueSample | None:
        """Process one state (any object with the RiderStateSample fields).

        Parameters
        ----------
        state : RiderStateSample
            The state (or any object with its fields).

        Returns
        -------
        TorqueSample or None
            None when the state is not valid, any torque would not be finite, or its time repeats the
            previous one (the sliding windows still age by one sample, except for a repeat).
        """
        self.counts["states"] += 1
        t = float(getattr(state, "t", np.nan))
        if not self._continuity(t):
            return None
        args = tuple(float(getattr(state, k)) for k in ("gamma", "phi", "gamma_dot", "phi_dot", "x_ddot",
                                                          "gamma_ddot", "phi_ddot"))
        psi_dot = self._yaw_rate(state)
        self._frame += 1
        ok = bool(getattr(state, "valid", True)) and all(np.isfinite(args))
        extra = None
        if ok and self.extra_Q is not None:
            extra = np.asarray(self.extra_Q(state), dtype=float)
            ok = bool(np.all(np.isfinite(extra)))
        d1 = d2 = np.nan
        if ok and self.model is not None:
            gamma, phi, gamma_dot, phi_dot, x_ddot, gamma_ddot, phi_ddot = args
            m1, m2 = self.model.torques(dict(
                t=(t - self._t0) if np.isfinite(t) else 0.0, x_dot=float(getattr(state, "x_dot", np.nan)),
                x_ddot=x_ddot, gamma=gamma, gamma_dot=gamma_dot, gamma_ddot=gamma_ddot, phi=phi, phi_dot=phi_dot,
                phi_ddot=phi_ddot, psi=float(getattr(state, "psi", 0.0)), psi_dot=psi_dot,
                theta=float(getattr(state, "theta", 0.0))))
            d1, d2 = float(np.squeeze(m1)), float(np.squeeze(m2))
        elif ok and self._scalar_params:
            d1, d2 = torques_one(*args, self.params, extra_Q=extra)
        elif ok:
            d1, d2 = (float(v) for v in torques(*args, self.params, extra_Q=extra))
        e1 = e2 = np.nan
        if ok:
            e1, e2 = (float(v) for v in torques_2dof(args[1], args[3], args[4], args[6], self.params))
        if not (ok and all(np.isfinite((d1, d2, e1, e2)))):
            self.counts["invalid"] += 1
            self._rmse.push(np.nan)
            if self._base is not None:
                self._base[1].push(np.nan)
            self._h.update(*([np.nan] * 7))
            return None
        rmse = self._rmse.push(d1 - d2)
        base = {}
        if self._base is not None:
            b1, b2 = torques_one(*args, self._base[0]) if self._scalar_params else \
                (float(v) for v in torques(*args, self._base[0]))
            base["rmse_base_nm"] = self._base[1].push(b1 - b2)
        est = self._h.update(*args)
        self.counts["outputs"] += 1
        return TorqueSample(frame=int(getattr(state, "frame", -1)), t=t,
                            M_d1=d1, M_d2=d2, M_d1_2dof=e1, M_d2_2dof=e2, h_m=float(self.params.h),
                            residual_nm=d1 - d2, rmse_window_nm=rmse, window_s=self.window_s,
                            h_online_m=est.h_m, h_online_std_m=est.h_std_m, model=self.model_name,
                            extra=base, h_online_status=self._h.status(self.dt, est))


def series_torques(series, states: RiderStateEstimator,
                   torque: TorqueEstimator) -> Iterator[tuple[int, RiderStateSample, TorqueSample]]:
    """Feed a recording frame by frame through a state and a torque estimator, as the nodes chain them.

    Parameters
    ----------
    series : MocapSeries
        The recording (Z-up world).
    states : RiderStateEstimator
    torque : TorqueEstimator

    Yields
    ------
    k : int
        Index of the newest frame fed.
    state : RiderStateSample
    out : TorqueSample
        The torque of ``state`` (states without one, ``None``, are passed over).
    """
    for k, state in states.update_series(series):
        out = torque.update(state)
        if out is not None:
            yield k, state, out


def extended_model_from_config(params: EucParams, effects: Sequence[str], assignments: Sequence[str],
                               *, key: str = "effects") -> Model | None:
    """The online extended model of the ``effects`` / ``effect_parameters`` settings, or None for none.

    Parameters
    ----------
    params : EucParams
        Nominal parameters with the CoG height to use [m].
    effects : sequence of str
        Effect names of the residual analysis (empty strings ignored), e.g. ``["ground_slope"]``.
    assignments : sequence of str
        ``"<effect>.<parameter>=<value>"`` in the residual report's units, e.g.
        ``["ground_slope.alpha_deg=2.9"]``.
    key : str
        Prefix of the configuration keys named in errors.

    Returns
    -------
    Model or None
        The model with its effect values fixed, or None when no effect is listed.

    Raises
    ------
    ConfigError
        Unknown effect, an effect that needs future samples (``mocap_time_offset``), a malformed
        assignment, one for an effect not listed, or a missing parameter.
    """
    names = [e.strip() for e in effects if e and e.strip()]
    items = [a for a in assignments if a and a.strip()]
    for item in items:
        lhs = item.split("=", 1)[0]
        effect = lhs.split(".", 1)[0].strip()
        if "=" not in item or "." not in lhs:
            raise ConfigError("expected '<effect>.<parameter>=<number>'", key=f"{key}: {item}")
        if effect not in names:
            raise ConfigError(f"effect {effect!r} is not in the list of effects {names}", key=f"{key}: {item}")
    if not names:
        return None
    return Model.from_report(params, parse_effect_assignments(names, items), online=True)
