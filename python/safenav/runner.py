"""Monte Carlo runner for SafeNav navigation (section V-D: 1000 trials per
path type and method).

A *sweep* is the grid path types × methods × filters × sources, with N trials
in each cell.  Trial i of path type p has the seed
``SeedSequence([seed, p_index]).generate_state(N)[i]``: it depends only on the
base seed, the path type and i, so

* every method, filter and source sees the same random trials (common random
  numbers: paired comparisons), and
* the results are identical whatever the number of workers or chunks, locally
  or on a Dask cluster.

Trials run in chunks inside the C++ core (``Navigator.run_many``, which
releases the GIL), so local workers are threads; a Dask cluster given by
``scheduler`` (an address, or a ``distributed.Client``) runs the same chunks.

The result is a tidy :class:`pandas.DataFrame`, one row per trial;
:func:`summarize` averages it per cell, and :func:`safenav.results.write_table`
writes it (the wall-time columns to a separate file, so that the table itself
is byte-identical for a fixed seed).
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor, as_completed
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from . import console
from . import navigation as nav
from .scenario import Scenario

__all__ = ["Sweep", "trial_seeds", "plan_safe_paths", "run_sweep", "map_ordered", "summarize", "METRICS"]

#: Per-trial metric columns averaged by :func:`summarize`.
METRICS = ("ade", "fde", "path_error_percent", "awrs", "awrs_true", "loc_ade", "loc_fde", "max_deviation")


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


def trial_seeds(seed: int, path_index: int, n: int) -> np.ndarray:
    """The n trial seeds of one path type (uint64); ``path_index`` is the path
    type's index in the *scenario* (see :meth:`Sweep.path_index`), so a run
    of a subset of the path types gives each the same trials as a full run."""
    return np.random.SeedSequence([int(seed), int(path_index)]).generate_state(n, dtype=np.uint64)


def plan_safe_paths(scenario: Scenario, path_types=None, *, progress: bool = False) -> dict[str, np.ndarray]:
    """RAw-RRT* safe path of each path type (deterministic: the scenario's planner seed)."""
    names = list(path_types or [p.name for p in scenario.path_types])
    out = {}
    with console.progress(len(names), "planning", unit="path", enabled=progress) as bar:
        for name in names:
            out[name] = np.asarray(nav.plan_safe_path(scenario, name).path)
            bar.update()
    return out


@dataclass(frozen=True)
class _Chunk:
    """A work unit: trials [start, stop) of one cell.  Picklable (for Dask)."""

    scenario: Scenario
    path_type: str
    path_index: int
    safe_path: np.ndarray
    method: str
    filter: str
    source: str
    seeds: np.ndarray
    start: int
    n_particles: int
    position_every: int
    extra: dict = field(default_factory=dict)


#: Position sources that run the vision pipeline instead of a noise profile.
CAMERA_SOURCES = ("lanbloc-camera",)


def _camera_trials(navigator, c: "_Chunk") -> dict:
    """Trials with LanBLoc through the camera loop (render, detect, SGBM,
    trilaterate) as the position callback: Python per fix, so slower."""
    from .lanbloc import CameraLoopSource

    keys = ("outcome", "steps", "replans", "position_fixes", "dropouts", "rejected", "chull_default",
            "chull_corrective", "chull_step_back", "time_s", "reason", *METRICS)
    d = {k: [] for k in keys}
    for s in c.seeds:
        source = CameraLoopSource(c.scenario.world, seed=int(s) % 2**32)
        r = navigator.run(int(s), position=source)
        for k in keys:
            if k in METRICS:
                d[k].append(r.metrics[k])
            elif k == "outcome":
                d[k].append(int(r.outcome))
            elif k == "time_s":
                d[k].append(r.wall_time)
            else:
                d[k].append(getattr(r, k))
    return d


def _run_chunk(c: _Chunk) -> pd.DataFrame:
    camera = c.source in CAMERA_SOURCES
    navigator = nav.make_navigator(c.scenario, c.safe_path, method=c.method, filter=c.filter,
                                   source="lanbloc" if camera else c.source, n_particles=c.n_particles,
                                   position_every=c.position_every, record=False, **c.extra)
    d = _camera_trials(navigator, c) if camera else navigator.run_many([int(s) for s in c.seeds])
    n = len(c.seeds)
    df = pd.DataFrame({
        "path_type": [c.path_type] * n, "method": [c.method] * n, "filter": [c.filter] * n,
        "source": [c.source] * n, "trial": np.arange(c.start, c.start + n), "seed": c.seeds.astype(np.uint64),
    })
    df["outcome"] = [nav.OUTCOMES[o] for o in d["outcome"]]
    df["success"] = np.asarray(d["outcome"]) == 0
    df["reason"] = d["reason"]
    for k in ("steps", "replans", "position_fixes", "dropouts", "rejected"):
        df[k] = np.asarray(d[k])
    for k in METRICS:
        df[k] = np.asarray(d[k])
    df["time_ms"] = np.asarray(d["time_s"]) * 1e3
    df["time_per_step_us"] = df["time_ms"] * 1e3 / np.maximum(df["steps"], 1)
    return df


def _chunks(sweep: Sweep, safe_paths: dict[str, np.ndarray], extra: dict) -> list[_Chunk]:
    out = []
    for name in sweep.path_types:
        pi = sweep.path_index(name)
        seeds = trial_seeds(sweep.seed, pi, sweep.trials)
        for method in sweep.methods:
            for filt in sweep.filters:
                for source in sweep.sources:
                    for a in range(0, sweep.trials, sweep.chunk):
                        out.append(_Chunk(sweep.scenario, name, pi, safe_paths[name], method, filt, source,
                                          seeds[a:a + sweep.chunk], a, sweep.n_particles, sweep.position_every,
                                          dict(extra)))
    return out


def run_sweep(sweep: Sweep, *, workers: int | None = None, scheduler=None, safe_paths=None,
              progress: bool = False, **navigator_options) -> pd.DataFrame:
    """Run every trial of ``sweep``; one row per trial, in (path type, method,
    filter, source, trial) order whatever ``workers`` or ``scheduler``.

    ``workers``: local threads (default: all cores).  ``scheduler``: a Dask
    scheduler address or a ``distributed.Client``; the same chunks then run on
    that cluster.  ``safe_paths``: precomputed {path type: path}; planned here
    otherwise.  ``navigator_options`` go to :func:`safenav.navigation.make_navigator`."""
    if safe_paths is None:
        safe_paths = plan_safe_paths(sweep.scenario, sweep.path_types)
    missing = [p for p in sweep.path_types if p not in safe_paths]
    if missing:
        raise ValueError(f"safe_paths: no path for {missing}")
    chunks = _chunks(sweep, safe_paths, navigator_options)
    return pd.concat(map_ordered(_run_chunk, chunks, workers=workers, scheduler=scheduler, progress=progress,
                                 desc="trials"), ignore_index=True)


def map_ordered(fn, items, *, workers: int | None = None, scheduler=None, progress: bool = False,
                desc: str = "chunks") -> list:
    """``[fn(item) for item in items]``, run on local threads or a Dask cluster,
    returned in the order of ``items`` whatever order the work finishes in.

    ``fn`` and the items must be picklable for Dask (module-level functions and
    dataclasses).  ``workers``: local threads (default: all cores); useful when
    ``fn`` spends its time in C++ calls that release the GIL.  ``scheduler``: a
    Dask scheduler address or a ``distributed.Client``."""
    items = list(items)
    if scheduler is None:
        n = workers if workers is not None else (os.cpu_count() or 1)
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ValueError(f"workers = {workers!r}: must be an integer >= 1")
    with console.progress(len(items), desc, unit="chunk", enabled=progress) as bar:
        if scheduler is not None:
            return _run_dask(fn, items, scheduler, bar)
        out = [None] * len(items)
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


def summarize(raw: pd.DataFrame) -> pd.DataFrame:
    """Per cell (path type, method, filter, source): trial count, success rate,
    the metrics' means over the *arrived* trials, and the median time per
    trial [ms] and per step [µs] over all trials."""
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
        rows.append(row)
    return pd.DataFrame(rows)
