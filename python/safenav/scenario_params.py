"""The parameter sections of a scenario file (``[seeds]``, ``[camera]``,
``[detection]``, ``[bmm]``, ``[noise]``, ``[planner]``, ``[buffer]``,
``[navigation]``; layout in :mod:`safenav.scenario`, every field's range in
docs/scenario.md).

Most fields are parameters declared in the core (``safenav/params.hpp``):
their defaults, ranges and documentation come from the declaration
(:func:`_core_section`), none is repeated here.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from . import _core
from . import validation
from .validation import Range

__all__ = ["CameraParams", "DetectionParams", "BmmConfig", "NoiseParams", "PlannerParams", "BufferParams", "Seeds",
           "SECTIONS", "MAX_STEPS", "MAX_ITERATIONS", "MAX_PATH_TYPES", "MAX_DESCRIPTION", "FIX_MODELS", "GUARD_MODES",
           "RANGINGS"]


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
    #: how the camera loop's front end ranges a marker: "corners" (ours: its refined corners
    #: triangulated) or "sgbm" (the paper's SGBM box median, [SafeNav §IV-A])
    ranging: str = "corners"

    RANGES = {"focal_length_px": _r(0, 1e5, True), "baseline_m": _r(0, 10, True),
              "image_width_px": _n(1, 100_000), "image_height_px": _n(1, 100_000),
              "field_of_view_deg": _r(0, 360, True)}

    def __post_init__(self):
        _Params.__post_init__(self)
        object.__setattr__(self, "ranging", validation.choice("ranging", self.ranging, RANGINGS))


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
RANGINGS = {"corners": "corners", "sgbm": "sgbm"}   #: camera.ranging: the camera loop's LanBLocRanging
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
    "Hazards (ours): ``hazard_weight`` (beta_h) adds beta_h * integral of risk ds over the hazards; 5 by default "
    "in a scenario, so that our loop plans round hazards; the papers' configuration (``--loop paper``, "
    "``safenav experiment``) plans with 0, the paper's cost.  Hazards with risk >= ``forbidden_risk`` are "
    "obstacles (above 1 = none, the paper).",
    [(_core.PlannerSettings, "alpha"), (_core.PlannerSettings, "beta"), (_core.PlannerSettings, "hazard_weight"),
     (_core.PlanningMap, "forbidden_risk")], defaults={"hazard_weight": 5.0})


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
    :class:`safenav.GuardSettings`) keeps k position sigmas clear of
    obstacles and forbidden hazards.  k follows from the mission's risk
    budget ``collision_probability`` and its path (docs/safety.md) unless
    ``guard_k`` > 0 sets it (0, the default: from the budget).  A command
    stops the vehicle while an input is older than ``input_timeout`` (0 or
    inf: off).  The papers' loop: ``guard = 'off'`` and
    ``gate_probability = 0``.""",
    [(_NAV, "cruise_speed"), (_NAV, "arrival_radius"), (_NAV, "segment_length"), (_NAV, "sub_segments"),
     (_NAV, "lookahead"), (_NAV, "step_back_speed"), (_NAV, "sensing_range"), (_NAV, "replan_lookahead"),
     ("vehicle_radius", _core.Inflation, "vehicle_radius"), ("clearance_margin", _core.Inflation, "margin"),
     ("plan_iterations", _core.PlannerSettings, "max_iterations"),
     (_NAV, "replan_iterations"), (_NAV, "corridor_bias"), (_NAV, "lost_position_std"), (_NAV, "max_steps"),
     (_NAV, "gate_probability"), (_NAV, "collision_probability"), (_NAV, "guard_k"), (_NAV, "guard_buffer"),
     (_NAV, "guard_slow_distance"), (_NAV, "guard_min_speed_fraction"), (_NAV, "guard_horizon"),
     (_NAV, "input_timeout")],
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


#: The sections by their table names, in the order a scenario file lists them.
SECTIONS: dict[str, type] = {
    "seeds": Seeds, "camera": CameraParams, "detection": DetectionParams, "bmm": BmmConfig,
    "noise": NoiseParams, "planner": PlannerParams, "buffer": BufferParams, "navigation": NavigationParams,
}
