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

    [camera]                   # the stereo pair ([SafeNav-ext §V-A2]: 2560x1440, B = 10-40 cm)
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
    lanbloc_std = [0.0142, 0.039]   # the paper's LanBLoc RMSE in X and Y [m] (the core's default)
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
``scenario.toml: world.obstacles[3].radius = -2.0: must be in (0, 100000]``.
Every field's range and every list's size limit are in docs/scenario.md.
"""

from __future__ import annotations

import json
import os
import re
import stat
import tomllib
from dataclasses import dataclass, field, fields
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w

from . import _core
from . import validation
from .validation import Range, ScenarioError
from .world import Circle, Field, Hazard, Landmark, PathType, Polygon, World  # noqa: F401

__all__ = [
    "ScenarioError", "CameraParams", "DetectionParams", "BmmConfig", "NoiseParams", "PlannerParams",
    "BufferParams", "Seeds", "Scenario", "load_scenario", "save_scenario", "default_scenario",
    "SCHEMA_VERSION",
]

SCHEMA_VERSION = 1


def _r(lo, hi, lo_open=False):
    return Range(lo, hi, lo_open)


def _n(lo, hi):
    return Range(lo, hi, integer=True)


MAX_STEPS = _core.NAVIGATION_MAX_STEPS   #: navigation.max_steps, given or derived (the core's limit)
MAX_ITERATIONS = 1_000_000    #: RAw-RRT* iterations of one plan
MAX_PATH_TYPES = 100
MAX_DESCRIPTION = 10_000      #: characters


class _Params:
    """Mixin for a flat parameter table whose keys are the field names.

    ``RANGES`` gives each scalar field's physical range (docs/scenario.md says
    why); ``__post_init__`` checks and normalises every one of them."""

    RANGES: dict = {}
    LISTS: dict = {}   #: list fields: name -> (range of each entry, most entries)
    FLAGS: tuple = ()  #: bool fields (the core's ParamKind.BOOLEAN): true or false, nothing else
    CORE: dict = {}    #: fields declared in the core: name -> (core settings type, its parameter name)

    def __post_init__(self):
        for name, rng in self.RANGES.items():
            object.__setattr__(self, name, rng.check(name, getattr(self, name)))
        for name in self.FLAGS:
            v = getattr(self, name)
            if not isinstance(v, (bool, np.bool_)):
                validation.fail(name, v, "must be true or false")
            object.__setattr__(self, name, bool(v))
        for name, (rng, max_len) in self.LISTS.items():
            v = validation.items(name, getattr(self, name), max_len)
            if not v:
                validation.fail(name, getattr(self, name), "needs at least one entry")
            object.__setattr__(self, name, tuple(rng.check(f"{name}[{i}]", x) for i, x in enumerate(v)))

    def apply(self, core):
        """Set this section's fields that are parameters of the core settings
        object ``core`` (by their core names) onto it; returns ``core``."""
        for key, (core_type, core_name) in self.CORE.items():
            if isinstance(core, core_type):
                core.set_param(core_name, getattr(self, key))
        return core

    def to_dict(self) -> dict:
        out = {}
        for f in fields(self):
            v = getattr(self, f.name)
            out[f.name] = list(v) if isinstance(v, tuple) else v
        return out

    @classmethod
    def from_dict(cls, data):
        t = validation.table("", data, required=(), optional=tuple(f.name for f in fields(cls)))
        return cls(**t)


@dataclass(frozen=True)
class CameraParams(_Params):
    """The stereo camera ([SafeNav-ext §V-A2]: 2560×1440 px, baseline 10–40 cm; f and FoV are ours)."""

    focal_length_px: float = 1400.0   #: f [px]
    baseline_m: float = 0.3           #: B [m]
    image_width_px: int = 2560
    image_height_px: int = 1440
    field_of_view_deg: float = 85.0   #: horizontal field of view [deg]

    RANGES = {"focal_length_px": _r(0, 1e5, True), "baseline_m": _r(0, 10, True),
              "image_width_px": _n(1, 100_000), "image_height_px": _n(1, 100_000),
              "field_of_view_deg": _r(0, 360, True)}


def _core_section(name: str, doc: str, keys, *, defaults=None, extra=None, own=()) -> type:
    """A frozen section class whose fields are parameters declared in the core
    (``safenav/params.hpp``): each key's default, range and documentation come
    from the core declaration, none is repeated here.

    ``keys``: ``(key, core_type, core_name)`` triples (a plain ``(core_type, key)``
    pair when the names agree); ``defaults``: the few scenario defaults that
    differ from the core struct's own, each with its reason at the call;
    ``extra``: methods and class attributes of the section; ``own``: extra
    ``(name, type, dataclasses.field)`` fields that the section checks itself."""
    defaults = defaults or {}
    spec_fields, ranges, lists, flags, core = [], {}, {}, [], {}
    for entry in keys:
        key, core_type, core_name = entry if len(entry) == 3 else (entry[1], entry[0], entry[1])
        spec = next(sp for sp in core_type.params() if sp.name == core_name)
        core[key] = (core_type, core_name)
        rng = Range(spec.lo, spec.hi, spec.lo_open, integer=spec.kind == _core.ParamKind.INTEGER)
        default = defaults.get(key, core_type().get_param(core_name))
        if spec.kind == _core.ParamKind.BOOLEAN:
            flags.append(key)
            spec_fields.append((key, bool, field(default=bool(default), metadata={"doc": spec.doc})))
        elif spec.kind == _core.ParamKind.REAL_LIST:
            lists[key] = (rng, spec.max_size)
            spec_fields.append((key, tuple, field(default=tuple(default), metadata={"doc": spec.doc})))
        else:
            ranges[key] = rng
            kind = int if rng.integer else float
            spec_fields.append((key, kind, field(default=default, metadata={"doc": spec.doc, "unit": spec.unit})))
    spec_fields += list(own)
    namespace = {"RANGES": ranges, "LISTS": lists, "FLAGS": tuple(flags), "CORE": core, "__doc__": doc, **(extra or {})}
    return dataclass(frozen=True)(type(name, (_Params,), {"__annotations__": {k: t for k, t, _ in spec_fields},
                                                          **{k: f for k, _, f in spec_fields}, **namespace}))


def _to_params(self):
    """The equivalent :class:`safenav.BmmParams`."""
    return self.apply(_core.BmmParams())


BmmConfig = _core_section(
    "BmmConfig", "BMM parameters (eqs. 3-9): :class:`safenav.BmmParams`' fields, defaults and ranges.",
    [(_core.BmmParams, sp.name) for sp in _core.BmmParams.params()], extra={"to_params": _to_params})

DetectionParams = _core_section(
    "DetectionParams", "Landmark detection: the range limit and the trilateration minimum (paper: >= 3 landmarks).\n\n"
    "``max_range_m`` (3D distance) also bounds a path cluster's landmarks: each cluster on a path needs "
    "``min_landmarks`` within it of its centroid.\n\n"
    "``occlusion`` (ours): obstacles hide the landmarks behind them from the simulated camera and from the "
    "guard's look (``ObstacleChecker.line_of_sight``); the papers' loop (``paper=True``) turns it off.",
    [("max_range_m", _core.SensorSettings, "max_range"), (_core.SensorSettings, "min_landmarks"),
     (_core.SensorSettings, "occlusion")])

FIX_MODELS = {"profile": "profile", "ranges": "ranges"}
GUARD_MODES = {"on": "on", "off": "off"}


def _check_noise(self):
    _Params.__post_init__(self)
    v = validation.vector("lanbloc_std", self.lanbloc_std, (2,))
    object.__setattr__(self, "lanbloc_std", tuple(self.LANBLOC_STD.check(f"lanbloc_std[{i}]", s)
                                                  for i, s in enumerate(v)))
    object.__setattr__(self, "fix_model", validation.choice("fix_model", self.fix_model, FIX_MODELS))
    if self.fix_model != "ranges" and self.faults().any():
        validation.fail("fix_model", self.fix_model, "landmark faults (dropout_probability, outlier_probability, "
                        "misassociation_probability) need fix_model = 'ranges'")


def _faults(self):
    """The landmark faults as the core's :class:`safenav.LandmarkFaults`."""
    return _core.LandmarkFaults(self.dropout_probability, self.outlier_probability, self.outlier_magnitude,
                                self.misassociation_probability)


