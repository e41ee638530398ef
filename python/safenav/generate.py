"""Seeded generator for SafeNav's real-imitated world [SafeNav-ext §V-A3(ii), Fig. 1].

[SafeNav-ext §V-A3(ii)] is [SafeNav-conf §V-A.2(ii)]; the conference has no
figure of the field (its Fig. 1 is the framework).

The paper maps real landmarks into a 200×200 grid, adds 25 obstacles and 25
hazards at random, keeps landmark clusters with at least three landmarks within
detection range, and follows path clusters through cluster centroids.  Three
path types start at different clusters and share one destination: P1 is
cluster 6 → 3, P2 is 4 → 3 and P3 is 7 → 3.  The paper does not publish its
map, so this generator makes one of the same kind.  Our decisions:

* **Clusters.** Nine clusters sit at fixed nominal places (scaled to the field)
  chosen so that the paper's path types exist: P1 = 6 → 5 → 2 → 3 from the
  south-west, P2 = 4 → 1 → 8 → 3 from the north-west (the most turns; the
  paper finds P2 the hardest), P3 = 7 → 9 → 3 from the south-east; cluster 3
  (north-east) is the common destination.  Each nominal place is jittered by
  up to ``cluster_jitter``.
* **Landmarks.** Each cluster gets ``landmarks_per_cluster`` landmarks (3–6)
  spread around its place at evenly spaced, jittered bearings and distances in
  ``landmark_radius``, with heights in ``landmark_height`` (3D positions).  A
  cluster is redrawn until every landmark is within ``detection_range`` (3D
  distance) of the cluster centroid, so all of them serve trilateration there.
* **Obstacles.** ``n_blocking`` of them are placed *across* the straight
  centroid polylines, in the middle part of a segment (never near a centroid),
  so that RAw-RRT* has to replan (round-robin over the path types, so every
  path gets at least one when ``n_blocking`` >= 3); at most ``max_blocked_fraction`` of any
  path's length may lie inside obstacles.  The others are placed anywhere
  clear of the polylines; some end up inside the safe buffer by chance.
  Obstacles are circles or star-shaped polygons (simple by construction), lie
  wholly inside the field, keep ``obstacle_gap`` between each other's bounding
  circles (so no wall of obstacles can cut a path off), and keep
  ``landmark_clearance`` from every landmark and ``centroid_clearance`` from
  every cluster centroid (the start, the destination and the waypoints stay free).
* **Hazards.** Circles or polygons anywhere in the field with risk levels
  0.25, 0.5, 0.75 or 1.0 (our scale; the paper gives none), never covering a
  landmark.  They may overlap paths and obstacles: they are risk, not walls.
* Coordinates are rounded to millimetres so that the file reads well.

The same seed and configuration give an identical world (NumPy's PCG64).
Regenerate the shipped default with ``python -m safenav.generate``.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass

import numpy as np

from . import _core
from .validation import FIELD_SIZE, MAX_HAZARDS, MAX_LANDMARKS, MAX_OBSTACLES, cut
from .world import Circle, Field, Hazard, Landmark, PathType, Polygon, World

__all__ = ["GeneratorConfig", "generate_world", "generate_scenario", "PAPER_PATH_TYPES",
           "CLUSTER_LAYOUT", "DEFAULT_SEED"]

#: Nominal cluster places on a 200×200 field (scaled to other sizes).
CLUSTER_LAYOUT: dict[int, tuple[float, float]] = {
    1: (72.0, 135.0),
    2: (112.0, 122.0),
    3: (170.0, 170.0),
    4: (28.0, 168.0),
    5: (78.0, 58.0),
    6: (28.0, 28.0),
    7: (174.0, 26.0),
    8: (118.0, 168.0),
    9: (146.0, 84.0),
}

#: The paper's path types: different origins (6, 4, 7), one destination (3).
PAPER_PATH_TYPES: tuple[PathType, ...] = (
    PathType("P1", (6, 5, 2, 3)),
    PathType("P2", (4, 1, 8, 3)),
    PathType("P3", (7, 9, 3)),
)

#: The seed of the shipped default scenario.
DEFAULT_SEED = 7

_CLASSES = ("tower", "building", "water_tank", "bridge", "monument", "tree", "rock", "antenna")
_RISK_LEVELS = (0.25, 0.5, 0.75, 1.0)


@dataclass(frozen=True)
class GeneratorConfig:
    """Knobs of :func:`generate_world`; the defaults give the paper's real-imitated world."""

    size: float = 200.0                                  #: field side [m] (paper: 200)
    n_obstacles: int = 25                                #: paper: 25
    n_hazards: int = 25                                  #: paper: 25
    n_blocking: int = 5                                  #: obstacles placed across the polylines
    landmarks_per_cluster: tuple[int, int] = (3, 6)      #: inclusive range
    landmark_radius: tuple[float, float] = (5.0, 14.0)   #: distance from the cluster's place [m]
    landmark_height: tuple[float, float] = (1.0, 10.0)   #: z [m]
    cluster_jitter: float = 6.0                          #: [m]
    detection_range: float = 30.0                        #: every landmark within this of its centroid [m]
    obstacle_radius: tuple[float, float] = (3.0, 9.0)    #: bounding radius of free obstacles [m]
    blocking_radius: tuple[float, float] = (3.0, 6.0)    #: bounding radius of blocking obstacles [m]
    hazard_radius: tuple[float, float] = (4.0, 12.0)     #: [m]
    obstacle_gap: float = 4.0                            #: between obstacles' bounding circles [m]
    landmark_clearance: float = 2.0                      #: obstacle/hazard edge to landmark [m]
    centroid_clearance: float = 6.0                      #: obstacle edge to cluster centroid [m]
    path_clearance: float = 1.0                          #: free obstacles to the polylines [m]
    max_blocked_fraction: float = 0.12                   #: of each path's length inside obstacles
    max_tries: int = 20000

    def __post_init__(self):
        lo, hi = FIELD_SIZE
        if isinstance(self.size, bool) or not isinstance(self.size, (int, float)) or not lo <= self.size <= hi:
            raise ValueError(f"size = {cut(self.size)}: must be a number in [{lo:g}, {hi:g}] m (a scenario's field size)")
        for n, hi in (("n_obstacles", MAX_OBSTACLES), ("n_hazards", MAX_HAZARDS), ("n_blocking", MAX_OBSTACLES)):
            v = getattr(self, n)
            if not isinstance(v, int) or isinstance(v, bool) or not 0 <= v <= hi:
                raise ValueError(f"{n} = {cut(v)}: must be an integer in [0, {hi}] (a scenario's limit)")
        if self.n_blocking > self.n_obstacles:
            raise ValueError(f"n_blocking = {self.n_blocking}: must be <= n_obstacles = {self.n_obstacles}")
        lo, hi = self.landmarks_per_cluster
        top = MAX_LANDMARKS // len(CLUSTER_LAYOUT)
        if not (3 <= lo <= hi <= top):
            raise ValueError(f"landmarks_per_cluster = {cut(self.landmarks_per_cluster)}: need 3 <= min <= max <= {top}")


