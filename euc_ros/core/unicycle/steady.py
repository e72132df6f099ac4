"""Steady states of the rolling wheel and the unicycle and their linear stability.

Steering paper, Sections II.B-C and III.B-C: turning-rolling steady states (eqs (13), (14), (41)),
straight rolling (eq (24)), spinning (eq (28)), non-tilted turning (eq (44)), tilted spinning
(eq (46)), the critical pitch rates (eqs (27), (54)), the critical yaw rates (eq (22)) and the
critical tilt angle (eq (23)), and vectorized stability maps like Figs 3, 5 and 6.

Stability is always decided from the *numerical* Jacobian of the closed-form model
(:mod:`euc_ros.core.unicycle.linearize`), never from the paper's printed characteristic
polynomials: the closed forms here are what the tests compare against.

Classification. The essential Jacobian ``J`` (4x4 wheel, 6x6 unicycle) at a steady state has the
characteristic polynomial ``lambda^2 (lambda^2 - s)`` (wheel, eq (20)) or
``lambda^2 (lambda^4 + p lambda^2 + q)`` (unicycle, eq (49)); odd powers vanish because the
unforced model is reversible. From the power sums ``tr(J^2)`` and ``tr(J^4)``::

    s = tr(J^2) / 2,    p = -tr(J^2) / 2,    q = (p^2 - tr(J^4) / 2) / 2.

A steady state is *neutrally stable* (all roots on the imaginary axis) iff ``s < 0`` (wheel) or
``p > 0, q > 0, p^2 >= 4 q`` (unicycle: both roots ``mu`` of ``mu^2 + p mu + q`` real negative);
otherwise it is unstable.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from euc_ros.core.unicycle.dynamics import (
    ESSENTIAL_STATES,
    STATE_NAMES,
    WHEEL_ESSENTIAL_STATES,
    WHEEL_STATE_NAMES,
    UnicycleParams,
    mass_height,
)
from euc_ros.core.unicycle.linearize import linearize, straight_rolling_state, wheel_jacobian

__all__ = [
    "wheel_critical_pitch_rate", "unicycle_critical_pitch_rate", "critical_speed", "wheel_critical_speed",
    "critical_tilt_angle", "spinning_critical_yaw_rate", "wheel_critical_yaw_rates",
    "wheel_turning_pitch_rate", "unicycle_turning_steady_state", "non_tilted_turning", "tilted_spinning",
    "wheel_steady_state", "unicycle_steady_state", "straight_rolling_coefficients",
    "wheel_stability_coefficients", "unicycle_stability_coefficients", "straight_rolling_is_stable",
    "StabilityMap", "wheel_stability_map", "unicycle_stability_map", "wheel_turning_lambda2",
    "wheel_steady_state_counts_rates", "wheel_steady_state_counts_tilt",
]

_CHUNK = 8192  # states per Jacobian batch (bounds memory of the complex-step arrays)


# ---------------------------------------------------------------------------------------------
# closed-form critical values
# ---------------------------------------------------------------------------------------------
def wheel_critical_pitch_rate(params: UnicycleParams) -> float:
    """Critical pitch rate of straight rolling of the bare wheel, ``sqrt(g / (3 R))`` [rad/s], eq (27).

    Parameters
    ----------
    params : UnicycleParams
        Physical parameters.

    Returns
    -------
    float
        The pitch rate [rad/s].
    """
    return float(np.sqrt(params.g / (3 * params.R)))


def unicycle_critical_pitch_rate(params: UnicycleParams) -> float:
    """Critical pitch rate of straight rolling of the unicycle, ``sqrt(g / (2 R))`` [rad/s], eq (54).

    Independent of ``m`` and ``m0`` (for any ``m0 > 0``).

    Parameters
    ----------
    params : UnicycleParams
        Physical parameters.

    Returns
    -------
    float
        The pitch rate [rad/s].
    """
    return float(np.sqrt(params.g / (2 * params.R)))


def critical_speed(params: UnicycleParams) -> float:
    """Critical wheel-centre speed of the unicycle, ``sqrt(g R / 2)`` [m/s] (1.213 m/s for Table I).

    Parameters
    ----------
    params : UnicycleParams
        Physical parameters.

    Returns
    -------
    float
        The speed [m/s].
    """
    return params.R * unicycle_critical_pitch_rate(params)


def wheel_critical_speed(params: UnicycleParams) -> float:
    """Critical wheel-centre speed of the bare wheel, ``sqrt(g R / 3)`` [m/s].

    Parameters
    ----------
    params : UnicycleParams
        Physical parameters.

    Returns
    -------
    float
        The speed [m/s].
    """
    return params.R * wheel_critical_pitch_rate(params)


def critical_tilt_angle() -> float:
    """Tilt angle above which every turning-rolling state of the wheel is stable [rad], eq (23).

    ``arcsin(sqrt(12/19 - 9 sqrt(5) / 38))`` = 18.62 deg, independent of every physical parameter.

    Returns
    -------
    float
        The angle [rad].
    """
    return float(np.arcsin(np.sqrt(12 / 19 - 9 * np.sqrt(5) / 38)))


def spinning_critical_yaw_rate(params: UnicycleParams) -> float:
    """Critical yaw rate of the wheel spinning on the spot, ``sqrt(4 g / (5 R))`` [rad/s], eq (31).

    Parameters
    ----------
    params : UnicycleParams
        Physical parameters.

    Returns
    -------
    float
        The yaw rate [rad/s].
    """
    return float(np.sqrt(4 * params.g / (5 * params.R)))


def wheel_critical_yaw_rates(theta, params: UnicycleParams) -> tuple[np.ndarray, np.ndarray]:
    """Critical yaw rates ``(psi_dot_crit1, psi_dot_crit2)`` of turning rolling, eq (22) [rad/s].

    Turning rolling of the wheel at tilt ``theta`` is unstable for
    ``psi_dot_crit1 < |psi_dot| < psi_dot_crit2``; NaN where ``|theta|`` exceeds the critical tilt
    angle (eq (23)) and no unstable band exists.

    Parameters
    ----------
    theta : array_like
        Steady tilt [rad].
    params : UnicycleParams
        Physical parameters.

    Returns
    -------
    psi_dot_crit1, psi_dot_crit2 : numpy.ndarray
        Lower and upper critical yaw rates [rad/s].
    """
    th = np.asarray(theta, dtype=float)
    s2 = np.sin(th) ** 2
    c = np.cos(th)
    disc = 76 * s2**2 - 96 * s2 + 9
    root = np.sqrt(np.where(disc >= 0, disc, np.nan))
    den = (2 * s2 - 3) * np.abs(c)
    pre = np.sqrt(2 * params.g / (5 * params.R))
    with np.errstate(invalid="ignore"):
        a = pre * np.sqrt((3 - 6 * c**2 + root) / den)
        b = pre * np.sqrt((3 - 6 * c**2 - root) / den)
    return np.fmin(a, b), np.fmax(a, b)


# ---------------------------------------------------------------------------------------------
# steady states
# ---------------------------------------------------------------------------------------------
def wheel_turning_pitch_rate(theta, psi_dot, params: UnicycleParams):
    """Pitch rate of the wheel's turning-rolling steady state, eq (14) [rad/s].

    ``phi_dot* = -5/6 psi_dot* sin(theta*) - 2 g tan(theta*) / (3 R psi_dot*)``, for ``psi_dot* != 0``.

    Parameters
    ----------
    theta : array_like
        Steady tilt [rad].
    psi_dot : array_like
        Steady yaw rate [rad/s], non-zero.
    params : UnicycleParams
        Physical parameters.

    Returns
    -------
    numpy.ndarray
        ``phi_dot*`` [rad/s].
    """
    th = np.asarray(theta, dtype=float)
    pd = np.asarray(psi_dot, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return -5 / 6 * pd * np.sin(th) - 2 * params.g / (3 * params.R) * np.tan(th) / pd


def unicycle_turning_steady_state(theta, psi_dot, params: UnicycleParams) -> tuple[np.ndarray, np.ndarray]:
    """Pitch rate and point-mass position of the unicycle's turning rolling with ``u = 0``, eq (41).

    Parameters
    ----------
    theta : array_like
        Steady tilt angle [rad].
    psi_dot : array_like
        Steady yaw rate [rad/s], non-zero and not at the singular values of eq (42).
    params : UnicycleParams

    Returns
    -------
    phi_dot : numpy.ndarray
        Steady pitch rate [rad/s].
    r : numpy.ndarray
        Steady point-mass position along the axle [m].
    """
    m, m0, R, g = params.m, params.m0, params.R, params.g
    th = np.asarray(theta, dtype=float)
    pd = np.asarray(psi_dot, dtype=float)
    s, c = np.sin(th), np.cos(th)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = m * R * (pd**2 * R * c + 2 * g) * s * c / (6 * pd**2 * m * R * c**3 - 4 * m0 * g)
        num = (-4 * m * g * R * s + pd**2 * (4 * m0 * r**2 - 5 * m * R**2) * s * c
               - 4 * pd**2 * m0 * R * r * s**2 + 4 * m0 * g * r * c)
        phi_dot = num / (pd * R * (6 * m * R * c + 4 * m0 * r * s))
    return phi_dot, r


def non_tilted_turning(r, params: UnicycleParams, sign: int = 1) -> tuple[float, np.ndarray]:
    """Non-tilted turning of the unicycle (``theta* = 0``), eq (44).

    Returns ``(psi_dot*, phi_dot*)`` with ``psi_dot* = sign sqrt(2 m0 g / (3 m R))`` and
    ``phi_dot* = sign sqrt(2 m0 g / (3 m R^3)) r``.

    Parameters
    ----------
    r : float or array_like
        Point-mass position along the axle [m].
    params : UnicycleParams
        Physical parameters (``m0 > 0``).
    sign : int
        +1 or -1: the turning direction.

    Returns
    -------
    psi_dot : float
        Yaw rate [rad/s].
    phi_dot : numpy.ndarray
        Pitch rate [rad/s].
    """
    m, m0, R, g = params.m, params.m0, params.R, params.g
    return (sign * float(np.sqrt(2 * m0 * g / (3 * m * R))),
            sign * np.sqrt(2 * m0 * g / (3 * m * R**3)) * np.asarray(r, dtype=float))


def tilted_spinning(theta, params: UnicycleParams) -> tuple[np.ndarray, np.ndarray]:
    """Tilted spinning of the unicycle (``phi_dot* = 0``, ``theta* != 0``), eq (46).

    Parameters
    ----------
    theta : array_like
        Steady tilt [rad].
    params : UnicycleParams
        Physical parameters (``m0 > 0``).

    Returns
    -------
    psi_dot : numpy.ndarray
        Positive steady yaw rate [rad/s] (``-psi_dot`` is a steady state too); NaN where none exists.
    r : numpy.ndarray
        Point-mass position [m]; ``r theta > 0`` (the mass is above the wheel centre).
    """
    m, m0, R, g = params.m, params.m0, params.R, params.g
    th = np.asarray(theta, dtype=float)
    s, c = np.sin(th), np.cos(th)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = R * np.tan(th) / (2 * m0) * (m * c**2 + m0 + np.sqrt(m**2 * c**4 + 3 * m * m0 * c**2 + m0**2))
        w2 = (4 * m0 * g * r * c - 4 * m * g * R * s) / ((5 * m * R**2 - 4 * m0 * r**2) * s * c
                                                         + 4 * m0 * R * r * s**2)
    return np.sqrt(np.where(w2 >= 0, w2, np.nan)), r


def wheel_steady_state(theta, psi_dot, phi_dot) -> np.ndarray:
    """Wheel state (eq (7)) of a steady state at t = 0, eq (17): shape (8, ...).

    Parameters
    ----------
    theta : array_like
        Steady tilt [rad].
    psi_dot : array_like
        Steady yaw rate [rad/s].
    phi_dot : array_like
        Steady pitch rate [rad/s].

    Returns
    -------
    numpy.ndarray
        Wheel states (8, ...).
    """
    th, pd, fd = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (theta, psi_dot, phi_dot)))
    x = np.zeros((len(WHEEL_STATE_NAMES),) + th.shape)
    x[1] = pd * np.sin(th) + fd
    x[2] = pd * np.cos(th)
    x[3] = th
    return x


def unicycle_steady_state(theta, psi_dot, phi_dot, r) -> np.ndarray:
    """Unicycle state (eq (37)) of a steady state at t = 0 (eq (38), ``sigma = 0``): shape (10, ...).

    Parameters
    ----------
    theta : array_like
        Steady tilt [rad].
    psi_dot : array_like
        Steady yaw rate [rad/s].
    phi_dot : array_like
        Steady pitch rate [rad/s].
    r : array_like
        Point-mass position along the axle [m].

    Returns
    -------
    numpy.ndarray
        Unicycle states (10, ...).
    """
    th, pd, fd, rr = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (theta, psi_dot, phi_dot, r)))
    x = np.zeros((len(STATE_NAMES),) + th.shape)
    x[1] = pd * np.sin(th) + fd
    x[2] = pd * np.cos(th)
    x[3] = th
    x[5] = rr
    return x


# ---------------------------------------------------------------------------------------------
# stability
# ---------------------------------------------------------------------------------------------
def wheel_stability_coefficients(J) -> np.ndarray:
    """``s = lambda_{1,2}^2 = tr(J^2)/2`` of the wheel's essential Jacobian(s) ``J`` (..., 4, 4), eq (20).

    Parameters
    ----------
    J : array_like
        Essential Jacobian(s) (..., 4, 4).

    Returns
    -------
    numpy.ndarray
        ``s`` (...): negative means neutrally stable.
    """
    J = np.asarray(J, dtype=float)
    return np.einsum("...ij,...ji->...", J, J) / 2


def unicycle_stability_coefficients(J) -> tuple[np.ndarray, np.ndarray]:
    """``(p, q)`` of ``lambda^2 (lambda^4 + p lambda^2 + q)`` for essential Jacobian(s) (..., 6, 6), eq (49).

    Parameters
    ----------
    J : array_like
        Essential Jacobian(s) (..., 6, 6).

    Returns
    -------
    p, q : numpy.ndarray
        The coefficients (...).
    """
    J = np.asarray(J, dtype=float)
    J2 = J @ J
    t2 = np.einsum("...ii->...", J2)
    t4 = np.einsum("...ij,...ji->...", J2, J2)
    p = -t2 / 2
    q = (p**2 - t4 / 2) / 2
    return p, q


def _unicycle_stable(p, q):
    scale = np.maximum(p**2, 1e-300)
    return (p > 0) & (q > 0) & (p**2 - 4 * q >= -1e-9 * scale)


def straight_rolling_coefficients(params: UnicycleParams, pitch_rate: float) -> tuple[float, float, float]:
    """Coefficients ``(a, b, c)`` of ``a lambda^4 + b lambda^2 + c``, eq (52) (straight rolling).

    Parameters
    ----------
    params : UnicycleParams
        Physical parameters.
    pitch_rate : float
        Steady pitch rate ``phi_dot*`` [rad/s].

    Returns
    -------
    a, b, c : float
        The coefficients.
    """
    m, m0, R, g = params.m, params.m0, params.R, params.g
    p2 = float(pitch_rate) ** 2
    return 5 * m * R**2, 12 * p2 * m * R**2 + 4 * (m0 - m) * g * R, 4 * m0 * g * (2 * p2 * R - g)


def straight_rolling_is_stable(params: UnicycleParams, pitch_rate: float, wheel: bool = False) -> bool:
    """Neutral stability of straight rolling at ``pitch_rate`` [rad/s] from the numerical Jacobian.

    ``wheel=True`` uses the bare wheel (eq (6)), else the unicycle with ``u = 0`` (eq (36)).

    Parameters
    ----------
    params : UnicycleParams
        Physical parameters.
    pitch_rate : float
        Steady pitch rate ``phi_dot*`` [rad/s].
    wheel : bool
        Use the bare wheel.

    Returns
    -------
    bool
        Whether straight rolling is neutrally stable.
    """
    if wheel:
        x = np.zeros(len(WHEEL_STATE_NAMES))
        x[1] = pitch_rate
        J = wheel_jacobian(params, x)[:WHEEL_ESSENTIAL_STATES, :WHEEL_ESSENTIAL_STATES]
        return bool(wheel_stability_coefficients(J) < 0)
    A, _ = linearize(params, straight_rolling_state(params, pitch_rate * params.R))
    p, q = unicycle_stability_coefficients(A[:ESSENTIAL_STATES, :ESSENTIAL_STATES])
    return bool(_unicycle_stable(p, q))


@dataclass(frozen=True)
class StabilityMap:
    """Turning-rolling steady states on a ``(theta*, psi_dot*)`` grid and their stability.

    Parameters
    ----------
    theta : numpy.ndarray, shape (n_theta,)
        Steady tilt angles [rad].
    psi_dot : numpy.ndarray, shape (n_psi,)
        Steady yaw rates [rad/s].
    phi_dot : numpy.ndarray, shape (n_theta, n_psi)
        Steady pitch rate [rad/s] (eq (14) or (41)); NaN where no steady state exists.
    r : numpy.ndarray, shape (n_theta, n_psi)
        Steady point-mass position [m] (zeros for the wheel).
    mass_height : numpy.ndarray, shape (n_theta, n_psi)
        Height of the point mass ``z_A`` [m] (eq (47)); the wheel-centre height for the wheel.
    feasible : numpy.ndarray of bool
        A steady state exists and ``z_A > 0``.
    stable : numpy.ndarray of bool
        Feasible and neutrally stable.
    m0 : float
        Point mass [kg] the map was computed for (0: bare wheel).
    """

    theta: np.ndarray
    psi_dot: np.ndarray
    phi_dot: np.ndarray
    r: np.ndarray
    mass_height: np.ndarray
    feasible: np.ndarray
    stable: np.ndarray
    m0: float


def _grid(theta, psi_dot):
    th = np.asarray(theta, dtype=float).ravel()
    pd = np.asarray(psi_dot, dtype=float).ravel()
    TH, PD = np.meshgrid(th, pd, indexing="ij")
    return th, pd, TH, PD


def wheel_turning_lambda2(params: UnicycleParams, theta, psi_dot) -> np.ndarray:
    """``lambda_{1,2}^2 = s`` of the wheel's turning rolling at ``(theta*, psi_dot*)`` (eqs (14), (20)).

    Computed from the numerical Jacobian of eq (6) at the steady state with the pitch rate of
    eq (14); negative means neutrally stable, positive unstable. NaN where ``psi_dot* = 0``.

    Parameters
    ----------
    params : UnicycleParams
        Physical parameters.
    theta : array_like
        Steady tilts [rad].
    psi_dot : array_like
        Steady yaw rates [rad/s] (broadcast with ``theta``).

    Returns
    -------
    numpy.ndarray
        ``lambda^2`` [1/s^2] (broadcast shape of ``theta`` and ``psi_dot``).
    """
    TH, PD = np.broadcast_arrays(np.asarray(theta, dtype=float), np.asarray(psi_dot, dtype=float))
    FD = wheel_turning_pitch_rate(TH, PD, params)
    exists = np.isfinite(FD)
    X = wheel_steady_state(TH, PD, np.where(exists, FD, 0.0)).reshape(len(WHEEL_STATE_NAMES), -1)
    s = np.empty(X.shape[1])
    for k in range(0, X.shape[1], _CHUNK):
        J = wheel_jacobian(params, X[:, k:k + _CHUNK])[:, :WHEEL_ESSENTIAL_STATES, :WHEEL_ESSENTIAL_STATES]
        s[k:k + _CHUNK] = wheel_stability_coefficients(J)
    return np.where(exists, s.reshape(TH.shape), np.nan)


def wheel_stability_map(params: UnicycleParams, theta, psi_dot) -> StabilityMap:
    """Stability of the wheel's turning rolling over a ``(theta*, psi_dot*)`` grid (Fig. 3).

    Parameters
    ----------
    params : UnicycleParams
        Only ``R`` and ``g`` matter.
    theta : array_like, shape (n_theta,)
        Tilt angles [rad], ``|theta| < 90 deg``.
    psi_dot : array_like, shape (n_psi,)
        Yaw rates [rad/s]; zero gives no steady state (NaN, infeasible) except straight rolling.

    Returns
    -------
    StabilityMap
    """
    th, pd, TH, PD = _grid(theta, psi_dot)
    FD = wheel_turning_pitch_rate(TH, PD, params)
    exists = np.isfinite(FD)
    s = wheel_turning_lambda2(params, TH, PD)
    stable = exists & (s < 0)
    return StabilityMap(th, pd, np.where(exists, FD, np.nan), np.zeros_like(TH), params.R * np.cos(TH),
                        exists, stable, 0.0)


def _count_stability(params, theta_roots, psi_roots, pixel, n_pixels):
    s = wheel_turning_lambda2(params, theta_roots, psi_roots)
    ok = np.isfinite(s)
    n_stable = np.bincount(pixel[ok & (s < 0)], minlength=n_pixels)
    n_unstable = np.bincount(pixel[ok & (s >= 0)], minlength=n_pixels)
    return n_stable, n_unstable


def wheel_steady_state_counts_rates(params: UnicycleParams, psi_dot, phi_dot, max_tilt: float = np.radians(85),
                                    n_theta: int = 721) -> tuple[np.ndarray, np.ndarray]:
    """Number of stable and unstable turning-rolling states at each ``(psi_dot*, phi_dot*)`` (Fig. 3(b)).

    For given yaw and pitch rates, the tilt solves eq (13),
    ``5 psi_dot^2 R sin cos + 6 psi_dot phi_dot R cos + 4 g sin = 0``, which may have several
    solutions (the folding of the steady-state surface); they are found by sign changes on
    ``n_theta`` samples of ``|theta| < max_tilt`` and refined linearly.

    Parameters
    ----------
    params : UnicycleParams
        Physical parameters.
    psi_dot : array_like
        Yaw rates [rad/s].
    phi_dot : array_like
        Pitch rates [rad/s] (broadcast with ``psi_dot``).
    max_tilt : float
        Largest tilt searched [rad].
    n_theta : int
        Tilt samples searched.

    Returns
    -------
    n_stable, n_unstable : numpy.ndarray of int, shape ``np.broadcast(psi_dot, phi_dot).shape``
    """
    PD, FD = np.broadcast_arrays(np.asarray(psi_dot, dtype=float), np.asarray(phi_dot, dtype=float))
    shape = PD.shape
    pdf, fdf = PD.ravel(), FD.ravel()
    th = np.linspace(-max_tilt, max_tilt, n_theta)
    sn, cs = np.sin(th), np.cos(th)
    R, g = params.R, params.g
    roots_th, roots_pix = [], []
    step = max(1, (1 << 21) // n_theta)
    for k in range(0, pdf.size, step):
        p_, f_ = pdf[k:k + step, None], fdf[k:k + step, None]
        F = 5 * p_**2 * R * sn * cs + 6 * p_ * f_ * R * cs + 4 * g * sn
        i, j = np.nonzero((F[:, :-1] * F[:, 1:] < 0) | ((F[:, :-1] == 0) & (F[:, 1:] != 0)))
        f0, f1 = F[i, j], F[i, j + 1]
        roots_th.append(th[j] - f0 * (th[j + 1] - th[j]) / (f1 - f0))
        roots_pix.append(i + k)
    theta_r = np.concatenate(roots_th)
    pix = np.concatenate(roots_pix)
    ns, nu = _count_stability(params, theta_r, pdf[pix], pix, pdf.size)
    return ns.reshape(shape), nu.reshape(shape)


def wheel_steady_state_counts_tilt(params: UnicycleParams, theta, phi_dot) -> tuple[np.ndarray, np.ndarray]:
    """Number of stable and unstable turning-rolling states at each ``(theta*, phi_dot*)`` (Fig. 3(c)).

    Eq (13) is quadratic in the yaw rate: ``(5 R sin cos) psi_dot^2 + (6 phi_dot R cos) psi_dot +
    4 g sin = 0``; each real root (``theta* != 0``) is a steady state.

    Parameters
    ----------
    params : UnicycleParams
        Physical parameters.
    theta : array_like
        Tilts [rad].
    phi_dot : array_like
        Pitch rates [rad/s] (broadcast with ``theta``).

    Returns
    -------
    n_stable, n_unstable : numpy.ndarray of int
    """
    TH, FD = np.broadcast_arrays(np.asarray(theta, dtype=float), np.asarray(phi_dot, dtype=float))
    shape = TH.shape
    thf, fdf = TH.ravel(), FD.ravel()
    R, g = params.R, params.g
    a = 5 * R * np.sin(thf) * np.cos(thf)
    b = 6 * fdf * R * np.cos(thf)
    c = 4 * g * np.sin(thf)
    disc = b**2 - 4 * a * c
    ok = (a != 0) & (disc >= 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        r1 = (-b + np.sqrt(disc)) / (2 * a)
        r2 = (-b - np.sqrt(disc)) / (2 * a)
    pix = np.concatenate([np.nonzero(ok)[0], np.nonzero(ok & (disc > 0))[0]])
    psi_r = np.concatenate([r1[ok], r2[ok & (disc > 0)]])
    ns, nu = _count_stability(params, thf[pix], psi_r, pix, thf.size)
    return ns.reshape(shape), nu.reshape(shape)


def unicycle_stability_map(params: UnicycleParams, theta, psi_dot) -> StabilityMap:
    """Stability of the unicycle's turning rolling (``u = 0``) over a ``(theta*, psi_dot*)`` grid.

    Figs 5 and 6: the steady pitch rate and mass position come from eq (41); a state is feasible
    if it exists and the point mass is above the ground (eq (47)); its stability is decided from
    the numerical essential Jacobian (module docstring). ``params.m0 == 0`` falls back to
    :func:`wheel_stability_map`.

    Parameters
    ----------
    params : UnicycleParams
        Physical parameters.
    theta : array_like
        Steady tilts (n_theta,) [rad].
    psi_dot : array_like
        Steady yaw rates (n_psi,) [rad/s].

    Returns
    -------
    StabilityMap
    """
    if params.m0 == 0:
        return wheel_stability_map(params, theta, psi_dot)
    th, pd, TH, PD = _grid(theta, psi_dot)
    FD, RR = unicycle_turning_steady_state(TH, PD, params)
    exists = np.isfinite(FD) & np.isfinite(RR)
    X = unicycle_steady_state(TH, PD, np.where(exists, FD, 0.0), np.where(exists, RR, 0.0))
    zA = mass_height(X, params)
    feasible = exists & (zA > 0)
    Xf = X.reshape(len(STATE_NAMES), -1)
    p = np.empty(Xf.shape[1])
    q = np.empty(Xf.shape[1])
    for k in range(0, Xf.shape[1], _CHUNK):
        A, _ = linearize(params, Xf[:, k:k + _CHUNK])
        p[k:k + _CHUNK], q[k:k + _CHUNK] = unicycle_stability_coefficients(
            A[:, :ESSENTIAL_STATES, :ESSENTIAL_STATES])
    stable = feasible & _unicycle_stable(p, q).reshape(TH.shape)
    return StabilityMap(th, pd, np.where(exists, FD, np.nan), np.where(exists, RR, np.nan), zA, feasible,
                        stable, params.m0)
