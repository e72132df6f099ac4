"""Soft-tissue and tracking artefacts of real recordings, applied to a simulated ride's mocap.

Markers sit on skin and clothes, so every rider rigid body slides against its bone: smoothly, within
the band of the rider's own motion, partly driven by the segment's acceleration (the soft tissue lags
behind the bone). Motive adds coloured (not white) pose noise, occasional marker swaps (the solve
jumps by centimetres and tens of degrees for a short stretch) and single frames with a rigid body
flipped by 180 deg. The session's segment CoM offsets come from anthropometric tables and are
centimetres off.

This module is the generator side only: it shares no code with the analysis (the model and states packages).
Everything is seeded and vectorized over bodies and frames.

* :func:`apply_artefacts` turns a clean :class:`~euc_ros.core.mocap.series.MocapSeries` into a recorded one
  and returns the list of injected faults (swaps, flips) as :class:`ArtefactEvent`;
* :func:`perturb_session` returns a copy of a session with every segment's CoM offset moved by
  1-3 cm: record with the true session, analyse with the perturbed one.

Sliding (per rider body, in its body frame, where the skin moves against the bone)::

    d(t) = s * normalise( sqrt(c) * bandpass(-a_body(t)) + sqrt(1 - c) * bandpass(white) )

with ``bandpass`` an exact band limitation to ``band_hz`` (Fourier coefficients outside the band set
to zero), ``a_body`` the pivot's acceleration in the body frame, ``c`` the correlated share of the
variance (``accel_share``) and ``s`` the RMS of the 3-D displacement ``sqrt(mean |d|^2)``. The
orientation slides the same way (a band-limited rotation vector of RMS angle ``slide_rot_rms_deg``,
not correlated with the acceleration), applied in the body frame: ``R_meas = R_true exp([w])``.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace

import numpy as np
from scipy.spatial.transform import Rotation

from euc_ros.core.errors import ConfigError
from euc_ros.core.mocap.series import MocapSeries
from euc_ros.core.rotations import canonical_quat
from euc_ros.core.session import Segment, Session


@dataclass(frozen=True)
class SoftTissueArtefacts:
    """What :func:`apply_artefacts` adds (defaults: moderate sliding, coloured noise, no faults).

    Parameters
    ----------
    slide_rms_m : float
        RMS of each rider body's 3-D pivot sliding [m] (``sqrt(mean |d|^2)``, per body and run).
    slide_rot_rms_deg : float
        RMS angle of each rider body's orientation sliding [deg].
    band_hz : tuple of float
        Band of the sliding [Hz] (exact: no power outside it).
    accel_share : float
        Share of the sliding variance that follows the segment's (band-limited) acceleration, in [0, 1].
    noise_pos_rms_m, noise_rot_rms_deg : float
        RMS of the coloured pose noise of every body, E included [m, deg] (3-D).
    noise_corner_hz : float
        Corner of the noise's first-order low-pass spectrum [Hz] (white above the Nyquist rate if large).
    swaps : int
        Marker-swap episodes per run (one random rider body each).
    swap_s : tuple of float
        Duration range of a swap [s].
    swap_jump_m, swap_rot_deg : tuple of float
        Ranges of the position jump [m] and rotation jump [deg] during a swap.
    flips : int
        Flip episodes per run (one random rider body rotated by 180 deg about its body x or y axis).
    flip_frames : tuple of int
        Length range of a flip [frames].
    bodies : tuple of str, optional
        Bodies that slide and may swap or flip (default: every body except ``euc_body``).
    euc_body : str
        The EUC's rigid body: hard shell, gets only the coloured noise.
    joint_mm_per_deg : float
        Scale of the joint-angle artefact (:data:`JOINT_GAIN_MM_PER_DEG` times this; 0: none). Each rider
        body's pivot moves by its gain [mm/deg] times the change of its angle to the EUC (the sum of the
        joint angles between it and the pedals; the rider's lean for a rider who pitches as one), in a
        direction fixed per body and run: the artefact modes of the field are linear in the joint angles.
        Added to the band-limited sliding.

    Raises
    ------
    ConfigError
        Naming the field that is negative, not finite or out of its range.
    """

    slide_rms_m: float = 0.005
    slide_rot_rms_deg: float = 2.0
    band_hz: tuple[float, float] = (0.3, 3.0)
    accel_share: float = 0.5
    noise_pos_rms_m: float = 0.2e-3
    noise_rot_rms_deg: float = 0.5
    noise_corner_hz: float = 5.0
    swaps: int = 0
    swap_s: tuple[float, float] = (0.05, 0.3)
    swap_jump_m: tuple[float, float] = (0.02, 0.05)
    swap_rot_deg: tuple[float, float] = (25.0, 40.0)
    flips: int = 0
    flip_frames: tuple[int, int] = (1, 5)
    bodies: tuple[str, ...] | None = None
    euc_body: str = "E"
    joint_mm_per_deg: float = 0.0

    def __post_init__(self) -> None:
        for k in ("slide_rms_m", "slide_rot_rms_deg", "noise_pos_rms_m", "noise_rot_rms_deg", "joint_mm_per_deg"):
            v = getattr(self, k)
            if not (math.isfinite(v) and v >= 0):
                raise ConfigError(f"must be a finite number >= 0, got {v}", key=k)
        lo, hi = self.band_hz
        if not 0 < lo < hi:
            raise ConfigError(f"need 0 < low < high, got {self.band_hz}", key="band_hz")
        if not 0 <= self.accel_share <= 1:
            raise ConfigError(f"must be in [0, 1], got {self.accel_share}", key="accel_share")
        if not self.noise_corner_hz > 0:
            raise ConfigError(f"must be > 0, got {self.noise_corner_hz}", key="noise_corner_hz")
        if self.swaps < 0 or self.flips < 0:
            raise ConfigError("swaps and flips must be >= 0", key="swaps" if self.swaps < 0 else "flips")
        for k in ("swap_s", "swap_jump_m", "swap_rot_deg", "flip_frames"):
            a, b = getattr(self, k)
            if not 0 <= a <= b:
                raise ConfigError(f"need 0 <= low <= high, got {(a, b)}", key=k)

    def to_dict(self) -> dict:
        """Plain mapping (for truth files and reports).

        Returns
        -------
        dict
            The fields by name.
        """
        return asdict(self)


@dataclass(frozen=True)
class ArtefactEvent:
    """One injected tracking fault: ``kind`` ("swap" or "flip") of ``body`` over frames [start, stop).

    Parameters
    ----------
    kind : str
        ``"swap"`` or ``"flip"``.
    body : str
        The rigid body.
    start, stop : int
        Frame range [start, stop).
    """

    kind: str
    body: str
    start: int
    stop: int


def _band_limited(x: np.ndarray, dt: float, band: tuple[float, float], axis: int) -> np.ndarray:
    """Zero every Fourier coefficient of ``x`` outside ``band`` (after removing the mean)."""
    n = x.shape[axis]
    f = np.fft.rfftfreq(n, dt)
    X = np.fft.rfft(x - x.mean(axis=axis, keepdims=True), axis=axis)
    keep = (f >= band[0]) & (f <= band[1])
    shape = [1] * x.ndim
    shape[axis] = f.size
    return np.fft.irfft(X * keep.reshape(shape), n=n, axis=axis)


def _unit_rms(x: np.ndarray) -> np.ndarray:
    """Scale ``x`` (b, n, 3) so that each body's 3-D RMS ``sqrt(mean_n |x|^2)`` is 1 (zeros stay zeros)."""
    r = np.sqrt(np.mean(np.sum(x * x, -1), axis=1, keepdims=True))[..., None]
    return np.divide(x, r, out=np.zeros_like(x), where=r > 0)


