"""Certified-missions benchmark ("Safe by design"): plan, certify, drive, calibrate.

1. Certification: each path type of each world is planned with RAw-RRT*,
   then with the belief planner and certified (``certify_paths(...,
   planner="belief")``); where landmarks are proposed they are added and the
   path replanned with them.  Per path: status, planner, landmarks added,
   predicted P(collision), the largest P(collision) and the least room along
   the methods' nominal runs (which the certificate also checks), planning
   times.  Missions that cannot be
   certified are reported apart and not driven.
2. Driving: each certified mission (the world with every proposed landmark,
   as ``safenav plan`` writes it) × method (CHull, Centroid) × measurements
   (clean; faulty: bench_safety's FAULTS) × filter (EKF, PF), our loop (guard
   and gate on), ``--trials`` per cell through bench_safety's ``run_cell``.
   Per cell: collisions, arrivals, other outcomes, guard holds, step-limit
   trials and how many of them end where the belief predicts no fix (a blind
   gap), NEES.  Targets: 0 collisions, arrival >= 99.9 %.
3. Calibration: (a) the predicted RMS position error sqrt(trace P_xy) of the
   expected belief (the vehicle's own camera) along the cell's method's
   nominal run (``propagate_belief_along`` of the navigator's
   ``nominal_trajectory()``) against the Monte Carlo RMS error of the
   first ``--record`` trials per cell, per arc-length bin (target: ratio
   within ±25 %), and for comparison the same along the path's legs
   (``propagate_belief``) and with the certificate's robust camera
   (``robust_sight``); per bin also the share of steps with a fix predicted
   along the legs and observed, and for the bins outside the band
   how many hold more than half their squared error in one trial (a rare
   event) and their ratios without it, how many have a trial-bootstrap
   interval that meets the band, and with ``--recheck N`` their ratios
   with the cell's first N trials recorded (a bin whose prediction rests on
   strata rarer than one in ``--record`` needs that many), with the bins
   that leave the band with N; ``--recheck-all`` rechecks every cell, not
   only those with a bin outside the band with ``--record``; (b) the predicted path collision
   probability (the certificate's robust belief, and the expected one)
   against the observed collision rate with its one-sided 95 %
   Clopper–Pearson bounds (target: observed not significantly above
   predicted).
4. Timing: per trial per filter, and the estimated wall time of a run of
   ``--full`` trials in all on ``--workers`` workers.

Fixed seeds: the planner seed of each scenario, and per cell the trial seeds
``runner.trial_seeds(sc.seeds.trials, path index, trials)`` (the same for
every method, measurement and filter); results do not depend on --workers.
The seed sequence is prefix-stable, so ``--first-trial K --trials n`` drives
trials [K, K + n) of each cell: a 10⁵-trial run can be split into parts
(with ``--record 0``, the calibration being the first trials') whose
counts add up.
Generated worlds 13 and 17 are used by no test or other benchmark (those use
0–5, 7 and 11).

    python bench/bench_certified.py [--trials 50] [--worlds 13 17] [--no-gap] [--filters ekf pf]
                                    [--record 200] [--bin-m 10] [--blind-check 10] [--workers 2]
                                    [--full 100000] [--first-trial 0] [--recheck 0] [--recheck-all]
                                    [--out DIR]
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_safety import SHORT, Cell, faulty, map_reporting, run_cell, verdict  # noqa: E402  (the grid's cell code)

from safenav import certify as C  # noqa: E402
from safenav import navigation as nav  # noqa: E402
from safenav import results, runner  # noqa: E402
from safenav.belief import (arc_position, clopper_pearson, propagate_belief,  # noqa: E402
                            pool_calibrations, propagate_belief_along, robust_sight, sigma_calibration)
from safenav.generate import DEFAULT_SEED, generate_scenario  # noqa: E402
from safenav.scenario import Scenario, default_scenario  # noqa: E402

METHODS = ("chull", "centroid")
MEASUREMENTS = ("clean", "faulty")
TARGET_ARRIVAL = 0.999
TARGET_RATIO = 0.25
#: A bin's ratio counts when at least this share of the recorded trials reached it.
MIN_BIN_TRIALS = 0.5
#: Recorded trials held at once by --recheck.
RECHECK_BATCH = 500


def blind_gap_world() -> Scenario:
    """A 150 x 40 m field with one narrow gap (half-width 3 m at y = 20, x in
    [85, 95]) and no landmark in view from x = 20 past the gap: the belief
    planner finds no path that meets k as given, so landmarks are proposed
    and the path replanned with them."""
    lms = [((2, 18), 0), ((2, 22), 0), ((11, 20), 0), ((125, 17), 1), ((125, 23), 1), ((140, 20), 1),
           ((16, 16), 2), ((16, 24), 2), ((19, 20), 2)]
    block = lambda y0, y1: {"type": "polygon", "vertices": [[85.0, y0], [95.0, y0], [95.0, y1], [85.0, y1]]}  # noqa
    return Scenario.from_dict({
        "name": "blind gap",
        "world": {"field": {"x_min": 0.0, "y_min": 0.0, "x_max": 150.0, "y_max": 40.0},
                  "obstacles": [block(0.0, 17.0), block(23.0, 40.0)],
                  "landmarks": [{"id": i, "position": [float(x), float(y)], "class": "tower", "cluster": c}
                                for i, ((x, y), c) in enumerate(lms)]},
        "path_types": [{"name": "G", "clusters": [0, 1]}],
        "navigation": {"plan_iterations": 1500}})


def worlds(seeds: list[int], gap: bool) -> dict[str, Scenario]:
    out = {f"default({DEFAULT_SEED})": default_scenario()}
    out.update({f"seed {s}": generate_scenario(s) for s in seeds})
    if gap:
        out["blind gap"] = blind_gap_world()
    return out


@dataclasses.dataclass(frozen=True)
class Mission:
    """One path type's certificate in one world, with its planning times."""
    world: str
    scenario: Scenario         # the world as given
    stream: int                # the path type's index: keys its trial seeds
    cert: C.PathCertificate
    raw_s: float               # RAw-RRT* [s]
    certify_s: float           # belief planning + certification (+ landmarks, replanning) [s]


