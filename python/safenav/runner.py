"""Monte Carlo runner for every experiment: SafeNav navigation sweeps
(section V-D: 1000 trials per path type and method) and the synthetic data
set (:mod:`safenav.experiments.synthetic`).

A *sweep* is the grid path types × methods × filters × sources, with N trials
in each cell.  :func:`run_trials` runs the trials of any grid of cells in
chunks, on local threads or a Dask cluster given by ``scheduler`` (an
address, or a ``distributed.Client``); navigation trials run inside the C++
core (``Navigator.run_many``, which releases the GIL), so threads suffice.

The seed rule, for every trial of every experiment
---------------------------------------------------
Trial i of a trial set gets the seed (:func:`trial_seeds`)::

    SeedSequence([seed, stream]).generate_state(N, uint64)[i]

where ``seed`` is the base seed and ``stream`` names the trial set: a
sweep's path type (its index in the scenario, :meth:`Sweep.path_index`), or
0 for the synthetic data set.  A random source inside a trial gets the
sub-seed ``_core.derive_seed(trial_seed, k)`` (:func:`sub_seed`), k its
number.  A trial's seed depends only on the base seed, the stream and i, so

* every method, filter and source sees the same random trials (common random
  numbers: paired comparisons), and
* the results are identical whatever the number of trials, workers or
  chunks, locally or on a Dask cluster.

The result of a sweep is a tidy :class:`pandas.DataFrame`, one row per trial;
:func:`summarize` averages it per cell, and :func:`safenav.results.write_table`
writes it (the wall-time columns to a separate file, so that the table itself
is byte-identical for a fixed seed).
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor, as_completed
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import pandas as pd

from . import _core, console
from . import navigation as nav
from .scenario import Scenario

__all__ = ["safety_line", "Sweep", "trial_seeds", "sub_seed", "SEED_RULE", "plan_safe_paths", "run_sweep", "run_trials",
           "map_ordered", "summarize", "safety_summary", "METRICS", "SAFETY", "COUNTS"]

#: The seed rule in one line (for ``parameters.json`` and the report).
SEED_RULE = ("trial i of stream p: SeedSequence([seed, p]).generate_state(N)[i], p the path type's index in the "
             "scenario (0 for the synthetic data set); random source k inside a trial: derive_seed(trial seed, k)")

#: Per-trial metric columns averaged by :func:`summarize` over the trials that arrived.
METRICS = ("path_ade", "goal_fde", "path_error_percent", "awrs", "awrs_true", "truth_ade", "truth_fde",
           "max_deviation")
#: Per-trial safety columns (ours): what the true vehicle met and whether the
#: filter knew its error; :func:`summarize` averages them over *all* trials.
SAFETY = ("min_clearance", "hazard_time", "hazard_length", "exposure", "nees", "outside_3sigma")
#: Per-trial counts: steps, updates, landmark observations and faults, guard events.
COUNTS = ("steps", "replans", "position_fixes", "dropouts", "rejected", "resets", "start_disputed", "observations",
          "dropped", "outliers", "misassociated", "ranges_rejected", "faults_through", "guard_slow", "guard_steer",
          "guard_hold", "stale_input")


@dataclass(frozen=True)
class Sweep:
    """What to run: the grid and its trial count."""

    scenario: Scenario
    path_types: tuple[str, ...] = ()        #: () = all of the scenario's
    methods: tuple[str, ...] = ("chull", "centroid")
    filters: tuple[str, ...] = ("ekf",)
    sources: tuple[str, ...] = ("lanbloc",)
    trials: int = 1000
    seed: int = 0
    n_particles: int = 500
    position_every: int = 1
    chunk: int = 50                          #: trials per work unit

    def __post_init__(self):
        if not isinstance(self.scenario, Scenario):
            raise ValueError(f"scenario = {self.scenario!r}: must be a safenav.Scenario")
        names = [p.name for p in self.scenario.path_types]
        pts = tuple(self.path_types) or tuple(names)
        for p in pts:
            if p not in names:
                raise ValueError(f"path_types: {p!r} is not a path type of the scenario (have: {names})")
        object.__setattr__(self, "path_types", pts)
        sources = {**nav.SOURCES, **{k: None for k in CAMERA_SOURCES}}
        for kind, values, table in (("methods", self.methods, nav.METHODS), ("filters", self.filters, nav.FILTERS),
                                    ("sources", self.sources, sources)):
            if not values:
                raise ValueError(f"{kind}: needs at least one")
            for v in values:
                if v not in table:
                    raise ValueError(f"{kind}: {v!r} is unknown (have: {sorted(table)})")
            object.__setattr__(self, kind, tuple(values))
        for name, lo in (("trials", 1), ("n_particles", 1), ("position_every", 1), ("chunk", 1)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
                raise ValueError(f"{name} = {v!r}: must be an integer >= {lo}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
            raise ValueError(f"seed = {self.seed!r}: must be an integer >= 0")

    def path_index(self, name: str) -> int:
        """The index of path type ``name`` in the scenario: it keys the path's trial seeds."""
        return [p.name for p in self.scenario.path_types].index(name)


