"""h held at the segments' geometric h: the criterion, the geometric h's bound and its Type B uncertainty.

The bound the uncertainty rests on (a common shift of the CoM offsets by ``d`` along the bodies' z axes and a
change ``e`` of l0 move the geometric h by at most ``|d| + |e|``) is checked on random geometry by moving G and
the hinge directly; the rectangular combination by sampling the two tolerances (the tolerance of a sampled
standard deviation is from its own standard error).
"""
from __future__ import annotations

import dataclasses
import math
import random
from types import SimpleNamespace

import numpy as np
import pytest

from euc_ros.core.identify.held import (
    data_bound_h,
    geometric_h,
    geometric_h_uncertainty,
    held_h,
)
from euc_ros.core.identify.interval import MAX_RIDE_ACCEL_RMS_MPS2, MIN_SHARPNESS
from euc_ros.core.model.terms import EucParams
from euc_ros.core.session import default_session


def _states(rng, n=500):
    """A rider-like geometry: C near the floor, G 0.6-0.9 m above, small EUC angles."""
    C = np.column_stack([rng.normal(0, 1, n), rng.normal(0, 1, n), np.full(n, 0.2)])
    G = C + np.column_stack([rng.normal(0, 0.05, n), rng.normal(0, 0.05, n), rng.uniform(0.6, 0.9, n)])
    return SimpleNamespace(C=C, G=G, gamma=rng.normal(0, 0.05, n), psi=rng.uniform(-np.pi, np.pi, n),
                           theta=rng.normal(0, 0.03, n), valid=np.ones(n, bool))


def _params(l0=0.05):
    return dataclasses.replace(EucParams.from_session(default_session()), l0=l0)


def test_geometric_h_is_the_median_distance_of_g_from_the_hinge():
    rng = np.random.default_rng(random.randrange(1, 1 << 30))
    st = _states(rng)
    p = _params()
    # the hinge written out independently: A = C - l0 z_E, z_E = Rz(psi) Rx(theta) Ry(gamma) e_z
    g, th, ps = st.gamma, st.theta, st.psi
    zb = np.column_stack([np.sin(g), -np.sin(th) * np.cos(g), np.cos(th) * np.cos(g)])
    zw = np.column_stack([np.cos(ps) * zb[:, 0] - np.sin(ps) * zb[:, 1], np.sin(ps) * zb[:, 0] + np.cos(ps) * zb[:, 1],
                          zb[:, 2]])
    expected = float(np.median(np.linalg.norm(st.G - (st.C - p.l0 * zw), axis=1)))
    assert math.isclose(geometric_h([st], p), expected, rel_tol=1e-12)


def test_a_shift_of_the_coms_and_of_l0_moves_the_geometric_h_by_at_most_their_sum():
    seed = random.randrange(1, 1 << 30)
    rng = np.random.default_rng(seed)
    st = _states(rng)
    p = _params()
    h0 = geometric_h([st], p)
    for _ in range(20):
        d, e = rng.uniform(-0.02, 0.02), rng.uniform(-0.01, 0.01)
        # G moves by d times a convex combination of unit vectors (the bodies' z axes): length <= |d|
        w = rng.dirichlet(np.ones(5))
        axes = rng.normal(size=(5, 3))
        axes /= np.linalg.norm(axes, axis=1)[:, None]
        moved = SimpleNamespace(**{**vars(st), "G": st.G + d * (w @ axes)})
        p2 = dataclasses.replace(p, l0=p.l0 + e)
        dh = geometric_h([moved], p2) - h0
        assert abs(dh) <= abs(d) + abs(e) + 1e-12, (seed, dh, d, e)
    # upright bodies (z axes along G - A) reach the bound: sensitivity 1 to a common shift
    up = SimpleNamespace(**{**vars(st), "G": st.G + 0.01 * np.array([0.0, 0.0, 1.0])})
    assert 0.009 < geometric_h([up], p) - h0 <= 0.01 + 1e-12


def test_uncertainty_is_the_rectangular_combination_of_the_two_tolerances():
    rng = np.random.default_rng(random.randrange(1, 1 << 30))
    a, b = 0.01, 0.004
    u = geometric_h_uncertainty({"rider.segments.com_offset": a, "euc.l0": b}, l0=0.05)
    n = 200_000
    s = float(np.std(rng.uniform(-a, a, n) + rng.uniform(-b, b, n)))
    # standard error of a sampled standard deviation: sigma sqrt((kurtosis - 1) / (4 n)), kurtosis < 3 here
    se = u * math.sqrt(2.0 / (4 * n))
    assert abs(s - u) < 5 * se, (s, u, se)


