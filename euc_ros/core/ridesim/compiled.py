"""Compiled ride simulation: the truth's right-hand side and DOP853 with dense output, in numba.

The reference simulation (``RideConfig(method="reference")``) integrates the right-hand side of
:class:`~euc_ros.core.ridesim.simulate._RunDynamics`, written in Python, with
``scipy.integrate.solve_ivp`` (DOP853): about 15 000 calls of a ~50 us function per 9 s of simulated
time. This module computes the same right-hand side compiled (``method="compiled"``, the default):

* the equations of motion are the functions that :mod:`.eom_codegen` printed from the sympy
  derivation (:mod:`.eom_generated`), compiled as they are (no formula is copied by hand);
* the forces, controllers, maneuver signals, floors, external forces and rider motions follow
  :meth:`~euc_ros.core.ridesim.simulate._RunDynamics.rhs` term by term, with every run's numbers
  packed into one :class:`RunParams`;
* the integrator is DOP853 as ``solve_ivp`` runs it: the same Butcher tableau (scipy's
  coefficients), error norm, step-size control, initial step and 7th-order dense output, so both
  paths keep the same local error bound ``atol + rtol |y|`` per step.

``test/unit/core/ridesim/test_compiled.py`` checks that both paths give the same states within the
integrator's tolerance for every effect, floor, external force and rider motion.

Functions are compiled on first use and cached on disk (numba ``cache=True``, next to this file).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np
from scipy.integrate._ivp import dop853_coefficients as _dop

from euc_ros.core.ridesim import eom_generated as _eom
from euc_ros.core.ridesim.effects import ROLLING_SIGN_SPEED
from euc_ros.core.ridesim.external import AIR_DENSITY as EXTERNAL_AIR_DENSITY
from euc_ros.core.ridesim.truth_model import solve3

_jit = numba.njit(cache=True, nogil=True, error_model="numpy")

# the equations of motion, compiled from the printed derivation
_planar_mass = _jit(_eom.planar_mass)
_planar_bias = _jit(_eom.planar_bias)
_planar_jac_g = _jit(_eom.planar_jac_g)
_planar_vel_g = _jit(_eom.planar_vel_g)
_floor_mass = _jit(_eom.floor_mass)
_floor_bias = _jit(_eom.floor_bias)
_pedal_mass = _jit(_eom.pedal_mass)
_pedal_bias = _jit(_eom.pedal_bias)

#: Truth geometries (:attr:`RunParams.model`).
MODEL_PLANAR, MODEL_FLOOR, MODEL_PEDAL = 0, 1, 2
#: Floor components (rows of :attr:`RunParams.floor`: code, then the parameters of :mod:`.floors`).
FLOOR_RAMP, FLOOR_RAMP_FROM, FLOOR_BUMP, FLOOR_STEP = 0, 1, 2, 3
#: External forces (rows of :attr:`RunParams.external`: code, then the parameters of :mod:`.external`).
EXT_TORQUE_RIPPLE, EXT_ROPE, EXT_HEADWIND, EXT_CONTACT_DRAG, EXT_WHEEL_HARMONICS, EXT_LAB_BUMP = 0, 1, 2, 3, 4, 5
#: Order of the arm-swing profile tables in :attr:`RunParams.arm_c` (:meth:`.ArmKinematics._tables`).
ARM_TABLES = ("h", "h1", "h2", "beta", "dJ", "J1", "K", "P")


class RunParams(NamedTuple):
    """Everything the compiled right-hand side of one run needs (SI units, rad).

    Scalars mirror the attributes of :class:`~euc_ros.core.ridesim.simulate._RunDynamics`, its plan and its
    controllers; tables are float arrays with one row per item.
    """

    # truth model (PlanarParams, true values)
    m: float
    m0: float
    mw: float
    Jw: float
    J0: float
    J: float
    R: float
    l0: float
    h0: float
    g: float
    model: int
    # rider CoG height h(t): mean, time_varying_h amplitude and angular frequency (0: constant)
    h_mean: float
    h_amp: float
    h_w: float
    # gravity: ground slope, tilt_gravity gain
    sin_a: float
    cos_a: float
    tilt_gain: float
    # non-conservative effects
    c_rr: float
    normal_force: float
    c_v: float
    c_wb: float
    k_aero: float
    # controllers
    euc_kp: float
    euc_kd: float
    euc_kv: float
    rider_kp: float
    rider_kd: float
    rider_kspeed: float
    rider_kint: float
    rider_cff: float
    rider_mgh: float
    # plan: heading path, speed profile
    psi0: float
    path_amp: float
    path_len: float
    path_phase: float
    v0: float
    v1: float
    t1: float
    ramp_s: float
    slow_in_turns: float
    kappa_max: float
    # pedals that flex (model MODEL_PEDAL)
    pedal_k: float
    pedal_c: float
    # arm swing (has_arms): angle amp sin(w t + phase); tables as cubic splines on arm_x
    has_arms: bool
    arm_amp: float
    arm_w: float
    arm_phase: float
    # tables: sinusoids (amplitude, frequency [Hz], phase), floor components, external forces, arm splines
    sway: np.ndarray
    wobble: np.ndarray
    floor: np.ndarray
    external: np.ndarray
    arm_x: np.ndarray
    arm_c: np.ndarray


def pack(dyn) -> RunParams:
    """Pack a run's dynamics into :class:`RunParams`.

    Parameters
    ----------
    dyn : euc_ros.core.ridesim.simulate._RunDynamics
        Plan, true parameters, controllers, effects, floor, external forces and rider motion of one run.

    Returns
    -------
    RunParams
        The same numbers, in the form the compiled right-hand side reads.
    """
    p, plan, euc, rider = dyn.p, dyn.plan, dyn.euc, dyn.rider

    def sinusoids(s):
        return np.array([s.amplitudes, s.freqs_hz, s.phases], float).T.reshape(-1, 3).copy()

    floor = np.zeros((0, 4))
    if dyn.floor is not None:
        rows = []
        for c in dyn.floor.components:
            q = c.params
            if c.kind == "ramp":
                rows.append((FLOOR_RAMP, math.tan(math.radians(q["slope_deg"])), 0.0, 1.0))
            elif c.kind == "ramp_from":
                rows.append((FLOOR_RAMP_FROM, math.tan(math.radians(q["slope_deg"])), q["x0_m"], q["width_m"]))
            else:
                rows.append((FLOOR_BUMP if c.kind == "bump" else FLOOR_STEP, q["height_m"], q["x0_m"], q["width_m"]))
        floor = np.array(rows, float).reshape(-1, 4)
    ext_rows = []
    for f in dyn.external:
        q = f.params
        if f.kind == "torque_ripple":
            ext_rows.append((EXT_TORQUE_RIPPLE, q["amp_nm"], q["per_turn"], 0.0))
        elif f.kind == "rope":
            ext_rows.append((EXT_ROPE, q["k_n_per_m"], q["anchor_x_m"], q["hand_m"]))
        elif f.kind == "contact_drag":
            ext_rows.append((EXT_CONTACT_DRAG, q["c_n_s2_per_m2"], 0.0, 0.0))
        elif f.kind == "lab_bump":
            ext_rows.append((EXT_LAB_BUMP, q["amp_n"], q["x0_m"], q["width_m"]))
        elif f.kind == "wheel_harmonics":
            ext_rows.append((EXT_WHEEL_HARMONICS, q["amp2_n"], q["amp3_n"], q["phase3_rad"]))
        else:
            ext_rows.append((EXT_HEADWIND, q["wind_m_per_s"], q["cda_m2"], 0.0))
    external = np.array(ext_rows, float).reshape(-1, 4)
    arm_x, arm_c = np.zeros(2), np.zeros((len(ARM_TABLES), 4, 1))
    arms = dyn.arms
    if arms is not None:
        arms.profile(0.0)                         # builds the splines
        arm_x = np.ascontiguousarray(arms._splines["h"].x, float)
        arm_c = np.ascontiguousarray(np.stack([arms._splines[k].c for k in ARM_TABLES]), float)
    if dyn.pedal_k is not None:
        model = MODEL_PEDAL
    elif dyn.floor is not None:
        model = MODEL_FLOOR
    else:
        model = MODEL_PLANAR
    sp = plan.speed
    return RunParams(
        m=p.m, m0=p.m0, mw=p.mw, Jw=p.Jw, J0=p.J0, J=p.J, R=p.R, l0=p.l0, h0=p.h0, g=p.g, model=model,
        h_mean=float(dyn.h_mean), h_amp=float(dyn.h_amp), h_w=float(dyn.h_w),
        sin_a=dyn.sin_a, cos_a=dyn.cos_a, tilt_gain=float(dyn.tilt_gain),
        c_rr=float(dyn.c_rr), normal_force=float(dyn.normal_force), c_v=float(dyn.c_v), c_wb=float(dyn.c_wb),
        k_aero=float(dyn.k_aero),
        euc_kp=float(euc.k_p), euc_kd=float(euc.k_d), euc_kv=float(euc.k_v),
        rider_kp=float(rider.k_p), rider_kd=float(rider.k_d), rider_kspeed=float(rider.k_speed),
        rider_kint=float(rider.k_int), rider_cff=float(rider.c_ff), rider_mgh=float(rider.mgh),
        psi0=float(plan.path.psi0), path_amp=float(plan.path.amplitude), path_len=float(plan.path.length),
        path_phase=float(plan.path.phase),
        v0=float(sp.v0), v1=float(sp.v1), t1=float(sp.t1), ramp_s=float(sp.ramp_s),
        slow_in_turns=float(sp.slow_in_turns), kappa_max=float(sp.kappa_max),
        pedal_k=float(dyn.pedal_k or 0.0), pedal_c=float(dyn.pedal_c or 0.0),
        has_arms=arms is not None, arm_amp=float(arms.amp) if arms else 0.0, arm_w=float(arms.w) if arms else 0.0,
        arm_phase=float(arms.p0) if arms else 0.0,
        sway=sinusoids(plan.sway), wobble=sinusoids(plan.tilt_wobble), floor=floor, external=external,
        arm_x=arm_x, arm_c=arm_c)


# --- pieces of the right-hand side (each mirrors the numpy function named in its docstring) -----------------
@_jit
def _sinusoids(tab, t):
    """:class:`~euc_ros.core.ridesim.maneuvers.Sinusoids` at time t."""
    s = 0.0
    for k in range(tab.shape[0]):
        s += tab[k, 0] * math.sin(2 * math.pi * tab[k, 1] * t + tab[k, 2])
    return s


@_jit
def _smooth_step(u):
    """:func:`~euc_ros.core.ridesim.maneuvers.smooth_step` and its derivative."""
    if u <= 0.0 or u >= 1.0:
        return (1.0 if u >= 1.0 else 0.0), 0.0
    fa, fb = math.exp(-1.0 / u), math.exp(-1.0 / (1.0 - u))
    den = fa + fb
    return fa / den, (fa / u**2 * fb + fa * fb / (1.0 - u) ** 2) / den**2


@_jit
def _speed_reference(p, t, kappa, dkappa, xd):
    """:meth:`~euc_ros.core.ridesim.maneuvers.SpeedProfile.reference`: ``(v_ref, a_ref)``."""
    if p.v1 == p.v0:
        v, a = p.v0, 0.0
    else:
        step, dstep = _smooth_step((t - p.t1) / p.ramp_s)
        v = p.v0 + (p.v1 - p.v0) * step
        a = (p.v1 - p.v0) * dstep / p.ramp_s
    if p.slow_in_turns != 0.0:
        r = kappa / p.kappa_max
        v = v - p.slow_in_turns * r * r
        a = a - p.slow_in_turns * 2 * r * dkappa / p.kappa_max * xd
    return v, a


@_jit
def _sigmoid(u):
    return 0.5 * (1.0 + math.tanh(0.5 * u))


@_jit
def _floor_slope(p, X, psi, kappa):
    """:meth:`~euc_ros.core.ridesim.floors.FloorProfile.slope_along`: ``(a, da/ds)``."""
    dz = 0.0
    ddz = 0.0
    for k in range(p.floor.shape[0]):
        code, q0, x0, w = p.floor[k, 0], p.floor[k, 1], p.floor[k, 2], p.floor[k, 3]
        if code == FLOOR_RAMP:
            dz += q0
        elif code == FLOOR_RAMP_FROM:
            s = _sigmoid((X - x0) / w)
            dz += q0 * s
            ddz += q0 * s * (1 - s) / w
        elif code == FLOOR_BUMP:
            u = (X - x0) / w
            e = math.exp(-0.5 * u * u)
            dz += -q0 * u * e / w
            ddz += q0 * (u * u - 1) * e / (w * w)
        else:
            s = _sigmoid((X - x0) / w)
            dz += q0 * s * (1 - s) / w
            ddz += q0 * s * (1 - s) * (1 - 2 * s) / (w * w)
    c, s = math.cos(psi), math.sin(psi)
    a = math.atan(dz * c)
    ca = math.cos(a)
    return a, ca * ca * (ddz * c * c * ca - dz * s * kappa)


@_jit
def _external(p, x, gam, phi, xd, gd, pd, h, X, psi):
    """Sum of :meth:`~euc_ros.core.ridesim.external.ExternalForce.generalized` over the run's forces."""
    q0 = q1 = q2 = 0.0
    R, l0 = p.R, p.l0
    for k in range(p.external.shape[0]):
        code, a, b, c = p.external[k, 0], p.external[k, 1], p.external[k, 2], p.external[k, 3]
        if code == EXT_TORQUE_RIPPLE:
            tau = a * math.sin(b * x / R)
            q0 += tau / R
            q1 += -tau
        elif code == EXT_ROPE:
            off = -l0 * math.sin(gam) + c * math.sin(phi)
            hand_x = X + off * math.cos(psi)
            F = -a * (hand_x - b) * math.cos(psi)
            q0 += F
            q1 += -l0 * math.cos(gam) * F
            q2 += c * math.cos(phi) * F
        elif code == EXT_CONTACT_DRAG:
            q0 += -a * xd * abs(xd)
        elif code == EXT_LAB_BUMP:
            u = (X - b) / c
            F = a * math.exp(-0.5 * u * u) * math.cos(psi)
            q0 += F
            q1 += -l0 * math.cos(gam) * F
            q2 += h * math.cos(phi) * F
        elif code == EXT_WHEEL_HARMONICS:
            q0 += a * math.sin(2.0 * x / R) + b * math.sin(3.0 * x / R + c)
        else:
            w = -a * math.cos(psi)
            vx = xd - l0 * math.cos(gam) * gd + h * math.cos(phi) * pd - w
            vz = l0 * math.sin(gam) * gd - h * math.sin(phi) * pd
            kk = 0.5 * EXTERNAL_AIR_DENSITY * b
            speed = math.sqrt(vx * vx + vz * vz)
            Fx, Fz = -kk * speed * vx, -kk * speed * vz
            q0 += Fx
            q1 += -l0 * math.cos(gam) * Fx + l0 * math.sin(gam) * Fz
            q2 += h * math.cos(phi) * Fx - h * math.sin(phi) * Fz
    return q0, q1, q2


