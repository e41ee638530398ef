"""The method's nominal trajectory (Navigator/Guidance.nominal_trajectory) and
the belief along it (propagate_belief_along; docs/belief_planning.md, "Along
the nominal trajectory").

References: the trajectory against SafeNav Algorithms 1 and 2's own controls
(centroid_control, chull_control) stepped through the BMM's noise-free
transition [SafeNav eqs. 3-9], and against the truth of a noise-free trial of
the simulator; the belief against FilterPy's KalmanFilter driven by numpy
Jacobians of the BMM at each state and control [SafeNav eqs. 3, 4, 7, 9, 11],
with visibility from each state's pose by SensorSettings.landmarks_in_view."""
from __future__ import annotations

import numpy as np
import pytest

from safenav import _core
from safenav import guidance as gd
from safenav import navigation as nv
from safenav import planning as P
from test_belief import open_map, profile_cov, reference_covariances, reference_mixture, sensors
from test_navigation import BEND, build, parts

METHODS = ["chull", "centroid"]


@pytest.mark.parametrize("circles", [(), [(28.0, 7.5, 0.5)]], ids=["open", "obstacle inside the bend"])
@pytest.mark.parametrize("method", METHODS)
def test_nominal_trajectory_is_the_methods_control_on_the_noise_free_bmm(method, circles):
    navigator = build(BEND, method=method, circles=circles)
    x = np.asarray(navigator.nominal_trajectory())
    if circles and method == "chull":  # the obstacle shortens CHull's look-ahead: the run keeps wider
        open_run = np.asarray(build(BEND, method=method).nominal_trajectory())
        assert len(open_run) != len(x) or not np.array_equal(open_run, x)
    st = navigator.settings
    bmm = _core.Bmm(navigator.problem.bmm)
    # A trial's true start: the path's first vertex, at rest, heading along the first edge.
    np.testing.assert_array_equal(x[0], [*BEND[0], 0.0, 0.0])
    checker = _core.ObstacleChecker(navigator.problem.map)
    for k in range(len(x) - 1):
        if method == "centroid":
            u = nv.centroid_control(navigator.segments, x[k], st.cruise_speed)
        else:
            u = nv.chull_control(navigator.segments, bmm, x[k], st.cruise_speed, st.lookahead, st.step_back_speed,
                                 checker).control
        np.testing.assert_array_equal(x[k + 1], bmm.predict(x[k], u))
        assert np.linalg.norm(x[k, :2] - BEND[-1]) > st.arrival_radius  # it stops on arrival, not before
    assert np.linalg.norm(x[-1, :2] - BEND[-1]) <= st.arrival_radius
    assert len(x) - 1 < navigator.max_steps


@pytest.mark.parametrize("method", METHODS)
def test_nominal_trajectory_is_what_a_noise_free_trial_drives(method):
    navigator = build(BEND, method=method, noise=False)
    x = np.asarray(navigator.nominal_trajectory())
    trial = navigator.run(seed=3)
    assert trial.success, trial.reason
    truth = np.asarray(trial.truth)
    n = min(len(x), len(truth))
    assert abs(len(x) - len(truth)) <= 1
    # The trial's estimate is off the truth by its 1e-6 sensors' noise only.
    np.testing.assert_allclose(truth[:n], x[:n], atol=1e-3)


def test_guidance_nominal_trajectory_takes_its_step_limit():
    problem, s, se = parts(BEND)
    g = gd.Guidance(problem, s, gd.localizer_settings(), se.landmarks, list(range(len(se.landmarks))))
    full = np.asarray(g.nominal_trajectory(100000))
    np.testing.assert_array_equal(full, build(BEND).nominal_trajectory())
    np.testing.assert_array_equal(g.nominal_trajectory(5), full[:6])
    np.testing.assert_array_equal(g.nominal_trajectory(0), full[:1])
    with pytest.raises(ValueError, match="max_steps = -1"):
        g.nominal_trajectory(-1)


# --------------------------------------------------------------------------- the belief along it

def trajectory_stage(states, bmm):
    """Stage k's (F, G, camera heading) from the states: the BMM [SafeNav eqs. 3, 4, 7, 9] from
    state k-1 under the control that reaches state k (the speed reached, the heading change),
    by its equations: x' = x + c v' cos th', y' = y + c v' sin th', v' = v +- a dt unless a
    limit binds (then dv'/dv = 0), th' = th + dth; c = dt / (1 + terrain effect)."""
    c = bmm.dt / (1.0 + bmm.terrain_effect)

    def stage(k):
        v, v1, th1 = states[k - 1, 2], states[k, 2], states[k, 3]
        ramp = np.isclose(v1, v + bmm.acceleration * bmm.dt, rtol=0, atol=1e-12) or np.isclose(
            v1, v - bmm.deceleration * bmm.dt, rtol=0, atol=1e-12)
        dv = 1.0 if ramp and v1 > 0 else 0.0
        cs, sn = np.cos(th1), np.sin(th1)
        F = np.eye(4)
        F[2, 2] = dv
        F[0, 2], F[1, 2] = c * cs * dv, c * sn * dv
        F[0, 3], F[1, 3] = -c * v1 * sn, c * v1 * cs
        G = np.eye(4)
        G[0, 2], G[1, 2] = c * cs, c * sn
        G[0, 3], G[1, 3] = -c * v1 * sn, c * v1 * cs
        return F, G, th1

    return stage


