"""Controllers of a ride: the EUC's balance loop on the motor, the rider's ankle-torque loop.

* The EUC holds its body level: a PD law on pitch and pitch rate, with a tilt-back of the pitch
  reference above a speed limit (the firmware's way of slowing a rider), behind a first-order motor
  torque lag. Its gains are set from a chosen natural frequency and damping of the pitch mode, so the
  balance loop's bandwidth is a per-ride draw.
* The rider balances on the pedals and follows a speed reference with the ankle torque ``M_h``:
  full-state feedback from a linear-quadratic design (weights per ride) plus the steady lean for the
  reference acceleration, behind a first-order muscle lag.

Both laws are vectorized: the same functions serve the integrator (one state) and the recording of
the truth (every frame).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_continuous_are

from euc_ros.core.worldsim.dynamics import PlantParams, solve

#: Closed-loop state of the linear design: pitch angles, speed, pitch rates, the two torques.
LOOP_STATES = ("gamma", "phi", "x_dot", "gamma_dot", "phi_dot", "M_d", "M_h")


def plant_jacobians(p: PlantParams, step: float = 1e-6) -> dict[str, np.ndarray]:
    """Linearization of the accelerations about upright rest (all states and torques zero).

    Parameters
    ----------
    p : PlantParams
    step : float
        Central-difference step [rad, N m].

    Returns
    -------
    dict
        ``"angles"`` (3, 2): d(x_ddot, gamma_ddot, phi_ddot) / d(gamma, phi); ``"torques"`` (3, 2):
        d(...) / d(M_d, M_h). The rates enter only quadratically, so they have no linear term, and x
        is cyclic.

    Notes
    -----
    Central differences of :func:`~euc_ros.core.worldsim.dynamics.solve`: the truncation error is
    ``O(step^2)`` of the third derivatives (order one here), far below the design's needs.
    """
    z = np.zeros(3)
    cols = []
    for k in (1, 2):
        dq = np.zeros(3)
        dq[k] = step
        plus = solve(z + dq, z, 0.0, 0.0, p)[:3]
        minus = solve(z - dq, z, 0.0, 0.0, p)[:3]
        cols.append((plus - minus) / (2 * step))
    angles = np.stack(cols, axis=1)
    cols = []
    for md, mh in ((1.0, 0.0), (0.0, 1.0)):
        plus = solve(z, z, md * step, mh * step, p)[:3]
        minus = solve(z, z, -md * step, -mh * step, p)[:3]
        cols.append((plus - minus) / (2 * step))
    return {"angles": angles, "torques": np.stack(cols, axis=1)}


@dataclass(frozen=True)
class EucLoop:
    """The EUC's balance loop: ``M_d_cmd = k_p (gamma - gamma_ref(v)) + k_d gamma_dot``.

    Parameters
    ----------
    k_p : float
        Pitch stiffness [N m / rad].
    k_d : float
        Pitch damping [N m s / rad].
    tau : float
        Motor torque lag [s]: ``tau dM_d/dt = M_d_cmd - M_d``.
    v_limit : float
        Speed above which the pitch reference tilts back [m/s].
    tilt_back : float
        Tilt-back slope [rad per m/s].
    natural_hz, damping : float
        The pitch mode the gains were set for (informative): frequency [Hz] and damping ratio.
    """

    k_p: float
    k_d: float
    tau: float
    v_limit: float = np.inf
    tilt_back: float = 0.0
    natural_hz: float = np.nan
    damping: float = np.nan

    def pitch_reference(self, v):
        """Pitch reference [rad]: ``-tilt_back * s softplus((v - v_limit) / s)``, ``s = 0.1 m/s``.

        Zero well below the limit, a slope of ``-tilt_back`` well above; smooth in between.

        Parameters
        ----------
        v : array_like
            Wheel speed [m/s] (any shape).

        Returns
        -------
        numpy.ndarray
            The shape of ``v`` [rad] (zeros without a finite limit or with no tilt-back).
        """
        if not np.isfinite(self.v_limit) or self.tilt_back == 0.0:
            return np.zeros_like(np.asarray(v, dtype=float))
        s = 0.1
        return -self.tilt_back * s * np.logaddexp(0.0, (np.asarray(v, dtype=float) - self.v_limit) / s)

    def pitch_reference_one(self, v: float) -> float:
        """:meth:`pitch_reference` of one speed, in scalar arithmetic.

        Parameters
        ----------
        v : float
            Wheel speed [m/s].

        Returns
        -------
        float
            Pitch reference [rad].
        """
        if not math.isfinite(self.v_limit) or self.tilt_back == 0.0:
            return 0.0
        u = (v - self.v_limit) / 0.1
        return -self.tilt_back * 0.1 * (max(u, 0.0) + math.log1p(math.exp(-abs(u))))

    def command(self, gamma, gamma_dot, v):
        """Commanded motor torque [N m] (any shape).

        Parameters
        ----------
        gamma : array_like
            EUC body pitch [rad].
        gamma_dot : array_like
            Its rate [rad/s].
        v : array_like
            Wheel speed [m/s] (the tilt-back's input); the three broadcast.

        Returns
        -------
        numpy.ndarray or float
            ``M_d_cmd`` [N m].
        """
        return self.k_p * (gamma - self.pitch_reference(v)) + self.k_d * gamma_dot


def design_euc_loop(p: PlantParams, natural_hz: float, damping: float, tau: float, *, v_limit: float = np.inf,
                    tilt_back: float = 0.0) -> EucLoop:
    """Set the balance loop's PD gains for a pitch mode of given frequency and damping.

    Parameters
    ----------
    p : PlantParams
        The plant.
    natural_hz : float
        Natural frequency of the design's pitch mode [Hz].
    damping : float
        Its damping ratio.
    tau : float
        Motor torque lag [s] (not part of the design, see Notes).
    v_limit : float
        Speed above which the pitch reference tilts back [m/s] (inf: never).
    tilt_back : float
        Tilt-back slope [rad per m/s].

    Returns
    -------
    EucLoop
        The gains and the design values.

    Notes
    -----
    With the rider held (``M_h`` and ``phi`` frozen), the linearized pitch obeys
    ``gamma_ddot = a gamma + b M_d`` (``a``, ``b`` from :func:`plant_jacobians`, ``b < 0``: the
    motor's reaction tips the body back). ``M_d = k_p gamma + k_d gamma_dot`` gives
    ``gamma_ddot = (a + b k_p) gamma + b k_d gamma_dot``; matching ``-w^2 gamma - 2 zeta w gamma_dot``
    gives ``k_p = -(w^2 + a) / b`` and ``k_d = -2 zeta w / b``. The motor lag and the rider's
    coupling move the mode of the complete loop; :func:`closed_loop_matrix` gives it exactly.
    """
    jac = plant_jacobians(p)
    a = jac["angles"][1, 0]
    b = jac["torques"][1, 0]
    w = 2 * np.pi * natural_hz
    return EucLoop(k_p=float(-(w**2 + a) / b), k_d=float(-2 * damping * w / b), tau=tau, v_limit=v_limit,
                   tilt_back=tilt_back, natural_hz=natural_hz, damping=damping)


def open_loop_matrices(p: PlantParams, euc: EucLoop, tau_h: float) -> tuple[np.ndarray, np.ndarray]:
    """Linear model of :data:`LOOP_STATES` with the EUC loop closed; input: the rider's commanded torque.

    Parameters
    ----------
    p : PlantParams
        The plant, linearized about upright rest (:func:`plant_jacobians`).
    euc : EucLoop
        The balance loop (its gains and motor lag).
    tau_h : float
        The rider's muscle lag [s].

    Returns
    -------
    A : ndarray (7, 7)
        State matrix on :data:`LOOP_STATES`.
    B : ndarray (7, 1)
        Input matrix of the commanded ankle torque [N m].

    Notes
    -----
    ``d(gamma, phi)/dt = (gamma_dot, phi_dot)``; ``d(x_dot, gamma_dot, phi_dot)/dt = J_a (gamma, phi)
    + J_t (M_d, M_h)`` (:func:`plant_jacobians`); ``tau_d dM_d/dt = k_p gamma + k_d gamma_dot - M_d``
    (the tilt-back is off at the design point); ``tau_h dM_h/dt = u - M_h``.
    """
    jac = plant_jacobians(p)
    A = np.zeros((7, 7))
    A[0, 3] = 1.0
    A[1, 4] = 1.0
    A[2:5, 0:2] = jac["angles"]
    A[2:5, 5:7] = jac["torques"]
    A[5, 0] = euc.k_p / euc.tau
    A[5, 3] = euc.k_d / euc.tau
    A[5, 5] = -1.0 / euc.tau
    A[6, 6] = -1.0 / tau_h
    B = np.zeros((7, 1))
    B[6, 0] = 1.0 / tau_h
    return A, B


@dataclass(frozen=True)
class RiderLoop:
    """The rider's ankle-torque law ``M_h_cmd = M_h_ff(a_ref) - K (z - z_ref(v_ref, a_ref))``.

    Parameters
    ----------
    K : ndarray (7,)
        State-feedback gains on :data:`LOOP_STATES` [N m per unit].
    tau : float
        Muscle lag [s]: ``tau dM_h/dt = M_h_cmd - M_h``.
    steady : ndarray (7,)
        Steady state per unit reference acceleration (``z_ref = steady * a_ref``, speed entry 0).
    weights : dict
        The design's maximum deviations (informative).
    """

    K: np.ndarray
    tau: float
    steady: np.ndarray
    weights: dict

    def command(self, z, v_ref, a_ref):
        """Commanded ankle torque [N m]; ``z`` (..., 7) in :data:`LOOP_STATES` order.

        Parameters
        ----------
        z : array_like (..., 7)
            Loop states [rad, m/s, rad/s, N m].
        v_ref : array_like (...)
            Speed reference [m/s].
        a_ref : array_like (...)
            Reference acceleration [m/s^2]: ``z_ref = steady a_ref`` with speed entry ``v_ref``, and the
            feed-forward ``M_h_ff = steady[6] a_ref``.

        Returns
        -------
        numpy.ndarray (...)
            ``M_h_cmd`` [N m].
        """
        z = np.asarray(z, dtype=float)
        zr = np.asarray(a_ref, dtype=float)[..., None] * self.steady
        zr = zr + np.asarray(v_ref, dtype=float)[..., None] * np.eye(7)[2]
        return np.asarray(a_ref, dtype=float) * self.steady[6] - (z - zr) @ self.K


def steady_acceleration(p: PlantParams, euc: EucLoop) -> np.ndarray:
    """Linear steady state of :data:`LOOP_STATES` per unit acceleration (speed entry 0).

    Parameters
    ----------
    p : PlantParams
        The plant (linearized, :func:`plant_jacobians`).
    euc : EucLoop
        The balance loop (its ``k_p``).

    Returns
    -------
    numpy.ndarray (7,)
        States per m/s^2 of acceleration [rad, m/s, rad/s, N m per m/s^2]; rates and speed entries 0.

    Notes
    -----
    Constant acceleration ``a`` with constant pitch angles: ``J_a (gamma, phi) + J_t (M_d, M_h) =
    (a, 0, 0)`` and ``M_d = k_p gamma`` (steady motor lag). Three equations in ``gamma, phi, M_h``.
    """
    jac = plant_jacobians(p)
    Ja, Jt = jac["angles"], jac["torques"]
    M = np.column_stack([Ja[:, 0] + Jt[:, 0] * euc.k_p, Ja[:, 1], Jt[:, 1]])
    gam, phi, mh = np.linalg.solve(M, np.array([1.0, 0.0, 0.0]))
    return np.array([gam, phi, 0.0, 0.0, 0.0, euc.k_p * gam, mh])


def design_rider_loop(p: PlantParams, euc: EucLoop, tau: float, *, max_gamma: float, max_phi: float,
                      max_speed_error: float, max_rate: float, max_torque: float) -> RiderLoop:
    """Linear-quadratic design of the rider's ankle-torque loop (Bryson weights).

    Parameters
    ----------
    p : PlantParams
    euc : EucLoop
    tau : float
        Muscle lag [s].
    max_gamma, max_phi : float
        Acceptable pitch deviations [rad].
    max_speed_error : float
        Acceptable speed error [m/s].
    max_rate : float
        Acceptable pitch rates [rad/s].
    max_torque : float
        Acceptable ankle torque [N m].

    Returns
    -------
    RiderLoop

    Notes
    -----
    Minimizes ``int z^T Q z + R u^2 dt`` with ``Q = diag(1/max^2)`` on pitch, lean, speed error and
    rates (none on the torques) and ``R = 1/max_torque^2``: ``K = R^-1 B^T P`` with ``P`` from the
    continuous algebraic Riccati equation of :func:`open_loop_matrices`.
    """
    A, B = open_loop_matrices(p, euc, tau)
    Q = np.diag([max_gamma**-2, max_phi**-2, max_speed_error**-2, max_rate**-2, max_rate**-2, 0.0, 0.0])
    Q[5, 5] = Q[6, 6] = 1e-9 * max_torque**-2   # keeps Q > 0 on the torques (numerical regularity only)
    R = np.array([[max_torque**-2]])
    P = solve_continuous_are(A, B, Q, R)
    K = (np.linalg.solve(R, B.T @ P))[0]
    return RiderLoop(K=K, tau=tau, steady=steady_acceleration(p, euc),
                     weights={"max_gamma": max_gamma, "max_phi": max_phi, "max_speed_error": max_speed_error,
                              "max_rate": max_rate, "max_torque": max_torque})


def closed_loop_matrix(p: PlantParams, euc: EucLoop, rider: RiderLoop) -> np.ndarray:
    """``A - B K``: the linearized ride with both loops closed (:data:`LOOP_STATES`).

    Parameters
    ----------
    p : PlantParams
        The plant.
    euc : EucLoop
        The balance loop.
    rider : RiderLoop
        The rider's loop (its gains ``K`` and muscle lag).

    Returns
    -------
    numpy.ndarray (7, 7)
        State matrix of :func:`open_loop_matrices` with ``u = -K z``.
    """
    A, B = open_loop_matrices(p, euc, rider.tau)
    return A - B @ rider.K[None, :]


def pitch_mode_hz(p: PlantParams, euc: EucLoop, rider: RiderLoop) -> float:
    """Frequency [Hz] of the closed-loop mode with the largest EUC-pitch share (its natural frequency |lambda|/2 pi).

    Parameters
    ----------
    p : PlantParams
        The plant.
    euc : EucLoop
        The balance loop.
    rider : RiderLoop
        The rider's loop.

    Returns
    -------
    float
        ``|lambda| / (2 pi)`` [Hz] of the eigenvalue of :func:`closed_loop_matrix` whose eigenvector has the
        largest share of EUC pitch rate.
    """
    lam, vec = np.linalg.eig(closed_loop_matrix(p, euc, rider))
    share = np.abs(vec[3]) / np.linalg.norm(vec, axis=0)   # pitch-rate component of each mode
    return float(np.abs(lam[int(np.argmax(share))]) / (2 * np.pi))
