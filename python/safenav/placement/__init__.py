"""Landmark placement for guaranteed observability (the landmark placement paper).

A vehicle with a forward camera (range ``R``, viewing angle ``α``) follows a
route; a bearing-only filter is observable only while at least two landmarks
are in view.  Given candidate landmark locations, place the fewest landmarks
so that every point of the route sees at least ``k`` (the paper: 2), no
landmark is within ``p`` of the route and no two chosen landmarks lie on one
bearing from the camera.

Numbers in this package are the placement paper's (tag ``Placement`` in
``docs/paper_map.md``); its Algorithm 1 is not SafeNav's.

* :func:`place_along_route` — the paper's algorithm [Placement §II]: per edge
  the rigid transform to ``(0,0) → (d,0)``, the visibility interval
  ``[t_s, t_d]`` of every candidate [Placement Lemma 2] ([Placement Cor. 1]
  for a circular field of view, typo fixed), the greedy k-interval cover
  [Placement Alg. 1] (optimal per edge by [Placement Prop. 1]), then the
  union over edges.  Options: ``corners``
  (cover the in-place turn at every vertex, the paper's future work),
  ``reuse`` (an edge counts landmarks placed for earlier edges).
* :func:`place_optimal` — the global optimum over the whole route: an integer
  program (``scipy.optimize.milp``, HiGHS) with one coverage row per interval
  endpoint, alignment point and gap between them, which is exact because the
  number of landmarks in view is constant between those points.
* :func:`place_through_targets` — a route through targets first (open tour
  from the first to the last target, 2-opt + Or-opt; see :func:`plan_tour`).
* :func:`place_along_path` — the same for a SafeNav safe path (a polyline,
  e.g. :meth:`safenav.World.path_polyline` or a planner's path).
* Occlusion (ours; the paper has no obstacles): every entry point takes
  ``obstacles=`` (a :class:`safenav.World`, a dict of circles and polygons,
  see :func:`occluders`); a candidate an obstacle hides from part of an
  edge does not cover that part.
* :func:`simulate` — [Placement §III-A]: a ground robot at 0.2 m/s with
  a heading controller, bearings to the landmarks in view, and the extended
  information filter (:class:`safenav.InformationFilter`).
* :func:`table_one` — [Placement Table I] on fresh random instances.

The heavy lifting is in the C++ core (``safenav._core``: ``place_landmarks``,
``edge_visibility``, ``alignments``, ``check_coverage``).

The package: :mod:`~safenav.placement.algorithm` (camera, greedy, ILP,
coverage check), :mod:`~safenav.placement.tour` (the route through the
targets), :mod:`~safenav.placement.study` ([Placement Table I] and the
[Placement §III-A] simulation), :mod:`~safenav.placement.plots` (figures) and
:mod:`~safenav.placement.cli` (``safenav place``).
"""

from .algorithm import (PAPER_AREA, PAPER_SPACING, CameraParams, PlacementResult, candidate_grid, check_coverage,
                        occluders, place_along_path, place_along_route, place_optimal, place_through_targets)
from .plots import paper_figures, plot_corner_gap, plot_placement, plot_simulation
from .study import PAPER_TABLE_ONE, SimulationResult, corner_gap_demo, random_instance, simulate, table_one
from .tour import plan_tour, tour_length

__all__ = [
    "CameraParams", "PlacementResult", "SimulationResult", "PAPER_TABLE_ONE", "PAPER_AREA", "PAPER_SPACING",
    "candidate_grid", "occluders", "plan_tour", "tour_length", "place_along_route", "place_through_targets",
    "place_along_path", "place_optimal", "check_coverage", "simulate", "random_instance",
    "table_one", "corner_gap_demo", "plot_placement", "plot_simulation", "plot_corner_gap", "paper_figures",
]
