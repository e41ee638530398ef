"""Each parameter is declared once, in the core (safenav/params.hpp): its name,
unit, range and meaning beside the struct whose member initialiser is the
default.  The scenario sections, validate() and the generic get/set all read
that one declaration."""
from __future__ import annotations

import dataclasses
import math
import re

import pytest

from safenav import _core
from safenav.scenario import (_SECTIONS, BmmConfig, BufferParams, DetectionParams, NavigationParams, NoiseParams,
                              PlannerParams, default_scenario)

CORE_TYPES = (_core.BmmParams, _core.RiskZones, _core.PlannerSettings, _core.PlanningMap,
              _core.NavigationSettings, _core.SensorSettings, _core.LocalizerSettings, _core.AugmentedStates,
              _core.GuardSettings, _core.FilterOptions, _core.PositionNoise, _core.SegmentOptions,
              _core.LocalizationOptions, _core.BoxRangeOptions)


@pytest.mark.parametrize("core_type", CORE_TYPES, ids=lambda t: t.__name__)
def test_every_declaration_is_complete_and_its_default_in_range(core_type):
    specs = core_type.params()
    assert specs and len({s.name for s in specs}) == len(specs)
    default = core_type()
    default.check_params()                       # the member initialisers lie in the declared ranges
    for s in specs:
        assert s.doc and s.hi >= s.lo, s.name
        v = default.get_param(s.name)
        if s.kind == _core.ParamKind.INTEGER:
            assert isinstance(v, int) and s.lo <= v <= s.hi, s.name
        elif s.kind == _core.ParamKind.REAL_LIST:
            assert 1 <= len(v) <= s.max_size and all(s.lo < x <= s.hi for x in v), s.name
        elif s.kind == _core.ParamKind.BOOLEAN:
            assert isinstance(v, bool) and (s.lo, s.hi) == (0, 1), s.name
        else:
            assert isinstance(v, float) and (s.lo < v if s.lo_open else s.lo <= v) and v <= s.hi, s.name


@pytest.mark.parametrize("core_type", CORE_TYPES, ids=lambda t: t.__name__)
def test_set_param_checks_the_declared_range_at_its_ends(core_type):
    for s in core_type.params():
        obj = core_type()
        if s.kind == _core.ParamKind.BOOLEAN:       # a switch: True or False, nothing else
            for good in (True, False):
                obj.set_param(s.name, good)
                assert obj.get_param(s.name) is good, s.name
            for bad in (1, 0.0, "true", None):
                with pytest.raises(TypeError, match=rf"{s.name}: .* is not a bool"):
                    obj.set_param(s.name, bad)
            continue
        ok_lo = math.nextafter(s.lo, math.inf) if s.lo_open else s.lo
        if s.kind == _core.ParamKind.INTEGER:
            ok_lo = math.ceil(ok_lo)
        for good in (ok_lo, s.hi):
            value = [good] if s.kind == _core.ParamKind.REAL_LIST else good
            obj.set_param(s.name, value)
            got = obj.get_param(s.name)
            assert (got[0] if s.kind == _core.ParamKind.REAL_LIST else got) == good, s.name
        bad_lo = s.lo if s.lo_open else (s.lo - 1 if s.kind == _core.ParamKind.INTEGER else math.nextafter(s.lo, -math.inf))
        # an infinite hi is "no limit" (inf itself means "none"): nothing lies above it
        for bad in (bad_lo, math.nan) + ((s.hi * 2 + 1,) if math.isfinite(s.hi) else ()):
            value = [bad] if s.kind == _core.ParamKind.REAL_LIST else bad
            label = f"{s.name}\\[0\\]" if s.kind == _core.ParamKind.REAL_LIST else s.name
            with pytest.raises(ValueError, match=rf"^{label} = .*: must be .*in [\[(]"):
                obj.set_param(s.name, value)
        if s.kind == _core.ParamKind.INTEGER:
            with pytest.raises(ValueError, match=rf"{s.name} = .*: must be an integer"):
                obj.set_param(s.name, ok_lo + 0.5)
        what = "a list of numbers" if s.kind == _core.ParamKind.REAL_LIST else "a number"
        for wrong_type in (None, "1.0" if s.kind != _core.ParamKind.REAL_LIST else ["a"], object()):
            with pytest.raises(TypeError, match=rf"^{s.name}: .* is not {what}$"):
                obj.set_param(s.name, wrong_type)