def bend_world():
    """A bend driven from rest, with landmarks that come into view only as the vehicle turns
    (a narrow camera) and a wall that hides one of them for a while."""
    lms = [[34.0, 18.0], [38.0, 24.0], [26.0, 26.0], [33.0, 44.0], [12.0, 1.0]]
    se = sensors(lms, max_range=20.0, fov=np.deg2rad(60))
    m = open_map(upper=(60, 50), polygons=[[(35.0, 10.0), (37.0, 10.0), (37.0, 14.0), (35.0, 14.0)]])
    return se, m


@pytest.mark.parametrize("method, nodes, along", [(m, n, False) for m in METHODS for n in (0, 3)]
                         + [("chull", 7, False), ("chull", 3, True), ("centroid", 3, True)])
def test_belief_along_the_trajectory_equals_filterpy(method, nodes, along):
    se, m = bend_world()
    x = np.asarray(build(BEND, method=method).nominal_trajectory())
    bmm = _core.BmmParams()
    P0 = np.diag([0.3, 0.2, 0.003, 0.001])
    prof = P.propagate_belief_along(x, sensors=se, map=m, bmm=bmm, start_cov=P0, deviation_mixture=nodes > 0,
                                    deviation_nodes=max(nodes, 3), deviation_along=along, deviation_split=False)
    np.testing.assert_array_equal(prof.positions, x[:, :2])
    np.testing.assert_allclose(prof.time, np.arange(len(x)) * bmm.dt, rtol=1e-12)
    checker = _core.ObstacleChecker(m)
    # What each stage sees is what a vehicle at that state sees (the simulator's rule).
    np.testing.assert_array_equal(prof.landmarks, [se.landmarks_in_view(s, checker) for s in x])
    assert 0 < prof.landmarks.max() and prof.landmarks.min() == 0
    stage = trajectory_stage(x, bmm)
    ref = (reference_mixture(prof, bmm, se, P0, 0.0, checker, stage=stage, nodes=nodes, along=along) if nodes
           else reference_covariances(prof, bmm, se, P0, 0.0, checker, stage=stage))
    np.testing.assert_allclose(profile_cov(prof), ref, rtol=1e-9, atol=1e-15)


def test_a_straight_run_at_cruise_is_the_belief_along_its_path():
    bmm = _core.BmmParams()
    v = 2.0
    n = 300
    step = v * bmm.dt / (1.0 + bmm.terrain_effect)
    x = np.c_[5.0 + step * np.arange(n + 1), np.full(n + 1, 20.0), np.full(n + 1, v), np.zeros(n + 1)]
    se = sensors([[20.0, 25.0], [24.0, 14.0], [27.0, 22.0], [50.0, 25.0]], max_range=15.0, fov=np.deg2rad(85))
    m = open_map()
    kw = dict(sensors=se, map=m, bmm=bmm, start_cov=np.diag([0.5, 0.5, 0.003, 0.001]))
    along = P.propagate_belief_along(x, **kw)
    path = P.propagate_belief(x[[0, -1], :2], speed=v / (1.0 + bmm.terrain_effect), **kw)
    assert len(path.sigma) == len(along.sigma)
    np.testing.assert_allclose(along.positions, path.positions, atol=1e-9)
    np.testing.assert_allclose(profile_cov(along), profile_cov(path), rtol=1e-9, atol=1e-15)


def test_coarser_steps_keep_the_trajectorys_end_and_time():
    se, m = bend_world()
    x = np.asarray(build(BEND, method="centroid").nominal_trajectory())
    bmm = _core.BmmParams()
    prof = P.propagate_belief_along(x, sensors=se, map=m, bmm=bmm, step=0.25)
    every = round(0.25 / bmm.dt)
    np.testing.assert_array_equal(prof.positions[:-1], x[::every, :2][:len(prof.positions) - 1])
    np.testing.assert_array_equal(prof.positions[-1], x[-1, :2])
    assert prof.time[-1] == pytest.approx((len(x) - 1) * bmm.dt)


@pytest.mark.parametrize("states, match", [
    (np.zeros((1, 4)), "1 rows"),
    (np.array([[0.0, 0.0, 1.0, 0.0], [1.0, np.nan, 1.0, 0.0]]), r"states\[\(1, 1\)\] = nan"),
    (np.zeros((3, 2)), "states"),
])
def test_bad_trajectories_name_the_value(states, match):
    se, m = bend_world()
    with pytest.raises(ValueError, match=match):
        P.propagate_belief_along(states, sensors=se, map=m, start_cov=np.eye(4))


def test_the_cores_check_names_the_bad_state():
    se, m = bend_world()
    x = np.array([[0.0, 0.0, 1.0, 0.0], [1.0, 0.0, 1.0, np.inf], [2.0, 0.0, 1.0, 0.0]])
    with pytest.raises(ValueError, match="belief trajectory state 1.theta = inf is not finite"):
        _core.propagate_belief_along(x, _core.BmmParams(), se, m, np.eye(4))
    with pytest.raises(ValueError, match="has 1 states: needs >= 2"):
        _core.propagate_belief_along(x[:1], _core.BmmParams(), se, m, np.eye(4))