def certify_one(job: tuple) -> Mission:
    """RAw-RRT*, then ``certify_paths(..., planner="belief")`` on one path type, timed."""
    world, sc, stream, name = job
    t = time.perf_counter()
    res = C.plan_or_none(sc, name)
    raw = None if res is None else np.asarray(res.path)
    t_raw = time.perf_counter() - t
    t = time.perf_counter()
    (cert,), _ = C.certify_paths(sc, {name: raw}, planner="belief")
    return Mission(world, sc, stream, cert, t_raw, time.perf_counter() - t)


def print_certificates(missions: list[Mission]) -> dict[str, Scenario]:
    """Section 1's table; returns each world's driven scenario (with every proposed landmark)."""
    print(f"   {'world':12} {'path':4} {'status':20} {'planner':27} {'len m':>6} {'added':>5} {'P(coll)':>9} "
          f"{'sigma max':>9} {'runs P':>8} {'runs room':>9} {'RRT* s':>7} {'belief+cert s':>13}")
    print("   (runs: along each method's nominal run, the largest P(collision) and the least room, robust camera)")
    driven = {}
    for m in missions:
        c = m.cert
        ch = c.final or c.given
        runs = list(ch.along.values()) if ch else []
        run_p = max((r.collision_probability for r in runs), default=np.nan)
        run_room = min((r.min_room for r in runs), default=np.nan)
        print(f"   {m.world:12} {c.name:4} {c.status:20} {c.planner:27} "
              f"{np.sum(np.hypot(*np.diff(c.path, axis=0).T)) if len(c.path) else 0.0:6.1f} {c.n_added:5d} "
              f"{(ch.collision_probability if ch else np.nan):9.2g} {(ch.sigma_max if ch else np.nan):9.3f} "
              f"{run_p:8.2g} {run_room:9.2f} {m.raw_s:7.2f} {m.certify_s:13.2f}")
    for w in dict.fromkeys(m.world for m in missions):
        ms = [m for m in missions if m.world == w]
        proposed = C.proposed_scenario(ms[0].scenario, [m.cert for m in ms])
        driven[w] = proposed or ms[0].scenario
        n = len(driven[w].world.landmarks) - len(ms[0].scenario.world.landmarks)
        replanned = sum(m.cert.proposed_for is not None for m in ms)
        print(f"   {w}: {n} landmark(s) added; {replanned} path(s) replanned with them and certified")
    bad = [m for m in missions if m.cert.status == C.CANNOT]
    print(f"   not certified (not driven): {len(bad)}" + "".join(f"\n     {m.world} {m.cert.name}: {m.cert.reason}"
                                                            for m in bad))
    t_raw = [m.raw_s for m in missions]
    t_cert = [m.certify_s for m in missions]
    print(f"   planning time per path: RAw-RRT* median {np.median(t_raw):.2f} s (max {max(t_raw):.2f}); belief "
          f"planning + certification median {np.median(t_cert):.2f} s (max {max(t_cert):.2f})")
    return driven


