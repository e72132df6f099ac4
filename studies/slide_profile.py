"""Can h be told from soft-tissue sliding? The profile of h with artefact modes' parameters free.

Soft-tissue sliding biases the rider's pitch phi as the field's artefact models say it does: as a function of
the joint angles (Dumas, Camomilla, Bonci: artefact modes) and of the segments' accelerations (wobbling masses,
Gruber 1998). Three modes of the pitch's error are tried, each with one free parameter:

* ``gain``: ``dphi = c phi`` (an artefact growing with the rider's lean, a joint-angle mode);
* ``offset``: ``dphi = b`` (a constant lean of the markers on the body);
* ``accel``: ``dphi = k x_ddot`` (the bodies' markers lag or lead with the vehicle's acceleration, a wobbling mode).

The model's residual ``e(h; theta)`` is linear in small ``theta`` (its derivative by finite differences of the
states), so the profile ``RMSE(h) = min_theta RMSE(h, theta)`` is one least-squares solve per h. Per ride this
gives the plain fit's h, the profiled h, the variance inflation of h when the modes are free (Fisher
information: ``(F^-1)_hh F_hh``) and each mode's estimate.

Beside it, the standard error of the plain fit's h from its residual alone, as a sandwich with the scores'
autocovariance to a lag ``L`` (Newey-West, Bartlett weights; ``L`` = 0.5-5 s), against the actual errors:
whether a resampling of the residual can see what the sliding does to h.

Rides: the real-ride study's folders (``studies/real_ride_identify.py --out DIR``; seeds 100-123 are tuning
seeds), identified with the perturbed session.

    PYTHONPATH=$PWD python studies/slide_profile.py /tmp/rr --modes offset,accel
"""
from __future__ import annotations

import glob
import json
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != REPO / "studies"]
sys.path.insert(0, str(REPO))

from euc_ros.core.identify.fit import coefficients_for, fit_h  # noqa: E402
from euc_ros.core.model.terms import EucParams  # noqa: E402
from euc_ros.core.session import load_session  # noqa: E402
from euc_ros.core.states.load import load_states  # noqa: E402
from euc_ros.core.states.settings import ReconstructionSettings  # noqa: E402

GRID = np.arange(0.3, 1.5, 0.0025)
MODES = ("gain", "offset", "accel")


def residuals(coef: np.ndarray, h: np.ndarray) -> np.ndarray:
    """``e(h)`` per sample, (len(h), n)."""
    c, a0, a1, a2, d0, d1 = coef
    hh = h[:, None]
    return c * (a0 + a1 * hh + a2 * hh ** 2) / (d0 + d1 * hh)


def moved(st, mode: str, eps: float):
    """The states with the pitch moved by ``eps`` of the mode (phi and its derivatives together)."""
    import dataclasses

    if mode == "gain":
        return dataclasses.replace(st, phi=st.phi * (1 + eps), phi_dot=st.phi_dot * (1 + eps),
                                   phi_ddot=st.phi_ddot * (1 + eps))
    if mode == "offset":
        return dataclasses.replace(st, phi=st.phi + eps)
    # accel: dphi = k x_ddot; its derivatives by differences of x_ddot on the state's clock
    xd = np.asarray(st.x_ddot, float)
    d1 = np.gradient(xd, st.t)
    d2 = np.gradient(d1, st.t)
    return dataclasses.replace(st, phi=st.phi + eps * xd, phi_dot=st.phi_dot + eps * d1,
                               phi_ddot=st.phi_ddot + eps * d2)


def profile(states, params, modes=MODES) -> dict:
    """Plain and profiled h, the inflation of h's variance with the modes free, and the modes' estimates."""
    base = np.concatenate([residuals(c, GRID) for c in coefficients_for(states, params, "3dof", None)], axis=1)
    eps = {"gain": 1e-3, "offset": 1e-4, "accel": 1e-4}
    J = []
    for m in modes:
        cm = coefficients_for([moved(s, m, eps[m]) for s in states], params, "3dof", None)
        J.append((np.concatenate([residuals(c, GRID) for c in cm], axis=1) - base) / eps[m])
    J = np.stack(J, -1)                                   # (grid, n, modes)
    ok = np.all(np.isfinite(base), axis=0) & np.all(np.isfinite(J), axis=(0, 2))
    base, J = base[:, ok], J[:, ok]
    sse_plain = np.sum(base ** 2, axis=1)
    theta = np.stack([np.linalg.lstsq(J[i], -base[i], rcond=None)[0] for i in range(GRID.size)])
    sse_prof = np.array([np.sum((base[i] + J[i] @ theta[i]) ** 2) for i in range(GRID.size)])
    i0, i1 = int(np.argmin(sse_plain)), int(np.argmin(sse_prof))
    # Fisher information at the profiled optimum: columns d e / d h and d e / d theta
    dh = (base[min(i1 + 1, GRID.size - 1)] - base[max(i1 - 1, 0)]) / (2 * (GRID[1] - GRID[0]))
    X = np.column_stack([dh, J[i1]])
    F = X.T @ X
    inflation = float(np.linalg.inv(F)[0, 0] * F[0, 0])
    per_mode = {}
    for j, m in enumerate(modes):
        Xm = np.column_stack([dh, J[i1][:, j]])
        Fm = Xm.T @ Xm
        per_mode[m] = float(np.linalg.inv(Fm)[0, 0] * Fm[0, 0])
    return {"h_plain": float(GRID[i0]), "h_profiled": float(GRID[i1]), "inflation": inflation,
            "inflation_per_mode": per_mode, "theta": dict(zip(modes, map(float, theta[i1]))),
            "rmse_plain": float(np.sqrt(sse_plain[i0] / base.shape[1])),
            "rmse_profiled": float(np.sqrt(sse_prof[i1] / base.shape[1]))}


