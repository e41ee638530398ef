"""Late measurements (``LocalizerSettings.max_delay``): a measurement up to
max_delay older than the filter's time is applied at its own time, the
inputs since applied again after it.  The reference is exact: the same
inputs given in time order must give the same estimate, bit for bit (the
EKF's arithmetic is repeated, the particle filter's generator restored),
and the same counts of applied and rejected updates."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from safenav import _core
from safenav.guidance import InputStatus, Localizer, localizer_settings

LANDMARKS = np.array([[0.0, 10.0], [20.0, -5.0], [15.0, 15.0], [-10.0, 0.0]])
X0 = np.array([0.0, 0.0, 1.0, 0.2])
P0 = np.diag([0.5, 0.5, 0.2, 0.05]) ** 2


def stream(seed: int, duration: float = 12.0):
    """Time-ordered inputs: motion at 20 Hz; ranges, bearings, range+bearing, fixes, IMU at random times."""
    rng = np.random.default_rng(seed)
    ev = [("motion", k * 0.05, (1.0 + 0.3 * np.sin(k / 20), 0.02 * np.cos(k / 15))) for k in range(1, int(duration / 0.05))]
    for t in np.sort(rng.uniform(0.1, duration, 60)):
        kind = rng.choice(["range", "bearing", "both", "fix", "imu"], p=[0.3, 0.2, 0.3, 0.1, 0.1])
        j = int(rng.integers(len(LANDMARKS)))
        ev.append((str(kind), float(t), (j, rng.normal(), rng.normal())))
    ev.sort(key=lambda e: e[1])
    return ev


def feed(loc: Localizer, e):
    kind, t, a = e
    if kind == "motion":
        return loc.motion(t, a[0], a[1])
    j, n1, n2 = a
    if kind == "range":
        return loc.observe(t, j, range=8.0 + n1, range_std=0.5)
    if kind == "bearing":
        return loc.observe(t, j, bearing=0.3 * n2, bearing_std=0.1)
    if kind == "both":
        return loc.observe(t, j, range=8.0 + n1, bearing=0.3 * n2, range_std=0.5, bearing_std=0.1)
    if kind == "fix":
        return loc.fix(t, t + n1, 0.5 * n2, np.diag([1.0, 1.0]))
    return loc.speed_heading(t, 1.0 + 0.1 * n1, 0.2 + 0.05 * n2, 0.2, 0.1)


def run(s, events, delays=None):
    """Feed `events`; with `delays`, each measurement arrives that much later (motion on time)."""
    loc = Localizer(s, LANDMARKS)
    loc.initialize(0.0, X0, P0)
    if delays is None:
        order = range(len(events))
    else:
        arrival = [e[1] + (0.0 if e[0] == "motion" else d) for e, d in zip(events, delays)]
        order = sorted(range(len(events)), key=lambda i: (arrival[i], events[i][0] != "motion", i))
    status = {}
    for i in order:
        status[i] = str(feed(loc, events[i]).status)
    return loc, [status[i] for i in range(len(events))]


def settings_for(kind: str):
    if kind == "ekf":
        return localizer_settings(gate=0.99)
    if kind == "pf":
        return localizer_settings(filter="pf", n_particles=200, seed=5, gate=0.99)
    return localizer_settings(augment=("range_scale", "heading_rate_bias", "range_bias"), gate=0.99)


@pytest.mark.parametrize("kind", ["ekf", "pf", "augmented"])
@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 2**16), spread=st.floats(0.0, 0.45))
def test_late_measurements_give_the_in_order_estimate_exactly(kind, seed, spread):
    events = stream(seed)
    s = settings_for(kind)
    ref, ref_status = run(s, events)
    delays = np.random.default_rng(seed + 1).uniform(0.0, spread, len(events))
    late, late_status = run(s, events, delays)
    np.testing.assert_array_equal(late.x, ref.x)
    np.testing.assert_array_equal(late.P, ref.P)
    # Statuses are answered on arrival: an input later overtaken by an older
    # one kept the answer it got then; the counts are recounted on each replay.
    assert "InputStatus.LATE" not in late_status
    a, b = late.counts, ref.counts
    assert (a.applied, a.rejected, a.late, a.motion) == (b.applied, b.rejected, b.late, b.motion)
    assert a.late == 0


def test_older_than_max_delay_is_late_and_zero_turns_it_off():
    events = stream(3)
    s = settings_for("ekf")
    s.max_delay = 0.2
    loc = Localizer(s, LANDMARKS)
    loc.initialize(0.0, X0, P0)
    for e in events:
        if e[0] == "motion" and e[1] <= 5.0:
            feed(loc, e)
    x = loc.x.copy()
    assert loc.observe(4.7, 0, range=9.0, range_std=0.5).status == InputStatus.LATE   # 0.3 s > 0.2 s
    np.testing.assert_array_equal(loc.x, x)
    r = loc.observe(4.85, 0, range=9.0, range_std=0.5)                                      # 0.15 s: applied
    assert r.status in (InputStatus.APPLIED, InputStatus.REJECTED) and np.isfinite(r.nis)
    assert loc.time == pytest.approx(5.0)
    s.max_delay = 0.0
    off = Localizer(s, LANDMARKS)
    off.initialize(0.0, X0, P0)
    off.motion(0.05, 1.0, 0.0)
    off.motion(0.10, 1.0, 0.0)
    assert off.observe(0.07, 0, range=9.0, range_std=0.5).status == InputStatus.LATE
    assert off.counts.late == 1


def test_a_late_input_that_fails_leaves_the_localizer_as_it_was():
    s = settings_for("ekf")
    loc = Localizer(s, LANDMARKS)
    loc.initialize(0.0, X0, P0)
    for k in range(1, 11):
        loc.motion(0.05 * k, 1.0, 0.01)
    x, P, counts = loc.x.copy(), loc.P.copy(), loc.counts.applied
    with pytest.raises(ValueError, match="fix"):
        loc.fix(0.3, 1.0, 0.0, np.array([[1.0, 2.0], [2.0, 1.0]]))    # R not positive definite
    np.testing.assert_array_equal(loc.x, x)
    np.testing.assert_array_equal(loc.P, P)
    assert loc.counts.applied == counts
    loc.motion(0.55, 1.0, 0.01)                                        # and it goes on
    assert loc.time == pytest.approx(0.55)


def test_max_delay_is_declared():
    s = _core.LocalizerSettings()
    assert s.max_delay == 0.5
    with pytest.raises(ValueError, match="max_delay"):
        s.set_param("max_delay", -1.0)


def test_plaza1_with_ranges_up_to_300_ms_late_keeps_its_accuracy():
    """The replay delivers each range up to 0.3 s late: none is dropped (one taken before the start from
    the data joins the start's fit), and the causal RMSE stays within 0.30 m; with max_delay = 0 most are
    dropped."""
    from safenav import replay as rp
    from safenav.logs import plaza1_path

    log = rp.load(plaza1_path(), range_std=rp.PLAZA_RANGE_STD)
    ranges = log.events["kind"].eq("range").to_numpy()
    d = np.where(ranges, np.random.default_rng(1).uniform(0.0, 0.3, len(ranges)), 0.0)
    for seed in (0, 1):  # seed 0 delays a range past the start it belongs to
        d = np.where(ranges, np.random.default_rng(seed).uniform(0.0, 0.3, len(ranges)), 0.0)
        res = rp.replay(log, rp.preset_settings("plaza"), delays=d)
        assert res.counts["late"] == 0 and res.metrics["truth_rmse"] <= 0.30
    off = rp.preset_settings("plaza")
    off.max_delay = 0.0
    dropped = rp.replay(log, off, delays=d)
    assert dropped.counts["late"] > 1000 and dropped.metrics["truth_rmse"] > res.metrics["truth_rmse"]
    with pytest.raises(ValueError, match=r"delays\[3\] = -1"):
        rp.replay(log, delays=np.where(np.arange(len(ranges)) == 3, -1.0, 0.0))


# -- an observation from before the start from the data, delivered after it ----------------------------------


def _plaza1_before_start():
    """Plaza1, the plaza preset, and the last range before its start from the data (index, time)."""
    from safenav import replay as rp
    from safenav.logs import plaza1_path

    log = rp.load(plaza1_path(), range_std=rp.PLAZA_RANGE_STD)
    s = rp.preset_settings("plaza")
    ev = log.events
    t_start = rp.replay(log, s).t_start
    i = int(np.flatnonzero(ev["kind"].eq("range").to_numpy() & (ev["t"].to_numpy() < t_start))[-1])
    return log, s, i


def _delayed(log, s, i, arrival, lag=2.0, smoother="rts"):
    from safenav import replay as rp

    d = np.zeros(len(log.events))
    d[i] = arrival - log.events["t"][i]
    return rp.replay(log, s, lag=lag, delays=d, smoother=smoother)


@pytest.mark.parametrize("smoother", ["rts", "iterated"])
def test_a_range_from_before_the_start_joins_its_fit(smoother):
    """The last range before Plaza1's start, delivered after a start made without it (within max_delay),
    re-runs that start with it in the fit's window: the estimate is then the one it gets when it arrives
    just before the start's motion input (buffered in time), bit for bit, causal rows after the start and
    fixed-lag outputs alike; nothing is late."""
    log, s, i = _plaza1_before_start()
    t_r = log.events["t"][i]
    # Without it the fit at the in-order start fails; the next motion input starts the filter.
    t_start = _delayed(log, s, i, t_r + 0.14).t_start
    assert t_start > t_r + 0.14
    in_time = _delayed(log, s, i, t_start - 1e-3, smoother=smoother)  # buffered before the start's fit
    after = _delayed(log, s, i, t_start + 0.05, smoother=smoother)    # delivered after that start: it re-runs
    assert in_time.t_start == after.t_start and t_start + 0.05 - t_r <= s.max_delay
    assert after.counts == in_time.counts and after.counts["late"] == 0
    # Row 0 is the estimate at the start, recorded before the range arrived (causal); every later row
    # and every smoothed output is the in-time estimate.
    np.testing.assert_array_equal(after.trajectory.to_numpy()[1:], in_time.trajectory.to_numpy()[1:])
    np.testing.assert_array_equal(after.smoothed.to_numpy(), in_time.smoothed.to_numpy())
    assert not np.array_equal(after.trajectory.to_numpy()[0], in_time.trajectory.to_numpy()[0])


def test_a_range_from_before_the_start_that_spoils_its_fit_is_rejected():
    """When the start's fit with the late range no longer passes (here: the range 1.5 m off and the RMS
    limit just above the start's), the start stands as it was, the range counts as rejected, and the
    estimate is the one of the log without that range."""
    import dataclasses
    import re

    from safenav import replay as rp

    log, s, i = _plaza1_before_start()
    ev = log.events
    without = dataclasses.replace(log, events=ev.drop(index=i).reset_index(drop=True))
    rms = float(re.search(r"residual RMS ([0-9.]+) m", rp.replay(without, s).reason).group(1))
    strict = rp.preset_settings("plaza")
    strict.set_param("init_max_rms", rms + 0.005)
    ref = rp.replay(without, strict, lag=2.0)
    bad = ev.copy()
    bad.loc[i, "range"] += 1.5
    res = _delayed(dataclasses.replace(log, events=bad), strict, i, ref.t_start + 0.05)
    assert res.counts == {**ref.counts, "rejected": ref.counts["rejected"] + 1}
    np.testing.assert_array_equal(res.trajectory.to_numpy(), ref.trajectory.to_numpy())
    np.testing.assert_array_equal(res.smoothed.to_numpy(), ref.smoothed.to_numpy())


def test_a_range_older_than_max_delay_before_the_start_stays_late():
    log, s, i = _plaza1_before_start()
    t_r = log.events["t"][i]
    res = _delayed(log, s, i, t_r + s.max_delay + 0.3, lag=None)
    assert res.counts["late"] == 1
