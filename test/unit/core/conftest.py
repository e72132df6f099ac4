"""Shared fixtures of the core tests: the short ride's Motive export with either up axis (``up_axis_csvs``),
and the EUC model's independent derivation (``symbolic``) with rides and mocap built from it (``synth``).

``symbolic`` is an independent derivation of the 3-DoF model with sympy: the kinetic energy is built
from the point kinematics of the geometry (C, A, G0, G, rolling wheel) rather than typed from the
paper, the generalized forces from the virtual power of gravity and the two internal torques, then
Lagrange's equations of the second kind (4) are solved for the unknown torques. It imports none of
the closed forms under test.
"""
from __future__ import annotations

import shutil
from types import SimpleNamespace

import numpy as np
import pytest
import sympy as sp

from euc_ros.core.io.motive_csv import read_motive_csv, write_motive_csv


@pytest.fixture(scope="module")
def up_axis_csvs(short_ride, tmp_path_factory):
    """``{"y": path, "z": path}``: the simulated Y-up CSV (Motive's default) and a Z-up export of the same
    frames, in a folder of the test module's own."""
    src, _ = short_ride
    d = tmp_path_factory.mktemp("up_axis")
    yup = d / "ride_yup.csv"
    shutil.copy(src / "deceleration_01.csv", yup)
    return {"y": yup, "z": write_motive_csv(read_motive_csv(yup, world_up="y"), d / "ride_zup.csv", world_up="z")}


PARAM_NAMES = ("m", "J", "m0", "J0", "mw", "Jw", "R", "h0", "l0", "g", "h")


def _derive():
    t = sp.symbols("t")
    m, J, m0, J0, mw, Jw, R, h0, l0, g, h = sp.symbols(PARAM_NAMES, real=True)
    Md, Mh = sp.symbols("M_d M_h", real=True)
    x, gam, ph = (sp.Function(n)(t) for n in ("x", "gamma", "phi"))
    q = [x, gam, ph]
    qd = [c.diff(t) for c in q]
    # Geometry (ERRATA): C = (x, R); A below C along the body axis; G0 above C; G above A.
    C = sp.Matrix([x, R])
    A = C + l0 * sp.Matrix([-sp.sin(gam), -sp.cos(gam)])
    G0 = C + h0 * sp.Matrix([sp.sin(gam), sp.cos(gam)])
    G = A + h * sp.Matrix([sp.sin(ph), sp.cos(ph)])
    vC, vG0, vG = C.diff(t), G0.diff(t), G.diff(t)
    beta_dot = qd[0] / R  # rolling without slip: wheel pitch rate
    T = (sp.Rational(1, 2) * mw * vC.dot(vC) + sp.Rational(1, 2) * Jw * beta_dot**2
         + sp.Rational(1, 2) * m0 * vG0.dot(vG0) + sp.Rational(1, 2) * J0 * qd[1] ** 2
         + sp.Rational(1, 2) * m * vG.dot(vG) + sp.Rational(1, 2) * J * qd[2] ** 2)
    # Power of the active forces: gravity on G and G0; M_d on the wheel (+) and body (-);
    # M_h on the body (+) and rider (-). Contact forces do no work (pure rolling).
    P = (-m * g * vG[1] - m0 * g * vG0[1] + Md * (beta_dot - qd[1]) + Mh * (qd[1] - qd[2]))
    Q = [sp.expand(P).coeff(v) for v in qd]
    eqs = [sp.diff(T.diff(qd[i]), t) - T.diff(q[i]) - Q[i] for i in range(3)]
    xdd, gdd, pdd, xd, gd, pd_ = sp.symbols("xdd gdd pdd xd gd pd", real=True)
    gs, ps, xs = sp.symbols("gs ps xs", real=True)
    subs = {c.diff(t, 2): s for c, s in zip(q, (xdd, gdd, pdd))}
    subs2 = {c.diff(t): s for c, s in zip(q, (xd, gd, pd_))}
    subs3 = {x: xs, gam: gs, ph: ps}
    eqs = [sp.expand(e.subs(subs).subs(subs2).subs(subs3)) for e in eqs]
    T_s = sp.expand(T.subs(subs2).subs(subs3))
    # The equations are linear in the unknowns: solve them as linear systems (Cramer, unsimplified).
    # Eq (9): first row alone.
    A1, b1 = sp.linear_eq_to_matrix([eqs[0]], [Md])
    Md1 = b1[0] / A1[0, 0]
    # Eq (10): all three rows, eliminating x_ddot.
    A3, b3 = sp.linear_eq_to_matrix(eqs, [xdd, Md, Mh])
    det = A3.det(method="berkowitz")
    sol = {}
    for j, unknown in enumerate((xdd, Md, Mh)):
        Aj = A3.copy()
        Aj[:, j] = b3
        sol[unknown] = Aj.det(method="berkowitz") / det
    Md2 = sol[Md]
    # Rider torque with x_ddot measured (rows 1 and 3).
    A13, b13 = sp.linear_eq_to_matrix([eqs[0], eqs[2]], [Md, Mh])
    Mh_meas = A13.LUsolve(b13)[1]
    params = sp.symbols(PARAM_NAMES, real=True)
    args = (gs, ps, gd, pd_, xdd, gdd, pdd) + tuple(params)
    f_Md1 = sp.lambdify(args, Md1, "numpy")
    f_Md2 = sp.lambdify(args, Md2, "numpy")
    f_Mh = sp.lambdify(args, Mh_meas, "numpy")
    # The acceleration the model needs for a given pitch motion (from the same elimination).
    f_xdd = sp.lambdify((gs, ps, gd, pd_, gdd, pdd) + tuple(params), sol[xdd], "numpy")
    # Kinetic energy as printed in the paper (A.1), to compare with the one derived from geometry.
    T_A1 = (sp.Rational(1, 2) * (m + m0 + mw + Jw / R**2) * xd**2
            + sp.Rational(1, 2) * (J0 + m * l0**2 + m0 * h0**2) * gd**2
            + sp.Rational(1, 2) * (J + m * h**2) * pd_**2
            - (m * l0 - m0 * h0) * xd * gd * sp.cos(gs) + m * h * xd * pd_ * sp.cos(ps)
            - m * h * l0 * gd * pd_ * sp.cos(ps - gs))
    return SimpleNamespace(Md1=f_Md1, Md2=f_Md2, Mh=f_Mh, xdd=f_xdd, T_geometry=T_s, T_A1=T_A1,
                           eqs=eqs, params=params)


