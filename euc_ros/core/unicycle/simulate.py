"""Deterministic fixed-step simulation of the unicycle (eq (36)) in closed loop.

The integrator is what a node loop does: at ``t_k = k dt`` the controller sees ``x_k`` and
returns ``u_k``, held constant (zero-order hold) over ``[t_k, t_k + dt)`` while the model is
advanced by ``substeps`` classical Runge-Kutta (RK4) steps of ``dt / substeps``. With the same
``dt``, ``substeps`` and controller, :class:`UnicycleSimulator` stepped by hand (e.g. by a ROS node
exchanging topics in lockstep) and :func:`simulate` give bit-identical trajectories.

Domain. The model is singular at ``|theta| = 90 deg`` (eq (78)) and unphysical when the point
mass is below the ground (eq (47)). A step that ends outside the domain stops the simulator with
a status string instead of producing NaN:

* ``'tilt_limit'``: ``|theta| >= max_tilt`` (default 80 deg);
* ``'mass_below_ground'``: ``z_A = R cos(theta) + r sin(theta) <= 0``;
* ``'non_finite'``: a state or the input is not finite (the last finite state is kept).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from euc_ros.core.errors import ConfigError
from euc_ros.core.rotations import quat_from_yaw_tilt_pitch
from euc_ros.core.unicycle.dynamics import STATE_NAMES, UnicycleParams, scalar_rhs

__all__ = [
    "STATUS_OK", "STATUS_TILT", "STATUS_GROUND", "STATUS_NON_FINITE", "DEFAULT_DT", "DEFAULT_SUBSTEPS",
    "DEFAULT_MAX_TILT", "domain_status", "rk4_step", "UnicycleSimulator", "SimulationResult", "simulate",
    "ManeuverMetrics", "maneuver_metrics", "reference_path", "wheel_pose",
]

STATUS_OK = "ok"
STATUS_TILT = "tilt_limit"
STATUS_GROUND = "mass_below_ground"
STATUS_NON_FINITE = "non_finite"
#: Control period [s] (100 Hz).
DEFAULT_DT = 0.01
#: RK4 steps per control period (2 ms): final positions agree with a 10x finer step to < 0.1 mm.
DEFAULT_SUBSTEPS = 5
#: Largest admissible |tilt| [rad].
DEFAULT_MAX_TILT = math.radians(80.0)

_N = len(STATE_NAMES)


def domain_status(x, params: UnicycleParams, max_tilt: float = DEFAULT_MAX_TILT) -> str:
    """Status of a state: :data:`STATUS_OK` or why it is outside the model's domain (module docstring).

    Parameters
    ----------
    x : array_like
        State (10,).
    params : UnicycleParams
        Physical parameters.
    max_tilt : float
        Largest tilt |theta| in the domain [rad].

    Returns
    -------
    str
        A ``STATUS_*`` constant.
    """
    x = [float(v) for v in np.asarray(x, dtype=float).reshape(-1)]
    if not all(math.isfinite(v) for v in x):
        return STATUS_NON_FINITE
    th, r = x[3], x[5]
    if abs(th) >= max_tilt:
        return STATUS_TILT
    if params.R * math.cos(th) + r * math.sin(th) <= 0:
        return STATUS_GROUND
    return STATUS_OK


def wheel_pose(x, params: UnicycleParams) -> tuple[np.ndarray, np.ndarray]:
    """Position of the wheel centre ``(x_G, y_G, R cos(theta))`` [m] and body quaternion (x, y, z, w).

    The body frame is F2 (eq (73)) turned by the rolling angle ``phi`` about the axle:
    ``Rz(psi) Rx(theta) Ry(phi)`` (yaw, tilt about the forward axis, rolling angle about the axle;
    :func:`euc_ros.core.rotations.quat_from_yaw_tilt_pitch`), REP-103 world frame.

    Parameters
    ----------
    x : array_like
        State (10,).
    params : UnicycleParams
        Physical parameters.

    Returns
    -------
    position : numpy.ndarray
        Wheel centre (3,) [m].
    quat : numpy.ndarray
        Body quaternion (4,), (x, y, z, w).
    """
    x = np.asarray(x, dtype=float)
    pos = np.array([x[8], x[9], params.R * math.cos(x[3])])
    return pos, quat_from_yaw_tilt_pitch(x[6], x[3], x[7])


def rk4_step(params: UnicycleParams, x: list[float], u: float, h: float) -> list[float]:
    """One classical Runge-Kutta step of eq (36) with constant input ``u`` [N] over ``h`` [s].

    Parameters
    ----------
    params : UnicycleParams
        Physical parameters.
    x : list of float
        State (10).
    u : float
        Control force [N].
    h : float
        Step [s].

    Returns
    -------
    list of float
        The state after the step (10).
    """
    k1 = scalar_rhs(x, u, params)
    k2 = scalar_rhs([a + 0.5 * h * b for a, b in zip(x, k1)], u, params)
    k3 = scalar_rhs([a + 0.5 * h * b for a, b in zip(x, k2)], u, params)
    k4 = scalar_rhs([a + h * b for a, b in zip(x, k3)], u, params)
    return [a + h / 6 * (b1 + 2 * b2 + 2 * b3 + b4) for a, b1, b2, b3, b4 in zip(x, k1, k2, k3, k4)]


class UnicycleSimulator:
    """Fixed-step simulator of the unicycle with zero-order-hold input; one ``step`` per control period.

    Parameters
    ----------
    params : UnicycleParams
        Physical parameters (``m0 > 0``).
    x0 : array_like, shape (10,)
        Initial state (:data:`~euc_ros.core.unicycle.dynamics.STATE_NAMES`).
    dt : float
        Control period [s].
    max_tilt : float
        Tilt magnitude [rad] at which the simulation stops (``0 < max_tilt < pi/2``).
    substeps : int
        RK4 steps per period.
    t0 : float
        Initial time [s].

    Raises
    ------
    ConfigError
        When the initial state has not 10 entries, or ``dt``, ``max_tilt`` or ``substeps`` is out of range.

    Examples
    --------
    >>> from euc_ros.core.unicycle.linearize import straight_rolling_state
    >>> p = UnicycleParams()
    >>> sim = UnicycleSimulator(p, straight_rolling_state(p, 5.0), dt=0.01)
    >>> x, status = sim.step(0.0)
    >>> status, round(sim.t, 2), round(float(x[8]), 4)
    ('ok', 0.01, 0.05)
    """

    def __init__(self, params: UnicycleParams, x0, dt: float = DEFAULT_DT, *, max_tilt: float = DEFAULT_MAX_TILT,
                 substeps: int = DEFAULT_SUBSTEPS, t0: float = 0.0) -> None:
        params.require_point_mass()
        x0 = np.asarray(x0, dtype=float)
        if x0.shape != (_N,):
            raise ConfigError(f"the initial state needs {_N} entries ({', '.join(STATE_NAMES)}), got shape {x0.shape}",
                              key="x0")
        if not (math.isfinite(dt) and dt > 0):
            raise ConfigError(f"must be a positive finite period in s, got {dt!r}", key="dt")
        if not (0 < max_tilt < math.pi / 2):
            raise ConfigError(f"must lie in (0, pi/2) rad, got {max_tilt!r}", key="max_tilt")
        if int(substeps) != substeps or substeps < 1:
            raise ConfigError(f"must be a positive integer, got {substeps!r}", key="substeps")
        self.params = params
        self.dt = float(dt)
        self.max_tilt = float(max_tilt)
        self.substeps = int(substeps)
        self._t0 = float(t0)
        self._k = 0
        self._x = [float(v) for v in x0]
        self._status = domain_status(self._x, params, self.max_tilt)

    @property
    def t(self) -> float:
        """Current time [s] (``t0 + k dt``, no accumulated rounding)."""
        return self._t0 + self._k * self.dt

    @property
    def x(self) -> np.ndarray:
        """Copy of the current state (10,)."""
        return np.array(self._x)

    @property
    def status(self) -> str:
        """:data:`STATUS_OK` while running, else why the simulation stopped."""
        return self._status

    @property
    def steps(self) -> int:
        """Number of periods simulated."""
        return self._k

    def step(self, u: float) -> tuple[np.ndarray, str]:
        """Advance one period with input ``u`` [N] held constant; return ``(x, status)``.

        Once the status is not :data:`STATUS_OK` the simulator stays stopped: further calls return
        the same state and status without integrating.

        Parameters
        ----------
        u : float
            Control force [N].

        Returns
        -------
        x : numpy.ndarray
            The state (10,).
        status : str
            A ``STATUS_*`` constant.
        """
        if self._status != STATUS_OK:
            return self.x, self._status
        u = float(u)
        if not math.isfinite(u):
            self._status = STATUS_NON_FINITE
            return self.x, self._status
        h = self.dt / self.substeps
        x = self._x
        for _ in range(self.substeps):
            try:
                x = rk4_step(self.params, x, u, h)
            except (OverflowError, ZeroDivisionError):
                x = [math.nan] * _N
            if not all(math.isfinite(v) for v in x):
                self._status = STATUS_NON_FINITE
                return self.x, self._status
        self._x = x
        self._k += 1
        self._status = domain_status(x, self.params, self.max_tilt)
        return self.x, self._status


@dataclass(frozen=True)
class SimulationResult:
    """A closed-loop run.

    Parameters
    ----------
    t : numpy.ndarray, shape (n + 1,)
        Times [s] of the states.
    x : numpy.ndarray, shape (n + 1, 10)
        States.
    u : numpy.ndarray, shape (n,)
        Input applied over ``[t_k, t_{k+1})`` [N].
    y_des : numpy.ndarray, shape (n, k)
        Desired outputs at ``t_k``.
    status : str
        :data:`STATUS_OK` if ``t_end`` was reached, else why the run stopped.
    dt : float
        Control period [s].
    meta : dict
        Free-form annotations (empty unless a caller adds some).
    """

    t: np.ndarray
    x: np.ndarray
    u: np.ndarray
    y_des: np.ndarray
    status: str
    dt: float
    meta: dict = field(default_factory=dict)


def simulate(params: UnicycleParams, controller, x0, t_end: float, dt: float = DEFAULT_DT, *,
             max_tilt: float = DEFAULT_MAX_TILT, substeps: int = DEFAULT_SUBSTEPS) -> SimulationResult:
    """Run ``controller`` on the nonlinear model from ``x0`` for ``t_end`` seconds.

    Parameters
    ----------
    params : UnicycleParams
        Plant parameters.
    controller : object
        Anything with ``command(t, x) -> (u, y_des)``, e.g.
        :class:`~euc_ros.core.unicycle.steering.SteeringController`.
    x0 : array_like, shape (10,)
        Initial state.
    t_end : float
        Duration [s]; ``round(t_end / dt)`` periods are simulated.
    dt, max_tilt, substeps
        See :class:`UnicycleSimulator`.

    Returns
    -------
    SimulationResult
        Stops early (with the status) if the state leaves the model's domain.

    Raises
    ------
    ConfigError
        When ``t_end`` is not a positive finite duration.
    """
    if not (math.isfinite(t_end) and t_end > 0):
        raise ConfigError(f"must be a positive finite duration in s, got {t_end!r}", key="t_end")
    sim = UnicycleSimulator(params, x0, dt, max_tilt=max_tilt, substeps=substeps)
    n = int(round(t_end / sim.dt))
    ts, xs, us, ys = [sim.t], [sim.x], [], []
    status = sim.status
    for _ in range(n):
        if status != STATUS_OK:
            break
        u, y_des = controller.command(sim.t, sim.x)
        x, status = sim.step(u)
        if sim.steps == len(us):          # stopped without advancing (non-finite u or state)
            break
        ts.append(sim.t)
        xs.append(x)
        us.append(u)
        ys.append(np.asarray(y_des, dtype=float))
    y_des = np.array(ys).reshape(len(ys), -1) if ys else np.zeros((0, 0))
    return SimulationResult(np.array(ts), np.array(xs), np.array(us, dtype=float), y_des, status, sim.dt)


@dataclass(frozen=True)
class ManeuverMetrics:
    """Summary of a maneuver run (what ``euc-ros steer`` reports).

    Parameters
    ----------
    final_lateral_error : float
        Signed distance [m] of the wheel centre from the final reference line at the end (left of
        the line positive): the line ``y = target`` for the lane change; for the turn the line
        through the end of the ideal path (heading ``psi_des(t)`` at the design speed from the
        origin) with the final heading.
    final_yaw_error : float
        ``psi - psi_des`` at the end [rad].
    max_abs_u : float
        Largest ``|u|`` [N].
    max_abs_tilt : float
        Largest ``|theta|`` [rad].
    status : str
        Simulation status.
    t_end : float
        Time reached [s].
    """

    final_lateral_error: float
    final_yaw_error: float
    max_abs_u: float
    max_abs_tilt: float
    status: str
    t_end: float

    def as_dict(self) -> dict:
        """JSON-serializable dict (angles also in degrees, with ``_deg`` keys, for reports).

        Returns
        -------
        dict
            The fields, plus ``final_yaw_error_deg`` and ``max_abs_tilt_deg``.
        """
        return {"final_lateral_error": self.final_lateral_error, "final_yaw_error": self.final_yaw_error,
                "final_yaw_error_deg": math.degrees(self.final_yaw_error), "max_abs_u": self.max_abs_u,
                "max_abs_tilt": self.max_abs_tilt, "max_abs_tilt_deg": math.degrees(self.max_abs_tilt),
                "status": self.status, "t_end": self.t_end}


def reference_path(controller, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ideal path ``(x_ref, y_ref, psi_ref)`` of the maneuver at times ``t`` (starting at 0 s).

    Lane change: ``(v t, y_des(t), 0)``. Turn: heading ``psi_des(t)`` integrated at the design
    speed from the origin (trapezoidal rule on a 1 ms grid).

    Parameters
    ----------
    controller : SteeringController
        The maneuver's controller.
    t : array_like
        Times (n,) [s].

    Returns
    -------
    x_ref, y_ref : numpy.ndarray
        Position (n,) [m].
    psi_ref : numpy.ndarray
        Heading (n,) [rad].
    """
    t = np.asarray(t, dtype=float)
    v = controller.speed
    if controller.maneuver == "lane_change":
        return v * t, controller.reference(t)[-1], np.zeros_like(t)
    grid = np.arange(0.0, float(np.max(t)) + 1e-3, 1e-3)
    psi = controller.reference(grid)[-1]
    dx, dy = v * np.cos(psi), v * np.sin(psi)
    h = np.diff(grid)
    xg = np.concatenate([[0.0], np.cumsum(h * (dx[1:] + dx[:-1]) / 2)])
    yg = np.concatenate([[0.0], np.cumsum(h * (dy[1:] + dy[:-1]) / 2)])
    return np.interp(t, grid, xg), np.interp(t, grid, yg), controller.reference(t)[-1]


def maneuver_metrics(result: SimulationResult, controller) -> ManeuverMetrics:
    """Final lateral and yaw errors, max |u| and max |tilt| of a run (:class:`ManeuverMetrics`).

    Parameters
    ----------
    result : SimulationResult
        The run.
    controller : SteeringController
        Its controller (the maneuver and reference).

    Returns
    -------
    ManeuverMetrics
        The summary.
    """
    t_end = float(result.t[-1])
    x_end = result.x[-1]
    xr, yr, pr = (float(np.asarray(a)) for a in reference_path(controller, t_end))
    lateral = -(x_end[8] - xr) * math.sin(pr) + (x_end[9] - yr) * math.cos(pr)
    yaw = x_end[6] - pr
    max_u = float(np.max(np.abs(result.u))) if result.u.size else 0.0
    return ManeuverMetrics(float(lateral), float(yaw), max_u, float(np.max(np.abs(result.x[:, 3]))),
                           result.status, t_end)
