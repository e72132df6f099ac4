"""Console text of ``euc-ros identify``: the fit table, the verdict on h, the filter and the samples used.

:func:`format_table`, :func:`format_uncertainty`, :func:`format_filter` and :func:`format_usage` (the latter
also printed by ``euc-ros residual``).
"""
from __future__ import annotations

import numpy as np

from euc_ros.core.identify.cog_height import HIdentification


def _fmt(v: float, digits: int) -> str:
    return "nan" if not np.isfinite(v) else f"{v:.{digits}f}"


def format_uncertainty(ident: HIdentification) -> str:
    """The verdict on the headline h: its interval, or why h is not identifiable; diagnostics and the budget.

    With a filter chosen from the data the headline is h corrected for the pose noise and the filter's
    distortion (:attr:`~euc_ros.core.identify.cog_height.HIdentification.corrected`), and the uncorrected
    h at the chosen filter follows as a diagnostic line.
    """
    def ci_text(ci) -> str:           # [lo, hi] to 1 mm, "-" for an end the data do not bound
        lo, hi = ci if ci is not None else (None, None)
        return "[" + ", ".join("-" if v is None else f"{v:.3f}" for v in (lo, hi)) + "]"

    unc = ident.uncertainty
    u = unc["uncertainty"]
    comb = ident.combined
    h = comb.h_data_m if comb is not None else ident.h        # the data's h (the headline is the combination)
    ci = ci_text(unc["h_ci95_m"])
    data_label = "from the data: " if comb is not None else ""
    to_use = "" if comb is not None else "; the one to use"
    bias = u.get("eiv_bias_m")
    floor = u.get("filter_floor_m")
    step = u.get("distortion_correction_m")
    sharp = "-" if u.get("sharpness") is None else f"{u['sharpness']:.2f}"
    blocks = f"{u.get('method', 'block bootstrap')} over {u['n_blocks']} blocks of {u['block_s']:.1f} s"
    if not unc["identifiable"]:
        fit = ident.held.h_from_data_m if ident.held is not None else h
        lines = ["h is NOT identifiable from these recordings:",
                 *(f"  - {r}" for r in (unc["identifiability_reason"] or "").split("; ")),
                 f"  (best fit {fit:.3f} m, 95 % interval {ci} m; curve sharpness {sharp}: do not use it as h)"]
        if ident.held is not None:
            lines.append(ident.held.console_line())
    elif ident.corrected:
        diag = unc["diagnostics"]
        removed = [f"noise bias {1e3 * bias:+.1f} mm" if bias is not None else "",
                   f"filter distortion {-1e3 * step:+.1f} mm" if step is not None else ""]
        lines = [f"{data_label}h = {h:.3f} m, 95 % interval {ci} m (corrected for the pose noise and the filter's "
                 f"distortion{to_use})",
                 f"  {blocks}" + (f", {' and '.join(r for r in removed if r)} removed" if any(removed) else "")
                 + f"; curve sharpness {sharp}",
                 f"  diagnostic, not for use: h at the chosen filter, uncorrected = "
                 f"{diag['h_at_chosen_filter_m']:.3f} m, 95 % interval {ci_text(diag['h_at_chosen_filter_ci95_m'])} m"
                 + (f" (noise bias included, filter distortion +-{1e3 * floor:.3f} mm)" if floor is not None else "")]
    else:
        how = (blocks + (f", noise bias {1e3 * bias:+.1f} mm included" if bias is not None else "")
               + (f", filter distortion +-{1e3 * floor:.3f} mm" if floor is not None else ""))
        lines = [f"{data_label}h = {h:.3f} m, 95 % interval {ci} m ({how}); curve sharpness {sharp}"]
        if u.get("h_corrected_not_headline") and u.get("h_corrected_m") is not None:
            lines.append(f"  not used: h extrapolated to no filter distortion = {u['h_corrected_m']:.3f} m; the "
                         "noise is coloured (soft-tissue sliding), so the probe filter's change of h is not the "
                         "distortion's alone")
    if comb is not None:        # the headline first: the one to use
        lines.insert(0, comb.console_line())
    ex = u.get("excitation")
    if ex and unc["identifiable"] and ex.get("accel_rms_mps2") is not None:
        need = ex.get("accel_rms_needed_mps2")
        lines.append(f"excitation: RMS longitudinal acceleration {ex['accel_rms_mps2']:.2f} m/s^2"
                     + (f" (h needs about {need:.2f})" if need is not None else "")
                     + f", {ex['blocks']} blocks of {ex['block_s']:.1f} s ({ex['blocks_needed']} needed)")
    b = unc.get("uncertainty_budget")
    if b and unc["identifiable"]:
        rows = sorted(b["sensitivity"].items(), key=lambda kv: -(kv[1]["dh_m"] or 0.0))
        lines.append("h depends on nominal values no residual can check (dh for the stated tolerance, its standard "
                     "uncertainty; --tolerance):")
        lines += [f"  {k:<29} {v['dh_dp']:+9.4f} {v['unit'].split(' (')[0]:<26} x {v['tolerance']:g} -> "
                  f"{1e3 * v['dh_m']:5.1f} mm (u {1e3 * (v.get('u_m') or 0.0):4.1f} mm)"
                  for k, v in rows[:6] if v["dh_dp"] is not None]
        lo2, hi2 = b["h_range_m"]
        lines.append(f"  h range for these tolerances: [{lo2:.3f}, {hi2:.3f}] m")
        if b.get("u_session_m") is not None:
            data = "unbounded" if b.get("u_data_m") is None else f"{1e3 * b['u_data_m']:.1f} mm"
            lines.append(f"  the interval holds them: u = {1e3 * b['u_session_m']:.1f} mm from the session, "
                         f"{data} from the data; the largest share: {b['dominant']}")
    return "\n".join(lines)


