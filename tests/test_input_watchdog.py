"""The stale-input watchdog and the estimate predicted to a command's time
(guidance.hpp; docs/safety.md, "Stale inputs").

A command at t past the localizer's time uses the estimate and covariance
predicted to t by the EKF's eq. 11 at the last motion input's rates, on a
copy: checked against a twin localizer that receives that motion input, and
against the core EKF.  A command stops the vehicle (StaleInput, control 0)
while the latest motion input or measurement is older than
``input_timeout``; the simulator, whose inputs arrive every step, never
trips it."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

import safenav
from safenav import _core
from safenav import guidance as gd
from safenav import navigation as nv
from safenav import planning as P
from safenav.filters import Ekf
from safenav.motion import BmmParams
from safenav.scenario import ScenarioError

X0 = np.array([0.0, 0.0, 2.0, 0.0])
P0 = np.diag([0.2, 0.2, 0.1, 0.02]) ** 2
R = np.diag([0.05, 0.05]) ** 2
U = (2.0, 0.01)   # speed [m/s], heading change per 0.05 s step [rad]


def _guidance(timeout=1.0):
    p = _core.NavigationProblem()
    p.path = np.array([(0.0, 0.0), (200.0, 0.0)])
    p.zones = _core.RiskZones()
    p.map = P.make_map(lower=(-20, -40), upper=(220, 40))
    p.bmm = BmmParams()
    s = _core.NavigationSettings()
    s.replan = False
    s.input_timeout = timeout
    g = gd.Guidance(p, s, gd.localizer_settings(), np.zeros((0, 2)), [], 0)
    g.localizer.initialize(0.0, X0, P0)
    return g


def _drive(g, t_end, *, fix_until=math.inf, dt=0.05):
    """Motion every step up to t_end, a fix every step up to fix_until; a command each step."""
    cmds = []
    for k in range(1, int(round(t_end / dt)) + 1):
        t = k * dt
        g.motion(t, *U)
        if t <= fix_until + 1e-9:
            x = g.localizer.x
            g.fix(t, x[0], x[1], R)
        cmds.append((t, g.command(t)))
    return cmds


def test_no_measurement_for_longer_than_the_timeout_stops_the_vehicle():
    g = _guidance(timeout=1.0)
    cmds = _drive(g, 3.0, fix_until=0.5)
    stale = [(t, c) for t, c in cmds if c.events & gd.EVENTS["stale_input"]]
    # Fixes stop after t = 0.5: every command from t = 1.55 on (age 1.05 s > 1 s) stops, none before.
    assert [round(t, 2) for t, _ in stale] == [round(1.55 + 0.05 * i, 2) for i in range(len(stale))]
    assert round(stale[-1][0], 2) == 3.0
    for t, c in stale:
        assert c.status == gd.GuidanceStatus.STALE_INPUT and c.speed == 0.0 and c.heading_change == 0.0
        assert c.input_age == pytest.approx(t - 0.5) and gd.event_names(c.events) == ["stale_input"]
    assert "measurement" in g.detail and "input_timeout 1 s" in g.detail
    # A fix brings it back.
    x = g.localizer.x
    g.fix(3.0, x[0], x[1], R)
    c = g.command(3.0)
    assert c.status == gd.GuidanceStatus.GUIDING and c.speed > 0 and c.input_age == 0.0


def test_inputs_on_time_never_stop_it():
    g = _guidance(timeout=1.0)
    cmds = _drive(g, 3.0)
    assert all(c.status == gd.GuidanceStatus.GUIDING and not c.events & gd.EVENTS["stale_input"] for _, c in cmds)
    assert all(c.input_age == 0.0 for _, c in cmds)


def test_no_motion_input_stops_it_and_zero_turns_it_off():
    for timeout, stops in ((0.5, True), (0.0, False)):
        g = _guidance(timeout=timeout)
        for k in range(1, 21):                      # fixes only: the motion input stream is silent
            g.fix(k * 0.05, 0.0, 0.0, R)
        c = g.command(1.0)
        assert (c.status == gd.GuidanceStatus.STALE_INPUT) == stops
        assert c.input_age == pytest.approx(1.0)
        if stops:
            assert "motion input" in g.detail


def test_a_late_input_does_not_count_as_heard():
    g = _guidance(timeout=1.0)
    _drive(g, 1.0)
    assert g.fix(0.2, 0.4, 0.0, R).status == gd.InputStatus.LATE
    c = g.command(2.1)                              # latest on-time inputs at t = 1.0
    assert c.status == gd.GuidanceStatus.STALE_INPUT and c.input_age == pytest.approx(1.1)


@pytest.mark.parametrize("value", [-1.0, math.nan, math.inf, 2e6])
def test_a_bad_timeout_names_it(value):
    s = _core.NavigationSettings()
    s.input_timeout = value
    with pytest.raises(ValueError, match="settings.input_timeout"):
        s.validate()
    if not math.isnan(value):
        with pytest.raises(ValueError, match="input_timeout"):
            _core.NavigationSettings().set_param("input_timeout", value)
    with pytest.raises(ScenarioError, match="input_timeout"):
        replace(safenav.default_scenario().navigation, input_timeout=value)


# --------------------------------------------------------------------------- the covariance at t

@pytest.mark.parametrize("ahead", [0.05, 0.3, 0.9])
def test_the_command_uses_the_covariance_predicted_to_its_time(ahead):
    g = _guidance(timeout=5.0)
    _drive(g, 1.0)
    loc = g.localizer
    t_f, x_f, P_f = loc.time, loc.x.copy(), loc.P.copy()
    t = t_f + ahead
    c = g.command(t)
    # The localizer is left as it was.
    assert loc.time == t_f
    np.testing.assert_array_equal(loc.x, x_f)
    np.testing.assert_array_equal(loc.P, P_f)
    # A twin fed the same inputs, then the motion input at t at the same rates, holds P(t).
    twin = _guidance(timeout=5.0)
    _drive(twin, 1.0)
    twin.motion(t, U[0], U[1] * ahead / 0.05)
    assert c.position_std == pytest.approx(twin.localizer.position_std, rel=1e-12)
    # And so does the core EKF's predict (eq. 11) on a copy, over one step of `ahead` seconds
    # (Bmm.with_step: Δt = ahead, each noise σ scaled by √(ahead/Δt₀)).
    b = BmmParams()
    f = math.sqrt(ahead / b.dt)
    b.dt, b.speed_noise, b.heading_noise, b.position_noise = ahead, f * b.speed_noise, f * b.heading_noise, \
        f * b.position_noise
    ekf = Ekf(b, x_f, P_f)
    ekf.predict([U[0], U[1] * ahead / 0.05])
    sigma = math.sqrt(np.linalg.eigvalsh(ekf.P[:2, :2]).max())
    assert c.position_std == pytest.approx(sigma, rel=1e-12)
    assert c.position_std > loc.position_std
    # At the localizer's own time, nothing is predicted.
    assert g.command(t_f).position_std == loc.position_std


def test_the_guard_sees_the_grown_covariance():
    # A boulder beside the path: at the localizer's time the k-σ disc clears it, 2 s of dead reckoning later not.
    p = _core.NavigationProblem()
    p.path = np.array([(0.0, 0.0), (200.0, 0.0)])
    p.zones = _core.RiskZones()
    p.map = P.make_map(lower=(-20, -40), upper=(220, 40), circles=[(8.0, 2.4, 0.5)])
    p.bmm = BmmParams()
    s = _core.NavigationSettings()
    s.replan = False
    s.guard.k = 3.0
    s.input_timeout = 0.0
    g = gd.Guidance(p, s, gd.localizer_settings(), np.zeros((0, 2)), [], 0)
    g.localizer.initialize(0.0, np.array([2.0, 0.0, 2.0, 0.0]), np.diag([0.1, 0.1, 0.05, 0.01]) ** 2)
    now = g.command(0.0)
    later = g.command(1.5)
    assert later.position_std > 2 * now.position_std
    assert later.guard_margin < now.guard_margin


# --------------------------------------------------------------------------- the simulator

def test_the_simulator_never_trips_the_watchdog_and_is_unchanged_by_it():
    sc = safenav.default_scenario()
    safe = nv.plan_safe_path(sc, "P2").path
    seeds = [1, 2, 3]
    on = nv.make_navigator(sc, safe, record=False).run_many(seeds)
    off = nv.make_navigator(replace(sc, navigation=replace(sc.navigation, input_timeout=0.0)), safe,
                            record=False).run_many(seeds)
    assert list(on["stale_input"]) == [0, 0, 0]
    for k in ("steps", "truth_ade", "nees", "min_clearance", "guard_slow", "guard_hold"):
        np.testing.assert_array_equal(on[k], off[k])
