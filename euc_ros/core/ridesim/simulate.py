"""Ride simulation: integrate the truth, sample it at the mocap rate and synthesize the mocap.

:func:`simulate_ride` is the core API (no files): it plans each run (:mod:`.maneuvers`), integrates
the planar truth model (:mod:`.truth_model`) driven by the EUC balance controller and the leaning
rider (:mod:`.controllers`) with the active effects (:mod:`.effects`), samples the dense solution at
the capture rate, computes the true inputs and accelerations exactly at the samples, places the
EUC body and the rider skeleton in 3-D (:mod:`.skeleton`) and adds OptiTrack-like noise, occlusion
gaps and dropped frames (:mod:`.mocap_synth`).

3-D placement (conventions fixed project-wide)::

    moving frame  R_M = Rz(psi) Rx(theta)             (EUC paper, eqs 1-2)
    EUC body      R_E = R_M Ry(gamma),  E = C - R_E p  (p = session pivot_to_wheel_center)
    hinge         A   = C - l0 R_E e_z
    rider lean    R_L = R_M Ry(phi),    G = A + h R_L e_z
    wheel centre  C   = (X, Y, R cos(theta))           (the tilted wheel touches the floor)

with ``psi = psi(x)`` the path heading at arc length x and (X, Y) integrated from
``d(X, Y)/dt = x_dot (cos psi, sin psi)``, so the longitudinal component of the velocity of C in the
moving frame is exactly ``x_dot`` and its acceleration ``x_ddot``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import fsolve

from euc_ros.core.errors import ConfigError, EucError
from euc_ros.core.mocap.series import MocapSeries
from euc_ros.core.ridesim.controllers import EucBalanceController, RiderLeanController
from euc_ros.core.ridesim.effects import AIR_DENSITY, ROLLING_SIGN_SPEED, EffectSet
from euc_ros.core.ridesim.floors import FloorProfile
from euc_ros.core.ridesim.maneuvers import MANEUVERS, RunPlan, plan_run
from euc_ros.core.ridesim.mocap_synth import MocapNoise, corrupt, rotations_to_quats
from euc_ros.core.ridesim.rider_motion import ArmKinematics, ArmSwing, PedalFlex
from euc_ros.core.ridesim.skeleton import Skeleton
from euc_ros.core.ridesim.truth_model import FloorModel, PedalModel, PlanarModel, PlanarParams
from euc_ros.core.session import Session, default_session

#: State vector of the ODE (with pedals that flex, ``u`` and ``u_dot`` follow).
STATE_NAMES = ("x", "gamma", "phi", "x_dot", "gamma_dot", "phi_dot", "X", "Y", "z", "Z")
#: Default true rider CoG height (EUC paper, Fig. 6: h = 0.61 m).
DEFAULT_H_M = 0.61
#: Integration methods: the compiled right-hand side and DOP853 (:mod:`.compiled`), or the Python right-hand
#: side with ``scipy.integrate.solve_ivp`` (DOP853) and the equations lambdified from sympy in this process.
METHODS = ("compiled", "reference")
#: Residual accelerations [m/s^2, rad/s^2] below which the initial state counts as balanced.
BALANCE_TOL = 1e-10


@dataclass(frozen=True)
class RideConfig:
    """What to simulate.

    Parameters
    ----------
    maneuver : str
        ``constant_speed``, ``acceleration``, ``deceleration`` or ``figure_eight``.
    runs : int
        Number of runs (recordings).
    seed : int
        Seed of every random choice (plans, noise, gaps); equal seeds give identical results.
    h : float
        True rider CoG height above the ankle hinge [m] (hidden from the session file).
    effects : EffectSet
        Active effects (see :mod:`.effects`).
    session : Session, optional
        Nominal session (default :func:`~euc_ros.core.session.default_session` with Y-up).
    duration_s : float, optional
        Recording duration of each run [s] (default per maneuver).
    speed_scale : float
        Multiplies every planned speed (1 = the paper-like defaults).
    path_scale : float
        Multiplies the figure-eight's length (1 = 16 m).
    settle_s : float
        Simulated time before the recording starts [s].
    noise : MocapNoise
        Noise, occlusion gaps and dropped frames of the synthesized mocap.
    euc_controller : EucBalanceController
        The EUC's balance loop.
    rider_gains : tuple of float
        ``(k_p [N m/rad], k_d [N m s/rad], k_speed [rad s/m], k_int [rad/m])`` of the rider.
    rtol, atol : float
        Integration tolerances of DOP853: each step's local error estimate stays below ``atol + rtol |y|``.
    method : str
        ``compiled`` (default) or ``reference`` (:data:`METHODS`): the same DOP853 steps on the same equations,
        compiled or in Python; their states agree within the tolerances.
    floor : FloorProfile, optional
        A floor that is not level in a level lab (:mod:`.floors`): the dynamics follow it
        (:class:`~euc_ros.core.ridesim.truth_model.FloorModel`, x is then the arc length of the wheel
        centre's path) and the recorded positions are lab positions (not re-centred).
    external : tuple of ExternalForce
        Forces outside the residual analysis' library (:mod:`.external`: a rope held in the hand, a
        headwind, motor torque ripple).
    pedals : PedalFlex, optional
        Pedals that flex under the rider's load (:mod:`.rider_motion`): a fourth coordinate u of the truth.
    arms : ArmSwing, optional
        Arms swinging about the shoulders (:mod:`.rider_motion`): the rider's CoG and pitch angular momentum
        move with them.
    """

    maneuver: str = "deceleration"
    runs: int = 3
    seed: int = 0
    h: float = DEFAULT_H_M
    effects: EffectSet = field(default_factory=EffectSet)
    session: Session | None = None
    duration_s: float | None = None
    speed_scale: float = 1.0
    path_scale: float = 1.0
    settle_s: float = 2.0
    noise: MocapNoise = field(default_factory=MocapNoise)
    euc_controller: EucBalanceController = field(default_factory=EucBalanceController)
    rider_gains: tuple[float, float, float, float] = (800.0, 150.0, 0.12, 0.05)
    rtol: float = 1e-10
    atol: float = 1e-10
    method: str = "compiled"
    floor: FloorProfile | None = None
    external: tuple = ()
    pedals: PedalFlex | None = None
    arms: ArmSwing | None = None

    def nominal_session(self) -> Session:
        """The session written to session.yaml (nominal values).

        Returns
        -------
        Session
            ``session``, or the default Y-up session.
        """
        return self.session if self.session is not None else default_session("y")


@dataclass
class RunResult:
    """Truth and synthesized mocap of one run (arrays over the n samples of the recording).

    Parameters
    ----------
    name : str
        Run name (``<maneuver>_NN``), also the CSV stem.
    plan : RunPlan
        The run's random plan.
    t : ndarray (n,)
        Time [s] from the recording start; ``frame = round(t * rate)``.
    frame : ndarray (n,) of int64
    q, q_dot, q_ddot : ndarray (n, 3)
        True [x, gamma, phi] and derivatives (SI, rad).
    psi, theta, psi_dot : ndarray (n,)
        Yaw, tilt [rad] and yaw rate [rad/s] of the EUC.
    M_d, M_h : ndarray (n,)
        True driving torque and rider torque [N m].
    h, h_dot, h_ddot : ndarray (n,)
        True rider CoG height [m] and derivatives.
    signals : dict of ndarray (n,)
        Effect signals: ``a_c`` [m/s^2], ``g_x``, ``g_z`` (in-plane gravity [m/s^2]), ``F_contact`` [N],
        ``tau_wb`` [N m], ``F_aero_x``, ``F_aero_z`` [N], ``dQ_x`` [N], ``dQ_gamma``, ``dQ_phi`` [N m]
        (generalized force of the non-conservative effects).
    C, A, G, E : ndarray (n, 3)
        World positions [m] (Z-up, floor frame) of wheel centre, hinge, rider CoG, EUC pivot.
    mocap : MocapSeries
        The recording as written (noise, gaps, dropped frames; measurement effects applied).
    mocap_clean : MocapSeries
        The same without noise, gaps and dropped frames (measurement effects applied).
    state : ndarray (n, n_states)
        The integrated state (:data:`STATE_NAMES`, then u, u_dot with pedals that flex) at the samples.
    solver_stats : dict
        Integration method, right-hand-side evaluations ``nfev``, accepted ``steps``, ``rtol``, ``atol``.
    """

    name: str
    plan: RunPlan
    t: np.ndarray
    frame: np.ndarray
    q: np.ndarray
    q_dot: np.ndarray
    q_ddot: np.ndarray
    psi: np.ndarray
    theta: np.ndarray
    psi_dot: np.ndarray
    M_d: np.ndarray
    M_h: np.ndarray
    h: np.ndarray
    h_dot: np.ndarray
    h_ddot: np.ndarray
    signals: dict
    C: np.ndarray
    A: np.ndarray
    G: np.ndarray
    E: np.ndarray
    mocap: MocapSeries
    mocap_clean: MocapSeries
    state: np.ndarray | None = None
    solver_stats: dict = field(default_factory=dict)


@dataclass
class RideResult:
    """All runs of a simulated ride, with the true and nominal parameters.

    Parameters
    ----------
    config : RideConfig
        What was simulated.
    session : Session
        The nominal session.
    params_true, params_nominal : PlanarParams
        True (effects applied) and nominal parameters.
    runs : list of RunResult
        The runs.
    """

    config: RideConfig
    session: Session
    params_true: PlanarParams
    params_nominal: PlanarParams
    runs: list[RunResult]

    def truth_dict(self) -> dict:
        """JSON-friendly description of the hidden truth (what ``truth.json`` holds).

        Returns
        -------
        dict
            The truth by name.
        """
        differ = {}
        names = {"m": "rider.mass", "J": "rider.inertia_pitch", "R": "euc.wheel_radius", "m0": "euc.body_mass",
                 "mw": "euc.wheel_mass", "Jw": "euc.wheel_inertia", "J0": "euc.body_inertia", "h0": "euc.h0",
                 "l0": "euc.l0"}
        for k, key in names.items():
            a, b = getattr(self.params_true, k), getattr(self.params_nominal, k)
            if a != b:
                differ[key] = {"true": a, "nominal": b}
        c = self.config
        return {
            "generator": "euc_ros.core.ridesim",
            "maneuver": c.maneuver,
            "seed": c.seed,
            "h_m": c.h,
            "effect": c.effects.label,
            "effect_parameters": c.effects.parameters(),
            "effects": c.effects.to_list(),
            "true_parameters_that_differ": differ,
            "gravity_m_per_s2": self.params_true.g,
            "controllers": {
                "euc": {"k_p": c.euc_controller.k_p, "k_d": c.euc_controller.k_d, "k_v": c.euc_controller.k_v},
                "rider": dict(zip(("k_p", "k_d", "k_speed", "k_int"), c.rider_gains)),
            },
            "noise": c.noise.to_dict(),
            "floor": c.floor.to_dict() if c.floor is not None else None,
            "external": [f.to_dict() for f in c.external],
            "rider_motion": [m.to_dict() for m in (c.pedals, c.arms) if m is not None],
            "runs": [{
                "run": r.name, "csv": f"{r.name}.csv", "truth_csv": f"truth/{r.name}_truth.csv",
                "duration_s": r.plan.duration_s, "psi0_rad": r.plan.path.psi0,
                "v_start_m_per_s": float(r.q_dot[0, 0]), "v_end_m_per_s": float(r.q_dot[-1, 0]),
                "frames": int(r.t.size), "frames_written": int(r.mocap.n_frames),
                "solver": r.solver_stats,
            } for r in self.runs],
        }


def true_params(nominal: PlanarParams, effects: EffectSet) -> PlanarParams:
    """Apply the parameter effects (rider mass/inertia, wheel radius) to the nominal parameters.

    Parameters
    ----------
    nominal : PlanarParams
        Nominal parameters.
    effects : EffectSet
        Active effects.

    Returns
    -------
    PlanarParams
        True parameters.
    """
    return nominal.with_changes(
        m=nominal.m + effects.get("rider_mass_error", "delta_m_kg"),
        J=nominal.J + effects.get("rider_inertia_error", "delta_j_kgm2"),
        R=nominal.R + effects.get("wheel_radius_error", "delta_r_m"),
    )


class _RunDynamics:
    """Right-hand side and sampled signals of one run (one numpy code path for scalars and arrays)."""

    def __init__(self, plan: RunPlan, model: PlanarModel, effects: EffectSet, h_mean: float,
                 euc: EucBalanceController, rider: RiderLeanController) -> None:
        self.plan, self.model, self.euc, self.rider = plan, model, euc, rider
        p = model.params
        self.p = p
        self.h_mean = h_mean
        self.h_amp = effects.get("time_varying_h", "amplitude_m")
        self.h_w = (2 * math.pi / effects.get("time_varying_h", "period_s")) if "time_varying_h" in effects else 0.0
        alpha = math.radians(effects.get("ground_slope", "alpha_deg"))
        self.sin_a, self.cos_a = math.sin(alpha), math.cos(alpha)
        self.tilt_gain = effects.get("tilt_gravity", "gain")
        self.c_rr = effects.get("rolling_resistance", "c_rr")
        self.c_v = effects.get("viscous_friction", "c_v")
        self.c_wb = effects.get("wheel_body_friction", "c_wb")
        self.k_aero = 0.5 * AIR_DENSITY * effects.get("aero_drag", "cda_m2")
        self.normal_force = p.total_mass * p.g
        self.floor = None
        self.external = ()
        self.pedal_k = self.pedal_c = None     # pedals that flex: stiffness, damping
        self.arms: ArmKinematics | None = None

    def external_forces(self, y, env, h):
        """Sum of the external forces' generalized forces (dQ_x, dQ_gamma, dQ_phi)."""
        out = [0.0 * y[3], 0.0 * y[3], 0.0 * y[3]]
        for f in self.external:
            q = f.generalized(x=y[0], gamma=y[1], phi=y[2], x_dot=y[3], gamma_dot=y[4], phi_dot=y[5], h=h, X=y[6],
                              psi=env["psi"], R=self.p.R, l0=self.p.l0)
            out = [a + b for a, b in zip(out, q)]
        return out

    def slope(self, X, psi, kappa):
        """Floor slope along travel and its rate along the path (0, 0 on a level floor)."""
        if self.floor is None:
            return 0.0 * X, 0.0 * X
        return self.floor.slope_along(X, psi, kappa)

    # --- pieces ---
    def h_profile(self, t):
        """h(t), h_dot(t), h_ddot(t) [m, m/s, m/s^2]."""
        if self.arms is not None:
            a = self.arms.profile(t)
            return a["h"], a["h_dot"], a["h_ddot"]
        if not self.h_w:
            if np.ndim(t) == 0:
                return self.h_mean, 0.0, 0.0
            z = np.zeros_like(np.asarray(t, float))
            return self.h_mean + z, z, z
        t = np.asarray(t, float)
        s, c = np.sin(self.h_w * t), np.cos(self.h_w * t)
        a, w = self.h_amp, self.h_w
        return self.h_mean + a * s, a * w * c, -a * w * w * s

    def environment(self, t, y):
        """Path, tilt and gravity signals at (t, state)."""
        x, xd = y[0], y[3]
        path = self.plan.path
        kappa = path.kappa(x)
        psi = path.psi(x)
        a_c = kappa * xd * xd
        theta = self.plan.tilt(t, xd, kappa, self.p.g)
        g_n = self.p.g * self.cos_a
        if self.tilt_gain:
            g_n = g_n + self.tilt_gain * (g_n * np.cos(theta) - a_c * np.sin(theta) - g_n)
        g_x = -self.p.g * self.sin_a * np.cos(psi)
        a, a1 = self.slope(y[6], psi, kappa)
        return {"psi": psi, "kappa": kappa, "psi_dot": kappa * xd, "theta": theta, "a_c": a_c,
                "g_x": g_x + 0.0 * xd, "g_z": -g_n + 0.0 * xd, "floor_a": a, "floor_a1": a1}

    def inputs(self, t, y, env):
        """True M_d and M_h [N m]."""
        x, gam, phi, xd, gd, pd = y[:6]
        v_ref, a_ref = self.plan.speed.reference(t, env["kappa"], self.plan.path.dkappa(x), xd)
        phi_des = self.rider.desired_lean(v_ref, a_ref, xd, y[8], self.plan.sway(t))
        return self.euc.torque(gam, gd, xd), self.rider.torque(phi, pd, phi_des), v_ref

    def effect_forces(self, y, h, hd, vel_g, jac_g):
        """Generalized forces of the non-conservative effects (dQ_x, dQ_gamma, dQ_phi) and their parts."""
        xd, gd = y[3], y[4]
        F_c = -self.c_rr * self.normal_force * np.tanh(xd / ROLLING_SIGN_SPEED) - self.c_v * xd + 0.0
        tau_wb = -self.c_wb * (xd / self.p.R - gd) + 0.0
        if self.k_aero:
            vx, vz = vel_g
            speed = np.sqrt(vx * vx + vz * vz)
            Fx, Fz = -self.k_aero * speed * vx, -self.k_aero * speed * vz
            j = jac_g
            qa = (j[0] * Fx + j[3] * Fz, j[1] * Fx + j[4] * Fz, j[2] * Fx + j[5] * Fz)
        else:
            Fx = Fz = 0.0 * xd
            qa = (0.0, 0.0, 0.0)
        dQ = (F_c + tau_wb / self.p.R + qa[0], -tau_wb + qa[1], qa[2] + 0.0 * xd)
        return dQ, {"F_contact": F_c, "tau_wb": tau_wb, "F_aero_x": Fx, "F_aero_z": Fz}

    # --- ODE ---
    def rhs(self, t, y):
        """d/dt of :data:`STATE_NAMES`."""
        x, gam, phi, xd, gd, pd = y[:6]
        h, hd, hdd = (float(v) for v in self.h_profile(t))
        env = self.environment(t, y)
        M_d, M_h, v_ref = self.inputs(t, y, env)
        if self.k_aero:
            jac, vel = self.model.g_point_scalar(gam, phi, xd, gd, pd, h, hd)
        else:
            jac = vel = None
        dQ, _ = self.effect_forces(y, h, hd, vel, jac)
        if self.external:
            dQ = tuple(a + float(b) for a, b in zip(dQ, self.external_forces(y, env, h)))
        R = self.p.R
        Q0 = M_d / R + dQ[0]
        Q1 = M_h - M_d + dQ[1]
        Q2 = -M_h + dQ[2]
        psi = env["psi"]
        if self.pedal_k is not None:
            u, ud = y[10], y[11]
            a = self.model.accel_scalar(gam, phi, u, xd, gd, pd, ud, h, hd, hdd, float(env["g_x"]), float(env["g_z"]),
                                        (float(Q0), float(Q1), float(Q2), -self.pedal_k * u - self.pedal_c * ud))
            return [xd, gd, pd, a[0], a[1], a[2], xd * math.cos(psi), xd * math.sin(psi), float(v_ref) - xd, 0.0,
                    ud, a[3]]
        if self.arms is not None:
            ar = self.arms.profile(t)
            a = self.model.accel_scalar(gam, phi, xd, gd, pd, h, hd, hdd, float(env["g_x"]), float(env["g_z"]),
                                        float(Q0), float(Q1), float(Q2 - ar["dJ_dot"] * pd - ar["H_dot"]), dJ=ar["dJ"])
            return [xd, gd, pd, a[0], a[1], a[2], xd * math.cos(psi), xd * math.sin(psi), float(v_ref) - xd, 0.0]
        if self.floor is None:
            a = self.model.accel_scalar(gam, phi, xd, gd, pd, h, hd, hdd, float(env["g_x"]), float(env["g_z"]),
                                        float(Q0), float(Q1), float(Q2))
            return [xd, gd, pd, a[0], a[1], a[2], xd * math.cos(psi), xd * math.sin(psi), float(v_ref) - xd, 0.0]
        fa = float(env["floor_a"])
        a = self.model.accel_scalar(gam, phi, xd, gd, pd, h, hd, hdd, float(env["g_x"]), float(env["g_z"]), fa,
                                    float(env["floor_a1"]), float(Q0), float(Q1), float(Q2))
        vh = xd * math.cos(fa)
        return [xd, gd, pd, a[0], a[1], a[2], vh * math.cos(psi), vh * math.sin(psi), float(v_ref) - xd,
                xd * math.sin(fa)]

    def sample(self, t: np.ndarray, Y: np.ndarray) -> dict:
        """All truth signals at sample times t (n,) for states Y (8, n), vectorized."""
        x, gam, phi, xd, gd, pd = Y[:6]
        h, hd, hdd = self.h_profile(t)
        env = self.environment(t, Y)
        M_d, M_h, v_ref = self.inputs(t, Y, env)
        vel = self.model.rider_cog_velocity(gam, phi, xd, gd, pd, h, hd).T
        jac = self.model.rider_cog_jacobian(gam, phi, h).reshape(-1, 6).T
        dQ, parts = self.effect_forces(Y, h, hd, vel, jac)
        if self.external:
            dQ = tuple(a + b for a, b in zip(dQ, self.external_forces(Y, env, h)))
        R = self.p.R
        Q = np.stack([M_d / R + dQ[0], M_h - M_d + dQ[1], -M_h + dQ[2]], -1)
        extra = {}
        if self.pedal_k is not None:
            u, ud = Y[10], Y[11]
            Qu = -self.pedal_k * u - self.pedal_c * ud
            q4 = self.model.accelerations(gam, phi, u, xd, gd, pd, ud, h, hd, hdd, env["g_x"], env["g_z"],
                                          np.concatenate([Q, Qu[:, None]], axis=1))
            qdd = q4[:, :3]
            extra = {"pedal_u": u, "pedal_force": -Qu}
        elif self.arms is not None:
            ar = self.arms.profile(t)
            Q[:, 2] -= ar["dJ_dot"] * pd + ar["H_dot"]
            qdd = self.model.accelerations(gam, phi, xd, gd, pd, h, hd, hdd, env["g_x"], env["g_z"], Q, dJ=ar["dJ"])
            extra = {"arm_beta": ar["beta"], "arm_dJ": ar["dJ"], "arm_H_dot": ar["H_dot"]}
        elif self.floor is None:
            qdd = self.model.accelerations(gam, phi, xd, gd, pd, h, hd, hdd, env["g_x"], env["g_z"], Q)
        else:
            qdd = self.model.accelerations(gam, phi, xd, gd, pd, h, hd, hdd, env["g_x"], env["g_z"], env["floor_a"],
                                           env["floor_a1"], Q)
        return {"env": env, "M_d": M_d, "M_h": M_h, "v_ref": v_ref, "h": h, "h_dot": hd, "h_ddot": hdd,
                "dQ": np.stack(dQ, -1), "parts": {**parts, **extra}, "q_ddot": qdd}

    def world(self, t, Y, xy_offset, session: Session) -> dict:
        """3-D placement at times t (n,) for states Y (8, n): C, A, G, E and rotations (Z-up)."""
        x, gam, phi = Y[:3]
        env = self.environment(t, Y)
        psi, theta = env["psi"], env["theta"]
        h = self.h_profile(t)[0]
        n = np.size(t)
        C = np.stack([Y[6] - xy_offset[0], Y[7] - xy_offset[1], Y[9] + self.p.R * np.cos(theta)], -1).reshape(n, 3)
        R_E = yaw_tilt_pitch_matrices(psi, theta, gam).reshape(n, 3, 3)
        R_L = yaw_tilt_pitch_matrices(psi, theta, phi).reshape(n, 3, 3)
        p = np.asarray(session.euc.pivot_to_wheel_center, float)
        E = C - R_E @ p
        l_hinge = self.p.l0 if self.pedal_k is None else self.p.l0 + np.reshape(Y[10], (-1, 1))
        A = C - l_hinge * R_E[:, :, 2]
        G = A + np.reshape(h, (-1, 1)) * R_L[:, :, 2]
        return {"C": C, "A": A, "G": G, "E": E, "R_E": R_E, "R_L": R_L, "h": np.broadcast_to(h, (n,))}


