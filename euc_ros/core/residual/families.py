"""Flexible function families of the discovery: the basis its search chooses from (:mod:`.search`).

A discovered force is a smooth function of measured signals acting at a physical point. Each **family**
is a group of basis columns (functions of the recording, before the point) at a few complexity
**levels**; with a point (:data:`POINTS`) it is a **group** of generalized-force columns, chosen or left
out as a whole (:func:`~euc_ros.core.residual.search.group_path`). The families (signals of a recording's
context; SI units):

==================  ==============================  =========================================================
family              argument                        columns (level = complexity)
==================  ==============================  =========================================================
``lab field``       lab X (lab Y), alone, times     B-splines of the lab position, times ``cos(psi)``
                    x_dot or sign(x_dot)            (``sin(psi)``): a lab-fixed horizontal force as the
                                                    heading sees it; levels: linear and cubic over the
                                                    observed range, then cubic pieces of 4, 2 and 1 m over
                                                    the span two passes meet (:func:`revisited_span`),
                                                    zero beyond their support (:func:`local_bspline_basis`)
``wheel rotation``  wheel angle s/R                 Fourier series ``sin(k s/R), cos(k s/R)``, k = 1..K,
                                                    K = 1..4 (an out-of-round or unbalanced tyre)
``speed``           speed |x_dot|, odd or even      B-splines of ``|x_dot|`` (levels as the lab field), times
                                                    ``sign(x_dot)`` (odd: viscous, quadratic, Coulomb-like)
                                                    or not (even)
``drift``           time t, per recording           Legendre polynomials of degree 0..L (L = 0, 1, 2) over
                                                    each recording's own time range, zero on the others;
                    or since each recording's       or one such polynomial (degree 1..L) of the time since
                    start, shared                   each recording's start, shared by the recordings
``dynamics``        x_dot, |x_dot|, phi_dot,        the state through causal first-order low-passes
                    gamma_dot                       ``1 / (tau s + 1)``, tau in :data:`TIME_CONSTANTS_S`
                                                    (level 1), and their squares (critically damped second
                                                    order, level 2): a force obeying its own linear
                                                    dynamics driven by a state
``oscillator``      x_dot, phi_dot, gamma_dot       a resonance of the state without its ends (no mass, no
(not in the         (:data:`OSCILLATORS`)           acceleration: :func:`~.basis_filters.payload_band`),
default)                                            with the derivatives in ``ln w``, one resonance
                                                    frequency per level (:data:`RESONANCE_HZ`, damping
                                                    :data:`~.basis_filters.RESONANCE_DAMPING`): a payload
                                                    on a spring carried by the rider or the EUC
a user's family     one of :data:`ARGUMENTS`        the user's ``basis(x, level) -> (n, m)``
                                                    (:meth:`Family.custom`)
==================  ==============================  =========================================================

Not in any family: accelerations and pitch angles themselves (the residual is linear in them, so such
columns cancel the residual's own noise on held-out data; the named mass and inertia candidates test
them). The longest time constant (3 s) keeps the filtered pitch rates from turning into pitch angles over
the runs' seconds. Families whose columns span the same space as an earlier one on the recordings (the odd
and even speed parts when the speed never changes sign, a lab field times sign(x_dot) then, a constant
lab Y) are dropped (:class:`Families`).

The spline knots, ranges and recording names are fixed from the analysed recordings (the argument's
observed range, not the residual), so every fold and every re-prepared copy of the recordings shares them;
outside the range the argument is clipped (constant extrapolation).

The filters that make the dynamics and oscillator columns, and the states' smoothing they pass through, are in
:mod:`.basis_filters`; the phases of the ``aligned`` wheel family in :mod:`.wheel_phase` (both importable from here).
"""
from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np
from numpy.polynomial import legendre
from scipy import signal

from euc_ros.core.errors import ConfigError
from euc_ros.core.memory import release_free_memory
from euc_ros.core.residual.basis_filters import RESONANCE_DAMPING as RESONANCE_DAMPING
from euc_ros.core.residual.basis_filters import RESONANCE_STEP as RESONANCE_STEP
from euc_ros.core.residual.basis_filters import low_pass, resonator_columns, savgol_kernel
from euc_ros.core.residual.basis_filters import payload_band as payload_band
from euc_ros.core.residual.basis_filters import resonate as resonate
from euc_ros.core.residual.splines import bspline_basis as bspline_basis
from euc_ros.core.residual.splines import local_bspline_basis as local_bspline_basis
from euc_ros.core.residual.splines import local_pieces
from euc_ros.core.residual.splines import revisited_span as revisited_span
from euc_ros.core.residual.splines import uniform_knots as uniform_knots
from euc_ros.core.residual.wheel_phase import PHASE_GRID as PHASE_GRID
from euc_ros.core.residual.wheel_phase import PHASE_SWEEPS as PHASE_SWEEPS
from euc_ros.core.residual.wheel_phase import align_wheel_phases as align_wheel_phases
from euc_ros.core.residual.wheel_phase import phase_rotations as phase_rotations
from euc_ros.core.residual.wheel_phase import wheel_phase_mix as wheel_phase_mix

