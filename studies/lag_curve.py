#!/usr/bin/env python3
"""Lag against torque error: how late must the live states be for a given torque accuracy?

Usage: python studies/lag_curve.py [--seeds 1 2 3 4] [--train-seeds 1 2] [--duration 12] [--out docs/figures/lag]

Simulated rides (acceleration, deceleration, figure-eight; one run per maneuver and seed; the paper's
mocap noise, 0.2 mm and 0.5 deg per frame) are reconstructed frame by frame (bridging, geometry) and
their pitch angles and wheel centre differentiated by fixed-lag filters; M_d1 (eq 9) and M_d2 (eq 10)
at the true h are compared with the simulator's true M_d of the same frame (each estimate is
aligned with the frame it describes, i.e. for the lag). Filters, at every lag from 0.02 to 0.6 s:

* ``savgol``: today's centred Savitzky-Golay filter (1.2 s, order 6, lag 0.6 s): the reference;
* ``savgol_offcentre``: Savitzky-Golay fits evaluated ``lag`` before the newest sample (window and
  order chosen from a grid);
* ``kalman3`` / ``kalman4``: the steady-state Kalman fixed-lag smoother of
  :mod:`euc_ros.core.filters.causal` on a constant-acceleration / constant-jerk model (smoothing
  time chosen from a grid).

* ``split`` (:mod:`euc_ros.core.states.split_lag`): the pivot positions, the segments' and the EUC's
  orientation-borne pieces smoothed each with its own smoothing time and composed (the smoothing
  times of ``SPLIT_SMOOTHING``, chosen at 0.1 s, used unchanged at every lag). Its rows are
  scored on the frames it has an output for, within the common ones, against the default on those
  same frames ("x default" is that ratio). With its 3.1 s memory, these are all the common frames.

* ``trained_fir_bound`` (unless ``--no-bound``): the best ``kalman4`` filter's values and rates, with
  acceleration weights of the same length fitted (least squares, cubics kept exact) to the true M_d
  of the training seeds: what a fixed-lag FIR can reach on these rides when tuned on the truth. A
  bound, not a product.

Every filter is applied to all coordinates alike. Settings are chosen on the training seeds and the
errors reported on the other seeds, over the frames every filter has an output for (the longest
filter memory and lag trimmed from each run). Writes ``lag_table.md``, ``lag_table.csv`` and
``lag_vs_error.png`` to ``--out``.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from euc_ros.core.filters.causal import fir_derivatives, kalman_weights  # noqa: E402
from euc_ros.core.filters.derivatives import savgol_coefficients, window_samples  # noqa: E402
from euc_ros.core.mocap.bridging import bridge_series  # noqa: E402
from euc_ros.core.model.terms import EucParams  # noqa: E402
from euc_ros.core.model.torque import torques  # noqa: E402
from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride  # noqa: E402
from euc_ros.core.states.geometry import frame_geometry  # noqa: E402
from euc_ros.core.states.kinematics import DEFAULT_SG_POLYORDER, DEFAULT_WINDOW_S  # noqa: E402
from euc_ros.core.states.split_lag import SPLIT_SMOOTHING, split_derivatives, split_pieces  # noqa: E402

MANEUVERS = ("acceleration", "deceleration", "figure_eight")
LAGS_S = (0.02, 0.04, 0.06, 0.08, 0.1, 0.15, 0.2, 0.3, 0.4, 0.6)
SG_WINDOWS_S = (0.2, 0.3, 0.4, 0.6, 0.8, 1.0, 1.2, 1.6)
SG_ORDERS = (2, 3, 4, 5, 6)
TAUS_S = (0.04, 0.05, 0.065, 0.08, 0.1, 0.13)
H_TRUE = 0.61
SPLIT_LAGS_S = (0.05, 0.075, 0.1, 0.15, 0.2)


def simulate(seeds, duration_s):
    """Per run: geometry of the noisy recording and the truth."""
    runs = []
    for m in MANEUVERS:
        for seed in seeds:
            ride = simulate_ride(RideConfig(maneuver=m, runs=1, seed=seed, duration_s=duration_s))
            r = ride.runs[0]
            item = dict(maneuver=m, seed=seed, M_d=r.M_d, params=EucParams.from_session(ride.session, H_TRUE),
                        dt=1.0 / ride.session.rate_hz)
            for key, rec in (("noisy", r.mocap), ("clean", r.mocap_clean)):
                item[key] = recording_geometry(rec, ride.session)
            runs.append(item)
    return runs


def recording_geometry(rec, session, euc_center=(0.0, 0.0, 0.0)):
    """What the filters need of one recording (bridged): frames, gamma, phi, C, unwrapped psi and the
    split estimator's pieces (split at ``euc_center`` on the EUC body, see
    :func:`~euc_ros.core.states.split_lag.split_pieces`)."""
    series, _ = bridge_series(rec, 5)
    geo = frame_geometry(series.position, series.quat, series.tracked, session, series.bodies)
    psi = geo["psi"].copy()
    fin = np.isfinite(psi)
    psi[fin] = np.unwrap(psi[fin])
    return dict(frame=np.asarray(series.frame), gamma=geo["gamma"], phi=geo["phi_hinge"], C=geo["C"], psi=psi,
                pieces=split_pieces(series.position, series.quat, series.tracked, session, series.bodies,
                                    euc_center=euc_center))


def torque_errors(run, weights, lag, recording="noisy"):
    """(M_d1 - M_d, M_d2 - M_d) per frame (NaN where the filter has no output) of the noisy or the
    clean (noise-free: the filter's bias alone) recording."""
    g = run[recording]
    kw = dict(max_gap=5, frame=g["frame"])
    dg = fir_derivatives(run["dt"], g["gamma"], weights, lag, **kw)
    dp = fir_derivatives(run["dt"], g["phi"], weights, lag, **kw)
    dc = fir_derivatives(run["dt"], g["C"], weights, lag, **kw)
    c, s = np.cos(g["psi"]), np.sin(g["psi"])
    x_ddot = c * dc.y_ddot[:, 0] + s * dc.y_ddot[:, 1]
    m1, m2 = torques(dg.y, dp.y, dg.y_dot, dp.y_dot, x_ddot, dg.y_ddot, dp.y_ddot, run["params"])
    return m1 - run["M_d"], m2 - run["M_d"]


def split_errors(run, lag_s, recording="noisy"):
    """(M_d1 - M_d, M_d2 - M_d) per frame of the split estimator (:mod:`euc_ros.core.states.split_lag`)."""
    g = run[recording]
    st = split_derivatives(run["dt"], g["pieces"], lag_s=lag_s, frame=g["frame"], max_gap=5)
    m1, m2 = torques(st.gamma, st.phi, st.gamma_dot, st.phi_dot, st.x_ddot, st.gamma_ddot, st.phi_ddot,
                     run["params"])
    return m1 - run["M_d"], m2 - run["M_d"]


def _windows(y, W, lag):
    """(n, W) windows of ``y`` (oldest first) ending ``lag`` samples after each frame; NaN rows elsewhere."""
    from numpy.lib.stride_tricks import sliding_window_view

    n = y.shape[0]
    out = np.full((n, W), np.nan)
    if n >= W:
        out[W - 1 - lag:n - lag] = sliding_window_view(y - y[n // 2], W)
    return out


def acceleration_design(run, weights, lag):
    """The torques as affine functions of the acceleration weights (values and rates from ``weights``).

    M_d1 and M_d2 are affine in (x_ddot, gamma_ddot, phi_ddot) at given angles and rates, and each
    acceleration is the window of its coordinate times the acceleration weights ``w``. Returns
    ``(a, B)`` with ``M_dk = a[k] + B[k] @ w`` per frame (``a`` (2, n), ``B`` (2, n, W)).
    """
    g = run["noisy"]
    if np.any(np.diff(g["frame"]) != 1):
        raise ValueError("the trained bound needs gap-free recordings")
    n, W = g["gamma"].shape[0], weights.shape[1]
    kw = dict(max_gap=5, frame=g["frame"])
    dg = fir_derivatives(run["dt"], g["gamma"], weights, lag, **kw)
    dp = fir_derivatives(run["dt"], g["phi"], weights, lag, **kw)
    zero, one = np.zeros(n), np.ones(n)

    def tq(xdd, gdd, pdd):
        return np.array(torques(dg.y, dp.y, dg.y_dot, dp.y_dot, xdd, gdd, pdd, run["params"]))

    a = tq(zero, zero, zero)
    bx, bg, bp = tq(one, zero, zero) - a, tq(zero, one, zero) - a, tq(zero, zero, one) - a
    c, s = np.cos(g["psi"]), np.sin(g["psi"])
    Xx = c[:, None] * _windows(g["C"][:, 0], W, lag) + s[:, None] * _windows(g["C"][:, 1], W, lag)
    Xg, Xp = _windows(g["gamma"], W, lag), _windows(g["phi"], W, lag)
    B = bx[:, :, None] * Xx[None] + bg[:, :, None] * Xg[None] + bp[:, :, None] * Xp[None]
    return a, B


def trained_bound(runs, train, base, lag, ridge=1e-6):
    """Acceleration weights fitted to the true M_d on the training runs (cubics kept exact), the
    values and rates from ``base``: the lowest error a fixed-lag FIR of that length reaches on these
    rides (a bound, tuned on the simulator's truth; not a product). Returns the torque errors per run."""
    from numpy.polynomial import legendre

    W = base.shape[1]
    c0 = (W - 1) / 2.0
    V = legendre.legvander((np.arange(W) - c0) / c0, 3)
    null = np.linalg.svd(V.T)[2][4:].T                  # (W, W - 4): changes that keep cubics exact
    designs = [acceleration_design(r, base, lag) for r in runs]
    rows, rhs = [], []
    for i in train:
        a, B = designs[i]
        ok = np.all(np.isfinite(B), axis=2) & np.isfinite(a)
        for k in (0, 1):
            rows.append(B[k][ok[k]] @ null)
            rhs.append(runs[i]["M_d"][ok[k]] - a[k][ok[k]] - B[k][ok[k]] @ base[2])
    A, y = np.concatenate(rows), np.concatenate(rhs)
    lam = ridge * np.trace(A.T @ A) / A.shape[1]
    z = np.linalg.solve(A.T @ A + lam * np.eye(A.shape[1]), A.T @ y)
    w = base[2] + null @ z
    out = []
    for (a, B), r in zip(designs, runs):
        est = a + np.einsum("knw,w->kn", np.nan_to_num(B), w)
        est[~(np.all(np.isfinite(B), axis=2) & np.isfinite(a))] = np.nan
        out.append((est[0] - r["M_d"], est[1] - r["M_d"]))
    return out


def candidates(dt):
    """(family, lag_s, setting, weights, lag frames) of every filter tried."""
    out = []
    w = window_samples(dt, window_s=DEFAULT_WINDOW_S, polyorder=DEFAULT_SG_POLYORDER)
    half = (w - 1) // 2
    out.append(("savgol", half * dt, f"{w * dt:.2f} s, order {DEFAULT_SG_POLYORDER} (default)",
                savgol_coefficients(w, DEFAULT_SG_POLYORDER, dt, [half])[:, 0], half))
    for lag_s in LAGS_S:
        lag = int(round(lag_s / dt))
        for win_s in SG_WINDOWS_S:
            for p in SG_ORDERS:
                w = window_samples(dt, window_s=win_s, polyorder=p)
                if lag > (w - 1) // 2:
                    continue
                out.append(("savgol_offcentre", lag_s, f"{w * dt:.2f} s, order {p}",
                            savgol_coefficients(w, p, dt, [w - 1 - lag])[:, 0], lag))
        for order in (3, 4):
            for tau in TAUS_S:
                out.append((f"kalman{order}", lag_s, f"tau {tau:g} s",
                            kalman_weights(dt, lag, order=order, smoothing_s=tau), lag))
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4])
    ap.add_argument("--train-seeds", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--duration", type=float, default=12.0, help="duration of each run [s]")
    ap.add_argument("--out", type=Path, default=Path("docs/figures/lag"))
    ap.add_argument("--no-bound", dest="bound", action="store_false",
                    help="skip the trained FIR bound (accelerations fitted to the truth of the training seeds)")
    a = ap.parse_args()
    runs = simulate(a.seeds, a.duration)
    dt = runs[0]["dt"]
    cands = candidates(dt)
    errs = [[torque_errors(r, wts, lag) for r in runs] for (_, _, _, wts, lag) in cands]
    # frames every filter has an output for, per run
    common = [np.all([np.isfinite(e[i][0]) & np.isfinite(e[i][1]) for e in errs], axis=0) for i in range(len(runs))]
    train = [i for i, r in enumerate(runs) if r["seed"] in a.train_seeds]
    test = [i for i, r in enumerate(runs) if r["seed"] not in a.train_seeds]

    def rms(e, idx):
        e1 = np.concatenate([e[i][0][common[i]] for i in idx])
        e2 = np.concatenate([e[i][1][common[i]] for i in idx])
        return float(np.sqrt(np.mean(e1**2))), float(np.sqrt(np.mean(e2**2)))

    scored = [(c, rms(e, train), rms(e, test)) for c, e in zip(cands, errs)]
    ref = next(s for s in scored if s[0][0] == "savgol")
    ref_test = ref[2]
    best = {}
    for c, tr, te in scored:
        key = (c[0], c[1])
        score = np.hypot(*tr)
        if key not in best or score < best[key][0]:
            best[key] = (score, c, tr, te)
    if a.bound:
        for lag_s in LAGS_S:
            c = best[("kalman4", lag_s)][1]
            e = trained_bound(runs, train, c[3], c[4])
            best[("trained_fir_bound", lag_s)] = (0.0, ("trained_fir_bound", lag_s,
                                                       f"kalman4 {c[2]}, accelerations fitted", c[3], c[4]),
                                                  rms(e, train), rms(e, test))
    split_rows = []
    setting = "tau " + "; ".join(f"{k} {v:g}" for k, v in SPLIT_SMOOTHING.items()) + " s"
    for lag_s in SPLIT_LAGS_S:
        e = [split_errors(r, lag_s) for r in runs]
        eb = [split_errors(r, lag_s, "clean") for r in runs]
        own = [common[i] & np.isfinite(e[i][0]) & np.isfinite(e[i][1]) for i in range(len(runs))]

        def rms_own(err, idx):
            e1 = np.concatenate([err[i][0][own[i]] for i in idx])
            e2 = np.concatenate([err[i][1][own[i]] for i in idx])
            return float(np.sqrt(np.mean(e1**2))), float(np.sqrt(np.mean(e2**2)))

        ref_own = rms_own(errs[[c[0] for c in cands].index("savgol")], test)
        te, b = rms_own(e, test), rms_own(eb, test)
        ratio = max(te[0] / ref_own[0], te[1] / ref_own[1])
        n_own = sum(int(own[i].sum()) for i in test)
        split_rows.append((lag_s, "split", f"{setting} ({n_own} frames, default there "
                           f"{ref_own[0]:.3f} / {ref_own[1]:.3f})", te[0], te[1], ratio, b[0], b[1]))
    rows = []
    for (family, lag_s), (_, c, tr, te) in sorted(best.items(), key=lambda kv: (kv[0][1], kv[0][0])):
        ratio = max(te[0] / ref_test[0], te[1] / ref_test[1])
        bias = (rms([torque_errors(r, c[3], c[4], "clean") for r in runs], test) if family != "trained_fir_bound"
                else (np.nan, np.nan))
        rows.append((lag_s, family, c[2], te[0], te[1], ratio, bias[0], bias[1]))
    rows = sorted(rows + split_rows, key=lambda r: (r[0], r[1]))
    a.out.mkdir(parents=True, exist_ok=True)
    n_test = sum(int(common[i].sum()) for i in test)
    lines = [f"Test seeds {sorted(set(runs[i]['seed'] for i in test))} (settings chosen on seeds "
             f"{sorted(a.train_seeds)}), {len(MANEUVERS)} maneuvers, {n_test} frames at {1 / dt:g} Hz; "
             "RMS of the estimate minus the true M_d of the same frame; ratio = the larger of the two "
             "RMS ratios to today's default; bias = the same on the noise-free recording (the rest is noise).",
             "",
             "| lag [s] | filter | setting | RMS(M_d1 - M_d) [N m] | RMS(M_d2 - M_d) [N m] | x default | "
             "bias M_d1 / M_d2 [N m] |",
             "|---:|:---|:---|---:|---:|---:|---:|"]
    for lag_s, family, setting, e1, e2, ratio, b1, b2 in rows:
        bias = f"{b1:.3f} / {b2:.3f}" if np.isfinite(b1) else "-"
        lines.append(f"| {lag_s:.2f} | {family} | {setting} | {e1:.3f} | {e2:.3f} | {ratio:.2f} | {bias} |")
    (a.out / "lag_table.md").write_text("\n".join(lines) + "\n")
    with open(a.out / "lag_table.csv", "w") as fh:
        fh.write("lag_s,filter,setting,rms_md1_nm,rms_md2_nm,ratio_to_default,bias_md1_nm,bias_md2_nm\n")
        for lag_s, family, setting, e1, e2, ratio, b1, b2 in rows:
            fh.write(f"{lag_s:.3f},{family},{setting},{e1:.4f},{e2:.4f},{ratio:.3f},{b1:.4f},{b2:.4f}\n")
    print("\n".join(lines))

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), sharey=True)
    styles = {"savgol_offcentre": ("C0", "o"), "kalman3": ("C1", "s"), "kalman4": ("C2", "^"),
              "trained_fir_bound": ("C3", "x"), "split": ("C4", "D")}
    for ax, k, label in zip(axes, (3, 4), ("M_d1 (eq 9)", "M_d2 (eq 10)")):
        for family, (color, marker) in styles.items():
            pts = [(r[0], r[k]) for r in rows if r[1] == family]
            if pts:
                x, y = zip(*pts)
                ax.plot(x, y, color=color, marker=marker, label=family)
        ref_val = ref_test[k - 3]
        ax.plot([ref[0][1]], [ref_val], "k*", ms=12, label="default Savitzky-Golay (1.2 s)")
        ax.axhline(2 * ref_val, color="k", ls=":", lw=1, label="2 x default")
        ax.axvline(0.1, color="grey", ls="--", lw=1)
        ax.set_xlabel("lag [s]")
        ax.set_title(f"RMS({label} - true M_d)")
        ax.set_yscale("log")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("torque error [N m]")
    axes[1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(a.out / "lag_vs_error.png", dpi=110)
    return 0


if __name__ == "__main__":
    sys.exit(main())