def _apply_noise(self, core):
    _Params.apply(self, core)
    if isinstance(core, _core.SensorSettings):
        core.fix_model = _core.FixModel.RANGES if self.fix_model == "ranges" else _core.FixModel.PROFILE
    return core


NoiseParams = _core_section(
    "NoiseParams", "Measurement noise: the LanBLoc position sigma (the core's ``PositionNoise.named('lanbloc')``: "
    "the paper's RMSE) and the IMU's sigma (``SensorSettings``).\n\n"
    "Landmark level (ours): ``fix_model = 'ranges'`` builds each fix from single landmark ranges "
    "(sigma ``range_std``) by LanBLoc's trilateration with its outlier rejection; only then can the "
    "landmark faults act: a missed detection (``dropout_probability``), another landmark's id "
    "(``misassociation_probability``), a range off by +-``outlier_magnitude`` (``outlier_probability``). "
    "``'profile'`` (default) is the paper's measurement-level error model.",
    [(_core.SensorSettings, "imu_speed_std"), (_core.SensorSettings, "imu_heading_std"),
     (_core.SensorSettings, "range_std"), (_core.SensorSettings, "dropout_probability"),
     (_core.SensorSettings, "outlier_probability"), (_core.SensorSettings, "outlier_magnitude"),
     (_core.SensorSettings, "misassociation_probability")],
    own=[("lanbloc_std", tuple, field(default=tuple(float(v) for v in _core.PositionNoise.named("lanbloc").std),
                                      metadata={"doc": "LanBLoc's position sigma in X and Y", "unit": "m"})),
         ("fix_model", str, field(default="profile", metadata={
             "doc": "where fixes come from: 'profile' (the paper's error model) or 'ranges' (landmark ranges, "
                    "trilateration; needed by the landmark faults)"}))],
    #: each entry of ``lanbloc_std``; a sigma of 0 would make the filters' covariances singular
    extra={"LANBLOC_STD": Range(1e-6, 100), "__post_init__": _check_noise, "faults": _faults,
           "apply": _apply_noise})