def trial_seeds(seed: int, stream: int, n: int) -> np.ndarray:
    """The n trial seeds (uint64) of trial set ``stream`` (the seed rule
    above).  For a sweep ``stream`` is the path type's index in the
    *scenario* (see :meth:`Sweep.path_index`), so a run of a subset of the
    path types gives each the same trials as a full run."""
    return np.random.SeedSequence([int(seed), int(stream)]).generate_state(n, dtype=np.uint64)


def sub_seed(trial_seed, k: int) -> int:
    """The seed of random source ``k`` inside the trial of seed ``trial_seed``
    (the seed rule above: the core's ``derive_seed``, splitmix64)."""
    return int(_core.derive_seed(int(trial_seed), int(k)))


def plan_safe_paths(scenario: Scenario, path_types=None, *, progress: bool = False,
                    paper: bool = False) -> dict[str, np.ndarray]:
    """RAw-RRT* safe path of each path type (deterministic: the scenario's planner seed); ``paper``: the
    papers' paths (no hazard term, :func:`safenav.navigation.plan_safe_path`)."""
    names = list(path_types or [p.name for p in scenario.path_types])
    out = {}
    with console.progress(len(names), "planning", unit="path", enabled=progress) as bar:
        for name in names:
            out[name] = np.asarray(nav.plan_safe_path(scenario, name, paper=paper).path)
            bar.update()
    return out


@dataclass(frozen=True)
class _Cell:
    """One cell of a sweep: a path type with a method, filter and source.  Picklable (for Dask)."""

    scenario: Scenario
    path_type: str
    safe_path: np.ndarray
    method: str
    filter: str
    source: str
    n_particles: int
    position_every: int
    extra: dict = field(default_factory=dict)


#: Position sources that run the vision pipeline instead of a noise profile.
CAMERA_SOURCES = ("lanbloc-camera",)


def _camera_trials(navigator, c: _Cell, seeds) -> dict:
    """Trials with LanBLoc through the camera loop (its camera at its own resolution, from the
    scenario): each fix step the vehicle's localizer plans where the core's front end searches
    (windows from its own prediction), :class:`~safenav.vision.camera_loop.CameraFrames` renders
    those regions at the true pose, and the localizer detects, triangulates the markers' corners,
    trilaterates and updates (``Navigator.run_camera``, in the core).  With the scenario's
    landmark faults on, they act on each frame's ranged sightings before trilateration, with
    the vehicle at its true position (``apply_sighting_faults``, as the measurement level's
    ranges), and the loop counts them."""
    from .vision.camera_loop import CameraFrames

    d = {k: [] for k in ("outcome", "reason", "time_s", *COUNTS, *METRICS, *SAFETY)}
    for s in seeds:
        r = CameraFrames.from_scenario(c.scenario, seed=int(s) % 2**32).run(navigator, int(s))
        d["outcome"].append(int(r.outcome))
        d["reason"].append(r.reason)
        d["time_s"].append(r.wall_time)
        for k in COUNTS:
            d[k].append(getattr(r, k))
        for k in (*METRICS, *SAFETY):
            d[k].append(r.metrics[k])
    return d