def yaw_tilt_pitch_matrices(psi, theta, pitch) -> np.ndarray:
    """``Rz(psi) Rx(theta) Ry(pitch)`` (..., 3, 3) in closed form.

    The matrices of :func:`~euc_ros.core.rotations.quat_from_yaw_tilt_pitch`, without the quaternion round
    trip.

    Parameters
    ----------
    psi, theta, pitch : array_like
        Yaw, tilt and pitch [rad] (broadcast together).

    Returns
    -------
    numpy.ndarray
        Rotation matrices (..., 3, 3).
    """
    psi, theta, pitch = np.broadcast_arrays(*(np.asarray(v, float) for v in (psi, theta, pitch)))
    cz, sz, cx, sx, cy, sy = np.cos(psi), np.sin(psi), np.cos(theta), np.sin(theta), np.cos(pitch), np.sin(pitch)
    return np.stack([np.stack([cz * cy - sz * sx * sy, -sz * cx, cz * sy + sz * sx * cy], -1),
                     np.stack([sz * cy + cz * sx * sy, cz * cx, sz * sy - cz * sx * cy], -1),
                     np.stack([-cx * sy, sx, cx * cy], -1)], -2)


def _run_index(name: str) -> int:
    """The index k (from 0) of a run named ``<maneuver>_NN`` (NN = k + 1)."""
    tail = name.rsplit("_", 1)[-1]
    return max(int(tail) - 1, 0) if tail.isdigit() else 0