@_jit
def _spline(c, j, i, dx):
    """Cubic j of the tables c on interval i at offset dx (scipy's PPoly coefficients, highest power first)."""
    return ((c[j, 0, i] * dx + c[j, 1, i]) * dx + c[j, 2, i]) * dx + c[j, 3, i]


@_jit
def _arms(p, t):
    """:meth:`~euc_ros.core.ridesim.rider_motion.ArmKinematics.profile` at time t.

    Returns ``(h, h_dot, h_ddot, dJ, dJ_dot, H_dot)``.
    """
    arg = p.arm_w * t + p.arm_phase
    th = p.arm_amp * math.sin(arg)
    thd = p.arm_amp * p.arm_w * math.cos(arg)
    thdd = -p.arm_amp * p.arm_w * p.arm_w * math.sin(arg)
    x, c = p.arm_x, p.arm_c
    lo, hi = 0, x.shape[0] - 2          # the interval i with x[i] <= th < x[i + 1], clamped to the grid
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if x[mid] <= th:
            lo = mid
        else:
            hi = mid - 1
    i = lo
    dx = th - x[i]
    h, h1, h2 = _spline(c, 0, i, dx), _spline(c, 1, i, dx), _spline(c, 2, i, dx)
    dJ, J1, K, P = _spline(c, 4, i, dx), _spline(c, 5, i, dx), _spline(c, 6, i, dx), _spline(c, 7, i, dx)
    return h, h1 * thd, h2 * thd**2 + h1 * thdd, dJ, J1 * thd, P * thd**2 + K * thdd


