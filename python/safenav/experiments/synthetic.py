"""The SafeNav paper's synthetic data set experiment, [SafeNav-conf Table I]
(= [SafeNav-ext Table II]): every position source ×
EKF/PF on synthetic trajectories, run by :func:`safenav.runner.run_trials`
under its seed rule (stream 0; in a trial, sub-seed 0 draws the data, 1
the prior, 2 the filter)."""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from .. import runner
from ..validation import as_positive_int, as_seed
from ..datasets import SyntheticConfig, synthetic_trajectory
from ..filters import filter_trajectory
from ..metrics import RiskZones, evaluate, wrs
from .paper import PAPER_TABLE1

#: Initial estimate uncertainty (x, y, v, θ) — ours.
PRIOR_STD = np.array([0.1, 0.1, 0.1, 0.05])


def source_config(source: str, base: SyntheticConfig | None = None) -> SyntheticConfig:
    """The synthetic data set with the position fixes of ``source`` (a key of
    :data:`safenav.navigation.SOURCES`).  The synthetic set has no landmarks,
    so every source fixes at every step."""
    from ..navigation import position_source

    return replace(base or SyntheticConfig(), position=position_source(source))


#: The synthetic set's stream in the seed rule (:mod:`safenav.runner`).
SYNTHETIC_STREAM = 0


def _sub_seeds(trial_seed) -> tuple[int, int, int]:
    """(data, prior, filter) seeds of the trial of seed ``trial_seed``."""
    return tuple(runner.sub_seed(trial_seed, k) for k in range(3))


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
    trial_seed = runner.trial_seeds(as_seed("seed", seed), SYNTHETIC_STREAM, trial + 1)[trial]
    cfg = source_config(source, config) if source else (config or SyntheticConfig())
    data, results, _ = _run_trial(cfg, _sub_seeds(trial_seed), filters, n_particles)
    return data, results


@dataclass(frozen=True)
class _SyntheticCell:
    """The trials of one source: a picklable cell of :func:`safenav.runner.run_trials`."""

    config: SyntheticConfig
    source: str
    filters: tuple[str, ...]
    n_particles: int
    zones: RiskZones


def _truth_named(metrics: dict) -> dict:
    """:meth:`TrajectoryMetrics.as_dict` with ADE and FDE named by their
    reference, the true trajectory (``truth_ade``, ``truth_fde``), as in the
    navigation tables."""
    return {(f"truth_{k}" if k in ("ade", "fde") else k): v for k, v in metrics.items()}


def _synthetic_trials(c: _SyntheticCell, seeds, start: int):
    """Rows of the raw table for trials [start, start + len(seeds)), and the
    per-step WRS of each trial per filter."""
    rows, wrs_trials = [], {}
    n_steps = c.config.n_steps
    for k, trial_seed in enumerate(seeds):
        data, results, times = _run_trial(c.config, _sub_seeds(trial_seed), c.filters, c.n_particles)
        for name, res in results.items():
            est = res.states[:, :2]
            m = evaluate(est, data.states[:, :2], zones=c.zones)
            w = wrs(est, data.states[:, :2], c.zones)
            wrs_trials.setdefault(name, []).append(w)
            rows.append({"source": c.source, "trial": start + k, "filter": name, **_truth_named(m.as_dict()),
                         "steps": n_steps, "ms_per_trial": times[name] * 1e3,
                         "us_per_step": times[name] * 1e6 / n_steps, "n_gaps": res.n_gaps,
                         "n_resampled": res.n_resampled})
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
    ([SafeNav-conf Table I]'s grid: sources × filters).

    Trial i has the same truth, commands and white noise for every source
    (common random numbers); the sources differ in their error profile.  The
    results do not depend on ``workers``, ``chunk`` or ``scheduler`` (see
    :func:`safenav.runner.run_trials`).  Time per trial is the wall time of
    the filter call (data generation is not timed)."""
    from ..navigation import position_source

    trials = as_positive_int("trials", trials)
    chunk = as_positive_int("chunk", chunk)
    for s in sources:
        position_source(s)
    if not sources:
        raise ValueError("sources: needs at least one")
    zones = zones or RiskZones()
    cells = [(SYNTHETIC_STREAM, _SyntheticCell(source_config(src, config), src, tuple(filters), n_particles, zones))
             for src in sources]
    parts = runner.run_trials(_synthetic_trials, cells, seed=as_seed("seed", seed), trials=trials, chunk=chunk,
                              workers=workers, scheduler=scheduler, progress=progress, desc="synthetic")
    rows, wrs_trials = [], {}
    for cell, (r, w) in parts:
        rows += r
        for f, v in w.items():
            wrs_trials.setdefault((cell.source, f), []).extend(v)
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
    """Mean per (source, filter), with [SafeNav-conf Table I]'s numbers beside ours."""
    if raw.empty:
        raise ValueError("summarize_synthetic: the raw table has no rows")
    agg = raw.groupby(["source", "filter"], sort=False).agg(
        trials=("trial", "count"), truth_ade=("truth_ade", "mean"), truth_fde=("truth_fde", "mean"),
        awrs=("awrs", "mean"),
        path_err_pct=("path_length_error_percent", "mean"), ms_per_trial=("ms_per_trial", "median"),
        us_per_step=("us_per_step", "median")).reset_index()
    for i, col in enumerate(("truth_ade", "truth_fde", "awrs", "ms_per_trial")):
        agg[f"paper_{col}"] = [PAPER_TABLE1.get((s, f), (np.nan,) * 4)[i] for s, f in zip(agg["source"], agg["filter"])]
    return agg
