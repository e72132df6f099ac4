"""Layout checks of a figure before it is written (:func:`figure_problems`)."""
from __future__ import annotations

import numpy as np

from euc_ros.cli.figures.gaps import GAP_GID


def _data_points(ax) -> np.ndarray:
    """Display coordinates (m, 2) of the data drawn in ``ax`` (lines, markers, bars)."""
    pts = []
    for line in ax.get_lines():
        xy = np.asarray(line.get_xydata(), float)
        if xy.size:
            pts.append(ax.transData.transform(xy[np.all(np.isfinite(xy), axis=1)]))
    for coll in ax.collections:
        if coll.get_gid() == GAP_GID:
            continue
        off = np.asarray(coll.get_offsets(), float)
        if off.size and off.ndim == 2:
            pts.append(coll.get_offset_transform().transform(off[np.all(np.isfinite(off), axis=1)]))
    for patch in ax.patches:
        bb = patch.get_window_extent()
        if np.all(np.isfinite([bb.x0, bb.y0, bb.x1, bb.y1])) and bb.width < 0.5 * ax.bbox.width:
            pts.append(np.array([[bb.x0, bb.y1], [bb.x1, bb.y1], [0.5 * (bb.x0 + bb.x1), bb.y1]]))
    return np.concatenate(pts) if pts else np.zeros((0, 2))


def has_content(ax) -> bool:
    """Whether ``ax`` shows something (shaded gaps alone are no content).

    Something is a line with a finite point, data collections, patches, images, tables or text.
    """
    lines = [ln for ln in ax.get_lines() if np.isfinite(np.asarray(ln.get_xydata(), float)).all(axis=1).any()]
    return bool(lines or [c for c in ax.collections if c.get_gid() != GAP_GID] or ax.patches or ax.images
                or ax.tables or [t for t in ax.texts if t.get_text().strip()])


def figure_problems(fig) -> list[str]:
    """What makes a figure unfit to print: text outside the canvas, visible empty axes, a legend over data.

    The figure is drawn first (the layout is final). Returns one sentence per problem (empty: fit).
    """
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    canvas = fig.bbox
    problems = []
    def outside(bb) -> bool:
        return bb.x0 < canvas.x0 - 1 or bb.y0 < canvas.y0 - 1 or bb.x1 > canvas.x1 + 1 or bb.y1 > canvas.y1 + 1

    # what is drawn: each axes' tight box (its ticks, labels, title and legend) and the figure's own texts
    for ax in fig.axes:
        if ax.get_visible() and outside(ax.get_tightbbox(renderer)):
            problems.append(f"labels of the axes {ax.get_title()[:40]!r} are cut by the canvas edge")
    for t in [*fig.texts, *([fig._suptitle] if fig._suptitle is not None else []), *fig.legends]:
        if t.get_visible() and outside(t.get_window_extent(renderer)):
            problems.append("a figure title or legend is cut by the canvas edge")
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        if not has_content(ax):
            problems.append(f"axes {ax.get_title()[:40]!r} are empty")
        leg = ax.get_legend()
        if leg is not None and leg.get_visible():
            bb = leg.get_window_extent(renderer)
            pts = _data_points(ax)
            inside = ((pts[:, 0] > bb.x0) & (pts[:, 0] < bb.x1) & (pts[:, 1] > bb.y0) & (pts[:, 1] < bb.y1)).sum() \
                if pts.size else 0
            if inside:
                problems.append(f"the legend of {ax.get_title()[:40]!r} covers {inside} data point(s)")
    return problems