#: (coordinate, point) of the forces' directions and points of application.
POINTS = (("x", "contact"), ("x", "rider CoG"), ("z", "rider CoG"), ("pitch", "rider"))
#: Unit of each point's generalized force: a force [N], or a torque on the rider's pitch [N m].
POINT_UNITS = ("N", "N", "N", "N m")
#: Speed scale of the smooth sign ``tanh(x_dot / SIGN_SPEED)`` [m/s].
SIGN_SPEED = 0.05
#: Time constants of the dynamics family [s] (a factor ~3 apart: a first-order law between two of them is
#: a combination of its neighbours to a few per cent, measured in ``test_families.py``).
TIME_CONSTANTS_S = (0.1, 0.3, 1.0, 3.0)
#: Resonance frequencies of the oscillator family [Hz], one per level (a geometric grid, 16 % apart). A payload's
#: reaction of a resonance between two of them (damping 0.05-0.2) carried at a random speed is explained by
#: its nearer level's columns to 0.78-0.90 of its variance (5 draws; ``test_families.py`` asks 0.7).
RESONANCE_HZ = tuple(float(f) for f in np.geomspace(0.5, 4.0, 15))
#: Most wheel-angle harmonics.
MAX_HARMONICS = 4
#: Spline levels of the speed: (degree, interior knots at quantiles of the observed argument).
SPLINE_LEVELS = ((1, 0), (3, 0), (3, 3))
#: Levels of a lab field: (degree, knot spacing [m]; None: no interior knot). A force fixed in the lab has
#: features of its own size wherever they are (a mat, a door's draught, a ramp: about 1-5 m), so its finer
#: levels space their knots evenly in metres, not at quantiles of where the rider happened to be, and only over
#: the span two passes meet: a feature one pass crossed is fitted by its own columns, which no held-out pass
#: can check, and costs the search their price (measured on the open-world pilot: a 31 m range with 8 m met
#: twice had 34 columns at 1 m).
LAB_LEVELS = ((1, None), (3, None), (3, 4.0), (3, 2.0), (3, 1.0))
#: Return [m] from a pass's furthest point that starts the next pass (:func:`revisited_span`): the levels with knots
#: fit a lab field only over the span two passes meet, where a held-out pass can check it.
REVERSAL_M = 0.25
#: Highest drift polynomial degree per recording.
MAX_DRIFT_DEGREE = 2
#: Columns with less than this relative residual outside another family's span duplicate it on these recordings
#: (tanh(v / 0.05) and 1 differ by 1e-5 at 0.3 m/s).
DUPLICATE_TOL = 1e-3
#: Points on the report grid of a discovered function.
GRID_POINTS = 41