@pytest.fixture(scope="session")
def symbolic():
    """Lambdified torques from the independent sympy derivation (args: states then PARAM_NAMES)."""
    return _derive()


@pytest.fixture(scope="session")
def rng():
    return np.random.default_rng(20240502)


def rider_skeleton(session):
    """Pivots of a standing rider in the rider's lean frame, relative to the ankle hinge A [m].

    A plausible skeleton (x forward, y left, z up). The tests shift it along the lean axis so that
    the mass-weighted segment CoG lies exactly at (0, 0, h).
    """
    base = {"H": (0.0, 0.0, 1.72), "CHR": (0.0, -0.19, 1.42), "CHL": (0.0, 0.19, 1.42),
            "UAR": (0.05, -0.22, 1.1), "UAL": (0.05, 0.22, 1.1), "LAR": (0.2, -0.2, 0.9),
            "LAL": (0.2, 0.2, 0.9), "HR": (0.0, -0.1, 0.92), "HL": (0.0, 0.1, 0.92),
            "TR": (0.03, -0.1, 0.48), "TL": (0.03, 0.1, 0.48), "LR": (0.0, -0.1, 0.0), "LL": (0.0, 0.1, 0.0)}
    names, fractions, offsets = session.segment_arrays()
    piv = np.array([base[nm] for nm in names])
    cog = np.sum(fractions[:, None] * (piv + offsets), axis=0) / fractions.sum()
    return names, piv - cog  # CoG of the returned skeleton at the origin


