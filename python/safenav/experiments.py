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