def test_names_kinds_and_errors():
    n = _core.NavigationSettings()
    with pytest.raises(ValueError, match=r"unknown parameter 'speed' \(known: cruise_speed, arrival_radius"):
        n.set_param("speed", 1.0)
    with pytest.raises(TypeError, match="True is not a number"):
        n.set_param("cruise_speed", True)
    with pytest.raises(ValueError, match=r"weights: needs 1 to 64 entries, got 0"):
        _core.RiskZones().set_param("weights", [])
    # parameters of nested structs are reached through the declaration
    n.set_param("segment_length", 7.5)
    n.set_param("replan_iterations", 1234)
    n.set_param("corridor_bias", 0.25)
    assert n.segments.length == 7.5 and n.planner.max_iterations == 1234 and n.planner.corridor_bias == 0.25
    assert n.get_param("replan_iterations") == 1234
    # validate() checks the declared ranges too, naming the field as the navigator sees it
    n.cruise_speed = 1000.0
    with pytest.raises(ValueError, match=r"settings.cruise_speed = 1000: must be in \[0.01, 100\] m/s"):
        n.validate()
    b = _core.BmmParams()
    b.dt = 11.0
    with pytest.raises(ValueError, match=r"dt = 11: must be in \(0, 10\] s"):
        _core.Bmm(b)
    assert str(_core.BmmParams.params()[0]) == "ParamSpec(acceleration in (0, 100] m/s^2)"


#: scenario defaults that differ from the core struct's, on purpose (scenario_params.py says why):
#: a scenario plans round hazards (our loop), the core's PlannerSettings keeps the paper's cost
#: (navigation's 2 m clearance is the core's Inflation default, vehicle_radius + margin = 1 + 1)
OVERRIDES: dict = {("planner", "hazard_weight"): 5.0}


@pytest.mark.parametrize("key", sorted(_SECTIONS))
def test_scenario_sections_mirror_nothing(key):
    """A section's core-declared fields take name mapping, default and range
    from the core; only the listed overrides differ."""
    cls = _SECTIONS[key]
    d = cls()
    for name, (core_type, core_name) in getattr(cls, "CORE", {}).items():
        spec = next(s for s in core_type.params() if s.name == core_name)
        if spec.kind == _core.ParamKind.BOOLEAN:
            assert name in cls.FLAGS and getattr(d, name) is core_type().get_param(core_name), (key, name)
            continue
        rng = cls.LISTS[name][0] if name in cls.LISTS else cls.RANGES[name]
        assert (rng.lo, rng.hi, rng.lo_open, rng.integer) == (
            spec.lo, spec.hi, spec.lo_open, spec.kind == _core.ParamKind.INTEGER), (key, name)
        core_default = core_type().get_param(core_name)
        expect = OVERRIDES.get((key, name), tuple(core_default) if isinstance(core_default, list) else core_default)
        assert getattr(d, name) == expect, (key, name)


def test_sections_apply_onto_the_core_structs():
    s = default_scenario()
    nav = dataclasses.replace(s.navigation, segment_length=12.5, replan_iterations=777, lookahead=3.0)
    core = nav.apply(_core.NavigationSettings())
    assert (core.segments.length, core.planner.max_iterations, core.lookahead) == (12.5, 777, 3.0)
    se = DetectionParams(max_range_m=12.0, min_landmarks=4).apply(_core.SensorSettings())
    assert (se.max_range, se.min_landmarks) == (12.0, 4)
    NoiseParams(imu_speed_std=0.2).apply(se)
    assert se.imu_speed_std == 0.2
    assert BmmConfig(dt=0.1).to_params().dt == 0.1
    assert list(BufferParams(half_width=3.0).risk_zones().weights) == [2.0, 4.0, 6.0, 8.0]
    p = PlannerParams(alpha=2.0).apply(_core.PlannerSettings())
    assert (p.alpha, p.beta) == (2.0, 1.0)
    # each field goes to the struct that declares it: plan_iterations is the safe path's planner budget,
    # corridor_bias the navigator's detours' (plan_safe_path passes it on explicitly)
    p = NavigationParams(plan_iterations=42, corridor_bias=0.9).apply(_core.PlannerSettings())
    assert (p.max_iterations, p.corridor_bias) == (42, _core.PlannerSettings().corridor_bias)


def test_the_safe_path_planner_gets_every_scenario_setting(monkeypatch):
    from safenav import navigation

    seen = {}

    def fake_plan(problem, settings):
        seen["s"], seen["p"] = settings, problem
        raise StopIteration

    monkeypatch.setattr(navigation, "plan", fake_plan)
    s = default_scenario()
    s = dataclasses.replace(s, navigation=dataclasses.replace(s.navigation, corridor_bias=0.3, plan_iterations=99,
                                                              clearance=1.5),
                            planner=PlannerParams(alpha=2.0, beta=0.5, hazard_weight=2.0, forbidden_risk=0.7))
    with pytest.raises(StopIteration):
        navigation.plan_safe_path(s, "P1", seed=7)
    st = seen["s"]
    assert (st.corridor_bias, st.max_iterations, st.alpha, st.beta, st.seed, st.smooth) == (0.3, 99, 2.0, 0.5, 7, True)
    assert seen["p"].map.clearance == 1.5 and seen["p"].zones.half_width == s.buffer.half_width
    # the hazards reach the planner's map, with the scenario's weight and forbidden level
    assert st.hazard_weight == 2.0
    assert seen["p"].map.forbidden_risk == 0.7 and len(seen["p"].map.hazards) == len(s.world.hazards)