@dataclasses.dataclass(frozen=True)
class DriveJob:
    cell: Cell
    record: int                # trials recorded for the calibration (the cell's first ones)
    bin_m: float
    blind_check: int           # step-limit trials rerun with a record to see where they ended
    nodes: int = 3             # n per axis of the rule (cells, or nodes) of the expected belief's deviation mixture
    along: bool = C.NOMINAL_DEVIATION["deviation_along"]  # the nominal's mixture stratifies along the path too
    split: bool = True         # the mixture's strata are cells, cut where the view changes (False: the nodes)
    recheck: int = 0           # recorded trials of a cell with a bin outside the band, to check that bin again
    recheck_all: bool = False  # recheck every cell, whatever its bins with the first --record trials


def _profiles(sc, path, navigator, nodes: int = 3, along: bool = C.NOMINAL_DEVIATION["deviation_along"],
              split: bool = True):
    """(expected, robust, nominal): the belief along ``path`` with ``sc``'s
    sensors, seen with the vehicle's own camera (what it will get; the
    lateral strata: the legs' turns are instant) and with the certificate's
    robust camera; and the expected belief along the method's nominal
    trajectory (``navigator.nominal_trajectory()``; ``along``: stratified
    along the path too, as the certificate's)."""
    kw = C.mission_inputs(sc, path)
    dev = {"deviation_nodes": nodes, "deviation_split": split}
    return (propagate_belief(path, **dev, **kw), propagate_belief(path, **robust_sight(), **kw),
            nominal_profile(sc, path, navigator, nodes, along, split))


def nominal_profile(sc, path, navigator, nodes: int = 3, along: bool = C.NOMINAL_DEVIATION["deviation_along"],
                    split: bool = True, **belief):
    """The expected belief along the method's nominal run (the third of
    :func:`_profiles`, the reported σ profile); ``belief``: other settings of
    the belief to change (e.g. ``deviation_free_strata``)."""
    run_kw = {k: v for k, v in C.mission_inputs(sc, path).items() if k != "speed"}
    return propagate_belief_along(navigator.nominal_trajectory(), deviation_along=along, deviation_nodes=nodes,
                                  deviation_split=split, **belief, **run_kw)


def _fix_shares(profiles, needs: int, edges: np.ndarray, truths, measured) -> list[np.ndarray]:
    """Per arc-length bin: the share of each profile's stages with a fix in
    view (the profiles are of one path: their stages coincide), then the
    share of the recorded steps with a fix measured."""
    pos = np.asarray(profiles[0].positions)
    nb = len(edges) - 1
    bins = lambda s: np.clip(np.searchsorted(edges, s, side="right") - 1, 0, nb - 1)  # noqa: E731
    b = bins(arc_position(pos, pos))
    n_stage = np.maximum(np.bincount(b, minlength=nb), 1)
    out = [np.bincount(b, np.asarray(p.landmarks) >= needs, nb) / n_stage for p in profiles]
    hit, n = np.zeros(nb), np.zeros(nb)
    for x, z in zip(truths, measured):
        b = bins(arc_position(pos, x[:, :2]))
        hit += np.bincount(b, np.isfinite(z[:, 0]), nb)
        n += np.bincount(b, minlength=nb)
    with np.errstate(invalid="ignore", divide="ignore"):
        return out + [hit / n]


