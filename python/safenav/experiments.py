"""The SafeNav paper's experiments: the synthetic data set (Table I of the
conference version, Table II of the extended one) and the paper's numbers for
every table, beside which ours are printed.

Table numbers follow the *conference* version throughout (I synthetic, II
real-imitated, III % path-length error, IV ADE/FDE/AWRS/time); the extended
version numbers them one higher.  :mod:`safenav.reproduce` runs them all."""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from .validation import as_positive_int, as_seed
from .datasets import SyntheticConfig, synthetic_trajectory
from .filters import filter_trajectory
from .metrics import RiskZones, evaluate, wrs

#: The localization methods of Tables I and II, in the paper's row order
#: (keys of :data:`safenav.navigation.SOURCES`).
PAPER_SOURCES = ("deeploc-gps", "deeploc-ekf-gps", "sensor-fusion", "lanbloc")

#: The paper's Table I (synthetic trajectories): (source, filter) ->
#: ADE, FDE [m], AWRS, time per trial [ms].
PAPER_TABLE1 = {
    ("deeploc-gps", "ekf"): (0.6069, 0.5495, 0.3926, 5.02), ("deeploc-gps", "pf"): (1.1335, 1.7614, 2.1414, 9815.0),
    ("deeploc-ekf-gps", "ekf"): (0.5621, 0.4818, 0.3590, 4.57),
    ("deeploc-ekf-gps", "pf"): (1.4864, 1.5709, 1.7823, 10054.0),
    ("sensor-fusion", "ekf"): (1.3546, 0.5714, 0.3513, 4.90), ("sensor-fusion", "pf"): (1.9155, 3.1229, 2.9387, 10103.0),
    ("lanbloc", "ekf"): (0.4972, 0.4675, 0.3492, 3.98), ("lanbloc", "pf"): (0.9471, 0.8177, 1.2612, 9551.0),
}
#: The paper's Table II (real-imitated trajectories, the mean over P1-P3):
#: (source, filter) -> ADE, FDE [m], AWRS, time per trial [ms].
PAPER_TABLE2 = {
    ("deeploc-gps", "ekf"): (0.3041, 0.3103, 0.2009, 20.58), ("deeploc-gps", "pf"): (1.6928, 2.8891, 4.3586, 192621.0),
    ("deeploc-ekf-gps", "ekf"): (0.2869, 0.2969, 0.1906, 18.94),
    ("deeploc-ekf-gps", "pf"): (2.0672, 7.1665, 3.6346, 197250.0),
    ("sensor-fusion", "ekf"): (0.2998, 0.3115, 0.1749, 22.31), ("sensor-fusion", "pf"): (1.6831, 4.2886, 5.4116, 198790.0),
    ("lanbloc", "ekf"): (0.2393, 0.3095, 0.1528, 14.94), ("lanbloc", "pf"): (1.5162, 1.4024, 3.1623, 185502.0),
}
#: The LanBLoc-BMM rows of Table I by filter (kept for the filter benchmark).
PAPER_SYNTHETIC = {f: dict(zip(("ade", "fde", "awrs", "ms_per_trial"), PAPER_TABLE1[("lanbloc", f)]))
                   for f in ("ekf", "pf")}

#: Initial estimate uncertainty (x, y, v, θ) — ours.
PRIOR_STD = np.array([0.1, 0.1, 0.1, 0.05])


def source_config(source: str, base: SyntheticConfig | None = None) -> SyntheticConfig:
    """The synthetic data set with the position fixes of ``source`` (a key of
    :data:`safenav.navigation.SOURCES`): its white noise, bias, bias walk and
    outliers.  The synthetic set has no landmarks, so every source fixes at
    every step."""
    from .navigation import position_source

    p = position_source(source)
    return replace(base or SyntheticConfig(), position_std=tuple(p.std), position_bias_std=p.bias_std,
                   position_bias_walk_std=p.bias_walk_std, outlier_probability=p.outlier_probability,
                   outlier_std=p.outlier_std)


