"""Scenario files: a world plus every parameter a SafeNav run needs.

A scenario is a TOML file (JSON also works, chosen by the ``.json`` suffix)
read with :mod:`tomllib` and written with ``tomli_w``.  Layout (every table
but ``world`` and ``path_types`` is optional and defaults to the values below)::

    schema_version = 1
    name = "real-imitated"
    description = "..."

    [seeds]                    # world generator, Monte-Carlo trials, planner
    world = 7
    trials = 0
    planner = 0

    [camera]                   # the stereo pair (SafeNav V-A2: 2560x1440, B = 10-40 cm)
    focal_length_px = 1400.0
    baseline_m = 0.3
    image_width_px = 2560
    image_height_px = 1440
    field_of_view_deg = 85.0

    [detection]
    max_range_m = 30.0         # landmarks farther than this are not detected
    min_landmarks = 3          # trilateration needs at least this many

    [bmm]                      # safenav.BmmParams field names (eqs. 3-9)
    acceleration = 3.0
    ...

    [noise]
    lanbloc_std = [0.0142, 0.039]   # the paper's LanBLoc RMSE in X and Y [m]
    imu_speed_std = 0.05
    imu_heading_std = 0.02

    [planner]                  # RAw-RRT*: cost = alpha*length + beta*sum WRS (eq. 19)
    alpha = 1.0
    beta = 1.0

    [buffer]                   # safe buffer: half-width and zone weights (eq. 18)
    half_width = 8.0
    weights = [2.0, 4.0, 6.0, 8.0]

    [[path_types]]
    name = "P1"
    start = 6                  # optional; must equal clusters[0]
    clusters = [6, 5, 2, 3]
    destination = 3            # optional; must equal clusters[-1]

    [world.field]
    x_min = 0.0
    y_min = 0.0
    x_max = 200.0
    y_max = 200.0

    [[world.obstacles]]
    type = "circle"            # or "polygon" with vertices = [[x, y], ...]
    center = [50.0, 60.0]
    radius = 4.5

    [[world.hazards]]
    type = "polygon"
    vertices = [[10.0, 10.0], [20.0, 10.0], [15.0, 18.0]]
    risk = 0.75                # in (0, 1]

    [[world.landmarks]]
    id = 1
    position = [24.0, 31.5, 6.0]   # (x, y) or (x, y, z)
    class = "tower"
    cluster = 6

Loading validates every field; each problem is a :class:`ScenarioError`
(a ``ValueError``) naming the file, the field path and the value, e.g.
``scenario.toml: world.obstacles[3].radius = -2.0: must be > 0``.
"""

from __future__ import annotations

import json
import re
import tomllib
from dataclasses import dataclass, field, fields
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w

from .world import (Circle, Field, Hazard, Landmark, PathType, Polygon, ScenarioError, World,  # noqa: F401
                    _at, _fail, _integer, _items, _real, _table, _text, _vector)

__all__ = [
    "ScenarioError", "CameraParams", "DetectionParams", "BmmConfig", "NoiseParams", "PlannerParams",
    "BufferParams", "Seeds", "Scenario", "load_scenario", "save_scenario", "default_scenario",
    "SCHEMA_VERSION",
]

SCHEMA_VERSION = 1


class _Params:
    """Mixin: ``to_dict``/``from_dict`` for a flat parameter table whose keys are the field names."""

    def to_dict(self) -> dict:
        out = {}
        for f in fields(self):
            v = getattr(self, f.name)
            out[f.name] = list(v) if isinstance(v, tuple) else v
        return out

    @classmethod
    def from_dict(cls, data):
        t = _table("", data, required=(), optional=tuple(f.name for f in fields(cls)))
        return cls(**t)


