"""Each parameter is declared once, in the core (safenav/params.hpp): its name,
unit, range and meaning beside the struct whose member initialiser is the
default.  The scenario sections, validate() and the generic get/set all read
that one declaration."""
from __future__ import annotations

import dataclasses
import math

import pytest

from safenav import _core
from safenav.scenario import (_SECTIONS, BmmConfig, BufferParams, DetectionParams, NavigationParams, NoiseParams,
                              PlannerParams, default_scenario)

CORE_TYPES = (_core.BmmParams, _core.RiskZones, _core.PlannerSettings, _core.PlanningMap,
              _core.NavigationSettings, _core.SensorSettings, _core.LocalizerSettings, _core.AugmentedStates)


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
        for bad in (bad_lo, s.hi * 2 + 1, math.nan):
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


#: scenario defaults that differ from the core struct's, on purpose (scenario_params.py says why)
#: (none: navigation's 2 m clearance is now the core's Inflation default, vehicle_radius + margin = 1 + 1)
OVERRIDES: dict = {}


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
