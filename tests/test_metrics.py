"""Trajectory metrics (SafeNav section V-B) and filter consistency statistics.

Every expected value here comes from somewhere other than safenav itself:

* ADE (eq. 21), FDE (eq. 22) and path length are checked against evo's APE
  (translation part, no alignment) and evo's ``path_length``, on random 2-D
  trajectories and on real KITTI 00 data (ground truth and ORB-SLAM2 estimate
  from evo's own test data, see ``tests/data/README.md``).
* WRS (eq. 18) is checked against a pure-Python transcription of the paper's
  formula with exact rational zone bounds (``fractions.Fraction``), following
  DESIGN.md "Reading the SafeNav paper: decisions", item 6.
* ``distance_to_path`` is checked against a brute-force minimum over 10^5
  points sampled along the polyline, and exactly where the nearest point is a
  vertex.
* ADE/FDE/% path-length error (eq. 23) against plain NumPy.

NEES and the chi-square interval are in ``test_metrics_nees.py``.
"""

from __future__ import annotations

import math
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

import safenav.scenario
from safenav import metrics
from safenav.metrics import RiskZones

try:  # evo is in the optional test extra: without it only the evo cross-checks are skipped
    import evo.core.metrics as evo_metrics
    import evo.core.trajectory as evo_trajectory
    import evo.main_ape as evo_main_ape
    import evo.tools.file_interface as evo_file_interface
except ImportError:  # pragma: no cover
    evo_metrics = None
needs_evo = pytest.mark.skipif(evo_metrics is None, reason="evo is not installed (pip install safenav[test])")

DATA = Path(__file__).parent / "data"
KITTI_GT = DATA / "KITTI_00_gt_every10.txt"
KITTI_EST = DATA / "KITTI_00_ORB_every10.txt"

PAPER_WEIGHTS = (2.0, 4.0, 6.0, 8.0)  # SafeNav section V-A(iii)


# --------------------------------------------------------------------------- helpers

def rng(seed):
    return np.random.default_rng(seed)


def random_walk(g, n, step=1.0):
    return np.cumsum(g.normal(scale=step, size=(n, 2)), axis=0) + g.uniform(-50, 50, size=2)


def evo_traj_2d(xy, name=None):
    """A PoseTrajectory3D on the plane z = 0 with identity orientations."""
    xy = np.asarray(xy, dtype=float)
    n = len(xy)
    xyz = np.column_stack([xy, np.zeros(n)])
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    return evo_trajectory.PoseTrajectory3D(positions_xyz=xyz, orientations_quat_wxyz=quat,
                                           timestamps=np.arange(n, dtype=float) * 0.1, name=name)


def evo_ape(truth_xy, est_xy):
    """evo's APE, translation part, no alignment, no scale correction."""
    return evo_main_ape.ape(evo_traj_2d(truth_xy, "truth"), evo_traj_2d(est_xy, "estimate"),
                            pose_relation=evo_metrics.PoseRelation.translation_part,
                            align=False, correct_scale=False)


def evo_ape_low_level(truth_xy, est_xy):
    ape = evo_metrics.APE(evo_metrics.PoseRelation.translation_part)
    ape.process_data((evo_traj_2d(truth_xy), evo_traj_2d(est_xy)))
    return ape


def paper_wrs(d, d_max=2.0, weights=PAPER_WEIGHTS):
    """Eq. 18 as printed, read per DESIGN.md item 6, in pure Python.

    The buffer half-width d_max is cut into n = len(weights) equal zones per
    side, zone j = [a_j, b_j) with a_j = (j-1)·d_max/n, b_j = j·d_max/n.
    Inside zone j: |d|·(|d|/w_j).  At or beyond d_max: d_max·(d_max/w_max).
    Zone membership is decided in exact rational arithmetic so the reference
    has no rounding of its own at the borders.
    """
    ad = abs(float(d))
    w_max = max(weights)
    n = len(weights)
    if Fraction(ad) >= Fraction(d_max):
        return d_max * (d_max / w_max)
    for j in range(1, n + 1):
        a_j = Fraction(j - 1) * Fraction(d_max) / n
        b_j = Fraction(j) * Fraction(d_max) / n
        if a_j <= Fraction(ad) < b_j:
            return ad * (ad / weights[j - 1])
    raise AssertionError(f"deviation {d} fell in no zone")  # pragma: no cover