@dataclass(frozen=True)
class CameraParams(_Params):
    """The stereo camera (SafeNav V-A2: 2560×1440 px, baseline 10–40 cm; f and FoV are ours)."""

    focal_length_px: float = 1400.0   #: f [px]
    baseline_m: float = 0.3           #: B [m]
    image_width_px: int = 2560
    image_height_px: int = 1440
    field_of_view_deg: float = 85.0   #: horizontal field of view [deg]

    def __post_init__(self):
        for n in ("focal_length_px", "baseline_m"):
            object.__setattr__(self, n, _real(n, getattr(self, n), lo=0.0, lo_open=True))
        for n in ("image_width_px", "image_height_px"):
            object.__setattr__(self, n, _integer(n, getattr(self, n), lo=1))
        object.__setattr__(self, "field_of_view_deg",
                           _real("field_of_view_deg", self.field_of_view_deg, lo=0.0, lo_open=True, hi=360.0))


@dataclass(frozen=True)
class DetectionParams(_Params):
    """Landmark detection: the range limit and the trilateration minimum (paper: ≥ 3 landmarks)."""

    max_range_m: float = 30.0   #: landmarks farther than this (3D distance) are not detected [m]
    min_landmarks: int = 3      #: a cluster used on a path needs this many within range of its centroid

    def __post_init__(self):
        object.__setattr__(self, "max_range_m", _real("max_range_m", self.max_range_m, lo=0.0, lo_open=True))
        object.__setattr__(self, "min_landmarks", _integer("min_landmarks", self.min_landmarks, lo=1))


@dataclass(frozen=True)
class BmmConfig(_Params):
    """BMM parameters (eqs. 3–9) under :class:`safenav.BmmParams`' field names and defaults."""

    acceleration: float = 3.0        #: a [m/s²]
    deceleration: float = 3.0        #: d [m/s²]
    max_speed: float = 10.0          #: v_max [m/s]
    max_heading_rate: float = 1.5    #: m [rad/s]
    dt: float = 0.05                 #: Δt [s]
    terrain_effect: float = 0.0      #: τ
    speed_noise: float = 0.05        #: σ of ε_v
    heading_noise: float = 0.01      #: σ of ε_θ
    position_noise: float = 0.01     #: σ of ε_x, ε_y

    def __post_init__(self):
        for f in fields(self):
            positive = f.name in ("acceleration", "deceleration", "max_speed", "max_heading_rate", "dt")
            object.__setattr__(self, f.name, _real(f.name, getattr(self, f.name), lo=0.0, lo_open=positive))

    def to_params(self):
        """The equivalent :class:`safenav.BmmParams` (needs the C++ core)."""
        from .motion import BmmParams
        p = BmmParams()
        for f in fields(self):
            setattr(p, f.name, getattr(self, f.name))
        return p


@dataclass(frozen=True)
class NoiseParams(_Params):
    """Measurement noise: LanBLoc position σ (paper's RMSE 0.0142 m X, 0.039 m Y) and the IMU's σ."""

    lanbloc_std: tuple[float, float] = (0.0142, 0.039)  #: [m] in X and Y
    imu_speed_std: float = 0.05                         #: [m/s]
    imu_heading_std: float = 0.02                       #: [rad]

    def __post_init__(self):
        v = _vector("lanbloc_std", self.lanbloc_std, (2,))
        for i, s in enumerate(v):
            _real(f"lanbloc_std[{i}]", s, lo=0.0)
        object.__setattr__(self, "lanbloc_std", v)
        for n in ("imu_speed_std", "imu_heading_std"):
            object.__setattr__(self, n, _real(n, getattr(self, n), lo=0.0))


@dataclass(frozen=True)
class PlannerParams(_Params):
    """RAw-RRT* weights: cost = α·length + β·ΣWRS (eqs. 16, 19); β = 0 is plain RRT*."""

    alpha: float = 1.0   #: α
    beta: float = 1.0    #: β

    def __post_init__(self):
        object.__setattr__(self, "alpha", _real("alpha", self.alpha, lo=0.0, lo_open=True))
        object.__setattr__(self, "beta", _real("beta", self.beta, lo=0.0))


