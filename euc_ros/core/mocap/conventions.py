"""Conventions of a recording checked against the data: which axis of the file is vertical.

A Motive CSV never says whether its world is Y-up or Z-up (the session's ``world_up`` does), and a
wrong ``world_up`` turns every height into a horizontal coordinate: the analysis still runs and gives
a wrong h with no warning. The data say which axis is up. For each candidate (the file's Y or Z
axis) the recording is read as if that axis were up and checked against what a ridden EUC looks like:

* **floor**: every tracked pivot is above the floor (none lower than :data:`FLOOR_TOLERANCE_M`
  below it);
* **upright rider**: the tracked bodies of a frame span more along the vertical than along the
  lateral axis (a standing rider is taller than wide; needs 3 or more bodies in a frame);
* **wheel centre** (needs the session): the wheel centre ``C = E + R_E @ pivot_to_wheel_center`` stays
  at about ``wheel_radius`` above the floor all along the ride (level within
  :data:`WHEEL_LEVEL_TOLERANCE_M`, spread within :data:`WHEEL_SPREAD_TOLERANCE_M`);
* **EUC axis** (needs the session): the EUC's axis, from the wheel centre C to its top pivot E, is
  near vertical (median tilt under :data:`EUC_AXIS_MAX_TILT_DEG`).

A candidate fits when it fails no test that applies. :func:`infer_up_axis` names the one that fits
when the other does not; :func:`check_conventions` (run by every offline analysis through
:func:`euc_ros.core.mocap.checks.check_recording`) turns a conclusive contradiction with the session into a
:class:`~euc_ros.core.errors.ConfigError` on the key ``world_up`` that names the value the data
suggest. Short recordings (under :data:`MIN_DURATION_S` tracked) and recordings where both axes fit
(an EUC standing still where its sideways offset happens to look like a height) are ambiguous: never
an error.

Bags are Z-up by contract (docs/bags.md): their ``y`` and ``z`` axes are the
candidates, and a bag whose data say ``y`` is an :class:`~euc_ros.core.errors.InputError` naming it.
"""
from __future__ import annotations

import numpy as np

from euc_ros.core.errors import ConfigError, InputError
from euc_ros.core.rotations import (
    rotate,
    y_up_to_z_up_position,
    y_up_to_z_up_quat,
    z_up_to_y_up_position,
    z_up_to_y_up_quat,
)

#: A pivot lower than this below the floor [m] rules the axis out as "up" (marker noise, a floor
#: calibrated a little high).
FLOOR_TOLERANCE_M = 0.05
#: The wheel centre's median height may differ from the session's wheel radius by this much [m]
#: (tyre compression, a ground plane calibrated a few cm off, a nominal radius).
WHEEL_LEVEL_TOLERANCE_M = 0.10
#: Spread (5th to 95th percentile) of the wheel centre's height over the ride [m] on a level floor.
WHEEL_SPREAD_TOLERANCE_M = 0.10
#: Largest median tilt of the EUC's axis (wheel centre -> top pivot) from the vertical [deg]; a ridden
#: EUC pitches and rolls by well under 30 deg.
EUC_AXIS_MAX_TILT_DEG = 45.0
#: An axis along which the bodies of a frame span less than this fraction of their span along the
#: other candidate (which must be at least :data:`UPRIGHT_MIN_SPAN_M`) is not the vertical.
UPRIGHT_SPAN_RATIO = 0.5
UPRIGHT_MIN_SPAN_M = 0.5
#: Least time (and frames) with the bodies a test needs tracked for it to count [s]: the tests beyond
#: the floor look at a ride, not at a pose.
MIN_DURATION_S = 0.5
MIN_SAMPLES = 10
#: Least number of bodies tracked in one frame for the upright-rider test.
UPRIGHT_MIN_BODIES = 3
#: The tests are statistics over the ride: longer recordings are thinned to this many evenly spaced
#: frames (a 10-minute recording at 120 Hz is checked in ~20 ms instead of ~0.4 s).
MAX_FRAMES = 4000

_CANDIDATES = ("y", "z")


