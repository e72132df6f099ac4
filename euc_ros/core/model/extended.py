"""The paper's 3-DoF model extended with effects.

One :class:`Model` for the residual analysis, ``identify`` and the online torque estimator.

A model is a list of effects (:class:`~euc_ros.core.model.effects.Candidate`) with the parameter vector
``x = [h, theta_1..., theta_2...]``. The residual analysis fits ``x`` (:meth:`Model.residual`); once an effect
is selected (``euc-ros residual`` reports its name and parameters), :meth:`Model.from_report` builds the
model with those values fixed and :meth:`Model.torques` computes M_d1 and M_d2 with the effect's generalized
force or parameter change included, so the residual drops in the offline identification and live.

Examples
--------
>>> from euc_ros.core.session import default_session
>>> from euc_ros.core.model.terms import EucParams
>>> model = Model.from_report(EucParams.from_session(default_session(), 0.61), {"ground_slope": {"alpha_deg": 2.0}})
>>> model.name, model.label, model.n_params
('ground_slope', '3dof+ground_slope', 2)
>>> model.x_.round(4).tolist()
[0.61, 2.0]
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from euc_ros.core.errors import ConfigError
from euc_ros.core.model.candidate import Candidate, ModelContext
from euc_ros.core.model.effects import FloorGeometry, make_candidates, theta_from_report
from euc_ros.core.model.terms import EucParams
from euc_ros.core.model.torque import torque_difference, torques

#: Effects that need the recording's geometry (future samples) and are offline only.
OFFLINE_ONLY = {"mocap_time_offset"}

#: The states :meth:`Model.torques` takes, in the order of :class:`~euc_ros.core.model.effects.ModelContext`.
SAMPLE_NAMES = ("t", "x_dot", "x_ddot", "gamma", "gamma_dot", "gamma_ddot", "phi", "phi_dot", "phi_ddot", "psi",
                "psi_dot", "theta")

#: h bounds of the joint fits [m].
H_BOUNDS = (0.05, 1.6)

#: Key of a prepared recording's ``ctx.extras`` holding h held fixed [m]: :meth:`Model.residual` then uses it
#: instead of ``x[0]``, so every fit of the recording leaves h where it is held (the residual does not depend on
#: ``x[0]``, whose fitted value stays at its start).
HELD_H = "h_held"


def parse_effect_assignments(effects: list[str], assignments: list[str]) -> dict[str, dict[str, float]]:
    """``["ground_slope"]``, ``["ground_slope.alpha_deg=2.9"]`` -> ``{"ground_slope": {"alpha_deg": 2.9}}``.

    Parameters
    ----------
    effects : list of str
        Effect names (empty strings ignored).
    assignments : list of str
        ``<effect>.<parameter>=<number>`` items (empty strings ignored).

    Returns
    -------
    dict of str to dict of str to float
        Parameter values by effect, every listed effect present.

    Raises
    ------
    ConfigError
        Naming the assignment that is malformed or refers to an effect not listed.
    """
    listed = [e for e in effects if e]
    out: dict[str, dict[str, float]] = {e: {} for e in listed}
    for item in assignments:
        if not item:
            continue
        lhs, sep, value = item.partition("=")
        effect, dot, param = lhs.strip().partition(".")
        try:
            number = float(value)
        except ValueError:
            number = None
        if not sep or not dot or not param.strip() or number is None:
            raise ConfigError("expected '<effect>.<parameter>=<number>'", key=f"effect_parameters: {item}")
        if effect not in listed:
            raise ConfigError(f"effect {effect!r} is not in the list of effects ({', '.join(listed) or 'none'})",
                              key=f"effect_parameters: {item}")
        out[effect][param.strip()] = number
    return out


def m11(p: EucParams):
    """First diagonal entry of the mass matrix, eq (6): m + m0 + mw + Jw / R^2.

    Parameters
    ----------
    p : EucParams
        Model parameters (arrays broadcast).

    Returns
    -------
    float or numpy.ndarray
        m11 [kg].
    """
    return p.m + p.m0 + p.mw + p.Jw / np.asarray(p.R, float) ** 2


#: The fields of ``R m11`` (:func:`m11`).
_M11_FIELDS = ("R", "m", "m0", "mw", "Jw")


@dataclass
class Model:
    """The paper's 3-DoF model plus a list of effects; parameter vector ``x = [h, theta_1..., theta_2...]``.

    Parameters
    ----------
    effects : list of Candidate
        The effects, in selection order.
    params_ : EucParams, optional
        Nominal parameters of a model with fixed values (:meth:`from_report`; used by :meth:`torques`).
    x_ : ndarray, optional
        The fixed parameter vector of such a model (``x_[0]`` is ``params_.h``).
    """

    effects: list[Candidate] = field(default_factory=list)
    params_: EucParams | None = field(default=None, compare=False, repr=False)
    x_: np.ndarray | None = field(default=None, compare=False, repr=False)

    @classmethod
    def from_report(cls, params: EucParams, effects: Mapping[str, Mapping[str, float]] | None = None, *,
                    online: bool = False) -> "Model":
        """The model of reported effects with their values fixed (``identify --effect``, ``torque_estimator``).

        Parameters
        ----------
        params : EucParams
            Nominal parameters including the identified h.
        effects : mapping
            ``{effect name: {parameter: value}}`` with the names and units of the residual report.
        online : bool
            Refuse effects that need future samples (time offsets).

        Returns
        -------
        Model
            With ``params_`` and ``x_`` set.

        Raises
        ------
        ConfigError
            An unknown effect, a missing parameter, or with ``online`` an effect that needs future samples.
        """
        effects = dict(effects or {})
        cands = make_candidates(list(effects))
        # a ground slope measured as the floor of a level lab (residual JSON: level_lab = 1) is the floor
        # geometry model, not gravity tilted against the mocap frame
        for k, c in enumerate(cands):
            vals = effects[c.name]
            if c.name == "ground_slope" and float(vals.get("level_lab", 0.0)):
                cands[k] = FloorGeometry(float(vals.get("alpha_deg", 0.0)), float(vals.get("alpha_y_deg", 0.0)))
        if online:
            bad = [c.name for c in cands if c.name in OFFLINE_ONLY]
            if bad:
                raise ConfigError(f"effect {bad[0]!r} needs future samples and is available offline only",
                                  key="effects")
        x = np.concatenate([[float(params.h)]] + [theta_from_report(c, effects[c.name]) for c in cands])
        return cls(cands, params, x)

    @property
    def label(self) -> str:
        """``3dof`` or ``3dof+<effect>+...`` (the name of the model in ``identify`` and live)."""
        return "+".join(["3dof"] + [c.name for c in self.effects])

    def torques(self, samples: Mapping[str, object], *, h: float | None = None,
                extras: Mapping | None = None) -> tuple[np.ndarray, np.ndarray]:
        """M_d1, M_d2 [N m] of the model with its fixed values (:meth:`from_report`) for samples.

        Parameters
        ----------
        samples : mapping of str to array_like
            The samples' states by name, :data:`SAMPLE_NAMES` (arrays of equal length or scalars) [SI];
            ``psi``, ``psi_dot`` and ``theta`` default to 0.
        h : float, optional
            h to use instead of the fixed one [m].
        extras : dict, optional
            Further inputs some effects need (the recording's geometry).

        Returns
        -------
        tuple of ndarray
            M_d1 and M_d2 [N m].

        Raises
        ------
        ConfigError
            A model without fixed values.
        """
        if self.params_ is None or self.x_ is None:
            raise ConfigError("the model has no fixed values: build it with Model.from_report", key="effects")
        defaults = {"psi": 0.0, "psi_dot": 0.0, "theta": 0.0}
        arrays = [np.atleast_1d(np.asarray(samples[k] if k in samples else defaults[k], float)) for k in SAMPLE_NAMES]
        n = max(a.shape[0] for a in arrays)
        arrays = [np.broadcast_to(a, (n,)) for a in arrays]
        params = self.params_ if h is None else self.params_.with_h(h)
        ctx = ModelContext(*arrays, params=params, extras=dict(extras or {}))
        _, thetas = self.split(self.x_)
        for c, th in zip(self.effects, thetas):
            c.modify(ctx, th)
        for c, th in zip(self.effects, thetas):
            dQ = c.force(ctx, th)
            if dQ is not None:
                ctx.add_force(dQ)
        return torques(ctx.gamma, ctx.phi, ctx.gamma_dot, ctx.phi_dot, ctx.x_ddot, ctx.gamma_ddot, ctx.phi_ddot,
                       ctx.p(), extra_Q=ctx.extra_Q)

    @property
    def name(self) -> str:
        """``none`` or the effect names joined with ``+`` in selection order."""
        return "+".join(c.name for c in self.effects) or "none"

    @property
    def n_params(self) -> int:
        """1 (h) plus every effect's parameters."""
        return 1 + sum(c.n_params for c in self.effects)

    def split(self, x: np.ndarray) -> tuple[float, list[np.ndarray]]:
        """The pair (h, [theta per effect]) of ``x``.

        Parameters
        ----------
        x : numpy.ndarray
            The parameter vector ``[h, theta_1..., theta_2...]``.

        Returns
        -------
        h : float
            CoG height [m].
        thetas : list of numpy.ndarray
            Each effect's parameters, in effect order.
        """
        out, k = [], 1
        for c in self.effects:
            out.append(np.asarray(x[k:k + c.n_params], float))
            k += c.n_params
        return float(x[0]), out

    def residual(self, rec, x: np.ndarray, extra_dQ: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
        """The pair (M_d1 - M_d2 [N m], usable mask) of the model with parameters ``x`` on ``rec``.

        ``rec`` is a prepared recording (:class:`~euc_ros.core.states.contexts.Recording`); ``extra_dQ``: a
        further generalized force, for the discovery's sensitivities. A recording whose ``ctx.extras`` holds
        :data:`HELD_H` is evaluated at that h, whatever ``x[0]``.

        Parameters
        ----------
        rec : Recording
            The prepared recording.
        x : numpy.ndarray
            The parameter vector ``[h, theta_1..., theta_2...]``.
        extra_dQ : numpy.ndarray, optional
            Further generalized force (n, 3) [N, N m, N m].

        Returns
        -------
        residual : numpy.ndarray
            ``M_d1 - M_d2`` (n,) [N m] scaled to the nominal ``R m11``; 0 where not usable.
        mask : numpy.ndarray
            Usable samples (n,), bool.
        """
        h, thetas = self.split(x)
        h = float(rec.ctx.extras.get(HELD_H, h))
        ctx = rec.ctx.copy()
        ctx.overrides["h"] = h
        ctx.params = ctx.params.with_h(h)
        mask = np.ones(ctx.t.shape[0], bool)
        for c, th in zip(self.effects, thetas):
            c.modify(ctx, th)
            if ctx.mask is not None:
                mask &= ctx.mask
                ctx.mask = None
        for c, th in zip(self.effects, thetas):
            dQ = c.force(ctx, th)
            if dQ is not None:
                ctx.add_force(dQ)
        if extra_dQ is not None:
            ctx.add_force(extra_dQ)
        p_mod = ctx.p()
        diff = torque_difference(ctx.gamma, ctx.phi, ctx.gamma_dot, ctx.phi_dot, ctx.x_ddot, ctx.gamma_ddot,
                                 ctx.phi_ddot, p_mod, extra_Q=ctx.extra_Q)
        # M_d1 - M_d2 = R m11 (x_ddot - x_ddot*): compare models on the acceleration mismatch scaled by the
        # NOMINAL R m11, so a parameter change (R, m) cannot shrink the residual by rescaling the equations.
        # For the base model and every effect that keeps R and m this is exactly M_d1 - M_d2.
        p_nom = rec.ctx.params
        nominal = p_nom.R * m11(p_nom)
        if all(getattr(p_mod, f) is getattr(p_nom, f) for f in _M11_FIELDS) and np.ndim(nominal) == 0 \
                and np.isfinite(nominal) and nominal != 0:
            r = diff            # the same R m11 over itself: the ratio is exactly 1
        else:
            r = diff * (nominal / (np.asarray(p_mod.R, float) * m11(p_mod)))
        mask &= np.isfinite(r)
        return np.where(mask, r, 0.0), mask

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of ``x``.

        Returns
        -------
        low, high : numpy.ndarray
            Bounds of ``x``, h's first [m].
        """
        lo = [H_BOUNDS[0]] + [q.low for c in self.effects for q in c.params]
        hi = [H_BOUNDS[1]] + [q.high for c in self.effects for q in c.params]
        return np.array(lo), np.array(hi)

    def scales(self) -> np.ndarray:
        """Typical magnitudes of ``x`` (least-squares scaling).

        Returns
        -------
        numpy.ndarray
            Scale of each entry of ``x`` (h's 0.1 m first).
        """
        return np.array([0.1] + [q.scale for c in self.effects for q in c.params])

    def starts(self, h0: float, fixed: np.ndarray | None = None) -> list[np.ndarray]:
        """Starting points: the last effect's starts appended to ``fixed`` (the previous fit) or defaults.

        Parameters
        ----------
        h0 : float
            Starting CoG height [m] when ``fixed`` is None.
        fixed : numpy.ndarray, optional
            The previous fit's vector (h and the effects before the new ones).

        Returns
        -------
        list of numpy.ndarray
            Starting vectors of ``x``: every combination of the new effects' starts.
        """
        head = np.array([h0]) if fixed is None else np.asarray(fixed, float)
        known = head.size - 1
        rest = []
        k = 0
        for c in self.effects:
            if k >= known:
                rest.append(c.starts())
            k += c.n_params
        if not rest:
            return [head]
        combos = [head]
        for options in rest:
            combos = [np.concatenate([base, s]) for base in combos for s in options]
        return combos

    def report(self, x: np.ndarray) -> dict[str, float]:
        """All effect parameters by their reported names.

        Parameters
        ----------
        x : numpy.ndarray
            The parameter vector ``[h, theta_1..., theta_2...]``.

        Returns
        -------
        dict of str to float
            Reported values of every effect's parameters.
        """
        _, thetas = self.split(x)
        out: dict[str, float] = {}
        for c, th in zip(self.effects, thetas):
            out.update(c.report(th))
        return out