def _blind_step_limits(navigator_rec, prof, seeds, outcome, check: int) -> tuple[int, int, int]:
    """(step-limit trials, how many of them were rerun with a record (the
    first ``check``), how many of those end at a stage where the belief
    predicts no fix in view: a blind gap)."""
    from safenav.belief import arc_position

    sl = np.flatnonzero(outcome == nav.OUTCOMES.index("step_limit"))
    n_sl, sl = len(sl), sl[:check]
    needs = C.fix_needs(navigator_rec.sensors)
    pos = np.asarray(prof.positions)
    s_stage = arc_position(pos, pos)
    blind = 0
    for i in sl:
        end = np.asarray(navigator_rec.run(seeds[i]).truth)[-1:, :2]
        j = int(np.argmin(np.abs(s_stage - arc_position(pos, end)[0])))
        blind += int(np.asarray(prof.landmarks)[j] < needs)
    return n_sl, len(sl), blind


def _recheck(rec, nominal, cal, job: DriveJob):
    """The expected belief's calibration with the cell's first ``job.recheck``
    trials recorded (in batches: ``pool_calibrations``), where a bin is
    outside the band with the first ``job.record`` (every cell with
    ``job.recheck_all``); else None.  The bootstrap interval cannot show an
    event that no recorded trial met: a bin whose prediction rests on rare
    strata needs more trials, and a bin inside the band with the first trials
    may leave it with more (a rare vehicle whose error the prediction lacks)."""
    c = job.cell
    if job.recheck <= job.record or not (job.recheck_all or _out_of_band(cal, job.record).any()):
        return None
    seeds = runner.trial_seeds(c.scenario.seeds.trials, c.stream, c.first + job.recheck)[c.first + job.record:]
    parts = [cal]
    for a in range(0, len(seeds), RECHECK_BATCH):
        runs = [rec.run(int(s)) for s in seeds[a:a + RECHECK_BATCH]]
        parts.append(sigma_calibration(nominal, [np.asarray(r.truth) for r in runs],
                                       [np.asarray(r.estimate) for r in runs], bin_m=job.bin_m))
    return pool_calibrations(parts)


def drive(job: DriveJob) -> dict:
    """run_cell, then the calibration trials (record=True) and the step-limit analysis."""
    c = job.cell
    cpu = time.thread_time()              # run_many runs on this thread: its CPU time, whatever else runs
    out = run_cell(c)
    cpu_trials = time.thread_time() - cpu
    rec = nav.make_navigator(c.scenario, c.path, method=c.method, filter=c.filter, record=True)
    prof, robust, nominal = _profiles(c.scenario, c.path, rec, job.nodes, job.along, job.split)
    truths, estimates, measured = [], [], []
    for seed in out["seeds"][:job.record]:
        r = rec.run(seed)
        truths.append(np.asarray(r.truth))
        estimates.append(np.asarray(r.estimate))
        measured.append(np.asarray(r.measured))
    cal = sigma_calibration(prof, truths, estimates, bin_m=job.bin_m)
    cal_robust = sigma_calibration(robust, truths, estimates, bin_m=job.bin_m)
    cal_nominal = sigma_calibration(nominal, truths, estimates, bin_m=job.bin_m)
    rechecked = _recheck(rec, nominal, cal_nominal, job)
    needs = C.fix_needs(rec.sensors)
    fix_expected, fix_robust, fix_observed = _fix_shares([prof, robust], needs, cal.edges, truths, measured)
    d = out["trials"]
    n_sl, n_checked, n_blind = _blind_step_limits(rec, prof, out["seeds"], out["outcome"], job.blind_check)
    cpu_extra = time.thread_time() - cpu - cpu_trials
    row = dict(out["row"], filt=c.filter, predicted_pc=float(robust.collision_probability),
               expected_pc=float(prof.collision_probability),
               holds=float(np.mean(d["guard_hold"])), held_trials=int(np.sum(np.asarray(d["guard_hold"]) > 0)),
               step_limit=n_sl, step_limit_checked=n_checked, step_limit_blind=n_blind, cpu_s=cpu_trials,
               extra_cpu_s=cpu_extra)
    return dict(row=row, calibration=cal, calibration_robust=cal_robust, calibration_nominal=cal_nominal,
                rechecked=rechecked, crashes=out["crashes"],
                fix_shares=(fix_expected, fix_robust, fix_observed))