def test_every_struct_validates_its_declared_ranges():
    with pytest.raises(ValueError, match=r"RiskZones.half_width = 2000: must be in \(0, 1000\] m"):
        _core.RiskZones(half_width=2000.0)
    with pytest.raises(ValueError, match=r"clearance = 200: must be in \[0, 100\] m"):
        _core.PlanningMap(clearance=200.0)
    with pytest.raises(ValueError, match=r"max_iterations = 2000000: must be an integer in \[1, 1000000\]"):
        _core.PlannerSettings(max_iterations=2_000_000)
    s = _core.SensorSettings()
    s.min_landmarks = 0
    with pytest.raises(ValueError, match=r"sensors.min_landmarks = 0: must be an integer in \[1, 1000\]"):
        s.validate()


# --------------------------------------------------------------------------- nested sets: each field declared once

#: (outer struct, its member, the inner struct, prefix, names that keep a scenario key other than prefix + name)
NESTED = [(_core.NavigationSettings, "guard", _core.GuardSettings, "guard_", {}),
          (_core.NavigationSettings, "filter", _core.FilterOptions, "filter_", {"gate_probability": "gate_probability"}),
          (_core.NavigationSettings, "segments", _core.SegmentOptions, "segment_", {"sub_segments": "sub_segments"}),
          (_core.LocalizerSettings, "filter", _core.FilterOptions, "filter_", {"gate_probability": "gate_probability"}),
          (_core.LocalizerSettings, "bmm", _core.BmmParams, "bmm_", {}),
          (_core.LocalizerSettings, "augment", _core.AugmentedStates, "augment_", {})]


def _spec_key(s):
    return (s.kind, s.unit, s.lo, s.hi, s.lo_open, s.max_size, s.doc)


@pytest.mark.parametrize("outer, member, inner, prefix, rename", NESTED,
                         ids=lambda v: v if isinstance(v, str) and v else getattr(v, "__name__", None))
def test_a_nested_struct_is_declared_once_and_reached_through_the_outer_set(outer, member, inner, prefix, rename):
    """Every parameter of the inner struct appears in the outer set, with the
    inner declaration's range, unit and doc, under prefix + name (or its kept
    scenario key), and reads and writes the nested member."""
    outer_specs = {s.name: s for s in outer.params()}
    for s in inner.params():
        name = rename.get(s.name, prefix + s.name)
        assert name in outer_specs, (outer.__name__, name)
        assert _spec_key(outer_specs[name]) == _spec_key(s), name
        o = outer()
        if s.kind == _core.ParamKind.BOOLEAN:
            value = not o.get_param(name)
        elif s.kind == _core.ParamKind.INTEGER:
            value = int(s.hi) if o.get_param(name) != s.hi else int(max(s.lo + (1 if s.lo_open else 0), 0))
        else:
            value = s.hi if math.isfinite(s.hi) else 1.5 * (s.lo + 1.0)
        o.set_param(name, value)
        assert getattr(o, member).get_param(s.name) == value == o.get_param(name), name


def test_the_scenario_keys_of_nested_fields_are_unchanged():
    names = [s.name for s in _core.NavigationSettings.params()]
    for key in ("segment_length", "sub_segments", "gate_probability", "guard_k", "guard_buffer",
                "guard_slow_distance", "guard_horizon", "guard_min_speed_fraction"):
        assert key in names
    n = _core.NavigationSettings()
    n.set_param("guard_k", 4.0)
    n.set_param("segment_length", 7.0)
    n.set_param("gate_probability", 0.5)
    assert (n.guard.k, n.segments.length, n.filter.gate_probability) == (4.0, 7.0, 0.5)
    with pytest.raises(ValueError, match=r"^guard_min_speed_fraction = 0: must be in \(0, 1\]$"):
        n.set_param("guard_min_speed_fraction", 0.0)
    with pytest.raises(ValueError, match=r"^gate_probability = 1: must be in \[0, 0.999999\]$"):
        _core.LocalizerSettings().set_param("gate_probability", 1.0)


# --------------------------------------------------------------------------- validate() checks the declared ranges

