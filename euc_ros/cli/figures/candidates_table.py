"""The ``candidates`` figure of ``euc-ros residual --plots DIR``.

The candidate table with a status per row (:func:`candidate_rows`): selected, tie, refused, not admissible,
undetectable, not significant; refused and not admissible rows are coloured and their reasons listed under
the table, so no refused effect reads as a contender.
"""
from __future__ import annotations

import textwrap
from dataclasses import dataclass

from euc_ros.cli.figures.common import pyplot

#: Row status of the candidate table, and its row colour.
STATUS_COLOURS = {
    "selected": "#d9ead3",
    "selected (tie)": "#d9ead3",
    "tie": "#fff2cc",
    "refused": "#f4cccc",
    "not admissible": "#fce5cd",
    "undetectable": "#e6e6e6",
    "not significant": "#ffffff",
    "not selected": "#ffffff",
    "baseline": "#ffffff",
}
#: Statuses of rows that are no explanation (their text is greyed).
EXCLUDED = ("refused", "not admissible", "undetectable")
#: Columns of the candidate table.
COLUMNS = ("effect", "status", "held-out RMSE [N m]", "p", "p adj.", "parameters")


@dataclass(frozen=True)
class CandidateRow:
    """One row of the candidate figure.

    Attributes
    ----------
    effect : str
        The candidate's name (``none``: the base model).
    status : str
        One of :data:`STATUS_COLOURS`.
    rmse : str
        Held-out RMSE [N m] (``-`` when undetectable).
    p, p_adjusted : str
        Its p-value and the family-wise one (``-``: not tested).
    parameters : str
        Fitted parameters, ``name=value``.
    note : str
        Why it was refused or is not admissible (empty otherwise).
    """

    effect: str
    status: str
    rmse: str
    p: str
    p_adjusted: str
    parameters: str
    note: str = ""

    def cells(self) -> list[str]:
        """The table cells, in the order of :data:`COLUMNS`."""
        return [self.effect, self.status, self.rmse, self.p, self.p_adjusted, self.parameters]


def _p(v) -> str:
    return "-" if v is None else f"{v:.2g}"


def candidate_rows(data: dict) -> list[CandidateRow]:
    """The candidate table of a residual JSON document, each row with its status.

    The status of a candidate, first match: ``selected`` (``selected (tie)`` when the data cannot tell it
    from another explanation); ``refused`` (its fit left a plausible range: a row flag ``refused`` or an
    entry of ``refused``); ``not admissible``; ``undetectable``; ``tie``; ``not significant`` (family-wise p
    at or above the significance level); ``not selected``. The row ``none`` (the base model) is
    ``selected`` when no effect was selected, else ``baseline``.

    Parameters
    ----------
    data : dict
        The residual analysis' JSON document (``candidates``, ``selection_steps``, ``refused``, ``ties``,
        ``ambiguous_with``, ``effect``, ``significance_level``).

    Returns
    -------
    list of CandidateRow
        In the order of ``data["candidates"]``.
    """
    named = {s["selected"] for s in data.get("selection_steps", [])
             if s.get("selected") not in (None, "discovered")}
    refused: dict[str, list[str]] = {}
    for r in data.get("refused", []):
        refused.setdefault(r["effect"], []).append(r.get("text") or f"refused {r['effect']}")
    tied = {e for t in data.get("ties", []) for e in t.get("effects", [])} | set(data.get("ambiguous_with", []))
    alpha = data.get("significance_level")
    rows = []
    for c in data.get("candidates", []):
        e = c["effect"]
        note = ""
        if e == "none":
            status = "selected" if data.get("effect") == "none" else "baseline"
        elif e in named:
            status = "selected (tie)" if e in tied else "selected"
        elif c.get("refused") or e in refused:
            status = "refused"
            note = "; ".join(dict.fromkeys([t for t in [c.get("refused")] if t] + refused.get(e, [])))
        elif c.get("inadmissible"):
            status = "not admissible"
            note = f"{e} not admissible: {str(c['inadmissible']).removeprefix(e + ': ')}"
        elif not c.get("detectable", True):
            status = "undetectable"
        elif e in tied:
            status = "tie"
        elif alpha is not None and c.get("p_adjusted") is not None and c["p_adjusted"] >= alpha:
            status = "not significant"
        else:
            status = "not selected"
        detectable = c.get("detectable", True) and c.get("rmse_after_nm") is not None
        rows.append(CandidateRow(
            effect=e, status=status, rmse=f"{c['rmse_after_nm']:.3f}" if detectable else "-",
            p=_p(c.get("p_value")), p_adjusted=_p(c.get("p_adjusted")),
            parameters=", ".join(f"{k}={v:.3g}" for k, v in (c.get("effect_parameters") or {}).items()),
            note=note))
    return rows


def draw_candidates(data: dict):
    """The candidate table of a residual JSON document (:func:`candidate_rows`) as a Figure.

    One row per candidate with its status, coloured by it (:data:`STATUS_COLOURS`), and the reasons of the
    refused and not admissible ones under the table.
    """
    plt = pyplot()
    rows = candidate_rows(data)
    notes = [line for r in rows if r.note for line in textwrap.wrap(r.note, 140, subsequent_indent="    ")]
    table_h = 0.26 * (len(rows) + 1)
    notes_h = 0.17 * len(notes) + (0.1 if notes else 0.0)
    fig, ax = plt.subplots(figsize=(10, table_h + notes_h + 0.6))
    ax.axis("off")
    frac = table_h / (table_h + notes_h)
    table = ax.table(cellText=[r.cells() for r in rows], colLabels=list(COLUMNS), loc="center", cellLoc="left",
                     bbox=[0, 1 - frac, 1, frac], colWidths=[0.2, 0.12, 0.14, 0.07, 0.07, 0.4])
    table.auto_set_font_size(False)
    table.set_fontsize(8)
    for (i, _), cell in table.get_celld().items():
        cell.PAD = 0.03
        if i == 0:
            cell.set_text_props(weight="bold")
            continue
        row = rows[i - 1]
        cell.set_facecolor(STATUS_COLOURS.get(row.status, "#ffffff"))
        if row.status in EXCLUDED:
            cell.get_text().set_color("0.35")
    if notes:
        ax.text(0.0, (1 - frac) - 0.02, "\n".join(notes), transform=ax.transAxes, ha="left", va="top", fontsize=7)
    effect = data.get("effect", "none")
    ax.set_title(f"candidates (selected: {effect}); refused and not admissible fits are no explanation",
                 fontsize=10)
    return fig