PlannerParams = _core_section(
    "PlannerParams", "RAw-RRT* weights: cost = alpha*length + beta*sum(WRS) (eqs. 16, 19); beta = 0 is plain RRT*.\n\n"
    "Hazards (ours): ``hazard_weight`` (beta_h) adds beta_h * integral of risk ds over the hazards (0 = the paper); "
    "hazards with risk >= ``forbidden_risk`` are obstacles (above 1 = none, the paper).",
    [(_core.PlannerSettings, "alpha"), (_core.PlannerSettings, "beta"), (_core.PlannerSettings, "hazard_weight"),
     (_core.PlanningMap, "forbidden_risk")])


def _check_weights(self):
    _Params.__post_init__(self)
    w = self.weights
    for i in range(1, len(w)):
        if w[i] < w[i - 1]:
            validation.fail(f"weights[{i}]", w[i], f"must not be below weights[{i - 1}] = {w[i - 1]} (risk grows outward)")


def _risk_zones(self):
    """The equivalent :class:`safenav.RiskZones`."""
    return self.apply(_core.RiskZones())


BufferParams = _core_section(
    "BufferParams", "The safe buffer (eq. 18): ``half_width`` [m] split into equal zones with these weights.",
    [(_core.RiskZones, "half_width"), (_core.RiskZones, "weights")],
    extra={"__post_init__": _check_weights, "risk_zones": _risk_zones})
BufferParams.WEIGHT = BufferParams.LISTS["weights"][0]   #: each entry of ``weights``

_NAV = _core.NavigationSettings


def _check_navigation(self):
    _Params.__post_init__(self)
    object.__setattr__(self, "guard", validation.choice("guard", self.guard, GUARD_MODES))
    if self.clearance is not None:
        object.__setattr__(self, "clearance", self.CLEARANCE.check("clearance", self.clearance))