def _initial_state(dyn: _RunDynamics, t0: float, rhs=None) -> np.ndarray:
    """State at t0 with zero accelerations at the reference speed (unknowns gamma, phi, z).

    ``rhs(t, y) -> list`` is the right-hand side to balance (default ``dyn.rhs``).
    """
    rhs = dyn.rhs if rhs is None else rhs
    v0 = float(dyn.plan.speed.reference(t0, dyn.plan.path.kappa(0.0), dyn.plan.path.dkappa(0.0), 0.0)[0])
    guess = np.array([-dyn.euc.k_v * v0 / dyn.euc.k_p, 0.0, 0.0])
    X0 = Z0 = 0.0
    if dyn.floor is not None:     # runs start at -run_start_m heading +X, at +run_start_m heading -X
        X0 = -dyn.floor.run_start_m * math.copysign(1.0, math.cos(dyn.plan.path.psi0))
        Z0 = float(dyn.floor.evaluate(X0)[0])

    if dyn.pedal_k is not None:      # pedals: the static deflection is a fourth unknown
        guess = np.append(guess, dyn.p.m * dyn.p.g / dyn.pedal_k)

    def acc(u):
        y = [0.0, u[0], u[1], v0, 0.0, 0.0, X0, 0.0, u[2], Z0]
        if dyn.pedal_k is not None:
            r = rhs(t0, y + [u[3], 0.0])
            return r[3:6] + [r[11]]
        return rhs(t0, y)[3:6]

    sol, info, ok, _ = fsolve(acc, guess, full_output=True, xtol=1e-12)
    # fsolve may stop short of its xtol ("not making good progress") on a solution balanced to rounding: the
    # residual accelerations decide
    balanced = ok == 1 or np.max(np.abs(info["fvec"])) <= BALANCE_TOL
    u = sol if balanced and np.all(np.abs(sol[:2]) < 0.5) else guess
    y0 = [0.0, u[0], u[1], v0, 0.0, 0.0, X0, 0.0, u[2], Z0]
    return np.array(y0 + ([u[3], 0.0] if dyn.pedal_k is not None else []))


