"""A ride from a seed: draw the rider, the EUC, the controllers and the excitation, integrate, record the truth.

Everything random comes from one ``numpy.random.Generator`` seeded by the caller, so a seed gives
the same ride on every machine (up to the floating-point reproducibility of numpy and scipy).
"""
from __future__ import annotations

import dataclasses
import math
from bisect import bisect_right
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from scipy.integrate import solve_ivp

from euc_ros.core.errors import ConfigError
from euc_ros.core.worldsim import body as B
from euc_ros.core.worldsim import control as K
from euc_ros.core.worldsim.dynamics import PlantParams, energy, solve, solve_one, torque_power
from euc_ros.core.worldsim.excitation import (
    BAND_LIMITS_HZ,
    PROFILE_KINDS,
    BandNoise,
    SpeedProfile,
    band_noise,
    random_band,
    random_speed_profile,
)
from euc_ros.core.worldsim.forces import ForceLaw, residual_effect

#: Integrator state: coordinates, rates, the two torques (lagged) and the work of the torques. A ride with a
#: hidden force law (:mod:`.forces`) adds the law's work ``work_ext`` and the law's own states ``z0, z1``.
STATE = ("x", "gamma", "phi", "x_dot", "gamma_dot", "phi_dot", "M_d", "M_h", "work")
#: Frame rates the generator writes [Hz].
RATES_HZ = (100.0, 120.0, 240.0, 360.0)
#: Largest pitch angles a ride may reach before it counts as a fall [rad].
FALL_GAMMA, FALL_PHI = np.radians(25.0), np.radians(35.0)
#: Absolute tolerance scale per state (rtol times these): m, rad, rad, m/s, rad/s, rad/s, N m, N m, J.
ATOL_SCALE = np.array([1.0, 0.1, 0.1, 1.0, 1.0, 1.0, 10.0, 10.0, 10.0])
#: Absolute tolerance scale of the law's work [J] and of its states (inputs of order 1 m/s or rad/s).
ATOL_SCALE_WORK_EXT, ATOL_SCALE_LAW = 10.0, 1.0