def _planning_clearance(self) -> float:
    """The planning clearance [m]: ``clearance`` if set (old scenario files), else
    ``vehicle_radius + clearance_margin`` (:class:`safenav.Inflation`)."""
    if self.clearance is not None:
        return self.clearance
    return _core.Inflation(vehicle_radius=self.vehicle_radius, margin=self.clearance_margin).clearance


def _navigation_to_dict(self) -> dict:
    out = _Params.to_dict(self)
    if out["clearance"] is None:
        del out["clearance"]
    return out


_CLEARANCE_SPEC = next(sp for sp in _core.PlanningMap.params() if sp.name == "clearance")
NavigationParams = _core_section(
    "NavigationParams",
    """SafeNav navigation [SafeNav Algs. 1–2, SafeNav-ext Alg. 4].  The paper gives none of these
    numbers; ours are declared with the core's settings (``NavigationSettings``,
    ``Inflation``, ``PlanningMap.clearance``, ``PlannerSettings.max_iterations``).

    Planned paths (the safe path and detours) keep ``planning_clearance`` from
    obstacles: ``vehicle_radius + clearance_margin`` (1 + 1 = 2 m by default).
    Precedence: ``clearance``, when a scenario sets it (files written before
    the two fields existed), is the planning clearance and the other two are
    ignored; unset (``None``, the default) it follows from them.
    ``plan_iterations`` is the RAw-RRT* budget of the safe path,
    ``replan_iterations`` that of a detour; ``corridor_bias`` their share of
    samples drawn inside the corridor (0 = uniform, as in the paper).

    Safety (ours, on by default): each update passes a chi-square gate at
    ``gate_probability``, and the guard (``guard``, ``guard_k``, ...; see
    :class:`safenav.GuardSettings`) keeps ``guard_k`` position sigmas clear of
    obstacles and forbidden hazards.  The papers' loop: ``guard = 'off'`` and
    ``gate_probability = 0``.""",
    [(_NAV, "cruise_speed"), (_NAV, "arrival_radius"), (_NAV, "segment_length"), (_NAV, "sub_segments"),
     (_NAV, "lookahead"), (_NAV, "step_back_speed"), (_NAV, "sensing_range"), (_NAV, "replan_lookahead"),
     ("vehicle_radius", _core.Inflation, "vehicle_radius"), ("clearance_margin", _core.Inflation, "margin"),
     ("plan_iterations", _core.PlannerSettings, "max_iterations"),
     (_NAV, "replan_iterations"), (_NAV, "corridor_bias"), (_NAV, "lost_position_std"), (_NAV, "max_steps"),
     (_NAV, "gate_probability"), (_NAV, "guard_k"), (_NAV, "guard_buffer"), (_NAV, "guard_slow_distance"),
     (_NAV, "guard_min_speed_fraction"), (_NAV, "guard_horizon")],
    own=[("guard", str, field(default="on", metadata={
        "doc": "the uncertainty-aware guard: 'on', or 'off' (the papers' loop; with gate_probability = 0)"})),("clearance", object, field(default=None, metadata={
        "doc": "planning clearance; overrides vehicle_radius + clearance_margin when set (old scenario files)",
        "unit": "m"}))],
    extra={"__post_init__": _check_navigation, "planning_clearance": property(_planning_clearance),
           "to_dict": _navigation_to_dict,
           "CLEARANCE": Range(_CLEARANCE_SPEC.lo, _CLEARANCE_SPEC.hi, _CLEARANCE_SPEC.lo_open)})

@dataclass(frozen=True)
class Seeds(_Params):
    """Seeds: the world generator's, the Monte-Carlo trials' base seed, the planner's."""

    world: int = 0
    trials: int = 0
    planner: int = 0

    # TOML integers are signed 64-bit.
    RANGES = {"world": _n(0, 2**63 - 1), "trials": _n(0, 2**63 - 1), "planner": _n(0, 2**63 - 1)}


_SECTIONS: dict[str, type] = {
    "seeds": Seeds, "camera": CameraParams, "detection": DetectionParams, "bmm": BmmConfig,
    "noise": NoiseParams, "planner": PlannerParams, "buffer": BufferParams, "navigation": NavigationParams,
}


