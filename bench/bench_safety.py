"""Safety benchmark (issue 15, "Safe by measurement").

1. Navigation safety grid: worlds (the default scenario and generated worlds
   with other seeds) × path types (up to 3) × method (CHull, Centroid) × loop
   (the papers' loop: guard and chi-square gate off; ours: guard on, 99 % gate)
   × measurements (clean: the scenario as is; faulty: fixes from landmark
   ranges with 20 % dropout, 5 % outliers, 1 % misassociation).  Per cell:
   outcomes, steps, the guard's time penalty, clearance, hazard exposure, NEES,
   guard events, rejected updates, faults; then the targets with PASS/MISS.
2. Hazard-aware planning: RAw-RRT* with hazard_weight 0 (the paper's cost)
   and each beta_h of --weights: length, exposure, clearance and their ratios.
3. Timing: wall time per cell and the median µs/step of paper vs ours.

Fixed seeds throughout: the planner seed of each scenario and the trial seeds
``runner.trial_seeds(sc.seeds.trials, path index, trials)``, the same for both
loops, both methods and both measurement settings.

    python bench/bench_safety.py [--trials 1000] [--quick] [--worlds 1 2 3] [--weights 5 10 20]
                                 [--workers 2] [--out DIR]
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats

from safenav import navigation as nav
from safenav import results, runner
from safenav.generate import DEFAULT_SEED, generate_scenario
from safenav.scenario import default_scenario

METHODS = ("chull", "centroid")
LOOPS = ("paper", "ours")
MEASUREMENTS = ("clean", "faulty")
#: The faulty measurements: LanBLoc fixes trilaterated from single landmark
#: ranges (the faults need them), 20 % dropout, 5 % outliers (5 m, the
#: default outlier_magnitude), 1 % misassociation.
FAULTS = dict(fix_model="ranges", dropout_probability=0.2, outlier_probability=0.05,
              misassociation_probability=0.01)
MAX_PATH_TYPES = 3
SHORT = {"left_corridor": "lc", "step_limit": "sl", "lost_localization": "lost", "no_path": "np", "blocked": "bl"}
#: Targets of issue 15.
TARGET_ARRIVAL = 0.99
TARGET_PENALTY = 0.10
TARGET_EXPOSURE_RATIO = 10.0
TARGET_LENGTH_RATIO = 0.10
#: The 95 % band of one step's 4-state NEES (chi-square, 4 dof): [0.48, 11.1].
STEP_BAND = tuple(float(v) for v in stats.chi2.ppf([0.025, 0.975], 4))
CELL_KEY = ["world", "path_type", "method", "measurement"]  # a cell of the grid, less its loop


@dataclasses.dataclass(frozen=True)
class Cell:
    """One cell of the grid: a world's path type driven by one method, loop and measurement setting."""

    world: str
    scenario: object           # the measured scenario (clean or faulty)
    path_type: str
    stream: int                # the path type's index in the scenario: keys its trial seeds
    path: np.ndarray
    method: str
    loop: str
    measurement: str
    trials: int
    filter: str = "ekf"        # "ekf" or "pf" (bench_certified.py drives both)
    first: int = 0             # the cell's trials are [first, first + trials) of its seed sequence


@dataclasses.dataclass(frozen=True)
class PlanJob:
    world: str
    scenario: object
    path_type: str
    hazard_weight: float


def worlds(quick: bool, seeds: list[int]) -> dict[str, object]:
    """The default scenario and generated ones (their own path types); --quick keeps one generated world."""
    out = {f"default({DEFAULT_SEED})": default_scenario()}
    for s in seeds[:1] if quick else seeds:
        out[f"seed {s}"] = generate_scenario(s)
    return out


def faulty(sc):
    return dataclasses.replace(sc, noise=dataclasses.replace(sc.noise, **FAULTS))


def path_types(sc) -> list[tuple[int, str]]:
    return [(i, p.name) for i, p in enumerate(sc.path_types)][:MAX_PATH_TYPES]