@dataclass(frozen=True)
class Family:
    """One family of basis functions with one argument (a group before its point).

    Parameters
    ----------
    kind : str
        ``lab``, ``wheel``, ``speed``, ``drift``, ``dyn``, ``osc`` or ``custom``.
    option : tuple
        The kind's options (lab: coordinate ``X``/``Y`` and modifier ``1``/``speed``/``sign``; wheel:
        ``aligned`` or none; speed: ``odd``/``even``; dyn, osc: the state; custom: the argument).
    family, argument, argument_unit : str
        Names for the report.
    function : str
        The force's form, e.g. ``f(X) cos(psi)``.
    per_unit : str
        Unit the reported function is per (``1``: a force; ``m/s``: a force per unit speed).
    basis : callable, optional
        A custom family's ``basis(x, level) -> (n, m)`` (:meth:`custom`).
    levels : int
        A custom family's complexity levels.
    """

    kind: str
    option: tuple
    family: str
    argument: str
    argument_unit: str
    function: str
    per_unit: str = "1"
    basis: Callable[[np.ndarray, int], np.ndarray] | None = None
    levels: int = 1

    @property
    def key(self) -> str:
        """``"<family>: <function>"``: the family's name with its force's form (in the report and parameter names)."""
        return f"{self.family}: {self.function}"

    @classmethod
    def custom(cls, family: str, argument: str, basis: Callable[[np.ndarray, int], np.ndarray], *,
               levels: int = 1, function: str | None = None) -> "Family":
        """A family of the user's basis functions of one signal of the recordings (``kind="custom"``).

        Parameters
        ----------
        family : str
            Its name in the report.
        argument : str
            The signal the functions take, one of :data:`ARGUMENTS` (its unit is the report's).
        basis : callable
            ``basis(x, level) -> ndarray (n, m)``: the columns at complexity ``level`` (0 to ``levels - 1``)
            of the argument's samples ``x`` (n,); ``m`` may depend on the level only. A force along the
            group's direction is ``basis(x, level) @ c``.
        levels : int
            Complexity levels (nested or not: each is a group of its own).
        function : str, optional
            The force's form in the report (default ``f(<argument>)``).

        Returns
        -------
        Family

        Raises
        ------
        ConfigError
            An unknown argument, no level, or a basis that does not give finite (n, m) columns.

        Examples
        --------
        >>> fam = Family.custom("tyre wear", "wheel_angle", lambda th, lv: np.cos(th)[:, None])
        >>> fam.key, fam.argument_unit, fam.levels
        ('tyre wear: f(wheel_angle)', 'rad', 1)
        """
        if argument not in ARGUMENTS:
            raise ConfigError(f"expected one of {', '.join(ARGUMENTS)}, got {argument!r}", key="argument")
        if int(levels) < 1:
            raise ConfigError(f"need at least one level, got {levels}", key="levels")
        probe = np.linspace(-1.0, 1.0, 7)
        for lv in range(int(levels)):
            with np.errstate(all="ignore"):
                C = np.asarray(basis(probe, lv), float)
            if C.ndim != 2 or C.shape[0] != probe.size or C.shape[1] < 1 or not np.all(np.isfinite(C)):
                raise ConfigError(f"basis(x, {lv}) must give finite columns of shape (len(x), m), got "
                                  f"shape {C.shape}", key="basis")
        return cls("custom", (argument,), family, argument, ARGUMENTS[argument][1],
                   function or f"f({argument})", "1", basis, int(levels))


def _family_list() -> list[Family]:
    out = []
    for coord, proj in (("X", "cos(psi)"), ("Y", "sin(psi)")):
        for mod, label, unit in (("1", "", "1"), ("speed", " x_dot", "m/s"), ("sign", " sign(x_dot)", "1")):
            out.append(Family("lab", (coord, mod), "lab field", f"lab {coord}", "m", f"f({coord}){label} {proj}", unit))
    out.append(Family("wheel", (), "wheel rotation", "wheel angle s/R", "rad", "f(s/R)"))
    out.append(Family("wheel", ("aligned",), "wheel rotation", "wheel angle s/R (+ a phase per recording)", "rad",
                      "f(s/R + delta_run)"))
    out.append(Family("speed", ("odd",), "speed", "speed |x_dot|", "m/s", "f(|x_dot|) sign(x_dot)"))
    out.append(Family("speed", ("even",), "speed", "speed |x_dot|", "m/s", "f(|x_dot|)"))
    # the shared drift first: it lies in the span of the per-recording ones, which would prune it
    out.append(Family("drift", ("shared",), "drift", "time t since the recording's start", "s", "f(t)"))
    out.append(Family("drift", (), "drift", "time t per recording", "s", "f_run(t)"))
    for state, unit in (("x_dot", "m/s"), ("|x_dot|", "m/s"), ("phi_dot", "rad/s"), ("gamma_dot", "rad/s")):
        out.append(Family("dyn", (state,), "dynamics", f"time after a unit step of {state}", "s",
                          f"G(s) {state}", unit))
    return out


#: Every family of the default discovery before the recordings prune duplicates.
FAMILIES = tuple(_family_list())
#: The oscillator families (one per state), not in :data:`FAMILIES`: on rides with soft-tissue sliding and no
#: force they explain the sliding (a tissue that follows the segment's acceleration is itself a damped
#: oscillator; ``test_artefacts_residual.py``), so they are the user's to add (``FAMILIES + OSCILLATORS``).
OSCILLATORS = tuple(Family("osc", (state,), "oscillator", f"time after a unit step of {state}", "s",
                           f"H_f(s) {state}", unit)
                    for state, unit in (("x_dot", "m/s"), ("phi_dot", "rad/s"), ("gamma_dot", "rad/s")))


