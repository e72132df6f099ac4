"""Named effects beside discovered terms: kept only where they add to those terms (:func:`names_beside_discovery`).

A step of :func:`~euc_ros.core.residual.analysis.analyze`, after the discovery.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from euc_ros.core.model.extended import H_BOUNDS
from euc_ros.core.residual.discovery import structure_heldout
from euc_ros.core.residual.groups import discovery_problem
from euc_ros.core.residual.interval import sandwich_covariance
from euc_ros.core.residual.records import DiscoveryOutcome, Journal, Setup, Stage
from euc_ros.core.residual.search import GroupSearch
from euc_ros.core.residual.selection import Model, admissibility, common_samples, fit_model, held_out
from euc_ros.core.residual.selector import Selector
from euc_ros.core.residual.significance import paired_block_test


def names_beside_discovery(setup: Setup, found: DiscoveryOutcome, library: set[str], rules: Selector,
                           journal: Journal, say: Callable[[str], None]) -> DiscoveryOutcome:
    """Step 6c: named effects kept beside accepted discovered terms only where they add to those terms.

    The discovered terms (the same groups) are refitted without the library's names (the geometric effects and the
    session's nuisance kept) and held out as the discovery judged them beside the names (h and the groups'
    coefficients fitted per fold with the prior, :func:`~.discovery.structure_heldout`). When the names and the terms
    together are not significantly better than the terms alone (the paired test at alpha, by the minimum gain),
    the names' signature lies in the terms' span (a lab field's constant part on the rider's pitch looks like a
    slope) and they explain nothing the terms do not: the terms alone are the final model. A name whose
    signature the terms cannot hold (a constant force beside a field proportional to the speed) stays.

    Parameters
    ----------
    setup : Setup
        The prepared recordings and folds.
    found : DiscoveryOutcome
        The discovery step's outcome.
    library : set of str
        The library candidates' names.
    rules : Selector
        The significance level and minimum gain.
    journal : Journal
        Gets the step and a warning when the names are dropped.
    say : callable
        Progress lines.

    Returns
    -------
    DiscoveryOutcome
        ``found``, or the terms alone.
    """
    names = [e.name for e in found.named.model.effects if e.name in library]
    if not found.rows or not names:
        return found
    d_eff = found.stage.model.effects[-1]
    x_terms = np.asarray(found.stage.x, float)[-d_eff.n_params:]
    root = [e for e in found.named.model.effects if e.name not in library]
    both_model, terms_model = found.stage.model, Model(root + [d_eff])
    root_fit = fit_model(Model(root), setup.recs, setup.h0)
    root_ho = held_out(Model(root), setup.recs, setup.h0, setup.folds, start=root_fit.x)
    terms_fit = fit_model(terms_model, setup.recs, setup.h0, start=np.concatenate([root_fit.x, x_terms]))
    # held out as the discovery judged the terms beside the names: h and the groups' coefficients shrunk per fold
    problem = discovery_problem(Model(root), root_fit.x, root_ho, setup.recs, setup.folds, setup.h0, d_eff.basis,
                                GroupSearch())
    terms_ho = structure_heldout(problem, terms_model, d_eff.groups, float(np.clip(terms_fit.x[0], *H_BOUNDS)))
    if terms_ho is None:
        return found
    pair = common_samples(terms_ho, found.stage.heldout)
    if pair is None or not pair[0].residual.size:
        return found
    terms, both = pair
    p = paired_block_test(terms, both)
    if (p < rules.alpha and rules.cuts(both, terms)) or admissibility(terms_model, terms_fit.x, setup.h_geo):
        return found
    label = "+".join(names)
    journal.warnings.append(f"named {label} not reported: the discovered terms explain as much without it "
                            f"(held-out {both.rmse:.3f} N m with it, {terms.rmse:.3f} without, p = {p:.2g})")
    journal.steps.append({"model": both_model.name, "rmse_nm": both.rmse, "selected": None,
                          "dropped_beside_discovery": label, "p_value": p, "rmse_after_nm": terms.rmse})
    say(f"named {label} dropped: the discovered terms explain as much without it (held-out {terms.rmse:.3f} N m)")
    cov, n_blocks = sandwich_covariance(terms_model, setup.recs, terms_fit.x)
    rows = d_eff.describe(terms_fit.x[-d_eff.n_params:], cov[-d_eff.n_params:, -d_eff.n_params:],
                          n_blocks - terms_fit.x.size)
    for row in rows:
        row["rmse_after_nm"] = terms_ho.rmse
    named = Stage(Model(root), root_ho, root_fit.x)
    return DiscoveryOutcome(Stage(terms_model, terms_ho, terms_fit.x), named,
                            {**found.info, "names_dropped": names}, rows, found.p_value)