def plan_one(job: PlanJob) -> dict:
    """RAw-RRT* on one path type with hazard weight beta_h (0 = the paper's cost)."""
    sc = dataclasses.replace(job.scenario, planner=dataclasses.replace(job.scenario.planner,
                                                                       hazard_weight=job.hazard_weight))
    t = time.perf_counter()
    try:
        r = nav.plan_safe_path(sc, job.path_type)
    except RuntimeError as exc:
        return dict(world=job.world, path_type=job.path_type, hazard_weight=job.hazard_weight, ok=False,
                    error=str(exc), time_ms=(time.perf_counter() - t) * 1e3)
    s = r.safety
    return dict(world=job.world, path_type=job.path_type, hazard_weight=job.hazard_weight, ok=True, error="",
                length=float(s.length), exposure=float(s.exposure), min_clearance=float(s.min_clearance),
                hazard_length=float(np.sum(s.hazard_length)), path=np.asarray(r.path),
                time_ms=(time.perf_counter() - t) * 1e3)


def run_cell(c: Cell) -> dict:
    """run_many over the cell's trials; the cell's statistics, the per-trial arrays the summary needs, and
    run_many's dict (``trials``) with the ``seeds``."""
    navigator = nav.make_navigator(c.scenario, c.path, method=c.method, filter=c.filter, record=False,
                                   paper=c.loop == "paper")
    # trial_seeds is prefix-stable: trials [first, first + n) of a cell are those of one longer run
    seeds = [int(s) for s in runner.trial_seeds(c.scenario.seeds.trials, c.stream, c.first + c.trials)[c.first:]]
    t = time.perf_counter()
    d = navigator.run_many(seeds)
    wall = time.perf_counter() - t
    o = np.asarray(d["outcome"])
    steps = np.asarray(d["steps"], dtype=float)
    rows = steps + 1                    # the metrics average over the recorded states, the start included
    names = [nav.OUTCOMES[k] for k in o]
    other = {n: names.count(n) for n in nav.OUTCOMES[2:] if names.count(n)}
    clear = np.asarray(d["min_clearance"], dtype=float)
    clear = clear[np.isfinite(clear)]
    nees = np.asarray(d["nees"], dtype=float)
    ok = np.isfinite(nees)
    guard = np.asarray(d["guard_slow"]) + np.asarray(d["guard_steer"]) + np.asarray(d["guard_hold"])
    moving = steps > 0
    us_step = np.asarray(d["time_s"])[moving] / steps[moving] * 1e6
    coll = np.flatnonzero(o == nav.OUTCOMES.index("collision"))
    row = dict(
        world=c.world, path_type=c.path_type, method=c.method, loop=c.loop, measurement=c.measurement,
        trials=c.trials,
        collisions=int(len(coll)),
        arrival=float(np.mean(o == nav.OUTCOMES.index("arrived"))),
        other_failures=int(sum(other.values())),
        other=" ".join(f"{SHORT[k]}:{v}" for k, v in other.items()) or "-",
        mean_steps=float(steps.mean()),
        min_clearance_min=float(clear.min()) if clear.size else np.nan,
        min_clearance_p5=float(np.percentile(clear, 5)) if clear.size else np.nan,
        exposure=float(np.mean(d["exposure"])),
        hazard_time=float(np.mean(d["hazard_time"])),
        # the mean over all recorded steps of the cell (each trial's mean weighted by its steps)
        nees=float(np.sum(nees[ok] * rows[ok]) / np.sum(rows[ok])) if ok.any() else np.nan,
        nees_steps=int(np.sum(rows[ok])),
        outside_3sigma=float(np.mean(d["outside_3sigma"])),
        guard_events=float(guard.mean()),
        rejected=float(np.mean(d["rejected"])),
        faults=float(np.mean(np.asarray(d["outliers"]) + np.asarray(d["misassociated"]))),
        faults_through=float(np.mean(d["faults_through"])),
        resets=float(np.mean(d["resets"])),
        start_disputed=int(np.sum(d["start_disputed"])),
        guard_k=float(navigator.settings.guard.k) if navigator.settings.guard.enabled else np.nan,
        stale_input=float(np.mean(d["stale_input"])),
        time_ms=wall * 1e3,
        time_per_step_us=float(np.median(us_step)) if us_step.size else np.nan,
    )
    reasons = d.get("reason")
    crashes = [(c.first + int(i), seeds[i], float(d["min_clearance"][i]), str(reasons[i]) if reasons is not None else "")
               for i in coll]
    return dict(row=row, steps=steps, outcome=o, crashes=crashes, trials=d, seeds=seeds)


