"""What the interval of h includes, and what a caller measured already.

The two option objects of :func:`~euc_ros.core.identify.cog_height.identify_h`.

Examples
--------
>>> IntervalOptions().h_bounds, IntervalOptions(sliding=False).with_budget
((0.1, 1.2), True)
>>> IntervalOptions(h_bounds=(0.9, 0.3))
Traceback (most recent call last):
    ...
euc_ros.core.errors.ConfigError: key 'h_bounds': need 0 < low < high, got (0.9, 0.3)
"""
from __future__ import annotations

from dataclasses import dataclass

from euc_ros.core.errors import ConfigError
from euc_ros.core.identify.simex import SimexShare
from euc_ros.core.identify.sliding_prior import SlidingPrior

#: Lowest and highest h the interval may reach [m] (the ends of the default grid).
H_BOUNDS = (0.1, 1.2)


@dataclass(frozen=True)
class IntervalOptions:
    """What the interval of the pooled 3-DoF h includes.

    Parameters
    ----------
    h_bounds : tuple of float
        Lowest and highest h the bootstrap may reach [m].
    sliding : bool
        Include the SIMEX bias of the soft-tissue sliding the rider's links show.
    sliding_prior : SlidingPrior, optional
        The sliding all the rider's bodies share, which no link shows (:mod:`.sliding_prior`; default: as
        large as the sliding the links show).
    tolerances : dict, optional
        Tolerances of the session's nominal values for the budget (default :data:`~.budget.DEFAULT_TOLERANCES`).
    with_budget : bool
        Also the budget over the nominal values (re-identifies h once per value).

    Raises
    ------
    ConfigError
        ``h_bounds`` not ``0 < low < high``.
    """

    h_bounds: tuple[float, float] = H_BOUNDS
    sliding: bool = True
    sliding_prior: SlidingPrior | None = None
    tolerances: dict | None = None
    with_budget: bool = True

    def __post_init__(self) -> None:
        lo, hi = self.h_bounds
        if not 0 < lo < hi:
            raise ConfigError(f"need 0 < low < high, got {tuple(self.h_bounds)}", key="h_bounds")


@dataclass(frozen=True)
class Measured:
    """What a caller measured on the same recordings already, so that the interval does not measure it again.

    Parameters
    ----------
    simex_share : SimexShare, optional
        Holds SIMEX's first replicate when the residual's noise floor made it.
    link_sliding : dict, optional
        The sliding the rigid links show
        (:func:`~euc_ros.core.states.link_sliding.estimate_sliding` of the recordings).
    """

    simex_share: SimexShare | None = None
    link_sliding: dict | None = None


#: The interval with everything in it (:func:`~euc_ros.core.identify.cog_height.identify_h`'s default).
FULL_INTERVAL = IntervalOptions()