def run_dynamics(plan: RunPlan, config: RideConfig, params: PlanarParams, skeleton: Skeleton) -> _RunDynamics:
    """The dynamics of one planned run: truth model, controllers, effects, floor, external forces, rider motion.

    Parameters
    ----------
    plan : RunPlan
        The run's plan (path, speed profile, sway).
    config : RideConfig
        The ride's configuration (its ``method`` picks the source of the equations: generated or sympy).
    params : PlanarParams
        True physical parameters.
    skeleton : Skeleton
        The rider's segments (for arm swing).

    Returns
    -------
    _RunDynamics
        Right-hand side (``rhs``), sampled truth (``sample``) and 3-D placement (``world``) of the run.

    Raises
    ------
    ConfigError
        For pedals or arm swing combined with what they do not support.
    """
    effects = config.effects
    if config.pedals is not None and (config.floor is not None or config.external or config.arms is not None
                                      or "aero_drag" in effects or "time_varying_h" in effects):
        raise ConfigError("pedals combine only with effects that need no rider-CoG geometry (no floor, external "
                          "force, arm swing, aero_drag or time_varying_h)", key="pedals")
    if config.arms is not None and (config.floor is not None or "time_varying_h" in effects):
        raise ConfigError("arm swing does not combine with a floor or time_varying_h", key="arms")
    equations = "sympy" if config.method == "reference" else "generated"
    if config.pedals is not None:
        model = PedalModel(params, equations)
    else:
        model = PlanarModel(params, equations) if config.floor is None else FloorModel(params, equations)
    m_eq = params.total_mass + params.Jw / params.R ** 2
    k_p, k_d, k_speed, k_int = config.rider_gains
    rider = RiderLeanController.for_rider(params.m, config.h, params.g, params.R, m_eq,
                                          k_p=k_p, k_d=k_d, k_speed=k_speed, k_int=k_int)
    dyn = _RunDynamics(plan, model, effects, config.h, config.euc_controller, rider)
    dyn.floor = config.floor
    dyn.external = tuple(config.external)
    if config.pedals is not None:
        dyn.pedal_k, dyn.pedal_c = config.pedals.k_n_per_m, config.pedals.damping(params.m)
    if config.arms is not None:
        dyn.arms = ArmKinematics(config.arms, skeleton, config.h, params.m, run_index=_run_index(plan.name))
    return dyn