def cell_table(rows: pd.DataFrame) -> str:
    show = pd.DataFrame({
        "world": rows.world, "path": rows.path_type, "method": rows.method, "loop": rows.loop,
        "meas": rows.measurement, "coll": rows.collisions, "arrive": rows.arrival.map("{:.3f}".format),
        "other": rows.other, "steps": rows.mean_steps.map("{:.0f}".format),
        "penalty": rows.penalty.map(lambda v: "" if np.isnan(v) else f"{v:+.1%}"),
        "clr_min": rows.min_clearance_min.map("{:.2f}".format), "clr_p5": rows.min_clearance_p5.map("{:.2f}".format),
        "expo": rows.exposure.map("{:.2f}".format), "haz_s": rows.hazard_time.map("{:.2f}".format),
        "NEES": rows.nees.map("{:.3g}".format), "out3s": rows.outside_3sigma.map("{:.3f}".format),
        "guard/tr": rows.guard_events.map("{:.1f}".format), "rej/tr": rows.rejected.map("{:.1f}".format),
        "faults/tr": rows.faults.map("{:.1f}".format), "through/tr": rows.faults_through.map("{:.2f}".format),
        "resets/tr": rows.resets.map("{:.2f}".format),
        "k": rows.guard_k.map(lambda v: "-" if np.isnan(v) else f"{v:.2f}"),
        "stale/tr": rows.stale_input.map("{:.2f}".format), "wall_s": (rows.time_ms / 1e3).map("{:.1f}".format),
        "us/step": rows.time_per_step_us.map("{:.1f}".format),
    })
    return show.to_string(index=False)


def verdict(ok: bool) -> str:
    return "PASS" if ok else "MISS"


def _arguments() -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trials", type=int, default=None, help="trials per cell (default 1000; --quick: 100)")
    ap.add_argument("--quick", action="store_true", help="100 trials, the default world and one generated world")
    ap.add_argument("--worlds", type=int, nargs="+", default=[1, 2, 3], help="seeds of the generated worlds")
    ap.add_argument("--weights", type=float, nargs="+", default=[5.0, 10.0, 20.0], help="hazard weights beta_h")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=None, help="write the per-cell and planning tables (CSV) here")
    ap.add_argument("--guard-k", type=float, default=None,
                    help="our loop's guard k (default: the scenario's, 0 = from navigation.collision_probability)")
    ap.add_argument("--collision-probability", type=float, default=None,
                    help="our loop's risk budget per mission (default: the scenario's, 1e-4)")
    return ap.parse_args()


def grid_cells(scenarios: dict, plan_of: dict, trials: int) -> list:
    """The navigation grid's cells: every world's paths (its hazard_weight 0 plan), methods, measurements and loops."""
    cells = []
    for w, sc in scenarios.items():
        measured = {"clean": sc, "faulty": faulty(sc)}
        for stream, name in path_types(sc):
            base = plan_of[(w, name, 0.0)]
            if not base["ok"]:
                print(f"  {w} {name}: no safe path ({base['error']}); its cells are skipped")
                continue
            for method in METHODS:
                for m in MEASUREMENTS:
                    for loop in LOOPS:
                        cells.append(Cell(w, measured[m], name, stream, base["path"], method, loop, m, trials))
    return cells


