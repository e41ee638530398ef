"""The synthetic trajectory data set of SafeNav section V-A(3)(i).

The paper drives the trajectory with

    a(t_i) = 3·sin(4π t_i / T),   θ(t_i) = (π/2)·sin(2π t_i / T),

with ``dt = 0.05 s`` and ``T = N·dt``, and stores seven variables per point:
``px, sx, ax, py, sy, ay, θ`` (position, speed and acceleration along x and y,
and heading).  The paper does not say how long its trajectories are, what the
initial speed is, or how noise enters; our choices (documented on
:class:`SyntheticConfig`) are:

* the profile is the *command*: desired speed ``v_0 + Σ a·dt`` and heading
  change ``θ(t_{k+1}) − θ(t_k)``;
* the true vehicle follows the noisy BMM (eqs. 6–9) under those commands,
  seeded, so that truth and commands differ as they would in the field;
* measurements are drawn around the truth from the chosen model: LanBLoc
  position fixes (default σ = 0.0142 m in X, 0.039 m in Y, the paper's RMSE),
  an IMU speed/heading, or ranges/bearings to landmarks placed around the
  route; ``dropout`` removes a random fraction of the position fixes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .validation import as_positive_int, as_seed
from .measurement import LANBLOC_STD
from .motion import Bmm, BmmParams

COLUMNS = ("px", "sx", "ax", "py", "sy", "ay", "theta")


@dataclass(frozen=True)
class SyntheticConfig:
    """Parameters of the synthetic data set (defaults are ours unless noted)."""

    n_steps: int = 200                         #: N (T = N·dt = 10 s)
    dt: float = 0.05                           #: paper: 0.05 s
    initial_speed: float = 1.0                 #: v_0 [m/s]
    accel_amplitude: float = 3.0               #: paper: a(t) = 3 sin(4πt/T)
    heading_amplitude: float = np.pi / 2       #: paper: θ(t) = π/2 sin(2πt/T)
    bmm: BmmParams = field(default_factory=BmmParams)  #: the true vehicle's BMM (dt is overridden)
    position_std: tuple[float, float] = LANBLOC_STD    #: LanBLoc fix noise (paper's RMSE)
    #: Error profile of the position source beyond white noise (see
    #: :class:`safenav.navigation.SourceProfile`): a constant bias drawn per
    #: trial, a bias random walk per fix, and occasional outliers.  All 0 for
    #: LanBLoc; the emulated baselines set them.
    position_bias_std: float = 0.0
    position_bias_walk_std: float = 0.0
    outlier_probability: float = 0.0
    outlier_std: float = 0.0
    imu: bool = True                           #: also measure (v, θ)
    speed_std: float = 0.05                    #: IMU speed noise [m/s]
    heading_std: float = 0.02                  #: IMU heading noise [rad]
    dropout: float = 0.0                       #: fraction of steps without a position fix
    landmarks: np.ndarray | None = None        #: (K, 2) for range/bearing measurements
    range_std: float = 0.1                     #: range noise [m]
    bearing_std: float = 0.02                  #: bearing noise [rad]

    def __post_init__(self):
        as_positive_int("n_steps", self.n_steps)
        for name in ("dt", "speed_std", "heading_std", "range_std", "bearing_std", "initial_speed"):
            v = getattr(self, name)
            if not (np.isfinite(v) and (v > 0 or (v == 0 and name == "initial_speed"))):
                raise ValueError(f"SyntheticConfig.{name} = {v!r} must be finite and > 0")
        if not (0.0 <= self.dropout < 1.0):
            raise ValueError(f"SyntheticConfig.dropout = {self.dropout!r} must be in [0, 1)")
        for name in ("position_bias_std", "position_bias_walk_std", "outlier_std"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"SyntheticConfig.{name} = {v!r} must be finite and >= 0")
        if not (0.0 <= self.outlier_probability <= 1.0):
            raise ValueError(f"SyntheticConfig.outlier_probability = {self.outlier_probability!r} must be in [0, 1]")
        if len(self.position_std) != 2 or not all(np.isfinite(s) and s > 0 for s in self.position_std):
            raise ValueError(f"SyntheticConfig.position_std = {self.position_std!r} must be two values > 0")

    def position_cov(self) -> np.ndarray:
        """The 2×2 covariance a filter is told for one position fix: white noise
        plus the bias and outlier variances (the C++ ``PositionSource.reported_cov``,
        so that the synthetic set and the navigation loop tell filters the same)."""
        from .navigation import SourceProfile

        profile = SourceProfile("synthetic", "synthetic", tuple(self.position_std), self.position_bias_std,
                                self.position_bias_walk_std, self.outlier_probability, self.outlier_std)
        return np.asarray(profile.to_core().reported_cov())

    def params(self) -> BmmParams:
        """The true vehicle's BMM parameters with this data set's dt."""
        p = BmmParams(**{k: getattr(self.bmm, k) for k in (
            "acceleration", "deceleration", "max_speed", "max_heading_rate", "terrain_effect", "speed_noise",
            "heading_noise", "position_noise")}, dt=self.dt)
        return p


@dataclass(frozen=True)
class SyntheticTrajectory:
    """One synthetic trial: commands, truth and measurements."""

    config: SyntheticConfig
    t: np.ndarray            #: (N+1,) time [s]
    controls: np.ndarray     #: (N, 2) desired speed, heading change
    states: np.ndarray       #: (N+1, 4) true (x, y, v, θ)
    position: np.ndarray     #: (N, 2) position fixes after each step (NaN rows = dropout)
    speed_heading: np.ndarray | None  #: (N, 2) IMU
    ranges: np.ndarray | None         #: (N, K)
    bearings: np.ndarray | None       #: (N, K)

    @property
    def truth(self) -> pd.DataFrame:
        """The paper's seven variables per point: px, sx, ax, py, sy, ay, θ."""
        x, y, v, th = self.states.T
        sx, sy = v * np.cos(th), v * np.sin(th)
        dt = self.config.dt
        return pd.DataFrame({"t": self.t, "px": x, "sx": sx, "ax": np.gradient(sx, dt), "py": y, "sy": sy,
                             "ay": np.gradient(sy, dt), "theta": th})

    @property
    def x0(self) -> np.ndarray:
        return self.states[0].copy()