def cell_table(df: pd.DataFrame) -> str:
    show = pd.DataFrame({
        "world": df.world, "path": df.path_type, "method": df.method, "meas": df.measurement, "filter": df.filt,
        "trials": df.trials, "coll": df.collisions, "arrive": df.arrival.map("{:.4f}".format), "other": df.other,
        "sl(blind/chk)": [f"{a}({b}/{c})" for a, b, c in zip(df.step_limit, df.step_limit_blind,
                                                                 df.step_limit_checked)],
        "held": df.held_trials, "holds/tr": df.holds.map("{:.2f}".format), "disp": df.start_disputed,
        "NEES": df.nees.map("{:.3g}".format), "out3s": df.outside_3sigma.map("{:.3f}".format),
        "clr_min": df.min_clearance_min.map("{:.2f}".format), "run min/med/max": df.ratios,
        "legs min/med/max": df.ratios_path,
        "P pred": df.predicted_pc.map("{:.2g}".format), "wall_s": (df.time_ms / 1e3).map("{:.1f}".format),
    })
    return show.to_string(index=False)


def _kept_bins(cal, record: int) -> np.ndarray:
    """The bins that enough recorded trials reached and that have a ratio."""
    return (cal.trials >= max(1, math.ceil(MIN_BIN_TRIALS * record))) & np.isfinite(cal.ratio)


def _out_of_band(cal, record: int) -> np.ndarray:
    """The kept bins whose ratio lies outside ±TARGET_RATIO."""
    return _kept_bins(cal, record) & (np.abs(cal.ratio - 1) > TARGET_RATIO)


def _ratio_bins(cal, record: int) -> np.ndarray:
    """The cell's bin ratios observed / predicted where enough recorded trials reached the bin."""
    return cal.ratio[_kept_bins(cal, record)]


def print_targets(df: pd.DataFrame) -> None:
    n = int(df.trials.sum())
    coll = int(df.collisions.sum())
    arr = float((df.arrival * df.trials).sum() / n)
    print(f"   total: {n} trials in {len(df)} cells")
    print(f"   collisions: {coll} in {n} trials (target 0): {verdict(coll == 0)}")
    worst = df.loc[df.arrival.idxmin()]
    print(f"   arrival: {arr:.4%} (target >= {TARGET_ARRIVAL:.1%}): {verdict(arr >= TARGET_ARRIVAL)}; worst cell "
          f"{worst.arrival:.2%} ({worst.world} {worst.path_type} {worst.method} {worst.measurement} {worst.filt})")
    print(f"   step-limit trials: {int(df.step_limit.sum())}; of {int(df.step_limit_checked.sum())} rerun to see where "
          f"they ended, {int(df.step_limit_blind.sum())} in a blind gap; trials with a guard hold: "
          f"{int(df.held_trials.sum())}")
    for (m, f), g in df.groupby(["measurement", "filt"], sort=False):
        nees = float((g.nees * g.nees_steps).sum() / g.nees_steps.sum())
        a = float((g.arrival * g.trials).sum() / g.trials.sum())
        print(f"   {m:6} {f:3}: collisions {int(g.collisions.sum())} / {int(g.trials.sum())}, arrival {a:.4%}, "
              f"mean NEES {nees:.3g} (4 for a consistent filter)")


def _ratio_line(label: str, v: np.ndarray) -> str:
    if not v.size:
        return f"     {label}: no bins"
    inside = float(np.mean(np.abs(v - 1) <= TARGET_RATIO))
    return (f"     {label}: {v.size:4d} bins, ratio min {np.min(v):.2f} median {np.median(v):.2f} max {np.max(v):.2f}; "
            f"{inside:.0%} of bins within ±{TARGET_RATIO:.0%}, {np.mean(v < 1 - TARGET_RATIO):.0%} below, "
            f"{np.mean(v > 1 + TARGET_RATIO):.0%} above")


def _rechecked_bins(r, cal, rechecked, out_band) -> list[tuple]:
    """(cell, bin, ratio with --record trials, ratio with --recheck, its 95 % bootstrap interval, trials) per
    bin outside the band with either count of trials, where the cell was rechecked."""
    if rechecked is None:
        return []
    cell = f"{r.world} {r.path_type} {r.method}"
    n = len(rechecked.trial_sq)
    return [(cell, f"{cal.edges[b]:.0f}-{cal.edges[b + 1]:.0f} m", cal.ratio[b], rechecked.ratio[b],
             rechecked.observed_low[b] / rechecked.predicted[b], rechecked.observed_high[b] / rechecked.predicted[b],
             n) for b in np.flatnonzero(out_band | _out_of_band(rechecked, n))]


