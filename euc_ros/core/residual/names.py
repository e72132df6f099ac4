"""The ``effect`` string of the residual JSON.

Library effect names joined by ``+``, and the outcome markers that are not effects.
"""
from __future__ import annotations

#: Parts of ``effect`` that name no library effect: ``none`` (the residual at its noise floor), ``discovered``
#: (terms of the discovery, fitted on the analysed recordings) and ``unexplained`` (the residual stays above
#: its floor and nothing explains it).
OUTCOME_MARKERS = ("none", "discovered", "unexplained")


def library_effects(effect: str) -> list[str]:
    """The library effects of an ``effect`` string, in order.

    Parameters
    ----------
    effect : str
        The ``effect`` of the residual JSON: names joined by ``+``.

    Returns
    -------
    list of str
        Its names that are not :data:`OUTCOME_MARKERS`.

    Examples
    --------
    >>> library_effects("ground_slope+unexplained")
    ['ground_slope']
    >>> library_effects("rolling_resistance+discovered")
    ['rolling_resistance']
    >>> library_effects("none")
    []
    """
    return [n.strip() for n in str(effect).split("+") if n.strip() and n.strip() not in OUTCOME_MARKERS]


def has_discovered(effect: str) -> bool:
    """Whether ``effect`` holds the discovery's terms.

    Parameters
    ----------
    effect : str
        The ``effect`` of the residual JSON: names joined by ``+``.

    Returns
    -------
    bool
        True when one of its parts is ``discovered``.
    """
    return "discovered" in (n.strip() for n in str(effect).split("+"))