def command_profile(cfg: SyntheticConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The paper's a(t) and θ(t) turned into BMM commands.  Returns (t, speed, heading)."""
    n, dt = cfg.n_steps, cfg.dt
    T = n * dt
    t = np.arange(n + 1) * dt
    a = cfg.accel_amplitude * np.sin(4 * np.pi * t / T)
    speed = cfg.initial_speed + np.concatenate([[0.0], np.cumsum(a[:-1] * dt)])
    heading = cfg.heading_amplitude * np.sin(2 * np.pi * t / T)
    return t, speed, heading


def _source_errors(cfg: SyntheticConfig, n: int, rng) -> np.ndarray:
    """(n, 2) bias + bias walk + outliers of the position source, in the order
    the C++ navigation loop draws them (bias once, then per fix: walk, outlier)."""
    err = np.zeros((n, 2))
    if cfg.position_bias_std > 0:
        err += rng.standard_normal(2) * cfg.position_bias_std
    if cfg.position_bias_walk_std > 0:
        err += np.cumsum(rng.standard_normal((n, 2)) * cfg.position_bias_walk_std, axis=0)
    if cfg.outlier_probability > 0:
        hit = rng.random(n) < cfg.outlier_probability
        err += hit[:, None] * rng.standard_normal((n, 2)) * cfg.outlier_std
    return err


def synthetic_trajectory(config: SyntheticConfig | None = None, seed: int = 0) -> SyntheticTrajectory:
    """Generate one seeded synthetic trial (SafeNav section V-A(3)(i))."""
    cfg = config or SyntheticConfig()
    seed = as_seed("seed", seed)
    t, speed, heading = command_profile(cfg)
    controls = np.column_stack([speed[1:], np.diff(heading)])
    ss = np.random.SeedSequence(seed)
    motion_seed, meas_seed, error_seed = ss.spawn(3)  # the first two as before the error profile existed
    x0 = np.array([0.0, 0.0, speed[0], heading[0]])
    states = Bmm(cfg.params()).simulate(x0, controls, int(motion_seed.generate_state(1, np.uint64)[0]))
    rng = np.random.default_rng(meas_seed)
    n = cfg.n_steps
    truth = states[1:]
    position = truth[:, :2] + rng.standard_normal((n, 2)) * np.asarray(cfg.position_std)
    position += _source_errors(cfg, n, np.random.default_rng(error_seed))
    if cfg.dropout > 0:
        position[rng.random(n) < cfg.dropout] = np.nan
    speed_heading = None
    if cfg.imu:
        speed_heading = truth[:, 2:] + rng.standard_normal((n, 2)) * [cfg.speed_std, cfg.heading_std]
        speed_heading[:, 1] = (speed_heading[:, 1] + np.pi) % (2 * np.pi) - np.pi
    ranges = bearings = None
    if cfg.landmarks is not None:
        lm = np.asarray(cfg.landmarks, dtype=float)
        d = lm[None, :, :] - truth[:, None, :2]
        ranges = np.hypot(d[..., 0], d[..., 1]) + rng.standard_normal((n, len(lm))) * cfg.range_std
        b = np.arctan2(d[..., 1], d[..., 0]) - truth[:, 3:4] + rng.standard_normal((n, len(lm))) * cfg.bearing_std
        bearings = (b + np.pi) % (2 * np.pi) - np.pi
    return SyntheticTrajectory(config=cfg, t=t, controls=controls, states=states, position=position,
                               speed_heading=speed_heading, ranges=ranges, bearings=bearings)

