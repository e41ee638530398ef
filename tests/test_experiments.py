"""The synthetic data set (SafeNav V-A) and the main job end to end."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import safenav
from safenav import cli, results
from safenav.datasets import COLUMNS, SyntheticConfig, command_profile, synthetic_trajectory
from safenav.experiments import PAPER_SYNTHETIC, run_synthetic, summarize_synthetic, synthetic_trial


def test_command_profile_follows_the_papers_formulas():
    cfg = SyntheticConfig(n_steps=400)
    t, speed, heading = command_profile(cfg)
    T = cfg.n_steps * cfg.dt
    assert t[-1] == pytest.approx(T)
    # θ(t) = π/2 sin(2πt/T)
    np.testing.assert_allclose(heading, np.pi / 2 * np.sin(2 * np.pi * t / T), atol=1e-15)
    # speed integrates a(t) = 3 sin(4πt/T): its increments are a(t_k)·dt
    np.testing.assert_allclose(np.diff(speed), 3 * np.sin(4 * np.pi * t[:-1] / T) * cfg.dt, atol=1e-12)


def test_synthetic_trajectory_has_the_seven_variables_and_is_seeded():
    cfg = SyntheticConfig(n_steps=120)
    a = synthetic_trajectory(cfg, seed=3)
    b = synthetic_trajectory(cfg, seed=3)
    c = synthetic_trajectory(cfg, seed=4)
    truth = a.truth
    assert tuple(truth.columns[1:]) == COLUMNS
    assert len(truth) == cfg.n_steps + 1
    np.testing.assert_array_equal(a.states, b.states)
    np.testing.assert_array_equal(a.position, b.position)
    assert not np.array_equal(a.states, c.states)
    # speeds along the axes are consistent with speed and heading
    np.testing.assert_allclose(np.hypot(truth.sx, truth.sy), a.states[:, 2], atol=1e-12)
    # ax is the derivative of sx
    np.testing.assert_allclose(truth.ax, np.gradient(truth.sx, cfg.dt))
    # fixes scatter around the truth with the LanBLoc RMSE (0.0142 m in X, 0.039 m in Y)
    big = synthetic_trajectory(SyntheticConfig(n_steps=4000), seed=1)
    err = big.position - big.states[1:, :2]
    np.testing.assert_allclose(err.std(axis=0), [0.0142, 0.039], rtol=0.05)


def test_synthetic_dropout_makes_gaps_that_the_filter_bridges():
    cfg = SyntheticConfig(n_steps=200, position=safenav.PositionNoise(dropout_probability=0.5))
    data = synthetic_trajectory(cfg, seed=0)
    gaps = np.isnan(data.position[:, 0])
    assert 60 < gaps.sum() < 140
    res = safenav.filter_trajectory(data.controls, data.x0, np.eye(4) * 0.01, params=cfg.params(),
                                    position=data.position)
    assert res.n_gaps == gaps.sum()
    # covariance grows across a gap and shrinks at the next fix
    k = int(np.argmax(gaps[1:] & ~gaps[:-1])) + 1  # first step of a gap
    assert res.covariances[k + 1, 0, 0] > res.covariances[k, 0, 0]
    assert safenav.metrics.ade(res.states[:, :2], data.states[:, :2]) < 0.1


def test_synthetic_config_rejects_bad_values():
    with pytest.raises(ValueError, match=r"n_steps must be a positive integer, got 0"):
        SyntheticConfig(n_steps=0)
    with pytest.raises(ValueError, match=r"SyntheticConfig.dt = -0.05"):
        SyntheticConfig(dt=-0.05)
    noise = safenav.PositionNoise()
    noise.dropout_probability = 1.5
    with pytest.raises(ValueError, match=r"position.dropout_probability = 1.5: must be in \[0, 1\]"):
        SyntheticConfig(position=noise)
    with pytest.raises(TypeError, match=r"SyntheticConfig.position must be a PositionNoise, got tuple"):
        SyntheticConfig(position=(0.1, 0.1))


def test_run_synthetic_summary_is_recomputed_from_the_raw_table():
    raw = run_synthetic(4, seed=7, n_particles=300)
    assert set(raw["filter"]) == {"ekf", "pf"} and len(raw) == 8
    summary = summarize_synthetic(raw).set_index("filter")
    for f in ("ekf", "pf"):
        rows = raw[raw["filter"] == f]
        assert summary.loc[f, "truth_ade"] == pytest.approx(rows["truth_ade"].mean())
        assert summary.loc[f, "awrs"] == pytest.approx(rows["awrs"].mean())
        assert summary.loc[f, "path_err_pct"] == pytest.approx(rows["path_length_error_percent"].mean())
        assert summary.loc[f, "paper_truth_ade"] == PAPER_SYNTHETIC[f]["truth_ade"]
    # each row's metrics are those of the trial it names
    data, results = synthetic_trial(2, seed=7, n_particles=300)
    row = raw[(raw.trial == 2) & (raw["filter"] == "ekf")].iloc[0]
    assert row.truth_ade == pytest.approx(safenav.metrics.ade(results["ekf"].states[:, :2], data.states[:, :2]))


def test_run_synthetic_is_reproducible_and_independent_of_trial_count():
    a = run_synthetic(3, seed=11, n_particles=200).drop(columns=["ms_per_trial", "us_per_step"])
    b = run_synthetic(5, seed=11, n_particles=200).drop(columns=["ms_per_trial", "us_per_step"])
    pd.testing.assert_frame_equal(a, b.iloc[: len(a)].reset_index(drop=True))


def test_synthetic_command_prints_the_table_and_writes_files(tmp_path, capsys):
    assert cli.main(["synthetic", "--trials", "3", "--particles", "200", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "paper_truth_ade" in out and "ekf" in out and "pf" in out
    for name in ("synthetic_trials.csv", "synthetic_trials_timings.csv", "synthetic_summary.csv",
                 "synthetic_trial.png", "synthetic_trial.svg", "manifest.json"):
        assert (tmp_path / name).stat().st_size > 0
    raw = results.read_table(tmp_path / "synthetic_trials.csv")
    assert len(raw) == 6 and not list(tmp_path.glob(".safenav-tmp-*"))
    assert raw["ms_per_trial"].gt(0).all() and "ms_per_trial" not in pd.read_csv(tmp_path / "synthetic_trials.csv")
    assert len(results.verify_run(tmp_path)["files"]) == 6


def test_cli_reports_bad_arguments_cleanly(capsys):
    assert cli.main(["synthetic", "--trials", "0"]) == 2
    assert capsys.readouterr().err == "safenav: error: argument --trials: must be an integer >= 1, got 0\n"


def test_synthetic_trials_follow_the_one_seed_rule():
    # safenav.runner's rule: trial i of stream 0 has SeedSequence([seed, 0]).generate_state(N)[i];
    # its data, prior and filter draw from derive_seed(trial seed, 0 | 1 | 2).
    from safenav import _core, runner
    from safenav.experiments.synthetic import PRIOR_STD

    trial_seed = np.random.SeedSequence([7, 0]).generate_state(3, dtype=np.uint64)[2]
    assert runner.trial_seeds(7, 0, 3)[2] == trial_seed
    cfg = SyntheticConfig(n_steps=40)
    data, res = synthetic_trial(2, filters=("ekf",), seed=7, config=cfg)
    want = synthetic_trajectory(cfg, _core.derive_seed(int(trial_seed), 0))
    np.testing.assert_array_equal(data.states, want.states)
    np.testing.assert_array_equal(data.position, want.position)
    x0 = want.x0 + np.random.default_rng(_core.derive_seed(int(trial_seed), 1)).standard_normal(4) * PRIOR_STD
    np.testing.assert_array_equal(res["ekf"].states[0], x0)
    # the same trial inside a Monte Carlo run, whatever the chunking
    raw = run_synthetic(3, filters=("ekf",), seed=7, config=cfg)
    assert raw.loc[raw.trial == 2, "truth_ade"].item() == safenav.evaluate(res["ekf"].states[:, :2],
                                                                           data.states[:, :2]).ade
