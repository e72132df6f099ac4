"""Figure settings and writing shared by the CLI commands (matplotlib imported lazily with Agg).

Figures are written in the formats and at the resolution :func:`configure` sets (``--plot-format``,
``--dpi``): PNG for a quick look, PDF and SVG (vector) for a paper. Text is written as text a journal
accepts (:data:`FONT_RC`): TrueType fonts embedded in PDF and PostScript (no Type 3 fonts), ``<text>``
elements in SVG. Every figure is laid out by matplotlib's constrained layout and then checked by
:func:`~euc_ros.cli.figures.checks.figure_problems` (text inside the canvas, no empty axes, legends clear
of the data); a legend over the data is moved below its axes, and what cannot be fixed is a warning on the
console, never a lost analysis.

An h is written with its status (:func:`h_text`): one the data do not identify reads as a best fit not
for use, never as the answer.
"""
from __future__ import annotations

import os
import sys
import warnings
from pathlib import Path
from typing import Sequence

import numpy as np

from euc_ros.cli.figures.checks import figure_problems

#: Default raster resolution [dots per inch] (print quality; vector formats ignore it).
DPI = 200
#: Formats a figure can be written in.
FORMATS = ("png", "pdf", "svg")
#: Current output settings (:func:`configure`).
_settings = {"formats": ("png",), "dpi": DPI, "strict": False}
#: rcParams of every figure written: TrueType (Type 42) fonts in PDF and PS, text kept as text in SVG.
FONT_RC = {"pdf.fonttype": 42, "ps.fonttype": 42, "svg.fonttype": "none"}


def configure(formats: Sequence[str] = ("png",), dpi: float = DPI, *, strict: bool = False) -> None:
    """Set the formats and resolution of the figures written from now on.

    Parameters
    ----------
    formats : sequence of {"png", "pdf", "svg"}
        Every figure is written once per format (same stem).
    dpi : float
        Raster resolution [dots per inch].
    strict : bool
        A layout problem (:func:`figure_problems`) raises instead of warning (tests; also with the
        environment variable ``EUC_ROS_STRICT_FIGURES=1``).
    """
    bad = [f for f in formats if f not in FORMATS]
    if bad or not formats:
        from euc_ros.core.errors import ConfigError

        raise ConfigError(f"plot formats are {', '.join(FORMATS)}, got {', '.join(bad) or 'none'}", key="--plot-format")
    if not 30 <= dpi <= 2400:
        from euc_ros.core.errors import ConfigError

        raise ConfigError(f"--dpi must be in 30-2400, got {dpi:g}", key="--dpi")
    strict = strict or os.environ.get("EUC_ROS_STRICT_FIGURES", "") not in ("", "0")
    _settings.update(formats=tuple(dict.fromkeys(formats)), dpi=float(dpi), strict=strict)


def add_figure_arguments(parser) -> None:
    """``--plot-format`` and ``--dpi`` for a command that writes figures."""
    parser.add_argument("--plot-format", default="png", metavar="FMT[,FMT]",
                        help="figure formats: png, pdf, svg, comma-separated (pdf/svg are vector, for papers) [png]")
    parser.add_argument("--dpi", type=float, default=DPI, help=f"raster resolution of PNG figures [{DPI}]")


def configure_from_args(args) -> None:
    """Apply ``--plot-format`` and ``--dpi`` (when the command has them)."""
    fmt = getattr(args, "plot_format", None)
    if fmt is not None:
        configure([f.strip().lower() for f in str(fmt).split(",") if f.strip()], getattr(args, "dpi", DPI))


def pyplot():
    """Return ``matplotlib.pyplot`` with the non-interactive Agg backend and the font settings of :data:`FONT_RC`.

    It is imported on first use.
    """
    import matplotlib

    matplotlib.use("Agg", force=True)
    matplotlib.rcParams.update(FONT_RC)
    import matplotlib.pyplot as plt

    return plt


def h_text(h: float, identifiable: bool | None = True, *, digits: int = 3) -> str:
    """An h [m] as a figure states it, with its status.

    Parameters
    ----------
    h : float
        The fitted h [m].
    identifiable : bool or None
        Whether the data identify h (``identifiable`` of the analysis); None: not assessed.
    digits : int
        Decimals of the metre value.

    Returns
    -------
    str
        ``h = 0.667 m``; ``h not identifiable (best fit 0.667 m, not for use)``; ``h = 0.667 m
        (identifiability not assessed)``; ``h not determined`` for a value that is not finite.
    """
    if h is None or not np.isfinite(h):
        return "h not determined"
    if identifiable is False:
        return f"h not identifiable (best fit {h:.{digits}f} m, not for use)"
    if identifiable is None:
        return f"h = {h:.{digits}f} m (identifiability not assessed)"
    return f"h = {h:.{digits}f} m"


def _move_legends_below(fig) -> None:
    for ax in fig.axes:
        leg = ax.get_legend()
        if leg is not None:
            handles, labels = ax.get_legend_handles_labels()
            ax.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, -0.18), fontsize=8,
                      ncols=min(3, max(1, len(labels))), frameon=False)


def save_figure(fig, path: str | Path, title: str = "") -> Path:
    """Title, lay out, check, write ``path`` in every configured format (parent created), close the figure.

    Returns the path of the first format written (the one a report links).
    """
    if title:
        fig.suptitle(title, fontsize=10)
    fig.set_layout_engine("constrained")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)      # layout notes: checked below instead
        problems = figure_problems(fig)
        if any("legend" in p for p in problems):
            _move_legends_below(fig)
            problems = figure_problems(fig)
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        written = []
        import matplotlib

        with matplotlib.rc_context(FONT_RC):
            for fmt in _settings["formats"]:
                out = path.with_suffix(f".{fmt}")
                meta = {"Creator": "euc_ros"} if fmt != "png" else None
                fig.savefig(out, dpi=_settings["dpi"], format=fmt, metadata=meta)
                written.append(out)
    pyplot().close(fig)
    if problems:
        text = f"figure {path.name}: " + "; ".join(problems)
        if _settings["strict"]:
            raise AssertionError(text)
        print(f"warning: {text}", file=sys.stderr)
    return written[0]