def _out_of_range(s):
    """A value just outside the declared range (below lo), or None for a switch."""
    if s.kind == _core.ParamKind.BOOLEAN:
        return None
    if s.lo_open:
        return s.lo
    return int(s.lo) - 1 if s.kind == _core.ParamKind.INTEGER else math.nextafter(s.lo, -math.inf)


# struct -> (how to build it with one field set directly, bypassing set_param; the prefix validate() names it with)
STRUCTS = {
    _core.GuardSettings: (lambda name, v: _with(_core.GuardSettings(), name, v), "settings.guard."),
    _core.FilterOptions: (lambda name, v: _with(_core.FilterOptions(), name, v), "filter."),
    _core.LocalizationOptions: (lambda name, v: _with(_core.LocalizationOptions(), name, v), ""),
    _core.BoxRangeOptions: (lambda name, v: _with(_core.BoxRangeOptions(), name, v), ""),
    _core.PositionNoise: (lambda name, v: _noise(name, v), "position."),
}


def _with(obj, name, v):
    setattr(obj, name, v)
    return obj


def _noise(name, v):
    p = _core.PositionNoise()
    if name in ("std_x", "std_y"):
        std = list(p.std)
        std[name == "std_y"] = v
        p.std = std
    else:
        setattr(p, name, v)
    return p


@pytest.mark.parametrize("core_type", list(STRUCTS), ids=lambda t: t.__name__)
def test_validate_refuses_each_field_outside_its_declared_range(core_type):
    """A field set directly (no set_param) outside its declared range, or NaN,
    fails validate() with the parameter named: the range lives in the
    declaration only."""
    build, prefix = STRUCTS[core_type]
    for s in core_type.params():
        bad = _out_of_range(s)
        if bad is None:
            continue
        bads = [bad] if s.kind == _core.ParamKind.INTEGER else [bad, math.nan]
        if math.isfinite(s.hi):
            bads.append(int(s.hi) + 1 if s.kind == _core.ParamKind.INTEGER else math.nextafter(s.hi, math.inf))
        for v in bads:
            with pytest.raises(ValueError, match=rf"^{re.escape(prefix + s.name)} = .*: must be "):
                build(s.name, v).validate()


def test_segment_options_and_localization_options_keep_their_other_rules():
    for s in _core.SegmentOptions.params():
        bad = _out_of_range(s)
        with pytest.raises(ValueError, match=rf"^SegmentOptions\.{s.name} = "):
            _core.SegmentOptions(**{s.name: bad})
    # the closed declared range ends at pi/2; crossing lines at pi/2 are never parallel
    o = _core.LocalizationOptions()
    o.set_param("min_crossing_angle", math.pi / 2)
    with pytest.raises(ValueError, match=r"^min_crossing_angle = 1.57\d*: must be below pi/2$"):
        o.validate()
    o.min_crossing_angle = 0.5
    o.validate()
    # an infinite max_range / max_gdop is "none"
    b = _core.BoxRangeOptions()
    b.set_param("max_range", math.inf)
    b.validate()
    assert _core.LocalizationOptions().get_param("max_gdop") == 100.0


def test_the_named_position_profiles_lie_in_the_declared_ranges():
    for name in _core.PositionNoise.names():
        p = _core.PositionNoise.named(name)
        p.check_params()
        assert (p.get_param("std_x"), p.get_param("std_y")) == tuple(p.std)


def test_docs_list_the_core_settings_outside_scenario_files():
    """docs/scenario.md has a table per struct whose parameters no scenario
    section sets, with each declared parameter's range and unit."""
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[1] / "docs" / "scenario.md").read_text(encoding="utf-8")
    part = doc.split("## Core settings outside scenario files", 1)[1]
    nested = ("bmm_", "augment_", "filter_")
    for core_type in (_core.GuardSettings, _core.FilterOptions, _core.SegmentOptions, _core.LocalizerSettings,
                      _core.PositionNoise, _core.LocalizationOptions, _core.BoxRangeOptions):
        section = part.split(f"### `{core_type.__name__}`", 1)[1].split("###", 1)[0]
        rows = {cells[1].strip(): [c.strip() for c in cells[1:6]]
                for cells in (line.split("|") for line in section.splitlines() if line.startswith("| `"))}
        own = [s for s in core_type.params()
               if core_type is not _core.LocalizerSettings or not (s.name.startswith(nested) or s.name == "gate_probability")]
        assert sorted(rows) == sorted(f"`{s.name}`" for s in own), core_type.__name__
        for s in own:
            _, _, rng, unit, meaning = rows[f"`{s.name}`"]
            assert rng == ("true or false" if s.kind == _core.ParamKind.BOOLEAN else s.range_text()), s.name
            assert unit == s.unit and meaning, s.name