@dataclass(frozen=True)
class RideSpec:
    """Everything a ride is made of (drawn by :func:`draw_spec`, or built by hand).

    Parameters
    ----------
    plant : PlantParams
        Masses, inertias and lengths (:func:`draw_spec` takes the rider's ``m``, ``J``, ``h`` from ``rider``).
    rider : RiderBody
        The rider's segments (the recording's rigid bodies).
    place : Placement
        Start point and heading in the lab, and the EUC's pivot.
    euc : EucLoop
        The EUC's balance loop.
    rider_loop : RiderLoop
        The rider's ankle-torque loop.
    profile : SpeedProfile
        The speed reference.
    dist_h, dist_d, dist_v : BandNoise
        Disturbances of the ankle torque [N m], of the motor torque [N m] and of the speed
        reference [m/s].
    duration : float
        Ride length [s].
    info : dict
        The draws (bands, frequencies, weights), for the truth file.
    force : ForceLaw, optional
        A hidden external force law (:mod:`.forces`); None for none.
    """

    plant: PlantParams
    rider: B.RiderBody
    place: B.Placement
    euc: K.EucLoop
    rider_loop: K.RiderLoop
    profile: SpeedProfile
    dist_h: BandNoise
    dist_d: BandNoise
    dist_v: BandNoise
    duration: float
    info: dict = field(default_factory=dict)
    force: ForceLaw | None = None

    @property
    def n_state(self) -> int:
        """Length of the integrator state: :data:`STATE`, plus ``work_ext`` and the law's states with a law."""
        return len(STATE) + (0 if self.force is None else 1 + self.force.n_states)

    def atol_scale(self) -> np.ndarray:
        """Absolute tolerance scale per integrator state.

        Returns
        -------
        numpy.ndarray (n_state,)
            :data:`ATOL_SCALE`, with a law also :data:`ATOL_SCALE_WORK_EXT` and :data:`ATOL_SCALE_LAW` per
            law state [the states' units].
        """
        if self.force is None:
            return ATOL_SCALE
        return np.concatenate([ATOL_SCALE, [ATOL_SCALE_WORK_EXT], np.full(self.force.n_states, ATOL_SCALE_LAW)])

    def inputs(self, t, y):
        """Commanded torques ``(M_d_cmd, M_h_cmd)`` [N m] at times ``t`` and states ``y`` (..., 9).

        Parameters
        ----------
        t : array_like (...)
            Times [s].
        y : array_like (..., 9)
            Integrator states on :data:`STATE` (entries after the ninth are not read).

        Returns
        -------
        tuple of numpy.ndarray (...)
            ``(M_d_cmd, M_h_cmd)`` [N m], the disturbances included.
        """
        y = np.asarray(y, dtype=float)
        v_ref = self.profile.speed(t) + self.dist_v(t)
        a_ref = self.profile.acceleration(t) + self.dist_v(t, deriv=1)
        md = self.euc.command(y[..., 1], y[..., 4], y[..., 3]) + self.dist_d(t)
        z = y[..., [1, 2, 3, 4, 5, 6, 7]]
        mh = self.rider_loop.command(z, v_ref, a_ref) + self.dist_h(t)
        return md, mh

    @cached_property
    def _scalar(self):
        """Tables of the one-state right-hand side: one sinusoid sum for all disturbances, plain floats."""
        parts = [(self.dist_h, 0), (self.dist_d, 1), (self.dist_v, 2)]
        w = np.concatenate([2 * np.pi * d.freqs for d, _ in parts])
        cos_c = np.zeros((w.size, 4))
        sin_c = np.zeros((w.size, 4))
        i = 0
        for d, col in parts:
            k = d.freqs.size
            cos_c[i:i + k, col] = d.a
            sin_c[i:i + k, col] = d.b
            if col == 2:                       # derivative of the speed disturbance
                cos_c[i:i + k, 3] = w[i:i + k] * d.b
                sin_c[i:i + k, 3] = -w[i:i + k] * d.a
            i += k
        prof = self.profile
        return {"w": w, "cos": cos_c, "sin": sin_c, "t0": prof.t0.tolist(), "t1": prof.t1.tolist(),
                "v0": prof.v0.tolist(), "v1": prof.v1.tolist(), "K": [float(k) for k in self.rider_loop.K],
                "steady": [float(s) for s in self.rider_loop.steady]}

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        """Right-hand side of the ride's ODE on :data:`STATE` (one state; :attr:`n_state` with a law).

        The same laws as :meth:`inputs`, in scalar arithmetic (tested equal): the integrator calls
        this some 10^5 times per ride. A hidden law adds its generalized force to the dynamics, its power
        ``Q . q_dot`` as the rate of ``work_ext``, and its states' rates.

        Parameters
        ----------
        t : float
            Time [s].
        y : numpy.ndarray (n_state,)
            The state.

        Returns
        -------
        numpy.ndarray (n_state,)
            ``dy/dt``.
        """
        c = self._scalar
        ph = c["w"] * t
        d_h, d_d, d_v, d_v1 = np.cos(ph) @ c["cos"] + np.sin(ph) @ c["sin"]
        i = max(bisect_right(c["t0"], t) - 1, 0)
        dur = c["t1"][i] - c["t0"][i]
        tau = min(max((t - c["t0"][i]) / dur, 0.0), 1.0)
        dv = c["v1"][i] - c["v0"][i]
        v_ref = c["v0"][i] + dv * (tau - math.sin(2 * math.pi * tau) / (2 * math.pi)) + d_v
        a_ref = dv / dur * (1.0 - math.cos(2 * math.pi * tau)) + d_v1
        x, gam, phi, xd, gd, pd, md, mh = (float(v) for v in y[:8])
        euc = self.euc
        md_cmd = euc.k_p * (gam - euc.pitch_reference_one(xd)) + euc.k_d * gd + d_d
        z = (gam, phi, xd, gd, pd, md, mh)
        st, K = c["steady"], c["K"]
        fb = sum(K[j] * (z[j] - st[j] * a_ref - (v_ref if j == 2 else 0.0)) for j in range(7))
        mh_cmd = a_ref * st[6] - fb + d_h
        p = self.plant
        law = self.force
        Q = None
        if law is not None:
            zl = [float(v) for v in y[10:]]
            F = law.value_one(t, x, xd, gd, pd, zl)
            j = law.point.jacobian_one(gam, phi, p)
            Q = (F * j[0], F * j[1], F * j[2])
        acc = solve_one((x, gam, phi), (xd, gd, pd), md, mh, p, Q)
        power = md * (xd / p.R - gd) + mh * (gd - pd)
        out = [xd, gd, pd, acc[0], acc[1], acc[2], (md_cmd - md) / euc.tau, (mh_cmd - mh) / self.rider_loop.tau, power]
        if law is not None:
            out.append(Q[0] * xd + Q[1] * gd + Q[2] * pd)
            out.extend(law.state_rates_one(xd, gd, pd, zl))
        return np.array(out)


