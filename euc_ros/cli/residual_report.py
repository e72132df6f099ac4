"""Console, Markdown and paper text of ``euc-ros residual`` (:func:`format_summary`, :func:`markdown_report`).

Everything is formatted from the analysis' JSON document (docs/residual.md, JSON).
"""
from __future__ import annotations

import math
import os
from pathlib import Path


def format_summary(data: dict) -> str:
    """Console summary: the verdict and the candidate table."""
    lines = [f"h (3-DoF, no effect) = {data['h_m']:.3f} m; held-out RMSE of M_d1 - M_d2: "
             f"{data['rmse_before_nm']:.3f} N m ({data['held_out']['kind']}, {data['held_out']['folds']} folds)"]
    lines.append(base_status_text(data))
    held = data.get("h_held")
    if held:
        lo, hi = held["ci95_m"]
        lines.append(f"h held at the segments' geometric h in every fit: use h = {held['h_m']:.3f} m (standard "
                     f"uncertainty {1e3 * held['std_m']:.1f} mm from the session tolerances, 95 % interval "
                     f"[{lo:.3f}, {hi:.3f}] m), because {held['reason']}")
    if data["effect"] == "none":
        lines.append("effect: none (the residual is at its noise floor; no candidate beats chance)")
    else:
        params = ", ".join(f"{k} = {v:.4g}" for k, v in data["effect_parameters"].items())
        tie = " (one of a tie)" if data.get("effect_is_tie") else ""
        lines.append(f"effect{tie}: {data['effect']} ({params}); h = {data['h_after_m']:.3f} m; held-out RMSE "
                     f"{data['rmse_before_nm']:.3f} -> {data['rmse_after_nm']:.3f} N m")
        if data.get("ambiguous_with"):
            lines.append(f"  not distinguishable on this data from: {', '.join(data['ambiguous_with'])}")
    final = final_interval_text(data)
    if final:
        lines.append(final)
    lines += verdict_lines(data)
    lo, hi = data.get("h_range_m") or (None, None)
    if lo is not None and hi - lo > 0.001:
        lines.append(f"  h range over the models the data cannot tell apart: [{lo:.3f}, {hi:.3f}] m ("
                     + ", ".join(f"{t['effect']}: {t['h_m']:.3f}" for t in data.get("tied_models", [])) + ")")
    for d in data.get("discovered", []):
        lines.append(f"  discovered: {d['formula']} ({d['coefficient_unit']}); held-out RMSE after "
                     f"{d['rmse_after_nm']:.3f} N m")
    nf = data.get("noise_floor_nm")
    lines.append(f"residual after: {'above' if data.get('residual_significant') else 'at'} its noise floor"
                 + (f" ({nf:.3f} N m: {floor_parts(data)})" if nf is not None else "")
                 + ("; UNEXPLAINED: nothing named or discovered explains it" if data.get("unexplained") else ""))
    geo = data.get("geometry") or {}
    floor = geo.get("floor")
    if floor:
        lines.append(f"floor from the wheel's contact path: slope {floor['slope_along_travel_deg']:+.2f} deg along "
                     f"travel, rises {floor['rise_m'] * 1e3:.1f} mm over {floor['extent_m']:.1f} m, deviation "
                     f"{floor['deviation_m'] * 1e3:.1f} mm, scatter {floor['scatter_m'] * 1e3:.2f} mm"
                     f"{' (flat)' if floor['flat'] else ''}")
    if geo.get("samples") and math.isfinite(geo.get("rolling_radius_measured_m", float("nan"))):
        lines.append(f"rolling radius from the contact path: {geo['rolling_radius_measured_m']:.4f} m "
                     f"(session {geo['rolling_radius_nominal_m']:.4f} m){' -> wheel_radius_error' if geo['used'] else ''}")  # noqa: E501
    elif geo.get("rolling_radius_reason"):
        lines.append(f"rolling radius: not measured: {geo['rolling_radius_reason']}")
    lines.append(f"{'candidate':22s} {'held-out RMSE':>14s} {'p':>9s} {'p adj.':>9s}  parameters")
    for c in data["candidates"]:
        p = "-" if c.get("p_value") is None else f"{c['p_value']:.2g}"
        pa = "-" if c.get("p_adjusted") is None else f"{c['p_adjusted']:.2g}"
        rmse = "undetectable" if not c["detectable"] else f"{c['rmse_after_nm']:.3f}"
        params = ", ".join(f"{k}={v:.4g}" for k, v in (c.get("effect_parameters") or {}).items())
        lines.append(f"{c['effect']:22s} {rmse:>14s} {p:>9s} {pa:>9s}  {params}")
    return "\n".join(lines)


def console_warnings(data: dict) -> list[str]:
    """The warnings to print once each: the recordings' and the analysis'.

    Without those the summary shows already (a refused name is a line of the verdict).
    """
    said = tuple(r["text"] for r in data.get("refused", []))
    out = [w for w in list(data.get("warnings", [])) + list(data.get("analysis_warnings", []))
           if not (said and w.startswith(said))]
    return list(dict.fromkeys(out))