def integrate_run(dyn: _RunDynamics, config: RideConfig, t0: float, t_end: float):
    """Integrate a run's dynamics from its balanced initial state at t0 to t_end with ``config.method``.

    Parameters
    ----------
    dyn : _RunDynamics
        From :func:`run_dynamics`.
    config : RideConfig
        ``method``, ``rtol`` and ``atol`` are used.
    t0, t_end : float
        Start (settling included, negative) and end of the integration [s].

    Returns
    -------
    solution
        ``solve_ivp``'s result (reference) or a :class:`~.compiled.CompiledSolution`: ``t`` (step boundaries),
        ``y`` (states there, (n_states, steps + 1)), ``sol(t)`` (dense output), ``nfev``, ``success``, ``message``.
    """
    if config.method == "reference":
        y0 = _initial_state(dyn, t0)
        return solve_ivp(dyn.rhs, (t0, t_end), y0, method="DOP853", rtol=config.rtol, atol=config.atol,
                         dense_output=True)
    from euc_ros.core.ridesim import compiled  # lazily: numba compiles (or loads its cache) on first use

    packed = compiled.pack(dyn)
    y0 = _initial_state(dyn, t0, lambda tt, y: compiled.rhs_value(tt, np.asarray(y, float), packed).tolist())
    return compiled.integrate(packed, t0, t_end, y0, config.rtol, config.atol)