def print_summary(df: pd.DataFrame, cells: list, out: list, default_world: str) -> None:
    """The grid's collisions and arrival per loop and measurement, our loop's collisions one by one, and the time
    penalty of ours over the paper's loop on the default world."""
    crashes = [(c, o["crashes"]) for c, o in zip(cells, out) if c.loop == "ours" and o["crashes"]]
    if crashes:
        print("\n   collisions of ours (trial index, seed, min clearance, reason):")
        for c, lst in crashes:
            for i, seed, clr, reason in lst:
                print(f"   {c.world} {c.path_type} {c.method} {c.measurement}: trial {i} seed {seed} "
                      f"clearance {clr:.3f} m: {reason}")

    print("\n   summary")
    print(f"   {'collisions':24}" + "".join(f"{m:>10}" for m in MEASUREMENTS))
    for loop in LOOPS:
        print(f"   {loop:24}" + "".join(f"{int(df[(df.loop == loop) & (df.measurement == m)].collisions.sum()):>10}"
                                         for m in MEASUREMENTS))
    ours = df[df.loop == "ours"]
    for m in MEASUREMENTS:
        n = int(ours[ours.measurement == m].collisions.sum())
        print(f"   ours, {m}: {n} collisions in {int(ours[ours.measurement == m].trials.sum())} trials "
              f"(target 0): {verdict(n == 0)}")
    for m in MEASUREMENTS:
        o = ours[ours.measurement == m]
        rate = float((o.arrival * o.trials).sum() / o.trials.sum())
        worst = o.loc[o.arrival.idxmin()]
        print(f"   ours, {m}: arrival rate {rate:.2%} (target >= {TARGET_ARRIVAL:.0%}): {verdict(rate >= TARGET_ARRIVAL)}"
              f"; worst cell {worst.arrival:.1%} ({worst.world} {worst.path_type} {worst.method})")

    # Time penalty on the default scenario: the sum of ours' mean steps over its cells against the paper's.
    for m in MEASUREMENTS:
        sel = (df.world == default_world) & (df.measurement == m)
        p = df[sel & (df.loop == "paper")].mean_steps.sum()
        q = df[sel & (df.loop == "ours")].mean_steps.sum()
        pen = q / p - 1
        worst = df[sel & (df.loop == "ours")].penalty.max()
        # For information: the same ratio over the trials that arrived in both loops (a collision ends a trial early).
        both_p = both_q = 0.0
        for ci, c in enumerate(cells):
            if c.world == default_world and c.measurement == m and c.loop == "ours":
                j = next(k for k, d in enumerate(cells) if d.loop == "paper" and
                         (d.world, d.path_type, d.method, d.measurement) == (c.world, c.path_type, c.method, m))
                arrived = (out[ci]["outcome"] == 0) & (out[j]["outcome"] == 0)
                both_q += out[ci]["steps"][arrived].sum()
                both_p += out[j]["steps"][arrived].sum()
        paired = both_q / both_p - 1 if both_p else np.nan
        print(f"   ours, {m}, {default_world}: time penalty {pen:+.1%} (target <= {TARGET_PENALTY:.0%}): "
              f"{verdict(pen <= TARGET_PENALTY)}; worst cell {worst:+.1%}; over trials arrived in both loops {paired:+.1%}")


def print_nees(df: pd.DataFrame) -> None:
    """The mean NEES of each of our loop's faulty cells against its bands, and of every loop pooled."""
    # NEES with faults for ours.  A consistent filter's NEES is chi-square with 4 dof each step; the mean of N
    # such values (N = the recorded steps of the cell) lies in chi2.ppf([0.025, 0.975], 4N) / N with 95 %
    # probability (treating the steps as independent, which they are not: a very tight band).  The simple
    # per-step band chi2.ppf([0.025, 0.975], 4) = [0.48, 11.1] is printed beside it.
    print(f"   NEES of ours with faults (tight band: mean of N chi2_4 steps, chi2.ppf([.025,.975], 4N)/N; "
          f"per-step band [{STEP_BAND[0]:.2f}, {STEP_BAND[1]:.1f}]):")
    ours = df[df.loop == "ours"]
    o = ours[ours.measurement == "faulty"]
    in_tight = in_step = 0
    for _, r in o.iterrows():
        lo, hi = stats.chi2.ppf([0.025, 0.975], 4 * r.nees_steps) / r.nees_steps
        t_ok, s_ok = lo <= r.nees <= hi, STEP_BAND[0] <= r.nees <= STEP_BAND[1]
        in_tight += t_ok
        in_step += s_ok
        print(f"     {r.world:12} {r.path_type:4} {r.method:9} NEES {r.nees:8.3f}  N {r.nees_steps:9d}  "
              f"tight [{lo:.3f}, {hi:.3f}] {'in ' if t_ok else 'out'}  per-step {'in' if s_ok else 'out'}")
    n_all = int(o.nees_steps.sum())
    pooled = float((o.nees * o.nees_steps).sum() / n_all)
    lo, hi = stats.chi2.ppf([0.025, 0.975], 4 * n_all) / n_all
    print(f"   ours, faulty: mean NEES over all cells {pooled:.3f} (N = {n_all}); tight band [{lo:.4f}, {hi:.4f}]: "
          f"{verdict(lo <= pooled <= hi)} ({in_tight}/{len(o)} cells inside); per-step band "
          f"[{STEP_BAND[0]:.2f}, {STEP_BAND[1]:.1f}]: {verdict(STEP_BAND[0] <= pooled <= STEP_BAND[1])} "
          f"({in_step}/{len(o)} cells inside)")
    for loop, m in (("paper", "faulty"), ("ours", "clean"), ("paper", "clean")):
        s = df[(df.loop == loop) & (df.measurement == m)]
        print(f"   (information) {loop}, {m}: mean NEES over all cells "
              f"{float((s.nees * s.nees_steps).sum() / s.nees_steps.sum()):.3g}")