def _print_recheck(label: str, rows: list[tuple]) -> None:
    if not rows:
        return
    inside = sum(abs(x[3] - 1) <= TARGET_RATIO for x in rows)
    print(f"     {label} rechecked with more recorded trials (--recheck): of {len(rows)} bins outside the band with "
          f"the first trials or with all, {inside} within it with all")
    for cell, b, before, after, lo, hi, n in rows:
        print(f"       {cell} {b}: {before:.2f} with the first trials -> {after:.2f} with {n} "
              f"(95 % bootstrap {lo:.2f}-{hi:.2f})")


def print_calibration(df: pd.DataFrame, outs: list, record: int) -> None:
    print(f"   (a) RMS position error, Monte Carlo / predicted sqrt(trace P_xy), per arc-length bin reached by "
          f">= {MIN_BIN_TRIALS:.0%} of the {record} recorded trials (target within ±{TARGET_RATIO:.0%}); "
          "expected = the vehicle's own camera along the method's nominal run (the reported sigma profile), "
          "path = the same along the path's legs, robust = the certificate's camera along the path; "
          "fix = mean |predicted − observed share of steps with a fix| per bin (path and robust)")
    groups = {}
    for (_, r), o in zip(df.iterrows(), outs):
        g = groups.setdefault((r.measurement, r.filt), {"expected": [], "robust": [], "path": [], "fix_e": [],
                                                         "fix_r": [], "out_share": [], "out_rest": [],
                                                         "out_meets": [], "recheck": []})
        cal = o["calibration_nominal"]
        keep = _kept_bins(cal, record)
        g["expected"].append(cal.ratio[keep])
        out_band = _out_of_band(cal, record)
        g["out_share"].append(cal.worst_share[out_band])
        g["out_rest"].append(cal.observed_without_worst[out_band] / cal.predicted[out_band])
        g["out_meets"].append((cal.observed_low[out_band] <= (1 + TARGET_RATIO) * cal.predicted[out_band])
                              & (cal.observed_high[out_band] >= (1 - TARGET_RATIO) * cal.predicted[out_band]))
        g["recheck"] += _rechecked_bins(r, cal, o["rechecked"], out_band)
        g["robust"].append(o["calibration_robust"].ratio[_kept_bins(o["calibration_robust"], record)])
        on_path = o["calibration"]
        keep = _kept_bins(on_path, record)
        g["path"].append(on_path.ratio[keep])
        fe, fr, fo = o["fix_shares"]
        g["fix_e"].append(np.abs(fe - fo)[keep])
        g["fix_r"].append(np.abs(fr - fo)[keep])
    for (m, f), g in groups.items():
        v = {k: np.concatenate(x) if x else np.zeros(0) for k, x in g.items() if k != "recheck"}
        inside = bool(v["expected"].size) and bool(np.all(np.abs(v["expected"] - 1) <= TARGET_RATIO))
        print(_ratio_line(f"{m:6} {f:3} expected", v["expected"]) + f": {verdict(inside)}")
        if v["out_share"].size:
            one = v["out_share"] > 0.5
            rest = v["out_rest"][one]
            print(f"     {m:6} {f:3} of the {v['out_share'].size} bins outside the band, {int(one.sum())} hold more "
                  "than half their squared error in one trial (a rare event that this many trials cannot resolve)"
                  + (f"; without that trial their ratios are {np.nanmin(rest):.2f}–{np.nanmax(rest):.2f}"
                     if np.isfinite(rest).any() else ""))
            print(f"     {m:6} {f:3} of the {v['out_share'].size} bins outside the band, "
                  f"{int(np.sum(v['out_meets']))} have a 95 % trial-bootstrap interval of the observed RMS that "
                  "meets the band (the prediction within the Monte Carlo's own sampling error)")
        _print_recheck(f"{m:6} {f:3}", g["recheck"])
        print(_ratio_line(f"{m:6} {f:3} path    ", v["path"]))
        print(_ratio_line(f"{m:6} {f:3} robust  ", v["robust"]))
        if v["fix_e"].size:
            print(f"     {m:6} {f:3} fix share |predicted − observed| per bin: path mean "
                  f"{np.mean(v['fix_e']):.3f} "
                  f"max {np.max(v['fix_e']):.2f}; robust mean {np.mean(v['fix_r']):.3f} max {np.max(v['fix_r']):.2f}")
    print("   (b) predicted path collision probability (belief with the cell's sensors: the certificate's robust "
          "camera, and the expected one) vs observed rate; one-sided 95 % Clopper-Pearson bounds")
    for (m, f), g in [(("all", "all"), df), *df.groupby(["measurement", "filt"], sort=False)]:
        n, k = int(g.trials.sum()), int(g.collisions.sum())
        pred = float((g.predicted_pc * g.trials).sum() / n)
        expd = float((g.expected_pc * g.trials).sum() / n)
        lo, hi = clopper_pearson(k, n)
        print(f"     {m:6} {f:3}: predicted {pred:.3g} (expected belief {expd:.3g}; expected collisions "
              f"{pred * n:.3g}); "
              f"observed {k}/{n} = {k / n:.3g}, 95 % upper {hi:.3g}, lower {lo:.3g}; observed not significantly "
              f"above predicted: {verdict(lo <= pred)}")