def format_filter(info: dict) -> str:
    """One line: the filter chosen from the data and what it leaves in the accelerations."""
    worst = max(info["distortion"].items(), key=lambda kv: kv[1][2])
    noisiest = max(info["noise"].items(), key=lambda kv: kv[1])
    rates = info.get("per_rate")
    return (f"filter chosen from the data: Savitzky-Golay {info['window_s']:.3f} s ({info['window']} samples"
            + (f" at {info['rate_hz']:g} Hz" if info.get("rate_hz") else "") + f"), order {info['polyorder']}; "
            f"remaining distortion of the accelerations up to {100 * worst[1][2]:.1f} % ({worst[0]}), noise up to "
            f"{100 * noisiest[1]:.1f} % ({noisiest[0]}) of their RMS"
            + (" (per rate: " + ", ".join(f"{r} Hz {v['window_s']:.3f} s / {v['polyorder']}" for r, v in rates.items())
               + "; the longest window is used)" if rates else ""))


def format_usage(usage: list[dict]) -> str:
    """One line: the share of each recording's frames the analysis used."""
    return "samples used: " + ", ".join(
        f"{u['recording']} {100 * u['samples_used_fraction']:.0f} % ({u['samples_used']}/{u['frames']}"
        + (f", {u['bridged_frames']} frames bridged" if u.get("bridged_frames") else "") + ")" for u in usage)


def format_table(result, identifiable: bool | None = None) -> str:
    """The per-recording and pooled table printed by the command (an extended model adds two columns)."""
    extra = [m for m in result.pooled if m not in ("3dof", "2dof")]
    head = (f"{'recording':<28} {'samples':>8}  {'3-DoF h [m]':>11} {'RMSE [Nm]':>10}  "
            f"{'2-DoF h [m]':>11} {'RMSE [Nm]':>10}")
    for m in extra:
        label = m.replace("3dof", "3-DoF", 1) + " h [m]"
        head += f"  {label:>11} {'RMSE [Nm]':>10}"
    lines = [head, "-" * len(head)]

    def row(name, n, fits):
        cells = []
        for f in [fits.get("3dof"), fits.get("2dof")] + [fits.get(m) for m in extra]:
            if f is None:
                cells += ["-", "-"]
            else:
                h = _fmt(f.h_m, 3) + ("*" if f.at_bound else " ")
                cells += [h, _fmt(f.rmse_nm, 3)]
        text = f"{name[:28]:<28} {n:>8}  {cells[0]:>11} {cells[1]:>10}  {cells[2]:>11} {cells[3]:>10}"
        for k, m in enumerate(extra):
            width = max(11, len(m.replace("3dof", "3-DoF", 1) + " h [m]"))
            text += f"  {cells[4 + 2 * k]:>{width}} {cells[5 + 2 * k]:>10}"
        return text

    for rec in result.per_recording:
        lines.append(row(rec.recording, rec.n_samples, rec.fits))
    lines.append("-" * len(head))
    pooled_n = next(iter(result.pooled.values())).n_samples if result.pooled else 0
    lines.append(row("pooled", pooled_n, result.pooled))
    if identifiable is not False and (any(f.at_bound for rec in result.per_recording for f in rec.fits.values())
                                      or any(f.at_bound for f in result.pooled.values())):
        lines.append("* optimum at the end of the h grid: widen --h-min/--h-max")
    return "\n".join(lines)