def draw_spec(seed: int, *, duration: float = 30.0, kind: str = "mixed", euc_hz=(6.0, 15.0), euc_damping=(0.4, 1.0),
              v_max: float = 4.0, disturbance_scale: float = 1.0) -> RideSpec:
    """Draw a ride's rider, EUC, controllers and excitation from a seed.

    Parameters
    ----------
    seed : int
    duration : float
        Ride length [s].
    kind : str
        Speed-profile kind (:data:`~euc_ros.core.worldsim.excitation.PROFILE_KINDS`).
    euc_hz : (float, float)
        Range of the EUC balance loop's design pitch frequency [Hz] (log-uniform).
    euc_damping : (float, float)
        Range of its damping ratio.
    v_max : float
        Highest reference speed [m/s].
    disturbance_scale : float
        Multiplies every disturbance's rms (0 for none).

    Returns
    -------
    RideSpec

    Raises
    ------
    ConfigError
        An unknown ``kind`` or a ``duration`` not > 0 (keys ``kind``, ``duration``), or a draw whose
        linearized closed loop is unstable (key ``seed``).

    Notes
    -----
    Draws (uniform unless said): rider mass 55-95 kg and a posture (:meth:`Posture.draw`); wheel
    radius 0.18-0.25 m, wheel 2.5-5 kg, body 10-20 kg, their inertias, ``h_0`` 0.03-0.12 m,
    ``l_0`` 0.02-0.10 m; the EUC pitch mode (``euc_hz``, ``euc_damping``), motor lag 1-4 ms, a
    tilt-back 0.05-0.15 rad per m/s above 70-100 % of ``v_max``; the rider's design weights (pitch
    4-10 deg, lean 8-15 deg, speed error 0.5-1.5 m/s, rates 60-150 deg/s, torque 25-60 N m) and
    muscle lag 30-90 ms; the disturbances (:data:`DISTURBANCES`, rms times ``disturbance_scale``): 2-8 N m
    on the ankle torque and 0.5-3 N m on the motor torque, bands log-uniform within 0.1-3 Hz, and
    0.05-0.2 m/s on the speed reference, within :data:`SPEED_BAND_HZ`.
    """
    if kind not in PROFILE_KINDS:
        raise ConfigError(f"must be one of {PROFILE_KINDS}, got {kind!r}", key="kind")
    if not duration > 0:
        raise ConfigError(f"must be > 0 s, got {duration}", key="duration")
    rng = np.random.default_rng(seed)
    posture = B.Posture.draw(rng)
    rider = B.build_rider(posture, rng.uniform(55.0, 95.0))
    R = rng.uniform(0.18, 0.25)
    m_w = rng.uniform(2.5, 5.0)
    m_0 = rng.uniform(10.0, 20.0)
    plant = PlantParams(R=R, m_w=m_w, J_w=m_w * R**2 * rng.uniform(0.6, 0.9), m_0=m_0,
                        J_0=m_0 * rng.uniform(0.025, 0.05), h_0=rng.uniform(0.03, 0.12), l_0=rng.uniform(0.02, 0.10),
                        m=rider.mass, J=rider.J, h=rider.h)
    place = B.Placement(origin=rng.uniform(-3.0, 3.0, 2), heading=rng.uniform(-np.pi, np.pi),
                        euc_top=np.array([rng.uniform(-0.03, 0.03), 0.0, rng.uniform(0.25, 0.45)]))
    f_e = float(np.exp(rng.uniform(np.log(euc_hz[0]), np.log(euc_hz[1]))))
    zeta = rng.uniform(*euc_damping)
    euc = K.design_euc_loop(plant, f_e, zeta, rng.uniform(0.001, 0.004), v_limit=rng.uniform(0.7, 1.0) * v_max,
                            tilt_back=rng.uniform(0.05, 0.15))
    weights = dict(max_gamma=np.radians(rng.uniform(4, 10)), max_phi=np.radians(rng.uniform(8, 15)),
                   max_speed_error=rng.uniform(0.5, 1.5), max_rate=np.radians(rng.uniform(60, 150)),
                   max_torque=rng.uniform(25, 60))
    rider_loop = K.design_rider_loop(plant, euc, rng.uniform(0.03, 0.09), **weights)
    lam = np.linalg.eigvals(K.closed_loop_matrix(plant, euc, rider_loop))
    if not np.all(lam.real < 0):
        raise ConfigError(f"seed {seed}: the linearized closed loop is unstable (eigenvalues {lam})", key="seed")
    profile, dists, bands = _draw_excitation(rng, duration, kind, v_max, disturbance_scale)
    info = {"seed": int(seed), "kind": kind, "posture": {k: float(v) for k, v in vars(posture).items()},
            "euc_design_hz": f_e, "euc_damping": zeta, "closed_loop_eigenvalues": [[float(v.real), float(v.imag)]
                                                                                 for v in lam],
            "pitch_mode_hz": K.pitch_mode_hz(plant, euc, rider_loop), "disturbances": bands}
    return RideSpec(plant, rider, place, euc, rider_loop, profile, dists["dist_h"], dists["dist_d"],
                    dists["dist_v"], float(duration), info)