def simulate_run(plan: RunPlan, config: RideConfig, params: PlanarParams, skeleton: Skeleton,
                 noise_rng: np.random.Generator) -> RunResult:
    """Simulate one planned run (see :func:`simulate_ride`).

    Parameters
    ----------
    plan : RunPlan
        The run's plan.
    config : RideConfig
        The ride's settings.
    params : PlanarParams
        True parameters.
    skeleton : Skeleton
        The rider's skeleton.
    noise_rng : numpy.random.Generator
        Source of the mocap noise.

    Returns
    -------
    RunResult
        Truth and mocap of the run.

    Raises
    ------
    ConfigError
        When the step exceeds the settle time.
    EucError
        When the integration fails.
    """
    session = config.nominal_session()
    effects = config.effects
    dyn = run_dynamics(plan, config, params, skeleton)
    rate = session.rate_hz
    n = int(round(plan.duration_s * rate))
    frame = np.arange(n, dtype=np.int64)
    t = frame / rate
    dt_off = effects.get("mocap_time_offset", "dt_ms") * 1e-3
    t0 = -config.settle_s
    if dt_off > config.settle_s:
        raise ConfigError(f"dt_ms must not exceed the settle time {config.settle_s} s", key="dt_ms")
    t_end = t[-1] + max(0.0, -dt_off) + 1.0 / rate
    sol = integrate_run(dyn, config, t0, t_end)
    if not sol.success:
        raise EucError(f"ride simulation of {plan.name} failed: {sol.message}")
    Y = sol.sol(t)
    s = dyn.sample(t, Y)
    env = s["env"]
    # centre the recorded C track in the capture volume, unless something is fixed in the lab (a floor, a rope's
    # anchor): then every run is recorded in the one lab frame the simulation used
    xy = Y[6:8]
    lab_fixed = config.floor is not None or any(getattr(f, "lab_fixed", False) for f in config.external)
    xy_offset = 0.5 * (xy.min(axis=1) + xy.max(axis=1)) if not lab_fixed else np.zeros(2)
    w = dyn.world(t, Y, xy_offset, session)
    # rider at t - dt for the mocap_time_offset effect (measurement only)
    w_rider = w if dt_off == 0 else dyn.world(t - dt_off, sol.sol(t - dt_off), xy_offset, session)
    if dyn.arms is not None:
        seg_pos, seg_rot = dyn.arms.poses(w_rider["A"], w_rider["R_L"], t - dt_off)
    else:
        seg_pos, seg_rot = skeleton.poses(w_rider["A"], w_rider["R_L"], w_rider["h"])
    e_pos = w["E"][None]
    bodies = skeleton.bodies + [session.euc.body]
    pos = np.concatenate([seg_pos, e_pos], axis=0)
    quat = np.concatenate([rotations_to_quats(seg_rot), rotations_to_quats(w["R_E"][None])], axis=0)
    clean = MocapSeries(t=t.copy(), frame=frame.copy(), bodies=list(bodies), position=pos, quat=quat,
                        tracked=np.ones(pos.shape[:2], bool), mean_marker_error=np.zeros(pos.shape[:2]),
                        name=plan.name, meta={"rate_hz": rate, "world_up": "z", "synthetic": True})
    recorded = corrupt(clean, config.noise, noise_rng)
    q = Y[:3].T.copy()
    qd = Y[3:6].T.copy()
    signals = {"a_c": env["a_c"], "g_x": env["g_x"], "g_z": env["g_z"], "v_ref": s["v_ref"],
               "floor_slope": np.broadcast_to(env["floor_a"], t.shape).astype(float),
               "dQ_x": s["dQ"][:, 0], "dQ_gamma": s["dQ"][:, 1], "dQ_phi": s["dQ"][:, 2],
               **{k: np.broadcast_to(v, t.shape).astype(float) for k, v in s["parts"].items()}}
    return RunResult(
        name=plan.name, plan=plan, t=t, frame=frame, q=q, q_dot=qd, q_ddot=s["q_ddot"],
        psi=env["psi"], theta=env["theta"], psi_dot=env["psi_dot"], M_d=s["M_d"], M_h=s["M_h"],
        h=np.broadcast_to(s["h"], t.shape).copy(), h_dot=np.broadcast_to(s["h_dot"], t.shape).copy(),
        h_ddot=np.broadcast_to(s["h_ddot"], t.shape).copy(), signals=signals,
        C=w["C"], A=w["A"], G=w["G"], E=w["E"], mocap=recorded, mocap_clean=clean,
        state=Y.T.copy(),
        solver_stats={"method": config.method, "nfev": int(sol.nfev), "steps": int(sol.t.size - 1),
                      "rtol": config.rtol, "atol": config.atol},
    )