def synthesize_mocap(session, *, t, C, psi, theta, gamma, phi, h, rng=None, pos_noise=0.0, rot_noise=0.0,
                     name="synthetic"):
    """Build a Z-up MocapSeries from a planar motion placed on a heading (independent construction).

    E and every segment get the orientations the conventions prescribe: R_E = Rz(psi) Rx(theta) Ry(gamma);
    the rider frame R_r = Rz(psi) Rx(theta) Ry(phi) about the hinge A = C - l0 R_E e_z, with all
    segments rigidly attached to it and their CoG at A + h R_r e_z.
    """
    from scipy.spatial.transform import Rotation

    from euc_ros.core.mocap.series import MocapSeries

    n = t.size
    rE = Rotation.from_euler("ZXY", np.column_stack([psi, theta, gamma]))
    rR = Rotation.from_euler("ZXY", np.column_stack([psi, theta, phi]))
    E = C - rE.apply(np.asarray(session.euc.pivot_to_wheel_center))
    A = C - session.euc.l0 * rE.apply([0.0, 0.0, 1.0])
    names, skel = rider_skeleton(session)
    bodies = [session.euc.body] + names
    pos = np.empty((len(bodies), n, 3))
    quat = np.empty((len(bodies), n, 4))
    pos[0], quat[0] = E, rE.as_quat()
    for k, p in enumerate(skel):
        pos[k + 1] = A + rR.apply(p + np.array([0.0, 0.0, h]))
        quat[k + 1] = rR.as_quat()
    if rng is not None and (pos_noise or rot_noise):
        pos = pos + rng.normal(0, pos_noise, pos.shape)
        for b in range(len(bodies)):
            noise = Rotation.from_rotvec(rng.normal(0, rot_noise, (n, 3)))
            quat[b] = (Rotation.from_quat(quat[b]) * noise).as_quat()
    tracked = np.ones((len(bodies), n), bool)
    return MocapSeries(t=t, frame=np.arange(n, dtype=np.int64), bodies=bodies, position=pos, quat=quat,
                       tracked=tracked, mean_marker_error=np.zeros((len(bodies), n)), name=name,
                       meta={"rate_hz": 1.0 / (t[1] - t[0])})


def planar_ride(symbolic, params, *, duration=12.0, rate=120.0, v0=3.0, seed=0, decel=0.0):
    """A trajectory consistent with the model: chosen pitch motions, x_ddot from the symbolic solution.

    phi(t) and gamma(t) are smooth sums of sines (plus a lean-back ramp when ``decel`` > 0); the
    longitudinal acceleration is the one the (independently derived) equations require, integrated
    with solve_ivp. Returns a dict of exact states sampled at ``rate``.
    """
    from scipy.integrate import solve_ivp

    r = np.random.default_rng(seed)
    amp_p, amp_g = r.uniform(0.03, 0.06, 3), r.uniform(0.005, 0.015, 2)
    fr_p, fr_g = r.uniform(0.3, 1.2, 3), r.uniform(0.4, 1.5, 2)
    ph_p, ph_g = r.uniform(0, 2 * np.pi, 3), r.uniform(0, 2 * np.pi, 2)

    def angles(tt):
        tt = np.asarray(tt, float)
        w_p, w_g = 2 * np.pi * fr_p, 2 * np.pi * fr_g
        arg_p = w_p[:, None] * tt + ph_p[:, None]
        arg_g = w_g[:, None] * tt + ph_g[:, None]
        phi = (amp_p[:, None] * np.sin(arg_p)).sum(0) - decel * (1 - np.cos(np.pi * tt / duration)) / 2
        k = np.pi / duration
        phid = (amp_p[:, None] * w_p[:, None] * np.cos(arg_p)).sum(0) - decel * k * np.sin(k * tt) / 2
        phidd = (-amp_p[:, None] * w_p[:, None] ** 2 * np.sin(arg_p)).sum(0) - decel * k**2 * np.cos(k * tt) / 2
        gam = (amp_g[:, None] * np.sin(arg_g)).sum(0)
        gamd = (amp_g[:, None] * w_g[:, None] * np.cos(arg_g)).sum(0)
        gamdd = (-amp_g[:, None] * w_g[:, None] ** 2 * np.sin(arg_g)).sum(0)
        return gam, phi, gamd, phid, gamdd, phidd

    pv = [getattr(params, k) for k in PARAM_NAMES]

    def xdd(tt):
        g_, p_, gd_, pd_, gdd_, pdd_ = angles(tt)
        return symbolic.xdd(g_, p_, gd_, pd_, gdd_, pdd_, *pv)

    t = np.arange(int(round(duration * rate))) / rate
    sol = solve_ivp(lambda tt, y: [y[1], float(np.squeeze(xdd(np.atleast_1d(tt))))], (0, t[-1]), [0.0, v0],
                    t_eval=t, rtol=1e-11, atol=1e-12, method="DOP853")
    g_, p_, gd_, pd_, gdd_, pdd_ = angles(t)
    return dict(t=t, x=sol.y[0], x_dot=sol.y[1], x_ddot=xdd(t), gamma=g_, phi=p_, gamma_dot=gd_, phi_dot=pd_,
                gamma_ddot=gdd_, phi_ddot=pdd_)


@pytest.fixture(scope="session")
def synth():
    """Helpers that build model-consistent rides and mocap from them (see the functions above)."""
    return SimpleNamespace(planar_ride=planar_ride, synthesize_mocap=synthesize_mocap, rider_skeleton=rider_skeleton,
                           PARAM_NAMES=PARAM_NAMES)
