"""The length unit of a recording checked against the size of a rider on an EUC.

A Motive CSV states its ``Length Units``, and the reader scales to metres; an export whose values are
millimetres under a ``Meters`` label (a converter that rescaled without rewriting the header, a
hand-edited file) still reads, and every length is then 1000 times too long: the h fit runs to the end
of its grid. A rider standing on an EUC spans, from the ankles and the EUC's top to the helmet, between
:data:`MIN_SPAN_M` and :data:`MAX_SPAN_M`; the median span of the session's tracked pivots over the
recording tells the unit. A span that fits only after dividing by 1000 (or 100) is an error
naming the unit it looks like (Motive exports metres, centimetres or millimetres).

Examples
--------
>>> span_unit(1.6), span_unit(1600.0), span_unit(160.0), span_unit(10.0)
(None, 'millimetres', 'centimetres', None)
"""
from __future__ import annotations

import numpy as np

from euc_ros.core.errors import InputError

#: Plausible span of the session's pivots on a ridden EUC [m] (a child on a small EUC to a tall adult
#: with arms raised).
MIN_SPAN_M, MAX_SPAN_M = 0.3, 3.5
#: Unit names by the factor that brings a span into the plausible range.
UNITS = ((1000.0, "millimetres"), (100.0, "centimetres"))
#: Frames used (evenly spaced): the span is a median.
MAX_FRAMES = 2000


def span_unit(span_m: float) -> str | None:
    """The unit a span read as metres looks like (None when it is plausible in metres or in no unit).

    Parameters
    ----------
    span_m : float
        Span read as metres [m].

    Returns
    -------
    str or None
        Name of the unit in which the span is plausible.
    """
    if MIN_SPAN_M <= span_m <= MAX_SPAN_M or not np.isfinite(span_m):
        return None
    for factor, name in UNITS:
        if MIN_SPAN_M <= span_m / factor <= MAX_SPAN_M:
            return name
    return None


def median_span(series, bodies: list[str]) -> float:
    """Median over frames of the largest distance between two tracked pivots of ``bodies`` [m].

    NaN when no frame has two of them tracked.

    Parameters
    ----------
    series : MocapSeries
        The recording.
    bodies : list of str
        Bodies whose pivots are spanned (absent ones ignored).

    Returns
    -------
    float
        The median span [m].
    """
    rows = [series.bodies.index(b) for b in bodies if b in series.bodies]
    n = series.n_frames
    if len(rows) < 2 or n == 0:
        return float("nan")
    idx = np.unique(np.linspace(0, n - 1, min(n, MAX_FRAMES)).round().astype(np.int64))
    p = np.asarray(series.position, float)[rows][:, idx]                 # (b, m, 3)
    ok = np.asarray(series.tracked, bool)[rows][:, idx] & np.all(np.isfinite(p), axis=-1)
    p = np.where(ok[..., None], p, np.nan)
    lo, hi = np.nanmin(p, axis=0), np.nanmax(p, axis=0)                  # (m, 3) bounding box per frame
    enough = ok.sum(axis=0) >= 2
    if not enough.any():
        return float("nan")
    return float(np.median(np.linalg.norm(hi[enough] - lo[enough], axis=-1)))


def check_length_scale(series, session, path=None) -> list[str]:
    """Refuse a recording whose pivots span a size no rider on an EUC has, when a unit slip explains it.

    Parameters
    ----------
    series : MocapSeries
        The recording.
    session : Session
        Gives the rider's bodies (mass fraction > 0) and the EUC's.
    path : str or Path, optional
        File named in the error; default the recording's ``meta["path"]``.

    Returns
    -------
    list of str
        A warning for a span that is implausible in every unit (a recording of something else, or a
        mislabelled body); empty otherwise.

    Raises
    ------
    InputError
        The span fits a rider only in another unit, naming the unit and the span.
    """
    bodies = [b for b, seg in session.rider.segments.items() if seg.mass_fraction > 0] + [session.euc.body]
    span = median_span(series, bodies)
    if not np.isfinite(span):
        return []
    unit = span_unit(span)
    where = path if path is not None else series.meta.get("path")
    stated = series.meta.get("length_units")
    if unit is not None:
        label = f"the file says {stated}" if stated else "read as metres"
        raise InputError(f"the rider and EUC span {span:.4g} m ({label}): the positions look like {unit}; "
                         "re-export from Motive with Length Units set to Meters (or the unit the values are in)",
                         path=where, key="Length Units")
    if not MIN_SPAN_M <= span <= MAX_SPAN_M:
        return [f"the rider and EUC span {span:.3g} m in the median frame, not {MIN_SPAN_M}-{MAX_SPAN_M} m: check "
                "the length unit of the recording and the session's body names"]
    return []