def dense_polyline_samples(path, n_samples):
    """n_samples points spread along the polyline by arc length, vertices included."""
    path = np.asarray(path, dtype=float)
    seg = np.diff(path, axis=0)
    seg_len = np.hypot(seg[:, 0], seg[:, 1])
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    s = np.linspace(0.0, cum[-1], n_samples)
    x = np.interp(s, cum, path[:, 0])
    y = np.interp(s, cum, path[:, 1])
    samples = np.column_stack([x, y])
    return np.vstack([samples, path]), cum[-1] / (n_samples - 1)


def brute_force_distance(points, samples, chunk=20):
    out = np.empty(len(points))
    for i in range(0, len(points), chunk):
        p = points[i:i + chunk, None, :]
        d2 = ((p - samples[None, :, :]) ** 2).sum(axis=2)
        out[i:i + chunk] = np.sqrt(d2.min(axis=1))
    return out


def kitti_xz(path):
    """Horizontal (x, z) positions of a KITTI pose file: the camera frame has y down."""
    poses = evo_file_interface.read_kitti_poses_file(str(path))
    return poses.positions_xyz[:, [0, 2]].copy(), poses


# --------------------------------------------------------------------------- 1. evo cross-checks

@needs_evo
@pytest.mark.parametrize("seed,n", [(0, 2), (1, 17), (2, 500), (3, 2000)])
def test_ade_equals_evo_ape_translation_mean(seed, n):
    g = rng(seed)
    truth = random_walk(g, n)
    est = truth + g.normal(scale=0.7, size=truth.shape) + np.array([0.3, -0.2])
    result = evo_ape(truth, est)
    ours = metrics.ade(est, truth)
    assert ours == pytest.approx(result.stats["mean"], rel=1e-9, abs=0.0)
    # the lower-level API agrees too, and ADE is symmetric in its two arguments
    low = evo_ape_low_level(truth, est)
    assert ours == pytest.approx(low.get_statistic(evo_metrics.StatisticsType.mean), rel=1e-9)
    assert metrics.ade(truth, est) == pytest.approx(ours, rel=1e-12)


@needs_evo
@pytest.mark.parametrize("seed,n", [(4, 2), (5, 40), (6, 700)])
def test_fde_equals_last_evo_ape_error(seed, n):
    g = rng(seed)
    truth = random_walk(g, n)
    est = truth + g.normal(scale=1.5, size=truth.shape)
    errors = evo_ape(truth, est).np_arrays["error_array"]
    assert len(errors) == n
    assert metrics.fde(est, truth) == pytest.approx(errors[-1], rel=1e-9, abs=0.0)


@needs_evo
@pytest.mark.parametrize("seed,n", [(7, 2), (8, 3), (9, 1000)])
def test_path_length_equals_evo_path_length(seed, n):
    path = random_walk(rng(seed), n, step=3.0)
    assert metrics.path_length(path) == pytest.approx(evo_traj_2d(path).path_length, rel=1e-9, abs=0.0)


def test_path_length_single_point_is_zero():
    assert metrics.path_length([[3.0, 4.0]]) == 0.0


@needs_evo
def test_kitti_fixture_is_present_and_paired():
    truth, gt3 = kitti_xz(KITTI_GT)
    est, est3 = kitti_xz(KITTI_EST)
    assert gt3.num_poses == est3.num_poses == 455
    # a real drive: kilometres long, mostly flat (the y axis points down in KITTI's camera frame)
    assert metrics.path_length(truth) > 3000.0
    assert np.ptp(gt3.positions_xyz[:, 1]) < 0.1 * np.ptp(truth, axis=0).min()


@needs_evo
def test_kitti_ade_fde_path_length_match_evo():
    truth, gt3 = kitti_xz(KITTI_GT)
    est, est3 = kitti_xz(KITTI_EST)
    result = evo_ape(truth, est)  # same 2-D positions, put on z = 0
    errors = result.np_arrays["error_array"]

    ade = metrics.ade(est, truth)
    assert ade == pytest.approx(result.stats["mean"], rel=1e-9, abs=0.0)
    assert ade > 1.0  # ORB-SLAM2 on KITTI 00 drifts by metres: the comparison is not trivial
    assert metrics.fde(est, truth) == pytest.approx(errors[-1], rel=1e-9, abs=0.0)

    len_truth = evo_traj_2d(truth).path_length
    len_est = evo_traj_2d(est).path_length
    assert metrics.path_length(truth) == pytest.approx(len_truth, rel=1e-9, abs=0.0)
    assert metrics.path_length(est) == pytest.approx(len_est, rel=1e-9, abs=0.0)
    assert metrics.path_length_error_percent(est, truth) == pytest.approx(
        abs(len_est - len_truth) / len_truth * 100.0, rel=1e-9)

    # evo's own projection onto the x-z plane of the untouched 3-D poses gives the same APE
    projected = evo_main_ape.ape(gt3, est3, pose_relation=evo_metrics.PoseRelation.translation_part,
                                 align=False, correct_scale=False,
                                 project_to_plane=evo_trajectory.Plane.XZ)
    assert ade == pytest.approx(projected.stats["mean"], rel=1e-9, abs=0.0)


