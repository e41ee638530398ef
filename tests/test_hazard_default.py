"""Hazards by default in our loop: the scenario's planner has a hazard term
(``planner.hazard_weight`` = 5), the papers' configuration plans without it
(``paper=True``: ``--loop paper``, the experiments), and the exposure that
no path can avoid (a start or destination inside a hazard) is computed apart:
:func:`safenav.planning.unavoidable_exposure`, checked against exact
geometry and against the exposure of paths (``path_safety``)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from safenav import planning
from safenav.navigation import plan_safe_path
from safenav.planning import HazardZone, make_map, path_safety, unavoidable_exposure
from safenav.scenario import default_scenario


def test_our_paths_avoid_hazards_and_the_papers_keep_theirs():
    sc = default_scenario()
    assert sc.planner.hazard_weight == 5.0
    no_hazard_term = replace(sc, planner=replace(sc.planner, hazard_weight=0.0))
    hazards = planning.map_from_world(sc.world)
    for name in ("P1", "P2", "P3"):
        ours, paper = plan_safe_path(sc, name), plan_safe_path(sc, name, paper=True)
        # the papers' path is RAw-RRT* with the paper's cost, bit for bit
        np.testing.assert_array_equal(np.asarray(paper.path), np.asarray(plan_safe_path(no_hazard_term, name).path))
        assert ours.safety.exposure < paper.safety.exposure, name
        gt = sc.path_polyline(name)
        assert ours.safety.exposure >= unavoidable_exposure(gt[0], gt[-1], hazards) - 1e-9


def _rect(x0, y0, w, h, risk):
    return HazardZone.from_polygon([[x0, y0], [x0 + w, y0], [x0 + w, y0 + h], [x0, y0 + h]], risk)


@settings(max_examples=150, deadline=None)
@given(w=st.floats(1, 30), h=st.floats(1, 30), u=st.floats(0, 1), v=st.floats(0, 1), risk=st.floats(0.05, 1),
       circle=st.booleans())
def test_the_bound_is_the_depth_and_a_straight_exit_attains_it(w, h, u, v, risk, circle):
    if circle:
        hz = HazardZone.from_circle(np.array([0.0, 0.0]), w, risk)
        p = np.array([u * w * 0.999 * np.cos(6.28 * v), u * w * 0.999 * np.sin(6.28 * v)])
        depth = w - np.hypot(*p)
        out = p / np.hypot(*p) if np.hypot(*p) > 1e-9 else np.array([1.0, 0.0])   # at the centre: any way out
        exit_point = p + out * (depth + 1e-6)
    else:
        hz = _rect(0.0, 0.0, w, h, risk)
        p = np.array([u * w, v * h])
        gaps = [p[0], w - p[0], p[1], h - p[1]]                      # exact distances to the four sides
        depth = min(gaps)
        k = int(np.argmin(gaps))
        step = [(-1, 0), (1, 0), (0, -1), (0, 1)][k]
        exit_point = p + np.array(step) * (depth + 1e-6)
    m = make_map(lower=(-100, -100), upper=(100, 100), hazards=[hz])
    far = np.array([90.0, 90.0])
    bound = unavoidable_exposure(p, far, m)
    assert bound == pytest.approx(risk * depth, rel=1e-9, abs=1e-12)
    # the straight way out takes exactly that much; a path to anywhere takes at least it
    assert path_safety(np.array([p, exit_point]), m).exposure == pytest.approx(risk * depth, rel=1e-6, abs=1e-6)
    assert path_safety(np.array([p, far]), m).exposure >= bound - 1e-9
    # start and goal both inside: the straight segment between them is allowed
    q = p * 0.5 + (np.array([w, h]) * 0.5 if not circle else 0.0) * 0.5
    both = unavoidable_exposure(p, q, m)
    assert both <= path_safety(np.array([p, q]), m).exposure + 1e-9
    assert unavoidable_exposure(far, -far, m) == 0.0                  # outside: nothing is forced