def _round(x) -> float:
    return round(float(x), 3)


def _make_shape(rng: np.random.Generator, center: np.ndarray, radius: float) -> Circle | Polygon:
    """A circle, a rotated rectangle or a star-shaped polygon whose bounding radius is ``radius``."""
    kind = rng.integers(3)
    if kind == 0:
        return Circle((_round(center[0]), _round(center[1])), _round(radius))
    if kind == 1:
        ang = rng.uniform(0.25, 0.45) * math.pi          # half-diagonal angle: aspect ratio
        base = rng.uniform(0, math.pi)
        angles = base + np.array([ang, math.pi - ang, math.pi + ang, 2 * math.pi - ang])
        radii = np.full(4, radius)
    else:
        n = int(rng.integers(5, 9))
        # keep bearings apart so the star polygon stays well shaped
        angles = np.linspace(0, 2 * math.pi, n, endpoint=False) + rng.uniform(-0.25, 0.25, n) * (2 * math.pi / n)
        angles += rng.uniform(0, 2 * math.pi)
        radii = radius * rng.uniform(0.55, 1.0, n)
        radii[int(rng.integers(n))] = radius
    verts = tuple((_round(center[0] + r * math.cos(a)), _round(center[1] + r * math.sin(a)))
                  for a, r in zip(angles, radii))
    return Polygon(verts)