@dataclass(frozen=True)
class BufferParams(_Params):
    """The safe buffer (eq. 18): ``half_width`` [m] split into equal zones with these weights."""

    half_width: float = 8.0
    weights: tuple[float, ...] = (2.0, 4.0, 6.0, 8.0)

    def __post_init__(self):
        object.__setattr__(self, "half_width", _real("half_width", self.half_width, lo=0.0, lo_open=True))
        w = _items("weights", self.weights)
        if not w:
            _fail("weights", self.weights, "needs at least one zone weight")
        w = tuple(_real(f"weights[{i}]", x, lo=0.0, lo_open=True) for i, x in enumerate(w))
        for i in range(1, len(w)):
            if w[i] < w[i - 1]:
                _fail(f"weights[{i}]", w[i], f"must not be below weights[{i - 1}] = {w[i - 1]} (risk grows outward)")
        object.__setattr__(self, "weights", w)

    def risk_zones(self):
        """The equivalent :class:`safenav.RiskZones` (needs the C++ core)."""
        from .metrics import RiskZones
        return RiskZones(half_width=self.half_width, weights=list(self.weights))


@dataclass(frozen=True)
class NavigationParams(_Params):
    """SafeNav navigation (Algorithms 1, 2 and 4).  The paper gives none of these
    numbers; ours are stated here and in the README.

    ``clearance`` keeps planned paths (the safe path and detours) that far from
    obstacles; ``plan_iterations`` is the RAw-RRT* budget of the safe path,
    ``replan_iterations`` that of a detour; ``corridor_bias`` their share of
    samples drawn inside the corridor (0 = uniform, as in the paper)."""

    cruise_speed: float = 2.0          #: desired speed [m/s]
    arrival_radius: float = 1.0        #: arrived when the estimate is this close to the destination [m]
    segment_length: float = 10.0       #: longest path segment of Algorithms 1-2 [m]
    sub_segments: int = 4              #: Algorithm 2's sub-segments per segment
    lookahead: float = 5.0             #: Algorithm 1's corrective look-ahead [m]
    step_back_speed: float = 0.5       #: Algorithm 1's step-back speed [m/s]
    sensing_range: float = 10.0        #: obstacles this far ahead on the path are detected [m]
    replan_lookahead: float = 20.0     #: a detour rejoins the path this far ahead [m]
    clearance: float = 2.0             #: planned paths keep this far from obstacles [m]
    plan_iterations: int = 5000        #: RAw-RRT* iterations for the safe path
    replan_iterations: int = 3000      #: RAw-RRT* iterations for a detour
    corridor_bias: float = 0.5         #: share of corridor samples in RAw-RRT*
    lost_position_std: float = 10.0    #: lost localization above this position σ [m]
    max_steps: int = 0                 #: 0 = 3 × path length / (speed · dt) + 200

    def __post_init__(self):
        for n in ("cruise_speed", "arrival_radius", "segment_length", "lookahead", "step_back_speed",
                  "sensing_range", "replan_lookahead", "lost_position_std"):
            object.__setattr__(self, n, _real(n, getattr(self, n), lo=0.0, lo_open=True))
        object.__setattr__(self, "clearance", _real("clearance", self.clearance, lo=0.0))
        object.__setattr__(self, "corridor_bias", _real("corridor_bias", self.corridor_bias, lo=0.0, hi=1.0))
        object.__setattr__(self, "sub_segments", _integer("sub_segments", self.sub_segments, lo=1))
        for n in ("plan_iterations", "replan_iterations"):
            object.__setattr__(self, n, _integer(n, getattr(self, n), lo=1))
        object.__setattr__(self, "max_steps", _integer("max_steps", self.max_steps, lo=0))


@dataclass(frozen=True)
class Seeds(_Params):
    """Seeds: the world generator's, the Monte-Carlo trials' base seed, the planner's."""

    world: int = 0
    trials: int = 0
    planner: int = 0

    def __post_init__(self):
        for f in fields(self):
            # TOML integers are signed 64-bit.
            object.__setattr__(self, f.name, _integer(f.name, getattr(self, f.name), lo=0, hi=2**63 - 1))


_SECTIONS: dict[str, type] = {
    "seeds": Seeds, "camera": CameraParams, "detection": DetectionParams, "bmm": BmmConfig,
    "noise": NoiseParams, "planner": PlannerParams, "buffer": BufferParams, "navigation": NavigationParams,
}


