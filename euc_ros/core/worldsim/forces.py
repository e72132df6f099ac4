r"""Hidden force laws of the open world: random laws by family, applied at random points by virtual power.

A law is a scalar signal ``F = amplitude * shape(t, x, x_dot, gamma_dot, phi_dot, z)`` (a force [N], or a
torque [N m] for the pitch-torque point) acting at a point of the rider or the EUC. Its shape is drawn
from one of five families:

``lab_field``
    a smooth function of the travel ``x`` along the track (a sum of 1-4 Gaussian bumps centred within
    the track, or of 1-3 sinusoids), length scales 0.5-5 m (log-uniform), alone or multiplied by the
    speed or its (smooth) sign;
``wheel``
    periodic in the wheel angle ``x / R``: harmonics 1-4 (a random subset), random amplitudes and
    phases (an out-of-round tyre, a bent rim);
``speed``
    a smooth function of the speed ``x_dot``: odd and monotone (a positive combination of
    ``tanh(v/v_s)``, ``v``, ``v |v|``, ``v^3``, ``v / sqrt(1 + (v/v_s)^2)``) or even (of ``v^2``,
    ``tanh(v/v_s)^2``, ``|v|^3``, ``sqrt(1 + (v/v_s)^2) - 1``), overall sign random;
``drift``
    a slow drift in time: a ramp over the ride, 1-3 sinusoids with periods 10-60 s, or both;
``dynamic``
    a hidden linear dynamic driven by a measured state (the speed, or the rider's or the EUC's pitch
    rate): first order ``tau z' = -z + u`` or second order ``z'' + 2 zeta w z' + w^2 z = w^2 u``
    (``w = 1 / tau``), ``tau`` 0.1-2 s (log-uniform), ``zeta`` 0.2-1; ``F`` is proportional to ``z``.
    These laws add one or two integrator states.

Points of application (:class:`Point`):

``contact``
    a horizontal force at the tyre contact, moving with the wheel: its virtual velocity is the travel
    rate ``x_dot``, so ``Q = (F, 0, 0)``. (A force on the tyre's material point at the contact does no
    work, ``v_P = 0``, and only shifts the ground's friction force; a resisting contact force such as
    rolling resistance is the ground's pressure shifted ahead of the axle, whose couple makes it act
    like a force at the axle: that is this point.)
``cog_x``, ``cog_z``
    horizontal or vertical at the rider's centre of gravity G;
``rider_x``
    horizontal at another point of the rider (a hand, a shoulder): ``height`` along the rider's up
    axis from the ankle hinge A and ``forward`` along its forward axis;
``pitch``
    a pure pitch torque on the rider (``Q = (0, 0, T)``).

Torques between the wheel, the EUC body and the rider (a bearing's friction, a stiffness at the
ankle) are not drawn: an internal torque ``T`` between two bodies has the generalized force
``T (b_2 - b_1)``, a combination of the input directions ``b_d = (1/R, -1, 0)`` and ``b_h = (0, 1, -1)``
of the motor and ankle torques. The analysed residual ``M_d1 - M_d2`` does not depend on the inputs
(it is their elimination), so such a torque cannot show in it: it is absorbed in the estimated motor
and ankle torques.

The generalized force is ``Q = J^T F`` with ``J`` the point's velocity Jacobian with respect to
``(x_dot, gamma_dot, phi_dot)`` (virtual power ``F . v = Q . q_dot``), written out from the geometry
of :func:`euc_ros.core.worldsim.dynamics.points`: ``C = (x, R)``, ``A = C - l_0 e(gamma)``, a rider
point ``A + d e(phi) + f n(phi)`` with ``e(a) = (sin a, cos a)``, ``n(a) = e'(a) = (cos a, -sin a)``,
``n'(a) = -e(a)``. The dynamics apply ``Q`` (:func:`euc_ros.core.worldsim.dynamics.newton_euler_system`).

Amplitude: the residual of the two model torques responds to ``Q`` through (:func:`residual_effect`)

.. math:: \Delta(M_{d1} - M_{d2}) = \frac{R\, m_{eq}\, (R Q_x + Q_\gamma + Q_\phi)}
          {R\, m_{eq} - (m l_0 - m_0 h_0) \cos\gamma + m h \cos\phi},

the first row of the equations of motion times ``R`` minus the same with the acceleration ``x_ddot``
the weighted sum of all rows (weights ``(R, 1, 1)``, which annihilate both inputs) predicts.
:func:`calibrate` scales a law so that a perfect model would cut the residual's RMSE by a chosen
ratio ``floor / sqrt(floor^2 + effect^2)``.

Only numpy and scipy are used (the analysis' code is not).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from euc_ros.core.errors import ConfigError
from euc_ros.core.worldsim.dynamics import PlantParams

#: Families of hidden laws.
FAMILIES = ("lab_field", "wheel", "speed", "drift", "dynamic")
#: Points of application.
POINTS = ("contact", "cog_x", "rider_x", "cog_z", "pitch")
#: Speed scale of the smooth sign ``tanh(v / SIGN_SPEED)`` [m/s].
SIGN_SPEED = 0.1
#: Reference speed of the speed laws' powers [m/s].
V_REF = 2.0
#: Range of the lab field's and the dynamic law's scales: length 0.5-5 m, time constant 0.1-2 s.
LENGTH_SCALE_M = (0.5, 5.0)
TAU_S = (0.1, 2.0)
#: Periods of the drift's sinusoids [s].
DRIFT_PERIOD_S = (10.0, 60.0)
#: Range of the design ratio RMSE(perfect model) / RMSE(no effect).
RATIO_RANGE = (0.2, 0.5)


def _loguniform(rng: np.random.Generator, lo: float, hi: float, size=None):
    return np.exp(rng.uniform(math.log(lo), math.log(hi), size))


# --------------------------------------------------------------------------------------------------
# points of application
# --------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Point:
    """Where a law's force acts (:data:`POINTS`).

    Parameters
    ----------
    kind : str
        One of :data:`POINTS`.
    height : float
        ``rider_x``: distance of the point from the ankle hinge A along the rider's up axis [m]
        (``cog_x``, ``cog_z``: the rider's h, set by :meth:`bind`).
    forward : float
        ``rider_x``: offset along the rider's forward axis [m].

    Raises
    ------
    ConfigError
        ``kind`` is not one of :data:`POINTS` (key ``point``).
    """

    kind: str
    height: float = 0.0
    forward: float = 0.0

    def __post_init__(self):
        if self.kind not in POINTS:
            raise ConfigError(f"must be one of {POINTS}, got {self.kind!r}", key="point")

    @property
    def unit(self) -> str:
        """Unit of the law's value at this point."""
        return "N m" if self.kind == "pitch" else "N"

    def bind(self, p: PlantParams) -> "Point":
        """The point with the rider's h filled in for the CoG points.

        Parameters
        ----------
        p : PlantParams
            The plant (its ``h``).

        Returns
        -------
        Point
            ``cog_x``, ``cog_z``: ``height = p.h``, ``forward = 0``; any other point unchanged.
        """
        return replace(self, height=p.h, forward=0.0) if self.kind in ("cog_x", "cog_z") else self

    def jacobian(self, gamma, phi, p: PlantParams) -> np.ndarray:
        """``dQ/dF`` (..., 3): the generalized force of a unit law value at pitches ``gamma``, ``phi``.

        For the force points, the row of the point's velocity Jacobian along the force's direction;
        for ``pitch``, ``(0, 0, 1)``.

        Parameters
        ----------
        gamma, phi : array_like
            EUC and rider pitch [rad] (broadcast).
        p : PlantParams
            The plant (``l_0``, and ``h`` for the CoG points).

        Returns
        -------
        numpy.ndarray (..., 3)
            ``(dQ_x, dQ_gamma, dQ_phi) / dF`` [1, m, m] (dimensionless at the pitch point).
        """
        gamma, phi = np.broadcast_arrays(np.asarray(gamma, dtype=float), np.asarray(phi, dtype=float))
        J = np.zeros(gamma.shape + (3,))
        d, f = self.bind(p).height, self.forward
        if self.kind == "contact":
            J[..., 0] = 1.0
        elif self.kind in ("cog_x", "rider_x"):
            J[..., 0] = 1.0
            J[..., 1] = -p.l_0 * np.cos(gamma)
            J[..., 2] = d * np.cos(phi) - f * np.sin(phi)
        elif self.kind == "cog_z":
            J[..., 1] = p.l_0 * np.sin(gamma)
            J[..., 2] = -d * np.sin(phi) - f * np.cos(phi)
        else:
            J[..., 2] = 1.0
        return J

    def jacobian_one(self, gamma: float, phi: float, p: PlantParams) -> tuple[float, float, float]:
        """:meth:`jacobian` of one state in scalar arithmetic (the integrator's right-hand side).

        Parameters
        ----------
        gamma, phi : float
            EUC and rider pitch [rad].
        p : PlantParams
            The plant.

        Returns
        -------
        tuple of float
            ``(dQ_x, dQ_gamma, dQ_phi) / dF``.
        """
        k = self.kind
        if k == "contact":
            return 1.0, 0.0, 0.0
        if k == "pitch":
            return 0.0, 0.0, 1.0
        d = p.h if k in ("cog_x", "cog_z") else self.height
        f = 0.0 if k in ("cog_x", "cog_z") else self.forward
        if k == "cog_z":
            return 0.0, p.l_0 * math.sin(gamma), -d * math.sin(phi) - f * math.cos(phi)
        return 1.0, -p.l_0 * math.cos(gamma), d * math.cos(phi) - f * math.sin(phi)

    def describe(self) -> dict:
        """Plain mapping for the truth file.

        Returns
        -------
        dict
            ``kind``, ``height_m``, ``forward_m`` [m] and ``unit`` (of the law's value).
        """
        return {"kind": self.kind, "height_m": self.height, "forward_m": self.forward, "unit": self.unit}


def draw_point(rng: np.random.Generator, stature: float) -> Point:
    """A random point, uniform over :data:`POINTS`.

    A ``rider_x`` point 0.45-0.78 of the stature above the ankle (hands to shoulders) and 0-0.3 m forward.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the draws.
    stature : float
        Rider's stature [m].

    Returns
    -------
    Point
        Unbound (:meth:`Point.bind` fills in a CoG point's height).

    Raises
    ------
    ConfigError
        ``stature`` is not > 0 (key ``stature``).
    """
    if not stature > 0:
        raise ConfigError(f"must be > 0 m, got {stature}", key="stature")
    kind = POINTS[int(rng.integers(len(POINTS)))]
    if kind == "rider_x":
        return Point(kind, height=float(rng.uniform(0.45, 0.78) * stature), forward=float(rng.uniform(0.0, 0.3)))
    return Point(kind)


# --------------------------------------------------------------------------------------------------
# shapes by family
# --------------------------------------------------------------------------------------------------
def _odd_basis(name: str, v, s: float, xp):
    if name == "tanh":
        return xp.tanh(v / s)
    if name == "linear":
        return v / V_REF
    if name == "quadratic":
        return v * abs(v) / V_REF**2 if xp is math else v * np.abs(v) / V_REF**2
    if name == "cubic":
        return (v / V_REF) ** 3
    return (v / s) / xp.sqrt(1.0 + (v / s) ** 2)          # saturation


def _even_basis(name: str, v, s: float, xp):
    if name == "square":
        return (v / V_REF) ** 2
    if name == "tanh2":
        return xp.tanh(v / s) ** 2
    if name == "abs_cubic":
        return (abs(v) if xp is math else np.abs(v)) ** 3 / V_REF**3
    return xp.sqrt(1.0 + (v / s) ** 2) - 1.0              # soft |v|


ODD_BASIS = ("tanh", "linear", "quadratic", "cubic", "saturation")
EVEN_BASIS = ("square", "tanh2", "abs_cubic", "soft_abs")


@dataclass(frozen=True)
class ForceLaw:
    """A hidden force law: ``value = amplitude * shape`` at a :class:`Point`.

    Parameters
    ----------
    family : str
        One of :data:`FAMILIES`.
    point : Point
        Where it acts.
    amplitude : float
        Scale of the law [N, or N m at the pitch point]; 1 for a drawn, uncalibrated law.
    params : dict
        The shape's draws (plain floats, lists and strings; see :func:`draw_law`).

    Raises
    ------
    ConfigError
        ``family`` is unknown (key ``family``) or ``amplitude`` not finite (key ``amplitude``).
    """

    family: str
    point: Point
    amplitude: float = 1.0
    params: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.family not in FAMILIES:
            raise ConfigError(f"must be one of {FAMILIES}, got {self.family!r}", key="family")
        if not math.isfinite(self.amplitude):
            raise ConfigError(f"must be finite, got {self.amplitude}", key="amplitude")

    # -- the law's own states ------------------------------------------------------------------
    @property
    def n_states(self) -> int:
        """Integrator states of the law (the dynamic family's order, else 0)."""
        return int(self.params["order"]) if self.family == "dynamic" else 0

    def _input(self, xd, gd, pd):
        u = self.params["input"]
        return xd if u == "speed" else (pd if u == "rider_pitch_rate" else gd)

    def initial_states(self, xd: float, gd: float, pd: float) -> np.ndarray:
        """States at rest for a constant input: ``z = u`` (and ``z' = 0``).

        Parameters
        ----------
        xd, gd, pd : float
            Speed [m/s], EUC and rider pitch rates [rad/s] (the law's input is one of them).

        Returns
        -------
        numpy.ndarray (n_states,)
            Empty for a law without states.
        """
        if self.n_states == 0:
            return np.zeros(0)
        u = float(self._input(xd, gd, pd))
        return np.array([u] if self.n_states == 1 else [u, 0.0])

    def state_rates(self, xd, gd, pd, z):
        """``dz/dt`` (..., n_states) of the dynamic law; ``z`` (..., n_states).

        Parameters
        ----------
        xd, gd, pd : array_like
            Speed [m/s], EUC and rider pitch rates [rad/s].
        z : array_like (..., n_states)
            The law's states (unit of its input; the second is its rate).

        Returns
        -------
        numpy.ndarray (..., n_states)
            Zeros of ``z``'s shape for a law without states.
        """
        z = np.asarray(z, dtype=float)
        if self.n_states == 0:
            return np.zeros_like(z)
        u = self._input(np.asarray(xd, float), np.asarray(gd, float), np.asarray(pd, float))
        tau = self.params["tau_s"]
        if self.n_states == 1:
            return ((u - z[..., 0]) / tau)[..., None]
        w, zeta = 1.0 / tau, self.params["zeta"]
        return np.stack([z[..., 1], w * w * (u - z[..., 0]) - 2.0 * zeta * w * z[..., 1]], -1)

    def state_rates_one(self, xd: float, gd: float, pd: float, z) -> list[float]:
        """:meth:`state_rates` of one state, scalar arithmetic.

        Parameters
        ----------
        xd, gd, pd : float
            Speed [m/s], EUC and rider pitch rates [rad/s].
        z : sequence of float (n_states,)
            The law's states.

        Returns
        -------
        list of float
            ``dz/dt`` (empty for a law without states).
        """
        n = self.n_states
        if n == 0:
            return []
        u = self._input(xd, gd, pd)
        tau = self.params["tau_s"]
        if n == 1:
            return [(u - z[0]) / tau]
        w, zeta = 1.0 / tau, self.params["zeta"]
        return [z[1], w * w * (u - z[0]) - 2.0 * zeta * w * z[1]]

    # -- the value -------------------------------------------------------------------------------
    def value(self, t, x, xd, gd, pd, z=None):
        """The law's value [N or N m] at times and states (arrays broadcasting; ``z`` (..., n_states)).

        Parameters
        ----------
        t : array_like
            Times [s].
        x : array_like
            The integrator's travel [m] (the lab field's and the wheel angle's coordinate).
        xd, gd, pd : array_like
            Speed [m/s], EUC and rider pitch rates [rad/s].
        z : array_like (..., n_states), optional
            The dynamic law's states (needed by that family only).

        Returns
        -------
        numpy.ndarray
            ``amplitude * shape`` [N, or N m at the pitch point].
        """
        t, x, xd, gd, pd = (np.asarray(a, dtype=float) for a in (t, x, xd, gd, pd))
        return self.amplitude * self._shape(t, x, xd, z, np)

    def value_one(self, t: float, x: float, xd: float, gd: float, pd: float, z=()) -> float:
        """:meth:`value` of one state, scalar arithmetic.

        Parameters
        ----------
        t, x, xd, gd, pd : float
            One time and state, as for :meth:`value` [s, m, m/s, rad/s, rad/s].
        z : sequence of float
            The dynamic law's states (empty for the others).

        Returns
        -------
        float
            [N, or N m at the pitch point].
        """
        return self.amplitude * self._shape(t, x, xd, z, math)

    def _shape(self, t, x, v, z, xp):
        P, fam = self.params, self.family
        if fam == "lab_field":
            s = 0.0
            if P["kind"] == "bumps":
                for a, c, w in zip(P["weights"], P["centres_m"], P["scales_m"], strict=True):
                    s = s + a * xp.exp(-0.5 * ((x - c) / w) ** 2)
            else:
                for a, w, ph in zip(P["weights"], P["scales_m"], P["phases"], strict=True):
                    s = s + a * xp.sin(x / w + ph)
            m = P["multiplier"]
            if m == "speed":
                return s * v / V_REF
            if m == "sign":
                return s * xp.tanh(v / SIGN_SPEED)
            return s
        if fam == "wheel":
            s = 0.0
            for k, a, ph in zip(P["harmonics"], P["weights"], P["phases"], strict=True):
                s = s + a * xp.cos(k * x / P["R"] + ph)
            return s
        if fam == "speed":
            s = 0.0
            basis = _odd_basis if P["parity"] == "odd" else _even_basis
            for name, a, sc in zip(P["basis"], P["weights"], P["scales"], strict=True):
                s = s + a * basis(name, v, sc, xp)
            return P["sign"] * s
        if fam == "drift":
            s = P["ramp"] * t / P["duration_s"]
            for a, per, ph in zip(P["weights"], P["periods_s"], P["phases"], strict=True):
                s = s + a * xp.sin(2.0 * math.pi * t / per + ph)
            return s
        # dynamic: the first state, per unit of its input
        z0 = z[0] if xp is math else np.asarray(z, dtype=float)[..., 0]
        return P["sign"] * z0 / P["input_scale"]

    def generalized(self, t, x, xd, gd, pd, gamma, phi, p: PlantParams, z=None) -> np.ndarray:
        """Generalized force ``Q`` (..., 3) [N, N m, N m] of the law at times and states.

        Parameters
        ----------
        t, x, xd, gd, pd : array_like
            Times and states, as for :meth:`value` [s, m, m/s, rad/s, rad/s].
        gamma, phi : array_like
            EUC and rider pitch [rad].
        p : PlantParams
            The plant.
        z : array_like (..., n_states), optional
            The dynamic law's states.

        Returns
        -------
        numpy.ndarray (..., 3)
            ``value * Point.jacobian`` [N, N m, N m].
        """
        F = self.value(t, x, xd, gd, pd, z)
        return F[..., None] * self.point.jacobian(gamma, phi, p)

    def with_amplitude(self, amplitude: float) -> "ForceLaw":
        """The same law with another amplitude.

        Parameters
        ----------
        amplitude : float
            The new amplitude.

        Returns
        -------
        ForceLaw
        """
        return replace(self, amplitude=float(amplitude))

    def describe(self) -> dict:
        """Plain mapping for the truth file.

        Returns
        -------
        dict
            ``family``, ``amplitude``, ``unit``, ``point`` (:meth:`Point.describe`) and ``params``.
        """
        return {"family": self.family, "amplitude": self.amplitude, "unit": self.point.unit,
                "point": self.point.describe(), "params": self.params}


def draw_law(rng: np.random.Generator, family: str, *, R: float, track_m: tuple[float, float],
             duration: float, stature: float, point: Point | None = None) -> ForceLaw:
    """A random law of a family, with unit amplitude, at a random (or given) point.

    Parameters
    ----------
    rng : numpy.random.Generator
    family : str
        One of :data:`FAMILIES`.
    R : float
        Wheel radius [m] (the wheel family's angle ``x / R``).
    track_m : (float, float)
        Range of the travel ``x`` the ride covers (the integrator's ``x``) [m]: the lab field's bumps are
        centred within it.
    duration : float
        Ride length [s] (the drift's ramp spans it).
    stature : float
        Rider's stature [m] (heights of the rider points).
    point : Point, optional
        Force the point (default: :func:`draw_point`).

    Returns
    -------
    ForceLaw
        Amplitude 1; each shape's weights sum to 1 in absolute value.
    """
    if family not in FAMILIES:
        raise ConfigError(f"must be one of {FAMILIES}, got {family!r}", key="family")
    lo, hi = float(track_m[0]), float(track_m[1])
    if not (math.isfinite(lo) and math.isfinite(hi) and hi >= lo):
        raise ConfigError(f"need a finite range low <= high, got {track_m}", key="track_m")
    if not (R > 0 and duration > 0):
        raise ConfigError(f"need R > 0 and duration > 0, got {R}, {duration}", key="R")
    pt = draw_point(rng, stature) if point is None else point

    def weights(k, lo_w=0.3):
        w = rng.uniform(lo_w, 1.0, k) * rng.choice([-1.0, 1.0], k)
        return (w / np.sum(np.abs(w))).tolist()

    if family == "lab_field":
        kind = ("bumps", "modes")[int(rng.integers(2))]
        k = int(rng.integers(1, 5)) if kind == "bumps" else int(rng.integers(1, 4))
        params = {"kind": kind, "weights": weights(k), "scales_m": _loguniform(rng, *LENGTH_SCALE_M, k).tolist(),
                  "multiplier": ("none", "speed", "sign")[int(rng.integers(3))]}
        if kind == "bumps":
            params["centres_m"] = rng.uniform(lo, hi, k).tolist()
        else:
            params["phases"] = rng.uniform(-np.pi, np.pi, k).tolist()
    elif family == "wheel":
        n = int(rng.integers(1, 5))
        harm = np.sort(rng.choice(np.arange(1, 5), n, replace=False))
        params = {"R": float(R), "harmonics": harm.tolist(), "weights": weights(n),
                  "phases": rng.uniform(-np.pi, np.pi, n).tolist()}
    elif family == "speed":
        parity = ("odd", "even")[int(rng.integers(2))]
        names = ODD_BASIS if parity == "odd" else EVEN_BASIS
        n = int(rng.integers(1, 4))
        basis = [names[i] for i in rng.choice(len(names), n, replace=False)]
        w = rng.uniform(0.2, 1.0, n)                      # positive: an odd law stays monotone
        params = {"parity": parity, "basis": basis, "weights": (w / w.sum()).tolist(),
                  "scales": _loguniform(rng, 0.05, 1.5, n).tolist(), "sign": float(rng.choice([-1.0, 1.0]))}
    elif family == "drift":
        kind = ("ramp", "smooth", "both")[int(rng.integers(3))]
        k = 0 if kind == "ramp" else int(rng.integers(1, 4))
        w = weights(k + (kind != "smooth"))
        params = {"kind": kind, "duration_s": float(duration), "ramp": w[-1] if kind != "smooth" else 0.0,
                  "weights": w[:k], "periods_s": _loguniform(rng, *DRIFT_PERIOD_S, k).tolist(),
                  "phases": rng.uniform(-np.pi, np.pi, k).tolist()}
    else:
        order = int(rng.integers(1, 3))
        inp = ("speed", "rider_pitch_rate", "euc_pitch_rate")[int(rng.integers(3))]
        params = {"order": order, "input": inp, "input_scale": 1.0, "tau_s": float(_loguniform(rng, *TAU_S)),
                  "zeta": float(rng.uniform(0.2, 1.0)) if order == 2 else None,
                  "sign": float(rng.choice([-1.0, 1.0]))}
    return ForceLaw(family, pt, 1.0, params)


# --------------------------------------------------------------------------------------------------
# the residual's response and the amplitude
# --------------------------------------------------------------------------------------------------
def residual_effect(Q, gamma, phi, p: PlantParams) -> np.ndarray:
    """Contribution [N m] of a generalized force ``Q`` (..., 3) to the residual ``M_d1 - M_d2``.

    ``R m_eq (R Q_x + Q_gamma + Q_phi) / (R m_eq - (m l_0 - m_0 h_0) cos gamma + m h cos phi)`` with
    ``m_eq = m + m_0 + m_w + J_w / R^2`` (module docstring), for a model with the true parameters.

    Parameters
    ----------
    Q : array_like (..., 3)
        ``(Q_x, Q_gamma, Q_phi)`` [N, N m, N m].
    gamma, phi : array_like (...)
        EUC and rider pitch [rad].
    p : PlantParams
        The true plant.

    Returns
    -------
    numpy.ndarray (...)
        Change of ``M_d1 - M_d2`` [N m].
    """
    Q = np.asarray(Q, dtype=float)
    m_eq = p.m + p.m_0 + p.m_w + p.J_w / p.R**2
    D = p.R * m_eq - (p.m * p.l_0 - p.m_0 * p.h_0) * np.cos(gamma) + p.m * p.h * np.cos(phi)
    return p.R * m_eq * (p.R * Q[..., 0] + Q[..., 1] + Q[..., 2]) / D


def law_states_on(law: ForceLaw, t, xd, gd, pd) -> np.ndarray:
    """The dynamic law's states (n, n_states) along sampled inputs, from rest at the first sample.

    The linear dynamics are integrated exactly for an input linear between samples
    (``scipy.signal.lsim``).

    Parameters
    ----------
    law : ForceLaw
        The law (no states: an (n, 0) result).
    t : array_like (n,)
        Sample times [s], increasing.
    xd, gd, pd : array_like (n,)
        Speed [m/s], EUC and rider pitch rates [rad/s] at the samples.

    Returns
    -------
    numpy.ndarray (n, n_states)
        The states at the samples.
    """
    from scipy.signal import lsim

    t = np.asarray(t, dtype=float)
    if law.n_states == 0:
        return np.zeros((t.size, 0))
    u = law._input(np.asarray(xd, float), np.asarray(gd, float), np.asarray(pd, float))
    tau = law.params["tau_s"]
    if law.n_states == 1:
        A, B = np.array([[-1.0 / tau]]), np.array([[1.0 / tau]])
    else:
        w, zeta = 1.0 / tau, law.params["zeta"]
        A, B = np.array([[0.0, 1.0], [-w * w, -2.0 * zeta * w]]), np.array([[0.0], [w * w]])
    C, D = np.eye(law.n_states), np.zeros((law.n_states, 1))
    _, _, z = lsim((A, B, C, D), u, t - t[0], X0=law.initial_states(xd[0], gd[0], pd[0]))
    return np.asarray(z, dtype=float).reshape(t.size, law.n_states)


def values_on(law: ForceLaw, truth: dict, t, x_offset: float = 0.0) -> np.ndarray:
    """The law's value [N or N m] along a recorded ride (see :func:`effect_on`).

    Parameters
    ----------
    law : ForceLaw
        The law.
    truth : dict
        The ride's ``x``, ``x_dot``, ``gamma_dot``, ``phi_dot`` (n,) (:attr:`Ride.truth`) [m, m/s, rad/s].
    t : array_like (n,)
        Sample times [s].
    x_offset : float
        Added to ``truth["x"]`` to give the integrator's travel [m].

    Returns
    -------
    numpy.ndarray (n,)
        [N, or N m at the pitch point].
    """
    x = np.asarray(truth["x"], float) + x_offset
    xd, gd, pd = (np.asarray(truth[k], float) for k in ("x_dot", "gamma_dot", "phi_dot"))
    z = law_states_on(law, t, xd, gd, pd) if law.n_states else None
    return law.value(t, x, xd, gd, pd, z)


def effect_on(law: ForceLaw, truth: dict, t, p: PlantParams, x_offset: float = 0.0) -> np.ndarray:
    """The law's residual contribution [N m] along a recorded ride (its truth), per sample.

    ``x_offset`` is added to the truth's travel ``x`` (counted from the first sample) to give the
    integrator's ``x``, on which the lab field and the wheel angle are defined. The dynamic law's
    states come from :func:`law_states_on` (from rest at the first sample).

    Parameters
    ----------
    law : ForceLaw
        The law.
    truth : dict
        The ride's ``x``, ``x_dot``, ``gamma``, ``gamma_dot``, ``phi``, ``phi_dot`` (n,)
        (:attr:`Ride.truth`) [m, m/s, rad, rad/s].
    t : array_like (n,)
        Sample times [s].
    p : PlantParams
        The true plant.
    x_offset : float
        The integrator's travel at the first sample [m].

    Returns
    -------
    numpy.ndarray (n,)
        :func:`residual_effect` of the law's generalized force [N m].
    """
    x = np.asarray(truth["x"], float) + x_offset
    xd, gd, pd = (np.asarray(truth[k], float) for k in ("x_dot", "gamma_dot", "phi_dot"))
    z = law_states_on(law, t, xd, gd, pd) if law.n_states else None
    Q = law.generalized(t, x, xd, gd, pd, truth["gamma"], truth["phi"], p, z)
    return residual_effect(Q, np.asarray(truth["gamma"], float), np.asarray(truth["phi"], float), p)


def rms(a) -> float:
    """Root mean square of ``a``.

    Parameters
    ----------
    a : array_like

    Returns
    -------
    float
    """
    a = np.asarray(a, dtype=float)
    return float(np.sqrt(np.mean(a * a)))


def ratio_of(floor: float, effect: float) -> float:
    """Design ratio ``floor / sqrt(floor^2 + effect^2)`` (a perfect model's RMSE over the RMSE without it).

    Parameters
    ----------
    floor : float
        RMSE of the residual without the effect [N m].
    effect : float
        RMS of the effect [N m].

    Returns
    -------
    float
        In (0, 1] for ``floor > 0`` (``ZeroDivisionError`` when both are 0).
    """
    return float(floor / math.hypot(floor, effect))


def calibrate(law: ForceLaw, truth: dict, t, p: PlantParams, floor_nm: float, ratio: float,
              x_offset: float = 0.0, view=None) -> tuple[ForceLaw, dict]:
    """Scale a law so that ``floor / sqrt(floor^2 + effect^2) = ratio`` on a ride.

    Parameters
    ----------
    law : ForceLaw
        Any amplitude (the shape is what counts).
    truth, t : dict, ndarray
        A ride without the law (:attr:`Ride.truth`, :attr:`Ride.t`): the law is evaluated along it.
    p : PlantParams
    floor_nm : float
        RMSE the analysis reaches on that ride [N m].
    ratio : float
        Target ratio, in (0, 1).
    x_offset : float
        See :func:`effect_on`.
    view : callable, optional
        ``view(effect) -> effect`` as the analysis sees it (e.g. through its filter); default as is.

    Returns
    -------
    law : ForceLaw
        With the amplitude that gives the effect RMS ``floor sqrt(1/ratio^2 - 1)`` along the ride.
    info : dict
        ``effect_target_nm``, ``effect_unit_nm`` (RMS per unit amplitude), ``ratio_target``.

    Notes
    -----
    The law changes the motion it acts on (the controllers respond), so the effect on the ride with
    the law differs a little from the target; the ride's truth records the achieved effect.
    """
    if not 0 < ratio < 1:
        raise ConfigError(f"must be in (0, 1), got {ratio}", key="ratio")
    if not floor_nm > 0:
        raise ConfigError(f"must be > 0 N m, got {floor_nm}", key="floor_nm")
    unit = law.with_amplitude(1.0)
    e1 = effect_on(unit, truth, t, p, x_offset)
    e1 = rms(view(e1) if view is not None else e1)
    if not e1 > 0:
        raise ConfigError("the law has no effect on the residual along this ride (e.g. a lab field off the "
                          "track, or a speed law on a ride at rest)", key="law")
    target = floor_nm * math.sqrt(1.0 / ratio**2 - 1.0)
    return unit.with_amplitude(target / e1), {"effect_target_nm": target, "effect_unit_nm": e1, "ratio_target": ratio}


__all__ = ["FAMILIES", "POINTS", "ForceLaw", "Point", "calibrate", "draw_law", "draw_point", "effect_on",
           "law_states_on", "ratio_of", "residual_effect", "rms", "values_on"]