def _polyline_distance(points: np.ndarray, polylines: list[np.ndarray]) -> np.ndarray:
    """Distance of each point to the nearest of the polylines (the core's eq. 17 deviation)."""
    return np.min([_core.distance_to_path(points, pl) for pl in polylines], axis=0)


def _dense(polyline: np.ndarray, step: float = 0.25) -> np.ndarray:
    out = []
    for a, b in zip(polyline[:-1], polyline[1:]):
        n = max(2, int(math.ceil(np.linalg.norm(b - a) / step)) + 1)
        out.append(a + np.linspace(0, 1, n)[:, None] * (b - a))
    return np.vstack(out)


def _clusters(rng: np.random.Generator, cfg: GeneratorConfig) -> list[Landmark]:
    scale = cfg.size / 200.0
    landmarks: list[Landmark] = []
    next_id = 1
    for cid in sorted(CLUSTER_LAYOUT):
        nominal = np.array(CLUSTER_LAYOUT[cid]) * scale
        center = nominal + rng.uniform(-cfg.cluster_jitter, cfg.cluster_jitter, 2) * scale
        for _ in range(cfg.max_tries):
            n = int(rng.integers(cfg.landmarks_per_cluster[0], cfg.landmarks_per_cluster[1] + 1))
            bearing = (np.linspace(0, 2 * math.pi, n, endpoint=False) + rng.uniform(0, 2 * math.pi)
                       + rng.uniform(-0.3, 0.3, n) * (2 * math.pi / n))
            dist = rng.uniform(*cfg.landmark_radius, n) * scale
            xy = center + np.c_[np.cos(bearing), np.sin(bearing)] * dist[:, None]
            xy = np.round(xy, 3)
            z = np.round(rng.uniform(*cfg.landmark_height, n), 3)
            c = xy.mean(axis=0)
            inside = (xy >= 0).all() and (xy <= cfg.size).all()
            if inside and np.all(np.sqrt(np.sum((xy - c) ** 2, axis=1) + z ** 2) <= cfg.detection_range):
                break
        else:
            raise RuntimeError(f"cluster {cid}: no landmark layout within detection range after {cfg.max_tries} tries")
        for k in range(n):
            cls = _CLASSES[int(rng.integers(len(_CLASSES)))]
            landmarks.append(Landmark(next_id, (float(xy[k, 0]), float(xy[k, 1]), float(z[k])), cls, cid))
            next_id += 1
    return landmarks