@dataclass(frozen=True)
class Scenario:
    """A world, its path types and the run parameters.

    Cross-checks on construction: path type names are unique; every cluster a
    path names exists; a path's start and destination (cluster centroids) lie
    outside every obstacle; every cluster on a path has at least
    ``detection.min_landmarks`` landmarks within ``detection.max_range_m`` of
    its centroid (the paper's trilateration sets).
    """

    world: World
    path_types: tuple[PathType, ...]
    name: str = "scenario"
    description: str = ""
    seeds: Seeds = field(default_factory=Seeds)
    camera: CameraParams = field(default_factory=CameraParams)
    detection: DetectionParams = field(default_factory=DetectionParams)
    bmm: BmmConfig = field(default_factory=BmmConfig)
    noise: NoiseParams = field(default_factory=NoiseParams)
    planner: PlannerParams = field(default_factory=PlannerParams)
    buffer: BufferParams = field(default_factory=BufferParams)
    navigation: NavigationParams = field(default_factory=NavigationParams)

    def __post_init__(self):
        _text("name", self.name)
        if not isinstance(self.description, str):
            _fail("description", self.description, "must be a string")
        if not isinstance(self.world, World):
            _fail("world", self.world, "must be a World")
        for key, cls in _SECTIONS.items():
            if not isinstance(getattr(self, key), cls):
                _fail(key, getattr(self, key), f"must be a {cls.__name__}")
        paths = _items("path_types", self.path_types)
        if not paths:
            _fail("path_types", self.path_types, "needs at least one path type")
        object.__setattr__(self, "path_types", paths)
        w = self.world
        known = set(w.cluster_ids)
        names: dict[str, int] = {}
        for i, pt in enumerate(paths):
            where = f"path_types[{i}]"
            if not isinstance(pt, PathType):
                _fail(where, pt, "must be a PathType")
            if pt.name in names:
                _fail(f"{where}.name", pt.name, f"duplicates path_types[{names[pt.name]}].name")
            names[pt.name] = i
            for k, c in enumerate(pt.clusters):
                if c not in known:
                    _fail(f"{where}.clusters[{k}]", c, f"unknown cluster (clusters with landmarks: {sorted(known)})")
            for k, role in ((0, "start"), (len(pt.clusters) - 1, "destination")):
                c = pt.clusters[k]
                p = w.cluster_centroid(c)
                hit = w.obstacles_at(p)
                if hit:
                    _fail(f"{where}.clusters[{k}]", c, f"the path's {role}, the centroid "
                          f"({p[0]:.6g}, {p[1]:.6g}) of cluster {c}, lies inside world.obstacles[{hit[0]}]")
            for k, c in enumerate(pt.clusters):
                n = len(w.landmarks_in_range(w.cluster_centroid(c), self.detection.max_range_m, cluster=c))
                if n < self.detection.min_landmarks:
                    _fail(f"{where}.clusters[{k}]", c,
                          f"cluster {c} has {n} landmark(s) within detection.max_range_m = "
                          f"{self.detection.max_range_m:g} m of its centroid; trilateration needs "
                          f"detection.min_landmarks = {self.detection.min_landmarks}")

    # ---- convenience
    def path_type(self, name: str) -> PathType:
        for pt in self.path_types:
            if pt.name == name:
                return pt
        raise KeyError(f"no path type {name!r} (have: {[p.name for p in self.path_types]})")

    def path_polyline(self, name: str) -> np.ndarray:
        """The ground-truth polyline of the path type ``name`` through cluster centroids."""
        return self.world.path_polyline(self.path_type(name))

    def bmm_params(self):
        return self.bmm.to_params()

    def risk_zones(self):
        return self.buffer.risk_zones()

    # ---- serialisation
    def to_dict(self) -> dict:
        """A plain mapping (TOML/JSON-ready) that :meth:`from_dict` reads back to an equal scenario."""
        out: dict[str, Any] = {"schema_version": SCHEMA_VERSION, "name": self.name,
                               "description": self.description}
        for key in _SECTIONS:
            out[key] = getattr(self, key).to_dict()
        out["path_types"] = [pt.to_dict() for pt in self.path_types]
        out["world"] = self.world.to_dict()
        return out

    @classmethod
    def from_dict(cls, data) -> "Scenario":
        """Validate and build; a :class:`ScenarioError` names the field path and the value."""
        d = _table("scenario", data, required=("world", "path_types"),
                   optional=("schema_version", "name", "description", *_SECTIONS))
        if "schema_version" in d:
            _integer("schema_version", d["schema_version"])
            if d["schema_version"] != SCHEMA_VERSION:
                _fail("schema_version", d["schema_version"], f"unsupported (this safenav reads {SCHEMA_VERSION})")
        kw: dict[str, Any] = {}
        for key, sec in _SECTIONS.items():
            if key in d:
                with _at(key):
                    kw[key] = sec.from_dict(d[key])
        with _at("world"):
            kw["world"] = World.from_dict(d["world"])
        paths = []
        for i, p in enumerate(_items("path_types", d["path_types"])):
            with _at(f"path_types[{i}]"):
                t = _table("", p, required=("name", "clusters"), optional=("start", "destination"))
                pt = PathType(t["name"], t["clusters"])
                for key, want, k in (("start", pt.start, 0), ("destination", pt.destination, -1)):
                    if key in t and (isinstance(t[key], bool) or t[key] != want):
                        _fail(key, t[key], f"must equal clusters[{k}] = {want}")
                paths.append(pt)
        kw["path_types"] = tuple(paths)
        for key in ("name", "description"):
            if key in d:
                kw[key] = d[key]
        return cls(**kw)


