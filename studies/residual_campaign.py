"""Run the undeclared-effect campaign and print the README's Markdown table.

Usage: .venv/bin/python studies/residual_campaign.py [--seed 11]
"""
import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # the repository: euc_ros and studies


from studies.campaign import CONTROLS, SCENARIOS, run_scenario, verdict  # noqa: E402

parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("--seed", type=int, default=11)
args = parser.parse_args()
print("| truth (hidden) | found | parameters found | h before -> after [m] | held-out RMSE before -> after [N m] "
      "| ratio | verdict |")
print("|---|---|---|---|---|---|---|")
for s in SCENARIOS + CONTROLS:
    out = run_scenario(s, seed=args.seed)
    ok, problems = verdict(s, out)
    truth = ", ".join(f"{e} ({', '.join(f'{k}={v:g}' for k, v in p.items())})" for e, p in s.effects.items()) or "none"
    found = ", ".join(f"{k}={v:.3g}" for k, v in out["effect_parameters"].items())
    ratio = out["rmse_after_nm"] / out["rmse_before_nm"]
    mark = "pass" if ok else "FAIL: " + "; ".join(problems)
    print(f"| {truth} | {out['effect']} | {found} | {out['h_m']:.3f} -> {out['h_after_m']:.3f} | "
          f"{out['rmse_before_nm']:.2f} -> {out['rmse_after_nm']:.2f} | {ratio:.2f} | {mark} |", flush=True)
    print(f"{s.name}: {'ok' if ok else problems}", file=sys.stderr)