def hazard_table(plans: list, plan_of: dict, weights: list) -> pd.DataFrame:
    """Hazard-aware planning against the paper's paths (hazard_weight 0), printed; the table."""
    print(f"\n2. hazard-aware planning: hazard_weight 0 (paper) vs beta_h in {weights}")
    prow = []
    for p in plans:
        if p["hazard_weight"] == 0.0:
            continue
        b = plan_of[(p["world"], p["path_type"], 0.0)]
        r = dict(world=p["world"], path_type=p["path_type"], hazard_weight=p["hazard_weight"])
        if not (p["ok"] and b["ok"]):
            r.update(error=p["error"] or b["error"])
            prow.append(r)
            continue
        r.update(paper_length=b["length"], length=p["length"], paper_exposure=b["exposure"], exposure=p["exposure"],
                 paper_min_clearance=b["min_clearance"], min_clearance=p["min_clearance"],
                 paper_hazard_length=b["hazard_length"], hazard_length=p["hazard_length"],
                 exposure_ratio=b["exposure"] / p["exposure"] if p["exposure"] > 0 else np.inf,
                 length_ratio=p["length"] / b["length"] - 1, time_ms=p["time_ms"], error="")
        prow.append(r)
    pdf = pd.DataFrame(prow)
    print(f"   {'world':12} {'path':4} {'beta_h':>6} {'len paper':>9} {'len':>8} {'expo paper':>10} {'expo':>8} "
          f"{'clr paper':>9} {'clr':>6} {'in-haz paper':>12} {'in-haz':>7} {'expo p/o':>9} {'len o/p-1':>9}")
    for _, r in pdf.iterrows():
        if r.get("error"):
            print(f"   {r.world:12} {r.path_type:4} {r.hazard_weight:6g} failed: {r.error}")
            continue
        print(f"   {r.world:12} {r.path_type:4} {r.hazard_weight:6g} {r.paper_length:9.1f} {r.length:8.1f} "
              f"{r.paper_exposure:10.2f} {r.exposure:8.2f} {r.paper_min_clearance:9.2f} {r.min_clearance:6.2f} "
              f"{r.paper_hazard_length:12.1f} {r.hazard_length:7.1f} {r.exposure_ratio:8.1f}x {r.length_ratio:+9.1%}")
    good = pdf[pdf.error == ""] if "error" in pdf else pdf
    for bh in weights:
        s = good[good.hazard_weight == bh]
        if s.empty:
            print(f"   beta_h {bh:g}: no plans")
            continue
        er = s.paper_exposure.sum() / s.exposure.sum() if s.exposure.sum() > 0 else np.inf
        lr = s.length.sum() / s.paper_length.sum() - 1
        each = int(((s.exposure_ratio >= TARGET_EXPOSURE_RATIO) & (s.length_ratio <= TARGET_LENGTH_RATIO)).sum())
        print(f"   beta_h {bh:g}: total exposure paper/ours {er:.1f}x (target >= {TARGET_EXPOSURE_RATIO:g}x), "
              f"total length ours/paper - 1 {lr:+.1%} (target <= {TARGET_LENGTH_RATIO:.0%}): "
              f"{verdict(er >= TARGET_EXPOSURE_RATIO and lr <= TARGET_LENGTH_RATIO)}; "
              f"{each}/{len(s)} paths meet both on their own")
    return pdf


def print_timing(df: pd.DataFrame, grid_wall: float, workers: int) -> None:
    """Our loop's time per step against the paper's, per measurement."""
    print(f"\n3. timing: grid {grid_wall:.1f} s wall on {workers} workers (cell wall times: wall_s above)")
    print(f"   {'measurement':12} {'paper us/step':>14} {'ours us/step':>13} {'ours/paper':>11}   "
          "(medians over cells of each cell's median over trials)")
    for m in MEASUREMENTS:
        p = df[(df.loop == "paper") & (df.measurement == m)].set_index(CELL_KEY).time_per_step_us
        q = df[(df.loop == "ours") & (df.measurement == m)].set_index(CELL_KEY).time_per_step_us
        ratio = float(np.median((q / p.reindex(q.index)).to_numpy()))
        print(f"   {m:12} {float(p.median()):14.2f} {float(q.median()):13.2f} {ratio:10.2f}x   "
              f"(median of per-cell ratios; ratio of medians {float(q.median() / p.median()):.2f}x)")


