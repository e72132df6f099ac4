"""Recompute the README's identification table on simulated rides (seed 1, true h = 0.61 m).

Usage: .venv/bin/python studies/paper_table.py
"""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # the repository: euc_ros and studies

from euc_ros.core.identify.fit import fit_h  # noqa: E402
from euc_ros.core.model.terms import EucParams  # noqa: E402
from euc_ros.core.ridesim.effects import make_effects  # noqa: E402
from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride  # noqa: E402
from euc_ros.core.states.kinematics import reconstruct_states  # noqa: E402

ROWS = [("deceleration", 10, [], {}), ("acceleration", 10, [], {}), ("constant_speed", 10, [], {}),
        ("figure_eight", 2, ["tilt_gravity"], {"gain": 1.0})]

print("| maneuver | runs | 3-DoF h [m], RMSE [N m] | 2-DoF h [m], RMSE [N m] | sharpness 3-DoF |")
print("|---|---|---|---|---|")
for maneuver, runs, effects, params in ROWS:
    res = simulate_ride(RideConfig(maneuver=maneuver, runs=runs, seed=1, effects=make_effects(effects, params)))
    states = [reconstruct_states(r.mocap, res.session) for r in res.runs]
    out = fit_h(states, EucParams.from_session(res.session)).to_json()
    pooled = {m: out["models"][m] for m in ("3dof", "2dof")}
    print(f"| {maneuver}{' + ' + '+'.join(effects) if effects else ''} | {runs} | "
          + " | ".join(f"{pooled[m]['h_m']:.3f}, {pooled[m]['rmse_nm']:.2f}" for m in ("3dof", "2dof"))
          + f" | {pooled['3dof'].get('sharpness', float('nan')):.2f} |")
