"""Run the SafeNav paper's experiments (``safenav experiment NAME|all``):
the options every experiment shares, one function per experiment, and
:func:`run_experiments`.  See :mod:`safenav.experiments` for the overview."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from .. import console, runner
from ..results import write_json, write_table
from ..scenario import Scenario, default_scenario
from .claims import localization_claims, navigation_claims
from .figures import navigation_figures, plot_field, plot_wrs_comparison
from .paper import (METHOD_LABELS, PAPER_SOURCES, SAFETY_COLUMNS, PAPER_TABLE1, PAPER_TABLE2, localization_table,
                    navigation_table, percent_error_table, source_label)
from .report import parameters
from .synthetic import SyntheticConfig, summarize_synthetic, synthetic_experiment

__all__ = ["ExperimentOptions", "ExperimentResult", "EXPERIMENTS", "ALIASES", "resolve", "run_experiments",
           "placed_scenario"]



@dataclass
class ExperimentOptions:
    """What every experiment shares (the ``safenav experiment`` options)."""

    trials: int = 1000                 #: Monte Carlo trials per cell (the paper's 1000)
    camera_trials: int = 1000          #: trials per cell of the camera-in-the-loop variants (0 = skip them)
    camera_position_every: int = 10    #: a camera frame every n steps
    particles: int = 1000              #: PF particles
    workers: int | None = None         #: local threads (default: all cores)
    scheduler: object = None           #: Dask scheduler address or distributed.Client
    seed: int | None = None            #: default: the scenario's ``seeds.trials``
    out: str | Path = "out/experiments"
    scenario: Scenario | None = None   #: default: the built-in scenario
    path_types: tuple[str, ...] = ()   #: () = all of the scenario's
    placement: bool = True             #: Table II also with landmarks placed along the safe paths
    progress: bool = False

    def __post_init__(self):
        for name, lo in (("trials", 1), ("camera_trials", 0), ("camera_position_every", 1), ("particles", 1),
                         ("workers", 1)):
            v = getattr(self, name)
            if name == "workers" and v is None:
                continue
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
                raise ValueError(f"{name} = {v!r}: must be an integer >= {lo}")
        if self.scenario is None:
            self.scenario = default_scenario()
        if self.seed is None:
            self.seed = self.scenario.seeds.trials
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise ValueError(f"seed = {self.seed!r}: must be an integer >= 0")
        names = [p.name for p in self.scenario.path_types]
        self.path_types = tuple(self.path_types) or tuple(names)
        for p in self.path_types:
            if p not in names:
                raise ValueError(f"path_types: {p!r} is not a path type of the scenario (have: {names})")
        self.out = Path(self.out)

    def sweep(self, scenario: Scenario | None = None, **kw) -> runner.Sweep:
        """The sweep of these options' path types, seed and particles on
        ``scenario`` (default: the options'); ``kw`` sets the rest."""
        return runner.Sweep(scenario or self.scenario, path_types=self.path_types, seed=int(self.seed),
                            n_particles=self.particles, **kw)

    def describe(self) -> dict:
        """The options as plain values (for the report and ``parameters.json``)."""
        return {"trials": self.trials, "camera_trials": self.camera_trials,
                "camera_position_every": self.camera_position_every, "particles": self.particles,
                "placement": self.placement, "workers": self.workers,
                "scheduler": None if self.scheduler is None else str(self.scheduler),
                "seed": int(self.seed), "scenario": self.scenario.name, "path_types": list(self.path_types)}


@dataclass
class ExperimentResult:
    """What an experiment produced: tables (title -> DataFrame), figures, files, notes and claims."""

    name: str
    title: str
    tables: dict = field(default_factory=dict)
    figures: list = field(default_factory=list)
    files: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    claims: list = field(default_factory=list)
    wall_s: float = 0.0
    camera_s: float = 0.0      #: of wall_s, the camera-in-the-loop variant's trials


# --------------------------------------------------------------------------- helpers

def _write_summary(res: ExperimentResult, folder: Path, name: str, title: str, df: pd.DataFrame) -> None:
    """Add ``df`` to the result and write it as ``name.csv`` and ``name.md`` (timings beside them)."""
    res.tables[title] = df
    res.files += write_table(df, folder / name, parquet=False, markdown=title)


def _run(opts: ExperimentOptions, sweep: runner.Sweep, safe: dict, **navigator_options) -> pd.DataFrame:
    return runner.run_sweep(sweep, workers=opts.workers, scheduler=opts.scheduler, safe_paths=safe,
                            progress=opts.progress, **navigator_options)


def safety_table(ours: pd.DataFrame, paper: pd.DataFrame) -> pd.DataFrame:
    """Per method and path type, the papers' loop (no guard, no gate) beside
    ours on the same trials: collisions, arrival, the least and 5th-percentile
    clearance of the true track, hazard time and exposure, mean NEES (4 if
    consistent), the share of steps outside 3σ, guard events per trial and
    the guard's mission-time cost (mean steps, ours / paper − 1)."""
    rows = []
    for loop, raw in (("paper", paper), ("ours", ours)):
        for (method, path), g in raw.groupby(["method", "path_type"], sort=False):
            s = runner.safety_summary(g)
            rows.append({"Approach": METHOD_LABELS.get(method, method), "Path": path, "loop": loop,
                         "trials": len(g), "collisions": int((g["outcome"] == "collision").sum()),
                         "arrived": float(g["success"].mean()), "clearance min m": s["min_clearance_min"],
                         "clearance p5 m": s["min_clearance_p5"], "hazard s": s["hazard_time"],
                         "exposure m": s["exposure"], "NEES": s["nees"], "out 3σ": s["outside_3sigma"],
                         "guard events": s["guard_events"], "mean steps": float(g["steps"].mean())})
    t = pd.DataFrame(rows)
    base = t[t["loop"] == "paper"].set_index(["Approach", "Path"])["mean steps"]
    t["time cost"] = [r["mean steps"] / base[(r["Approach"], r["Path"])] - 1.0 for _, r in t.iterrows()]
    return t


def _collision_note(table: pd.DataFrame) -> str:
    """Says plainly where each loop collided."""
    out = []
    for loop in ("paper", "ours"):
        hit = table[(table["loop"] == loop) & (table["collisions"] > 0)]
        where = ", ".join(f"{r['Approach']} on {r['Path']}: {r['collisions']} of {r['trials']}" for _, r in hit.iterrows())
        name = "The papers' loop (no guard, no gate)" if loop == "paper" else "Ours (guard and gate on)"
        out.append(f"{name} collided {'in ' + where if where else 'in no trial'}.")
    return " ".join(out)


def _safe_paths(opts: ExperimentOptions, cache: dict) -> dict:
    key = ("safe", opts.path_types)
    if key not in cache:
        # the papers' paths (no hazard term): the experiments reproduce the papers' configuration
        cache[key] = runner.plan_safe_paths(opts.scenario, list(opts.path_types), progress=opts.progress, paper=True)
    return cache[key]


def _path_average(summary: pd.DataFrame) -> pd.DataFrame:
    """Per (source, filter): the mean over path types of each cell's means
    (the paper's Table II averages over P1-P3); time = mean of the medians.

    Table II compares *localization* methods, so its ADE and FDE are those of
    the estimate against the true vehicle (``truth_ade``, ``truth_fde``); AWRS
    is the estimate's risk about the safe path, as everywhere."""
    cols = {"truth_ade": "mean", "truth_fde": "mean", "awrs": "mean", "path_error_percent": "mean", "time_ms": "mean",
            "time_per_step_us": "mean", "success_rate": "mean", "trials": "sum",
            **{k: "mean" for k in SAFETY_COLUMNS if k in summary}}
    g = summary.groupby(["source", "filter"], sort=False).agg(cols).reset_index()
    return g.rename(columns={"time_ms": "ms_per_trial"})


def _outcomes(raw: pd.DataFrame) -> str:
    """A sentence: how many trials arrived, and how the others ended."""
    fails = raw[~raw["success"]]
    why = ", ".join(f"{k} {v}" for k, v in fails["outcome"].value_counts().items())
    return (f"Metrics are means over the {len(raw) - len(fails)} of {len(raw)} trials that arrived"
            + (f"; the others ended in: {why}." if len(fails) else "."))


def _fix_share(raw: pd.DataFrame, by) -> pd.Series:
    """The mean share of steps with a position fix, per group of ``by`` columns."""
    return (raw["position_fixes"] / raw["steps"].clip(lower=1)).groupby([raw[c] for c in by], sort=False).mean()


def _fix_shares(raw: pd.DataFrame) -> str:
    """How often each source delivered a position fix (share of steps)."""
    share = _fix_share(raw, ["source"])
    return ("Share of steps with a position fix: " + ", ".join(f"{source_label(k)} {v:.0%}" for k, v in
                                                                share.items())
            + ". LanBLoc fixes only while at least the scenario's minimum number of landmarks is in range and in "
              "view, so between clusters it dead-reckons on the IMU; the emulated baselines fix at every step.")


# --------------------------------------------------------------------------- experiments

def run_field(opts: ExperimentOptions, cache: dict) -> ExperimentResult:
    """Fig. 1: the field and the safe paths."""
    from ..metrics import path_length

    res = ExperimentResult("field", "Fig. 1: the real-imitated field")
    folder = opts.out / "field"
    safe = _safe_paths(opts, cache)
    res.figures.append(plot_field(opts.scenario, safe, folder / "fig1_field.png"))
    w = opts.scenario.world
    rows = [{"path type": k, "clusters": " → ".join(map(str, opts.scenario.path_type(k).clusters)),
             "safe path waypoints": len(p), "safe path length m": path_length(p),
             "cluster polyline length m": path_length(opts.scenario.path_polyline(k))} for k, p in safe.items()]
    _write_summary(res, folder, "safe_paths", "Safe paths (RAw-RRT*) of the path types", pd.DataFrame(rows))
    res.notes.append(f"{w.field.describe()}; {len(w.obstacles)} obstacles, {len(w.hazards)} hazards, "
                     f"{len(w.landmarks)} landmarks in {len(w.cluster_ids)} clusters (the paper: 200×200 m, "
                     "25 obstacles, 25 hazards).")
    return res


def run_synthetic(opts: ExperimentOptions, cache: dict) -> ExperimentResult:
    """Table I and Fig. 3 on the synthetic data set."""
    res = ExperimentResult("synthetic", "Table I: synthetic trajectories; Fig. 3: weighted risk")
    folder = opts.out / "synthetic"
    cfg = SyntheticConfig()
    out = synthetic_experiment(opts.trials, sources=PAPER_SOURCES, filters=("ekf", "pf"), seed=int(opts.seed),
                                  n_particles=opts.particles, config=cfg, workers=opts.workers,
                                  scheduler=opts.scheduler, progress=opts.progress)
    raw = out.raw
    res.files += write_table(raw, folder / "trials")
    summary = summarize_synthetic(raw)
    table = localization_table(summary, PAPER_TABLE1)
    _write_summary(res, folder, "table1", f"Table I: synthetic trajectories, {opts.trials} trials "
                   f"({cfg.n_steps} steps of {cfg.dt} s; PF {opts.particles} particles); ADE / FDE against the true "
                   "trajectory; time = median per trial",
                   table)
    labels = {s: source_label(s) for s in PAPER_SOURCES}
    t = (np.arange(cfg.n_steps + 1)) * cfg.dt
    res.figures.append(plot_wrs_comparison(out.wrs_mean, t, folder / "fig3_wrs.png", labels=labels,
                                           title=f"Fig. 3: mean WRS per step over {opts.trials} synthetic trials"))
    res.claims += localization_claims(raw, "Table I", paper=PAPER_TABLE1,
                                       columns=("truth_ade", "truth_fde", "awrs", "ms_per_trial"))
    res.notes.append("The synthetic trajectory is the paper's a(t), θ(t) profile driving the noisy BMM; its "
                     "length (N = 200 steps), initial speed and IMU noise are ours (the paper does not give them). "
                     "AWRS is measured against the true trajectory as the central path.")
    return res


def run_real_imitated(opts: ExperimentOptions, cache: dict) -> ExperimentResult:
    """Table II: sources × filters on the real-imitated world, mean over P1-P3; camera-loop variant."""
    res = ExperimentResult("real-imitated", "Table II: real-imitated trajectories")
    folder = opts.out / "real-imitated"
    safe = _safe_paths(opts, cache)
    raw = _run_cells(opts, safe, cache, methods=("centroid",), filters=("ekf", "pf"), sources=PAPER_SOURCES,
                     trials=opts.trials, position_every=1)
    res.files += write_table(raw, folder / "trials")
    summary = runner.summarize(raw)
    res.files += write_table(summary, folder / "summary_per_path", parquet=False)
    table = localization_table(_path_average(summary), PAPER_TABLE2)
    _write_summary(res, folder, "table2", f"Table II: real-imitated world, mean over {', '.join(opts.path_types)}, "
                   f"{opts.trials} trials per path type (SafeNav-Centroid along the safe path; PF "
                   f"{opts.particles} particles); ADE / FDE against the true vehicle; time = mean over path types "
                   "of the median per trial", table)
    res.claims += localization_claims(raw, "Table II", paper=PAPER_TABLE2,
                                       columns=("truth_ade", "truth_fde", "awrs", "time_ms"))
    res.notes.append("The paper does not say which controller drove its Table II trials; we follow each safe path "
                     "with SafeNav-Centroid (Algorithm 2), the same path and seeds for every source and filter. "
                     "ADE and FDE here are localization errors: the estimate against the true vehicle at each step "
                     "(Table II compares localization methods). " + _outcomes(raw) + " " + _fix_shares(raw))
    if opts.placement:
        _placed_variant(opts, safe, folder, res, cache, raw)
    if opts.camera_trials:
        _camera_variant(opts, safe, folder, res, cache, methods=("centroid",), filters=("ekf", "pf"),
                        key=["filter"], label="Table II")
    return res


def _run_cells(opts: ExperimentOptions, safe: dict, cache: dict, *, methods, filters, sources, trials: int,
               position_every: int, chunk: int = 50) -> pd.DataFrame:
    """Trials of every (method, filter, source) cell over the path types, each
    cell run once per session (the camera variants of Tables II and IV share
    SafeNav-Centroid with the EKF)."""
    frames = []
    for m in methods:
        for f in filters:
            for s in sources:
                key = ("cell", m, f, s, trials, position_every, opts.path_types)
                if key not in cache:
                    sweep = opts.sweep(methods=(m,), filters=(f,), sources=(s,), trials=trials,
                                   position_every=position_every, chunk=chunk)
                    cache[key] = _run(opts, sweep, safe)
                frames.append(cache[key])
    order = {p: i for i, p in enumerate(opts.path_types)}
    raw = pd.concat(frames, ignore_index=True)
    # (path type, method, filter, source, trial) order, as run_sweep
    return raw.sort_values("path_type", key=lambda c: c.map(order), kind="stable").reset_index(drop=True)


def placed_scenario(scenario: Scenario, safe: dict, *, k: int | None = None, method: str = "optimal",
                    spacing: float = 2.0, occlusion: bool = True):
    """``scenario`` with landmarks added along its safe paths by the landmark
    placement code (:func:`safenav.placement.place_along_path`), so that a
    vehicle on any of the paths has at least ``k`` (default: the scenario's
    ``detection.min_landmarks``, what trilateration needs) in view.  The
    placement camera is narrower and shorter than the vehicle's (field of
    view − 25°, 90 % of the detection range) to leave a margin for heading and
    cross-track deviations; landmarks keep the planner's clearance from the
    path.  ``occlusion`` (default on): the world's obstacles hide landmarks,
    so a landmark counts only where the camera has a line of sight to it
    (``False``: the placement paper's model, nothing hides).  Returns
    (scenario, {path type: PlacementResult})."""
    from dataclasses import replace

    from .. import placement as P
    from ..certify import placement_camera
    from ..world import Landmark

    k = k or scenario.detection.min_landmarks
    cam = placement_camera(scenario)
    placed, added = {}, []
    next_id = max((lm.id for lm in scenario.world.landmarks), default=-1) + 1
    cluster = max(scenario.world.cluster_ids, default=-1) + 1
    seen = {tuple(np.round(lm.xy, 6)) for lm in scenario.world.landmarks}
    for name, path in safe.items():
        placed[name] = P.place_along_path(path, cam, world=scenario.world, spacing=spacing, k=k, method=method,
                                          occlusion=bool(occlusion) and bool(scenario.world.obstacles))
        for xy in placed[name].landmarks:
            key = tuple(np.round(xy, 6))
            if key not in seen:
                seen.add(key)
                added.append(Landmark(next_id, tuple(float(v) for v in xy), "placed", cluster))
                next_id += 1
    world = replace(scenario.world, landmarks=scenario.world.landmarks + tuple(added))
    return replace(scenario, world=world, name=f"{scenario.name}+placed"), placed


def _placed_variant(opts, safe, folder, res, cache, raw):
    """Beyond the paper: LanBLoc with landmarks placed along the safe paths
    (the placement paper's method, ILP), beside LanBLoc in the scenario's own
    clusters, on the same trials."""
    t0 = time.perf_counter()
    with console.task("placing landmarks along the safe paths (ILP)", enabled=opts.progress):
        scenario, placed = placed_scenario(opts.scenario, safe)
    t_place = time.perf_counter() - t0
    t0 = time.perf_counter()
    with console.task("the same without occlusion, for comparison (ILP)", enabled=opts.progress):
        _, unoccluded = placed_scenario(opts.scenario, safe, occlusion=False)
    t_plain = time.perf_counter() - t0
    sweep = opts.sweep(scenario, methods=("centroid",), filters=("ekf", "pf"), sources=("lanbloc",),
                   trials=opts.trials)
    placed_raw = _run(opts, sweep, safe).assign(source="lanbloc-placed")
    res.files += write_table(placed_raw, folder / "placed_trials")
    both = pd.concat([raw[raw["source"] == "lanbloc"], placed_raw], ignore_index=True)
    summary = _path_average(runner.summarize(both))
    share = _fix_share(both, ["source", "filter"])
    rows = []
    for _, r in summary.iterrows():
        rows.append({"Landmarks": "scenario clusters" if r["source"] == "lanbloc" else "clusters + placed (k = "
                     f"{opts.scenario.detection.min_landmarks}, ILP)", "Filter": r["filter"].upper(),
                     "ADE": r["truth_ade"], "FDE": r["truth_fde"], "AWRS": r["awrs"], "time ms": r["ms_per_trial"],
                     "fix share": share[(r["source"], r["filter"])], "arrived": r["success_rate"]})
    n_added = len(scenario.world.landmarks) - len(opts.scenario.world.landmarks)
    cam = next(iter(placed.values())).camera
    _write_summary(res, folder, "table2_placed", "Beyond the paper: LanBLoc-BMM with landmarks placed along the "
                   f"safe paths ({n_added} added to the scenario's {len(opts.scenario.world.landmarks)}), same "
                   "trials as Table II; ADE / FDE against the true vehicle", pd.DataFrame(rows))
    res.notes.append(f"Placed landmarks: {n_added} in all, "
                     + ", ".join(f"{k} {len(p.landmarks)}" for k, p in placed.items())
                     + f" (ILP per path, obstacles hide landmarks, {t_place:.1f} s); every point of each safe path "
                     f"has at least {opts.scenario.detection.min_landmarks} in a {cam.angle_deg:g}° sector of "
                     f"{cam.range:g} m with a clear line of sight (docs/placement.md).  Without occlusion (the "
                     "placement paper's model, not used in the trials): "
                     + ", ".join(f"{k} {len(p.landmarks)}" for k, p in unoccluded.items())
                     + f" ({t_plain:.1f} s).")


def _camera_variant(opts, safe, folder, res, cache, *, methods, filters, key, label):
    """LanBLoc through the camera loop beside LanBLoc at the measurement level
    with the same fix rate, on the same trials (the first ``camera_trials``
    seeds of each path type)."""
    n = opts.camera_trials
    kw = dict(methods=methods, filters=filters, trials=n, position_every=opts.camera_position_every)
    t0 = time.perf_counter()
    meas = _run_cells(opts, safe, cache, sources=("lanbloc",), **kw)
    cam = _run_cells(opts, safe, cache, sources=("lanbloc-camera",), chunk=10, **kw)
    res.camera_s += time.perf_counter() - t0
    raw = pd.concat([meas, cam], ignore_index=True)
    res.files += write_table(raw, folder / "camera_trials")
    s = runner.summarize(raw)
    keys = ["path_type", *key]
    rows = []
    for cell, g in s.groupby(keys, sort=False):
        m = g[g["source"] == "lanbloc"].iloc[0]
        c = g[g["source"] == "lanbloc-camera"].iloc[0]
        row = dict(zip(keys, cell))
        row["Path"] = row.pop("path_type")
        for k in ("method", "filter"):
            if k in row:
                row[k] = METHOD_LABELS.get(row[k], row[k].upper() if k == "filter" else row[k])
        for col, name in (("path_ade", "path ADE"), ("goal_fde", "goal FDE"), ("awrs", "AWRS"),
                          ("path_error_percent", "% err"), ("truth_ade", "truth ADE"), ("success_rate", "success")):
            row[f"{name} meas."] = m[col]
            row[f"{name} camera"] = c[col]
        row["camera ms/trial"] = c["time_ms"]
        rows.append(row)
    table = pd.DataFrame(rows)
    title = (f"{label}, camera in the loop: LanBLoc rendered and detected by region at the scenario camera's "
             f"resolution, ranged by triangulating the markers' corners, trilaterated, against LanBLoc at the "
             f"measurement level asked as often (every {opts.camera_position_every} steps), same {n} trials per "
             f"cell")
    _write_summary(res, folder, "camera_loop", title, table)
    res.notes.append(f"Camera loop ({label}): {len(cam)} trials, {cam['time_ms'].median() / 1e3:.1f} s median per "
                     "trial. 'path ADE' is the estimate's mean distance to the safe path, 'goal FDE' its final "
                     "distance to the destination, 'truth ADE' its mean error against the true vehicle; the camera "
                     "loop's fixes come from stereo pairs of the scenario's camera at its own resolution, rendered "
                     "and detected by region, the markers' corners triangulated (docs/lanbloc.md).")


def run_navigation(opts: ExperimentOptions, cache: dict) -> ExperimentResult:
    """Tables III and IV, Figs. 4 and 5; camera-loop variant."""
    res = ExperimentResult("navigation", "Tables III and IV, Figs. 4 and 5: SafeNav-CHull and SafeNav-Centroid")
    folder = opts.out / "navigation"
    safe = _safe_paths(opts, cache)
    sweep = opts.sweep(methods=("chull", "centroid"), filters=("ekf",), sources=("lanbloc",), trials=opts.trials)
    raw = _run(opts, sweep, safe)
    res.files += write_table(raw, folder / "trials")
    summary = runner.summarize(raw)
    res.files += write_table(summary, folder / "summary", parquet=False)
    pe = percent_error_table(summary)
    nt = navigation_table(summary)
    _write_summary(res, folder, "table3", f"Table III: % path-length error (SafeNav-ext eq. 23), LanBLoc-BMM(EKF), "
                   f"{opts.trials} trials per path type", pe)
    _write_summary(res, folder, "table4", "Table IV: ADE (estimate to the safe path) / FDE (final estimate to "
                   "the destination) [m], AWRS and median time per trial, "
                   f"LanBLoc-BMM(EKF), {opts.trials} trials per path type", nt)
    with console.task("Figs. 4-5 (trial 0 of each path type, recorded)", enabled=opts.progress):
        res.figures += navigation_figures(opts.scenario, safe, sweep, folder)
    res.claims += navigation_claims(raw)
    # The same trials in the papers' loop, for the safety table.
    paper_raw = _run(opts, sweep, safe, paper=True)
    res.files += write_table(paper_raw, folder / "trials_paper_loop")
    st = safety_table(raw, paper_raw)
    _write_summary(res, folder, "safety", f"Safety (ours): the papers' loop and ours on the same {opts.trials} "
                   "trials per path type (LanBLoc-BMM(EKF)); clearance and hazards of the true track", st)
    res.notes.append(_collision_note(st) + " Tables III and IV are from our loop (the guard and the χ² gate "
                     "on); the papers' loop is `paper=True` (docs/safety.md).")
    res.notes.append("ADE (path_ade) is the mean distance of the estimate to the safe path (cross-track; our reading "
                     "of SafeNav-ext eq. 21, whose point-wise pairing is undefined for an untimed path), FDE "
                     "(goal_fde) the final estimate's distance to the destination. " + _outcomes(raw))
    if opts.camera_trials:
        _camera_variant(opts, safe, folder, res, cache, methods=("chull", "centroid"), filters=("ekf",),
                        key=["method"], label="Table IV")
    return res


#: name -> (runner, one-line description)
EXPERIMENTS = {
    "field": (run_field, "Fig. 1: the field, clusters, obstacles, hazards and safe-path buffers"),
    "synthetic": (run_synthetic, "Table I and Fig. 3: four localization sources × EKF/PF on synthetic data"),
    "real-imitated": (run_real_imitated, "Table II: the same grid on the real-imitated world (+ camera loop)"),
    "navigation": (run_navigation, "Tables III-IV, Figs. 4-5: SafeNav-CHull vs SafeNav-Centroid (+ camera loop)"),
}
#: The paper's table and figure names, for ``safenav experiment table2`` etc.
ALIASES = {"fig1": "field", "table1": "synthetic", "fig3": "synthetic", "table2": "real-imitated",
           "table3": "navigation", "table4": "navigation", "fig4": "navigation", "fig5": "navigation"}


def resolve(names) -> list[str]:
    """Experiment names (``all``, names or the paper's table/figure aliases) to
    experiment keys in run order, without repeats; a clear error for an unknown one."""
    if isinstance(names, str):
        names = [names]
    keys = []
    for n in names:
        if n == "all":
            keys += list(EXPERIMENTS)
            continue
        k = ALIASES.get(n, n)
        if k not in EXPERIMENTS:
            raise ValueError(f"experiment {n!r} is unknown (have: all, {', '.join(EXPERIMENTS)}; "
                             f"aliases: {', '.join(ALIASES)})")
        keys.append(k)
    if not keys:
        raise ValueError("experiment: name at least one (or 'all')")
    return [k for k in EXPERIMENTS if k in keys]


def run_experiments(names, opts: ExperimentOptions, *, show=print) -> list[ExperimentResult]:
    """Run the named experiments (see :func:`resolve`); each writes its files
    under ``opts.out``.  Returns their results in run order.  ``show`` gets
    each table as text (status lines go to :mod:`safenav.console`)."""
    keys = resolve(names)
    opts.out.mkdir(parents=True, exist_ok=True)
    cache: dict = {}
    address = opts.scheduler
    with runner.connect(address) as client:         # one connection for every sweep
        opts.scheduler = client
        try:
            done = _run_all(keys, opts, cache, show)
        finally:
            opts.scheduler = address
    write_json(opts.out / "parameters.json", parameters(opts))
    return done


def _run_all(keys, opts: ExperimentOptions, cache: dict, show) -> list[ExperimentResult]:
    done = []
    for k in keys:
        fn, desc = EXPERIMENTS[k]
        console.info(f"[experiment] {k}: {desc}")
        t0 = time.perf_counter()
        res = fn(opts, cache)
        res.wall_s = time.perf_counter() - t0
        for title, df in res.tables.items():
            show(f"\n{title}\n{df.to_string(index=False, float_format=lambda v: f'{v:.4g}')}")
        console.info(f"[experiment] {k}: {res.wall_s:.1f} s"
                     + (f", of which the camera loop {res.camera_s:.1f} s" if res.camera_s else ""))
        done.append(res)
    return done