#: rms ranges and band limits of the disturbances :func:`draw_spec` draws: (name, rms range, band limits).
DISTURBANCES = (("dist_h", (2.0, 8.0), "band"), ("dist_d", (0.5, 3.0), "band"), ("dist_v", (0.05, 0.2), "speed"))


def _draw_excitation(rng: np.random.Generator, duration: float, kind: str, v_max: float,
                     disturbance_scale: float) -> tuple[SpeedProfile, dict, dict]:
    """A speed profile and the three disturbances, as :func:`draw_spec` draws them."""
    period = duration + 10.0
    profile = random_speed_profile(rng, duration, kind=kind, v_max=v_max)
    bands, dists = {}, {}
    for name, (lo, hi), which in DISTURBANCES:
        f_lo, f_hi = random_band(rng, BAND_LIMITS_HZ if which == "band" else SPEED_BAND_HZ)
        rms = disturbance_scale * rng.uniform(lo, hi)
        dists[name] = band_noise(rng, period, f_lo, f_hi, rms) if rms > 0 else BandNoise.zero()
        bands[name] = {"f_lo_hz": f_lo, "f_hi_hz": f_hi, "rms": rms}
    return profile, dists, bands


def another_run(spec: "RideSpec", seed: int, *, kind: str | None = None, v_max: float = 4.0,
                disturbance_scale: float = 1.0) -> "RideSpec":
    """The same rider, EUC, controllers and place, with a speed profile and disturbances of their own.

    A lab records several runs of one rider over the same floor: each run starts at the same place in the
    lab (the integrator's travel 0 at the start of its warm-up), so what is fixed in the lab is met again.

    Parameters
    ----------
    spec : RideSpec
    seed : int or sequence of int
        Seed of the run's draws.
    kind : str, optional
        Speed-profile kind (default: the spec's).
    v_max, disturbance_scale : float
        As for :func:`draw_spec`.

    Returns
    -------
    RideSpec
        ``spec`` with a new ``profile``, ``dist_h``, ``dist_d``, ``dist_v``; ``info`` gains the run's
        ``disturbances`` and ``run_seed``.
    """
    rng = np.random.default_rng(seed)
    kind = kind or spec.info.get("kind", "mixed")
    profile, dists, bands = _draw_excitation(rng, spec.duration, kind, v_max, disturbance_scale)
    info = dict(spec.info, disturbances=bands, run_seed=seed if isinstance(seed, int) else list(seed))
    return dataclasses.replace(spec, profile=profile, dist_h=dists["dist_h"], dist_d=dists["dist_d"],
                               dist_v=dists["dist_v"], info=info)