#: :func:`~euc_ros.core.ridesim.truth_model.solve3` compiled (Cramer's rule, symmetric 3x3).
_solve3 = _jit(solve3)


@_jit
def _solve4(e, r):
    """Solve the 4x4 system with row-major entries e (16) by Gaussian elimination with partial pivoting."""
    a = np.empty((4, 5))
    for i in range(4):
        for j in range(4):
            a[i, j] = e[4 * i + j]
        a[i, 4] = r[i]
    for k in range(4):
        piv = k
        for i in range(k + 1, 4):
            if abs(a[i, k]) > abs(a[piv, k]):
                piv = i
        if piv != k:
            for j in range(5):
                a[k, j], a[piv, j] = a[piv, j], a[k, j]
        for i in range(k + 1, 4):
            f = a[i, k] / a[k, k]
            for j in range(k, 5):
                a[i, j] -= f * a[k, j]
    x = np.empty(4)
    for i in range(3, -1, -1):
        s = a[i, 4]
        for j in range(i + 1, 4):
            s -= a[i, j] * x[j]
        x[i] = s / a[i, i]
    return x


@_jit
def rhs(t, y, dy, p):
    """:meth:`~euc_ros.core.ridesim.simulate._RunDynamics.rhs` compiled: write d/dt of the state into ``dy``.

    The state is :data:`~euc_ros.core.ridesim.simulate.STATE_NAMES`, then u, u_dot with pedals.
    """
    x, gam, phi, xd, gd, pd = y[0], y[1], y[2], y[3], y[4], y[5]
    # rider CoG height h(t)
    dJ = dJ_dot = H_dot = 0.0
    if p.has_arms:
        h, hd, hdd, dJ, dJ_dot, H_dot = _arms(p, t)
    elif p.h_w != 0.0:
        s, c = math.sin(p.h_w * t), math.cos(p.h_w * t)
        h, hd, hdd = p.h_mean + p.h_amp * s, p.h_amp * p.h_w * c, -p.h_amp * p.h_w * p.h_w * s
    else:
        h, hd, hdd = p.h_mean, 0.0, 0.0
    # environment: path, tilt, gravity
    k = 2 * np.pi / p.path_len
    kappa = p.path_amp * k * math.cos(k * x + p.path_phase)
    dkappa = -p.path_amp * k * k * math.sin(k * x + p.path_phase)
    psi = p.psi0 + p.path_amp * math.sin(2 * np.pi * x / p.path_len + p.path_phase)
    a_c = kappa * xd * xd
    theta = -math.atan(kappa * xd * xd / p.g) + _sinusoids(p.wobble, t)
    g_n = p.g * p.cos_a
    if p.tilt_gain != 0.0:
        g_n = g_n + p.tilt_gain * (g_n * math.cos(theta) - a_c * math.sin(theta) - g_n)
    g_x = -p.g * p.sin_a * math.cos(psi)
    g_z = -g_n
    # inputs
    v_ref, a_ref = _speed_reference(p, t, kappa, dkappa, xd)
    phi_des = (math.atan(p.rider_cff * a_ref) + p.rider_kspeed * (v_ref - xd) + p.rider_kint * y[8]
               + _sinusoids(p.sway, t))
    M_d = p.euc_kp * gam + p.euc_kd * gd + p.euc_kv * xd
    M_h = p.rider_mgh * math.sin(phi) + p.rider_kp * (phi - phi_des) + p.rider_kd * pd
    # non-conservative effects
    F_c = -p.c_rr * p.normal_force * math.tanh(xd / ROLLING_SIGN_SPEED) - p.c_v * xd
    tau_wb = -p.c_wb * (xd / p.R - gd)
    qa0 = qa1 = qa2 = 0.0
    if p.k_aero != 0.0:
        j = _planar_jac_g(gam, phi, h, p.m, p.m0, p.mw, p.Jw, p.J0, p.J, p.R, p.l0, p.h0)
        vx, vz = _planar_vel_g(gam, phi, xd, gd, pd, h, hd, p.m, p.m0, p.mw, p.Jw, p.J0, p.J, p.R, p.l0, p.h0)
        speed = math.sqrt(vx * vx + vz * vz)
        Fx, Fz = -p.k_aero * speed * vx, -p.k_aero * speed * vz
        qa0, qa1, qa2 = j[0] * Fx + j[3] * Fz, j[1] * Fx + j[4] * Fz, j[2] * Fx + j[5] * Fz
    dQ0, dQ1, dQ2 = F_c + tau_wb / p.R + qa0, -tau_wb + qa1, qa2
    if p.external.shape[0]:
        e0, e1, e2 = _external(p, x, gam, phi, xd, gd, pd, h, y[6], psi)
        dQ0, dQ1, dQ2 = dQ0 + e0, dQ1 + e1, dQ2 + e2
    Q0 = M_d / p.R + dQ0
    Q1 = M_h - M_d + dQ1
    Q2 = -M_h + dQ2
    dy[0], dy[1], dy[2] = xd, gd, pd
    dy[8] = v_ref - xd
    if p.model == MODEL_PEDAL:
        u, ud = y[10], y[11]
        e4 = _pedal_mass(gam, phi, u, h, p.m, p.m0, p.mw, p.Jw, p.J0, p.J, p.R, p.l0, p.h0)
        b4 = _pedal_bias(gam, phi, u, xd, gd, pd, ud, h, hd, hdd, g_x, g_z, p.m, p.m0, p.mw, p.Jw, p.J0, p.J, p.R,
                         p.l0, p.h0)
        a = _solve4(e4, (Q0 - b4[0], Q1 - b4[1], Q2 - b4[2], -p.pedal_k * u - p.pedal_c * ud - b4[3]))
        dy[3], dy[4], dy[5] = a[0], a[1], a[2]
        dy[6], dy[7], dy[9] = xd * math.cos(psi), xd * math.sin(psi), 0.0
        dy[10], dy[11] = ud, a[3]
    elif p.model == MODEL_FLOOR:
        fa, fa1 = _floor_slope(p, y[6], psi, kappa)
        ef = _floor_mass(gam, phi, h, fa, p.m, p.m0, p.mw, p.Jw, p.J0, p.J, p.R, p.l0, p.h0)
        bf = _floor_bias(gam, phi, xd, gd, pd, h, hd, hdd, g_x, g_z, fa, fa1, p.m, p.m0, p.mw, p.Jw, p.J0, p.J, p.R,
                         p.l0, p.h0)
        dy[3], dy[4], dy[5] = _solve3(ef[0], ef[1], ef[2], ef[3], ef[4], ef[5], Q0 - bf[0], Q1 - bf[1], Q2 - bf[2])
        vh = xd * math.cos(fa)
        dy[6], dy[7], dy[9] = vh * math.cos(psi), vh * math.sin(psi), xd * math.sin(fa)
    else:
        Q2 = Q2 - dJ_dot * pd - H_dot
        e = _planar_mass(gam, phi, h, p.m, p.m0, p.mw, p.Jw, p.J0, p.J, p.R, p.l0, p.h0)
        b = _planar_bias(gam, phi, xd, gd, pd, h, hd, hdd, g_x, g_z, p.m, p.m0, p.mw, p.Jw, p.J0, p.J, p.R, p.l0,
                         p.h0)
        dy[3], dy[4], dy[5] = _solve3(e[0], e[1], e[2], e[3], e[4], e[5] + dJ, Q0 - b[0], Q1 - b[1], Q2 - b[2])
        dy[6], dy[7], dy[9] = xd * math.cos(psi), xd * math.sin(psi), 0.0