def _run_chunk(c: _Cell, seeds: np.ndarray, start: int) -> pd.DataFrame:
    """Trials [start, start + len(seeds)) of cell ``c``: one row each."""
    camera = c.source in CAMERA_SOURCES
    navigator = nav.make_navigator(c.scenario, c.safe_path, method=c.method, filter=c.filter,
                                   source="lanbloc" if camera else c.source, n_particles=c.n_particles,
                                   position_every=c.position_every, record=False, **c.extra)
    d = _camera_trials(navigator, c, seeds) if camera else navigator.run_many([int(s) for s in seeds])
    n = len(seeds)
    df = pd.DataFrame({
        "path_type": [c.path_type] * n, "method": [c.method] * n, "filter": [c.filter] * n,
        "source": [c.source] * n, "trial": np.arange(start, start + n), "seed": seeds.astype(np.uint64),
    })
    df["outcome"] = [nav.OUTCOMES[o] for o in d["outcome"]]
    df["success"] = np.asarray(d["outcome"]) == 0
    df["reason"] = d["reason"]
    for k in (*COUNTS, *METRICS, *SAFETY):
        df[k] = np.asarray(d[k])
    df["time_ms"] = np.asarray(d["time_s"]) * 1e3
    df["time_per_step_us"] = df["time_ms"] * 1e3 / np.maximum(df["steps"], 1)
    return df


def _cells(sweep: Sweep, safe_paths: dict[str, np.ndarray], extra: dict) -> list[tuple[int, _Cell]]:
    return [(sweep.path_index(name), _Cell(sweep.scenario, name, safe_paths[name], method, filt, source,
                                           sweep.n_particles, sweep.position_every, dict(extra)))
            for name in sweep.path_types for method in sweep.methods for filt in sweep.filters
            for source in sweep.sources]


def run_sweep(sweep: Sweep, *, workers: int | None = None, scheduler=None, safe_paths=None,
              progress: bool = False, **navigator_options) -> pd.DataFrame:
    """Run every trial of ``sweep``; one row per trial, in (path type, method,
    filter, source, trial) order whatever ``workers`` or ``scheduler``.

    ``workers``: local threads (default: all cores).  ``scheduler``: a Dask
    scheduler address or a ``distributed.Client``; the same chunks then run on
    that cluster.  ``safe_paths``: precomputed {path type: path}; planned here
    otherwise.  ``navigator_options`` go to :func:`safenav.navigation.make_navigator`."""
    if safe_paths is None:
        safe_paths = plan_safe_paths(sweep.scenario, sweep.path_types, paper=bool(navigator_options.get("paper")))
    missing = [p for p in sweep.path_types if p not in safe_paths]
    if missing:
        raise ValueError(f"safe_paths: no path for {missing}")
    camera = any(source in CAMERA_SOURCES for source in sweep.sources)
    parts = run_trials(_run_chunk, _cells(sweep, safe_paths, navigator_options), seed=sweep.seed,
                       trials=sweep.trials, chunk=sweep.chunk, workers=workers, scheduler=scheduler, processes=camera,
                       progress=progress)
    return pd.concat([df for _, df in parts], ignore_index=True)


@dataclass(frozen=True)
class _TrialChunk:
    """A work unit of :func:`run_trials`: trials [start, start + len(seeds))
    of one cell.  Picklable (for Dask) when ``run`` is a module-level
    function and ``cell`` a dataclass."""

    run: Callable
    cell: object
    seeds: np.ndarray
    start: int


def _run_trial_chunk(c: _TrialChunk):
    return c.run(c.cell, c.seeds, c.start)


def run_trials(run, cells, *, seed: int, trials: int, chunk: int, workers: int | None = None, scheduler=None,
               progress: bool = False, desc: str = "trials", processes: bool = False) -> list:
    """``run(cell, seeds, start)`` for trials [start, start + len(seeds)) of
    every cell, in chunks of ``chunk`` trials; ``cells`` is a list of
    ``(stream, cell)`` pairs, and the ``trials`` trials of a cell have the
    seeds ``trial_seeds(seed, stream, trials)`` (the seed rule above), so
    cells of one stream share their trials.  Returns ``[(cell, result)]``,
    one per chunk, in the order of ``cells`` and then of the trials, whatever
    ``workers``, ``chunk`` or ``scheduler`` (see :func:`map_ordered`)."""
    chunks = []
    for stream, cell in cells:
        seeds = trial_seeds(seed, stream, trials)
        chunks += [_TrialChunk(run, cell, seeds[a:a + chunk], a) for a in range(0, trials, chunk)]
    out = map_ordered(_run_trial_chunk, chunks, workers=workers, scheduler=scheduler, progress=progress, desc=desc,
                      processes=processes)
    return [(c.cell, r) for c, r in zip(chunks, out)]