def _read_as(series) -> tuple[str, bool]:
    """(axis the series was read with, whether it comes from a CSV); bags and in-memory series are Z-up."""
    up = series.meta.get("world_up")
    return (str(up), True) if up in _CANDIDATES else ("z", False)


def poses_with_up(series, up: str, body: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The pair (position (b, n, 3), quat (b, n, 4)) of ``series`` in Z-up as if the file's ``up`` axis were up.

    ``body``: that body's only, (n, 3) and (n, 4).

    ``series`` was read with ``series.meta["world_up"]`` (a Motive CSV) or is Z-up (a bag): with the
    other candidate the file's own axes are recovered and read again (docs/motive_csv.md).

    Parameters
    ----------
    series : MocapSeries
        The recording.
    up : str
        ``"y"`` or ``"z"``: the file axis to take as up.
    body : int, optional
        Row of one body.

    Returns
    -------
    position : numpy.ndarray
        Positions (b, n, 3), or (n, 3) for one body [m].
    quat : numpy.ndarray
        Quaternions (b, n, 4), or (n, 4) for one body.
    """
    read_as, _ = _read_as(series)
    if body is not None:
        pos, quat = (np.asarray(v, float) for v in _body_poses(series, body))
    else:
        pos, quat = np.asarray(series.position, float), np.asarray(series.quat, float)
    if up == read_as:
        return pos, quat
    if read_as == "y":  # file axes are (x, z, -y) of the series; read with Z up: no swap
        return z_up_to_y_up_position(pos), z_up_to_y_up_quat(quat)
    return y_up_to_z_up_position(pos), y_up_to_z_up_quat(quat)


class _Thinned:
    """Frames ``idx`` of a recording, for the up-axis tests.

    Its times and tracked flags taken, its poses read one body at a time (:func:`_body_poses`), never every
    body's at once.
    """

    def __init__(self, series, idx: np.ndarray) -> None:
        self.base, self.idx = series, idx
        self.t, self.tracked = series.t[idx], series.tracked[:, idx]
        self.bodies, self.meta, self.n_frames = list(series.bodies), series.meta, int(idx.size)

    def body_poses(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        return self.base.position[i][self.idx], self.base.quat[i][self.idx]


def _body_poses(series, i: int) -> tuple[np.ndarray, np.ndarray]:
    """Body ``i``'s (position (n, 3), quat (n, 4)) of a recording or of its :class:`_Thinned` frames."""
    return series.body_poses(i) if isinstance(series, _Thinned) else (series.position[i], series.quat[i])


def _thinned(series):
    """``series`` itself when it has at most :data:`MAX_FRAMES` frames, else a :class:`_Thinned` view.

    The view holds that many evenly spaced frames.
    """
    n = series.n_frames
    if n <= MAX_FRAMES:
        return series
    return _Thinned(series, np.unique(np.linspace(0, n - 1, MAX_FRAMES).round().astype(np.int64)))


def _axis_names(series) -> dict[str, str]:
    _, csv = _read_as(series)
    return {c: (f"file {c.upper()}" if csv else f"{c} axis") for c in _CANDIDATES}


def _long_enough(t: np.ndarray) -> bool:
    """At least :data:`MIN_SAMPLES` frames over :data:`MIN_DURATION_S`."""
    return t.size >= MIN_SAMPLES and float(t[-1] - t[0]) >= MIN_DURATION_S


def _floor(heights: np.ndarray) -> dict:
    """Floor test on the tracked pivot heights of every body, per candidate."""
    low = {c: float(np.min(h)) if h.size else np.nan for c, h in heights.items()}
    if not all(np.isfinite(v) for v in low.values()):
        return {}
    return {c: {"ok": low[c] >= -FLOOR_TOLERANCE_M, "value": low[c],
                "text": f"lowest pivot at {low[c]:.3f} m"} for c in _CANDIDATES}


def _heights(series, up: str) -> np.ndarray:
    """Every body's pivot height (b, n) with the file's ``up`` axis up (one body's poses turned at a time)."""
    out = np.empty((len(series.bodies), np.shape(series.t)[0]))       # (0, n) for a recording without bodies
    for i in range(len(series.bodies)):
        out[i] = poses_with_up(series, up, i)[0][:, 2]
    return out


def _upright(series, names: list[str] | None, heights: dict) -> dict:
    """Upright-rider test: median per-frame span of the tracked bodies along each candidate axis."""
    rows = list(range(len(series.bodies))) if names is None else \
        [i for i, b in enumerate(series.bodies) if b in names]
    if len(rows) < UPRIGHT_MIN_BODIES:
        return {}
    trk = np.asarray(series.tracked, bool)[rows]
    frames = trk.sum(axis=0) >= UPRIGHT_MIN_BODIES
    if not _long_enough(np.asarray(series.t, float)[frames]):
        return {}
    span = {}
    for c in _CANDIDATES:
        h = np.where(trk[:, frames], heights[c][rows][:, frames], np.nan)
        span[c] = float(np.median(np.nanmax(h, axis=0) - np.nanmin(h, axis=0)))
    out = {}
    for c, o in zip(_CANDIDATES, _CANDIDATES[::-1]):
        bad = span[o] >= UPRIGHT_MIN_SPAN_M and span[c] < UPRIGHT_SPAN_RATIO * span[o]
        out[c] = {"ok": not bad, "value": span[c], "text": f"bodies {span[c]:.2f} m tall"}
    return out


def _euc(series, session) -> tuple[dict, dict]:
    """Wheel-centre and EUC-axis tests (empty when the EUC is not tracked long enough)."""
    body = session.euc.body
    if body not in series.bodies:
        return {}, {}
    i = series.bodies.index(body)
    trk = np.asarray(series.tracked[i], bool) & np.all(np.isfinite(_body_poses(series, i)[1]), axis=-1)
    t = np.asarray(series.t, float)[trk]
    if not _long_enough(t):
        return {}, {}
    p = np.asarray(session.euc.pivot_to_wheel_center, float)
    r = session.euc.wheel_radius
    wheel, axis = {}, {}
    for c in _CANDIDATES:
        pos, quat = poses_with_up(series, c, i)
        pos, quat = pos[trk], quat[trk]
        offset = rotate(quat, p)                         # E -> C in the world
        zc = pos[:, 2] + offset[:, 2]
        level = float(np.median(zc))
        spread = float(np.percentile(zc, 95) - np.percentile(zc, 5))
        ok = abs(level - r) <= WHEEL_LEVEL_TOLERANCE_M and spread <= WHEEL_SPREAD_TOLERANCE_M
        wheel[c] = {"ok": ok, "value": level, "spread": spread,
                    "text": f"wheel centre {level:.3f} m high (spread {spread:.3f} m)"}
        norm = float(np.linalg.norm(p))
        if norm > 0:
            cos = np.clip(-offset[:, 2] / norm, -1.0, 1.0)     # C -> E against the vertical
            tilt = float(np.degrees(np.median(np.arccos(cos))))
            axis[c] = {"ok": tilt <= EUC_AXIS_MAX_TILT_DEG, "value": tilt,
                       "text": f"EUC axis {tilt:.0f} deg off vertical"}
    return wheel, axis


def infer_up_axis(series, session=None) -> dict:
    """Infer which axis of a recording is vertical from its data.

    Parameters
    ----------
    series : MocapSeries
        As read: a Motive CSV with ``meta["world_up"]`` saying how (its file's Y and Z axes are the
        candidates), or a Z-up series (a bag; its y and z axes are the candidates).
    session : Session, optional
        Gives the EUC body, ``pivot_to_wheel_center`` and ``wheel_radius`` (wheel-centre and EUC-axis
        tests) and restricts the upright-rider test to the session's bodies. Without it only the floor
        and upright-rider tests run.

    Returns
    -------
    dict
        ``inferred``: ``"y"``, ``"z"``, ``"y or z"`` (both fit) or ``"unknown"`` (neither fits, or no
        data); ``reason``: one sentence with the evidence; ``evidence``: the evidence alone (the measured
        values behind each test; for an axis that does not fit, only the tests it fails);
        ``conclusive``: a test beyond the floor applied (the floor alone is weak evidence: a ground
        plane may be calibrated anywhere); ``tests``: ``{name: {candidate: {"ok", "value", "text"}}}``
        for the tests that applied.
    """
    series = _thinned(series)
    names = _axis_names(series)
    # the tests read the pivots' heights, and the EUC's poses: never every body's turned poses at once
    up_heights = {c: _heights(series, c) for c in _CANDIDATES}
    trk = np.asarray(series.tracked, bool)
    heights = {c: h[trk] for c, h in up_heights.items()}
    heights = {c: h[np.isfinite(h)] for c, h in heights.items()}
    if not heights["y"].size:
        return {"inferred": "unknown", "reason": "no tracked rigid-body samples", "evidence": "", "conclusive": False,
                "tests": {}}
    bodies, tests = None, {}
    if session is not None:
        bodies = [*session.rider.segments, session.euc.body]
        tests["wheel_centre"], tests["euc_axis"] = _euc(series, session)
    tests["upright"] = _upright(series, bodies, up_heights)
    tests["floor"] = _floor(heights)
    tests = {k: v for k, v in tests.items() if v}
    fits = {c: all(v[c]["ok"] for v in tests.values()) for c in _CANDIDATES}
    conclusive = any(k != "floor" for k in tests)
    # the evidence: everything for an axis that fits, the failed tests for one that does not
    evidence = "; ".join(f"{names[c]} up: " + ", ".join(
        v[c]["text"] for v in tests.values() if v[c]["ok"] == fits[c]) for c in _CANDIDATES)
    if "wheel_centre" in tests:
        evidence += f"; session wheel_radius {session.euc.wheel_radius:g} m"
    if fits["y"] and fits["z"]:
        inferred, head = "y or z", "both axes fit"
    elif fits["y"] or fits["z"]:
        inferred = "y" if fits["y"] else "z"
        head = f"only {names[inferred]} fits"
    else:
        inferred, head = "unknown", "neither axis fits"
    return {"inferred": inferred, "reason": f"{head} ({evidence})", "evidence": evidence, "conclusive": conclusive,
            "tests": tests}


def check_conventions(series, session, path=None) -> list[str]:
    """Check the recording's up axis against the session; return warnings (contradictions raise).

    Parameters
    ----------
    series : MocapSeries
        The recording as read with ``session.world_up`` (a CSV) or Z-up (a bag).
    session : Session
        The session it is analysed with.
    path : str or Path, optional
        Where the recording came from (for messages; default ``series.meta["path"]``).

    Returns
    -------
    list of str
        A warning when the data fit neither axis, or contradict the session on the floor alone.

    Raises
    ------
    ConfigError
        A CSV whose data fit only the other axis: on the session's key ``world_up``, naming the value
        the data suggest and the evidence.
    InputError
        A bag (Z-up by contract) whose data fit only its y axis.
    """
    path = path if path is not None else series.meta.get("path")
    read_as, csv = _read_as(series)
    info = infer_up_axis(series, session)
    inferred, reason, evidence = info["inferred"], info["reason"], info["evidence"]
    if inferred in _CANDIDATES and inferred != read_as:
        if not info["conclusive"]:
            what = f"world_up {inferred}, not {read_as}" if csv else f"the vertical is the recording's {inferred} axis"
            return [f"the floor alone suggests {what} ({evidence}); too little data to be sure"]
        if not csv:
            raise InputError(f"the poses are not Z-up (REP-103): the data suggest the vertical is the recording's "
                             f"{inferred} axis ({evidence}); record the poses in a Z-up world", path=path)
        where = f"the data of {path}" if path is not None else "the data"
        raise ConfigError(f"world_up is {read_as!r} but {where} suggest {inferred!r} ({evidence}); "
                          f"set world_up: {inferred} (or check Motive's up axis of the export)",
                          path=session.source or path, key="world_up")
    if inferred == "unknown" and info["conclusive"]:
        return [f"the data fit neither up axis: {reason}; check the ground plane and the session's euc geometry "
                f"(wheel_radius, pivot_to_wheel_center)"]
    return []
