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
from dataclasses import dataclass, field
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w

from . import validation
from .validation import ScenarioError
from .world import Circle, Field, Hazard, Landmark, PathType, Polygon, World  # noqa: F401
from .scenario_params import (SECTIONS, FIX_MODELS, GUARD_MODES, MAX_DESCRIPTION, MAX_ITERATIONS,  # noqa: F401
                              MAX_PATH_TYPES, MAX_STEPS, BmmConfig, BufferParams, CameraParams, DetectionParams,
                              NavigationParams, NoiseParams, PlannerParams, Seeds)

__all__ = [
    "ScenarioError", "CameraParams", "DetectionParams", "BmmConfig", "NoiseParams", "PlannerParams",
    "BufferParams", "NavigationParams", "Seeds", "Scenario", "load_scenario", "save_scenario", "default_scenario",
    "SCHEMA_VERSION",
]

SCHEMA_VERSION = 1
_SECTIONS = SECTIONS   # the name the tests and older callers use


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
        for key, cls in SECTIONS.items():
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
        for key in SECTIONS:
            out[key] = getattr(self, key).to_dict()
        out["path_types"] = [pt.to_dict() for pt in self.path_types]
        out["world"] = self.world.to_dict()
        return out

    @classmethod
    def from_dict(cls, data) -> "Scenario":
        """Validate and build; a :class:`ScenarioError` names the field path and the value."""
        d = validation.table("scenario", data, required=("world", "path_types"),
                   optional=("schema_version", "name", "description", *SECTIONS))
        if "schema_version" in d:
            validation.integer("schema_version", d["schema_version"], 0, field=True)
            if d["schema_version"] != SCHEMA_VERSION:
                validation.fail("schema_version", d["schema_version"], f"unsupported (this safenav reads {SCHEMA_VERSION})")
        kw: dict[str, Any] = {}
        for key, sec in SECTIONS.items():
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