# --------------------------------------------------------------------------- 2. WRS, AWRS, distance to path

def _deviations_to_probe(d_max, n_zones, g):
    borders = [j * d_max / n_zones for j in range(1, n_zones)] + [d_max]
    probe = [0.0, -0.0, 1e-300, d_max * 1e-9]
    for b in borders:
        probe += [b, math.nextafter(b, 0.0), math.nextafter(b, math.inf), b * (1 - 1e-9), b * (1 + 1e-9)]
    probe += [1.5 * d_max, 10 * d_max, 1e6 * d_max]
    probe += list(np.linspace(0.0, 1.3 * d_max, 1001))
    probe += list(g.uniform(0.0, 1.2 * d_max, 2000))
    probe = np.array(probe)
    return np.concatenate([probe, -probe])  # eq. 18 uses |d|


def test_wrs_of_deviation_matches_paper_formula_default_zones():
    d = _deviations_to_probe(2.0, 4, rng(10))
    ours = metrics.wrs_of_deviation(d, Z2)
    ref = np.array([paper_wrs(x) for x in d])
    np.testing.assert_allclose(ours, ref, rtol=1e-15, atol=0.0)


def test_default_risk_zones_are_the_papers():
    z = RiskZones()
    assert list(z.weights) == list(PAPER_WEIGHTS)
    # one default, declared in the core: the scenario's buffer reads it from there
    assert z.half_width == 8.0 == safenav.scenario.BufferParams().half_width


#: the zones of width 0.5 that the exact-value tests below are written for
Z2 = RiskZones(half_width=2.0, weights=list(PAPER_WEIGHTS))


def test_wrs_exact_values_at_zone_borders_default_zones():
    # zones of width 0.5: [0, .5) w=2, [.5, 1) w=4, [1, 1.5) w=6, [1.5, 2) w=8, >= 2: 2*2/8
    d = np.array([0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0])
    expect = np.array([0.0, 0.25**2 / 2, 0.5**2 / 4, 1.0**2 / 6, 1.5**2 / 8, 2.0 * 2.0 / 8, 2.0 * 2.0 / 8])
    np.testing.assert_array_equal(metrics.wrs_of_deviation(d, Z2), expect)


@pytest.mark.parametrize("border,w_below,w_above", [(0.5, 2.0, 4.0), (1.0, 4.0, 6.0), (1.5, 6.0, 8.0)])
def test_wrs_drops_at_zone_borders_as_documented(border, w_below, w_above):
    below = math.nextafter(border, 0.0)
    above = math.nextafter(border, math.inf)
    w = metrics.wrs_of_deviation([below, border, above], Z2)
    assert w[0] > w[1]  # it falls at the border ...
    assert w[1] == border * border / w_above  # ... the border belongs to the outer zone
    assert w[0] == pytest.approx(border * border / w_below, rel=1e-12)
    assert w[2] == pytest.approx(border * border / w_above, rel=1e-12)
    assert w[0] / w[2] == pytest.approx(w_above / w_below, rel=1e-12)


def test_wrs_saturates_at_and_beyond_d_max():
    w = metrics.wrs_of_deviation([2.0, 2.5, 100.0, -2.0, -1e9], Z2)
    np.testing.assert_array_equal(w, np.full(5, 2.0 * (2.0 / 8.0)))
    # with the paper's weights the outermost zone has w_max, so WRS is continuous at d_max
    assert metrics.wrs_of_deviation([math.nextafter(2.0, 0.0)], Z2)[0] == pytest.approx(0.5, rel=1e-12)


