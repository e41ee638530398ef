"""Hostile input to the online API (Localizer over the EKF and the particle
filter, plain or augmented; trilateration and bearing triangulation): every
call either refuses its input with a ValueError naming it and leaves the
object exactly as it was, or returns a finite result and leaves a finite state
with a valid covariance.  Each case below came back wrong with no error
before the checks of the one filter interface (safenav/filter.hpp)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from safenav import guidance as gd
from safenav import trilaterate, triangulate_bearings

LANDMARKS = np.array([(-20.0, -20.0), (20.0, -20.0), (20.0, 20.0), (-20.0, 20.0)])
X0, P0 = np.array([1.0, 2.0, 1.0, 0.3]), np.diag([0.3, 0.3, 0.2, 0.05]) ** 2
R = np.eye(2) * 0.1

FILTERS = [("ekf", ()), ("pf", ()), ("ekf", ("range_scale", "heading_rate_bias")),
           ("pf", ("range_scale", "heading_rate_bias"))]
IDS = [f"{f}{'+aug' if a else ''}" for f, a in FILTERS]


def localizer(kind="ekf", augment=(), gate=0.99):
    s = gd.localizer_settings(filter=kind, n_particles=200, seed=3, augment=augment, gate=gate)
    loc = gd.Localizer(s, LANDMARKS)
    loc.initialize(0.0, X0, P0)
    return loc


def snapshot(loc):
    c = loc.counts
    return (np.float64(loc.time).tobytes(), np.asarray(loc.x).tobytes(), np.asarray(loc.P).tobytes(),
            None if loc.augmented is None else np.asarray(loc.augmented).tobytes(),
            (c.motion, c.applied, c.rejected, c.late, c.buffered, c.resets))


def assert_valid(loc):
    x, P = np.asarray(loc.x), np.asarray(loc.P)
    assert np.isfinite(x).all() and np.isfinite(P).all()
    np.testing.assert_allclose(P, P.T, rtol=0, atol=1e-12 * np.abs(P).max())
    assert np.linalg.eigvalsh(P).min() >= -1e-12 * np.abs(P).max()
    assert math.isfinite(loc.position_std) and loc.position_std > 0.0


def refused(loc, call, match):
    before = snapshot(loc)
    with pytest.raises(ValueError, match=match):
        call()
    assert snapshot(loc) == before, "a refused input changed the localizer"


GROSS = {
    "speed_heading": lambda loc: loc.speed_heading(0.1, 1e200, 0.0, 0.1, 0.05),
    "fix": lambda loc: loc.fix(0.1, 1e200, 20.0, R),
    "observe": lambda loc: loc.observe(0.1, 0, range=1e200),
}


@pytest.mark.parametrize("call", sorted(GROSS))
@pytest.mark.parametrize("kind,augment", FILTERS, ids=IDS)
def test_gross_measurement_is_refused_and_leaves_the_localizer(kind, augment, call):
    """A measurement ~1e200 from the estimate: refused (NIS not finite), with the
    prediction to its time undone; the augmented PF used to apply it with NIS 0
    and turn its state to NaN."""
    loc = localizer(kind, augment)
    loc.motion(0.05, 1.0, 0.0)
    refused(loc, lambda: GROSS[call](loc), "at t = 0.1")
    assert_valid(loc)
    assert loc.fix(0.1, 1.1, 2.1, R).applied  # the localizer goes on


@pytest.mark.parametrize("kind,augment", FILTERS, ids=IDS)
def test_a_refused_measurement_far_in_the_future_leaves_the_time(kind, augment):
    """fix(1e300, …) with a gross z raises; the time stays where it was (the augmented
    PF used to keep t = 1e300 and an infinite P)."""
    loc = localizer(kind, augment)
    refused(loc, lambda: loc.fix(1e300, 1e200, 0.0, R), "fix at t = 1e\\+300")
    assert loc.time == 0.0
    assert_valid(loc)


@pytest.mark.parametrize("kind,augment", FILTERS, ids=IDS)
def test_time_jumps_leave_a_valid_covariance_or_are_refused(kind, augment):
    """motion(1e8) then fix(1e8 + 0.1), and fix(1e12) after a motion at 0.1 s: the
    EKF used to end with a covariance with a negative eigenvalue (−0.0018; P[1,1] = −187)."""
    for script in ([("motion", 1e8), ("fix", 1e8 + 0.1)], [("motion", 0.1), ("fix", 1e12)]):
        loc = localizer(kind, augment)
        for op, t in script:
            before = snapshot(loc)
            try:
                if op == "motion":
                    loc.motion(t, 1.0, 0.0)
                else:
                    loc.fix(t, 1.0, 2.0, R)
            except ValueError as e:
                assert f"t = {t:.12g}" in str(e) or "t = " in str(e)
                assert snapshot(loc) == before
            assert_valid(loc)


@pytest.mark.parametrize("kind,augment", FILTERS, ids=IDS)
def test_started_far_out_the_filter_stays_finite(kind, augment):
    """Started by a fix at y = 1e308 (no prior): odometry then either works or is
    refused; the augmented PF used to report P[1,1] = inf."""
    s = gd.localizer_settings(filter=kind, n_particles=100, seed=1, augment=augment)
    loc = gd.Localizer(s, LANDMARKS)
    loc.speed_heading(0.0, 1.0, 0.2, 0.1, 0.05)
    loc.fix(0.0, 0.0, 1e308, R)
    assert loc.initialized
    for t in (0.1, 0.2):
        before = snapshot(loc)
        try:
            loc.odometry(t, 0.1, 0.0)
        except ValueError:
            assert snapshot(loc) == before
        assert np.isfinite(loc.P).all() and np.isfinite(loc.x).all()


def test_a_huge_prior_has_a_finite_position_std():
    """initialize with a prior covariance of 1e300 (entries whose squares overflow):
    position_std is √λ_max, finite (it used to be inf)."""
    loc = gd.Localizer(gd.localizer_settings(), LANDMARKS)
    P = np.diag([1e300, 1.0, 1.0, 1.0])
    loc.initialize(0.0, X0, P)
    assert loc.position_std == pytest.approx(1e150, rel=1e-12)
    P = np.diag([1e300, 1e300, 1.0, 1.0])
    P[0, 1] = P[1, 0] = 0.5e300
    loc.initialize(0.0, X0, P)
    assert loc.position_std == pytest.approx(math.sqrt(1.5e300), rel=1e-12)


def test_position_std_unchanged_for_ordinary_covariances():
    """The overflow branch only: an ordinary P gives the closed form bit for bit."""
    loc = gd.Localizer(gd.localizer_settings(), LANDMARKS)
    P = np.array([[0.3, 0.05, 0, 0], [0.05, 0.2, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])
    loc.initialize(0.0, X0, P)
    a, b, c = 0.3, 0.05, 0.2
    assert loc.position_std == math.sqrt(max(0.0, 0.5 * (a + c) + math.sqrt(0.25 * (a - c) * (a - c) + b * b)))


def test_localization_refuses_sigmas_whose_weights_overflow():
    """σ = 1e155 (σ² overflows) and σ = 1e-155 (1/σ² overflows) used to return status
    ok with an infinite covariance; they are refused, naming the σ."""
    anchors = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0]])
    p = np.array([3.0, 4.0])
    ranges = np.linalg.norm(anchors - p, axis=1)
    bearings = np.arctan2(anchors[:, 1] - p[1], anchors[:, 0] - p[0])
    with pytest.raises(ValueError, match=r"sigmas\[0\] = 1e\+155"):
        trilaterate(anchors, ranges, np.full(4, 1e155))
    with pytest.raises(ValueError, match=r"sigmas\[0\] = 1e-155"):
        triangulate_bearings(anchors, bearings, np.full(4, 1e-155))
    for s in (1e150, 1e-150, 1.0):
        r = trilaterate(anchors, ranges, np.full(4, s))
        b = triangulate_bearings(anchors, bearings, np.full(4, s))
        for res in (r, b):
            if res.ok:
                assert np.isfinite(res.covariance).all()
