"""What every effect of the library is made of: its parameters, the samples it acts on and its interface.

:class:`ParamInfo` describes a parameter, :class:`ModelContext` holds the samples an effect acts on, and
:class:`Candidate` is the interface every effect implements. The effects themselves are in
:mod:`euc_ros.core.model.effects`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from euc_ros.core.model.terms import EucParams


@dataclass(frozen=True)
class ParamInfo:
    """One fitted parameter: reported name, unit, bounds, start value, typical magnitude, plausible range.

    ``low``/``high`` are the physical range: resistances, drag areas and the tilt coupling are not
    negative (a negative drag area is a force that pushes the rider, not drag), a mass or an inertia
    stays positive. A fit that ends on a bound explains nothing (the analysis does not select it).

    ``scale`` is the parameter's typical magnitude in practice: it scales the least-squares problem and
    is the prior scale of the tie-break between candidates the data cannot tell apart (a Motive system
    stamps all rigid bodies of a frame together, so a rider/EUC time offset is typically ~0; a tyre's
    rolling radius is known to ~1 cm; a rider's mass to ~5 kg; ...).

    ``plausible`` is the range the parameter takes for riders on lab floors (:data:`PLAUSIBLE_SOURCES`
    gives the reference of each, ``docs/effects.md`` the table), narrower than the fitting bounds: a fit
    outside it is not named as the effect (the residual analysis refuses the name). None: no range
    beyond the bounds.

    Parameters
    ----------
    name : str
        Reported name of the parameter.
    unit : str
        Its SI unit, as printed.
    low, high : float
        Fitting bounds (the physical range).
    start : float
        Starting value of the fit.
    scale : float
        Typical magnitude (least-squares scaling and tie-break prior), in the parameter's unit.
    reported : bool
        Whether the parameter appears in the reported values.
    plausible : tuple of float, optional
        Plausible range (low, high) for riders on lab floors; None: the bounds.
    """

    name: str
    unit: str
    low: float
    high: float
    start: float = 0.0
    scale: float = 1.0
    reported: bool = True
    plausible: tuple[float, float] | None = None


#: Where each plausible range of the library comes from, by ``effect.parameter`` (docs/effects.md).
PLAUSIBLE_SOURCES: dict[str, str] = {
    "rolling_resistance.c_rr": (
        "pneumatic tyres on hard smooth floors 0.002-0.01, several times more on carpet and gym mats "
        "(D. G. Wilson, Bicycling Science, 3rd ed., MIT Press 2004, ch. 5); 0.05 covers a soft EUC tyre on a mat"),
    "viscous_friction.c_v": (
        "the largest plausible resistance at riding speed, over that speed: rolling resistance at 0.05 of the "
        "weight (~45 N for 90 kg) plus air drag at 1 m^2 and 3 m/s (~5 N), at a typical 1.7 m/s: 30 N s/m"),
    "aero_drag.cda_m2": (
        "drag areas of cyclists 0.2-0.5 m^2 from racing to upright (P. Debraux et al., Aerodynamic drag in "
        "cycling: methods of assessment, Sports Biomechanics 10(3):197-218, 2011); a standing adult about "
        "0.8-0.9 m^2 (S. F. Hoerner, Fluid-Dynamic Drag, 1965, ch. 3): 0.2-1.0 m^2 for an EUC rider"),
    "ground_slope.alpha_deg": (
        "lab floors are level to well under a degree; a mocap ground plane set on a ramp at most the steepest "
        "accessible ramp, 1:12 = 4.8 deg (2010 ADA Standards for Accessible Design, 405.2): +-5 deg"),
    "wheel_radius_error.delta_r_m": (
        "tyre deflection under a rider 5-15 mm; a wrong nominal size (14/16/18 in tyres differ by 25 mm): "
        "+-30 mm"),
    "mocap_time_offset.dt_ms": (
        "one Motive system stamps all rigid bodies of a frame together (0 ms); separately synchronised "
        "systems or a resampled export: a few frames at 60-120 Hz, +-50 ms"),
    "rider_mass_error.delta_m_kg": (
        "a weighed rider is known to ~1 kg; a mass guessed from build is off by up to two standard deviations "
        "of adult body mass (~15 kg each, e.g. NCD-RisC body-mass surveys), a backpack adds up to ~10 kg: "
        "-30 to +40 kg"),
    "rider_inertia_error.delta_j_kgm2": (
        "a standing adult's pitch inertia about the CoG is 10-17 kg m^2 (segment tables: P. de Leva, J. "
        "Biomech. 29(9):1223-1230, 1996); tables differ by 20-30 %, arms held out add ~3 kg m^2, a backpack "
        "~1-2 kg m^2: -10 to +14 kg m^2"),
    "tilt_gravity.gain": (
        "1 is the coupling of a rider tilted with the EUC; a rider leaning further into the turn than the EUC "
        "(up to about twice its tilt): 0-2.5"),
    "time_varying_h.amplitude_m": (
        "the CoG of a rider flexing the knees moves by up to ~0.2 m (a squat from standing moves it by ~0.3 m, "
        "not held while riding): 0-0.2 m"),
    "time_varying_h.period_s": "any period the fit allows (1-60 s): the amplitude is what is implausible",
    "wheel_body_friction.c_wb": (
        "hub-motor bearing and seal friction: well under 1 N m s/rad; 3 N m s/rad with a dragging brake"),
}

@dataclass
class ModelContext:
    """The signals of one recording as a candidate model sees them (valid samples only).

    Candidates may replace ``phi``/``phi_dot``/``phi_ddot`` (timing) and put parameter overrides
    (scalars or per-sample arrays) into ``overrides``; ``extra_Q`` collects generalized forces.

    Parameters
    ----------
    t : numpy.ndarray
        Sample times (n,) [s].
    x_dot, x_ddot : numpy.ndarray
        Wheel-centre speed [m/s] and acceleration [m/s^2] along travel (n,).
    gamma, gamma_dot, gamma_ddot : numpy.ndarray
        EUC body pitch [rad] and its rates [rad/s, rad/s^2] (n,).
    phi, phi_dot, phi_ddot : numpy.ndarray
        Rider pitch about the ankle hinge [rad] and its rates [rad/s, rad/s^2] (n,).
    psi, psi_dot : numpy.ndarray
        Yaw [rad] and yaw rate [rad/s] (n,).
    theta : numpy.ndarray
        EUC tilt (roll) [rad] (n,).
    params : EucParams
        Nominal model parameters.
    extras : dict
        Further per-recording signals by name (floor slope, wheel-centre acceleration, ...).
    overrides : dict
        Parameter overrides (scalars or arrays (n,)) set by candidates.
    extra_Q : numpy.ndarray, optional
        Accumulated extra generalized force (n, 3) [N, N m, N m].
    mask : numpy.ndarray, optional
        Usable samples (n,) a candidate set; None: all.
    """

    t: np.ndarray
    x_dot: np.ndarray
    x_ddot: np.ndarray
    gamma: np.ndarray
    gamma_dot: np.ndarray
    gamma_ddot: np.ndarray
    phi: np.ndarray
    phi_dot: np.ndarray
    phi_ddot: np.ndarray
    psi: np.ndarray
    psi_dot: np.ndarray
    theta: np.ndarray
    params: EucParams
    extras: dict = field(default_factory=dict)
    overrides: dict = field(default_factory=dict)
    extra_Q: np.ndarray | None = None
    mask: np.ndarray | None = None

    def p(self) -> EucParams:
        """Parameters with the overrides applied.

        Returns
        -------
        EucParams
            ``params`` with ``overrides`` applied.
        """
        return self.params.with_values(self.overrides) if self.overrides else self.params

    def add_force(self, dQ: np.ndarray) -> None:
        """Accumulate a generalized force (n, 3).

        Parameters
        ----------
        dQ : numpy.ndarray
            Generalized force (n, 3) [N, N m, N m] added to ``extra_Q``.
        """
        self.extra_Q = dQ if self.extra_Q is None else self.extra_Q + dQ

    def copy(self) -> "ModelContext":
        """Shallow copy with fresh overrides/extra_Q (arrays shared, never modified in place).

        Returns
        -------
        ModelContext
            The copy, with ``overrides`` copied, ``extra_Q`` and ``mask`` None.
        """
        new = object.__new__(type(self))          # the fields shared as dataclasses.replace shares them, faster
        new.__dict__.update(self.__dict__)
        new.overrides, new.extra_Q, new.mask = dict(self.overrides), None, None
        return new


def jacobian_G(ctx: ModelContext, p: EucParams) -> tuple[np.ndarray, np.ndarray]:
    """Rows dG_x/dq and dG_z/dq (n, 3) of the rider CoG (Appendix A geometry).

    Parameters
    ----------
    ctx : ModelContext
        The recording's signals (``gamma``, ``phi`` used).
    p : EucParams
        Model parameters (``h``, ``l0`` used).

    Returns
    -------
    jx, jz : numpy.ndarray
        dG_x/dq and dG_z/dq (n, 3) with q = (x, gamma, phi) [1, m/rad, m/rad].
    """
    n = ctx.gamma.shape[0]
    h = np.asarray(p.h, float)
    if h.ndim:
        h = np.broadcast_to(h, (n,))
    jx, jz = np.empty((n, 3)), np.empty((n, 3))          # the columns side by side (as np.stack puts them)
    jx[:, 0], jx[:, 1], jx[:, 2] = 1.0, -p.l0 * np.cos(ctx.gamma), h * np.cos(ctx.phi)
    jz[:, 0], jz[:, 1], jz[:, 2] = 0.0, p.l0 * np.sin(ctx.gamma), -h * np.sin(ctx.phi)
    return jx, jz


class Candidate:
    """Base class: a named physical extension of the model with fitted parameters."""

    name = "none"
    params: tuple[ParamInfo, ...] = ()
    formula = ""

    def modify(self, ctx: ModelContext, theta: np.ndarray) -> None:
        """Phase 1: change parameters or states (default: nothing).

        Parameters
        ----------
        ctx : ModelContext
            The recording's signals, changed in place.
        theta : numpy.ndarray
            The effect's parameters (n_params,).
        """

    def force(self, ctx: ModelContext, theta: np.ndarray) -> np.ndarray | None:
        """Phase 2: extra generalized force (n, 3) evaluated with the final parameters (default: none).

        Parameters
        ----------
        ctx : ModelContext
            The recording's signals after every effect's :meth:`modify`.
        theta : numpy.ndarray
            The effect's parameters (n_params,).

        Returns
        -------
        numpy.ndarray or None
            The generalized force (n, 3) [N, N m, N m], or None for none.
        """
        return None

    def starts(self) -> list[np.ndarray]:
        """Initial guesses of the parameters (several for multi-modal fits).

        Returns
        -------
        list of numpy.ndarray
            Starting parameter vectors (n_params,).
        """
        return [np.array([q.start for q in self.params], float)]

    def report(self, theta: np.ndarray) -> dict[str, float]:
        """Parameters as reported in the JSON (spec names and units).

        Parameters
        ----------
        theta : numpy.ndarray
            The effect's parameters (n_params,).

        Returns
        -------
        dict of str to float
            Reported parameter values by name, in their units.
        """
        return {q.name: float(v) for q, v in zip(self.params, theta) if q.reported}

    @property
    def checked(self) -> tuple[ParamInfo, ...]:
        """The parameters whose plausible range is checked, by their reported names (keys of :meth:`report`)."""
        return tuple(q for q in self.params if q.reported)

    def plausible_range(self, param: str) -> tuple[float, float] | None:
        """Plausible range of a reported parameter: the override of :func:`with_plausible`, else its ParamInfo's.

        Parameters
        ----------
        param : str
            A reported parameter name.

        Returns
        -------
        tuple of float or None
            (low, high) in the parameter's unit, or None when it has no plausible range.
        """
        over = getattr(self, "plausible_overrides", {})
        if param in over:
            return over[param]
        return next((q.plausible for q in self.checked if q.name == param), None)

    def implausible(self, theta: np.ndarray) -> list[dict]:
        """The reported parameters of ``theta`` outside their plausible range (empty: plausible).

        Each record: ``effect``, ``parameter``, ``value``, ``unit``, ``plausible`` ([low, high]).

        Parameters
        ----------
        theta : numpy.ndarray
            The effect's parameters (n_params,).

        Returns
        -------
        list of dict
            One record per implausible parameter.
        """
        values = self.report(theta)
        out = []
        for q in self.checked:
            rng, v = self.plausible_range(q.name), values.get(q.name)
            if rng is not None and v is not None and not rng[0] <= v <= rng[1]:
                out.append({"effect": self.name, "parameter": q.name, "value": float(v), "unit": q.unit,
                            "plausible": [float(rng[0]), float(rng[1])]})
        return out

    @property
    def n_params(self) -> int:
        """Number of fitted parameters."""
        return len(self.params)