@dataclass
class Ride:
    """A simulated ride on a time grid: the truth and the spec it came from.

    Parameters
    ----------
    spec : RideSpec
        What the ride is made of.
    t : ndarray (n,)
        Sample times [s].
    truth : dict of ndarray (n,)
        ``x, x_dot, x_ddot, gamma, gamma_dot, gamma_ddot, phi, phi_dot, phi_ddot`` [m, rad and their
        derivatives], ``M_d, M_h`` [N m] (applied), ``M_d_cmd, M_h_cmd``, ground forces ``F_t, N``
        [N], ``energy`` and ``work`` [J], ``v_ref`` [m/s] (the disturbed speed reference); with a hidden
        law also its value, generalized force, work, residual contribution and states (:func:`simulate`).
    stats : dict
        Integrator statistics (``nfev``, ``rtol``, ``method``, ``x_offset_m``, ``power_check``).
    """

    spec: RideSpec
    t: np.ndarray
    truth: dict
    stats: dict

    @property
    def h(self) -> float:
        """The true distance A-G [m]."""
        return self.spec.plant.h


#: Band of the speed-reference disturbance [Hz]: a rider's intent wanders slowly (its derivative
#: enters the reference acceleration, so a fast wander would be a large acceleration demand).
SPEED_BAND_HZ = (0.05, 0.5)
#: Most right-hand side evaluations per simulated second before a ride counts as failed: some 50 times what a
#: ride takes (measured 2-4 thousand per second at rtol 1e-9); a law that makes the ride stiff would
#: otherwise crawl on for hours in an explicit integrator.
MAX_RHS_PER_S = 200_000
#: Time simulated before the first sample, for the start-up transient to die out [s].
WARMUP_S = 3.0