@pytest.mark.parametrize("half_width,weights", [
    (3.0, [1.0, 2.0, 3.0]),            # 3 zones of width 1
    (4.0, [1.0, 3.0, 2.0, 5.0, 7.0, 0.5, 9.0, 4.0]),  # 8 zones of width 0.5, unsorted weights
    (1.5, [10.0, 1.0, 5.0]),           # w_max is not the last zone's weight
    (1.0, [3.0]),                      # a single zone
])
def test_custom_risk_zones_match_paper_formula(half_width, weights):
    z = RiskZones(half_width=half_width, weights=weights)
    assert z.half_width == half_width and list(z.weights) == weights
    d = _deviations_to_probe(half_width, len(weights), rng(11))
    np.testing.assert_allclose(metrics.wrs_of_deviation(d, z),
                               [paper_wrs(x, half_width, weights) for x in d], rtol=1e-15, atol=0.0)
    # beyond d_max: d_max·d_max/w_max, with w_max the largest weight wherever it is
    assert metrics.wrs_of_deviation([10 * half_width], z)[0] == half_width * (half_width / max(weights))


def test_custom_risk_zones_non_dyadic_width_random_deviations():
    # zone widths that are not binary fractions: compare away from the borders only
    z = RiskZones(half_width=0.7, weights=[2.0, 4.0, 6.0, 8.0, 10.0])
    d = rng(12).uniform(-1.0, 1.0, 5000)
    np.testing.assert_allclose(metrics.wrs_of_deviation(d, z),
                               [paper_wrs(x, 0.7, [2.0, 4.0, 6.0, 8.0, 10.0]) for x in d], rtol=1e-15, atol=0.0)


@pytest.mark.parametrize("kwargs", [
    dict(half_width=0.0), dict(half_width=-1.0), dict(half_width=math.inf), dict(half_width=math.nan),
    dict(weights=[]), dict(weights=[2.0, 0.0]), dict(weights=[2.0, -4.0]), dict(weights=[math.nan]),
])
def test_invalid_risk_zones_raise(kwargs):
    with pytest.raises(ValueError, match="RiskZones"):
        RiskZones(**kwargs)


def test_risk_zones_made_invalid_after_construction_are_rejected():
    z = RiskZones()
    z.half_width = -1.0
    with pytest.raises(ValueError, match="half_width"):
        metrics.wrs_of_deviation([0.1], z)
    with pytest.raises(ValueError, match="half_width"):
        metrics.awrs([[0.0, 1.0]], [[0.0, 0.0], [1.0, 0.0]], z)


def test_wrs_of_points_equals_wrs_of_distance_to_path():
    g = rng(13)
    path = random_walk(g, 12, step=2.0)
    points = path[g.integers(0, len(path), 400)] + g.normal(scale=1.2, size=(400, 2))
    for zones in (Z2, RiskZones(half_width=3.0, weights=[1.0, 2.0, 3.0])):
        d = metrics.distance_to_path(points, path)
        np.testing.assert_array_equal(metrics.wrs(points, path, zones), metrics.wrs_of_deviation(d, zones))
        # and the whole chain against the paper formula
        hw, ws = (2.0, PAPER_WEIGHTS) if zones is Z2 else (3.0, [1.0, 2.0, 3.0])
        np.testing.assert_allclose(metrics.wrs(points, path, zones), [paper_wrs(x, hw, ws) for x in d],
                                   rtol=1e-15, atol=0.0)
    # the probe covers every zone and the saturated region
    assert (d < 0.5).any() and ((d >= 1.5) & (d < 2.0)).any() and (d >= 2.0).any()


def test_awrs_is_mean_of_wrs():
    g = rng(14)
    path = random_walk(g, 8, step=3.0)
    points = path[g.integers(0, len(path), 250)] + g.normal(scale=1.0, size=(250, 2))
    for zones in (None, RiskZones(half_width=1.5, weights=[10.0, 1.0, 5.0])):
        w = metrics.wrs(points, path, zones)
        assert metrics.awrs(points, path, zones) == pytest.approx(np.mean(w), rel=1e-12)
    hw = RiskZones().half_width  # the default zones
    ref = np.mean([paper_wrs(x, hw) for x in metrics.distance_to_path(points, path)])
    assert metrics.awrs(points, path) == pytest.approx(ref, rel=1e-12)


