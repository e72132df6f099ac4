"""Figures of the CLI commands (matplotlib imported lazily with Agg), one module per figure or concern.

* :mod:`~euc_ros.cli.figures.common`: output settings (``--plot-format``, ``--dpi``), :func:`pyplot`,
  :func:`h_text` and :func:`save_figure` (lay out, check, write in every format);
* :mod:`~euc_ros.cli.figures.checks`: :func:`figure_problems`, the layout checks before writing;
* :mod:`~euc_ros.cli.figures.gaps`: spans without usable samples, shaded and breaking the lines;
* :mod:`~euc_ros.cli.figures.ride_states`: :func:`plot_ride_states`, the EUC paper's Figs 6-7 layout;
* :mod:`~euc_ros.cli.figures.rmse_curves`: :func:`plot_rmse_curves`, the paper's Fig. 8;
* :mod:`~euc_ros.cli.figures.candidates_table`, :mod:`~euc_ros.cli.figures.h_range`,
  :mod:`~euc_ros.cli.figures.residual_series`, :mod:`~euc_ros.cli.figures.residual_plots`: the figures of
  ``euc-ros residual --plots DIR`` (:func:`write_plots`).

The names the commands and the tests use are re-exported here.
"""
from __future__ import annotations

from euc_ros.cli.figures.candidates_table import (
    COLUMNS,
    EXCLUDED,
    STATUS_COLOURS,
    CandidateRow,
    candidate_rows,
    draw_candidates,
)
from euc_ros.cli.figures.checks import figure_problems, has_content
from euc_ros.cli.figures.common import (
    DPI,
    FONT_RC,
    FORMATS,
    add_figure_arguments,
    configure,
    configure_from_args,
    h_text,
    pyplot,
    save_figure,
)
from euc_ros.cli.figures.gaps import GAP_GID, GAP_LABEL, break_at_jumps, gap_spans, mark_gaps
from euc_ros.cli.figures.h_range import draw_h_range, h_status
from euc_ros.cli.figures.residual_plots import discovered_figure, write_plots
from euc_ros.cli.figures.residual_series import draw_residual_time, draw_signature
from euc_ros.cli.figures.ride_states import draw_ride_states, plot_ride_states
from euc_ros.cli.figures.rmse_curves import plot_rmse_curves

__all__ = [
    "COLUMNS", "DPI", "EXCLUDED", "FONT_RC", "FORMATS", "GAP_GID", "GAP_LABEL", "STATUS_COLOURS", "CandidateRow",
    "add_figure_arguments", "break_at_jumps", "candidate_rows", "configure", "configure_from_args",
    "discovered_figure", "draw_candidates", "draw_h_range", "draw_residual_time", "draw_ride_states",
    "draw_signature", "figure_problems", "gap_spans", "h_status", "h_text", "has_content", "mark_gaps",
    "plot_ride_states", "plot_rmse_curves", "pyplot", "save_figure", "write_plots",
]
