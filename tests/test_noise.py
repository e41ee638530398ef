"""The core's position-source error model (``PositionNoise``, measurement.hpp):
the named profiles, validation, the sampler against the stated model, the
covariance filters are told, and its use by both the synthetic data set and
the navigation loop.

Statistical checks compare a sample statistic with the model's value within
``Z`` standard errors, the standard error taken from the sample size (or, for
heavy-tailed mixtures, from the sample itself); the seeds are fixed, so the
tests are deterministic."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import safenav
from safenav import _core
from safenav import navigation as nv
from safenav.datasets import SyntheticConfig, synthetic_trajectory
from safenav.experiments import source_config
from safenav.measurement import LANBLOC_STD, PositionNoise

Z = 4.0  # standard errors allowed


def errors(noise: PositionNoise, trials: int, fixes: int, seed: int = 0) -> np.ndarray:
    """(trials, fixes, 2) fix errors z − p of independent trials (NaN rows: lost fixes)."""
    return np.stack([noise.sample(np.zeros((fixes, 2)), _core.derive_seed(seed, t)) for t in range(trials)])


# --------------------------------------------------------------------------- named profiles

def test_named_profiles_are_declared_once_in_the_core():
    assert PositionNoise.names() == ["lanbloc", "deeploc-gps", "deeploc-ekf-gps", "sensor-fusion"]
    assert list(nv.SOURCES) == PositionNoise.names()
    lanbloc = PositionNoise.named("lanbloc")
    # the paper's LanBLoc RMSE (SafeNav section III) is the default, and Python reads it from the core
    assert tuple(lanbloc.std) == (0.0142, 0.039) == LANBLOC_STD
    assert tuple(PositionNoise().std) == LANBLOC_STD and lanbloc.needs_landmarks and not lanbloc.emulated
    for name in PositionNoise.names()[1:]:
        p = PositionNoise.named(name)
        assert p.emulated and p.label.endswith("(emulated)") and p.note.startswith("emulated")
        assert not p.needs_landmarks
        p.validate()
    # position_source hands out a copy: changing it leaves the table alone
    s = nv.position_source("deeploc-gps")
    s.bias_std = 5.0
    assert nv.SOURCES["deeploc-gps"].bias_std == PositionNoise.named("deeploc-gps").bias_std == 0.10
    with pytest.raises(ValueError, match="position source 'gps' is unknown \\(have: lanbloc, deeploc-gps"):
        PositionNoise.named("gps")
    with pytest.raises(ValueError, match="source = 'gps': unknown position source"):
        nv.position_source("gps")


def test_profiles_pickle_and_keep_every_field():
    p = PositionNoise(name="x", label="X", std=(0.1, 0.2), bias_std=0.3, bias_walk_std=0.01,
                      outlier_probability=0.05, outlier_std=1.5, dropout_probability=0.2, needs_landmarks=False,
                      emulated=True, note="n")
    q = pickle.loads(pickle.dumps(p))
    assert repr(q) == repr(p)
    assert (q.name, q.label, q.note, q.needs_landmarks, q.emulated) == ("x", "X", "n", False, True)
    np.testing.assert_array_equal(q.sample(np.zeros((50, 2)), 7), p.sample(np.zeros((50, 2)), 7))


# --------------------------------------------------------------------------- validation

BAD = [("std", (0.1, 0.0), r"position.std_y = 0: must be in \[1e-06, 100\] m"),
       ("std", (np.nan, 0.1), r"position.std_x = nan"),
       ("bias_std", -0.5, r"position.bias_std = -0.5: must be in \[0, 10000\] m"),
       ("bias_std", np.inf, r"position.bias_std = inf"),
       ("bias_walk_std", np.nan, r"position.bias_walk_std = nan"),
       ("outlier_std", -1.0, r"position.outlier_std = -1"),
       ("outlier_probability", 1.5, r"position.outlier_probability = 1.5: must be in \[0, 1\]"),
       ("outlier_probability", np.nan, r"position.outlier_probability = nan"),
       ("dropout_probability", -0.1, r"position.dropout_probability = -0.1: must be in \[0, 1\]")]


@pytest.mark.parametrize("field, value, match", BAD)
def test_bad_profiles_are_refused_naming_the_field(field, value, match):
    with pytest.raises(ValueError, match=match):
        PositionNoise(**{field: value})
    p = PositionNoise()
    setattr(p, field, value)
    for use in (p.validate, lambda: p.sample(np.zeros((3, 2)), 0), lambda: SyntheticConfig(position=p)):
        with pytest.raises(ValueError, match=match):
            use()
    se = nv.SensorSettings()
    se.position = p
    with pytest.raises(ValueError, match=match):
        se.validate()


def test_sample_refuses_non_finite_truth():
    with pytest.raises(ValueError, match="truth: every true position must be finite"):
        PositionNoise().sample(np.array([[0.0, np.nan]]), 0)


# --------------------------------------------------------------------------- the sampler vs the model

def test_white_noise_has_the_stated_sigmas_and_no_correlation():
    noise = PositionNoise(std=(0.3, 0.05))
    e = errors(noise, 1, 20000)[0]
    n = len(e)
    np.testing.assert_allclose(e.mean(axis=0), 0.0, atol=Z * 0.3 / np.sqrt(n))
    np.testing.assert_allclose(e.std(axis=0), noise.std, rtol=Z / np.sqrt(2 * n))
    assert abs(np.corrcoef(e.T)[0, 1]) < Z / np.sqrt(n)
    # fixes sit around the true positions given
    truth = np.column_stack([np.linspace(0, 100, 50), np.full(50, -7.0)])
    np.testing.assert_allclose(noise.sample(truth, 3) - truth, noise.sample(np.zeros((50, 2)), 3), atol=1e-12)


def test_bias_is_drawn_once_per_trial():
    noise = PositionNoise(std=(1e-4, 1e-4), bias_std=0.8)
    e = errors(noise, 3000, 20)
    bias = e[:, 0]
    # constant within a trial (up to the white noise) ...
    assert np.abs(e - bias[:, None]).max() < 10e-4
    # ... and N(0, bias_std² I) across trials
    T = len(bias)
    np.testing.assert_allclose(bias.mean(axis=0), 0.0, atol=Z * 0.8 / np.sqrt(T))
    np.testing.assert_allclose(bias.std(axis=0), 0.8, rtol=Z / np.sqrt(2 * T))


def test_bias_walks_with_the_stated_step():
    w, s = 0.05, 1e-3
    noise = PositionNoise(std=(s, s), bias_walk_std=w)
    e = errors(noise, 2000, 100)
    # increments between fixes: N(0, (w² + 2s²) I), independent of each other
    d = np.diff(e, axis=1).reshape(-1, 2)
    np.testing.assert_allclose(d.std(axis=0), np.hypot(w, np.sqrt(2) * s), rtol=Z / np.sqrt(2 * len(d)))
    # fix k (1-based) has variance k·w² + s²: a random walk, not a constant bias
    k = e.shape[1]
    var_k = e[:, -1].var(axis=0)
    np.testing.assert_allclose(var_k, k * w**2 + s**2, rtol=Z * np.sqrt(2 / e.shape[0]))


def test_outliers_come_at_the_stated_rate_and_size():
    p, o, s = 0.1, 3.0, 0.01
    noise = PositionNoise(std=(s, s), outlier_probability=p, outlier_std=o)
    e = errors(noise, 1, 40000)[0]
    n = len(e)
    # a fix is "far" beyond 8σ of the white noise in either axis: an outlier, unless it is small in both
    from scipy.stats import norm
    inside = 1 - 2 * norm.sf(8 * s / np.hypot(o, s))
    expect = p * (1 - inside**2)
    far = (np.abs(e) > 8 * s).any(axis=1).mean()
    assert far == pytest.approx(expect, abs=Z * np.sqrt(expect * (1 - expect) / n))
    # second moment per axis: s² + p·o² (standard error from the sample: the mixture is heavy-tailed)
    sq = e**2
    np.testing.assert_allclose(sq.mean(axis=0), s**2 + p * o**2, atol=Z * sq.std(axis=0).max() / np.sqrt(n))


def test_dropouts_lose_whole_fixes_at_the_stated_rate():
    p = 0.3
    e = errors(PositionNoise(dropout_probability=p), 1, 20000)[0]
    lost = np.isnan(e)
    assert (lost[:, 0] == lost[:, 1]).all()
    assert lost[:, 0].mean() == pytest.approx(p, abs=Z * np.sqrt(p * (1 - p) / len(e)))
    assert not np.isnan(errors(PositionNoise(), 1, 1000)).any()
    assert np.isnan(errors(PositionNoise(dropout_probability=1.0), 1, 100)).all()


@pytest.mark.parametrize("name", ["lanbloc", "deeploc-gps", "sensor-fusion"])
def test_reported_cov_is_the_fix_errors_covariance_without_a_walk(name):
    """Without a bias walk the error of a fix, over trials, has exactly the
    covariance the filter is told: diag(std²) + (bias_std² + p·outlier_std²) I."""
    noise = PositionNoise.named(name)
    e = errors(noise, 4000, 5)
    # per trial, the mean outer product of its fixes' errors: i.i.d. over trials with mean R
    m = np.einsum("tfi,tfj->tij", e, e) / e.shape[1]
    R = noise.reported_cov()
    se = m.std(axis=0) / np.sqrt(len(m))
    assert (np.abs(m.mean(axis=0) - R) < Z * se + 1e-12).all(), (m.mean(axis=0), R, se)


@pytest.mark.parametrize("std, bias, p, o", [((0.0142, 0.039), 0.0, 0.0, 0.0), ((0.3, 0.2), 0.1, 0.0, 0.0),
                                             ((0.25, 0.25), 0.15, 0.02, 2.0), ((1.0, 3.0), 0.0, 1.0, 0.5)])
def test_reported_cov_follows_the_formula(std, bias, p, o):
    noise = PositionNoise(std=std, bias_std=bias, outlier_probability=p, outlier_std=o, bias_walk_std=0.7)
    expect = np.diag(np.square(std)) + (bias**2 + p * o**2) * np.eye(2)
    np.testing.assert_allclose(noise.reported_cov(), expect, rtol=1e-15, atol=0)


# --------------------------------------------------------------------------- one object for both users

@pytest.mark.parametrize("name", PositionNoise.names())
def test_synthetic_set_draws_its_fixes_from_the_core_sampler(name):
    cfg = source_config(name, SyntheticConfig(n_steps=150))
    assert repr(cfg.position) == repr(PositionNoise.named(name))
    data = synthetic_trajectory(cfg, seed=11)
    expect = cfg.position.sample(data.states[1:, :2], _core.derive_seed(11, 1))
    np.testing.assert_array_equal(data.position, expect)
    np.testing.assert_array_equal(cfg.position_cov(), PositionNoise.named(name).reported_cov())