def base_status_text(data: dict) -> str:
    """How well the data determine the base 3-DoF model's h, one line."""
    ci = data.get("h_ci95_m") or [None, None]
    if not data.get("identifiable"):
        return f"  (base model: h NOT identifiable from these recordings: {data.get('identifiability_reason')})"
    return f"  (base model: h 95 % interval {_ci(ci)} m)"


def headline_text(data: dict, json_path: str | None = None, session: str | None = None) -> str:
    """The last lines: the h to use (the final model's) with its verdict, and how to run it live."""
    name = data["effect"] if data.get("h_after_ci95_m") is not None else "3-DoF, no effect"
    h = data.get("h_after_m", data["h_m"])
    ci = data.get("h_after_ci95_m") or data.get("h_ci95_m")
    held = " (held at the segments' geometric h: the data do not bound it)" if data.get("h_held") else ""
    comb = (data.get("diagnostics") or {}).get("h_after_combined")
    if comb and not held:           # the final model's h from the data with the segments' geometric h
        alone = ("" if data.get("h_after_identifiable") else
                 f"; the data alone do not identify it: {data.get('h_after_identifiability_reason')}")
        held = (f" (the final model's h from the data, {comb['h_from_data_m']:.3f} m, with the segments' geometric h "
                f"{comb['h_geometric_m']:.3f} m; the data carry {100 * (comb['weight_data'] or 0.0):.0f} %{alone})")
    if not held and not data.get("h_after_identifiable", data.get("identifiable")):
        why = data.get("h_after_identifiability_reason", data.get("identifiability_reason"))
        return (f"h of the final model ({name}) is NOT identifiable from these recordings: {why} (best fit "
                f"{h:.3f} m: do not use it as h)")
    text = f"h to use: {h:.3f} m{held}, 95 % interval {_ci(ci)} m (final model: {name})"
    if json_path and session:
        text += (f"\nlive with this model: euc-ros launch pipeline.launch.xml session:={session} model:={json_path} "
                 "...")
    return text


def _ci(iv) -> str:
    return f"[{iv[0]:.4g}, {iv[1]:.4g}]" if iv and None not in iv else "[not bounded]"


def final_interval_text(data: dict) -> str | None:
    """The final model's h with its 95 % interval and its effect parameters' intervals (None without)."""
    ci = data.get("h_after_ci95_m")
    if ci is None:
        return None
    params = "; ".join(f"{k} {_ci(v)}" for k, v in (data.get("effect_parameters_ci95") or {}).items())
    held = data.get("h_after_uncertainty", {}).get("widened_by") or []
    return (f"h (final model, {data['effect']}) = {data['h_after_m']:.3f} m, 95 % interval {_ci(ci)} m"
            + (f"; parameters 95 %: {params}" if params else "")
            + (f" (the interval holds {' and '.join(held)})" if held else ""))


def verdict_lines(data: dict) -> list[str]:
    """One line per tie (the names with the h each implies) and per refused name."""
    lines = [f"tie: {' | '.join(f'{e} (h {h:.3f} m)' for e, h in zip(t['effects'], t['h_m']))}: the data cannot "
             f"tell them apart" for t in data.get("ties", [])]
    return lines + [f"{r['text']} (its fit would leave {r['rmse_after_nm']:.3f} N m held out)"
                    for r in data.get("refused", [])]


def paper_paragraph(data: dict) -> str:
    """One paragraph that states the result as a paper would (numbers, their intervals, the method)."""
    n = len(data.get("recordings", []))
    settings = data.get("settings", {})
    ci = data.get("h_ci95_m") or [None, None]
    base = f"h = {data['h_m']:.3f} m" + (f" (95 % interval {ci[0]:.3f}-{ci[1]:.3f} m)" if None not in ci else "")
    text = (f"The rider's centre-of-gravity height above the ankle hinge was identified from {n} recording(s) by "
            f"minimising the RMS difference of the two model expressions of the driving torque, M_d1 - M_d2, of the "
            f"3-DoF model (states from Savitzky-Golay filtering, window {settings.get('window_s', float('nan')):g} s, "
            f"order {settings.get('polyorder', '?')}): {base}, held-out RMS residual "
            f"{data['rmse_before_nm']:.2f} N m.")
    if data["effect"] == "none":
        return text + " No candidate effect reduced the held-out residual significantly."
    params = ", ".join(f"{k} = {v:.3g}" for k, v in data["effect_parameters"].items())
    text += (f" Adding {data['effect'].replace('_', ' ')} ({params}) reduced it to {data['rmse_after_nm']:.2f} N m "
             f"(significant at the {data['significance_level']:g} level, family-wise over "
             f"{len(data.get('candidates', []))} candidates); with it h = {data['h_after_m']:.3f} m"
             + (f" (95 % interval {_ci(data['h_after_ci95_m'])} m, block-robust, with the base model's bias terms)"
                if data.get("h_after_ci95_m") else "") + ".")
    lo, hi = data.get("h_range_m") or (None, None)
    if lo is not None and hi - lo > 0.001:
        text += f" Explanations the data cannot tell apart put h between {lo:.3f} and {hi:.3f} m."
    return text