def _trial_seeds(seed: int, trials: int):
    """(data, prior, filter) seeds of each trial, derived with SeedSequence so that a
    trial's numbers do not depend on how many trials run or in what order."""
    for ss in np.random.SeedSequence(seed).spawn(trials):
        yield tuple(int(s.generate_state(1, np.uint64)[0]) for s in ss.spawn(3))


def _run_trial(cfg: SyntheticConfig, seeds, filters, n_particles: int):
    data_seed, prior_seed, filter_seed = seeds
    data = synthetic_trajectory(cfg, data_seed)
    x0 = data.x0 + np.random.default_rng(prior_seed).standard_normal(4) * PRIOR_STD
    P0 = np.diag(PRIOR_STD**2)
    imu_cov = np.diag([cfg.speed_std**2, cfg.heading_std**2]) if cfg.imu else None
    results, times = {}, {}
    for name in filters:
        t0 = time.perf_counter()
        results[name] = filter_trajectory(
            data.controls, x0, P0, params=cfg.params(), filter=name, position=data.position,
            position_cov=cfg.position_cov(), speed_heading=data.speed_heading,
            speed_heading_cov=imu_cov, n_particles=n_particles, seed=filter_seed)
        times[name] = time.perf_counter() - t0
    return data, results, times


def synthetic_trial(trial: int, *, filters=("ekf", "pf"), seed: int = 0, n_particles: int = 1000,
                    config: SyntheticConfig | None = None, source: str | None = None):
    """Trial number ``trial`` of :func:`run_synthetic`: returns (data, {filter: FilterResult})."""
    seeds = list(_trial_seeds(as_seed("seed", seed), trial + 1))[trial]
    cfg = source_config(source, config) if source else (config or SyntheticConfig())
    data, results, _ = _run_trial(cfg, seeds, filters, n_particles)
    return data, results


@dataclass(frozen=True)
class _SyntheticChunk:
    """Trials [start, start + len(seeds)) of one source: a picklable work unit."""

    config: SyntheticConfig
    source: str
    filters: tuple[str, ...]
    seeds: tuple
    start: int
    n_particles: int
    zones: RiskZones


def _synthetic_chunk(c: _SyntheticChunk):
    """Rows of the raw table, and the per-step WRS of each trial per filter."""
    rows, wrs_trials = [], {}
    n_steps = c.config.n_steps
    for k, seeds in enumerate(c.seeds):
        data, results, times = _run_trial(c.config, seeds, c.filters, c.n_particles)
        for name, res in results.items():
            est = res.states[:, :2]
            m = evaluate(est, data.states[:, :2], zones=c.zones)
            w = wrs(est, data.states[:, :2], c.zones)
            wrs_trials.setdefault(name, []).append(w)
            rows.append({"source": c.source, "trial": c.start + k, "filter": name, **m.as_dict(), "steps": n_steps,
                         "ms_per_trial": times[name] * 1e3, "us_per_step": times[name] * 1e6 / n_steps,
                         "n_gaps": res.n_gaps, "n_resampled": res.n_resampled})
    return rows, wrs_trials


@dataclass(frozen=True)
class SyntheticResult:
    """:func:`synthetic_experiment` output: the raw table (one row per
    source, trial and filter) and the mean WRS of each step over the trials
    per (source, filter), for the paper's Fig. 3."""

    raw: pd.DataFrame
    wrs_mean: dict