# ---------------------------------------------------------------------------- files

def _is_json(path: Path) -> bool:
    return path.suffix.lower() == ".json"


def load_scenario(path) -> Scenario:
    """Read and validate a scenario file (TOML, or JSON by suffix)."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ScenarioError(f"{path}: cannot read the scenario file: {exc}") from exc
    try:
        data = json.loads(raw) if _is_json(path) else tomllib.loads(raw.decode("utf-8"))
    except (tomllib.TOMLDecodeError, json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ScenarioError(f"{path}: not a valid {'JSON' if _is_json(path) else 'TOML'} file: {exc}") from exc
    try:
        return Scenario.from_dict(data)
    except ValueError as exc:
        raise ScenarioError(f"{path}: {exc}") from None


def dumps_scenario(scenario: Scenario, *, json_format: bool = False) -> str:
    """The scenario as TOML (or JSON) text."""
    if not isinstance(scenario, Scenario):
        raise TypeError(f"scenario must be a Scenario, got {type(scenario).__name__}")
    d = scenario.to_dict()
    if json_format:
        return json.dumps(d, indent=1, allow_nan=False) + "\n"
    head = f"# safenav scenario, schema {SCHEMA_VERSION}: {scenario.name}\n"
    return head + _NUMERIC_ARRAY.sub(_one_line, tomli_w.dumps(d))


# tomli_w puts every array item on its own line; put arrays of numbers on one line.
_NUMERIC_ARRAY = re.compile(r"\[\n((?:[ ]+[-+]?(?:[0-9][0-9_.eE+-]*|inf|nan),\n)+)[ ]*\]")


def _one_line(m: re.Match) -> str:
    return "[" + ", ".join(x.strip().rstrip(",") for x in m.group(1).splitlines()) + "]"


def save_scenario(scenario: Scenario, path) -> Path:
    """Write ``scenario`` with the one result writer (:func:`safenav.results.write_text`: atomic, the user's umask)."""
    from .results import write_text

    return write_text(path, dumps_scenario(scenario, json_format=_is_json(Path(path))))


DEFAULT_SCENARIO_FILE = "default_scenario.toml"


@lru_cache(maxsize=1)
def default_scenario() -> Scenario:
    """The shipped real-imitated scenario (``safenav/data/default_scenario.toml``, see :mod:`safenav.generate`)."""
    res = resources.files("safenav") / "data" / DEFAULT_SCENARIO_FILE
    try:
        return Scenario.from_dict(tomllib.loads(res.read_text(encoding="utf-8")))
    except ValueError as exc:
        raise ScenarioError(f"{DEFAULT_SCENARIO_FILE}: {exc}") from None