def map_reporting(work, jobs: list, workers: int, line) -> list:
    """``runner.map_ordered(work, jobs)``, with a line ``line(job, output)`` printed as each job
    finishes (numbered in the order they finish), so that a long run shows its progress."""
    done = []

    def run_and_report(job):
        o = work(job)
        done.append(job)
        print(f"   [{len(done):3d}/{len(jobs)}] {line(job, o)}", flush=True)
        return o

    return runner.map_ordered(run_and_report, jobs, workers=workers)


def run_grid(cells: list, trials: int, workers: int):
    """Every cell's trials (a line as each finishes, so that a long run shows its progress); the cells'
    outputs, their table with our loop's time penalty per cell, and the wall time."""
    t = time.perf_counter()

    def line(c: Cell, o: dict) -> str:
        r = o["row"]
        return (f"{c.world:12} {c.path_type:4} {c.method:9} {c.loop:5} {c.measurement:6} collisions "
                f"{r['collisions']:4d} arrival {r['arrival']:.3f} mean steps {r['mean_steps']:6.0f} "
                f"wall {r['time_ms'] / 1e3:6.1f} s")

    print(f"\nrunning {len(cells)} cells x {trials} trials", flush=True)
    out = map_reporting(run_cell, cells, workers, line)
    grid_wall = time.perf_counter() - t
    df = pd.DataFrame([o["row"] for o in out])
    paper_steps = df[df.loop == "paper"].set_index(CELL_KEY).mean_steps
    df["penalty"] = [r.mean_steps / paper_steps[tuple(r[k] for k in CELL_KEY)] - 1 if r.loop == "ours" else np.nan
                     for _, r in df.iterrows()]
    return out, df, grid_wall


def main() -> None:
    args = _arguments()
    trials = args.trials or (100 if args.quick else 1000)
    t_all = time.perf_counter()

    scenarios = worlds(args.quick, args.worlds)
    budget = {k: v for k, v in (("guard_k", args.guard_k), ("collision_probability", args.collision_probability))
              if v is not None}
    if budget:
        scenarios = {w: dataclasses.replace(sc, navigation=dataclasses.replace(sc.navigation, **budget))
                     for w, sc in scenarios.items()}
    print(f"worlds: {', '.join(scenarios)}; {trials} trials per cell; methods {', '.join(METHODS)}; "
          f"loops paper (guard off, gate off) / ours (guard on, gate {default_scenario().navigation.gate_probability}); "
          f"faulty = {FAULTS}; {args.workers} workers")

    # Planning first: the hazard_weight 0 paths are the paper's safe paths, driven in section 1.
    jobs = [PlanJob(w, sc, name, bh) for w, sc in scenarios.items() for _, name in path_types(sc)
            for bh in [0.0, *args.weights]]
    t = time.perf_counter()
    plans = runner.map_ordered(plan_one, jobs, workers=args.workers)
    print(f"planned {len(jobs)} paths (RAw-RRT*, {default_scenario().navigation.plan_iterations} iterations each) "
          f"in {time.perf_counter() - t:.1f} s")
    plan_of = {(p["world"], p["path_type"], p["hazard_weight"]): p for p in plans}

    # 1. The navigation grid.
    cells = grid_cells(scenarios, plan_of, trials)
    out, df, grid_wall = run_grid(cells, trials, args.workers)

    print(f"\n1. navigation safety grid: {len(cells)} cells x {trials} trials, {grid_wall:.1f} s wall")
    print("   coll = collisions; other = other failures (lc left corridor, sl step limit, lost lost localization, "
          "np no path); penalty = ours/paper mean steps - 1;\n   clr = min clearance of the true track [m] "
          "(min over trials, 5th percentile); expo = mean exposure [m]; haz_s = mean hazard time [s];\n"
          "   NEES = mean 4-state NEES over all steps of the cell; out3s = mean fraction of steps outside 3 sigma; "
          "/tr = per trial; guard = slow+steer+hold events; faults = outliers+misassociated injected")
    print(cell_table(df))

    print_summary(df, cells, out, next(iter(scenarios)))
    print_nees(df)

    # 2. Hazard-aware planning.
    pdf = hazard_table(plans, plan_of, args.weights)

    # 3. Timing.
    print_timing(df, grid_wall, args.workers)

    if args.out is not None:
        written = results.write_table(df, args.out / "safety_cells", parquet=False)
        written += results.write_table(pdf, args.out / "safety_planning", parquet=False)
        print("\nwrote " + ", ".join(str(p) for p in written))
    print(f"\ntotal {time.perf_counter() - t_all:.1f} s")


if __name__ == "__main__":
    main()