def map_ordered(fn, items, *, workers: int | None = None, scheduler=None, progress: bool = False,
                desc: str = "chunks", processes: bool = False) -> list:
    """``[fn(item) for item in items]``, run on local threads or a Dask cluster,
    returned in the order of ``items`` whatever order the work finishes in.

    ``fn`` and the items must be picklable for Dask (module-level functions and
    dataclasses).  ``workers``: local threads (default: all cores); useful when
    ``fn`` spends its time in C++ calls that release the GIL.  ``processes``:
    local processes instead (``spawn``), for work that holds the GIL (the
    camera loop's Python per frame; :func:`run_sweep` uses them for camera
    sources, so a script that runs such a sweep needs Python's
    ``if __name__ == "__main__":`` guard); with one worker it runs in this
    process.
    ``scheduler``: a Dask scheduler address or a ``distributed.Client``."""
    items = list(items)
    if scheduler is None:
        n = workers if workers is not None else (os.cpu_count() or 1)
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ValueError(f"workers = {workers!r}: must be an integer >= 1")
    with console.progress(len(items), desc, unit="chunk", enabled=progress) as bar:
        if scheduler is not None:
            return _run_dask(fn, items, scheduler, bar)
        out = [None] * len(items)
        if processes and int(n) > 1:
            import multiprocessing
            from concurrent.futures import ProcessPoolExecutor
            pool = ProcessPoolExecutor(max_workers=int(n), mp_context=multiprocessing.get_context("spawn"),
                                       initializer=_quiet_worker)
        else:
            pool = ThreadPoolExecutor(max_workers=int(n))
        try:
            futures = {pool.submit(fn, c): i for i, c in enumerate(items)}
            for fut in as_completed(futures):
                out[futures[fut]] = fut.result()
                bar.update()
        except BaseException:       # a failed item, Ctrl-C or SIGTERM: drop the queued items, don't run them
            pool.shutdown(wait=False, cancel_futures=True)
            raise
        pool.shutdown()
        return out


def _quiet_worker() -> None:
    """A process worker: OpenCV on one thread (the pool's processes are the parallelism)."""
    try:
        import cv2
        cv2.setNumThreads(1)
    except ImportError:   # pragma: no cover - OpenCV is a dependency
        pass


@contextmanager
def connect(scheduler):
    """A ``distributed.Client`` for a run: connected to ``scheduler`` (an
    address; 10 s time-out) and closed afterwards, or ``scheduler`` itself
    when it is a client already or None (local threads).  Errors name the
    address."""
    if scheduler is None or not isinstance(scheduler, str):
        yield scheduler
        return
    try:
        from distributed import Client
    except ImportError:
        raise ValueError(f"scheduler {scheduler!r}: needs Dask, which is not installed "
                         "(pip install 'safenav[dask]')") from None
    try:
        client = Client(scheduler, timeout=10)
    except (OSError, TimeoutError, ValueError) as exc:
        raise ValueError(f"scheduler {scheduler!r}: cannot connect ({exc})") from None
    with client:
        yield client


def _run_dask(fn, items, scheduler, bar):
    from distributed import as_completed as dask_completed

    with connect(scheduler) as client:
        futures = client.map(fn, items, pure=False)
        index = {f.key: i for i, f in enumerate(futures)}
        out = [None] * len(items)
        for fut in dask_completed(futures):
            out[index[fut.key]] = fut.result()
            bar.update()
        return out