@_jit
def rhs_value(t, y, p):
    """The right-hand side at (t, y) as a new array (for Python callers such as the initial-state solve)."""
    dy = np.empty_like(y)
    rhs(t, y, dy, p)
    return dy


# --- DOP853 (scipy.integrate.solve_ivp's algorithm and coefficients) ---------------------------------------------
_N_STAGES = _dop.N_STAGES
_A = np.ascontiguousarray(_dop.A)
_B = np.ascontiguousarray(_dop.B)
_C = np.ascontiguousarray(_dop.C)
_E3 = np.ascontiguousarray(_dop.E3)
_E5 = np.ascontiguousarray(_dop.E5)
_D = np.ascontiguousarray(_dop.D)
_N_EXT = _dop.N_STAGES_EXTENDED
_N_INTERP = _dop.INTERPOLATOR_POWER
_SAFETY, _MIN_FACTOR, _MAX_FACTOR = 0.9, 0.2, 10.0
_ERROR_EXPONENT = -1.0 / (7 + 1)

#: Integration outcomes.
STATUS_OK, STATUS_STEP_TOO_SMALL = 0, -1


@_jit
def _rms(v):
    return math.sqrt(np.sum(v * v) / v.size)


@_jit
def _initial_step(t0, y0, f0, t_bound, rtol, atol, p):
    """The ``select_initial_step`` of scipy (Hairer, Norsett, Wanner, Sec. II.4) for error order 7."""
    interval = abs(t_bound - t0)
    if interval == 0.0:
        return 0.0
    scale = atol + np.abs(y0) * rtol
    d0, d1 = _rms(y0 / scale), _rms(f0 / scale)
    h0 = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
    h0 = min(h0, interval)
    f1 = np.empty_like(y0)
    rhs(t0 + h0, y0 + h0 * f0, f1, p)
    d2 = _rms((f1 - f0) / scale) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / 8.0)
    return min(100 * h0, h1, interval)