@dataclass(frozen=True)
class Scenario:
    """A world, its path types and the run parameters.

    Cross-checks on construction, so that a bad combination of fields is
    refused before planning starts: path type names are unique; every cluster a path names exists; a
    path's start and destination (cluster centroids) lie farther than
    ``navigation.planning_clearance`` from every obstacle (else the planner cannot
    start or end) and farther apart than ``navigation.arrival_radius`` (else
    every trial "arrives" before it moves); the cruise and step-back speeds do
    not exceed ``bmm.max_speed``; with ``navigation.max_steps = 0`` the
    derived step budget 3·L/(v·Δt·terrain factor) + 200 of each path's
    polyline length L stays within ``MAX_STEPS``; every cluster on a path has
    at least ``detection.min_landmarks`` landmarks within
    ``detection.max_range_m`` of its centroid (the paper's trilateration sets).
    Every check is linear in the scenario's size.
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
        validation.text("name", self.name)
        if not isinstance(self.description, str):
            validation.fail("description", self.description, "must be a string")
        if len(self.description) > MAX_DESCRIPTION:
            validation.fail("description", self.description,
                  f"has {len(self.description)} characters, at most {MAX_DESCRIPTION} allowed")
        if not isinstance(self.world, World):
            validation.fail("world", self.world, "must be a World")
        for key, cls in _SECTIONS.items():
            if not isinstance(getattr(self, key), cls):
                validation.fail(key, getattr(self, key), f"must be a {cls.__name__}")
        paths = validation.items("path_types", self.path_types, MAX_PATH_TYPES)
        if not paths:
            validation.fail("path_types", self.path_types, "needs at least one path type")
        object.__setattr__(self, "path_types", paths)
        w, nav = self.world, self.navigation
        for n in ("cruise_speed", "step_back_speed"):
            if getattr(nav, n) > self.bmm.max_speed:
                validation.fail(f"navigation.{n}", getattr(nav, n), f"exceeds bmm.max_speed = {self.bmm.max_speed:g} m/s")
        groups, cents = w.clusters(), w.cluster_centroids()
        names: dict[str, int] = {}
        for i, pt in enumerate(paths):
            where = f"path_types[{i}]"
            if not isinstance(pt, PathType):
                validation.fail(where, pt, "must be a PathType")
            if pt.name in names:
                validation.fail(f"{where}.name", pt.name, f"duplicates path_types[{names[pt.name]}].name")
            names[pt.name] = i
            for k, c in enumerate(pt.clusters):
                if c not in groups:
                    validation.fail(f"{where}.clusters[{k}]", c, f"unknown cluster (clusters with landmarks: {validation.cut(sorted(groups))})")
        ends = np.array([cents[c] for pt in paths for c in (pt.start, pt.destination)])
        hits = w.first_obstacle_at(ends, nav.planning_clearance).reshape(-1, 2)
        for i, pt in enumerate(paths):
            where = f"path_types[{i}]"
            for j, (k, role) in enumerate(((0, "start"), (len(pt.clusters) - 1, "destination"))):
                if hits[i, j] >= 0:
                    c, p = pt.clusters[k], ends[2 * i + j]
                    validation.fail(f"{where}.clusters[{k}]", c, f"the path's {role}, the centroid ({p[0]:.6g}, {p[1]:.6g}) of "
                          f"cluster {c}, lies within navigation.clearance = {nav.planning_clearance:g} m of "
                          f"world.obstacles[{hits[i, j]}]")
            gap = float(np.hypot(*(ends[2 * i + 1] - ends[2 * i])))
            if nav.arrival_radius >= gap:
                validation.fail("navigation.arrival_radius", nav.arrival_radius,
                      f"must be below the {gap:.6g} m between the start and the destination of {where} "
                      f"({pt.name}); the vehicle would arrive before it moves")
            if nav.max_steps == 0:
                length = float(np.sum(np.hypot(*np.diff([cents[c] for c in pt.clusters], axis=0).T)))
                steps = 3.0 * length * (1.0 + self.bmm.terrain_effect) / (nav.cruise_speed * self.bmm.dt) + 200
                if steps > MAX_STEPS:
                    validation.fail("navigation.cruise_speed", nav.cruise_speed,
                          f"with bmm.dt = {self.bmm.dt:g} s and bmm.terrain_effect = {self.bmm.terrain_effect:g}, "
                          f"{where} ({length:.6g} m) needs {steps:.3g} steps, more than {MAX_STEPS}; "
                          f"raise the speed or set navigation.max_steps")
        in_range = {}      # per cluster: its landmarks within range of its centroid (3D distance)
        for c, lms in groups.items():
            xyz = np.array([(*lm.xy, lm.height) for lm in lms])
            in_range[c] = int(np.sum(np.hypot(np.hypot(*(xyz[:, :2] - cents[c]).T), xyz[:, 2])
                                     <= self.detection.max_range_m))
        for i, pt in enumerate(paths):
            for k, c in enumerate(pt.clusters):
                if in_range[c] < self.detection.min_landmarks:
                    validation.fail(f"path_types[{i}].clusters[{k}]", c,
                          f"cluster {c} has {in_range[c]} landmark(s) within detection.max_range_m = "
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
        d = validation.table("scenario", data, required=("world", "path_types"),
                   optional=("schema_version", "name", "description", *_SECTIONS))
        if "schema_version" in d:
            validation.integer("schema_version", d["schema_version"], 0, field=True)
            if d["schema_version"] != SCHEMA_VERSION:
                validation.fail("schema_version", d["schema_version"], f"unsupported (this safenav reads {SCHEMA_VERSION})")
        kw: dict[str, Any] = {}
        for key, sec in _SECTIONS.items():
            if key in d:
                with validation.at(key):
                    kw[key] = sec.from_dict(d[key])
        with validation.at("world"):
            kw["world"] = World.from_dict(d["world"])
        paths = []
        for i, p in enumerate(validation.items("path_types", d["path_types"], MAX_PATH_TYPES)):
            with validation.at(f"path_types[{i}]"):
                t = validation.table("", p, required=("name", "clusters"), optional=("start", "destination"))
                pt = PathType(t["name"], t["clusters"])
                for key, want, k in (("start", pt.start, 0), ("destination", pt.destination, -1)):
                    if key in t and (isinstance(t[key], bool) or t[key] != want):
                        validation.fail(key, t[key], f"must equal clusters[{k}] = {want}")
                paths.append(pt)
        kw["path_types"] = tuple(paths)
        for key in ("name", "description"):
            if key in d:
                kw[key] = d[key]
        return cls(**kw)


# ---------------------------------------------------------------------------- files

def _is_json(path: Path) -> bool:
    return path.suffix.lower() == ".json"


MAX_FILE_BYTES = 8 * 2**20    #: the largest scenario file read
MAX_DEPTH = 8                  #: tables and lists nested in a scenario (a polygon's vertex is 6 deep)


def _read(path: Path) -> bytes:
    """The bytes of the regular file ``path``, at most ``MAX_FILE_BYTES``.

    Opened non-blocking and checked with ``fstat`` before reading, so a FIFO,
    a device (``/dev/zero``, also through a symlink) or a directory is
    refused at once instead of blocking or filling memory."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except OSError as exc:
        raise ScenarioError(f"{path}: cannot read the scenario file: {exc.strerror}") from None
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            raise ScenarioError(f"{path}: not a regular file (mode {stat.filemode(mode)}); "
                                "a scenario must be a regular file")
        raw = b""
        while len(raw) <= MAX_FILE_BYTES and (chunk := os.read(fd, MAX_FILE_BYTES + 1 - len(raw))):
            raw += chunk
    finally:
        os.close(fd)
    if len(raw) > MAX_FILE_BYTES:
        raise ScenarioError(f"{path}: larger than the {MAX_FILE_BYTES} bytes a scenario file may have")
    return raw