#: The signals a user's family (:meth:`Family.custom`) may take: name -> (how it is made from a recording's
#: signals, its unit).
ARGUMENTS = {
    "x_dot": (lambda sig: sig["v"], "m/s"),
    "|x_dot|": (lambda sig: np.abs(sig["v"]), "m/s"),
    "path_s": (lambda sig: sig["s"], "m"),
    "wheel_angle": (lambda sig: sig["s"] / sig["R"], "rad"),
    "lab_x": (lambda sig: sig["X"], "m"),
    "lab_y": (lambda sig: sig["Y"], "m"),
    "psi": (lambda sig: sig["psi"], "rad"),
    "phi_dot": (lambda sig: sig["phi_dot"], "rad/s"),
    "gamma_dot": (lambda sig: sig["gamma_dot"], "rad/s"),
    "t": (lambda sig: sig["t"], "s"),
}


def n_levels(fam: Family) -> int:
    """Complexity levels of a family.

    Parameters
    ----------
    fam : Family

    Returns
    -------
    int
    """
    if fam.kind == "custom":
        return fam.levels
    if fam.kind == "drift" and fam.option:     # the shared drift starts at degree 1 (:func:`drift_degree`)
        return MAX_DRIFT_DEGREE
    return {"lab": len(LAB_LEVELS), "speed": len(SPLINE_LEVELS), "wheel": MAX_HARMONICS,
            "drift": MAX_DRIFT_DEGREE + 1, "dyn": 2, "osc": len(RESONANCE_HZ)}[fam.kind]


def drift_degree(fam: Family, level: int) -> int:
    """The polynomial degree of a drift family at ``level``.

    A per-recording drift starts at degree 0 (a constant per recording); the shared one at degree 1: one constant
    shared by every recording is no drift but a constant force, which the library names (a slope, a rider mass
    error, rolling resistance) and which would tie with them.

    Parameters
    ----------
    fam : Family
        A ``drift`` family.
    level : int

    Returns
    -------
    int
    """
    return level + 1 if fam.option else level


def _signals(ctx) -> dict:
    full = ctx.extras.get("full")
    if full is not None and len(full["index"]) == np.shape(ctx.t)[0]:
        # every sample of the recording: the columns are made there and passed through the states' filter
        return {"t": np.asarray(full["t"], float), "v": np.asarray(full["v"], float), "s": np.asarray(full["s"], float),
                "psi": full["psi"], "X": full["X"], "Y": full["Y"], "phi_dot": full["phi_dot"],
                "gamma_dot": full["gamma_dot"], "R": float(np.mean(ctx.params.R)),
                "name": ctx.extras.get("recording", ""), "index": np.asarray(full["index"]),
                "smooth": savgol_kernel(full["window"], full["polyorder"])}
    v = np.asarray(ctx.x_dot, float)
    t = np.asarray(ctx.t, float)
    s = ctx.extras.get("path_s")
    if s is None:
        s = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
    return {"t": t, "v": v, "s": np.asarray(s, float), "psi": np.asarray(ctx.psi, float),
            "X": np.asarray(ctx.extras.get("lab_x", np.zeros_like(t)), float),
            "Y": np.asarray(ctx.extras.get("lab_y", np.zeros_like(t)), float),
            "phi_dot": np.asarray(ctx.phi_dot, float), "gamma_dot": np.asarray(ctx.gamma_dot, float),
            "R": float(np.mean(ctx.params.R)), "name": ctx.extras.get("recording", "")}


class _Scaled:
    """The columns ``B * factor[:, None]``, made a block of columns at a time or whole.

    A block by ``C[:, lo:hi]``, whole by ``np.asarray``: a lab coordinate's spline basis times its modifier, without a
    second full-rate copy.
    """

    def __init__(self, B: np.ndarray, factor: np.ndarray) -> None:
        self.B, self.factor = B, factor
        self.shape = B.shape

    def __getitem__(self, key):
        rows, cols = key
        return self.B[rows, cols] * self.factor[rows, None]

    def __array__(self, dtype=None, copy=None):
        out = self.B * self.factor[:, None]
        return out if dtype is None else out.astype(dtype)