@_jit
def _stage(t, y, h, K, s, ys, p):
    """Stage ``s`` of the step ``h`` from ``(t, y)``: its state into ``ys``, its slope into ``K[s]``."""
    for i in range(y.size):
        acc = 0.0
        for r in range(s):
            acc += K[r, i] * _A[s, r]
        ys[i] = y[i] + acc * h
    rhs(t + _C[s] * h, ys, K[s], p)


@_jit
def dop853(t0, t_bound, y0, rtol, atol, p):
    """Integrate from t0 to t_bound with dense output.

    Returns
    -------
    ts : ndarray (s + 1,)
        Step boundaries.
    ys : ndarray (s + 1, n)
        States at the step boundaries.
    F : ndarray (s, 7, n)
        Coefficients of each step's interpolant (scipy's ``Dop853DenseOutput``).
    nfev : int
        Evaluations of the right-hand side (counted as ``solve_ivp`` counts them).
    status : int
        :data:`STATUS_OK` or :data:`STATUS_STEP_TOO_SMALL`.
    """
    n = y0.size
    cap = 256
    ts = np.empty(cap + 1)
    Y = np.empty((cap + 1, n))
    F = np.empty((cap, _N_INTERP, n))
    K = np.empty((_N_EXT, n))
    t, y = t0, y0.copy()
    f = np.empty(n)
    rhs(t, y, f, p)
    h_abs = _initial_step(t, y, f, t_bound, rtol, atol, p)
    nfev = 2
    ts[0] = t
    Y[0] = y
    steps = 0
    ys = np.empty(n)
    y_new = np.empty(n)
    f_new = np.empty(n)
    while t < t_bound:
        min_step = 10 * abs(np.nextafter(t, np.inf) - t)
        if h_abs < min_step:
            h_abs = min_step
        accepted = rejected = False
        h = 0.0
        while not accepted:
            if h_abs < min_step:
                return ts[:steps + 1], Y[:steps + 1], F[:steps], nfev, STATUS_STEP_TOO_SMALL
            t_new = t + h_abs
            if t_new - t_bound > 0:
                t_new = t_bound
            h = t_new - t
            h_abs = abs(h)
            # Runge-Kutta stages
            K[0] = f
            for s in range(1, _N_STAGES):
                _stage(t, y, h, K, s, ys, p)
            for i in range(n):
                acc = 0.0
                for r in range(_N_STAGES):
                    acc += K[r, i] * _B[r]
                y_new[i] = y[i] + h * acc
            rhs(t + h, y_new, f_new, p)
            K[_N_STAGES] = f_new
            nfev += _N_STAGES
            # error norm of the embedded 5th- and 3rd-order estimates
            e5 = 0.0
            e3 = 0.0
            for i in range(n):
                sc = atol + max(abs(y[i]), abs(y_new[i])) * rtol
                a5 = 0.0
                a3 = 0.0
                for r in range(_N_STAGES + 1):
                    a5 += K[r, i] * _E5[r]
                    a3 += K[r, i] * _E3[r]
                e5 += (a5 / sc) ** 2
                e3 += (a3 / sc) ** 2
            if e5 == 0 and e3 == 0:
                err = 0.0
            else:
                err = abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * n)
            if err < 1:
                factor = _MAX_FACTOR if err == 0 else min(_MAX_FACTOR, _SAFETY * err ** _ERROR_EXPONENT)
                if rejected:
                    factor = min(1.0, factor)
                h_abs *= factor
                accepted = True
            else:
                h_abs *= max(_MIN_FACTOR, _SAFETY * err ** _ERROR_EXPONENT)
                rejected = True
        # dense output: three extra stages and the interpolant of the step
        for s in range(_N_STAGES + 1, _N_EXT):
            _stage(t, y, h, K, s, ys, p)
        nfev += _N_EXT - _N_STAGES - 1
        if steps == cap:
            cap *= 2
            ts2, Y2, F2 = np.empty(cap + 1), np.empty((cap + 1, n)), np.empty((cap, _N_INTERP, n))
            ts2[:steps + 1], Y2[:steps + 1], F2[:steps] = ts[:steps + 1], Y[:steps + 1], F[:steps]
            ts, Y, F = ts2, Y2, F2
        for i in range(n):
            dyi = y_new[i] - y[i]
            F[steps, 0, i] = dyi
            F[steps, 1, i] = h * K[0, i] - dyi
            F[steps, 2, i] = 2 * dyi - h * (f_new[i] + K[0, i])
            for r in range(_N_INTERP - 3):
                acc = 0.0
                for c in range(_N_EXT):
                    acc += _D[r, c] * K[c, i]
                F[steps, 3 + r, i] = h * acc
        steps += 1
        ts[steps] = t_new
        Y[steps] = y_new
        t = t_new
        y[:] = y_new
        f[:] = f_new
    return ts[:steps + 1], Y[:steps + 1], F[:steps], nfev, STATUS_OK