class _Pairs(dict):
    """A JSON object that remembers its first repeated key (``object_pairs_hook``)."""

    def __init__(self, pairs):
        super().__init__()
        self.repeated = None
        for k, v in pairs:
            if k in self and self.repeated is None:
                self.repeated = k
            self[k] = v


def _check_tree(data) -> None:
    """Reject nesting deeper than ``MAX_DEPTH`` and repeated JSON keys, naming the field path."""
    todo = [(data, "", 0)] if isinstance(data, (dict, list)) else []
    while todo:
        node, where, depth = todo.pop()
        if depth > MAX_DEPTH:
            raise ScenarioError(f"{where} = {validation.cut(node)}: nested deeper than {MAX_DEPTH} levels")
        if isinstance(node, dict):
            if getattr(node, "repeated", None) is not None:
                k = node.repeated
                raise ScenarioError(f"{validation.join(where, k[:40])} = {validation.cut(node[k])}: "
                                    "the key appears twice in its table")
            todo.extend((v, validation.join(where, str(k)[:40]), depth + 1) for k, v in node.items()
                        if isinstance(v, (dict, list)))
        else:
            todo.extend((v, f"{where}[{i}]", depth + 1) for i, v in enumerate(node) if isinstance(v, (dict, list)))


_KEY = re.compile(r"""(?m)^[ \t]*\[{1,2}[ \t]*([A-Za-z0-9_.-]+)[ \t]*\]|["']?([A-Za-z0-9_.-]+)["']?[ \t]*[:=]""")
_DIGITS = re.compile(r"[0-9_]{1000,}")