def integrate(spec: RideSpec, t_eval, *, rtol: float = 1e-9, y0=None, method: str = "DOP853",
              warmup: float = WARMUP_S, stop_on_fall: bool = False):
    """Integrate a ride and return the ``solve_ivp`` result on ``t_eval``.

    Parameters
    ----------
    spec : RideSpec
    t_eval : ndarray (n,)
        Output times [s], increasing, from 0.
    rtol : float
        Relative tolerance; the absolute tolerance is ``rtol * ATOL_SCALE``.
    y0 : ndarray (spec.n_state,), optional
        State at ``-warmup`` (default: upright at the reference speed, torques at their commands, a law's
        states at rest for that state).
    method : str
        A ``solve_ivp`` explicit method.
    warmup : float
        Time integrated before ``t_eval[0]`` and not recorded [s] (the profile holds its first
        speed there; the disturbances are periodic).
    stop_on_fall : bool
        Stop where the pitch or the lean passes :data:`FALL_GAMMA` or :data:`FALL_PHI`, the warm-up included
        (``status`` 1, ``y`` up to there): a fallen ride's states grow without bound, and integrating them to
        the end takes the whole evaluation budget.

    Returns
    -------
    scipy.integrate.OdeResult
        ``solve_ivp``'s result: ``y`` (spec.n_state, n) at ``t_eval``, ``nfev``.

    Raises
    ------
    ConfigError
        ``y0`` is not of shape ``(spec.n_state,)`` (key ``y0``).
    RuntimeError
        The integration fails, or takes over :data:`MAX_RHS_PER_S` evaluations per simulated second.
    """
    t_start = float(t_eval[0]) - warmup
    if y0 is None:
        v0 = float(spec.profile.speed(t_start) + spec.dist_v(t_start))
        y0 = np.array([0.0, 0.0, 0.0, v0, 0.0, 0.0, 0.0, 0.0, 0.0])
        md, mh = spec.inputs(t_start, y0)
        y0[6], y0[7] = md, mh
        if spec.force is not None:
            y0 = np.concatenate([y0, [0.0], spec.force.initial_states(v0, 0.0, 0.0)])
    y0 = np.asarray(y0, dtype=float)
    if y0.shape != (spec.n_state,):
        raise ConfigError(f"needs {spec.n_state} states, got shape {y0.shape}", key="y0")
    budget = int(MAX_RHS_PER_S * (float(t_eval[-1]) - t_start + 1.0))
    calls = [0]

    def rhs(t, y):
        calls[0] += 1
        if calls[0] > budget:
            raise RuntimeError(f"integration too stiff: over {budget} evaluations for "
                               f"{float(t_eval[-1]) - t_start:.0f} s (a ride takes some {MAX_RHS_PER_S // 50} per s)")
        return spec.rhs(t, y)

    def fallen(t, y):           # crosses zero where the ride falls (the warm-up included: no ride gets up again)
        return min(FALL_GAMMA - abs(y[1]), FALL_PHI - abs(y[2]))

    fallen.terminal = True
    sol = solve_ivp(rhs, (t_start, float(t_eval[-1])), y0, method=method, t_eval=t_eval,
                    rtol=rtol, atol=rtol * spec.atol_scale(), events=fallen if stop_on_fall else None)
    if not sol.success:
        raise RuntimeError(f"integration failed: {sol.message}")
    return sol


