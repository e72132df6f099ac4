"""How a lab records a study ride and describes it: the artefact model of its sliding and its session's errors.

The ``classic`` design records every rider body with band-limited sliding, half of it following the segment's
acceleration, and gives the analysis the generator's own session (its nominal values are the truth). The
``lab`` design is what a lab has:

* the sliding comes from one of two artefact models of the field, or their mixture, drawn per ride
  (:data:`MODELS`): ``acceleration`` (wobbling masses: the skin lags its segment, Gruber et al. 1998; the
  ride's level of band-limited sliding, all of it following the acceleration), ``joint`` (artefact modes
  linear in the joint angles: each body's pivot moves with its angle to the EUC by a gain of the order the
  reviews report, :data:`~euc_ros.core.ridesim.artefacts.JOINT_GAIN_MM_PER_DEG`, scaled by
  :data:`JOINT_SCALE`), and ``mixture`` (both, the band-limited half following the acceleration);
* the session the analysis gets is an estimate (:func:`~euc_ros.core.ridesim.artefacts.perturb_session`):
  segment CoM offsets :data:`OFFSET_ERROR_M` off, mass fractions scattered by :data:`FRACTION_SD` as the
  anthropometric tables differ, masses within a scale's :data:`MASS_ERROR_KG`.

The draws come from a stream of their own (``[seed, family index, STREAM, 7]``), so a ride's law, level and
target ratio are the classic design's.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from euc_ros.core.errors import ConfigError

#: The designs a study may use.
DESIGNS = ("classic", "lab")
#: The artefact models of the ``lab`` design, drawn with equal chance.
MODELS = ("acceleration", "joint", "mixture")
#: Range of the joint-angle artefact's scale (1: the reviews' typical gains).
JOINT_SCALE = (0.5, 2.0)
#: Range of a segment's CoM offset error [m] (uniform length, random direction).
OFFSET_ERROR_M = (0.01, 0.02)
#: Relative scatter of each segment's mass fraction (de Leva 1996 against Dempster's and Zatsiorsky's data).
FRACTION_SD = 0.1
#: Half-width of the masses' error [kg] (a scale, clothing).
MASS_ERROR_KG = 0.5
#: Key of the design's sub-stream (after the seed, the family's index and the study's stream).
SUBSTREAM = 7


@dataclass(frozen=True)
class LabDesign:
    """One ride's recording and session, as drawn.

    Parameters
    ----------
    model : str
        ``classic`` or one of :data:`MODELS`.
    accel_share : float
        Share of the band-limited sliding's variance that follows the acceleration.
    band_sliding : bool
        Whether the ride's band-limited sliding is recorded (the ``joint`` model has none).
    joint_scale : float
        Scale of the joint-angle artefact (0: none).
    perturbed : bool
        Whether the analysis gets a perturbed session.
    session_seed : tuple of int
        Seed of the session's perturbation.
    """

    model: str
    accel_share: float
    band_sliding: bool
    joint_scale: float
    perturbed: bool
    session_seed: tuple

    def describe(self) -> dict:
        """The design as a row's fields.

        Returns
        -------
        dict
            ``artefact_model``, ``joint_scale``, ``session`` (``generator`` or ``perturbed``).
        """
        return {"artefact_model": self.model, "joint_scale": self.joint_scale,
                "session": "perturbed" if self.perturbed else "generator"}


def draw_design(design: str, seed: int, family_index: int, stream: int) -> LabDesign:
    """A ride's design.

    Parameters
    ----------
    design : str
        One of :data:`DESIGNS`.
    seed : int
        The ride's seed.
    family_index : int
        Its family's index.
    stream : int
        The study's stream key.

    Returns
    -------
    LabDesign

    Raises
    ------
    ConfigError
        An unknown design (key ``--design``).

    Examples
    --------
    >>> draw_design("classic", 3, 0, 20250).model
    'classic'
    >>> draw_design("lab", 3, 0, 20250).model in MODELS
    True
    """
    if design not in DESIGNS:
        raise ConfigError(f"must be one of {DESIGNS}, got {design!r}", key="--design")
    key = (int(seed), int(family_index), int(stream), SUBSTREAM)
    if design == "classic":
        return LabDesign("classic", 0.5, True, 0.0, False, key)
    rng = np.random.default_rng(list(key))
    model = MODELS[int(rng.integers(len(MODELS)))]
    scale = float(rng.uniform(*JOINT_SCALE))
    return LabDesign(model, 1.0 if model == "acceleration" else 0.5, model != "joint",
                     0.0 if model == "acceleration" else scale, True, key + (1,))


def analysed_session(session, design: LabDesign):
    """The session the analysis gets: the generator's, or a lab's estimate of it.

    Parameters
    ----------
    session : Session
        The generator's session (the truth).
    design : LabDesign
        The ride's design.

    Returns
    -------
    Session
    """
    from euc_ros.core.ridesim.artefacts import perturb_session

    if not design.perturbed:
        return session
    return perturb_session(session, np.random.default_rng(list(design.session_seed)), offset_error_m=OFFSET_ERROR_M,
                           fraction_sd=FRACTION_SD, mass_error_kg=MASS_ERROR_KG)