def _as_seen(C, sig: dict) -> np.ndarray:
    """Columns made on every sample, smoothed by the states' Savitzky-Golay filter and taken at the analysed samples.

    An extra force moves the residual through the filtered accelerations, so a force faster than the filter's passband
    (a tyre's harmonics at speed, a short bump passed quickly) reaches it smoothed alike.
    """
    if "smooth" not in sig:
        return np.asarray(C)
    k = sig["smooth"]
    h = k.size // 2
    index = sig["index"]
    out = np.empty((len(index), C.shape[1]))
    # a few columns at a time (each column is filtered on its own: the same numbers), so the padded and
    # filtered copies at the full rate are a block's, not every column's
    step = max(1, _SEEN_BLOCK // max(C.shape[0], 1))
    for lo in range(0, C.shape[1], step):
        Cp = np.pad(C[:, lo:lo + step], ((h, h), (0, 0)), mode="edge")
        out[:, lo:lo + step] = signal.oaconvolve(Cp, k[::-1, None], mode="valid", axes=0)[index]
    return out


#: Full-rate columns made [bytes] above which their freed temporaries are returned to the OS at once.
_RELEASE_BYTES = 64 << 20
#: Samples x columns filtered at once by :func:`_as_seen` (4 MB per full-rate copy).
_SEEN_BLOCK = 1 << 19


def _state(sig: dict, name: str) -> np.ndarray:
    return {"x_dot": sig["v"], "|x_dot|": np.abs(sig["v"]), "phi_dot": sig["phi_dot"],
            "gamma_dot": sig["gamma_dot"]}[name]


def _arrays(ctx) -> tuple:
    """The context arrays the columns are made from (their identity keys the caches)."""
    return (ctx.t, ctx.x_dot, ctx.psi, ctx.phi_dot, ctx.gamma_dot)


def _arrays_key(ctx) -> tuple:
    return tuple(id(a) for a in _arrays(ctx))


class Families:
    """The families' basis over a set of recordings: ranges, knots and recording names fixed from them.

    Parameters
    ----------
    ctxs : sequence of ModelContext
        The analysed recordings' contexts (their ``extras``: ``path_s``, ``lab_x``, ``lab_y``, ``recording``).
    families : sequence of Family, optional
        Families to consider (default :data:`FAMILIES`); duplicates on these recordings are dropped.
    """

    CACHE = 64

    def __init__(self, ctxs: Sequence, families: Sequence[Family] = FAMILIES):
        sigs = [_signals(c) for c in ctxs]
        # ranges and knots from the analysed samples
        at = [{k: (np.asarray(v)[s["index"]] if "index" in s and k in ("X", "Y", "v") else v) for k, v in s.items()}
              for s in sigs]
        cat = {k: np.concatenate([s[k] for s in at]) for k in ("X", "Y", "v")}
        self.ranges: dict[str, tuple[float, float, list[np.ndarray]]] = {}
        #: Per lab coordinate, the span two passes meet (:func:`revisited_span`): the knotted levels' range.
        self.spans: dict[str, tuple[float, float] | None] = {}
        for name, x in (("X", cat["X"]), ("Y", cat["Y"]), ("speed", np.abs(cat["v"]))):
            lo, hi = (float(np.min(x)), float(np.max(x))) if x.size else (0.0, 0.0)
            if name == "speed":
                knots = [np.quantile(x, np.linspace(0, 1, k + 2)[1:-1]) if hi > lo else np.zeros(k)
                         for _, k in SPLINE_LEVELS]
            else:
                knots = [uniform_knots(lo, hi, sp) for _, sp in LAB_LEVELS]
                self.spans[name] = revisited_span([s[name] for s in at], REVERSAL_M) if hi > lo else None
            self.ranges[name] = (lo, hi, knots)
        self.runs: dict[str, tuple[float, float]] = {}
        for s in sigs:
            lo, hi = self.runs.get(s["name"], (np.inf, -np.inf))
            self.runs[s["name"]] = (min(lo, float(s["t"].min())), max(hi, float(s["t"].max())))
        self.run_names = list(self.runs)
        # a user's families: their argument's observed range (the report's grid)
        for fam in families:
            if fam.kind == "custom" and fam.option[0] not in self.ranges:
                x = np.concatenate([np.asarray(ARGUMENTS[fam.option[0]][0](s), float)[s["index"]] if "index" in s
                                    else np.asarray(ARGUMENTS[fam.option[0]][0](s), float) for s in sigs])
                self.ranges[fam.option[0]] = (float(np.min(x)), float(np.max(x)), []) if x.size else (0.0, 0.0, [])
        self._cache: OrderedDict = OrderedDict()
        self.families: list[Family] = []
        kept: list[np.ndarray] = []
        # each recording's top-level columns, made here for the duplicate test, are kept for columns()
        self._top: dict[tuple, tuple] = {}
        made_bytes = 0
        for fam in families:
            if fam.kind in ("lab", "speed") and self._degenerate(fam):
                continue
            top = n_levels(fam) - 1
            if fam.kind != "lab":
                for s in sigs:
                    s.pop("_splines", None)     # the lab families' last spline basis: not needed any more
            per = [_as_seen(self._columns(fam, top, s), s) for s in sigs]
            made_bytes += sum(len(sg["t"]) * C.shape[1] * 8 for sg, C in zip(sigs, per))
            for c, C in zip(ctxs, per):
                self._top[(id(fam), _arrays_key(c))] = (_arrays(c), C)
            C = np.concatenate(per) if sigs else np.zeros((0, 1))
            scale = np.linalg.norm(C, axis=0)
            if not np.any(scale > 0):
                continue
            Cn = C[:, scale > 0] / scale[scale > 0]
            if any(_inside(Cn, K) for K in kept):
                continue
            self.families.append(fam)
            kept.append(Cn)
        if made_bytes > _RELEASE_BYTES:
            release_free_memory()       # the full-rate columns' temporaries

    def width(self, f: int, level: int) -> int:
        """Columns of family ``f`` at ``level``.

        Parameters
        ----------
        f : int
            Index into :attr:`families`.
        level : int

        Returns
        -------
        int
        """
        kind = self.families[f].kind
        if kind == "custom":
            return int(np.shape(self.families[f].basis(np.linspace(-1.0, 1.0, 7), level))[1])
        if kind in ("lab", "speed"):
            name = self.families[f].option[0] if kind == "lab" else "speed"
            degree, spacing = (LAB_LEVELS if kind == "lab" else SPLINE_LEVELS)[level]
            span = self.spans.get(name) if kind == "lab" and spacing is not None else None
            if span is not None:
                return local_pieces(span[0], span[1], spacing) + degree
            return degree + len(self.ranges[name][2][level]) + 1
        if kind == "wheel":
            return 2 * (level + 1) * (len(self.run_names) if self.families[f].option else 1)
        if kind == "drift":
            degree = drift_degree(self.families[f], level)
            return (degree + 1) * (1 if self.families[f].option else len(self.run_names))
        if kind == "osc":
            return 4
        return len(TIME_CONSTANTS_S) * (level + 1)

    def _degenerate(self, fam: Family) -> bool:
        lo, hi, _ = self.ranges[fam.option[0] if fam.kind == "lab" else "speed"]
        return not hi > lo

    # ------------------------------------------------------------------ columns
    def _spline(self, name: str, x: np.ndarray, level: int) -> np.ndarray:
        lo, hi, knots = self.ranges[name]
        degree, spacing = (SPLINE_LEVELS if name == "speed" else LAB_LEVELS)[level]
        span = self.spans.get(name) if name != "speed" and spacing is not None else None
        if span is not None:
            return local_bspline_basis(x, span[0], span[1], degree, spacing)
        return bspline_basis(x, lo, hi, degree, knots[level])

    def _columns(self, fam: Family, level: int, sig: dict) -> np.ndarray:
        """The family's columns (n, m) at ``level`` on one recording's signals.

        A lab coordinate's spline basis is made once per signals and level, for every modifier.
        """
        v = sig["v"]
        if fam.kind == "custom":
            return np.asarray(fam.basis(np.asarray(ARGUMENTS[fam.option[0]][0](sig), float), level), float)
        if fam.kind == "lab":
            coord, mod = fam.option
            proj = np.cos(sig["psi"]) if coord == "X" else np.sin(sig["psi"])
            factor = {"1": 1.0, "speed": v, "sign": np.tanh(v / SIGN_SPEED)}[mod] * proj
            memo = sig.setdefault("_splines", {})
            if (coord, level) not in memo:
                # one basis kept at a time (at the full rate it is the size of a recording's poses): the
                # callers make a coordinate's modifiers one after the other at each level
                memo.clear()
                memo[(coord, level)] = self._spline(coord, sig[coord], level)
            return _Scaled(memo[(coord, level)], factor)
        if fam.kind == "wheel":
            th = sig["s"] / sig["R"]
            k = np.arange(1, level + 2)
            F = np.concatenate([np.sin(np.outer(th, k)), np.cos(np.outer(th, k))], axis=1)
            if not fam.option:
                return F
            # the tyre's angle when a recording starts is not measured: the raw columns are the recording's own
            # (zero on the others); the selection turns them into one function with a phase per recording
            # (wheel_phase_mix)
            out = np.zeros((v.size, len(self.run_names) * F.shape[1]))
            if sig["name"] in self.runs:
                j = self.run_names.index(sig["name"])
                out[:, j * F.shape[1]:(j + 1) * F.shape[1]] = F
            return out
        if fam.kind == "speed":
            B = self._spline("speed", np.abs(v), level)
            return B * np.tanh(v / SIGN_SPEED)[:, None] if fam.option[0] == "odd" else B
        if fam.kind == "drift" and fam.option:
            # one function of the time since each recording's start, shared by the recordings (what every run
            # goes through again: a warm-up, a controller's or a battery's state after each start)
            lo = self.runs[sig["name"]][0] if sig["name"] in self.runs else float(sig["t"][0])
            span = max(max(hi - a for a, hi in self.runs.values()), 1e-9)
            u = np.clip(2.0 * (sig["t"] - lo) / span - 1.0, -1.0, 1.0)
            return legendre.legvander(u, drift_degree(fam, level))
        if fam.kind == "drift":
            out = np.zeros((v.size, len(self.run_names) * (level + 1)))
            if sig["name"] in self.runs:
                j = self.run_names.index(sig["name"])
                lo, hi = self.runs[sig["name"]]
                u = np.clip(2.0 * (sig["t"] - lo) / max(hi - lo, 1e-9) - 1.0, -1.0, 1.0)
                out[:, j * (level + 1):(j + 1) * (level + 1)] = legendre.legvander(u, level)
            return out
        # dynamics and oscillators
        u = _state(sig, fam.option[0])
        dt = float(np.median(np.diff(sig["t"]))) if sig["t"].size > 1 else 1.0
        if fam.kind == "osc":
            return resonator_columns(u, RESONANCE_HZ[level], dt)
        # written column by column into the result (no list of full-rate columns beside it)
        k = len(TIME_CONSTANTS_S)
        out = np.empty((u.size, k * (2 if level >= 1 else 1)))
        for i, tau in enumerate(TIME_CONSTANTS_S):
            out[:, i] = low_pass(u, tau, dt)
        if level >= 1:
            for i, tau in enumerate(TIME_CONSTANTS_S):
                out[:, k + i] = low_pass(np.ascontiguousarray(out[:, i]), tau, dt)
        return out

    def columns(self, ctx, keys=None) -> dict[tuple[int, int], np.ndarray]:
        """(family index, level) -> its columns (n, m) on ``ctx``: every one, or those of ``keys``.

        Cached per context arrays; a context asked for some keys keeps only those until it is asked for more.

        Parameters
        ----------
        ctx : ModelContext
            One recording's samples (its ``extras`` as for the constructor).
        keys : iterable of tuple of int, optional
            (family index, level) pairs.

        Returns
        -------
        dict of tuple of int to ndarray
        """
        arrays = _arrays(ctx)
        key = _arrays_key(ctx)
        every = [(f, lv) for f, fam in enumerate(self.families) for lv in range(n_levels(fam))]
        want = every if keys is None else list(keys)
        hit = self._cache.get(key)
        have = hit[1] if hit is not None and all(a is b for a, b in zip(hit[0], arrays)) else {}
        missing = [k for k in want if k not in have]
        if hit is not None and have:
            self._cache.move_to_end(key)
        if not missing:
            return have if keys is None and len(have) == len(every) else {k: have[k] for k in want}
        sig = _signals(ctx)

        def made(f: int, fam: Family, lv: int) -> np.ndarray:
            top = self._top.get((id(fam), key)) if lv == n_levels(fam) - 1 else None
            if top is not None and all(a is b for a, b in zip(top[0], arrays)):
                return top[1]
            return _as_seen(self._columns(fam, lv, sig), sig)

        def basis_of(k):   # a lab coordinate's modifiers at one level one after the other (one spline basis kept)
            fam = self.families[k[0]]
            return (fam.option[0], k[1]) if fam.kind == "lab" else ("", k[0], k[1])

        order = sorted(range(len(missing)), key=lambda i: (basis_of(missing[i]), i))
        made_ = {missing[i]: made(missing[i][0], self.families[missing[i][0]], missing[i][1]) for i in order}
        sig.pop("_splines", None)
        merged = {**have, **made_}
        out = {k: merged[k] for k in every if k in merged}
        self._cache[key] = (arrays, out)
        self._cache.move_to_end(key)
        if len(self._cache) > self.CACHE:
            self._cache.popitem(last=False)
        if len(sig["t"]) * sum(v.shape[1] for v in made_.values()) * 8 > _RELEASE_BYTES:
            release_free_memory()       # the full-rate columns' temporaries
        return out if keys is None else {k: out[k] for k in want}

    def retain(self, keys) -> None:
        """Keep only the cached columns of ``keys``; any other is made again when asked for.

        Parameters
        ----------
        keys : iterable of tuple of int
            (family index, level) pairs: what a fitted model of these families still asks for.
        """
        keep = set(keys)
        for ctx_key, (arrays, cols) in list(self._cache.items()):
            self._cache[ctx_key] = (arrays, {k: v for k, v in cols.items() if k in keep})
        top_of = {id(fam) for f, fam in enumerate(self.families) if (f, n_levels(fam) - 1) in keep}
        self._top = {k: v for k, v in self._top.items() if k[0] in top_of}

    # ------------------------------------------------------------------ report
    def curve(self, f: int, level: int) -> tuple[np.ndarray, np.ndarray, list[str]]:
        """The family's function on a grid over its argument's observed range.

        Parameters
        ----------
        f : int
            Index into :attr:`families`.
        level : int

        Returns
        -------
        grid : ndarray (g,)
            The argument's values (:data:`GRID_POINTS`; a step response's time for dyn and osc).
        Phi : ndarray (curves, g, m)
            Maps the group's coefficients to the function's values (the force along the family's direction
            per unit of ``per_unit``).
        curves : list of str
            Names of the rows (the recordings of a drift or an aligned wheel family, else one empty name).
        """
        fam = self.families[f]
        g = GRID_POINTS
        if fam.kind == "custom":
            lo, hi, _ = self.ranges[fam.option[0]]
            grid = np.linspace(lo, hi, g)
            return grid, np.asarray(fam.basis(grid, level), float)[None], [""]
        if fam.kind == "lab":
            lo, hi, _ = self.ranges[fam.option[0]]
            grid = np.linspace(lo, hi, g)
            return grid, self._spline(fam.option[0], grid, level)[None], [""]
        if fam.kind == "wheel":
            grid = np.linspace(0.0, 2.0 * np.pi, g)
            k = np.arange(1, level + 2)
            F = np.concatenate([np.sin(np.outer(grid, k)), np.cos(np.outer(grid, k))], axis=1)
            if not fam.option:
                return grid, F[None], [""]
            rows = []
            for j, _ in enumerate(self.run_names):
                P = np.zeros((g, len(self.run_names) * F.shape[1]))
                P[:, j * F.shape[1]:(j + 1) * F.shape[1]] = F
                rows.append(P)
            return grid, np.stack(rows), list(self.run_names)
        if fam.kind == "speed":
            lo, hi, _ = self.ranges["speed"]
            grid = np.linspace(lo, hi, g)
            return grid, self._spline("speed", grid, level)[None], [""]
        if fam.kind == "drift":
            grid = np.linspace(0.0, max(hi - lo for lo, hi in self.runs.values()), g)
            if fam.option:          # shared: the columns of any recording, on the time since its start
                name = self.run_names[0]
                sig = {"v": np.zeros(g), "t": self.runs[name][0] + grid, "name": name}
                return grid, self._columns(fam, level, sig)[None], [""]
            rows = []
            for name in self.run_names:
                lo, hi = self.runs[name]
                sig = {"v": np.zeros(g), "t": lo + grid, "name": name}
                P = self._columns(fam, level, sig)
                P[lo + grid > hi + 1e-9] = np.nan
                rows.append(P)
            return grid, np.stack(rows), list(self.run_names)
        if fam.kind == "osc":     # the columns' response to a unit step of the state (sampled at 1 kHz)
            grid = np.linspace(0.0, 3.0, g)
            fine = np.linspace(0.0, 3.0, 3001)
            u = (fine > 0).astype(float)
            P = resonator_columns(u, RESONANCE_HZ[level], fine[1])
            return grid, P[np.searchsorted(fine, grid)][None], [""]
        # dynamics: the response to a unit step of the state
        grid = np.linspace(0.0, 3.0 * max(TIME_CONSTANTS_S), g)
        taus = np.array(TIME_CONSTANTS_S)
        e = np.exp(-grid[:, None] / taus)
        cols = [1.0 - e] + ([1.0 - (1.0 + grid[:, None] / taus) * e] if level >= 1 else [])
        return grid, np.concatenate(cols, axis=1)[None], [""]


def _inside(C: np.ndarray, K: np.ndarray) -> bool:
    """True when every column of ``C`` lies in the span of ``K`` (relative residual below DUPLICATE_TOL)."""
    if C.shape[0] != K.shape[0] or C.shape[1] > K.shape[1]:
        return False
    coef, *_ = np.linalg.lstsq(K, C, rcond=None)
    return bool(np.linalg.norm(C - K @ coef) <= DUPLICATE_TOL * np.linalg.norm(C))
