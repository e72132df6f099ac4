"""How poses become states: one frozen settings object instead of the same loose keywords everywhere.

The filter (a Savitzky-Golay window in seconds with its polynomial order, or ``"auto"``: chosen from the
recordings' spectra), the rider pitch's definition, the CoG method and the gap rule travel together from
the command line through loading, identification and the residual analysis.

Examples
--------
>>> s = ReconstructionSettings()
>>> s.window_s, s.polyorder, s.phi_definition, s.cog_method, s.is_auto
('auto', None, 'hinge', 'segments', True)
>>> s.with_filter(1.425, 8).window_s
1.425
>>> ReconstructionSettings(window_s=1.2).polyorder      # a fixed window takes the default order
6
>>> ReconstructionSettings().reconstruct(None, None)
Traceback (most recent call last):
    ...
euc_ros.core.errors.ConfigError: key '--window-s': reconstructing needs a filter: fix it with with_filter() or window_s
>>> ReconstructionSettings(phi_definition="knee")
Traceback (most recent call last):
    ...
euc_ros.core.errors.ConfigError: key '--phi-definition': expected one of hinge, eq3, got 'knee'
"""
from __future__ import annotations

from dataclasses import dataclass, replace

from euc_ros.core.errors import ConfigError
from euc_ros.core.filters.derivatives import DEFAULT_MAX_GAP
from euc_ros.core.states.kinematics import (
    DEFAULT_SG_POLYORDER,
    DEFAULT_WINDOW_S,
    PHI_DEFINITIONS,
    RiderStates,
    iter_states_filters,
    reconstruct_states,
)
from euc_ros.core.states.skeleton import COG_METHODS


@dataclass(frozen=True)
class ReconstructionSettings:
    """The filter, the pitch definition, the CoG method and the gap rule of a reconstruction.

    Parameters
    ----------
    window_s : float or "auto"
        Savitzky-Golay window [s], or ``"auto"``: window and order chosen from the recordings
        (:func:`~euc_ros.core.states.filter_choice.choose_filter`).
    polyorder : int, optional
        The polynomial order with a window in seconds (default
        :data:`~euc_ros.core.states.kinematics.DEFAULT_SG_POLYORDER`); None with ``"auto"``.
    phi_definition : {"hinge", "eq3"}
        Rider pitch about the ankle hinge A (the model's) or about the wheel centre C.
    cog_method : {"segments", "skeleton"}
        Rider CoG from the measured segments or from a kinematic chain fitted to them.
    max_gap : int
        Longest run of missing frames a body is bridged across [frames].

    Raises
    ------
    ConfigError
        A value outside its choices, naming the command-line option.
    """

    window_s: float | str = "auto"
    polyorder: int | None = None
    phi_definition: str = "hinge"
    cog_method: str = "segments"
    max_gap: int = DEFAULT_MAX_GAP

    def __post_init__(self) -> None:
        if isinstance(self.window_s, str):
            if self.window_s != "auto":
                raise ConfigError(f"window must be 'auto' or a number of seconds, got {self.window_s!r}",
                                  key="--window-s")
            if self.polyorder is not None:
                raise ConfigError("the order is chosen with the window; give a window in seconds to fix it",
                                  key="--polyorder")
        elif self.polyorder is None:
            object.__setattr__(self, "polyorder", DEFAULT_SG_POLYORDER)
        if self.phi_definition not in PHI_DEFINITIONS:
            raise ConfigError(f"expected one of {', '.join(PHI_DEFINITIONS)}, got {self.phi_definition!r}",
                              key="--phi-definition")
        if self.cog_method not in COG_METHODS:
            raise ConfigError(f"expected one of {', '.join(COG_METHODS)}, got {self.cog_method!r}",
                              key="--cog-method")

    @property
    def is_auto(self) -> bool:
        """Whether the filter is chosen from the data."""
        return isinstance(self.window_s, str)

    def with_filter(self, window_s: float, polyorder: int) -> "ReconstructionSettings":
        """The same settings with the filter fixed (the one chosen from the data, say).

        Parameters
        ----------
        window_s : float
            Window [s].
        polyorder : int
            Polynomial order.

        Returns
        -------
        ReconstructionSettings
        """
        return replace(self, window_s=float(window_s), polyorder=int(polyorder))

    def _fixed(self) -> None:
        if self.is_auto:
            raise ConfigError("reconstructing needs a filter: fix it with with_filter() or window_s", key="--window-s")

    def reconstruct(self, series, session, *, skeleton=None, lean: bool = False) -> RiderStates:
        """A recording's states with these settings (:func:`~euc_ros.core.states.kinematics.reconstruct_states`).

        Parameters
        ----------
        series : MocapSeries
            The recording's poses.
        session : Session
            Its session.
        skeleton : SkeletonModel, optional
            The chain fitted to the recordings (``cog_method="skeleton"``; default: fitted to ``series``).
        lean : bool
            Keep only what the fits need.

        Returns
        -------
        RiderStates

        Raises
        ------
        ConfigError
            The filter is ``"auto"`` (not fixed yet).
        """
        self._fixed()
        return reconstruct_states(series, session, phi_definition=self.phi_definition, window_s=float(self.window_s),
                                  polyorder=int(self.polyorder), max_gap=self.max_gap, cog_method=self.cog_method,
                                  skeleton=skeleton, lean=lean)

    def iter_filters(self, series, session, filters, *, skeleton=None, shared: bool = False, lean: bool = False):
        """A recording's states at several filters, one at a time; the filter of these settings is not used.

        See :func:`~euc_ros.core.states.kinematics.iter_states_filters`.

        Parameters
        ----------
        series : MocapSeries
            The recording's poses.
        session : Session
            Its session.
        filters : sequence of (float, int)
            ``(window_s, polyorder)`` per filter.
        skeleton, shared, lean
            As for :func:`~euc_ros.core.states.kinematics.iter_states_filters`.

        Returns
        -------
        generator of RiderStates
        """
        return iter_states_filters(series, session, filters, phi_definition=self.phi_definition, max_gap=self.max_gap,
                                   cog_method=self.cog_method, skeleton=skeleton, shared=shared, lean=lean)


#: The fixed filter of the analyses that are not given one (the interval's re-reconstructions, the studies).
FIXED_DEFAULT = ReconstructionSettings(window_s=DEFAULT_WINDOW_S)
