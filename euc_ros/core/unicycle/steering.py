"""Steering control of the unicycle: controllability, pole placement, maneuver references.

Steering paper, Section IV. The design model is the linearisation about straight rolling along
+x0 at speed ``v = R phi_dot*`` (eqs (50), (55)); the feedback is the output feedback of eq (64),

    u = -K (y - y_des(t)),    y = C x,

with ``y = [omega1, theta, sigma, r, psi, y_G]`` for the lane change (eqs (61)-(62), gains
``K = [D_theta, P_theta, D_r, P_r, P_psi, P_y]``) and ``y = [omega1, theta, sigma, r, psi]`` for
the 90 deg turn (eqs (68)-(69), no ``P_y``).

Pole placement. ``omega2, phi, x_G`` are unreachable and ``omega3 + 2 phi_dot* theta`` is a linear
invariant (eq (59)), so on the invariant subspace the closed loop is the reduced model (60) under
*full state* feedback: 6 states (lane change) or 5 (turn; ``y_G`` does not feed back). Hence the
gains that put every non-zero closed-loop root at one value ``lambda`` are unique and given by
Ackermann's formula on the reduced model; the remaining roots of the full 10-state closed loop
``A - B K C`` (eq (67)) are zero (4 for the lane change, 5 for the turn). The reduced model is
taken from the *numerical* linearisation of the closed-form model, not from the printed (60).

References. The printed references (66) and (71) contradict their own end values; see
:func:`lane_change_reference` and :func:`turn_reference` for the consistent versions used here.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from euc_ros.core.errors import ConfigError
from euc_ros.core.unicycle.dynamics import STATE_NAMES, UnicycleParams
from euc_ros.core.unicycle.linearize import REDUCED_STATES, linearize_straight_rolling, reduce_linear_system
from euc_ros.core.unicycle.steady import critical_speed

__all__ = [
    "MANEUVERS", "OUTPUTS", "GAIN_NAMES", "GAIN_UNITS", "MANEUVER_START", "MANEUVER_DURATION",
    "MAX_REFERENCE_HEADING", "MAX_CONTROLLABILITY_CONDITION", "MAX_PLACEMENT_ERROR",
    "output_matrix", "controllability_matrix", "numerical_rank", "acker", "check_speed", "SteeringGains",
    "steering_gains", "lane_change_reference", "turn_reference", "default_lane_offset", "SteeringController",
]

MANEUVERS: tuple[str, ...] = ("lane_change", "turn")
#: Output states per maneuver (eqs (61), (68)).
OUTPUTS: dict[str, tuple[str, ...]] = {
    "lane_change": ("omega1", "theta", "sigma", "r", "psi", "y_G"),
    "turn": ("omega1", "theta", "sigma", "r", "psi"),
}
#: Gain names per maneuver, in the order of :data:`OUTPUTS` (eq (64)).
GAIN_NAMES: dict[str, tuple[str, ...]] = {
    "lane_change": ("D_theta", "P_theta", "D_r", "P_r", "P_psi", "P_y"),
    "turn": ("D_theta", "P_theta", "D_r", "P_r", "P_psi"),
}
#: SI units of the gains (angles in rad).
GAIN_UNITS: dict[str, str] = {"D_theta": "N s/rad", "P_theta": "N/rad", "D_r": "N s/m", "P_r": "N/m",
                              "P_psi": "N/rad", "P_y": "N/m"}
#: The reference starts changing at this time [s] (eqs (66), (71)).
MANEUVER_START = 2.0
#: ... and reaches its end value after this duration [s].
MANEUVER_DURATION = 5.0
#: Largest heading the lane-change reference may demand, ``max |y_des_dot| / v`` [rad]: beyond it the
#: linear design's small-yaw assumption (``y_G_dot = v psi``) is off by more than 16 %.
MAX_REFERENCE_HEADING = 1.0
#: Largest condition number of the reduced controllability matrix accepted for a design.
MAX_CONTROLLABILITY_CONDITION = 1e12
#: Largest relative error of the closed-loop characteristic polynomial accepted for a design.
MAX_PLACEMENT_ERROR = 1e-6


def _check_maneuver(maneuver: str) -> str:
    if maneuver not in MANEUVERS:
        raise ConfigError(f"unknown maneuver {maneuver!r}; choose one of {', '.join(MANEUVERS)}", key="maneuver")
    return maneuver


def output_matrix(maneuver: str) -> np.ndarray:
    """Output matrix ``C`` of eq (62) (lane change, 6x10) or eq (69) (turn, 5x10).

    Parameters
    ----------
    maneuver : str
        ``"lane_change"`` or ``"turn"``.

    Returns
    -------
    numpy.ndarray
        ``C`` (6, 10) or (5, 10).
    """
    names = OUTPUTS[_check_maneuver(maneuver)]
    C = np.zeros((len(names), len(STATE_NAMES)))
    for i, n in enumerate(names):
        C[i, STATE_NAMES.index(n)] = 1.0
    return C


def controllability_matrix(A, B) -> np.ndarray:
    """Controllability matrix ``[B, A B, ..., A^(n-1) B]`` (eq (56)), shape (n, n) for a single input.

    Parameters
    ----------
    A : array_like
        State matrix (n, n).
    B : array_like
        Input matrix (n,) or (n, 1).

    Returns
    -------
    numpy.ndarray
        The matrix (n, n).
    """
    A = np.asarray(A, float)
    cols = [np.asarray(B, float).reshape(-1)]
    for _ in range(A.shape[0] - 1):
        cols.append(A @ cols[-1])
    return np.column_stack(cols)


def numerical_rank(M, rtol: float = 1e-9) -> int:
    """Rank of ``M`` from its singular values after scaling every non-zero column to unit norm.

    The columns of a controllability matrix grow like ``|A|^k``; scaling them first keeps the
    relative threshold ``rtol`` meaningful.

    Parameters
    ----------
    M : array_like
        The matrix.
    rtol : float
        Singular values below ``rtol`` times the largest count as zero.

    Returns
    -------
    int
        The rank.
    """
    M = np.asarray(M, float)
    norms = np.linalg.norm(M, axis=0)
    M = M[:, norms > 0] / norms[norms > 0]
    if M.size == 0:
        return 0
    s = np.linalg.svd(M, compute_uv=False)
    return int(np.sum(s > rtol * s[0]))


def acker(A, B, poles) -> np.ndarray:
    """State-feedback gain ``K`` with ``eig(A - B K) = poles`` by Ackermann's formula.

    Unlike ``scipy.signal.place_poles`` this handles repeated poles of any multiplicity for a
    single input: ``K = e_n^T M_c^{-1} phi(A)``, with ``phi`` the desired characteristic polynomial.

    Parameters
    ----------
    A : array_like, shape (n, n)
    B : array_like, shape (n,) or (n, 1)
    poles : array_like, shape (n,)
        Desired closed-loop roots (complex ones in conjugate pairs).

    Returns
    -------
    numpy.ndarray, shape (n,)
    """
    A = np.asarray(A, float)
    n = A.shape[0]
    Mc = controllability_matrix(A, B)
    coeffs = np.real(np.poly(np.asarray(poles)))
    phiA = np.zeros_like(A)
    for c in coeffs:                       # Horner: phi(A) = (...((A + c1) A + c2) A ...) + cn
        phiA = phiA @ A + c * np.eye(n)
    e = np.zeros(n)
    e[-1] = 1.0
    return np.linalg.solve(Mc.T, e) @ phiA


def check_speed(params: UnicycleParams, speed) -> float:
    """Validate a design speed [m/s]; raise :class:`ConfigError` (key ``speed``) when unusable.

    The speed must be finite and positive (the maneuvers run forward along +x0; at ``v = 0`` the
    yaw is unreachable since ``psi_dot = -2 phi_dot* theta``, eq (59)). Speeds at which the
    reduced model is so badly conditioned that the gains are meaningless are rejected in
    :func:`steering_gains`.

    Parameters
    ----------
    params : UnicycleParams
        Physical parameters.
    speed : float
        The design speed [m/s].

    Returns
    -------
    float
        The speed [m/s].

    Raises
    ------
    ConfigError
        When the speed is not a finite positive number (key ``speed``).
    """
    try:
        v = float(speed)
    except (TypeError, ValueError):
        raise ConfigError(f"must be a number, got {speed!r}", key="speed") from None
    if not np.isfinite(v) or v <= 0:
        raise ConfigError(f"must be a positive finite speed in m/s (the maneuvers roll forward along +x; at 0 m/s "
                          f"the yaw cannot be steered), got {speed!r}", key="speed")
    return v


@dataclass(frozen=True)
class SteeringGains:
    """Gains of eq (64) for one maneuver and speed, with the resulting closed-loop roots.

    Parameters
    ----------
    maneuver : str
    speed : float
        Design speed [m/s].
    pole : float
        The value every non-zero closed-loop root is placed at [1/s].
    names : tuple of str
        Gain names (:data:`GAIN_NAMES`).
    K : numpy.ndarray
        Gains in the order of ``names`` (SI, see :data:`GAIN_UNITS`).
    closed_loop_roots : numpy.ndarray of complex
        Eigenvalues of the full 10-state ``A - B K C`` (eq (67)), sorted by real part.
    controllability_condition : float
        Condition number of the reduced controllability matrix used by Ackermann's formula.
    placement_error : float
        Largest relative error of the coefficients of ``det(lambda I - (A - B K C))`` against the
        target ``(lambda - pole)^k lambda^(10-k)`` (a check of the gains in the full model).
    """

    maneuver: str
    speed: float
    pole: float
    names: tuple[str, ...]
    K: np.ndarray
    closed_loop_roots: np.ndarray
    controllability_condition: float
    placement_error: float

    def as_dict(self) -> dict:
        """Gains by name plus metadata, JSON-serializable (roots as ``[re, im]`` pairs).

        Returns
        -------
        dict
            The gains by name, ``maneuver``, ``speed``, ``pole``, the roots and the checks.
        """
        out = {name: float(k) for name, k in zip(self.names, self.K)}
        out.update({
            "maneuver": self.maneuver, "speed": self.speed, "pole": self.pole,
            "closed_loop_roots": [[float(z.real), float(z.imag)] for z in self.closed_loop_roots],
            "controllability_condition": self.controllability_condition,
            "placement_error": self.placement_error,
            "units": {n: GAIN_UNITS[n] for n in self.names},
        })
        return out


def steering_gains(params: UnicycleParams, maneuver: str, speed: float, pole: float = -8.0) -> SteeringGains:
    """Gains placing every non-zero closed-loop root at ``pole`` (Tables II and III for -8 1/s).

    Parameters
    ----------
    params : UnicycleParams
        Physical parameters (``m0 > 0``).
    maneuver : {'lane_change', 'turn'}
    speed : float
        Design speed ``v = R phi_dot*`` [m/s], positive.
    pole : float
        Desired real closed-loop root [1/s], negative.

    Returns
    -------
    SteeringGains

    Raises
    ------
    ConfigError
        Unknown maneuver, non-negative pole, or a speed at which the design is impossible or
        ill-conditioned: ``speed <= 0``, a reduced controllability condition number above
        :data:`MAX_CONTROLLABILITY_CONDITION` or a closed-loop polynomial error above
        :data:`MAX_PLACEMENT_ERROR` (with Table I: the lane change below about 0.1 mm/s, both
        maneuvers above about 70 m/s). The critical speed ``sqrt(g R / 2)`` is *not* such a speed:
        the reduced model stays controllable there (condition number 2.3e3, gains finite and
        continuous in the speed).
    """
    maneuver = _check_maneuver(maneuver)
    params.require_point_mass()
    v = check_speed(params, speed)
    pole = float(pole)
    if not (np.isfinite(pole) and pole < 0):
        raise ConfigError(f"must be a negative finite closed-loop root in 1/s, got {pole!r}", key="pole")
    A, B = linearize_straight_rolling(params, v)
    Ar, Br = reduce_linear_system(A, B, v / params.R)
    n = len(OUTPUTS[maneuver])
    Ar, Br = Ar[:n, :n], Br[:n]                  # turn: drop y_G (it does not feed back)
    assert REDUCED_STATES[:n] == OUTPUTS[maneuver]
    cond = float(np.linalg.cond(controllability_matrix(Ar, Br)))
    K = acker(Ar, Br, [pole] * n) if cond <= MAX_CONTROLLABILITY_CONDITION else np.full(n, np.nan)
    A_cl = A - np.outer(B, K) @ output_matrix(maneuver)
    target = np.poly([pole] * n + [0.0] * (A.shape[0] - n))
    with np.errstate(invalid="ignore"):
        err = float(np.max(np.abs(np.real(np.poly(A_cl)) - target)) / np.max(np.abs(target))) \
            if np.all(np.isfinite(K)) else np.inf
    if not (cond <= MAX_CONTROLLABILITY_CONDITION and err <= MAX_PLACEMENT_ERROR):
        raise ConfigError(
            f"{v:g} m/s is outside the speeds where the {maneuver} gains are well conditioned: the reduced "
            f"controllability matrix has condition number {cond:.3g} (limit {MAX_CONTROLLABILITY_CONDITION:g}) and "
            f"the gains place the closed-loop polynomial with relative error {err:.3g} (limit "
            f"{MAX_PLACEMENT_ERROR:g}); the critical speed {critical_speed(params):.3f} m/s is fine, very low "
            f"and very high speeds are not", key="speed")
    roots = np.linalg.eigvals(A_cl)
    roots = roots[np.argsort(roots.real, kind="stable")]
    return SteeringGains(maneuver, v, pole, GAIN_NAMES[maneuver], K, roots, cond, err)


# ---------------------------------------------------------------------------------------------
# references
# ---------------------------------------------------------------------------------------------
def _cosine_step(t, end_value: float, start: float, duration: float) -> np.ndarray:
    """0 before ``start``, ``end_value (1 - cos(pi (t - start) / duration)) / 2`` during, then ``end_value``."""
    t = np.asarray(t, dtype=float)
    s = np.clip((t - start) / duration, 0.0, 1.0)
    return end_value * (1 - np.cos(np.pi * s)) / 2


def lane_change_reference(t, offset: float, start: float = MANEUVER_START,
                          duration: float = MANEUVER_DURATION) -> np.ndarray:
    """Desired lateral position ``y_des(t)`` [m] of the lane change (consistent version of eq (66)).

    Printed (66) moves ``L (cos(pi (t-2)/5) - 1)`` from 0 to ``-2 L`` by t = 7 s but then holds
    ``-L``: a 2 L jump-free path would not reach its own end value. Used here: the half-amplitude
    cosine ``offset (1 - cos(pi (t - 2)/5)) / 2``, which is continuous with zero slope at both ends
    and ends at ``offset`` (the paper's ``-L``: to the right, REP-103 y is left).

    Parameters
    ----------
    t : array_like
        Times [s].
    offset : float
        Final lateral position [m].
    start : float
        Start of the maneuver [s].
    duration : float
        Its duration [s].

    Returns
    -------
    numpy.ndarray
        ``y_des`` [m], the shape of ``t``.
    """
    return _cosine_step(t, float(offset), start, duration)


def turn_reference(t, angle: float = -np.pi / 2, start: float = MANEUVER_START,
                   duration: float = MANEUVER_DURATION) -> np.ndarray:
    """Desired yaw ``psi_des(t)`` [rad] of the turn (consistent version of eq (71)).

    Printed (71) moves ``pi/4 (cos(pi (t-2)/5) - 1)`` from 0 to ``-pi/2`` (a right turn, yaw about
    +z0) but then holds ``+pi/2``. Used here: ``angle (1 - cos(pi (t-2)/5)) / 2`` with the default
    ``angle = -pi/2``, i.e. the printed transition and the paper's "90 deg right turn".

    Parameters
    ----------
    t : array_like
        Times [s].
    angle : float
        Final yaw [rad].
    start : float
        Start of the maneuver [s].
    duration : float
        Its duration [s].

    Returns
    -------
    numpy.ndarray
        ``psi_des`` [rad], the shape of ``t``.
    """
    return _cosine_step(t, float(angle), start, duration)


def default_lane_offset(params: UnicycleParams, speed: float) -> float:
    """The paper's lane-change offset for a speed: ``-2.5 m`` below the critical speed, ``-10 m`` above.

    Parameters
    ----------
    params : UnicycleParams
        Physical parameters.
    speed : float
        The design speed [m/s].

    Returns
    -------
    float
        The offset [m].

    Raises
    ------
    ConfigError
        When the speed is not a finite positive number.
    """
    return -2.5 if check_speed(params, speed) < critical_speed(params) else -10.0


class SteeringController:
    """Output feedback ``u = -K (y - y_des(t))`` (eq (64)) for one maneuver at one speed.

    Gains are computed once, at construction (:func:`steering_gains`). ``command`` is what a node
    calls every control period.

    Parameters
    ----------
    params : UnicycleParams
        Model parameters used for the design.
    maneuver : {'lane_change', 'turn'}
    speed : float
        Design speed [m/s] (the unicycle should start in straight rolling at this speed).
    pole : float
        Closed-loop root [1/s] (default -8).
    target : float, optional
        Lane change: final lateral position ``y_G`` [m] (default :func:`default_lane_offset`);
        turn: final yaw [rad] (default ``-pi/2``, a right turn).
    start, duration : float
        Start time and duration of the reference transition [s].

    Raises
    ------
    ConfigError
        Bad maneuver, speed or pole (see :func:`steering_gains`), or a lane change so sharp that
        the demanded heading ``max |y_des_dot| / v`` exceeds :data:`MAX_REFERENCE_HEADING`.
    """

    def __init__(self, params: UnicycleParams, maneuver: str, speed: float, pole: float = -8.0, *,
                 target: float | None = None, start: float = MANEUVER_START,
                 duration: float = MANEUVER_DURATION) -> None:
        self.params = params
        self.gains = steering_gains(params, maneuver, speed, pole)
        self.maneuver = self.gains.maneuver
        self.speed = self.gains.speed
        if not (np.isfinite(start) and np.isfinite(duration) and duration > 0):
            raise ConfigError(f"needs a finite start and a positive duration, got {start!r}, {duration!r}",
                              key="duration")
        self.start, self.duration = float(start), float(duration)
        if target is None:
            target = default_lane_offset(params, speed) if self.maneuver == "lane_change" else -np.pi / 2
        target = float(target)
        if not np.isfinite(target):
            raise ConfigError(f"must be finite, got {target!r}", key="target")
        if self.maneuver == "lane_change":
            heading = abs(target) / 2 * np.pi / self.duration / self.speed
            if heading > MAX_REFERENCE_HEADING:
                raise ConfigError(
                    f"a {target:g} m lane change in {self.duration:g} s at {self.speed:g} m/s demands a heading of "
                    f"{np.degrees(heading):.0f} deg (> {np.degrees(MAX_REFERENCE_HEADING):.0f} deg): infeasible for a "
                    f"design linearised about straight rolling; use a smaller offset or a longer duration",
                    key="target")
        self.target = target
        self._idx = np.array([STATE_NAMES.index(n) for n in OUTPUTS[self.maneuver]])

    @property
    def output_names(self) -> tuple[str, ...]:
        """Names of the outputs ``y`` (and of the entries of ``y_des``)."""
        return OUTPUTS[self.maneuver]

    def reference(self, t) -> np.ndarray:
        """Desired outputs ``y_des(t)``: shape (k,) for scalar ``t``, (k, n) for ``t`` of shape (n,).

        Parameters
        ----------
        t : float or array_like
            Time(s) [s].

        Returns
        -------
        numpy.ndarray
            ``y_des`` (k,) or (k, n).
        """
        t = np.asarray(t, dtype=float)
        y = np.zeros((len(self._idx),) + t.shape)
        if self.maneuver == "lane_change":
            y[-1] = lane_change_reference(t, self.target, self.start, self.duration)
        else:
            y[-1] = turn_reference(t, self.target, self.start, self.duration)
        return y

    def command(self, t: float, x) -> tuple[float, np.ndarray]:
        """Control force ``u`` [N] and the desired outputs ``y_des`` at time ``t`` [s] for state ``x`` (10,).

        Parameters
        ----------
        t : float
            Time [s].
        x : array_like
            State (10,).

        Returns
        -------
        u : float
            Control force [N].
        y_des : numpy.ndarray
            Desired outputs (k,).
        """
        y_des = self.reference(t)
        y = np.asarray(x, dtype=float)[self._idx]
        return float(-self.gains.K @ (y - y_des)), y_des