def _coloured(rng: np.random.Generator, shape: tuple[int, ...], dt: float, corner_hz: float) -> np.ndarray:
    """Gaussian noise with a first-order low-pass spectrum (corner ``corner_hz``) along axis 1, unit 3-D RMS."""
    w = rng.normal(0.0, 1.0, shape)
    f = np.fft.rfftfreq(shape[1], dt)
    gain = 1.0 / np.sqrt(1.0 + (f / corner_hz) ** 2)
    y = np.fft.irfft(np.fft.rfft(w, axis=1) * gain[None, :, None], n=shape[1], axis=1)
    return _unit_rms(y)


def _body_acceleration(pos: np.ndarray, rot: np.ndarray, dt: float) -> np.ndarray:
    """Pivot acceleration (b, n, 3) expressed in the body frame (central differences)."""
    acc = np.gradient(np.gradient(pos, dt, axis=1), dt, axis=1)
    return np.einsum("bnji,bnj->bni", rot, acc)


#: Joint-angle artefact per body [mm of pivot displacement per deg of joint-angle change]: of the order the
#: reviews report for skin-mounted clusters (thigh 10-30 mm over 40-60 deg of hip and knee flexion, the
#: shank about half of it: Leardini et al. 2005, Gait Posture 21:212-225; Peters et al. 2010, Gait Posture
#: 31:1-8; trunk and pelvis clusters a few to 10 mm; the upper arm's in humeral rotation of the thigh's
#: order: Cutti et al. 2005, Med Biol Eng Comput 43:549-556); the head's cap barely slides.
JOINT_GAIN_MM_PER_DEG = {"H": 0.05, "CHR": 0.25, "CHL": 0.25, "UAR": 0.35, "UAL": 0.35, "LAR": 0.15,
                         "LAL": 0.15, "HR": 0.3, "HL": 0.3, "TR": 0.4, "TL": 0.4, "LR": 0.2, "LL": 0.2}


