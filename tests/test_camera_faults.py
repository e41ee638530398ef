"""Landmark-level faults in the camera loop: the core's
LandmarkFaults (dropout, misassociation, outliers; the simulator's
FixModel.RANGES model) corrupt LanBLoc's per-landmark ranges between stereo
ranging and trilateration.  One rendered scene with five markers in view and
one landmark far out of view (ids not 0..K-1, so rows and ids differ)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from safenav.navigation import LandmarkFaults
from safenav.vision.lanbloc import MISASSOCIATED, OUTLIER, CameraLoopSource, LanBLoc
from safenav.vision.sighting import REPEATED
from safenav.vision.render import StereoRenderer, StereoRig
from safenav.world import Landmark, World

POSE = (40.0, 60.0, 0.5)
STATE = np.array([POSE[0], POSE[1], 1.5, POSE[2]])
# (depth, lateral to the right, height) from the vehicle; id 40 is 35 m behind, beyond the confusion range
PLACEMENTS = {1: (7.0, -3.0, 2.5), 2: (10.0, 2.0, 1.8), 3: (13.0, -0.5, 4.0), 4: (16.0, 6.0, 3.0),
              5: (11.0, -8.5, 1.2), 40: (-35.0, 0.0, 2.0)}
IN_VIEW = {1, 2, 3, 4, 5}


def _world():
    th = POSE[2]
    fwd = np.array([math.cos(th), math.sin(th)])
    right = np.array([math.sin(th), -math.cos(th)])
    return World(landmarks=tuple(Landmark(k, (*(np.array(POSE[:2]) + z * fwd + lat * right), h), f"class{k}", 1)
                                 for k, (z, lat, h) in PLACEMENTS.items()))


WORLD = _world()
MAP = {lm.id: np.array(lm.position[:2], dtype=float) for lm in WORLD.landmarks}


def _frames(source, n, start=0):
    """Run ``n`` frames at POSE; the LanBLoc results."""
    out = []
    for k in range(start, start + n):
        source(STATE, k)
        out.append(source.last)
    return out


@pytest.fixture(scope="module")
def clean():
    """Three fault-free frames with seed 7."""
    return _frames(CameraLoopSource(WORLD, seed=7), 3)


def test_faults_off_is_bit_identical_and_the_faults_are_reproducible(clean):
    zero = _frames(CameraLoopSource(WORLD, seed=7, faults=LandmarkFaults()), 3)
    assert all(r.ok for r in clean)
    for a, b in zip(clean, zero):
        assert a.status == b.status and b.dropped == 0
        assert np.array_equal(a.position, b.position) and np.array_equal(a.covariance, b.covariance)
        assert [(o.landmark_id, o.range, o.sigma, o.bearing) for o in a.observations] == \
               [(o.landmark_id, o.range, o.sigma, o.bearing) for o in b.observations]
        assert all(o.faults == 0 and o.true_landmark_id is None for o in b.observations)
    # the same seed draws the same faults
    f = LandmarkFaults(dropout_probability=0.3, outlier_probability=0.3, misassociation_probability=0.3)
    runs = [[(r.status, [(o.landmark_id, o.faults, o.range) for o in r.observations])
             for r in _frames(CameraLoopSource(WORLD, seed=7, faults=f), 2)] for _ in range(2)]
    assert runs[0] == runs[1] and any(o[1] for _, obs in runs[0] for o in obs)


def test_dropout_one_leaves_no_fix_and_counts_every_range_as_dropped():
    src = CameraLoopSource(WORLD, faults=LandmarkFaults(dropout_probability=1.0))
    for k in range(3):
        assert src(STATE, k) is None
        assert src.last.status == "too_few_ranges" and "5 dropped by landmark faults" in src.last.reason
        assert src.last.n_ranges == 0 and src.last.dropped == 5 and len(src.last.detections) == 5
    fs = src.fault_stats
    assert fs["observations"] == fs["dropped"] == 15
    assert fs["outliers"] == fs["misassociated"] == fs["ranges_rejected"] == fs["faults_in_fix"] == 0
    assert src.stats["calls"] == 3 and src.stats["too_few_ranges"] == 3


def test_every_fault_reaches_the_camera_loop_at_its_rate():
    """Counts within 4 binomial standard errors of their probabilities: dropout
    over all ranged observations, misassociation and outliers over the kept ones."""
    p_drop, p_mis, p_out = 0.3, 0.25, 0.2
    src = CameraLoopSource(WORLD, seed=11, faults=LandmarkFaults(
        dropout_probability=p_drop, outlier_probability=p_out, outlier_magnitude=5.0,
        misassociation_probability=p_mis))
    n_frames = 30
    results = _frames(src, n_frames)
    fs = src.fault_stats
    assert fs["observations"] == 5 * n_frames
    kept = fs["observations"] - fs["dropped"]

    def within(count, n, p):
        return abs(count - n * p) <= 4 * math.sqrt(n * p * (1 - p)), (count, n, p)

    assert within(fs["dropped"], fs["observations"], p_drop)
    assert within(fs["misassociated"], kept, p_mis)
    assert within(fs["outliers"], kept, p_out)
    # the per-frame records add up to the counts; a range whose landmark another range of its
    # frame names too (a misassociation to a landmark in view) is not used, and counts as rejected
    assert sum(r.dropped for r in results) == fs["dropped"]
    repeated = sum(len(r.repeated) for r in results)
    assert sum(r.n_ranges for r in results) == kept - repeated and repeated > 0
    assert sum(len(r.rejected) for r in results) + repeated == fs["ranges_rejected"]
    assert sum(len(r.faults_in_fix) for r in results) == fs["faults_in_fix"]


def test_a_misassociation_uses_the_wrong_landmarks_position_and_an_outlier_moves_the_range(clean):
    both = _frames(CameraLoopSource(WORLD, seed=7, faults=LandmarkFaults(
        misassociation_probability=1.0, outlier_probability=1.0, outlier_magnitude=2.5)), 8)
    unique = 0
    for c, m in zip(clean + _frames(CameraLoopSource(WORLD, seed=7), 5, start=3), both):
        ranges = {ob.landmark_id: ob.range for ob in c.observations}
        assert len(m.observations) == 5
        names = [ob.landmark_id for ob in m.observations]
        for ob in m.observations:
            assert ob.faults == MISASSOCIATED | OUTLIER and ob.true_landmark_id in IN_VIEW
            # another landmark near the vehicle (never the far one): its id, class and map position
            assert ob.landmark_id in IN_VIEW - {ob.true_landmark_id}
            assert ob.class_name == f"class{ob.landmark_id}"
            np.testing.assert_array_equal(ob.anchor[:2], MAP[ob.landmark_id])
            if names.count(ob.landmark_id) > 1:
                # two ranges name one landmark: neither is used (the core front end's rule)
                assert not ob.ok and math.isnan(ob.range) and ob.reason.endswith(REPEATED), ob
                assert ob in m.repeated
                continue
            unique += 1
            # the range is still to the landmark seen, off by the outlier magnitude
            assert abs(ob.range - ranges[ob.true_landmark_id]) == pytest.approx(2.5, abs=1e-12)
        # the filter-facing measurements carry the corrupted observations that were used
        ids, anchors, _, _ = m.range_measurements()
        assert sorted(ids) == sorted(i for i in names if names.count(i) == 1)
        np.testing.assert_array_equal(anchors.reshape(-1, 2), np.array([MAP[i] for i in ids]).reshape(-1, 2))
    assert unique > 0


@pytest.mark.parametrize("faults, flag", [(LandmarkFaults(outlier_probability=0.2, outlier_magnitude=5.0), OUTLIER),
                                          (LandmarkFaults(misassociation_probability=0.2), MISASSOCIATED)])
def test_a_single_faulty_range_among_five_is_rejected_by_the_outlier_test(faults, flag):
    """Frames with exactly one faulty range of five: trilateration's outlier
    consensus rejects an outlier, and the fix stays within a metre (clean
    fixes here are 0.1-0.3 m off).  A misassociation names another landmark
    in view, which a clean range names too: neither is used, and the fix
    comes from the other three."""
    src = CameraLoopSource(WORLD, seed=3, faults=faults)
    seen = 0
    for k in range(12):
        if seen == 2:
            break
        z = src(STATE, k)
        res = src.last
        bad = [o for o in res.observations if o.faults]
        if res.n_ranges + len(res.repeated) != 5 or len(bad) != 1:
            continue
        seen += 1
        assert bad[0].faults == flag
        assert res.ok and z is not None, res.reason
        if flag == OUTLIER:
            assert [o.landmark_id for o in res.rejected] == [bad[0].landmark_id]
        else:
            assert res.rejected == () and res.n_ranges == 3
            assert [o.landmark_id for o in res.repeated] == [bad[0].landmark_id] * 2
        assert res.faults_in_fix == ()
        assert np.linalg.norm(z[0] - STATE[:2]) < 1.0
    assert seen >= 2


def test_bad_faults_are_named():
    with pytest.raises(ValueError, match="faults = 'often'"):
        CameraLoopSource(WORLD, faults="often")
    with pytest.raises(ValueError, match="faults = 0.1"):
        CameraLoopSource(WORLD, faults=0.1)
    f = LandmarkFaults()
    f.outlier_probability = 1.5
    with pytest.raises(ValueError, match="faults.outlier_probability"):
        CameraLoopSource(WORLD, faults=f)
    with pytest.raises(ValueError, match="seed"):
        CameraLoopSource(WORLD, faults=LandmarkFaults(), seed=-1)
    rig = StereoRig()
    left, right = StereoRenderer(WORLD, rig).render(POSE)
    lb = LanBLoc(WORLD, rig)
    with pytest.raises(ValueError, match="position"):
        lb.localize(left, right, faults=LandmarkFaults(dropout_probability=0.5))
    with pytest.raises(ValueError, match="faults = 3"):
        lb.localize(left, right, faults=3)
    # LanBLoc on its own: the seed is the frame's
    a = lb.localize(left, right, faults=LandmarkFaults(dropout_probability=0.5), position=POSE[:2], seed=4)
    b = lb.localize(left, right, faults=LandmarkFaults(dropout_probability=0.5), position=POSE[:2], seed=4)
    assert a.dropped == b.dropped and [o.landmark_id for o in a.observations] == \
           [o.landmark_id for o in b.observations]
    seeds = {tuple(o.landmark_id for o in lb.localize(left, right, faults=LandmarkFaults(dropout_probability=0.5),
                                                     position=POSE[:2], seed=s).observations) for s in range(6)}
    assert len(seeds) > 1   # the draws depend on the seed
