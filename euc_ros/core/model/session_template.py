"""A commented session file from the rider's measurements and the EUC's.

:func:`render_session` writes the YAML that :func:`euc_ros.core.session.parse_session` reads, with a
comment on every key saying what it is, its frame and unit, and how to measure it. The rider's
segments come from :mod:`euc_ros.core.anthropometry`; the EUC's values are the caller's measurements
(or the EUC paper's, marked as such, where none is given).

Examples
--------
>>> from euc_ros.core.session import parse_session
>>> from euc_ros.core.yamlfile import parse_yaml
>>> text = render_session(RiderMeasures(70.0, 1.75, "male"))
>>> parse_session(parse_yaml(text, "session.yaml")).rider.mass
70.0
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields

from euc_ros.core.anthropometry import BODIES, REFERENCE, rider_segments, standing_rider
from euc_ros.core.errors import ConfigError
from euc_ros.core.session import Euc


@dataclass(frozen=True)
class RiderMeasures:
    """What is measured of the rider: body mass [kg], standing height [m], sex, helmet top above vertex [m].

    Parameters
    ----------
    mass : float
        Body mass [kg].
    height : float
        Standing height [m].
    sex : str
        ``"male"`` or ``"female"``.
    helmet_m : float
        Helmet top above the vertex [m].
    """

    mass: float
    height: float
    sex: str
    helmet_m: float = 0.0


#: How to measure each EUC key (the comment written above it).
EUC_HOWTO = {
    "body": "name of the EUC's rigid body in Motive (its pivot on the top of the EUC)",
    "wheel_radius": "rolling radius R [m]: mark the tyre, roll N turns with the rider on at riding pressure, "
                    "distance / (2 pi N)",
    "wheel_mass": "wheel with tyre and motor rotor m_w [kg]: the manufacturer's figure or weighed apart",
    "body_mass": "EUC without its wheel m_0 [kg]: weigh the whole EUC, subtract wheel_mass",
    "wheel_inertia": "wheel pitch inertia J_w about the axle [kg m^2]: a bifilar or trifilar pendulum; "
                     "about 0.6 m_w R^2 for a hub-motor wheel",
    "body_inertia": "EUC body pitch inertia J_0 about its CoG G0 [kg m^2]: hang the EUC by its axle, time the "
                    "small swings (period T): J_0 = m_0 g h0 T^2 / (4 pi^2) - m_0 h0^2",
    "h0": "wheel centre C to the EUC body's CoG G0, along the EUC's axis, up positive [m]: balance the "
          "EUC body on a knife edge, or from the pendulum test",
    "l0": "ankle hinge A to the wheel centre C, along the EUC's axis [m]: the rider's ankle joint "
          "(lateral malleolus) height on the pedals minus the axle height",
    "pivot_to_wheel_center": "wheel centre C from the EUC body's pivot E, in the EUC body frame (x forward, "
                             "y left, z up) [m]: put a marker on the axle cap and read it in Motive with the EUC "
                             "upright, or move the rigid body's pivot onto the axle (then [0, 0, 0])",
}

_PAPER = "the EUC paper's value (Table 3): measure yours"


def _num(v: float) -> str:
    return f"{v:.6g}"


def _vec(v) -> str:
    return "[" + ", ".join(_num(float(x)) for x in v) + "]"


def render_session(rider: RiderMeasures, euc: dict | None = None, *, names: dict[str, str] | None = None,
                   world_up: str = "y", rate_hz: float = 120.0) -> str:
    """The commented YAML of a session.

    Parameters
    ----------
    rider : RiderMeasures
    euc : dict, optional
        Measured EUC values by key (:data:`EUC_HOWTO`); missing keys take the EUC paper's values and
        say so in their comment.
    names : dict, optional
        Rider body (``H``, ``CHR``...) -> the lab's Motive rigid-body name; unnamed bodies keep theirs.
    world_up : {"y", "z"}
        Motive's up axis (Edit > Settings > General > Up Axis; Y is Motive's default).
    rate_hz : float
        Capture rate [Hz].

    Returns
    -------
    str
        YAML text; :func:`euc_ros.core.session.parse_session` reads it.

    Raises
    ------
    ConfigError
        An unknown body or EUC key, a name used twice, or implausible rider measures.
    """
    names = dict(names or {})
    euc = dict(euc or {})
    unknown = sorted(set(names) - set(BODIES))
    if unknown:
        raise ConfigError(f"no rider body {unknown[0]!r} (bodies: {', '.join(BODIES)})", key="names")
    mapped = [names.get(b, b) for b in BODIES]
    twice = sorted({n for n in mapped if mapped.count(n) > 1})
    if twice:
        raise ConfigError(f"Motive name {twice[0]!r} given to two bodies", key="names")
    bad = sorted(set(euc) - set(EUC_HOWTO))
    if bad:
        raise ConfigError(f"no EUC key {bad[0]!r} (keys: {', '.join(EUC_HOWTO)})", key="euc")
    if world_up not in ("y", "z"):
        raise ConfigError(f"world_up must be y or z, got {world_up!r}", key="world_up")
    segments = rider_segments(rider.mass, rider.height, rider.sex, helmet_m=rider.helmet_m)
    standing = standing_rider(rider.mass, rider.height, rider.sex)
    defaults = {f.name: getattr(Euc(), f.name) for f in fields(Euc)}
    out = [
        "# euc_ros session: the nominal values of a recording session (docs/session.md explains every key).",
        f"# Rider: {_num(rider.mass)} kg, {_num(rider.height)} m, {rider.sex}; segments from {REFERENCE}.",
        "# Frames: a body frame is x forward, y left, z up when the rider stands upright facing +x; SI units.",
        "",
        f"world_up: {world_up}          # Motive's up axis (Edit > Settings > General > Up Axis); "
        "Y is Motive's default",
        f"rate_hz: {_num(rate_hz)}          # capture rate [Hz] (Motive's frame rate)",
        "rider:",
        f"  mass: {_num(rider.mass)}          # rider with clothes, helmet and gear [kg]",
        f"  inertia_pitch: {standing.inertia_pitch:.3f}   # pitch inertia about the rider's CoG [kg m^2]: "
        "the table's standing rider, arms hanging",
        "  # Rigid bodies of the rider: Motive rigid-body name -> mass fraction of the rider mass and CoM offset from",
        "  # the body's pivot, in the body frame [m]. Fractions sum to 1.",
        f"  # For reference, the standing rider's CoG is {standing.cog_above_ankle:.3f} m above the ankles "
        "(h on the EUC is lower: crouched; identify measures it).",
        "  segments:",
    ]
    for body, seg in segments.items():
        out.append(f"    # {body}: {BODIES[body]}")
        out.append(f"    {names.get(body, body)}: {{mass_fraction: {seg.mass_fraction:.5f}, "
                   f"com_offset: {_vec(seg.com_offset)}}}")
    out.append("euc:")
    for key, howto in EUC_HOWTO.items():
        given = key in euc
        value = euc[key] if given else defaults[key]
        note = "" if given else ("; E by default" if key == "body" else f"; {_PAPER}")
        out.append(f"  # {howto}{note}")
        text = _vec(value) if key == "pivot_to_wheel_center" else (str(value) if key == "body" else _num(value))
        out.append(f"  {key}: {text}")
    return "\n".join(out) + "\n"


@dataclass(frozen=True)
class NameMap:
    """Rider body -> Motive name pairs parsed from ``BODY=NAME`` items.

    Parameters
    ----------
    names : dict of str to str
        Motive rigid-body name by rider body name.
    """

    names: dict[str, str] = field(default_factory=dict)

    @classmethod
    def parse(cls, items: list[str]) -> "NameMap":
        """``["H=Helmet", "CHR=RShoulder"]`` -> NameMap; ConfigError naming a malformed item.

        Parameters
        ----------
        items : list of str
            ``BODY=NAME`` items.

        Returns
        -------
        NameMap
            The pairs, a later item for the same body winning.

        Raises
        ------
        ConfigError
            Naming the first malformed item (key ``--name``).
        """
        names = {}
        for item in items:
            body, sep, name = item.partition("=")
            if not sep or not body.strip() or not name.strip():
                raise ConfigError(f"expected BODY=MOTIVE_NAME (e.g. H=Helmet), got {item!r}", key="--name")
            names[body.strip()] = name.strip()
        return cls(names)
