"""The compiled simulator gives the reference simulator's states within the integrator's tolerance.

Both methods run DOP853 with the same rtol and atol on the same equations: the reference calls the
Python right-hand side through ``scipy.integrate.solve_ivp``, the default compiles the right-hand side
and the integrator (:mod:`euc_ros.core.ridesim.compiled`). Every effect of the catalogue, every floor
component, every external force and both rider motions are checked.

Tolerance. DOP853 keeps each step's local error within ``sc_i = atol + rtol |y_i|`` in the RMS norm over
the n states, so one component's local error is at most ``sqrt(n) sc_i``. The closed loop does not amplify
errors (it is stable; position-like states integrate velocity errors that the speed loop removes), so a
solution's global error after N steps is at most the sum of its local errors, ``N sqrt(n) sc_i``, and two
solutions differ by at most twice that: ``2 N sqrt(n) (atol + rtol max|y_i|)`` per state component.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from euc_ros.core.ridesim import EFFECTS, MANEUVERS, MocapNoise, RideConfig, make_effects, simulate_ride
from euc_ros.core.ridesim import external as external_mod
from euc_ros.core.ridesim import floors as floors_mod
from euc_ros.core.ridesim.external import ExternalForce
from euc_ros.core.ridesim.floors import FloorProfile
from euc_ros.core.ridesim.rider_motion import ArmSwing, PedalFlex

#: One case per floor kind (lab X of the runs: -5 m onwards heading +X, +5 m onwards heading -X).
FLOOR_CASES = {
    "ramp": {"slope_deg": 2.0},
    "ramp_from": {"slope_deg": 3.0, "x0_m": -3.0, "width_m": 0.5},
    "bump": {"height_m": 0.05, "x0_m": -3.5, "width_m": 0.3},
    "step": {"height_m": 0.03, "x0_m": -3.5, "width_m": 0.1},
}
#: One case per external force.
EXTERNAL_CASES = {
    "rope": {"k_n_per_m": 40.0, "anchor_x_m": 2.0, "hand_m": 1.0},
    "headwind": {"wind_m_per_s": 4.0, "cda_m2": 0.6},
    "torque_ripple": {"amp_nm": 3.0, "per_turn": 16.0},
    "contact_drag": {"c_n_s2_per_m2": 3.0},
    "wheel_harmonics": {"amp2_n": 8.0, "amp3_n": 6.0, "phase3_rad": 0.7},
    "lab_bump": {"amp_n": 30.0, "x0_m": -3.0, "width_m": 1.0},
}


def _config(**kw) -> RideConfig:
    """Short noise-free rides: 0.5 s settling and 1.5 s recorded (the speed ramps start at 0.5-1 s)."""
    base = {"maneuver": "deceleration", "runs": 1, "seed": 4, "duration_s": 1.5, "settle_s": 0.5,
            "noise": MocapNoise.none()}
    return RideConfig(**{**base, **kw})


CASES = {
    **{f"effect-{name}": _config(maneuver="figure_eight" if name == "tilt_gravity" else "deceleration",
                                 effects=make_effects([name])) for name in EFFECTS},
    **{f"maneuver-{m}": _config(maneuver=m) for m in MANEUVERS},
    **{f"floor-{k}": _config(maneuver="constant_speed", floor=FloorProfile.of((k, p))) for k, p in FLOOR_CASES.items()},
    **{f"external-{k}": _config(external=(ExternalForce(k, p),)) for k, p in EXTERNAL_CASES.items()},
    "pedals": _config(maneuver="acceleration", pedals=PedalFlex(1.0e5, 0.3)),
    "arms": _config(maneuver="acceleration", arms=ArmSwing(15.0, 1.2)),
    "effects-combined": _config(effects=make_effects(
        ["rolling_resistance", "viscous_friction", "aero_drag", "ground_slope", "time_varying_h",
         "wheel_body_friction", "tilt_gravity", "wheel_radius_error", "rider_mass_error"])),
}


def test_every_effect_floor_and_external_force_has_a_case():
    names = {k.split("-", 1)[-1] for k in CASES}
    assert set(EFFECTS) <= names
    assert set(FLOOR_CASES) == set(floors_mod.KINDS)
    assert set(EXTERNAL_CASES) == set(external_mod.KINDS)


def state_tolerance(run) -> np.ndarray:
    """Per state component: twice the global error bound ``N sqrt(n) (atol + rtol max|y_i|)`` (module docstring)."""
    st = run.solver_stats
    n = run.state.shape[1]
    return 2 * st["steps"] * np.sqrt(n) * (st["atol"] + st["rtol"] * np.abs(run.state).max(axis=0))


@pytest.mark.parametrize("case", sorted(CASES))
def test_compiled_states_equal_the_reference_within_the_tolerance(case):
    config = CASES[case]
    fast = simulate_ride(config).runs[0]
    ref = simulate_ride(replace(config, method="reference")).runs[0]
    assert fast.solver_stats["method"] == "compiled" and ref.solver_stats["method"] == "reference"
    assert fast.state.shape == ref.state.shape
    tol = state_tolerance(ref)
    diff = np.abs(fast.state - ref.state).max(axis=0)
    assert np.all(diff <= tol), (case, diff, tol)
    # the runs are not trivial: the states move by far more than the tolerance
    assert np.ptp(ref.state[:, 3]) > 1e3 * tol[3]
