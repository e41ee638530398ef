"""Experiments.  For now: the synthetic data set filtered by EKF and PF
(the LanBLoc-BMM rows of the SafeNav paper's synthetic-data table)."""

from __future__ import annotations

import time

import numpy as np
import pandas as pd

from ._checks import as_positive_int, as_seed
from .datasets import SyntheticConfig, synthetic_trajectory
from .filters import filter_trajectory
from .metrics import RiskZones, evaluate

#: The paper's LanBLoc-BMM rows of its synthetic-data table (Table II of the
#: extended version): ADE, FDE [m], AWRS, time per trial [ms].
PAPER_SYNTHETIC = {
    "ekf": {"ade": 0.4972, "fde": 0.4675, "awrs": 0.3492, "ms_per_trial": 3.98},
    "pf": {"ade": 0.9471, "fde": 0.8177, "awrs": 1.2612, "ms_per_trial": 9551.0},
}

#: Initial estimate uncertainty (x, y, v, θ) — ours.
PRIOR_STD = np.array([0.1, 0.1, 0.1, 0.05])


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
            position_cov=np.diag(np.square(cfg.position_std)), speed_heading=data.speed_heading,
            speed_heading_cov=imu_cov, n_particles=n_particles, seed=filter_seed)
        times[name] = time.perf_counter() - t0
    return data, results, times


def synthetic_trial(trial: int, *, filters=("ekf", "pf"), seed: int = 0, n_particles: int = 1000,
                    config: SyntheticConfig | None = None):
    """Trial number ``trial`` of :func:`run_synthetic`: returns (data, {filter: FilterResult})."""
    seeds = list(_trial_seeds(as_seed("seed", seed), trial + 1))[trial]
    data, results, _ = _run_trial(config or SyntheticConfig(), seeds, filters, n_particles)
    return data, results


def run_synthetic(trials: int = 100, *, filters=("ekf", "pf"), seed: int = 0, n_particles: int = 1000,
                  config: SyntheticConfig | None = None, zones: RiskZones | None = None) -> pd.DataFrame:
    """Monte Carlo over ``trials`` synthetic trajectories; one row per (trial, filter).

    Time per trial is the wall time of the filter call (the data generation is
    not timed)."""
    trials = as_positive_int("trials", trials)
    cfg = config or SyntheticConfig()
    zones = zones or RiskZones()
    rows = []
    for trial, seeds in enumerate(_trial_seeds(as_seed("seed", seed), trials)):
        data, results, times = _run_trial(cfg, seeds, filters, n_particles)
        for name, res in results.items():
            m = evaluate(res.states[:, :2], data.states[:, :2], zones=zones)
            rows.append({"trial": trial, "filter": name, **m.as_dict(), "steps": cfg.n_steps,
                         "ms_per_trial": times[name] * 1e3, "us_per_step": times[name] * 1e6 / cfg.n_steps,
                         "n_gaps": res.n_gaps, "n_resampled": res.n_resampled})
    return pd.DataFrame(rows)


def summarize_synthetic(raw: pd.DataFrame) -> pd.DataFrame:
    """Mean per filter, with the paper's numbers beside ours."""
    agg = raw.groupby("filter", sort=False).agg(
        trials=("trial", "count"), ade=("ade", "mean"), fde=("fde", "mean"), awrs=("awrs", "mean"),
        path_err_pct=("path_length_error_percent", "mean"), ms_per_trial=("ms_per_trial", "median"),
        us_per_step=("us_per_step", "median"))
    for col in ("ade", "fde", "awrs", "ms_per_trial"):
        agg[f"paper_{col}"] = [PAPER_SYNTHETIC.get(f, {}).get(col, np.nan) for f in agg.index]
    return agg.reset_index()


# --------------------------------------------------------------------------- navigation (SafeNav V-D)

#: The paper's Table IV (% path-length error per path type) of the extended
#: version (Table III of the conference version).
PAPER_PERCENT_ERROR = {
    "chull": {"P1": 5.755, "P2": 7.42, "P3": 6.35, "Average": 6.51},
    "centroid": {"P1": 5.32, "P2": 5.60, "P3": 5.47, "Average": 5.46},
}
#: The paper's Table V (extended; Table IV of the conference version):
#: ADE, FDE [m], AWRS and time per trial [ms].
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
    """Table III/IV layout of the % path-length error (eq. 23): one row per
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
    """Table IV/V layout: per method and path type (plus the average), ADE,
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