def test_evaluate_combines_the_metrics_and_uses_truth_as_default_central_path():
    g = rng(15)
    truth = random_walk(g, 60)
    est = truth + g.normal(scale=0.8, size=truth.shape)
    m = metrics.evaluate(est, truth)
    assert m.ade == metrics.ade(est, truth)
    assert m.fde == metrics.fde(est, truth)
    assert m.path_length_error_percent == metrics.path_length_error_percent(est, truth)
    assert m.awrs == metrics.awrs(est, truth)
    other = truth + np.array([0.0, 1.0])
    assert metrics.evaluate(est, truth, path=other).awrs == metrics.awrs(est, other)
    assert set(m.as_dict()) == {"ade", "fde", "awrs", "path_length_error_percent"}


@pytest.mark.parametrize("seed", [16, 17])
def test_distance_to_path_vs_dense_brute_force(seed):
    g = rng(seed)
    path = random_walk(g, 7, step=5.0)
    path = np.vstack([path, path[-1]])  # a repeated vertex: a zero-length segment
    lo, hi = path.min(axis=0) - 5.0, path.max(axis=0) + 5.0
    points = g.uniform(lo, hi, size=(150, 2))
    samples, spacing = dense_polyline_samples(path, 100_000)
    brute = brute_force_distance(points, samples)
    ours = metrics.distance_to_path(points, path)
    assert ours.shape == (150,)
    # the true distance is at most the sampled one, and at most half a sample spacing below it
    assert np.all(ours <= brute + 1e-12)
    assert np.all(brute - ours <= spacing / 2 + 1e-12)


def test_distance_to_path_exact_where_nearest_point_is_a_vertex():
    path = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [1.0, 7.0]])
    points = np.array([
        [-1.0, -2.0],   # behind the first vertex
        [-3.0, 0.0],    # on the first segment's extension
        [5.0, -1.0],    # outside the convex corner at (4, 0)
        [6.0, -2.0],
        [6.0, 4.0],     # outside the corner at (4, 3) (between the two segment normals)
        [0.0, 9.0],     # beyond the last vertex
        [4.0, 0.0],     # on a vertex
    ])
    nearest = np.array([[0, 0], [0, 0], [4, 0], [4, 0], [4, 3], [1, 7], [4, 0]], dtype=float)
    assert np.all(brute_force_distance(points, dense_polyline_samples(path, 10_001)[0])
                  >= np.hypot(*(points - nearest).T) - 1e-12)  # the fixture's nearest points are right
    expect = np.hypot(*(points - nearest).T)
    np.testing.assert_array_equal(metrics.distance_to_path(points, path), expect)
    # end vertices of a path with non-integer coordinates, approached along the end segments' extensions
    path = np.array([[0.1, 0.2], [3.3, 0.7], [5.9, 4.1], [2.2, 6.6]])
    tangent_first = path[0] - path[1]
    tangent_last = path[-1] - path[-2]
    p = np.array([path[0] + 0.7 * tangent_first, path[-1] + 1.3 * tangent_last])
    np.testing.assert_allclose(metrics.distance_to_path(p, path),
                               [0.7 * np.hypot(*tangent_first), 1.3 * np.hypot(*tangent_last)], rtol=1e-13)


def test_distance_to_path_perpendicular_feet_and_degenerate_paths():
    path = np.array([[0.0, 0.0], [10.0, 0.0]])
    x = np.linspace(0.0, 10.0, 11)
    pts = np.column_stack([x, np.full_like(x, -2.5)])
    np.testing.assert_array_equal(metrics.distance_to_path(pts, path), np.full(11, 2.5))
    # a single-vertex path is a point
    np.testing.assert_array_equal(metrics.distance_to_path([[3.0, 4.0], [0.0, 0.0]], [[0.0, 0.0]]), [5.0, 0.0])
    # all vertices equal
    np.testing.assert_array_equal(metrics.distance_to_path([[3.0, 4.0]], [[0.0, 0.0]] * 3), [5.0])
    # no points: empty result
    assert metrics.distance_to_path(np.empty((0, 2)), path).shape == (0,)


# --------------------------------------------------------------------------- 3. ADE / FDE / % path error

@pytest.mark.parametrize("seed", [20, 21, 22])
def test_ade_fde_path_error_vs_numpy(seed):
    g = rng(seed)
    n = int(g.integers(2, 300))
    truth = g.normal(scale=10.0, size=(n, 2))
    est = truth + g.normal(scale=2.0, size=(n, 2))
    err = np.sqrt(((est - truth) ** 2).sum(axis=1))
    assert metrics.ade(est, truth) == pytest.approx(err.mean(), rel=1e-12)
    assert metrics.fde(est, truth) == pytest.approx(err[-1], rel=1e-12)
    lt = np.sqrt((np.diff(truth, axis=0) ** 2).sum(axis=1)).sum()
    le = np.sqrt((np.diff(est, axis=0) ** 2).sum(axis=1)).sum()
    assert metrics.path_length_error_percent(est, truth) == pytest.approx(abs(le - lt) / lt * 100, rel=1e-12)


