"""The discovery's fall-back to a smaller set of its search path when the chosen set's h is not admissible.

:func:`~euc_ros.core.residual.discovery.admissible_subset` with the search stubbed: each number of groups k
along the path has a refit whose h is given, and admissibility is the analysis' own
(:func:`~euc_ros.core.residual.selection.admissibility`: within
:data:`~euc_ros.core.residual.selection.H_MAX_GEOMETRIC_DEV_M` of the geometric h). The h values are drawn
inside or outside that window at random.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from euc_ros.core.model.extended import Model
from euc_ros.core.residual import discovery as D
from euc_ros.core.residual.selection import H_MAX_GEOMETRIC_DEV_M

H_GEO = 0.8


def _h(rng, inside: bool) -> float:
    d = rng.uniform(0.0, 0.9 * H_MAX_GEOMETRIC_DEV_M) if inside else rng.uniform(1.2, 2.0) * H_MAX_GEOMETRIC_DEV_M
    return float(H_GEO + rng.choice([-1.0, 1.0]) * d)


def _stubbed(monkeypatch, h_of_k: dict[int, float]):
    asked = []

    def select(problem, h_lin, most=None):
        asked.append((h_lin, most))
        return SimpleNamespace(best_k=most)

    def refit(problem, choice, h_lin):
        return D.Refit(Model(), np.array([h_of_k[choice.best_k]]), None, choice, h_lin, choice.best_k)

    monkeypatch.setattr(D, "select", select)
    monkeypatch.setattr(D, "refit", refit)
    return asked


def _best(k: int, h: float, first):
    return D.Refit(Model(), np.array([h]), None, first if first is not None else SimpleNamespace(best_k=k), 0.7, k)


@pytest.mark.parametrize("seed", range(6))
def test_the_largest_admissible_smaller_set_is_taken(monkeypatch, seed):
    rng = np.random.default_rng(seed)
    k_best = int(rng.integers(2, 4))
    k_ok = int(rng.integers(1, k_best))
    h_of_k = {k: _h(rng, inside=(k <= k_ok)) for k in range(1, k_best + 1)}
    first = SimpleNamespace(best_k=k_best)
    asked = _stubbed(monkeypatch, h_of_k)
    out = D.admissible_subset(None, _best(k_best, h_of_k[k_best], first), first, H_GEO)
    assert out.choice.best_k == k_ok
    assert abs(out.x[0] - H_GEO) <= H_MAX_GEOMETRIC_DEV_M
    # the sets were asked for from the largest down, at the first linearisation's own h (None)
    assert [m for _, m in asked] == list(range(k_best - 1, k_ok - 1, -1))
    assert all(h is None for h, _ in asked)


def test_an_admissible_best_is_kept_without_a_search(monkeypatch):
    asked = _stubbed(monkeypatch, {})
    best = _best(3, H_GEO + 0.5 * H_MAX_GEOMETRIC_DEV_M, None)
    assert D.admissible_subset(None, best, None, H_GEO) is best
    assert asked == []


def test_no_admissible_smaller_set_keeps_the_best(monkeypatch):
    rng = np.random.default_rng(11)
    h_of_k = {k: _h(rng, inside=False) for k in (1, 2, 3)}
    _stubbed(monkeypatch, h_of_k)
    best = _best(3, h_of_k[3], None)
    assert D.admissible_subset(None, best, None, H_GEO) is best


def test_a_later_linearisation_is_searched_again_at_its_own_h(monkeypatch):
    rng = np.random.default_rng(12)
    h_of_k = {1: _h(rng, inside=True), 2: _h(rng, inside=False)}
    asked = _stubbed(monkeypatch, h_of_k)
    best = _best(2, h_of_k[2], None)           # its choice is not the first linearisation's
    out = D.admissible_subset(None, best, SimpleNamespace(best_k=2), H_GEO)
    assert out.choice.best_k == 1 and asked == [(best.h_lin, 1)]


def _refit(h: float, rmse: float, k: int = 2):
    from euc_ros.core.model.extended import Model
    from euc_ros.core.residual.discovery import Refit
    from euc_ros.core.residual.selection import HeldOut

    n = 40
    res = np.full(n, rmse)
    return Refit(Model(), np.array([h]), HeldOut(Model(), res, np.arange(n) // 4, []), None, h, k)


def test_an_inadmissible_discovery_gives_way_to_an_admissible_one_of_another_linearisation():
    """A re-linearisation that trades h out of the rider's window (h 0.11 m, geometric 0.83 m) fits best held out;
    the admissible models of the other linearisations are compared among themselves and the better one kept."""
    from euc_ros.core.model.extended import Model
    from euc_ros.core.residual.discovery import preferred, preferred_admissible
    from euc_ros.core.residual.selection import admissibility

    far, near_worse, near_better = _refit(0.11, 1.0), _refit(0.99, 3.0), _refit(0.83, 2.0)
    tried = [near_worse, near_better, far]
    best = preferred(preferred(near_worse, near_better), far)
    assert best is far and admissibility(Model(), far.x, 0.83) is not None
    assert preferred_admissible(tried, best, 0.83) is near_better
    # nothing admissible: the best stays (the smaller sets of its path are tried next)
    assert preferred_admissible([far], far, 0.83) is far
    # an admissible best is kept as it is
    assert preferred_admissible(tried, near_better, 0.83) is near_better
