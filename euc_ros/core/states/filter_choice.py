"""The Savitzky-Golay filter of a set of recordings, chosen from their own spectra.

:func:`choose_filter` reads the unfiltered signals the states are differentiated from (EUC pitch
``gamma``, rider pitch ``phi`` and the wheel centre's horizontal coordinates) off each recording's
frame geometry, puts them on the recording's frame grid (missing frames NaN) and hands them to
:func:`~euc_ros.core.filters.auto_window.choose_window`, which balances the filter's distortion of
the accelerations against the noise it passes. Recordings of different frame rates are chosen for
per rate; one filter (the longest window of the rates' choices) then serves them all, because h,
SIMEX and the interval use a single ``window_s`` and a longer window only adds distortion, which the
interval's probe term (:func:`~euc_ros.core.identify.cog_height.identify_h`) measures.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from euc_ros.core.errors import ConfigError
from euc_ros.core.filters.auto_window import WindowChoice, choose_window
from euc_ros.core.memory import release_free_memory
from euc_ros.core.states.geometry import block_geometry
from euc_ros.core.states.kinematics import PHI_DEFINITIONS, reconstruct_states, reconstruct_states_filters
from euc_ros.core.states.link_sliding import sliding_or_none


def raw_signals(series, session, phi_definition: str = "hinge") -> dict[str, np.ndarray]:
    """Unfiltered ``gamma``, ``phi``, ``C_x``, ``C_y`` of a recording on its frame grid.

    Parameters
    ----------
    series : MocapSeries
        Z-up poses.
    session : Session
    phi_definition : {"hinge", "eq3"}
        Which rider pitch the states use.

    Returns
    -------
    dict of ndarray (n,)
        ``n`` = last frame - first frame + 1; frames not in the recording, or without the bodies a
        signal needs, are NaN (the spectrum continues across short runs of them and splits at longer ones:
        :func:`~euc_ros.core.filters.auto_window.displacement_spectrum`).
    """
    geo, _, _ = block_geometry(series, session, 0)
    frame = np.asarray(series.frame, dtype=np.int64)
    n = int(frame[-1] - frame[0]) + 1 if frame.size else 0
    k = frame - frame[0] if frame.size else frame
    phi = geo["phi_hinge"] if phi_definition == "hinge" else geo["phi_eq3"]
    out = {}
    for name, v in (("gamma", geo["gamma"]), ("phi", phi), ("C_x", geo["C"][:, 0]), ("C_y", geo["C"][:, 1])):
        g = np.full(n, np.nan)
        g[k] = v
        out[name] = g
    return out


@dataclass(frozen=True)
class FilterChoice:
    """The filter :func:`choose_filter` chose, with the per-rate choices behind it.

    Parameters
    ----------
    choice : WindowChoice
        The filter used (``window_s``, ``polyorder``, its diagnostics and ``probe``).
    per_rate : dict of float to WindowChoice
        Frame rate [Hz] -> the choice for the recordings of that rate.
    sliding : dict or None
        What the rigid links between the rider's bodies show beyond white noise
        (:func:`~euc_ros.core.states.link_sliding.estimate_sliding`; None without links), kept for the
        interval's sliding terms.
    """

    choice: WindowChoice
    per_rate: dict = field(default_factory=dict)
    sliding: dict | None = None

    def __getattr__(self, name: str):
        """The chosen filter's own attributes (``window_s``, ``polyorder``, ``probe``, ``probe_ratio``...)."""
        if name == "choice" or name.startswith("__"):
            raise AttributeError(name)
        return getattr(self.choice, name)

    def to_json(self) -> dict:
        """``choice.to_json()`` plus ``rate_hz`` (the rate it was chosen at) and, for several rates, ``per_rate``.

        ``per_rate``: each rate's own choice (window and order).

        Returns
        -------
        dict
            The JSON form.
        """
        out = dict(self.choice.to_json())
        rate = next((r for r, c in self.per_rate.items() if c is self.choice), None)
        out["rate_hz"] = rate
        if len(self.per_rate) > 1:
            out["per_rate"] = {f"{r:g}": {"window_s": c.window_s, "polyorder": c.polyorder}
                               for r, c in sorted(self.per_rate.items())}
        return out


#: ``noise_power`` of :func:`~euc_ros.core.filters.auto_window.choose_window` for identification: h's
#: noise bias is removed by SIMEX (:mod:`euc_ros.core.identify.simex`), so the noise counts by the
#: square of its relative variance. The distortion this filter leaves in h, measured on the noise-free
#: twin of noisy rides (docs/studies/h_correction.md): -0.28 +- 0.06 mm on 24 generator rides and
#: -4.8 +- 2.5 mm on 8 rides of the project's simulator, against -0.68 +- 0.09 and -12.5 +- 5.5 mm with
#: the mean-square-error choice (1), whose window also reaches the longest candidate on some rides.
NOISE_POWER = 2


#: RMS of what a body's rigid links show beyond white noise [m] from which the noise is modelled as
#: coloured (:func:`choose_filter`). With white pose noise at the paper's level the estimate scatters up
#: to 0.8 mm on 12 s rides (its white part removed by third differences, from a few thousand samples);
#: the same noise low-passed at 5 Hz shows 2.9 mm.
COLOURED_LINK_RMS_M = 1.5e-3