@_jit
def dense(ts, ys, F, t):
    """The dense solution at times t (any order) as (n_times, n_states).

    As scipy's ``OdeSolution`` with ``Dop853DenseOutput`` (at a step boundary, the earlier step).
    """
    nseg, n = F.shape[0], ys.shape[1]
    out = np.empty((t.size, n))
    for j in range(t.size):
        seg = np.searchsorted(ts, t[j], side="left") - 1
        seg = min(max(seg, 0), nseg - 1)
        x = (t[j] - ts[seg]) / (ts[seg + 1] - ts[seg])
        for i in range(n):
            v = 0.0
            for r in range(_N_INTERP):
                v += F[seg, _N_INTERP - 1 - r, i]
                v *= x if r % 2 == 0 else 1 - x
            out[j, i] = v + ys[seg, i]
    return out


class CompiledSolution:
    """Dense solution of one run (the part of ``solve_ivp``'s result the simulator uses).

    Parameters
    ----------
    ts : numpy.ndarray
        Step boundaries (steps + 1,) [s].
    ys : numpy.ndarray
        States at the boundaries (steps + 1, n_states).
    F : numpy.ndarray
        Stage derivatives of each step, for the dense output (:func:`dense`).
    nfev : int
        Right-hand-side evaluations.
    status : int
        The integrator's status (``STATUS_OK``: reached the end).
    """

    def __init__(self, ts, ys, F, nfev: int, status: int) -> None:
        self.ts, self.ys, self.F = ts, ys, F
        self.nfev = int(nfev)
        self.success = status == STATUS_OK
        self.message = "ok" if self.success else "the step size fell below 10 ulp of t"

    @property
    def t(self) -> np.ndarray:
        """Step boundaries (steps + 1,) [s]."""
        return self.ts

    @property
    def y(self) -> np.ndarray:
        """States at the step boundaries (n_states, steps + 1)."""
        return self.ys.T

    def sol(self, t) -> np.ndarray:
        """States (n_states, n_times) at times t, like ``solve_ivp(...).sol``.

        Parameters
        ----------
        t : float or array_like
            Times [s] within the solved span.

        Returns
        -------
        numpy.ndarray
            States (n_states, n_times).
        """
        return dense(self.ts, self.ys, self.F, np.ascontiguousarray(np.atleast_1d(t), float)).T


def integrate(params: RunParams, t0: float, t_end: float, y0, rtol: float, atol: float) -> CompiledSolution:
    """Integrate one run with :func:`dop853`.

    Parameters
    ----------
    params : RunParams
        The run, from :func:`pack`.
    t0, t_end : float
        Start and end time [s].
    y0 : array_like (n_states,)
        State at t0 (:data:`~euc_ros.core.ridesim.simulate.STATE_NAMES`, then u, u_dot with pedals).
    rtol, atol : float
        DOP853's tolerances: each step's local error estimate stays below ``atol + rtol |y|`` (RMS norm).

    Returns
    -------
    CompiledSolution
        Step boundaries, states there, dense output, ``nfev`` and ``success``.
    """
    ts, ys, F, nfev, status = dop853(float(t0), float(t_end), np.ascontiguousarray(y0, float), float(rtol),
                                        float(atol), params)
    return CompiledSolution(ts, ys, F, nfev, status)
