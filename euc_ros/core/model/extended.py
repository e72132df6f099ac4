"""The paper's model extended with selected effects, for ``identify`` and the online torque estimator.

Step 5 of the residual analysis: once an effect is selected (``euc-ros residual`` reports its name and
parameters), the extended model computes M_d1 and M_d2 with the effect's generalized force or
parameter change included, so the residual drops in the offline identification and live.

Examples
--------
>>> from euc_ros.core.session import default_session
>>> from euc_ros.core.model.terms import EucParams
>>> model = ExtendedModel(EucParams.from_session(default_session(), 0.61), {"ground_slope": {"alpha_deg": 2.0}})
>>> model.name
'3dof+ground_slope'
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from euc_ros.core.errors import ConfigError
from euc_ros.core.model.effects import FloorGeometry, ModelContext, make_candidates, theta_from_report
from euc_ros.core.model.terms import EucParams
from euc_ros.core.model.torque import torques

#: Effects that need the recording's geometry (future samples) and are offline only.
OFFLINE_ONLY = {"mocap_time_offset"}


def parse_effect_assignments(effects: list[str], assignments: list[str]) -> dict[str, dict[str, float]]:
    """``["ground_slope"]``, ``["ground_slope.alpha_deg=2.9"]`` -> ``{"ground_slope": {"alpha_deg": 2.9}}``.

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


class ExtendedModel:
    """M_d1 and M_d2 of the 3-DoF model plus configured effects.

    Parameters
    ----------
    params : EucParams
        Nominal parameters including the identified h.
    effects : mapping
        ``{effect name: {parameter: value}}`` with the names and units of the residual report.
    online : bool
        Refuse effects that need future samples (time offsets).
    """

    def __init__(self, params: EucParams, effects: Mapping[str, Mapping[str, float]] | None = None, *,
                 online: bool = False):
        self.params = params
        effects = dict(effects or {})
        self.candidates = make_candidates(list(effects))
        # a ground slope measured as the floor of a level lab (residual JSON: level_lab = 1) is the floor
        # geometry model, not gravity tilted against the mocap frame
        for k, c in enumerate(self.candidates):
            vals = effects[c.name]
            if c.name == "ground_slope" and float(vals.get("level_lab", 0.0)):
                self.candidates[k] = FloorGeometry(float(vals.get("alpha_deg", 0.0)),
                                                   float(vals.get("alpha_y_deg", 0.0)))
        if online:
            bad = [c.name for c in self.candidates if c.name in OFFLINE_ONLY]
            if bad:
                raise ConfigError(f"effect {bad[0]!r} needs future samples and is available offline only",
                                  key="effects")
        self.thetas = [theta_from_report(c, effects[c.name]) for c in self.candidates]

    @property
    def name(self) -> str:
        """``3dof`` or ``3dof+<effect>+...``."""
        return "+".join(["3dof"] + [c.name for c in self.candidates])

    def torques(self, *, t, x_dot, x_ddot, gamma, gamma_dot, gamma_ddot, phi, phi_dot, phi_ddot, psi=0.0,
                psi_dot=0.0, theta=0.0, h=None, extras=None) -> tuple[np.ndarray, np.ndarray]:
        """M_d1, M_d2 [N m] for samples (arrays of equal length or scalars)."""
        arrays = [np.atleast_1d(np.asarray(v, float)) for v in
                  (t, x_dot, x_ddot, gamma, gamma_dot, gamma_ddot, phi, phi_dot, phi_ddot, psi, psi_dot, theta)]
        n = max(a.shape[0] for a in arrays)
        arrays = [np.broadcast_to(a, (n,)) for a in arrays]
        params = self.params if h is None else self.params.with_h(h)
        ctx = ModelContext(*arrays, params=params, extras=dict(extras or {}))
        for c, th in zip(self.candidates, self.thetas):
            c.modify(ctx, th)
        for c, th in zip(self.candidates, self.thetas):
            dQ = c.force(ctx, th)
            if dQ is not None:
                ctx.add_force(dQ)

        return torques(ctx.gamma, ctx.phi, ctx.gamma_dot, ctx.phi_dot, ctx.x_ddot, ctx.gamma_ddot, ctx.phi_ddot,
                       ctx.p(), extra_Q=ctx.extra_Q)