def _joint_angle_sliding(rot: np.ndarray, names: list, euc_body: str, scale: float,
                         rng: np.random.Generator) -> np.ndarray:
    """Body-frame pivot displacement (b, n, 3) [m] linear in each body's angle to the EUC.

    The angle is the rotation vector of ``R_euc^T R_body`` minus its median over the run; the
    displacement is the gain times a fixed random rotation of it (``|d| = gain |angle change|``). One
    rotation per body is drawn for every body of :data:`JOINT_GAIN_MM_PER_DEG` (a fixed number of draws).
    """
    b, n = rot.shape[:2]
    out = np.zeros((b, n, 3))
    turns = Rotation.random(len(JOINT_GAIN_MM_PER_DEG), random_state=rng).as_matrix()
    for k, (body, gain) in enumerate(JOINT_GAIN_MM_PER_DEG.items()):
        if body not in names or euc_body not in names:
            continue
        i, j = names.index(body), names.index(euc_body)
        rel = Rotation.from_matrix(np.einsum("nji,njk->nik", rot[j], rot[i])).as_rotvec()
        change = rel - np.median(rel, axis=0)
        out[i] = (change @ turns[k].T) * (scale * gain * 1e-3 * 180.0 / math.pi)
    return out


def apply_artefacts(clean: MocapSeries, artefacts: SoftTissueArtefacts,
                    rng: np.random.Generator) -> tuple[MocapSeries, list[ArtefactEvent]]:
    """A copy of ``clean`` with soft-tissue sliding, coloured noise, swaps and flips.

    Parameters
    ----------
    clean : MocapSeries
        Noise-free poses (evenly sampled, fully tracked), e.g. ``RunResult.mocap_clean``.
    artefacts : SoftTissueArtefacts
        Amplitudes, band, faults.
    rng : numpy.random.Generator
        Source of every random draw (fixed order and shapes: equal seeds give equal output).

    Returns
    -------
    series : MocapSeries
        The recorded series (``meta["artefacts"]`` holds the settings and the events).
    events : list of ArtefactEvent
        The injected swaps and flips, in the order drawn.

    Raises
    ------
    ConfigError
        When ``bodies`` names a body the series lacks.
    """
    a = artefacts
    b, n = clean.position.shape[:2]
    dt = 1.0 / clean.rate_hz
    names = list(clean.bodies)
    moving = [nm for nm in names if nm != a.euc_body] if a.bodies is None else list(a.bodies)
    unknown = [nm for nm in moving if nm not in names]
    if unknown:
        raise ConfigError(f"bodies {unknown} not in the series (has {', '.join(names)})", key="bodies")
    sel = np.array([nm in moving for nm in names])
    rot = Rotation.from_quat(clean.quat.reshape(-1, 4)).as_matrix().reshape(b, n, 3, 3)
    # --- draws in a fixed order and shape ---
    white_pos = rng.normal(0.0, 1.0, (b, n, 3))
    white_rot = rng.normal(0.0, 1.0, (b, n, 3))
    noise_pos = _coloured(rng, (b, n, 3), dt, a.noise_corner_hz)
    noise_rot = _coloured(rng, (b, n, 3), dt, a.noise_corner_hz)
    # --- sliding, body frame ---
    acc = _unit_rms(_band_limited(-_body_acceleration(clean.position, rot, dt), dt, a.band_hz, axis=1))
    rand = _unit_rms(_band_limited(white_pos, dt, a.band_hz, axis=1))
    slide = _unit_rms(math.sqrt(a.accel_share) * acc + math.sqrt(1.0 - a.accel_share) * rand) * a.slide_rms_m
    slide_rv = _unit_rms(_band_limited(white_rot, dt, a.band_hz, axis=1)) * math.radians(a.slide_rot_rms_deg)
    if a.joint_mm_per_deg > 0:
        slide = slide + _joint_angle_sliding(rot, names, a.euc_body, a.joint_mm_per_deg, rng)
    slide[~sel] = 0.0
    slide_rv[~sel] = 0.0
    pos = clean.position + np.einsum("bnij,bnj->bni", rot, slide) + noise_pos * a.noise_pos_rms_m
    rv = slide_rv + noise_rot * math.radians(a.noise_rot_rms_deg)
    # --- faults ---
    events: list[ArtefactEvent] = []
    fault_rot = np.zeros((b, n, 3))
    idx = np.flatnonzero(sel)
    for _ in range(a.swaps if idx.size else 0):
        i = int(idx[rng.integers(idx.size)])
        length = max(1, int(round(rng.uniform(*a.swap_s) / dt)))
        start = int(rng.integers(0, max(1, n - length)))
        d = rng.normal(0.0, 1.0, 3)
        jump = d / np.linalg.norm(d) * rng.uniform(*a.swap_jump_m)
        axis = rng.normal(0.0, 1.0, 3)
        angle = math.radians(rng.uniform(*a.swap_rot_deg))
        sl = slice(start, min(n, start + length))
        pos[i, sl] += rot[i, sl] @ jump
        fault_rot[i, sl] = axis / np.linalg.norm(axis) * angle
        events.append(ArtefactEvent("swap", names[i], sl.start, sl.stop))
    for _ in range(a.flips if idx.size else 0):
        i = int(idx[rng.integers(idx.size)])
        length = int(rng.integers(a.flip_frames[0], a.flip_frames[1] + 1))
        start = int(rng.integers(0, max(1, n - length)))
        axis = np.eye(3)[int(rng.integers(2))]          # body x or y
        sl = slice(start, min(n, start + length))
        fault_rot[i, sl] = axis * math.pi
        events.append(ArtefactEvent("flip", names[i], sl.start, sl.stop))
    r_meas = (Rotation.from_matrix(rot.reshape(-1, 3, 3)) * Rotation.from_rotvec(rv.reshape(-1, 3))
              * Rotation.from_rotvec(fault_rot.reshape(-1, 3)))
    quat = canonical_quat(r_meas.as_quat()).reshape(b, n, 4)
    meta = dict(clean.meta)
    meta["artefacts"] = {**a.to_dict(), "events": [asdict(e) for e in events]}
    out = MocapSeries(t=clean.t.copy(), frame=clean.frame.copy(), bodies=names, position=pos, quat=quat,
                      tracked=clean.tracked.copy(), mean_marker_error=clean.mean_marker_error.copy(),
                      name=clean.name, meta=meta)
    return out, events