def choose_filter(series_list: Sequence, session, *, phi_definition: str = "hinge",
                  noise_power: int = NOISE_POWER, sliding: dict | None = None) -> FilterChoice:
    """Choose the Savitzky-Golay window and order for recordings from their raw signals.

    Parameters
    ----------
    series_list : sequence of MocapSeries
        The recordings (Z-up).
    session : Session
    phi_definition : {"hinge", "eq3"}
    noise_power : {1, 2}
        How the noise counts against the distortion (:func:`~euc_ros.core.filters.auto_window.
        choose_window`); :data:`NOISE_POWER` for an h whose noise bias SIMEX removes.
    sliding : dict, optional
        :func:`~euc_ros.core.states.link_sliding.estimate_sliding` of ``series_list`` when the caller has it
        (default: measured here).

    Returns
    -------
    FilterChoice
        The noise floor of every signal is estimated from the top of its spectrum
        (:func:`~euc_ros.core.filters.auto_window.choose_window`); recordings are grouped by frame
        rate (rounded to 0.1 Hz) and the longest window of the groups' choices is used. The noise is
        modelled as coloured when the rigid links between the rider's bodies show at least
        :data:`COLOURED_LINK_RMS_M` beyond white noise (``sliding``), or when the white model's choice
        distorts too much (:func:`~euc_ros.core.filters.auto_window.choose_window`).
    """
    if phi_definition not in PHI_DEFINITIONS:
        raise ConfigError(f"phi definition must be one of {PHI_DEFINITIONS}, got {phi_definition!r}",
                          key="phi_definition")
    groups: dict[float, dict[str, list]] = {}
    dts: dict[float, float] = {}
    for s in series_list:
        rate = round(float(s.rate_hz), 1)
        dts.setdefault(rate, 1.0 / float(s.rate_hz))        # the spacing the states are filtered with
        sig = raw_signals(s, session, phi_definition)
        g = groups.setdefault(rate, {k: [] for k in sig})
        for k, v in sig.items():
            g[k].append(v)
    # the links between the rider's bodies: rigid, so what they show beyond white noise is coloured
    # noise or soft tissue, which the spectra of the signals alone can take for motion
    if sliding is None:
        sliding = sliding_or_none(list(series_list), session)
    coloured = sliding is not None and float(sliding.get("rms_max_m") or 0.0) >= COLOURED_LINK_RMS_M
    per_rate = {rate: choose_window(dts[rate], sig, noise_power=noise_power, coloured=coloured)
                for rate, sig in groups.items()}
    used = max(per_rate.values(), key=lambda c: c.window_s)
    del groups
    release_free_memory()       # the raw signals, spectra and the links' deviations: freed, not kept resident
    return FilterChoice(used, per_rate, sliding)


def data_filtered(series: list, session, phi_definition: str,
                  sliding: dict | None = None) -> tuple[list, list | None, float]:
    """The recordings' states with the Savitzky-Golay filter chosen from their own spectra, and its probe filter.

    Parameters
    ----------
    series : list of MocapSeries
        The recordings (Z-up).
    session : Session
        The session.
    phi_definition : {"hinge", "eq3"}
        Which rider pitch the states use.
    sliding : dict, optional
        As :func:`choose_filter`.

    Returns
    -------
    chosen : list of RiderStates
        The states with the chosen filter, one per recording.
    probe : list of RiderStates or None
        The states with the probe filter (None without one).
    probe_ratio : float
        The probe's predicted distortion over the chosen filter's (NaN without a probe).

    Raises
    ------
    ConfigError
        Naming ``phi_definition`` when it is unknown.
    """
    choice = choose_filter(series, session, phi_definition=phi_definition, sliding=sliding)

    probe = choice.probe
    filters = [(choice.window_s, choice.polyorder)] + ([tuple(probe)] if probe else [])
    # both filters from one evaluation of each recording's geometry
    per_rec = [reconstruct_states_filters(s, session, filters, phi_definition=phi_definition) for s in series]
    chosen = [st[0] for st in per_rec]
    return (chosen, [st[1] for st in per_rec] if probe else None,
            float(choice.probe_ratio) if probe else float("nan"))


def data_filters(series: list, session, phi_definition: str, sliding: dict | None = None) -> tuple:
    """:func:`data_filtered` made when asked for.

    ``(make_chosen, make_probe or None, probe_ratio)``, each ``make_*()`` the recordings' states with that
    filter (the same states). A caller that reduces the chosen filter's states before asking for the probe's
    never holds both (each evaluates the geometry anew).

    Parameters
    ----------
    series : list of MocapSeries
        The recordings (Z-up).
    session : Session
        The session.
    phi_definition : {"hinge", "eq3"}
        Which rider pitch the states use.
    sliding : dict, optional
        As :func:`choose_filter`.

    Returns
    -------
    tuple
        ``(make_chosen, make_probe, probe_ratio)``: callables returning lists of RiderStates (``make_probe``
        None without a probe) and the probe's distortion ratio (NaN without one).

    Raises
    ------
    ConfigError
        Naming ``phi_definition`` when it is unknown.
    """
    choice = choose_filter(series, session, phi_definition=phi_definition, sliding=sliding)

    def make(window_s: float, polyorder: int):
        return lambda: [reconstruct_states(s, session, phi_definition=phi_definition, window_s=window_s,
                                           polyorder=polyorder) for s in series]

    probe = choice.probe
    return (make(choice.window_s, choice.polyorder), make(*probe) if probe else None,
            float(choice.probe_ratio) if probe else float("nan"))
