"""The rate sweep's harness (run by studies/rate_sweep.py): one ride captured at several frame rates, analysed
offline and live.

The ride simulator integrates one continuous truth per run (its plan does not depend on the capture
rate), so sampling it at 60, 100, ..., 1000 Hz gives the same ride captured by different cameras.
For every rate this measures

* offline: ``reconstruct_states`` (Savitzky-Golay, same window in seconds) and the pooled 3-DoF h of
  ``fit_h``;
* live: the nodes' cores frame by frame (:class:`~euc_ros.core.online.estimators.RiderStateEstimator`
  -> :class:`~euc_ros.core.online.estimators.TorqueEstimator`), the final online h;
* the driving torques M_d1, M_d2 at the true h, interpolated onto the reference rate's capture
  times, and their RMS difference from the reference rate's (interior samples both have).

``studies/rate_sweep.py`` prints the table of the README; ``test/unit/core/identify/test_rate_sweep.py`` runs a
small version.
"""
from __future__ import annotations

import dataclasses
from typing import Sequence

import numpy as np

from euc_ros.core.model.terms import EucParams
from euc_ros.core.model.torque import torques
from euc_ros.core.session import default_session

#: The rates of the README table [Hz].
RATES_HZ = (60, 100, 120, 180, 240, 360, 500, 1000)


def simulate_at(rate_hz: float, *, runs: int = 3, seed: int = 5, noise: bool = True, maneuver: str = "deceleration"):
    """The simulator's ride with ``seed`` captured at ``rate_hz`` (session ``rate_hz`` set to it)."""
    from euc_ros.core.ridesim.mocap_synth import MocapNoise
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride

    session = dataclasses.replace(default_session("y"), rate_hz=float(rate_hz))
    cfg = RideConfig(maneuver=maneuver, runs=runs, seed=seed, session=session,
                     **({} if noise else {"noise": MocapNoise(0.0, 0.0, 0.0)}))
    return simulate_ride(cfg)


def offline(ride, h_true: float):
    """Offline states per run, the pooled 3-DoF h and the torques at ``h_true``."""
    from euc_ros.core.identify.fit import fit_h
    from euc_ros.core.states.kinematics import reconstruct_states

    params = EucParams.from_session(ride.session, h_true, g=ride.params_true.g)
    states = [reconstruct_states(r.mocap, ride.session) for r in ride.runs]
    h = fit_h(states, params, models=("3dof",)).pooled["3dof"].h_m
    series = []
    for st in states:
        m1, m2 = torques(st.gamma, st.phi, st.gamma_dot, st.phi_dot, st.x_ddot, st.gamma_ddot, st.phi_ddot, params)
        ok = st.valid & np.isfinite(m1) & np.isfinite(m2)
        series.append((st.t[ok], m1[ok], m2[ok]))
    return float(h), series


def live(ride, h_true: float):
    """The live cores frame by frame; returns the final online h and the torques per run."""
    from euc_ros.core.online.estimators import RiderStateEstimator, TorqueEstimator

    params = EucParams.from_session(ride.session, h_true, g=ride.params_true.g)
    dt = 1.0 / ride.runs[0].mocap.rate_hz
    torque = TorqueEstimator(params, dt, h_window_s=1.2 * sum(float(r.mocap.t[-1]) + dt for r in ride.runs))
    series, t_offset, h_online = [], 0.0, np.nan
    for run in ride.runs:
        m = run.mocap
        est = RiderStateEstimator(ride.session, dt)
        rows = []
        for _, s in est.update_series(m):
            out = torque.update(dataclasses.replace(s, t=s.t + t_offset))
            if out is not None and np.isfinite(out.M_d1):
                rows.append((s.t, out.M_d1, out.M_d2))
                h_online = out.h_online_m if np.isfinite(out.h_online_m) else h_online
        t_offset += float(m.t[-1]) + dt
        arr = np.asarray(rows, dtype=float).reshape(-1, 3)
        series.append((arr[:, 0], arr[:, 1], arr[:, 2]))
    return float(h_online), series


def torque_rms_difference(series, reference, edge_s: float = 0.05) -> float:
    """RMS over runs of (M_d1, M_d2) minus the reference's, on the reference times both cover [N m]."""
    sq, n = 0.0, 0
    for (t, m1, m2), (tr, r1, r2) in zip(series, reference):
        if t.size < 2 or tr.size < 2:
            continue
        keep = (tr >= t[0] + edge_s) & (tr <= t[-1] - edge_s)
        for m, r in ((m1, r1), (m2, r2)):
            d = np.interp(tr[keep], t, m) - r[keep]
            sq += float(np.dot(d, d))
            n += d.size
    return float(np.sqrt(sq / n)) if n else float("nan")


def sweep(rates: Sequence[float] = RATES_HZ, *, reference_hz: float = 120.0, runs: int = 3, seed: int = 5,
          noise: bool = True, live_path: bool = True, progress=None) -> list[dict]:
    """One row per rate: offline and live h and the torque differences from ``reference_hz``."""
    h_true = None
    results = {}
    todo = sorted(set(rates) | {reference_hz})
    for rate in (progress(todo) if progress else todo):
        ride = simulate_at(rate, runs=runs, seed=seed, noise=noise)
        h_true = ride.config.h if h_true is None else h_true
        row = {"rate_hz": float(rate), "frames": int(sum(r.mocap.n_frames for r in ride.runs))}
        row["h_offline_m"], off = offline(ride, h_true)
        row["_off"] = off
        if live_path:
            row["h_live_m"], on = live(ride, h_true)
            row["_live"] = on
        results[rate] = row
    ref = results[reference_hz]
    rows = []
    for rate in rates:
        row = dict(results[rate])
        row["dh_offline_mm"] = 1e3 * (row["h_offline_m"] - ref["h_offline_m"])
        row["torque_rms_offline_nm"] = torque_rms_difference(row.pop("_off"), ref["_off"])
        if live_path:
            row["dh_live_mm"] = 1e3 * (row["h_live_m"] - ref["h_live_m"])
            row["torque_rms_live_nm"] = torque_rms_difference(row.pop("_live"), ref["_live"])
        rows.append(row)
    for r in rows:
        r.pop("_off", None)
        r.pop("_live", None)
    return rows
