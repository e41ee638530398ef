"""Scenario files: round trips, every kind of malformed file, the shipped default."""

import copy
import dataclasses
import math
import os
from pathlib import Path

import numpy as np
import pytest
import tomli_w

import safenav
from safenav.generate import DEFAULT_SEED, GeneratorConfig, generate_scenario
from safenav.scenario import (_SECTIONS, MAX_DEPTH, MAX_FILE_BYTES, BmmConfig, BufferParams, NavigationParams,
                              NoiseParams, PlannerParams, Scenario, ScenarioError, default_scenario, dumps_scenario, load_scenario, save_scenario)
from safenav.world import Circle


@pytest.fixture(scope="module")
def base() -> dict:
    return default_scenario().to_dict()


def test_default_scenario_loads_and_is_the_generated_one():
    s = default_scenario()
    assert isinstance(s, Scenario) and s.name == "real-imitated"
    assert len(s.world.obstacles) == 25 and len(s.world.hazards) == 25
    assert [p.name for p in s.path_types] == ["P1", "P2", "P3"]
    assert {p.destination for p in s.path_types} == {3}
    assert s.seeds.world == DEFAULT_SEED
    # the committed file is exactly what the generator makes (regenerate with `python -m safenav.generate`)
    assert s == generate_scenario(DEFAULT_SEED)
    assert s.noise.lanbloc_std == safenav.LANBLOC_STD


def test_round_trip_toml_and_json_is_exact(tmp_path):
    s = default_scenario()
    odd = dataclasses.replace(
        s, description="line one\nline \"two\" ü",
        planner=PlannerParams(alpha=0.1 + 0.2, beta=1 / 3),
        noise=NoiseParams(lanbloc_std=(1e-6, 0.1 + 0.2), imu_speed_std=math.pi, imu_heading_std=1e-6),
        buffer=BufferParams(half_width=7.000000000000001, weights=(1.5, 1.5, 2.0)))
    for sc in (s, odd):
        for name in ("a.toml", "a.json"):
            path = save_scenario(sc, tmp_path / name)
            back = load_scenario(path)
            assert back == sc
            assert back.planner.alpha == sc.planner.alpha     # bit-exact floats
            assert back.to_dict() == sc.to_dict()
        assert Scenario.from_dict(sc.to_dict()) == sc
        assert Scenario.from_dict(copy.deepcopy(sc.to_dict())).to_dict() == sc.to_dict()


def test_save_is_atomic_and_leaves_no_temp_files(tmp_path, monkeypatch):
    s = default_scenario()
    path = tmp_path / "s.toml"
    save_scenario(s, path)
    before = path.read_bytes()
    save_scenario(s, path)                      # overwrite
    assert path.read_bytes() == before
    assert sorted(os.listdir(tmp_path)) == ["s.toml"]

    def boom(*a, **k):
        raise OSError("disk full")
    monkeypatch.setattr(os, "replace", boom)
    with pytest.raises(OSError, match="disk full"):
        save_scenario(dataclasses.replace(s, name="other"), path)
    assert path.read_bytes() == before          # the old file is untouched
    assert sorted(os.listdir(tmp_path)) == ["s.toml"]
    with pytest.raises(TypeError):
        dumps_scenario({"name": "x"})


def test_params_map_to_the_core_types():
    s = default_scenario()
    core = safenav.BmmParams()
    d = BmmConfig()
    for f in dataclasses.fields(BmmConfig):
        assert getattr(d, f.name) == getattr(core, f.name), f.name
    p = dataclasses.replace(s, bmm=BmmConfig(max_speed=4.5, dt=0.1)).bmm_params()
    assert isinstance(p, safenav.BmmParams) and p.max_speed == 4.5 and p.dt == 0.1
    z = s.risk_zones()
    assert z.half_width == s.buffer.half_width and list(z.weights) == [2.0, 4.0, 6.0, 8.0]
    pl = s.path_polyline("P2")
    np.testing.assert_array_equal(pl[0], s.world.cluster_centroid(4))
    with pytest.raises(KeyError, match="P9"):
        s.path_type("P9")


