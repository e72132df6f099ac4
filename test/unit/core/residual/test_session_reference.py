"""The session reference: what a CoM offset that is off fore and aft does, and that no name is given for it.

Known answers:

* a segment CoM moved by ``d`` along the rider's forward axis moves the CoG ``G`` by ``f d`` (``f`` the
  segment's mass fraction), and the pitch about the hinge, ``phi = atan2(G_x - A_x, G_z - A_z)``, by
  ``f d / h`` to first order: the reconstruction of a ride with every segment's offset moved gives that
  constant offset of phi, to the second-order terms ``(f d / h)^2`` and the lean's ``f d / h * phi``;
* the nuisance model fitted to states whose phi carries a constant offset ``delta`` returns ``-delta`` (to the
  pose noise's scatter), and the selection that starts from its residual names nothing, where the base
  model's residual names an effect (a constant torque: on a deceleration ride, a rolling resistance).
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from euc_ros.core.model.extended import Model
from euc_ros.core.model.terms import EucParams
from euc_ros.core.residual.analysis import analyze
from euc_ros.core.residual.selection import fit_base_h, fit_model
from euc_ros.core.residual.selector import ForwardSelector
from euc_ros.core.residual.session_reference import SessionTolerances, session_tolerances
from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
from euc_ros.core.states.contexts import prepare
from euc_ros.core.states.kinematics import reconstruct_states

#: A ride drawn once from a range by a fixed generator (not picked).
SEED = int(np.random.default_rng(2211).integers(500, 600))


@pytest.fixture(scope="module")
def ride():
    return simulate_ride(RideConfig(maneuver="deceleration", runs=3, seed=SEED))


def test_the_bound_is_the_com_tolerance_over_h():
    assert session_tolerances(0.5).dphi_max == pytest.approx(0.01 / 0.5)
    assert session_tolerances(0.5, {"rider.segments.com_offset": 0.02}).dphi_max == pytest.approx(0.04)
    assert session_tolerances(0.0) is None and session_tolerances(float("nan")) is None
    assert session_tolerances(0.6, {"rider.segments.com_offset": 0.0}) is None


def test_a_forward_com_error_is_a_constant_pitch_offset(ride):
    """Every segment's CoM offset moved 1 cm along its body x axis (forward for a rider standing in REP-103
    bodies): phi moves by a constant within the first-order prediction sum(f) d / h, its spread over the ride
    below the second-order terms."""
    session, d = ride.session, 0.01
    segs = session.rider.segments
    moved = dataclasses.replace(session, rider=dataclasses.replace(session.rider, segments={
        name: dataclasses.replace(seg, com_offset=tuple(np.add(seg.com_offset, (d, 0.0, 0.0))))
        for name, seg in segs.items()}))
    run = ride.runs[0].mocap_clean
    a, b = reconstruct_states(run, session), reconstruct_states(run, moved)
    dphi = (b.phi - a.phi)[np.isfinite(a.phi) & np.isfinite(b.phi)]
    h = ride.config.h
    f = sum(seg.mass_fraction for seg in segs.values())
    predicted = f * d / h
    second = predicted ** 2 + predicted * float(np.max(np.abs(a.phi[np.isfinite(a.phi)])))
    assert abs(abs(np.median(dphi)) - predicted) < 3 * second + 0.1 * predicted, (np.median(dphi), predicted)
    assert np.ptp(dphi) < 3 * second + 0.1 * predicted


def test_the_reference_takes_up_a_pitch_offset_and_no_slope_is_named(ride):
    p = EucParams.from_session(ride.session)
    delta = np.deg2rad(0.3)
    states = [reconstruct_states(r.mocap, ride.session) for r in ride.runs]
    offset = [dataclasses.replace(st, phi=st.phi + delta) for st in states]
    recs = prepare(offset, p)
    nuisance = SessionTolerances(np.deg2rad(1.0))
    fit = fit_model(Model([nuisance]), recs, fit_base_h(recs))
    # the poses' noise (0.2 mm, 0.5 deg) moves the fitted offset by a few hundredths of a degree
    assert np.rad2deg(fit.x[1]) == pytest.approx(-0.3, abs=0.05)
    plain = analyze(offset, p, discovery=False)
    judged = analyze(offset, p, discovery=False, selector=ForwardSelector(session=session_tolerances(ride.config.h)))
    assert plain.effect != "none", plain.effect               # the base residual names what the offset does
    assert judged.effect == "none", judged.effect
