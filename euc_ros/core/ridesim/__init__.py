"""Ride simulator: synthetic OptiTrack recordings of a human-ridden EUC with known truth.

Independent of the estimator (the model and states packages) by design: the truth model is derived here
from the point kinematics with sympy, so a bug in one cannot hide in the other. See
``docs/ridesim.md`` for the model, the controllers and every effect's derivation.

Examples
--------
>>> from euc_ros.core.ridesim import RideConfig, make_effects, simulate_ride
>>> ride = simulate_ride(RideConfig(maneuver="deceleration", runs=1, seed=7, duration_s=1.0,
...                                 effects=make_effects(["ground_slope"], {"alpha_deg": 3.0})))
>>> run = ride.runs[0]
>>> run.mocap.bodies[-1], run.mocap.position.shape
('E', (14, 120, 3))
"""
from euc_ros.core.ridesim.controllers import EucBalanceController, RiderLeanController
from euc_ros.core.ridesim.effects import EFFECTS, PARAM_OWNER, EffectSet, make_effects, parse_param_assignments
from euc_ros.core.ridesim.maneuvers import MANEUVERS
from euc_ros.core.ridesim.mocap_synth import MocapNoise
from euc_ros.core.ridesim.simulate import RideConfig, RideResult, RunResult, simulate_ride, true_params
from euc_ros.core.ridesim.truth_model import PlanarModel, PlanarParams
from euc_ros.core.ridesim.writers import write_ride

__all__ = ["EFFECTS", "MANEUVERS", "PARAM_OWNER", "EffectSet", "EucBalanceController", "MocapNoise",
           "PlanarModel", "PlanarParams", "RideConfig", "RideResult", "RiderLeanController", "RunResult",
           "make_effects", "parse_param_assignments", "simulate_ride", "true_params", "write_ride"]