def test_a_percent_tolerance_of_l0_is_of_the_session_l0():
    u = geometric_h_uncertainty({"rider.segments.com_offset": 0.0, "euc.l0": "10%"}, l0=0.08)
    assert math.isclose(u, 0.008 / math.sqrt(3.0), rel_tol=1e-12)


def test_the_data_do_not_bound_h_when_the_curve_is_flat_for_want_of_excitation_a_ride_gives():
    assert data_bound_h(MIN_SHARPNESS, 0.5)
    assert data_bound_h(float("nan"), 0.5)                        # sharpness unknown: not judged
    assert not data_bound_h(0.5 * MIN_SHARPNESS, 0.5 * MAX_RIDE_ACCEL_RMS_MPS2)
    assert not data_bound_h(0.5 * MIN_SHARPNESS, MAX_RIDE_ACCEL_RMS_MPS2)
    # flat because of a residual no ride's excitation would explain (an effect the model lacks), or unknown
    assert data_bound_h(0.5 * MIN_SHARPNESS, 1.01 * MAX_RIDE_ACCEL_RMS_MPS2)
    assert data_bound_h(0.5 * MIN_SHARPNESS, None)
    assert data_bound_h(0.5 * MIN_SHARPNESS, float("nan"))


def test_held_h_holds_only_what_the_data_do_not_bound():
    rng = np.random.default_rng(random.randrange(1, 1 << 30))
    st = _states(rng)
    p = _params()
    assert held_h([st], p, 0.6, (0.55, 0.65), sharpness=1.2, accel_needed_mps2=0.3) is None
    assert held_h([st], p, 0.3, (0.1, None), sharpness=0.3, accel_needed_mps2=11.0) is None     # an effect's residual
    assert held_h([st], p, 0.07, None, sharpness=0.3, accel_needed_mps2=0.9) is None           # no interval computed
    held = held_h([st], p, 0.07, (0.05, None), sharpness=0.3, accel_needed_mps2=0.9)
    assert held is not None and held.h_m == geometric_h([st], p)
    assert "too little" not in held.reason and "lacks speed changes" in held.reason and "unbounded" in held.reason
    lo, hi = held.ci95_m
    assert math.isclose(hi - lo, 2 * 1.959964 * held.std_m, rel_tol=1e-12) and lo < held.h_m < hi
    doc = held.to_json()
    assert doc["held"] is True and doc["h_from_data_m"] == 0.07 and doc["h_from_data_ci95_m"] == [0.05, None]
    assert "do not bound h" in doc["reason"] and f"{held.h_m:.3f}" in held.console_line()


def test_the_mass_fractions_terms_add_in_quadrature():
    from euc_ros.core.identify.held import MassSensitivity

    tol = {"rider.segments.com_offset": 0.01, "euc.l0": 0.005, "rider.segments.mass_fraction": 0.02,
           "rider.segments.mass_fraction_each": 0.1}
    u0 = geometric_h_uncertainty(tol, l0=0.05)
    u = geometric_h_uncertainty(tol, l0=0.05, mass_sensitivity=MassSensitivity(-0.5, {}))
    assert u == pytest.approx(math.sqrt(u0 ** 2 + (0.5 * 0.02) ** 2 / 3.0), rel=1e-12)
    # with the per-segment levers, their term stands for the mass fractions (the share is one of their
    # consequences, not counted twice)
    both = MassSensitivity(-0.5, {"BA": 0.03, "TR": -0.04})
    u2 = geometric_h_uncertainty(tol, l0=0.05, mass_sensitivity=both)
    assert u2 == pytest.approx(math.sqrt(u0 ** 2 + ((0.03 * 0.1) ** 2 + (0.04 * 0.1) ** 2) / 3.0), rel=1e-12)
    assert geometric_h_uncertainty(tol, l0=0.05, mass_sensitivity=MassSensitivity(float("nan"), {})) == u0
    u3 = geometric_h_uncertainty(tol, l0=0.05, mass_sensitivity=MassSensitivity(float("nan"), {"BA": 0.05}))
    assert u3 == pytest.approx(math.sqrt(u0 ** 2 + (0.05 * 0.1) ** 2 / 3.0), rel=1e-12)