def perturb_session(session: Session, rng: np.random.Generator, *,
                    offset_error_m: tuple[float, float] = (0.01, 0.03), fraction_sd: float = 0.0,
                    mass_error_kg: float = 0.0) -> Session:
    """Copy of ``session`` as a lab estimates it: CoM offsets, and optionally mass fractions and masses, off.

    Each offset moves in a uniformly random direction by a length drawn uniformly from
    ``offset_error_m`` [m]. With ``fraction_sd``, every segment's mass fraction is scaled by
    ``1 + N(0, fraction_sd)`` and all are rescaled to their former sum (the tables differ by about 10 % per
    segment: de Leva 1996 against Dempster's and Zatsiorsky's data); with ``mass_error_kg``, the rider's and
    the EUC's body and wheel masses move by a uniform error within it (a scale's tolerance). The draws come
    in this order, the offsets first, so that the offsets are those of a call without the others.

    Parameters
    ----------
    session : Session
        The session.
    rng : numpy.random.Generator
        Source of the directions and lengths.
    offset_error_m : tuple of float
        Range (low, high) of the move [m].
    fraction_sd : float
        Relative standard deviation of each mass fraction (0: unchanged).
    mass_error_kg : float
        Half-width of the masses' uniform error [kg] (0: unchanged).

    Returns
    -------
    Session
        The perturbed copy.

    Raises
    ------
    ConfigError
        When the range is not ``0 <= low <= high``, or ``fraction_sd`` or ``mass_error_kg`` is negative.
    """
    lo, hi = offset_error_m
    if not 0 <= lo <= hi:
        raise ConfigError(f"need 0 <= low <= high, got {offset_error_m}", key="offset_error_m")
    for key, v in (("fraction_sd", fraction_sd), ("mass_error_kg", mass_error_kg)):
        if not (math.isfinite(v) and v >= 0):
            raise ConfigError(f"must be a finite number >= 0, got {v}", key=key)
    names = list(session.rider.segments)
    d = rng.normal(0.0, 1.0, (len(names), 3))
    d *= (rng.uniform(lo, hi, len(names)) / np.linalg.norm(d, axis=1))[:, None]
    fractions = np.array([session.rider.segments[nm].mass_fraction for nm in names])
    if fraction_sd > 0:
        moved = fractions * np.clip(1.0 + rng.normal(0.0, fraction_sd, len(names)), 0.1, None)
        fractions = moved * (fractions.sum() / moved.sum()) if moved.sum() > 0 else fractions
    segs = {}
    for nm, dv, f in zip(names, d, fractions):
        s = session.rider.segments[nm]
        segs[nm] = Segment(float(f), tuple(float(v) for v in np.asarray(s.com_offset) + dv))
    rider, euc = replace(session.rider, segments=segs), session.euc
    if mass_error_kg > 0:
        dm = rng.uniform(-mass_error_kg, mass_error_kg, 3)
        rider = replace(rider, mass=rider.mass + float(dm[0]))
        euc = replace(euc, body_mass=euc.body_mass + float(dm[1]), wheel_mass=max(0.1, euc.wheel_mass + float(dm[2])))
    return replace(session, rider=rider, euc=euc)