def safety_summary(g: pd.DataFrame) -> dict:
    """The safety numbers of a group of trials (all of them, failures
    included): collision rate, the distribution of minimum clearance, hazard
    time, length and exposure, mean NEES, the share of steps outside 3σ,
    guard events per trial and their share of steps, gate rejections,
    position resets, and the landmark faults injected and let through."""
    clear = g["min_clearance"].to_numpy(float)
    steps = np.maximum(g["steps"].to_numpy(float), 1)
    guard = (g["guard_slow"] + g["guard_steer"] + g["guard_hold"]).to_numpy(float)
    return {
        "collision_rate": float((g["outcome"] == "collision").mean()),
        "min_clearance_min": float(clear.min()),
        "min_clearance_p5": float(np.percentile(clear, 5)),
        "min_clearance_median": float(np.median(clear)),
        "hazard_time": float(g["hazard_time"].mean()),
        "hazard_length": float(g["hazard_length"].mean()),
        "exposure": float(g["exposure"].mean()),
        "nees": float(g["nees"].mean()),
        "outside_3sigma": float(g["outside_3sigma"].mean()),
        "guard_events": float(guard.mean()),
        "guard_share": float((guard / steps).mean()),
        "guard_hold": float(g["guard_hold"].mean()),
        "stale_input": float(g["stale_input"].mean()),
        "rejected": float(g["rejected"].mean()),
        "resets": float(g["resets"].mean()),
        "dropped": float(g["dropped"].mean()),
        "faults_injected": int((g["outliers"] + g["misassociated"]).sum()),
        "faults_through": int(g["faults_through"].sum()),
    }


def summarize(raw: pd.DataFrame) -> pd.DataFrame:
    """Per cell (path type, method, filter, source): trial count, success rate,
    the metrics' means over the *arrived* trials, the median time per
    trial [ms] and per step [µs] over all trials, and the safety numbers of
    :func:`safety_summary` over all trials."""
    if raw.empty:
        raise ValueError("summarize: the raw table has no rows")
    keys = ["path_type", "method", "filter", "source"]
    rows = []
    for cell, g in raw.groupby(keys, sort=False):
        ok = g[g["success"]]
        row = dict(zip(keys, cell))
        row["trials"] = len(g)
        row["success_rate"] = float(g["success"].mean())
        for k in METRICS:
            row[k] = float(ok[k].mean()) if len(ok) else float("nan")
        row["steps"] = float(g["steps"].mean())
        row["replans"] = float(g["replans"].mean())
        row["dropout_share"] = float((g["dropouts"] / np.maximum(g["steps"], 1)).mean())
        row["time_ms"] = float(g["time_ms"].median())
        row["time_per_step_us"] = float(g["time_per_step_us"].median())
        for o in nav.OUTCOMES[1:]:
            row[f"n_{o}"] = int((g["outcome"] == o).sum())
        row.update(safety_summary(g))
        rows.append(row)
    return pd.DataFrame(rows)


def safety_line(raw: pd.DataFrame, loop: str, scenario: Scenario) -> str:
    """One paragraph: collisions, clearance, exposure (its unavoidable part apart), consistency and the guard,
    for the whole sweep."""
    from .planning import map_from_world, unavoidable_exposure

    s = safety_summary(raw)
    hazards = map_from_world(scenario.world)
    floor = {p: unavoidable_exposure(scenario.path_polyline(p)[0], scenario.path_polyline(p)[-1], hazards)
             for p in raw["path_type"].unique()}
    unavoidable = float(raw["path_type"].map(floor).mean())
    n_coll = int((raw["outcome"] == "collision").sum())
    where = ", ".join(f"{m} {p}: {len(g)}" for (m, p), g in raw[raw["outcome"] == "collision"]
                      .groupby(["method", "path_type"], sort=False))
    name = "ours (guard and gate on)" if loop == "ours" else "the papers' loop (no guard, no gate)"
    return (f"Safety, {name}: {n_coll} of {len(raw)} trials collided" + (f" ({where})" if where else "")
            + f"; true-track clearance min {s['min_clearance_min']:.2f} m, 5th percentile "
              f"{s['min_clearance_p5']:.2f} m; hazard time {s['hazard_time']:.1f} s and exposure "
              f"{s['exposure']:.1f} m per trial ({unavoidable:.1f} m unavoidable: a start or destination inside "
              f"a hazard); mean NEES {s['nees']:.2f} (4 if consistent), "
              f"{s['outside_3sigma']:.1%} of steps outside 3σ; guard events {s['guard_events']:.0f} per trial "
              f"({s['guard_share']:.1%} of steps); updates rejected {s['rejected']:.0f}, position resets "
              f"{s['resets']:.2f} per trial; landmark faults injected {s['faults_injected']}, through "
              f"{s['faults_through']}.")