def test_the_mass_sensitivity_is_the_geometric_h_of_moved_fractions(tmp_path):
    """Against the reconstruction itself: the session's fractions moved by +-0.01 of the body mass from the legs
    to the upper body (the budget's rule), the recording reconstructed again, central difference of its
    geometric h. First order: the difference of the two medians and the median of the projection agree to a
    fraction of the step's curvature (1 % of the value, and a few tenths of a millimetre over the 0.02 step)."""
    from euc_ros.core.identify.budget import LOWER_LIMBS
    from euc_ros.core.identify.held import geometric_mass_sensitivity
    from euc_ros.core.states.load import load_states
    from euc_ros.core.worldsim import Capture, simulate_ride, write_ride

    seed = 4242
    ride = simulate_ride(seed, 120.0, duration=8.0)
    paths = write_ride(ride, tmp_path / "motive", Capture(), seed=seed, name=f"ws{seed}")
    from euc_ros.core.session import load_session

    session = load_session(paths["session"])
    states = load_states(session, [str(paths["csv"])], keep_series=True)
    s = geometric_mass_sensitivity([st.meta["series"] for st in states], session)
    segs = session.rider.segments
    legs = sum(g.mass_fraction for n, g in segs.items() if n in LOWER_LIMBS)
    upper = sum(g.mass_fraction for n, g in segs.items() if n not in LOWER_LIMBS)

    def h_moved(d):
        moved = {n: dataclasses.replace(g, mass_fraction=g.mass_fraction * (
            1.0 - d / legs if n in LOWER_LIMBS else 1.0 + d / upper)) for n, g in segs.items()}
        sess = dataclasses.replace(session, rider=dataclasses.replace(session.rider, segments=moved))
        return geometric_h(load_states(sess, [str(paths["csv"])]), EucParams.from_session(sess))

    fd = (h_moved(0.01) - h_moved(-0.01)) / 0.02
    assert 0.2 < s.share < 1.2, s                 # the upper body's CoM lies above the legs'
    print(f"sensitivity {s.share:.4f}, central difference {fd:.4f} m per unit of body mass")
    assert abs(fd - s.share) <= 0.01 * abs(s.share) + 0.02, (fd, s.share)

    def h_scaled(name, e):          # one segment's fraction scaled by 1 + e, all rescaled to their former sum
        total = sum(g.mass_fraction for g in segs.values())
        scaled = {n: g.mass_fraction * (1.0 + e if n == name else 1.0) for n, g in segs.items()}
        k = total / sum(scaled.values())
        moved = {n: dataclasses.replace(g, mass_fraction=scaled[n] * k) for n, g in segs.items()}
        sess = dataclasses.replace(session, rider=dataclasses.replace(session.rider, segments=moved))
        return geometric_h(load_states(sess, [str(paths["csv"])]), EucParams.from_session(sess))

    weighted = {n for n, g in segs.items() if g.mass_fraction > 0}
    assert set(s.levers) == weighted
    # the heaviest upper-body segment's CoM lies above G, the heaviest leg segment's below it: the levers'
    # signs, and each lever against the reconstruction
    heaviest_upper = max((n for n in weighted if n not in LOWER_LIMBS), key=lambda n: segs[n].mass_fraction)
    lowest = max((n for n in weighted if n in LOWER_LIMBS), key=lambda n: segs[n].mass_fraction)
    assert s.levers[heaviest_upper] > 0 > s.levers[lowest], s.levers
    # the tolerance: the exact move is f (c - G) e / (1 + e f), so the central difference's own error is e^2 f^2
    # of the lever (under 0.1 %); what is left is the difference of two medians against the median of the
    # per-frame levers (as for the share above: a fraction of the step's curvature, 2 % of the value) and
    # the states' re-reconstruction (its filter), a few tenths of a millimetre over the 0.1 step
    for name in (heaviest_upper, lowest):
        fd = (h_scaled(name, 0.05) - h_scaled(name, -0.05)) / 0.1
        print(f"{name}: lever {s.levers[name]:.5f}, central difference {fd:.5f} m per unit relative change")
        assert abs(fd - s.levers[name]) <= 0.02 * abs(s.levers[name]) + 2e-3, (name, fd, s.levers[name])