def simulate_ride(config: RideConfig, progress=None) -> RideResult:
    """Simulate all runs of a ride and synthesize their mocap (no files written).

    Parameters
    ----------
    config : RideConfig
        Maneuver, number of runs, seed, true h, effects, nominal session, noise.
    progress : callable, optional
        ``progress(iterable)`` wraps the loop over runs (a progress bar).

    Returns
    -------
    RideResult
        Per run the true states, accelerations, inputs, 3-D points and the synthesized
        :class:`~euc_ros.core.mocap.series.MocapSeries` (Z-up), plus true and nominal parameters.

    Raises
    ------
    ConfigError
        For an unknown maneuver, a non-positive number of runs, h or duration, or a session whose
        segments the skeleton cannot place.

    Notes
    -----
    Randomness: ``np.random.SeedSequence(seed)`` is spawned into one child per run (its plan) and
    one per run (its noise), so run k is the same whatever the number of runs.
    """
    if config.maneuver not in MANEUVERS:
        raise ConfigError(f"unknown maneuver {config.maneuver!r} (known: {', '.join(MANEUVERS)})", key="maneuver")
    if config.runs < 1:
        raise ConfigError(f"must be >= 1, got {config.runs}", key="runs")
    if config.method not in METHODS:
        raise ConfigError(f"unknown method {config.method!r} (known: {', '.join(METHODS)})", key="method")
    if not 0.1 < config.h < 2.0:
        raise ConfigError(f"rider CoG height must be in (0.1, 2) m, got {config.h}", key="h")
    session = config.nominal_session()
    nominal = PlanarParams.from_session(session)
    params = true_params(nominal, config.effects)
    skeleton = Skeleton.for_session(session)
    seq = np.random.SeedSequence(config.seed)
    children = seq.spawn(2 * config.runs)
    runs = []
    for k in (progress(range(config.runs)) if progress else range(config.runs)):
        plan = plan_run(config.maneuver, k, np.random.default_rng(children[2 * k]), config.duration_s,
                        config.speed_scale, config.path_scale)
        runs.append(simulate_run(plan, config, params, skeleton, np.random.default_rng(children[2 * k + 1])))
    return RideResult(config=config, session=session, params_true=params, params_nominal=nominal, runs=runs)
