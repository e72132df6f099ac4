"""Session file (docs/session.md): the subject and vehicle of a recording.

The session file holds *nominal* values. :func:`load_session` validates it strictly: unknown keys,
missing keys, wrong types and mass fractions that do not sum to 1 are :class:`ConfigError` naming
the file and the dotted key.

Examples
--------
>>> s = default_session()
>>> round(sum(seg.mass_fraction for seg in s.rider.segments.values()), 6)
1.0
>>> s.euc.wheel_radius
0.2
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import yaml

from euc_ros.core.anthropometry import rider_segments, standing_rider
from euc_ros.core.errors import ConfigError
from euc_ros.core.yamlfile import load_yaml

#: Rigid bodies of the rider (EUC paper, Table 2), in a fixed order.
SEGMENT_BODIES = ("H", "CHR", "CHL", "UAR", "UAL", "LAR", "LAL", "HR", "HL", "TR", "TL", "LR", "LL")
#: Tolerance on the sum of the mass fractions (docs/session.md).
MASS_FRACTION_TOL = 1e-3


@dataclass(frozen=True)
class Segment:
    """One rider segment: mass fraction of the rider mass and CoM offset from the pivot [m, body frame].

    Parameters
    ----------
    mass_fraction : float
        Fraction of the rider's mass, in [0, 1].
    com_offset : tuple of float
        CoM offset from the segment body's pivot, body frame (x, y, z) [m].
    """

    mass_fraction: float
    com_offset: tuple[float, float, float]


@dataclass(frozen=True)
class Rider:
    """Rider: total mass [kg], pitch inertia about the CoG [kg m^2] and segments by body name.

    Parameters
    ----------
    mass : float
        Total rider mass [kg].
    inertia_pitch : float
        Pitch moment of inertia about the rider's CoG [kg m^2].
    segments : Mapping of str to Segment
        Segments by rigid-body name.
    """

    mass: float
    inertia_pitch: float
    segments: Mapping[str, Segment]


@dataclass(frozen=True)
class Euc:
    """EUC vehicle parameters (EUC paper, Table 3), SI units.

    Parameters
    ----------
    body : str
        Name of the EUC's rigid body in the recordings.
    wheel_radius : float
        Wheel radius R [m].
    wheel_mass : float
        Wheel mass mw [kg].
    body_mass : float
        Mass of the EUC body without the wheel m0 [kg].
    wheel_inertia : float
        Wheel moment of inertia about its axle Jw [kg m^2].
    body_inertia : float
        Pitch moment of inertia of the EUC body about its CoM J0 [kg m^2].
    h0 : float
        Distance from the wheel centre C up the EUC's axis to the body's CoG G0 [m] (signed).
    l0 : float
        Distance from the ankle hinge A down the EUC's axis to the wheel centre C [m] (signed).
    pivot_to_wheel_center : tuple of float
        Wheel centre from the EUC body's pivot, body frame (x, y, z) [m].
    """

    body: str = "E"
    wheel_radius: float = 0.2
    wheel_mass: float = 3.0
    body_mass: float = 13.0
    wheel_inertia: float = 0.12
    body_inertia: float = 0.5
    h0: float = 0.075
    l0: float = 0.05
    pivot_to_wheel_center: tuple[float, float, float] = (0.0, 0.0, -0.45)


@dataclass(frozen=True)
class Session:
    """A parsed session file.

    Parameters
    ----------
    world_up : str
        The recordings' up axis, ``"y"`` (Motive) or ``"z"`` (REP-103).
    rate_hz : float
        Nominal capture rate [Hz].
    rider : Rider
        The rider's mass, inertia and segments.
    euc : Euc
        The vehicle parameters.
    source : str, optional
        File the session was read from (not compared).
    """

    world_up: str
    rate_hz: float
    rider: Rider
    euc: Euc
    source: str | None = field(default=None, compare=False)

    def segment_arrays(self) -> tuple[list[str], np.ndarray, np.ndarray]:
        """The triple (names, mass fractions (n,), CoM offsets (n, 3)) in file order.

        Returns
        -------
        names : list of str
            Segment body names.
        fractions : numpy.ndarray
            Mass fractions (n,).
        offsets : numpy.ndarray
            CoM offsets (n, 3) from each pivot, body frame [m].
        """
        names = list(self.rider.segments)
        fractions = np.array([self.rider.segments[n].mass_fraction for n in names], dtype=float)
        offsets = np.array([self.rider.segments[n].com_offset for n in names], dtype=float)
        return names, fractions, offsets

    def to_dict(self) -> dict[str, Any]:
        """The plain-YAML form of the session (round-trips through :func:`parse_session`).

        Returns
        -------
        dict of str to Any
            Plain lists, floats and strings, without ``source``.
        """
        d = asdict(self)
        d.pop("source")
        d["rider"]["segments"] = {
            k: {"mass_fraction": v.mass_fraction, "com_offset": list(v.com_offset)}
            for k, v in self.rider.segments.items()
        }
        d["euc"]["pivot_to_wheel_center"] = list(self.euc.pivot_to_wheel_center)
        return d


_TOP_KEYS = {"world_up": str, "rate_hz": float, "rider": dict, "euc": dict}
_RIDER_KEYS = {"mass": float, "inertia_pitch": float, "segments": dict}
_SEGMENT_KEYS = {"mass_fraction": float, "com_offset": list}
_EUC_KEYS = {
    "body": str, "wheel_radius": float, "wheel_mass": float, "body_mass": float, "wheel_inertia": float,
    "body_inertia": float, "h0": float, "l0": float, "pivot_to_wheel_center": list,
}
_POSITIVE = {"rate_hz", "mass", "inertia_pitch", "wheel_radius", "wheel_mass", "body_mass", "wheel_inertia",
             "body_inertia"}


@dataclass(frozen=True)
class Plausible:
    """Plausible range of a session quantity in SI, and the unit slips a value outside it may come from.

    Parameters
    ----------
    lo, hi : float
        Range of the value (of the vector's length for ``com_offset`` and ``pivot_to_wheel_center``).
    unit : str
        SI unit, as printed.
    typical : (float, float)
        Where real values usually lie (same measure as ``lo``/``hi``): a value outside the range is
        explained by a unit slip only when the value converted back lands here.
    slips : tuple of (float, str)
        ``(factor, name)``: a value given in unit ``name`` is ``factor`` times too large in SI
        (millimetres: 1000).
    """

    lo: float
    hi: float
    unit: str
    typical: tuple[float, float]
    slips: tuple[tuple[float, str], ...] = ()


_LENGTH_SLIPS = ((1000.0, "millimetres"), (100.0, "centimetres"))
_MASS_SLIPS = ((1000.0, "grams"),)
_INERTIA_SLIPS = ((1000.0, "g m^2"), (1e4, "kg cm^2"), (1e6, "kg mm^2"))

#: Plausible ranges of every session quantity, by leaf key, generous enough for any real EUC and rider
#: (children to heavy riders with gear; 14" to 24" wheels; EUCs of 10 to 60 kg). A value outside its
#: range is a :class:`ConfigError` naming the key; when the value divided by a unit factor falls in the
#: typical range when the value converted back from a unit slip lands there (``wheel_radius: 200``,
#: ``mass: 65000``), the message suggests that unit.
PLAUSIBLE: dict[str, Plausible] = {
    "rate_hz": Plausible(1.0, 10000.0, "Hz", (30.0, 2000.0), ((1e-3, "kHz"),)),
    "mass": Plausible(20.0, 250.0, "kg", (30.0, 150.0), _MASS_SLIPS),                 # rider.mass
    "inertia_pitch": Plausible(0.5, 150.0, "kg m^2", (3.0, 50.0), _INERTIA_SLIPS),   # about the rider's CoG
    "com_offset": Plausible(0.0, 1.0, "m", (0.0, 0.5), _LENGTH_SLIPS),               # |offset| from the pivot
    "wheel_radius": Plausible(0.05, 0.5, "m", (0.1, 0.35), _LENGTH_SLIPS),
    "wheel_mass": Plausible(0.5, 50.0, "kg", (1.0, 25.0), _MASS_SLIPS),
    "body_mass": Plausible(1.0, 150.0, "kg", (5.0, 60.0), _MASS_SLIPS),
    "wheel_inertia": Plausible(1e-3, 10.0, "kg m^2", (0.02, 2.0), _INERTIA_SLIPS),
    "body_inertia": Plausible(1e-3, 20.0, "kg m^2", (0.1, 5.0), _INERTIA_SLIPS),
    "h0": Plausible(-1.0, 1.0, "m", (-0.2, 0.3), _LENGTH_SLIPS),                     # C to G0, signed
    "l0": Plausible(-1.0, 1.0, "m", (0.0, 0.3), _LENGTH_SLIPS),                      # A to C, signed
    "pivot_to_wheel_center": Plausible(0.0, 2.0, "m", (0.1, 1.0), _LENGTH_SLIPS),    # |E -> C|
}
_VECTORS = {"com_offset", "pivot_to_wheel_center"}


def _fmt(v: Any) -> str:
    """``0.2`` or ``[0, 0, -0.45]`` (numbers in ``%g``)."""
    if isinstance(v, (tuple, list)):
        return "[" + ", ".join(f"{x:g}" for x in v) + "]"
    return f"{v:g}"


def check_plausible(leaf: str, value: Any, *, key: str | None = None, source: str | Path | None = None) -> None:
    """Raise :class:`ConfigError` if a session value lies outside :data:`PLAUSIBLE` (no-op for other keys).

    Parameters
    ----------
    leaf : str
        Key name in the session file (``wheel_radius``).
    value : float or sequence of 3 floats
        The value in SI as read.
    key : str, optional
        Dotted key for the message (default ``leaf``).
    source : str or Path, optional
        The session file.

    Raises
    ------
    ConfigError
        Naming the key whose value is outside its plausible range.

    Examples
    --------
    >>> try:
    ...     check_plausible("wheel_radius", 200.0)
    ... except ConfigError as exc:
    ...     print(exc.detail)
    wheel_radius = 200 m is not plausible (expected 0.05-0.5 m); the value looks like millimetres: 0.2
    """
    rng = PLAUSIBLE.get(leaf)
    if rng is None:
        return
    vector = leaf in _VECTORS
    size = float(np.linalg.norm(value)) if vector else float(value)
    if rng.lo <= size <= rng.hi:
        return
    if vector:
        expected = f"a length of at most {rng.hi:g} {rng.unit}" if rng.lo == 0 else \
            f"a length of {rng.lo:g}-{rng.hi:g} {rng.unit}"
    else:
        expected = f"{rng.lo:g}{' to ' if rng.lo < 0 else '-'}{rng.hi:g} {rng.unit}"
    hints = []
    for factor, name in rng.slips:
        if rng.typical[0] <= size / factor <= rng.typical[1]:
            scaled = tuple(x / factor for x in value) if vector else size / factor
            hints.append(f"{name}: {_fmt(scaled)}")
    msg = f"{leaf} = {_fmt(value)} {rng.unit} is not plausible (expected {expected})"
    if hints:
        msg += "; the value looks like " + " or ".join(hints)
    raise ConfigError(msg, path=None if source is None else str(source), key=key or leaf)


def _check_keys(d: Any, spec: Mapping[str, type], prefix: str, src: str | None) -> None:
    if not isinstance(d, Mapping):
        raise ConfigError(f"expected a mapping, got {type(d).__name__}", path=src, key=prefix or None)
    for k in d:
        if k not in spec:
            raise ConfigError(f"unknown key (allowed: {', '.join(spec)})", path=src,
                              key=f"{prefix}.{k}" if prefix else str(k))
    for k in spec:
        if k not in d:
            raise ConfigError("missing required key", path=src, key=f"{prefix}.{k}" if prefix else k)


def _value(d: Mapping, k: str, typ: type, prefix: str, src: str | None) -> Any:
    key = f"{prefix}.{k}" if prefix else k
    v = d[k]
    if typ is float:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
            raise ConfigError(f"expected a finite number, got {v!r}", path=src, key=key)
        if k in _POSITIVE and v <= 0:
            raise ConfigError(f"must be > 0, got {v!r}", path=src, key=key)
        check_plausible(k, float(v), key=key, source=src)
        return float(v)
    if typ is list:
        if (not isinstance(v, list) or len(v) != 3
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and np.isfinite(x) for x in v)):
            raise ConfigError(f"expected a list of 3 finite numbers [x, y, z], got {v!r}", path=src, key=key)
        vec = tuple(float(x) for x in v)
        check_plausible(k, vec, key=key, source=src)
        return vec
    if not isinstance(v, typ):
        raise ConfigError(f"expected {typ.__name__}, got {v!r}", path=src, key=key)
    return v


def parse_session(data: Any, source: str | Path | None = None) -> Session:
    """Validate a session mapping (already loaded from YAML) and return a :class:`Session`.

    Parameters
    ----------
    data : Any
        The mapping loaded from the session YAML.
    source : str or Path, optional
        File the data came from, named in errors.

    Returns
    -------
    Session
        The validated session.

    Raises
    ------
    ConfigError
        Naming the offending key for unknown or missing keys, bad values, and mass fractions that do
        not sum to 1 within 1e-3.
    """
    src = None if source is None else str(source)
    _check_keys(data, _TOP_KEYS, "", src)
    world_up = _value(data, "world_up", str, "", src)
    if world_up not in ("y", "z"):
        raise ConfigError(f"must be 'y' or 'z', got {world_up!r}", path=src, key="world_up")
    rate_hz = _value(data, "rate_hz", float, "", src)

    rd = data["rider"]
    _check_keys(rd, _RIDER_KEYS, "rider", src)
    segs_raw = rd["segments"]
    if not isinstance(segs_raw, Mapping) or not segs_raw:
        raise ConfigError("expected a non-empty mapping of body -> segment", path=src, key="rider.segments")
    segments: dict[str, Segment] = {}
    for name, sd in segs_raw.items():
        prefix = f"rider.segments.{name}"
        _check_keys(sd, _SEGMENT_KEYS, prefix, src)
        frac = _value(sd, "mass_fraction", float, prefix, src)
        if not 0.0 <= frac <= 1.0:
            raise ConfigError(f"must be in [0, 1], got {frac}", path=src, key=f"{prefix}.mass_fraction")
        segments[str(name)] = Segment(frac, _value(sd, "com_offset", list, prefix, src))
    total = sum(s.mass_fraction for s in segments.values())
    if abs(total - 1.0) > MASS_FRACTION_TOL:
        raise ConfigError(f"mass fractions sum to {total:.6f}, must be 1 within {MASS_FRACTION_TOL}",
                          path=src, key="rider.segments")
    rider = Rider(_value(rd, "mass", float, "rider", src), _value(rd, "inertia_pitch", float, "rider", src),
                  segments)

    ed = data["euc"]
    _check_keys(ed, _EUC_KEYS, "euc", src)
    euc = Euc(**{k: _value(ed, k, t, "euc", src) for k, t in _EUC_KEYS.items()})
    if euc.body in segments:
        raise ConfigError(f"EUC body {euc.body!r} is also listed as a rider segment", path=src, key="euc.body")
    return Session(world_up=world_up, rate_hz=rate_hz, rider=rider, euc=euc, source=src)


def load_session(path: str | Path) -> Session:
    """Read and validate a session YAML file (docs/session.md).

    A Motive CSV export or a bag given as the session is refused with a message that says the order
    of the arguments without naming a command: the command line's error prefix names the one run.

    Parameters
    ----------
    path : str or Path
        The session YAML file.

    Returns
    -------
    Session
        The validated session.

    Raises
    ------
    ConfigError
        When the file is a recording rather than a session, cannot be read, is not valid YAML or fails
        :func:`parse_session`'s checks.
    """
    p = Path(path)
    if p.is_dir() or p.suffix.lower() in (".csv", ".mcap", ".db3"):
        what = "a bag" if p.is_dir() or p.suffix.lower() != ".csv" else "a Motive CSV export"
        raise ConfigError(f"is {what}, not a session file: the session comes first, then the recordings "
                          "(SESSION.yaml RECORDING...); were the two swapped?", path=p)
    data = load_yaml(p, "session file")
    return parse_session(data, p)


def save_session(session: Session, path: str | Path) -> None:
    """Write a session file that :func:`load_session` reads back unchanged.

    Values made with numpy (``numpy.float64`` and the like) are written as the plain numbers they hold.

    Parameters
    ----------
    session : Session
        The session to write.
    path : str or Path
        File to write (overwritten).
    """
    def plain(v):
        if isinstance(v, dict):
            return {k: plain(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [plain(x) for x in v]
        return v.item() if isinstance(v, np.generic) else v

    Path(path).write_text(yaml.safe_dump(plain(session.to_dict()), sort_keys=False), encoding="utf-8")


#: The default rider: the EUC paper's rider mass (Table 3) [kg], and the height [m] and sex that select
#: the segments and pitch inertia of :mod:`euc_ros.core.anthropometry` (a 1.75 m rider, the stature of
#: the ride simulator's riding posture).
DEFAULT_RIDER_MASS = 65.0
DEFAULT_RIDER_HEIGHT = 1.75
DEFAULT_RIDER_SEX = "male"


def default_rider() -> Rider:
    """The default rider: segments and pitch inertia from :mod:`euc_ros.core.anthropometry`.

    The same table and mapping onto the rider bodies as ``euc-ros session init --mass 65 --height 1.75
    --sex male``: mass fractions, CoM offsets from each pivot (body frame, x forward, y left, z up when
    standing) and the standing rider's pitch inertia about its CoG.

    Returns
    -------
    Rider
        The default 65 kg, 1.75 m male rider.
    """
    segments = rider_segments(DEFAULT_RIDER_MASS, DEFAULT_RIDER_HEIGHT, DEFAULT_RIDER_SEX)
    standing = standing_rider(DEFAULT_RIDER_MASS, DEFAULT_RIDER_HEIGHT, DEFAULT_RIDER_SEX)
    return Rider(DEFAULT_RIDER_MASS, standing.inertia_pitch,
                 {name: Segment(seg.mass_fraction, seg.com_offset) for name, seg in segments.items()})


def default_session(world_up: str = "y") -> Session:
    """The nominal session: the EUC paper's EUC (Table 3) and :func:`default_rider`.

    Parameters
    ----------
    world_up : str
        The recordings' up axis, ``"y"`` or ``"z"``.

    Returns
    -------
    Session
        The nominal session at 120 Hz.
    """
    return Session(world_up=world_up, rate_hz=120.0, rider=default_rider(), euc=Euc())