def simulate(spec: RideSpec, rate_hz: float = 120.0, *, rtol: float = 1e-9) -> Ride:
    """Integrate a ride and record the truth at ``rate_hz``.

    Parameters
    ----------
    spec : RideSpec
    rate_hz : float
        Sampling rate of the truth and of the recording [Hz].
    rtol : float
        Integrator relative tolerance.

    Returns
    -------
    Ride

    Raises
    ------
    ConfigError
        If the ride falls (pitch beyond :data:`FALL_GAMMA` or lean beyond :data:`FALL_PHI`).
    RuntimeError
        The integration fails (:func:`integrate`).

    Notes
    -----
    The accelerations, torques and ground forces are evaluated from the integrated states with the
    same Newton-Euler solve as the right-hand side (vectorized over the samples), so the recorded
    truth satisfies the equations of motion to round-off at every sample, the hidden law's generalized
    force included. With a law the truth adds ``F_ext`` (its value [N or N m]), ``Q_x, Q_gamma, Q_phi``,
    ``work_ext`` (its work [J] from the first sample), ``effect`` (its contribution to ``M_d1 - M_d2``
    for the true parameters [N m], :func:`~euc_ros.core.worldsim.forces.residual_effect`) and the law's
    states ``z0`` (``z1``); ``stats["x_offset_m"]`` is the integrator's travel at the first sample (the
    lab field's coordinate is ``x + x_offset_m``).
    """
    n = int(np.floor(spec.duration * rate_hz + 1e-9)) + 1
    t = np.arange(n) / rate_hz
    sol = integrate(spec, t, rtol=rtol, stop_on_fall=True)
    if sol.status == 1:
        ye = sol.y_events[0][-1]
        raise ConfigError(f"seed {spec.info.get('seed')}: the ride falls at t = {sol.t_events[0][-1]:.2f} s (|gamma| "
                          f"{np.degrees(abs(ye[1])):.1f} deg, |phi| {np.degrees(abs(ye[2])):.1f} deg)", key="seed")
    y = sol.y.T
    if np.max(np.abs(y[:, 1])) > FALL_GAMMA or np.max(np.abs(y[:, 2])) > FALL_PHI:
        raise ConfigError(f"seed {spec.info.get('seed')}: the ride falls (max |gamma| "
                          f"{np.degrees(np.max(np.abs(y[:, 1]))):.1f} deg, max |phi| "
                          f"{np.degrees(np.max(np.abs(y[:, 2]))):.1f} deg)", key="seed")
    x_offset = float(y[0, 0])
    y[:, 0] -= y[0, 0]                  # travel and work counted from the first sample
    y[:, 8] -= y[0, 8]
    p = spec.plant
    md_cmd, mh_cmd = spec.inputs(t, y)
    law, Q, extra = spec.force, None, {}
    if law is not None:
        y[:, 9] -= y[0, 9]
        zl = y[:, 10:]
        F = law.value(t, y[:, 0] + x_offset, y[:, 3], y[:, 4], y[:, 5], zl)
        Q = F[:, None] * law.point.jacobian(y[:, 1], y[:, 2], p)
        extra = {"F_ext": F, "Q_x": Q[:, 0], "Q_gamma": Q[:, 1], "Q_phi": Q[:, 2], "work_ext": y[:, 9],
                 "effect": residual_effect(Q, y[:, 1], y[:, 2], p),
                 **{f"z{k}": zl[:, k] for k in range(law.n_states)}}
    full = solve(y[:, 0:3], y[:, 3:6], y[:, 6], y[:, 7], p, Q)
    truth = {"x": y[:, 0], "x_dot": y[:, 3], "x_ddot": full[:, 0], "gamma": y[:, 1], "gamma_dot": y[:, 4],
             "gamma_ddot": full[:, 1], "phi": y[:, 2], "phi_dot": y[:, 5], "phi_ddot": full[:, 2],
             "M_d": y[:, 6], "M_h": y[:, 7], "M_d_cmd": md_cmd, "M_h_cmd": mh_cmd, "F_t": full[:, 3],
             "N": full[:, 4], "energy": energy(y[:, 0:3], y[:, 3:6], p) - energy(y[:1, 0:3], y[:1, 3:6], p)[0],
             "work": y[:, 8],
             "v_ref": spec.profile.speed(t) + spec.dist_v(t), **extra}
    stats = {"nfev": int(sol.nfev), "rtol": rtol, "method": "DOP853", "x_offset_m": x_offset,
             "power_check": float(np.max(np.abs(torque_power(y[:, 3:6], y[:, 6], y[:, 7], p))))}
    return Ride(spec, t, truth, stats)


def simulate_ride(seed: int, rate_hz: float = 120.0, *, max_attempts: int = 20, rtol: float = 1e-9,
                  **draw) -> Ride:
    """Draw and simulate a ride; a draw that falls is replaced by the next sub-seed (deterministically).

    Parameters
    ----------
    seed : int
    rate_hz : float
        Output rate [Hz].
    max_attempts : int
        Sub-seeds ``seed * 1000 + k`` tried, ``k = 0, 1, ...``.
    rtol : float
        Integrator relative tolerance.
    **draw
        Options of :func:`draw_spec`.

    Returns
    -------
    Ride
        ``ride.spec.info["seed"]`` is the sub-seed used; ``["requested_seed"]`` the one given.

    Raises
    ------
    ConfigError
        None of the ``max_attempts`` draws gives a stable ride that does not fall (key ``seed``).
    """
    last = None
    for k in range(max_attempts):
        sub = int(seed) * 1000 + k
        try:
            spec = draw_spec(sub, **draw)
            ride = simulate(spec, rate_hz, rtol=rtol)
        except ConfigError as exc:
            last = exc
            continue
        ride.spec.info["requested_seed"] = int(seed)
        return ride
    raise ConfigError(f"no stable ride in {max_attempts} draws from seed {seed}: {last}", key="seed")