#: Lags of the residual's autocovariance in the sandwich [s].
LAGS_S = (0.0, 0.5, 1.0, 2.0, 5.0)


def hac_se(states, params, h: float) -> dict:
    """Newey-West standard error of the fitted h from the residual's scores, per lag [m]."""
    coefs = coefficients_for(states, params, "3dof", None)
    dt, d = states[0].dt, 1e-4
    info, scores = 0.0, []
    for c in coefs:
        e = residuals(c, np.array([h]))[0]
        g = (residuals(c, np.array([h + d]))[0] - residuals(c, np.array([h - d]))[0]) / (2 * d)
        ok = np.isfinite(e) & np.isfinite(g)
        info += float(np.sum(g[ok] ** 2))
        scores.append((g * e)[ok])
    out = {}
    for lag in LAGS_S:
        m = int(round(lag / dt))
        v = sum(float(np.sum(s * s)) + 2 * sum((1 - k / (m + 1)) * float(np.sum(s[k:] * s[:-k]))
                                                for k in range(1, min(m, s.size - 1) + 1)) for s in scores)
        out[lag] = float(np.sqrt(max(v, 0.0)) / info)
    return out


def main(argv=None) -> int:
    """Every ride folder of a real-ride study's output."""
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("root", type=Path, help="a real-ride study's output folder (rows.jsonl, seed*/)")
    ap.add_argument("--modes", default=",".join(MODES), help=f"artefact modes left free [{','.join(MODES)}]")
    args = ap.parse_args(argv)
    root, modes = args.root, tuple(args.modes.split(","))
    rows = {json.loads(t)["seed"]: json.loads(t) for t in (root / "rows.jsonl").read_text().splitlines()}
    out = []
    for seed, row in sorted(rows.items()):
        folder = root / f"seed{seed}"
        session = load_session(folder / "session_perturbed.yaml")
        params = EucParams.from_session(session)
        csvs = sorted(glob.glob(str(folder / "run_*" / "*.csv")))
        states = load_states(session, csvs, ReconstructionSettings())
        p = profile(states, params, modes)
        p.update(seed=seed, h_true=row["h_true_m"], h_fit=fit_h(states, params, models=("3dof",)).pooled["3dof"].h_m)
        p["hac_se"] = hac_se(states, params, p["h_fit"])
        out.append(p)
        print(f"{seed}: true {p['h_true']:.3f} fit {1e3 * (p['h_fit'] - p['h_true']):+5.0f} mm, profiled "
              f"{1e3 * (p['h_profiled'] - p['h_true']):+5.0f} mm, inflation {p['inflation']:.1f} "
              f"({', '.join(f'{m} {v:.1f}' for m, v in p['inflation_per_mode'].items())}), theta "
              f"{', '.join(f'{m} {v:+.2e}' for m, v in p['theta'].items())}", flush=True)
    e0 = 1e3 * np.array([p["h_fit"] - p["h_true"] for p in out])
    e1 = 1e3 * np.array([p["h_profiled"] - p["h_true"] for p in out])
    print(f"fit: {e0.mean():+.1f} +- {e0.std(ddof=1):.1f} mm; profiled: {e1.mean():+.1f} +- {e1.std(ddof=1):.1f} mm")
    for lag in LAGS_S:
        se = 1e3 * np.array([p["hac_se"][lag] for p in out])
        z = e0 / se
        print(f"residual sandwich, lag {lag:g} s: median se {np.median(se):.1f} mm, sd of error/se {np.std(z):.2f}, "
              f"|error| <= 1.96 se in {np.mean(np.abs(z) <= 1.96):.0%}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
