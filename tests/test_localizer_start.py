"""The localizer's start from data (localizer.hpp, "Initialization"): one
rigid-transform fit of the motion integral to ranges, bearings and IMU
headings, through the landmark model of measurement.hpp.

Each rule is checked on a synthetic run with known truth: noise-free
odometry, observations with known σ, and the start pose compared with the
true pose at the start time within a tolerance derived from that σ
(k·(σ_r + d·σ_b) for a position seen at distance d, k·σ_b for a heading).
Degenerate data (one landmark, no motion, collinear geometry) must not start,
and the localizer must say why (``reason()``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from safenav import guidance as gd

LANDMARKS = np.array([(10.0, 0.0), (10.0, 6.0), (4.0, 8.0), (-2.0, 7.0), (20.0, 3.0), (30.0, 3.0)])
IDS = [0, 1, 2, 3, 4, 5]
SR, SB = 0.1, math.radians(2.0)   # σ_r [m], σ_b [rad]
K = 5.0                           # tolerance in σ


def wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


class Run:
    """A vehicle at `pose` driven at `speed` and `turn` (rad/s); odometry at
    10 Hz (heading first, then position: the localizer's integral), the
    camera at 5 Hz through `sight(t, pose)` -> [(id, range?, bearing?)]."""

    def __init__(self, pose, speed=0.0, turn=0.0, seed=0, settings=None):
        self.loc = gd.Localizer(settings or gd.localizer_settings(), LANDMARKS, IDS)
        self.pose = np.array(pose, float)
        self.speed, self.turn = speed, turn
        self.rng = np.random.default_rng(seed)
        self.truth = {}
        self.t_start = None

    def observe(self, t, lid, rng_on=True, bearing_on=True):
        d = LANDMARKS[lid] - self.pose[:2]
        kw = {}
        if rng_on:
            kw.update(range=float(np.hypot(*d) + SR * self.rng.normal()), range_std=SR)
        if bearing_on:
            kw.update(bearing=wrap(math.atan2(d[1], d[0]) - self.pose[2] + SB * self.rng.normal()), bearing_std=SB)
        self.loc.observe(t, IDS[lid], **kw)

    def drive(self, seconds, sight, t0=0.0):
        for k in range(1, int(round(seconds * 10)) + 1):
            t = t0 + k * 0.1
            dth, dd = self.turn * 0.1, self.speed * 0.1
            self.pose[2] = wrap(self.pose[2] + dth)
            self.pose[:2] += dd * np.array([math.cos(self.pose[2]), math.sin(self.pose[2])])
            self.loc.odometry(t, dd, dth)
            self.truth[round(t, 6)] = self.pose.copy()
            if self.t_start is None and self.loc.initialized:
                self.t_start, self.x0, self.P0 = t, self.loc.x.copy(), self.loc.P.copy()
                assert self.loc.time == pytest.approx(t)
            if k % 2 == 1:   # camera frames between odometry rows
                for obs in sight(t + 0.05, self.pose):
                    self.observe(t + 0.05, *obs)
        return self

    def start_error(self):
        """(position error [m], heading error [rad]) of the start against the truth at that time."""
        x = self.x0
        true = self.truth[round(self.t_start, 6)]
        return float(np.hypot(*(x[:2] - true[:2]))), abs(wrap(x[3] - true[2]))

    def check_covers_truth(self):
        """The start covariance covers the error (position NEES below the 99.9 % χ²₂ bound)."""
        e = self.x0[:2] - self.truth[round(self.t_start, 6)][:2]
        assert e @ np.linalg.solve(self.P0[:2, :2], e) < 13.8


def tol_position(distance):
    return K * (SR + distance * SB)


# --------------------------------------------------------------------------- rule (a)

def test_a_two_landmarks_range_and_bearing_at_one_instant_give_the_whole_pose():
    run = Run((6.0, 2.0, 0.6))      # standing still: the first frame sees landmarks 1 and 2
    run.drive(1.0, lambda t, p: [(1,), (2,)] if t < 0.2 else [])
    assert run.t_start == pytest.approx(0.2)      # the motion input after the first frame
    pos, head = run.start_error()
    d = max(np.hypot(*(LANDMARKS[i] - run.pose[:2])) for i in (1, 2))
    assert pos < tol_position(d) and head < K * SB
    run.check_covers_truth()
    assert run.loc.reason().startswith("started at t = 0.2")


def test_a_two_landmarks_seen_one_at_a_time_while_moving():
    run = Run((0.0, 0.0, 0.3), speed=0.5, turn=0.05)
    # landmark 2 in the first frames only, landmark 0 from t = 3 s on: never two at once
    run.drive(8.0, lambda t, p: [(2,)] if t < 1.0 else [(0,)] if t > 3.0 else [])
    assert run.t_start is not None and 3.0 < run.t_start < 3.3
    pos, head = run.start_error()
    assert pos < tol_position(10.0) and head < K * SB
    run.check_covers_truth()


# --------------------------------------------------------------------------- rule (b)

def test_b_one_landmark_gives_the_position_once_the_heading_is_known():
    run = Run((6.0, 2.0, 0.6))
    # the heading before any motion input (σ_θ = 0.01 rad): taken where the motion integral starts
    run.loc.speed_heading(0.0, 0.0, 0.6 + 0.01 * run.rng.normal(), 0.01, 0.01)
    run.drive(1.0, lambda t, p: [(1,)])
    assert run.t_start == pytest.approx(0.2)      # the motion input after the first frame (t = 0.15)
    pos, head = run.start_error()
    d = np.hypot(*(LANDMARKS[1] - run.pose[:2]))
    assert pos < tol_position(d) + K * 0.01 * d and head < K * 0.01


def test_one_landmark_without_a_heading_never_starts():
    # range and bearing of one landmark fix only where the vehicle is relative to it, not the heading
    run = Run((2.0, 0.0, 0.0), speed=0.5, turn=0.2)
    run.drive(30.0, lambda t, p: [(0,)])
    assert not run.loc.initialized
    r = run.loc.reason()
    assert r.startswith("waiting:") and "bearings of 1" in r and "need range+bearing of 2 landmarks" in r


# --------------------------------------------------------------------------- rule (c)

def test_c_bearings_alone_after_the_vehicle_has_moved():
    run = Run((0.0, 0.0, 0.2), speed=0.8, turn=0.03)
    run.drive(12.0, lambda t, p: [(0, False, True), (1, False, True)])
    assert run.t_start is not None
    moved = 0.8 * run.t_start
    assert moved >= run.loc.settings.get_param("init_min_path") - 0.2 and run.t_start < 10.0
    pos, head = run.start_error()
    # triangulated over a baseline b from a distance d: σ_p ≈ d²σ_b/b, σ_θ ≈ σ_p/d
    d, b = 10.0, moved
    assert pos < K * d * d * SB / b and head < K * d * SB / b
    run.check_covers_truth()


def test_bearings_of_three_landmarks_at_one_instant_resect_the_pose():
    run = Run((5.0, 2.0, 1.2))
    run.drive(1.0, lambda t, p: [(0, False, True), (1, False, True), (3, False, True)] if t < 0.2 else [])
    assert run.t_start == pytest.approx(0.2)
    pos, head = run.start_error()
    assert pos < tol_position(8.0) and head < K * SB


def test_bearings_without_motion_do_not_start():
    run = Run((5.0, 2.0, 0.6))
    run.drive(20.0, lambda t, p: [(0, False, True), (1, False, True)])
    assert not run.loc.initialized
    assert "0 m of motion" in run.loc.reason()


def test_bearings_collinear_with_the_track_do_not_start():
    # driving straight at landmarks 4 and 5, which lie on the path's line: every bearing is 0,
    # and where along the line the vehicle is stays unknown
    run = Run((0.0, 3.0, 0.0), speed=0.8)
    run.drive(15.0, lambda t, p: [(4, False, True), (5, False, True)])
    assert not run.loc.initialized
    assert "last fit" in run.loc.reason()


# --------------------------------------------------------------------------- rule (d)

def test_d_ranges_of_three_landmarks_after_moving():
    run = Run((0.0, 0.0, 0.3), speed=1.0, turn=0.05)
    run.drive(15.0, lambda t, p: [(0, True, False), (1, True, False), (2, True, False)])
    assert run.t_start is not None and run.t_start >= run.loc.settings.get_param("init_min_path") - 0.2
    pos, head = run.start_error()
    assert pos < K * SR * 2 and head < 0.1
    run.check_covers_truth()


def test_ranges_without_motion_or_along_a_line_of_landmarks_do_not_start():
    still = Run((5.0, 2.0, 0.6)).drive(20.0, lambda t, p: [(0, True, False), (1, True, False), (2, True, False)])
    assert not still.loc.initialized and "ranges of 3" in still.loc.reason()
    # on the line y = 3 through landmarks 4 and 5: the side of the line stays unknown
    line = Run((0.0, 3.0, 0.0), speed=1.0).drive(15.0, lambda t, p: [(4, True, False), (5, True, False)])
    assert not line.loc.initialized


# --------------------------------------------------------------------------- never silent

def test_reason_and_counts_before_and_after_the_start():
    loc = gd.Localizer(gd.localizer_settings(), LANDMARKS, IDS)
    assert loc.reason().startswith("waiting: no motion input yet")
    loc.odometry(0.1, 0.0, 0.0)   # the first motion input covers one nominal step before it
    assert loc.observe(0.15, 0, range=3.0, bearing=0.1).status == gd.InputStatus.BUFFERED
    loc.odometry(0.2, 0.0, 0.0)
    assert "ranges of 1 landmark(s)" in loc.reason() and "need" in loc.reason()
    loc.initialize(0.2, np.array([10.0, 0.0, 0.0, 0.0]), np.eye(4))
    # at the landmark: the observation has no model and is ignored, and counted
    assert loc.observe(0.2, 0, range=0.0).status == gd.InputStatus.IGNORED
    assert loc.counts.ignored == 1
    assert loc.reason() == "started at t = 0.2"