def generate_world(seed: int = DEFAULT_SEED, config: GeneratorConfig | None = None) -> World:
    """The real-imitated world for ``seed`` (same seed and config → identical world)."""
    cfg = config or GeneratorConfig()
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed = {cut(seed)}: must be a non-negative integer")
    rng = np.random.default_rng(int(seed))
    fld = Field(0.0, 0.0, float(cfg.size), float(cfg.size))
    landmarks = _clusters(rng, cfg)
    base = World(fld, (), (), tuple(landmarks))
    cents = base.cluster_centroids()
    cent_arr = np.array(list(cents.values()))
    lm_xy = base.landmark_array()[:, :2]
    polylines = [base.path_polyline(p) for p in PAPER_PATH_TYPES]
    dense = [_dense(pl) for pl in polylines]
    path_segments = [list(zip(p.clusters[:-1], p.clusters[1:])) for p in PAPER_PATH_TYPES]

    obstacles: list[Circle | Polygon] = []
    bounds: list[tuple[np.ndarray, float]] = []

    def fits(shape, blocking: bool) -> bool:
        c, r = shape.bounding_circle()
        if c[0] - r < 1.0 or c[1] - r < 1.0 or c[0] + r > cfg.size - 1.0 or c[1] + r > cfg.size - 1.0:
            return False
        if np.any(np.hypot(*(lm_xy - c).T) < r + cfg.landmark_clearance):
            return False
        if np.any(np.hypot(*(cent_arr - c).T) < r + cfg.centroid_clearance):
            return False
        if any(np.hypot(*(c - c2)) < r + r2 + cfg.obstacle_gap for c2, r2 in bounds):
            return False
        if blocking:
            hit = World(fld, tuple(obstacles) + (shape,))
            return all(hit.obstacle_mask(d).mean() <= cfg.max_blocked_fraction for d in dense)
        return bool(np.min(_polyline_distance(np.array([c]), polylines)) >= r + cfg.path_clearance)

    for k in range(cfg.n_obstacles):
        blocking = k < cfg.n_blocking
        for _ in range(cfg.max_tries):
            if blocking:
                segs = path_segments[k % len(path_segments)]     # round-robin over the path types
                a, b = segs[int(rng.integers(len(segs)))]
                pa, pb = cents[a], cents[b]
                t = rng.uniform(0.3, 0.7)
                r = rng.uniform(*cfg.blocking_radius)
                normal = np.array([pa[1] - pb[1], pb[0] - pa[0]]) / np.linalg.norm(pb - pa)
                c = pa + t * (pb - pa) + normal * rng.uniform(-0.5, 0.5) * r
            else:
                r = rng.uniform(*cfg.obstacle_radius)
                c = rng.uniform(r + 1.0, cfg.size - r - 1.0, 2)
            shape = _make_shape(rng, c, r)
            if blocking and not shape.segment_hits(*(cents[a], cents[b])):
                continue
            if fits(shape, blocking):
                obstacles.append(shape)
                bounds.append(shape.bounding_circle())
                break
        else:
            raise RuntimeError(f"seed {seed}: could not place obstacle {k} after {cfg.max_tries} tries")

    hazards: list[Hazard] = []
    for k in range(cfg.n_hazards):
        for _ in range(cfg.max_tries):
            r = rng.uniform(*cfg.hazard_radius)
            c = rng.uniform(r + 1.0, cfg.size - r - 1.0, 2)
            shape = _make_shape(rng, c, r)
            bc, br = shape.bounding_circle()
            inside = fld.contains(shape.array() if isinstance(shape, Polygon) else [bc - br, bc + br]).all()
            if inside and not shape.contains(lm_xy, cfg.landmark_clearance).any():
                hazards.append(Hazard(shape, _RISK_LEVELS[int(rng.integers(len(_RISK_LEVELS)))]))
                break
        else:
            raise RuntimeError(f"seed {seed}: could not place hazard {k} after {cfg.max_tries} tries")

    return World(fld, tuple(obstacles), tuple(hazards), tuple(landmarks))


def generate_scenario(seed: int = DEFAULT_SEED, config: GeneratorConfig | None = None, **params):
    """A :class:`~safenav.scenario.Scenario` around :func:`generate_world`'s world with the paper's path types.

    ``params`` are passed to :class:`~safenav.scenario.Scenario` (``camera=``, ``bmm=``, ...).
    The detection range defaults to the generator's ``detection_range``.
    """
    from .scenario import DetectionParams, Scenario, Seeds
    cfg = config or GeneratorConfig()
    params.setdefault("detection", DetectionParams(max_range_m=cfg.detection_range))
    params.setdefault("seeds", Seeds(world=int(seed)))
    params.setdefault("name", "real-imitated")
    params.setdefault("description",
                      f"SafeNav real-imitated world (section V-A): {cfg.size:g}x{cfg.size:g} m field, "
                      f"{cfg.n_obstacles} obstacles, {cfg.n_hazards} hazards, 9 landmark clusters; "
                      f"path types P1 (6->3), P2 (4->3), P3 (7->3). Generated by safenav.generate, seed {seed}.")
    return Scenario(world=generate_world(seed, cfg), path_types=PAPER_PATH_TYPES, **params)


def main(argv=None) -> None:
    from importlib import resources
    from pathlib import Path

    from .scenario import DEFAULT_SCENARIO_FILE, save_scenario
    ap = argparse.ArgumentParser(description="Generate a SafeNav real-imitated scenario file.")
    ap.add_argument("--seed", type=int, default=DEFAULT_SEED)
    ap.add_argument("--out", type=Path, default=None,
                    help="output .toml or .json (default: the package's data/default_scenario.toml)")
    args = ap.parse_args(argv)
    out = args.out or Path(str(resources.files("safenav") / "data" / DEFAULT_SCENARIO_FILE))
    print(save_scenario(generate_scenario(args.seed), out))


if __name__ == "__main__":
    main()