def print_timing(df: pd.DataFrame, wall: float, workers: int, full: int) -> None:
    """Time per trial (wall inside run_many, and CPU of the cell's thread: the CPU time does not grow when
    other work shares the cores), and the run of ``full`` trials estimated from each cell's CPU time per trial
    plus its fixed work (recorded and rerun trials)."""
    per = {f: (g.time_ms.sum() / 1e3 / g.trials.sum(), g.cpu_s.sum() / g.trials.sum())
           for f, g in df.groupby("filt", sort=False)}
    per_cell = math.ceil(full / len(df))
    est = float((per_cell * df.cpu_s / df.trials + df.extra_cpu_s).sum()) / workers
    print(f"   driving: {wall:.1f} s wall on {workers} workers; per trial (wall in run_many / CPU) " +
          ", ".join(f"{f} {w * 1e3:.1f} / {c * 1e3:.1f} ms" for f, (w, c) in per.items()))
    print(f"   a run of {full} trials ({len(df)} cells x --trials {per_cell} = {len(df) * per_cell}) needs about "
          f"{est * workers / 3600:.2f} CPU hours: {est / 3600:.2f} h on {workers} otherwise idle cores")


def _arguments() -> argparse.Namespace:
    """The command line, checked: a count below its least names the flag."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trials", type=int, default=50, help="trials per cell (default 50)")
    ap.add_argument("--worlds", type=int, nargs="*", default=[13, 17], help="seeds of the generated worlds")
    ap.add_argument("--no-gap", action="store_true", help="leave out the blind-gap world")
    ap.add_argument("--filters", nargs="+", choices=["ekf", "pf"], default=["ekf", "pf"])
    ap.add_argument("--record", type=int, default=200,
                    help="trials per cell recorded for the calibration (the first ones; at most --trials)")
    ap.add_argument("--bin-m", type=float, default=10.0, help="arc-length bin of the calibration [m]")
    ap.add_argument("--blind-check", type=int, default=10,
                    help="step-limit trials per cell rerun with a record to see whether they ended in a blind gap")
    ap.add_argument("--first-trial", type=int, default=0,
                    help="drive trials [first, first + trials) of each cell's seed sequence, so that a long run "
                         "can be split into parts whose trials add up to one run's (default 0)")
    ap.add_argument("--deviation-nodes", type=int, default=3, choices=[3, 5, 7],
                    help="cells (or Gauss-Hermite nodes) per axis of the expected belief's deviation mixture (default 3)")
    ap.add_argument("--deviation-lateral", dest="deviation_along", action="store_false",
                    help="stratify the nominal run's expected belief's deviation across the path and in heading "
                         "only (n^2 strata; by default along the path too, n^3, as the certificate's)")
    ap.add_argument("--deviation-points", dest="deviation_split", action="store_false",
                    help="the expected belief's strata at the Gauss-Hermite nodes, not at cells cut where the view changes")
    ap.add_argument("--recheck", type=int, default=0,
                    help="record this many trials of each cell with a bin of the expected belief outside the band "
                         "(the first --record included) and calibrate those bins again (default 0: none)")
    ap.add_argument("--recheck-all", action="store_true",
                    help="recheck every cell with --recheck trials, not only those with a bin outside the band with "
                         "the first --record (a bin whose error sits in rare vehicles reads inside with few trials)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--full", type=int, default=100_000, help="total trials of the run to estimate the time of")
    ap.add_argument("--out", type=Path, default=None, help="write the per-cell table (CSV) here")
    args = ap.parse_args()
    for name in ("trials", "record", "blind_check", "workers", "full", "first_trial", "recheck"):
        if getattr(args, name) < (0 if name in ("record", "blind_check", "first_trial", "recheck") else 1):
            ap.error(f"--{name} = {getattr(args, name)}: too small")
    return args


def main() -> None:
    args = _arguments()
    t_all = time.perf_counter()
    scenarios = worlds(args.worlds, not args.no_gap)
    print(f"worlds: {', '.join(scenarios)}; {args.trials} trials per cell from trial {args.first_trial}; "
          f"methods {', '.join(METHODS)}; "
          f"measurements clean / faulty; filters {', '.join(args.filters)}; our loop; {args.workers} workers")

    jobs = [(w, sc, i, p.name) for w, sc in scenarios.items() for i, p in enumerate(sc.path_types)]
    t = time.perf_counter()
    missions = runner.map_ordered(certify_one, jobs, workers=args.workers)
    print(f"\n1. certified missions ({len(missions)} paths, {time.perf_counter() - t:.1f} s wall)")
    driven = print_certificates(missions)

    cells = [Cell(m.world, meas, m.cert.name, m.stream, np.asarray(m.cert.path), method, "ours", name,
                  args.trials, filt, args.first_trial)
             for m in missions if m.cert.status != C.CANNOT
             for method in METHODS
             for name, meas in (("clean", driven[m.world]), ("faulty", faulty(driven[m.world])))
             for filt in args.filters]
    t = time.perf_counter()

    def line(job: DriveJob, o: dict) -> str:
        r = o["row"]
        return (f"{r['world']:12} {r['path_type']:4} {r['method']:9} {r['measurement']:6} {r['filt']:3} "
                f"collisions {r['collisions']} arrival {r['arrival']:.3f} wall {r['time_ms'] / 1e3:.1f} s")

    print(f"\n2. driving {len(cells)} cells x {args.trials} trials", flush=True)
    drive_jobs = [DriveJob(c, args.record, args.bin_m, args.blind_check, args.deviation_nodes,
                           args.deviation_along, args.deviation_split, args.recheck, args.recheck_all) for c in cells]
    out = map_reporting(drive, drive_jobs, args.workers, line)
    wall = time.perf_counter() - t
    df = pd.DataFrame([o["row"] for o in out])
    cals = [o["calibration"] for o in out]
    spread = lambda v: "{:.2f}/{:.2f}/{:.2f}".format(v.min(), np.median(v), v.max()) if v.size else "-"  # noqa: E731
    df["ratios"] = [spread(_ratio_bins(o["calibration_nominal"], args.record)) for o in out]
    df["ratios_path"] = [spread(_ratio_bins(c, args.record)) for c in cals]
    print("   other: " + ", ".join(f"{v} {k}" for k, v in SHORT.items()) + "; sl(blind/chk) = step-limit trials "
          "(in a blind gap / of those rerun);\n   held = trials with a guard hold; disp = trials whose start fix was disputed "
          "against the rough start; run, legs = Monte Carlo / predicted RMS "
          "error per bin, the belief along the method's nominal run and along the path's legs")
    print(cell_table(df))
    for o in out:
        for i, seed, clr, reason in o["crashes"]:
            r = o["row"]
            print(f"   collision: {r['world']} {r['path_type']} {r['method']} {r['measurement']} {r['filt']} "
                  f"trial {i} seed {seed} clearance {clr:.3f} m: {reason}")
    print("\n   targets")
    print_targets(df)
    print("\n3. calibration")
    print_calibration(df, out, args.record)
    print("\n4. timing")
    print_timing(df, wall, args.workers, args.full)
    if args.out is not None:
        print("\nwrote " + ", ".join(str(p) for p in results.write_table(df, args.out / "certified_cells",
                                                                         parquet=False)))
    print(f"\ntotal {time.perf_counter() - t_all:.1f} s")


if __name__ == "__main__":
    main()