def synthetic_experiment(trials: int = 100, *, sources=("lanbloc",), filters=("ekf", "pf"), seed: int = 0,
                         n_particles: int = 1000, config: SyntheticConfig | None = None,
                         zones: RiskZones | None = None, workers: int | None = 1, scheduler=None,
                         chunk: int = 25, progress: bool = False) -> SyntheticResult:
    """Monte Carlo over ``trials`` synthetic trajectories per position source
    (the paper's Table I grid: sources × filters).

    Trial i has the same truth, commands and white noise for every source
    (common random numbers); the sources differ in their error profile.  The
    results do not depend on ``workers``, ``chunk`` or ``scheduler`` (see
    :func:`safenav.runner.map_ordered`).  Time per trial is the wall time of
    the filter call (data generation is not timed)."""
    from .navigation import position_source
    from .runner import map_ordered

    trials = as_positive_int("trials", trials)
    chunk = as_positive_int("chunk", chunk)
    for s in sources:
        position_source(s)
    if not sources:
        raise ValueError("sources: needs at least one")
    zones = zones or RiskZones()
    seeds = list(_trial_seeds(as_seed("seed", seed), trials))
    jobs = [_SyntheticChunk(source_config(src, config), src, tuple(filters), tuple(seeds[a:a + chunk]), a,
                            n_particles, zones)
            for src in sources for a in range(0, trials, chunk)]
    parts = map_ordered(_synthetic_chunk, jobs, workers=workers, scheduler=scheduler, progress=progress,
                        desc="synthetic")
    rows, wrs_trials = [], {}
    for job, (r, w) in zip(jobs, parts):
        rows += r
        for f, v in w.items():
            wrs_trials.setdefault((job.source, f), []).extend(v)
    # a mean over the (trials, steps) stack in trial order: the same bits whatever the chunking
    wrs_mean = {k: np.mean(np.stack(v), axis=0) for k, v in wrs_trials.items()}
    return SyntheticResult(pd.DataFrame(rows), wrs_mean)


def run_synthetic(trials: int = 100, *, filters=("ekf", "pf"), seed: int = 0, n_particles: int = 1000,
                  config: SyntheticConfig | None = None, zones: RiskZones | None = None,
                  sources=("lanbloc",), workers: int | None = 1) -> pd.DataFrame:
    """The raw table of :func:`synthetic_experiment`: one row per (source, trial, filter)."""
    return synthetic_experiment(trials, sources=sources, filters=filters, seed=seed, n_particles=n_particles,
                                config=config, zones=zones, workers=workers).raw


def summarize_synthetic(raw: pd.DataFrame) -> pd.DataFrame:
    """Mean per (source, filter), with the paper's Table I numbers beside ours."""
    if raw.empty:
        raise ValueError("summarize_synthetic: the raw table has no rows")
    agg = raw.groupby(["source", "filter"], sort=False).agg(
        trials=("trial", "count"), ade=("ade", "mean"), fde=("fde", "mean"), awrs=("awrs", "mean"),
        path_err_pct=("path_length_error_percent", "mean"), ms_per_trial=("ms_per_trial", "median"),
        us_per_step=("us_per_step", "median")).reset_index()
    for i, col in enumerate(("ade", "fde", "awrs", "ms_per_trial")):
        agg[f"paper_{col}"] = [PAPER_TABLE1.get((s, f), (np.nan,) * 4)[i] for s, f in zip(agg["source"], agg["filter"])]
    return agg


def markdown_table(df: pd.DataFrame, digits: int = 3) -> str:
    """A DataFrame as a GitHub Markdown table (floats to ``digits`` significant digits)."""
    def cell(v):
        if isinstance(v, (float, np.floating)):
            return "—" if np.isnan(v) else f"{v:.{digits}g}"
        return str(v)
    lines = ["| " + " | ".join(map(str, df.columns)) + " |", "|" + "---|" * len(df.columns)]
    lines += ["| " + " | ".join(cell(v) for v in row) + " |" for row in df.itertuples(index=False)]
    return "\n".join(lines) + "\n"


def source_label(source: str) -> str:
    """The table label of a position source ("LanBLoc-BMM", "DeepLoc-GPS (emulated)", ...)."""
    from .navigation import SOURCES

    if source == "lanbloc":
        return "LanBLoc-BMM"
    if source == "lanbloc-camera":
        return "LanBLoc-BMM (camera loop)"
    return SOURCES[source].label if source in SOURCES else source


def localization_table(summary: pd.DataFrame, paper: dict) -> pd.DataFrame:
    """Table I/II layout: one row per (algorithm, filter) in the paper's order,
    ADE, FDE, AWRS and the median time per trial, with the paper's numbers
    beside.  ``summary`` has columns source, filter, ade, fde, awrs and
    ms_per_trial (one row per source and filter)."""
    order = {s: i for i, s in enumerate((*PAPER_SOURCES, "lanbloc-camera"))}
    s = summary.assign(_o=summary["source"].map(lambda v: order.get(v, len(order))),
                       _f=summary["filter"].map({"ekf": 0, "pf": 1})).sort_values(["_o", "_f"], kind="stable")
    rows = []
    for _, r in s.iterrows():
        p = paper.get((r["source"], r["filter"]), (np.nan,) * 4)
        row = {"Algorithm": source_label(r["source"]), "Filter": r["filter"].upper(),
               "ADE": r["ade"], "FDE": r["fde"], "AWRS": r["awrs"], "time ms": r["ms_per_trial"],
               "paper ADE": p[0], "paper FDE": p[1], "paper AWRS": p[2], "paper ms": p[3]}
        if "success_rate" in r:
            row["arrived"] = r["success_rate"]   # metrics are over the arrived trials
        rows.append(row)
    return pd.DataFrame(rows)