def test_docs_state_every_range():
    """docs/scenario.md gives each parameter's range exactly as the code checks it."""
    doc = (Path(__file__).resolve().parents[1] / "docs" / "scenario.md").read_text(encoding="utf-8")
    rows = {line.split("|")[1].strip(): line for line in doc.splitlines() if line.startswith("| `")}
    n = 0
    for key, cls in _SECTIONS.items():
        for name, rng in cls.RANGES.items():
            assert f"| {rng} |" in rows[f"`{key}.{name}`"], (key, name, str(rng))
            n += 1
    assert n == 54
    flags = [(key, name) for key, cls in _SECTIONS.items() for name in getattr(cls, "FLAGS", ())]
    assert sorted(flags) == [("bmm", "unicycle"), ("detection", "occlusion")]    # the bool fields: their rows say what they take
    for key, name in flags:
        assert "| true or false |" in rows[f"`{key}.{name}`"]
    assert f"| {NavigationParams.CLEARANCE} |" in rows["`navigation.clearance`"]
    assert f"each {NoiseParams.LANBLOC_STD} |" in rows["`noise.lanbloc_std`"]
    assert f"each {BufferParams.WEIGHT}, not decreasing |" in rows["`buffer.weights`"]
    assert f"at most {MAX_FILE_BYTES // 2**20} MiB" in doc and f"at most {MAX_DEPTH} levels" in doc


def test_generator_stays_within_the_limits():
    with pytest.raises(ValueError, match=r"size = 200000.0: must be a number in \[1, 100000\]"):
        GeneratorConfig(size=2e5)
    with pytest.raises(ValueError, match=r"n_hazards = 1001: must be an integer in \[0, 1000\]"):
        GeneratorConfig(n_hazards=1001)
    s = generate_scenario(11, GeneratorConfig(size=120.0, n_obstacles=12, n_hazards=8, n_blocking=3))
    assert Scenario.from_dict(s.to_dict()) == s and s.world.field.width == 120.0


def _centroid(base, cluster):
    xy = [lm["position"][:2] for lm in base["world"]["landmarks"] if lm["cluster"] == cluster]
    return [float(v) for v in np.mean(xy, axis=0)]


def _edge_circle(d):
    d["world"]["obstacles"][3] = {"type": "circle", "center": [197.0, 100.0], "radius": 5.0}


def _edge_polygon(d):
    d["world"]["obstacles"][2] = {"type": "polygon", "vertices": [[190.0, 10.0], [205.0, 12.0], [195.0, 20.0]]}


def _start_in_obstacle(d):
    d["world"]["obstacles"].append({"type": "circle", "center": _centroid(d, 6), "radius": 1.0})


def _thin_cluster(d):
    lms = [lm for lm in d["world"]["landmarks"] if lm["cluster"] == 5]
    for lm in lms[1:]:
        lm["cluster"] = 42


def _set(path, value):
    def mutate(d):
        *head, last = path
        t = d
        for k in head:
            t = t[k]
        t[last] = value
    return mutate


CASES = [
    # (mutation, substrings the message must contain)
    (_set(["colour"], "red"), ["colour = 'red'", "unknown key"]),
    (_set(["camera", "colour"], 1), ["camera.colour = 1", "unknown key"]),
    (_set(["world", "obstacles", 3, "colour"], 1), ["world.obstacles[3].colour", "unknown key"]),
    (_set(["world", "landmarks", 0, "name"], "x"), ["world.landmarks[0].name", "unknown key"]),
    (_set(["camera", "focal_length_px"], "1400"), ["camera.focal_length_px = '1400'", "number"]),
    (_set(["camera", "image_width_px"], 2560.5), ["camera.image_width_px = 2560.5", "integer"]),
    (_set(["planner", "alpha"], True), ["planner.alpha = True", "number"]),
    (_set(["world", "obstacles", 0, "radius"], float("nan")), ["world.obstacles[0].radius = nan", "finite"]),
    (_set(["bmm", "dt"], float("inf")), ["bmm.dt = inf", "finite"]),
    (_set(["bmm", "max_speed"], -1.0), ["bmm.max_speed = -1.0"]),
    (_set(["world", "obstacles", 0, "radius"], -2.0), ["world.obstacles[0].radius = -2.0", "(0, 100000]"]),
    (_set(["world", "field", "x_max"], -5.0), ["world.field.x_max = -5.0", "width"]),
    (_set(["world", "field", "y_max"], 0.0), ["world.field.y_max = 0.0", "height"]),
    (_set(["world", "field", "x_min"], float("nan")), ["world.field.x_min = nan"]),
    (_edge_circle, ["world.obstacles[3].radius = 5.0", "outside the field"]),
    (_edge_polygon, ["world.obstacles[2].vertices[1] = (205.0, 12.0)", "outside the field"]),
    (_set(["world", "landmarks", 5, "position"], [250.0, 10.0]), ["world.landmarks[5].position", "250.0"]),
    (_set(["world", "landmarks", 5, "position"], [1.0]), ["world.landmarks[5].position = [1.0]"]),
    (_set(["world", "landmarks", 1, "id"], 1), ["world.landmarks[1].id = 1", "duplicates"]),
    (_set(["world", "obstacles", 0, "type"], "triangle"), ["world.obstacles[0].type = 'triangle'"]),
    (_set(["world", "obstacles", 1, "vertices"], [[1.0, 1.0], [2.0, 2.0]]), ["world.obstacles[1].vertices", "3"]),
    (_set(["world", "obstacles", 0], {"type": "circle", "center": [5.0, 5.0]}), ["world.obstacles[0].radius", "missing"]),
    (_set(["world", "hazards", 2, "risk"], 1.5), ["world.hazards[2].risk = 1.5"]),
    (_set(["world", "obstacles"], {"type": "circle"}), ["world.obstacles", "must be a list"]),
    (_start_in_obstacle, ["path_types[0].clusters[0] = 6", "start", "within navigation.clearance = 2 m of world.obstacles[25]"]),
    (_set(["path_types", 1, "clusters"], [4, 1, 42, 3]), ["path_types[1].clusters[2] = 42", "unknown cluster"]),
    (_set(["path_types", 0, "start"], 5), ["path_types[0].start = 5", "clusters[0] = 6"]),
    (_set(["path_types", 2, "name"], "P1"), ["path_types[2].name = 'P1'", "duplicates"]),
    (_set(["path_types"], []), ["path_types", "at least one"]),
    (_thin_cluster, ["path_types[0].clusters[1] = 5", "1 landmark(s)", "min_landmarks = 3"]),
    (_set(["detection", "max_range_m"], 0.5), ["path_types[0].clusters[0] = 6", "0 landmark(s)"]),
    (_set(["buffer", "weights"], [2.0, 4.0, 3.0, 8.0]), ["buffer.weights[2] = 3.0"]),
    (_set(["noise", "lanbloc_std"], [0.01, -0.03]), ["noise.lanbloc_std[1] = -0.03"]),
    (_set(["seeds", "world"], -1), ["seeds.world = -1"]),
    (_set(["schema_version"], 2), ["schema_version = 2", "unsupported"]),
    (_set(["world", "landmarks", 0, "class"], ""), ["world.landmarks[0].class = ''"]),
]


