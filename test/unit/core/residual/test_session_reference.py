"""The session reference: what a CoM offset that is off fore and aft does, and that no name is given for it.

Known answers:

* a segment CoM moved by ``d`` along its body's forward axis moves the CoG ``G`` by ``f d`` along it (``f``
  the segment's mass fraction), and the pitch about the hinge, ``phi = atan2(G_x - A_x, G_z - A_z)``, by that
  shift's forward component over ``h`` to first order: the reconstruction of a ride with every segment's
  offset moved gives it, to the second-order terms ``(f d / h)^2`` and the lean's ``f d / h * phi``;
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
    """Every segment's CoM offset moved ``d`` = 1 cm along its body x axis: G moves by ``sum f_i d x_i``, and to
    first order phi by its component along the EUC's forward axis over h, ``d / h sum f_i (x_i . x_E)`` (an
    arm that hangs at an angle moves G less forward); the difference is of second order, ``(f d / h)^2`` and
    the lean's ``(f d / h) phi``."""
    from scipy.spatial.transform import Rotation

    session, d = ride.session, 0.01
    segs = session.rider.segments
    moved = dataclasses.replace(session, rider=dataclasses.replace(session.rider, segments={
        name: dataclasses.replace(seg, com_offset=tuple(np.add(seg.com_offset, (d, 0.0, 0.0))))
        for name, seg in segs.items()}))
    run = ride.runs[0].mocap_clean
    a, b = reconstruct_states(run, session), reconstruct_states(run, moved)
    ok = np.isfinite(a.phi) & np.isfinite(b.phi)
    h = ride.config.h
    x_e = Rotation.from_quat(run.quat[run.bodies.index(session.euc.body)]).apply([1.0, 0.0, 0.0])
    forward = sum(seg.mass_fraction * np.einsum("ni,ni->n", x_e, Rotation.from_quat(
        run.quat[run.bodies.index(name)]).apply([1.0, 0.0, 0.0])) for name, seg in segs.items() if name in run.bodies)
    predicted = (d / h * forward)[ok]
    first = d / h * sum(seg.mass_fraction for seg in segs.values())
    second = first ** 2 + first * float(np.max(np.abs(a.phi[ok])))
    dphi = (b.phi - a.phi)[ok]
    assert np.max(np.abs(np.abs(dphi) - predicted)) < second, (np.median(dphi), np.median(predicted), second)


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


def test_the_library_pipeline_judges_against_the_session_reference(tmp_path):
    """``trace_residual`` (the command's, the API's and the studies' pipeline) starts the selection from the session
    reference by default. On a lawless ride of the independent generator, a session whose segment CoM offsets are
    all 6 mm off forward (a pitch offset of about 0.4 deg, within the default 1 cm tolerance) gives the verdict of
    the generator's own session, with the warning that says why; the reference takes up the offsets' residual to
    what a constant pitch offset leaves of it, the lean's share (``phi`` of a few tenths of a radian at most: 10 %
    is a generous bound, the first test's second-order term)."""
    from euc_ros.core.openworld.study import lawless_ride
    from euc_ros.core.residual.pipeline import trace_residual
    from euc_ros.core.session import load_session, save_session

    r = lawless_ride(int(np.random.default_rng(2212).integers(0, 100)), tmp_path, 0.5)
    session = load_session(r["session"])
    segs = session.rider.segments
    off = dataclasses.replace(session, rider=dataclasses.replace(session.rider, segments={
        name: dataclasses.replace(seg, com_offset=tuple(np.add(seg.com_offset, (0.006, 0.0, 0.0))))
        for name, seg in segs.items()}))
    save_session(off, tmp_path / "session_off.yaml")
    csvs = [str(c) for c in r["csvs"]]
    true, data = (trace_residual(str(path), csvs).data for path in (r["session"], tmp_path / "session_off.yaml"))
    assert data["effect"] == true["effect"], (data["selection_steps"][0], true["selection_steps"][0])
    warnings = data["analysis_warnings"]
    assert any("session's CoM tolerance alone explains" in w for w in warnings), warnings
    reference, base_true = data["selection_steps"][0]["rmse_nm"], true["selection_steps"][0]["rmse_nm"]
    excess = data["rmse_before_nm"] - base_true
    assert abs(reference - base_true) <= 0.1 * excess, (reference, base_true, data["rmse_before_nm"])


@pytest.fixture(scope="module")
def friction_ride():
    from euc_ros.core.ridesim import make_effects

    return simulate_ride(RideConfig(maneuver="deceleration", runs=3, seed=SEED,
                                    effects=make_effects(["viscous_friction"], {"c_v": 10.0})))


def test_every_step_judges_against_the_session_reference(friction_ride):
    """A ride with a true viscous friction (10 N s/m) and a pitch offset of 0.3 deg, within the CoM tolerance: the
    first name must beat the offset's reference, and so must the second. Without the reference a constant torque (a
    rolling resistance on rides in one direction) takes up the offset's share of the residual and is named beside
    the friction; judged against the friction with the offset free, only the friction is named."""
    ride = friction_ride
    p = EucParams.from_session(ride.session)
    delta = np.deg2rad(0.3)
    states = [dataclasses.replace(st, phi=st.phi + delta)
              for st in (reconstruct_states(r.mocap, ride.session) for r in ride.runs)]
    plain = analyze(states, p, discovery=False)
    judged = analyze(states, p, discovery=False, selector=ForwardSelector(session=session_tolerances(ride.config.h)))
    assert plain.effect.startswith("viscous_friction+"), plain.effect
    assert judged.effect == "viscous_friction", judged.effect
