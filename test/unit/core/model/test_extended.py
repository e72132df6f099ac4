"""The extended model: configuration parsing and agreement with the analysis' candidate models.

Tolerances: the extended model and the candidate models run the same formulas on the same inputs:
equal to the last bits (atol 1e-12 on torques up to ~40 N m is ~1000 ulps).
"""
import numpy as np
import pytest

from euc_ros.core.errors import ConfigError
from euc_ros.core.model.extended import Model, parse_effect_assignments
from euc_ros.core.model.terms import EucParams
from euc_ros.core.model.torque import torques
from euc_ros.core.session import default_session


def test_parse_assignments():
    assert parse_effect_assignments(["ground_slope"], ["ground_slope.alpha_deg=2.9"]) == \
        {"ground_slope": {"alpha_deg": 2.9}}
    with pytest.raises(ConfigError, match="not in the list of effects"):
        parse_effect_assignments(["ground_slope"], ["rolling_resistance.c_rr=0.1"])
    for bad in ("ground_slope.alpha_deg", "ground_slope=1", "ground_slope.alpha_deg=abc"):
        with pytest.raises(ConfigError, match="expected"):
            parse_effect_assignments(["ground_slope"], [bad])


def test_online_refuses_offline_only_effects():
    p = EucParams.from_session(default_session(), 0.61)
    with pytest.raises(ConfigError, match="offline only"):
        Model.from_report(p, {"mocap_time_offset": {"dt_ms": 10.0}}, online=True)


def test_zero_effect_equals_the_paper_model():
    p = EucParams.from_session(default_session(), 0.61)
    rng = np.random.default_rng(0)
    s = {k: rng.normal(0, 0.1, 50) for k in ("x_dot", "x_ddot", "gamma", "gamma_dot", "gamma_ddot", "phi",
                                              "phi_dot", "phi_ddot", "psi", "psi_dot", "theta")}
    m = Model.from_report(p, {"ground_slope": {"alpha_deg": 0.0}, "viscous_friction": {"c_v": 0.0}})
    m1, m2 = m.torques({"t": np.arange(50) / 120, **s})
    r1, r2 = torques(s["gamma"], s["phi"], s["gamma_dot"], s["phi_dot"], s["x_ddot"], s["gamma_ddot"],
                     s["phi_ddot"], p)
    np.testing.assert_allclose(m1, r1, atol=1e-12)
    np.testing.assert_allclose(m2, r2, atol=1e-12)
    assert m.label == "3dof+ground_slope+viscous_friction" and m.name == "ground_slope+viscous_friction"


def test_a_reported_fit_is_the_same_model_with_the_same_values():
    """One model type: the values the residual analysis reports (Model.report) rebuild the same model with the
    same parameter vector (Model.from_report), for every library effect with a plain parameter vector."""
    from euc_ros.core.model.effects import FloorGeometry, TimeVaryingH, make_candidates

    p = EucParams.from_session(default_session(), 0.61)
    rng = np.random.default_rng(3)
    checked = 0
    for c in make_candidates():
        if isinstance(c, (FloorGeometry, TimeVaryingH)) or c.n_params == 0:
            continue
        lo = np.array([q.low for q in c.params])
        hi = np.array([q.high for q in c.params])
        x = np.concatenate([[0.58], lo + (hi - lo) * rng.uniform(0.2, 0.8, c.n_params)])
        fitted = Model([c])
        again = Model.from_report(p.with_h(0.58), {c.name: fitted.report(x)})
        assert again.name == fitted.name == c.name and again.n_params == fitted.n_params
        np.testing.assert_allclose(again.x_, x, rtol=1e-12, err_msg=c.name)
        checked += 1
    assert checked >= 5


def test_a_model_without_values_has_no_torques():
    with pytest.raises(ConfigError, match="from_report"):
        Model().torques(dict.fromkeys(("t", "x_dot", "x_ddot", "gamma", "gamma_dot", "gamma_ddot", "phi", "phi_dot",
                                       "phi_ddot"), 0.0))