@pytest.mark.parametrize("mutate, needles", CASES, ids=[n[0] for _, n in CASES])
def test_malformed_file_names_field_and_value(tmp_path, base, mutate, needles):
    d = copy.deepcopy(base)
    mutate(d)
    path = tmp_path / "bad.toml"
    path.write_text(tomli_w.dumps(d))
    with pytest.raises(ScenarioError) as exc:
        load_scenario(path)
    msg = str(exc.value)
    assert msg.startswith(f"{path}: ")
    for n in needles:
        assert n in msg, msg
    assert isinstance(exc.value, ValueError)


def test_missing_world_bad_syntax_and_json_nan(tmp_path, base):
    d = copy.deepcopy(base)
    del d["world"]
    p = tmp_path / "a.toml"
    p.write_text(tomli_w.dumps(d))
    with pytest.raises(ScenarioError, match="world: missing"):
        load_scenario(p)
    p.write_text("name = \n")
    with pytest.raises(ScenarioError, match="not a valid TOML"):
        load_scenario(p)
    j = tmp_path / "a.json"
    j.write_text(dumps_scenario(default_scenario(), json_format=True).replace('"alpha": 1.0', '"alpha": NaN'))
    with pytest.raises(ScenarioError, match=r"planner.alpha = nan"):
        load_scenario(j)
    with pytest.raises(ScenarioError, match="cannot read"):
        load_scenario(tmp_path / "missing.toml")


def test_minimal_hand_written_file_gets_defaults(tmp_path):
    p = tmp_path / "mini.toml"
    p.write_text("""
[[path_types]]
name = "A"
clusters = [1, 2]

[world.field]
x_max = 50
y_max = 50

[[world.obstacles]]
type = "circle"
center = [25, 25]
radius = 3

[[world.landmarks]]
id = 1
position = [5, 5]
cluster = 1
[[world.landmarks]]
id = 2
position = [7, 5]
cluster = 1
[[world.landmarks]]
id = 3
position = [6, 8]
cluster = 1
[[world.landmarks]]
id = 4
position = [40, 40, 2.5]
cluster = 2
[[world.landmarks]]
id = 5
position = [42, 40]
cluster = 2
[[world.landmarks]]
id = 6
position = [41, 43]
cluster = 2
""")
    s = load_scenario(p)
    assert s.world.field.x_max == 50.0 and s.bmm == BmmConfig() and s.detection.min_landmarks == 3
    assert s.world.obstacles == (Circle((25.0, 25.0), 3.0),)
    assert s.world.landmarks[3].position == (40.0, 40.0, 2.5)
    assert s.world.segment_hits_obstacle(*s.path_polyline("A"))