def markdown_report(data: dict, figures: list[Path], base: Path) -> str:
    """A Markdown report of the analysis (figures linked relative to the report)."""
    out = ["# Residual analysis: M_d1 - M_d2", "",
           f"Recordings: {', '.join(data.get('recordings', []))}  ",
           f"Held-out evaluation: {data['held_out']['kind']} ({data['held_out']['folds']} folds); "
           f"significance level {data['significance_level']} (family-wise over the candidates: max-T), "
           f"minimum gain {100 * data['min_relative_gain']:.0f} %.", "",
           "## Summary", "", paper_paragraph(data), "",
           "## Verdict", ""]
    if data["effect"] == "none":
        out.append("**No effect**: no candidate explains the residual better than chance.")
    else:
        params = ", ".join(f"`{k}` = {v:.4g}" for k, v in data["effect_parameters"].items())
        out.append(f"**{data['effect']}** ({params}).")
        if data.get("ambiguous_with"):
            out.append(f"The held-out data cannot tell it apart from: {', '.join(data['ambiguous_with'])} "
                       "(listed first: the lowest held-out RMSE; the result names none of them alone).")
    final = final_interval_text(data)
    out += [f"- {line}" for line in ([final] if final else []) + verdict_lines(data)]
    lo, hi = data.get("h_range_m") or (None, None)
    if lo is not None and hi - lo > 0.001:
        out.append(f"h range over the models the data cannot tell apart: **[{lo:.3f}, {hi:.3f}] m** ("
                   + ", ".join(f"{t['effect']}: {t['h_m']:.3f} m" for t in data.get("tied_models", [])) + ").")
    out.append(f"Residual after the model: {'above' if data.get('residual_significant') else 'at'} its noise floor"
               + (f" ({data['noise_floor_nm']:.3f} N m: {floor_parts(data)})"
                  if data.get("noise_floor_nm") is not None else "")
               + ("; **unexplained**: nothing named or discovered explains it." if data.get("unexplained") else "."))
    if data.get("discovered"):
        out += ["", "### Discovered terms", "", "| term | formula | point | coordinate | coefficient |",
                "|---|---|---|---|---|"]
        out += [f"| {d['name']} | {d['formula']} | {d['point']} | {d['coordinate']} | {d['coefficient']:.4g} "
                f"{d['coefficient_unit']} |" for d in data["discovered"]]
    floor = (data.get("geometry") or {}).get("floor")
    if floor:
        out += ["", "### Floor from the wheel's contact path", "",
                f"Plane slope {floor['slope_deg']:.2f} deg ({floor['slope_along_travel_deg']:+.2f} deg along travel on "
                f"average), rises {floor['rise_m'] * 1e3:.1f} mm over {floor['extent_m']:.1f} m, smooth deviation "
                f"{floor['deviation_m'] * 1e3:.1f} mm, scatter {floor['scatter_m'] * 1e3:.2f} mm: "
                f"{'flat' if floor['flat'] else 'not flat (in the model as measured geometry)'}."]
    if data.get("analysis_warnings"):
        out += ["", "### Warnings", ""] + [f"- {w}" for w in data["analysis_warnings"]]
    out += ["", "| | h [m] | held-out RMSE [N m] |", "|---|---|---|",
            f"| before (3-DoF model) | {data['h_m']:.3f} | {data['rmse_before_nm']:.3f} |",
            f"| after ({data['effect']}) | {data['h_after_m']:.3f} | {data['rmse_after_nm']:.3f} |", "",
            "## Candidates", "", "| effect | held-out RMSE [N m] | p | p adjusted (max-T) | parameters |",
            "|---|---|---|---|---|"]
    for c in data["candidates"]:
        p = "" if c.get("p_value") is None else f"{c['p_value']:.2g}"
        pa = "" if c.get("p_adjusted") is None else f"{c['p_adjusted']:.2g}"
        rmse = "undetectable (in span of the inputs)" if not c["detectable"] else f"{c['rmse_after_nm']:.3f}"
        params = ", ".join(f"{k}={v:.4g}" for k, v in (c.get("effect_parameters") or {}).items())
        out.append(f"| {c['effect']} | {rmse} | {p} | {pa} | {params} |")
    if figures:
        out += ["", "## Figures", ""]
        out += [f"![{f.stem}]({os.path.relpath(f, base)})" for f in figures]
    out += ["", "To use the selected model: `euc-ros identify SESSION RECORDING... --from-residual THIS.json`, or set",
            "the `torque_estimator` parameters `effects` and `effect_parameters`.", ""]
    return "\n".join(out)


def floor_parts(data: dict) -> str:
    """What the noise floor holds, in words: the pose noise and the measured sliding, each propagated."""
    parts = data.get("noise_floor_parts_nm") or {}
    if not parts.get("sliding"):
        return "the recordings' pose noise propagated"
    return (f"pose noise {parts['pose_noise']:.3f} and the links' measured soft-tissue sliding "
            f"{parts['sliding']:.3f} N m, propagated")