def _where(text: str, pos: int) -> str:
    """The key (TOML: ``table.key``) last named before offset ``pos`` of ``text``, and its line."""
    table, key = "", ""
    for m in _KEY.finditer(text, 0, pos):
        if m.group(1):
            table, key = m.group(1), ""
        else:
            key = m.group(2)
    name = ".".join(x for x in (table, key) if x) or "(top level)"
    return f"{name[:60]} (line {text.count(chr(10), 0, pos) + 1})"


def _deepest(text: str) -> int:
    """Offset where brackets first nest deeper than ``MAX_DEPTH`` (quoted strings skipped), else 0."""
    depth = 0
    for m in re.finditer(r'"(?:\\.|[^"\\\n])*"|\'[^\'\n]*\'|[\[{]|[\]}]', text):
        c = m.group()
        depth += 1 if c in "[{" else -1 if c in "]}" else 0
        if depth > MAX_DEPTH + 1:
            return m.start()
    return 0


def _parse(raw: bytes, path: Path):
    fmt = "JSON" if _is_json(path) else "TOML"
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ScenarioError(f"{path}: not UTF-8 text: byte {exc.start} = {raw[exc.start]:#04x}") from None
    try:
        return json.loads(text, object_pairs_hook=_Pairs) if fmt == "JSON" else tomllib.loads(text)
    except RecursionError:
        raise ScenarioError(f"{path}: {_where(text, _deepest(text))}: nested deeper than {MAX_DEPTH} levels") from None
    except json.JSONDecodeError as exc:
        raise ScenarioError(f"{path}: {_where(text, exc.pos)}: not a valid JSON file: {exc.msg[:100]}") from None
    except tomllib.TOMLDecodeError as exc:
        m = re.search(r"\(at line (\d+), column (\d+)\)", str(exc))
        pos = sum(len(x) + 1 for x in text.split("\n", int(m[1]) - 1)[:-1]) + int(m[2]) - 1 if m else 0
        raise ScenarioError(f"{path}: {_where(text, pos)}: not a valid TOML file: {str(exc)[:150]}") from None
    except ValueError as exc:     # Python's int-from-text digit limit (sys.get_int_max_str_digits)
        m = _DIGITS.search(text)
        if not m:
            raise ScenarioError(f"{path}: not a valid {fmt} file: {str(exc)[:150]}") from None
        raise ScenarioError(f"{path}: {_where(text, m.start())}: a number of {len(m.group())} digits; "
                            "no field takes more than 19") from None


def load_scenario(path) -> Scenario:
    """Read and validate a scenario file (TOML, or JSON by suffix).

    Only a regular file of at most ``MAX_FILE_BYTES`` is read; repeated keys
    (TOML and JSON) and nesting deeper than ``MAX_DEPTH`` are refused; then
    :meth:`Scenario.from_dict` checks every field against its range and every
    list against its size limit (docs/scenario.md).  Every problem is one
    :class:`ScenarioError` line naming the file, the field and the value."""
    path = Path(path)
    data = _parse(_read(path), path)
    try:
        _check_tree(data)
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
