"""The rider is not one rigid body on a rigid hinge: pedals that flex, arms that swing.

Truth-side effects outside the residual analysis' library, written from their own physics (no code
shared with :mod:`euc_ros.core.residual` or the model and states packages).

``PedalFlex``
    The pedals (and the shoe soles) give under the rider's load: the ankle hinge A moves down the EUC's
    axis by ``u``, a fourth coordinate of the truth model (:class:`~.truth_model.PedalModel`, Lagrange's
    equations with ``A = C + (l0 + u)(-sin gamma, -cos gamma)``) with the generalized force
    ``Q_u = -k u - c u_dot``, ``c = 2 zeta sqrt(k m)``. Quasi-static, ``k u`` equals the rider's load
    along the axis, ``m (a_G - g_vec) . e_ax`` (``m g cos gamma`` at rest: 6.4 mm for 65 kg at
    k = 1e5 N/m). The mocap places the rider on the flexed hinge; the EUC body does not see u.

``ArmSwing``
    Both arms (upper and lower arm bodies) swing rigidly about their shoulder pivot in the pitch plane,
    ``theta_a(t) = a sin(2 pi f t + p)`` (10 deg moves a hand ~9 cm), relative to a trunk that does not
    compensate: the rider's CoG moves in the trunk's frame. The lean frame L of the truth model is the
    frame in which G stays on its axis (G = A + h(t) R_L e_z): with g(theta) the CoG in the skeleton's
    frame S (origin A), ``h(t) = |g|``, the skeleton frame is ``R_S = R_L Ry(-beta)``,
    ``beta = atan2(g_x, g_z)``. The segments are point masses ``f_i m`` at their CoMs; relative to G, in
    L, at ``c_i(t)`` with ``sum f_i c_i = 0``, so the rider's kinetic energy is
    ``1/2 m |v_G|^2 + 1/2 (J + dJ(t)) phi_dot^2 + phi_dot H(t) + T_rel(t)`` with
    ``dJ = sum m f_i |c_i|^2 - (the same at theta_a = 0)`` and ``H = sum m f_i (z_i x_i' - x_i z_i')``
    (pitch-axis angular momentum of the relative motion). Lagrange's equation for phi gains
    ``dJ phi_ddot + dJ_dot phi_dot + H_dot``; h(t) is the truth model's rheonomic h. Gravity acts on G
    only (``sum f_i c_i = 0``). The segments' own inertia about their CoMs is left out (a rod of an arm:
    ~0.01 kg m^2), in the truth as in the mocap: the simulated rider is that point-mass rider.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from euc_ros.core.errors import ConfigError

#: Arm bodies and the body whose pivot is their shoulder.
ARM_SHOULDER = {"UAR": "UAR", "LAR": "UAR", "UAL": "UAL", "LAL": "UAL"}


@dataclass(frozen=True)
class PedalFlex:
    """Pedals that flex under the rider's load.

    Stiffness ``k_n_per_m`` along the EUC's axis, damping ratio ``damping_ratio`` of the rider bouncing on
    them.

    Parameters
    ----------
    k_n_per_m : float
        Stiffness along the EUC's axis [N/m].
    damping_ratio : float
        Damping ratio of the rider on the pedals.

    Raises
    ------
    ConfigError
        When the stiffness is not positive or the damping ratio is negative.
    """

    k_n_per_m: float = 1.0e5
    damping_ratio: float = 0.3

    def __post_init__(self) -> None:
        if not (math.isfinite(self.k_n_per_m) and self.k_n_per_m > 0):
            raise ConfigError(f"must be > 0, got {self.k_n_per_m}", key="pedals.k_n_per_m")
        if not (math.isfinite(self.damping_ratio) and self.damping_ratio >= 0):
            raise ConfigError(f"must be >= 0, got {self.damping_ratio}", key="pedals.damping_ratio")

    def damping(self, rider_mass: float) -> float:
        """Damping [N s/m] of the rider on the pedals.

        Parameters
        ----------
        rider_mass : float
            Rider mass [kg].

        Returns
        -------
        float
            The damping [N s/m].
        """
        return 2.0 * self.damping_ratio * math.sqrt(self.k_n_per_m * rider_mass)

    def to_dict(self) -> dict:
        """The pedals as a plain mapping, for ``truth.json``.

        Returns
        -------
        dict
            ``kind`` (``pedal_flex``) and the fields.
        """
        return {"kind": "pedal_flex", **asdict(self)}


@dataclass(frozen=True)
class ArmSwing:
    """Both arms swinging about the shoulders in the pitch plane.

    ``amplitude_deg`` at ``freq_hz``; the phase of run k is ``phase_rad + k * phase_step_rad``.

    Parameters
    ----------
    amplitude_deg : float
        Swing amplitude [deg], in [0, 60].
    freq_hz : float
        Swing frequency [Hz], in (0, 5].
    phase_rad : float
        Phase of run 0 [rad].
    phase_step_rad : float
        Phase step from run to run [rad].

    Raises
    ------
    ConfigError
        When the amplitude is outside [0, 60] deg or the frequency outside (0, 5] Hz.
    """

    amplitude_deg: float = 10.0
    freq_hz: float = 1.0
    phase_rad: float = 0.0
    phase_step_rad: float = 2.4

    def __post_init__(self) -> None:
        if not (math.isfinite(self.amplitude_deg) and 0 <= self.amplitude_deg <= 60):
            raise ConfigError(f"must be in [0, 60] deg, got {self.amplitude_deg}", key="arms.amplitude_deg")
        if not (math.isfinite(self.freq_hz) and 0 < self.freq_hz <= 5):
            raise ConfigError(f"must be in (0, 5] Hz, got {self.freq_hz}", key="arms.freq_hz")

    def to_dict(self) -> dict:
        """The arm swing as a plain mapping, for ``truth.json``.

        Returns
        -------
        dict
            ``kind`` (``arm_swing``) and the fields.
        """
        return {"kind": "arm_swing", **asdict(self)}


def _ry(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    z, o = np.zeros_like(a), np.ones_like(a)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2)


class ArmKinematics:
    """The swinging arms of one run on a :class:`~.skeleton.Skeleton`.

    Rider mass ``mass``, CoG height ``h`` above the hinge with the arms at rest.

    Parameters
    ----------
    swing : ArmSwing
        The swing.
    skeleton : Skeleton
        The rider's skeleton (with upper-arm and forearm bodies).
    h : float
        CoG height above the hinge with the arms at rest [m].
    mass : float
        Rider mass [kg].
    run_index : int
        Run index (sets the phase).

    Raises
    ------
    ConfigError
        When the skeleton lacks the arm bodies.
    """

    #: Step of the five-point derivative stencil in the arm angle [rad] (truncation ~ step^4, rounding ~1e-12).
    STEP = 1e-3
    #: Grid of the splines of :meth:`profile` (cubic: interpolation error ~ (grid step)^4).
    GRID = 401

    def __init__(self, swing: ArmSwing, skeleton, h: float, mass: float, run_index: int = 0) -> None:
        missing = [b for b in ARM_SHOULDER if b not in skeleton.bodies]
        if missing:
            raise ConfigError(f"arm swing needs the bodies {missing}", key="rider.segments")
        self.swing, self.sk, self.mass = swing, skeleton, mass
        self.amp = math.radians(swing.amplitude_deg)
        self.w = 2 * math.pi * swing.freq_hz
        self.p0 = swing.phase_rad + run_index * swing.phase_step_rad
        self.pivots = skeleton.pivots_lean(np.asarray(h, float))                       # (b, 3) at rest
        self.arm = np.array([b in ARM_SHOULDER for b in skeleton.bodies])
        idx = {b: i for i, b in enumerate(skeleton.bodies)}
        self.shoulder = np.array([self.pivots[idx[ARM_SHOULDER[b]]] if b in ARM_SHOULDER else np.zeros(3)
                                  for b in skeleton.bodies])
        self.J0 = float(self._inertia(self._relative(np.zeros(1))[0])[0])
        self._splines = None

    # --- geometry as a function of the arm angle (vectorized over angles) ---
    def segments(self, th: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pivots (b, n, 3), rotations (b, n, 3, 3) and CoMs (b, n, 3) in the skeleton frame S.

        Parameters
        ----------
        th : numpy.ndarray
            Arm angles (n,) [rad].

        Returns
        -------
        pivots : numpy.ndarray
            Pivots (b, n, 3) [m].
        rotations : numpy.ndarray
            Rotations (b, n, 3, 3).
        coms : numpy.ndarray
            CoMs (b, n, 3) [m].
        """
        th = np.atleast_1d(np.asarray(th, float))
        R = _ry(th)                                                         # (n, 3, 3)
        eye = np.broadcast_to(np.eye(3), R.shape)
        Rb = np.where(self.arm[:, None, None, None], R[None], eye[None])    # (b, n, 3, 3)
        rel = self.pivots - self.shoulder                                   # (b, 3)
        piv = self.shoulder[:, None] + np.einsum("bnij,bj->bni", Rb, rel)
        rot = np.einsum("bnij,bjk->bnik", Rb, self.sk.rel_rot)
        com = piv + np.einsum("bnij,bj->bni", rot, self.sk.offsets)
        return piv, rot, com

    def _relative(self, th):
        """(c_i in L relative to G (b, n, 3), h (n,), beta (n,)) at arm angles th."""
        _, _, com = self.segments(th)
        g = np.einsum("b,bni->ni", self.sk.fractions, com)
        beta = np.arctan2(g[:, 0], g[:, 2])
        h = np.hypot(g[:, 0], g[:, 2])
        c = np.einsum("nij,bnj->bni", _ry(-beta), com - g[None])
        return c, h, beta

    def _inertia(self, c):
        return self.mass * np.einsum("b,bn->n", self.sk.fractions, c[..., 0] ** 2 + c[..., 2] ** 2)

    def angle(self, t):
        """Arm angle and its first two time derivatives.

        Parameters
        ----------
        t : float or array_like
            Time [s].

        Returns
        -------
        tuple
            The angle [rad] and its rates [rad/s, rad/s^2].
        """
        t = np.asarray(t, float)
        s, co = np.sin(self.w * t + self.p0), np.cos(self.w * t + self.p0)
        return self.amp * s, self.amp * self.w * co, -self.amp * self.w * self.w * s

    def _tables(self, th):
        """Functions of the arm angle.

        h, h', h'', beta, dJ, J' (= 2 sum m f (x x' + z z')), K = sum m f (z x' - x z'),
        P = sum m f (z x'' - x z'') (five-point stencil in the angle).
        """
        d = self.STEP
        st = [self._relative(th + k * d) for k in (-2, -1, 0, 1, 2)]
        c = [s_[0] for s_ in st]
        hh = [s_[1] for s_ in st]
        c1 = (c[0] - 8 * c[1] + 8 * c[3] - c[4]) / (12 * d)
        c2 = (-c[0] + 16 * c[1] - 30 * c[2] + 16 * c[3] - c[4]) / (12 * d * d)
        x, z = c[2][..., 0], c[2][..., 2]
        mf = self.mass * self.sk.fractions
        return {"h": hh[2], "h1": (hh[0] - 8 * hh[1] + 8 * hh[3] - hh[4]) / (12 * d),
                "h2": (-hh[0] + 16 * hh[1] - 30 * hh[2] + 16 * hh[3] - hh[4]) / (12 * d * d), "beta": st[2][2],
                "dJ": self._inertia(c[2]) - self.J0, "J1": 2 * np.einsum("b,bn->n", mf, x * c1[..., 0] + z * c1[..., 2]),
                "K": np.einsum("b,bn->n", mf, z * c1[..., 0] - x * c1[..., 2]),
                "P": np.einsum("b,bn->n", mf, z * c2[..., 0] - x * c2[..., 2])}

    def profile(self, t, exact: bool = False) -> dict:
        """The arm motion at times t: h and its rates, beta, dJ, dJ_dot, H and H_dot.

        ``h, h_dot, h_ddot`` [m...], ``beta`` [rad], ``dJ`` [kg m^2], ``dJ_dot`` [kg m^2/s], ``H`` [N m s],
        ``H_dot`` [N m] (the relative motion's angular momentum about the pitch axis, ``theta_dot K``, and its
        rate ``theta_dot^2 P + theta_ddot K``). The functions of the arm angle come from cubic splines on a
        grid of :data:`GRID` angles (``exact``: from the geometry at every call, 50x slower).

        Parameters
        ----------
        t : float or array_like
            Time(s) [s].
        exact : bool
            Compute from the geometry instead of the splines.

        Returns
        -------
        dict
            The quantities by name: floats for a scalar ``t``, else arrays.
        """
        scalar = np.ndim(t) == 0
        th, thd, thdd = (np.atleast_1d(v) for v in self.angle(t))
        if exact:
            f = self._tables(th)
        else:
            if self._splines is None:
                from scipy.interpolate import CubicSpline

                grid = np.linspace(-self.amp - 0.01, self.amp + 0.01, self.GRID)
                tab = self._tables(grid)
                self._splines = {k: CubicSpline(grid, v) for k, v in tab.items()}
            f = {k: sp(th) for k, sp in self._splines.items()}
        out = {"h": f["h"], "h_dot": f["h1"] * thd, "h_ddot": f["h2"] * thd ** 2 + f["h1"] * thdd, "beta": f["beta"],
               "dJ": f["dJ"], "dJ_dot": f["J1"] * thd, "H": f["K"] * thd, "H_dot": f["P"] * thd ** 2 + f["K"] * thdd}
        return {k: float(v[0]) for k, v in out.items()} if scalar else out

    def poses(self, A: np.ndarray, R_lean: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World pivots (b, n, 3) and rotations (b, n, 3, 3): the skeleton frame ``R_S = R_L Ry(-beta)``.

        Parameters
        ----------
        A : numpy.ndarray
            Ankle hinge positions (n, 3) [m].
        R_lean : numpy.ndarray
            Lean-frame rotations (n, 3, 3).
        t : numpy.ndarray
            Times (n,) [s].

        Returns
        -------
        pivots : numpy.ndarray
            World pivots (b, n, 3) [m].
        rotations : numpy.ndarray
            Rotations (b, n, 3, 3).
        """
        th = self.angle(t)[0]
        piv, rot, _ = self.segments(th)
        beta = self._relative(th)[2]
        RS = np.einsum("nij,njk->nik", R_lean, _ry(-beta))
        pos = A[None] + np.einsum("nij,bnj->bni", RS, piv)
        return pos, np.einsum("nij,bnjk->bnik", RS, rot)