def test_ade_single_point_and_identity():
    assert metrics.ade([[1.0, 2.0]], [[4.0, 6.0]]) == 5.0
    t = random_walk(rng(23), 50)
    assert metrics.ade(t, t) == 0.0 and metrics.fde(t, t) == 0.0
    assert metrics.path_length_error_percent(t, t) == 0.0


def test_ade_rejects_different_lengths_naming_both():
    g = rng(24)
    with pytest.raises(ValueError, match=r"(?s)(?=.*\b5\b)(?=.*\b7\b)"):
        metrics.ade(g.normal(size=(5, 2)), g.normal(size=(7, 2)))
    with pytest.raises(ValueError, match=r"(?s)(?=.*\b12\b)(?=.*\b3\b)"):
        metrics.ade(g.normal(size=(3, 2)), g.normal(size=(12, 2)))


def test_fde_and_path_error_accept_different_lengths():
    g = rng(25)
    truth = random_walk(g, 40)
    est = random_walk(g, 55)
    assert metrics.fde(est, truth) == pytest.approx(np.hypot(*(est[-1] - truth[-1])), rel=1e-12)
    lt = np.hypot(*np.diff(truth, axis=0).T).sum()
    le = np.hypot(*np.diff(est, axis=0).T).sum()
    assert metrics.path_length_error_percent(est, truth) == pytest.approx(abs(le - lt) / lt * 100, rel=1e-12)
    # a shorter estimate: |L_est − L_true| uses the absolute value
    assert metrics.path_length_error_percent(est[:3], truth) == pytest.approx(
        abs(np.hypot(*np.diff(est[:3], axis=0).T).sum() - lt) / lt * 100, rel=1e-12)


@pytest.mark.parametrize("truth", [[[1.0, 1.0]], [[2.0, 3.0], [2.0, 3.0], [2.0, 3.0]]])
def test_path_error_of_zero_length_truth_raises(truth):
    with pytest.raises(ValueError, match="zero length"):
        metrics.path_length_error_percent([[0.0, 0.0], [1.0, 0.0]], truth)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("col", [0, 1])
def test_non_finite_points_raise_naming_the_index(bad, col):
    g = rng(26)
    a = g.normal(size=(6, 2))
    b = g.normal(size=(6, 2))
    k = 4

    def poisoned(x):
        x = x.copy()
        x[k, col] = bad
        return x

    where = rf"\[\({k}, {col}\)\]"
    cases = [
        (lambda: metrics.ade(poisoned(a), b), "estimate"),
        (lambda: metrics.ade(a, poisoned(b)), "truth"),
        (lambda: metrics.fde(poisoned(a), b), "estimate"),
        (lambda: metrics.fde(a, poisoned(b)), "truth"),
        (lambda: metrics.path_length_error_percent(poisoned(a), b), "estimate"),
        (lambda: metrics.path_length_error_percent(a, poisoned(b)), "truth"),
        (lambda: metrics.path_length(poisoned(a)), "path"),
        (lambda: metrics.distance_to_path(poisoned(a), b), "points"),
        (lambda: metrics.distance_to_path(a, poisoned(b)), "path"),
        (lambda: metrics.wrs(poisoned(a), b), "points"),
        (lambda: metrics.wrs(a, poisoned(b)), "path"),
        (lambda: metrics.awrs(poisoned(a), b), "points"),
        (lambda: metrics.awrs(a, poisoned(b)), "path"),
        (lambda: metrics.evaluate(poisoned(a), b), "estimate"),
        (lambda: metrics.evaluate(a, poisoned(b)), "truth"),
        (lambda: metrics.evaluate(a, b, path=poisoned(b)), "path"),
    ]
    for call, name in cases:
        with pytest.raises(ValueError, match=rf"{name}{where}"):
            call()
    d = np.linspace(0.0, 1.0, 6)
    d[k] = bad
    with pytest.raises(ValueError, match=rf"deviation\[{k}\]"):
        metrics.wrs_of_deviation(d)