# --------------------------------------------------------------------------- navigation (SafeNav V-D)

#: The paper's Table III (% path-length error per path type; Table IV of the
#: extended version).
PAPER_PERCENT_ERROR = {
    "chull": {"P1": 5.755, "P2": 7.42, "P3": 6.35, "Average": 6.51},
    "centroid": {"P1": 5.32, "P2": 5.60, "P3": 5.47, "Average": 5.46},
}
#: The paper's Table IV (Table V of the extended version): ADE, FDE [m], AWRS
#: and time per trial [ms].
PAPER_NAVIGATION = {
    "chull": {"P1": (2.73, 3.16, 1.31, 14.93), "P2": (2.72, 3.08, 1.11, 14.84), "P3": (3.46, 3.57, 1.71, 15.98),
              "Average": (2.97, 3.27, 1.38, 15.25)},
    "centroid": {"P1": (1.06, 0.87, 1.01, 16.74), "P2": (1.13, 1.03, 1.01, 16.94), "P3": (1.15, 1.06, 1.01, 16.97),
                 "Average": (1.11, 0.99, 1.01, 16.88)},
}
METHOD_LABELS = {"chull": "SafeNav-CHull", "centroid": "SafeNav-Centroid"}


def _with_average(summary: pd.DataFrame) -> pd.DataFrame:
    cols = ["ade", "fde", "awrs", "path_error_percent", "time_ms", "time_per_step_us", "success_rate", "steps"]
    avg = summary.groupby("method", sort=False)[cols].mean().reset_index()
    avg["path_type"] = "Average"
    return pd.concat([summary[["method", "path_type", *cols]], avg[["method", "path_type", *cols]]],
                     ignore_index=True)


def percent_error_table(summary: pd.DataFrame) -> pd.DataFrame:
    """Table III layout (the extended version's IV) of the % path-length error (eq. 23): one row per
    method, one column per path type plus the average; the paper's value beside
    each of ours (``paper P1`` …).  ``summary`` is :func:`safenav.runner.summarize`
    output for one filter and source."""
    s = _with_average(summary)
    rows = []
    for method, g in s.groupby("method", sort=False):
        row = {"Approach": METHOD_LABELS.get(method, method)}
        for _, r in g.iterrows():
            row[r["path_type"]] = r["path_error_percent"]
            row[f"paper {r['path_type']}"] = PAPER_PERCENT_ERROR.get(method, {}).get(r["path_type"], np.nan)
        rows.append(row)
    return pd.DataFrame(rows)


def navigation_table(summary: pd.DataFrame) -> pd.DataFrame:
    """Table IV layout (the extended version's V): per method and path type (plus the average), ADE,
    FDE, AWRS and the median time per trial, with the paper's numbers beside,
    then our success rate, steps and time per step."""
    s = _with_average(summary)
    rows = []
    for _, r in s.iterrows():
        paper = PAPER_NAVIGATION.get(r["method"], {}).get(r["path_type"], (np.nan,) * 4)
        rows.append({
            "Approach": METHOD_LABELS.get(r["method"], r["method"]), "Path": r["path_type"],
            "ADE": r["ade"], "FDE": r["fde"], "AWRS": r["awrs"], "time ms": r["time_ms"],
            "paper ADE": paper[0], "paper FDE": paper[1], "paper AWRS": paper[2], "paper ms": paper[3],
            "success": r["success_rate"], "steps": r["steps"], "µs/step": r["time_per_step_us"],
        })
    return pd.DataFrame(rows)
