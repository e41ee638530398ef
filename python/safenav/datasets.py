"""The synthetic trajectory data set of [SafeNav-ext §V-A3(i)] (= [SafeNav-conf §V-A.2(i)]).

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
* measurements are drawn around the truth from the chosen model: position
  fixes from a :class:`~safenav.measurement.PositionNoise` (default LanBLoc:
  σ = 0.0142 m in X, 0.039 m in Y, the paper's RMSE; its
  ``dropout_probability`` removes a random fraction of the fixes), drawn by
  the core's sampler exactly as the navigation loop draws them, an IMU
  speed/heading, or ranges/bearings to landmarks placed around the route.

Seeds follow the core's one rule (``safenav/seed.hpp``): trial seed ``s``
gives the true vehicle ``derive_seed(s, 0)``, the position source
``derive_seed(s, 1)`` (the navigation loop's sensor stream) and the IMU and
landmark measurements ``derive_seed(s, 2)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from . import _core
from .validation import as_positive_int, as_seed
from .measurement import PositionNoise
from .motion import Bmm, BmmParams, wrap_angle

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
    #: The position source's error model (white noise, bias, bias walk,
    #: outliers, dropouts); the named ones are ``PositionNoise.named(name)``.
    #: Its ``needs_landmarks`` is ignored: the synthetic set fixes at every step.
    position: PositionNoise = field(default_factory=lambda: PositionNoise.named("lanbloc"))
    imu: bool = True                           #: also measure (v, θ)
    speed_std: float = 0.05                    #: IMU speed noise [m/s]
    heading_std: float = 0.02                  #: IMU heading noise [rad]
    landmarks: np.ndarray | None = None        #: (K, 2) for range/bearing measurements
    range_std: float = 0.1                     #: range noise [m]
    bearing_std: float = 0.02                  #: bearing noise [rad]

    def __post_init__(self):
        as_positive_int("n_steps", self.n_steps)
        for name in ("dt", "speed_std", "heading_std", "range_std", "bearing_std", "initial_speed"):
            v = getattr(self, name)
            if not (np.isfinite(v) and (v > 0 or (v == 0 and name == "initial_speed"))):
                raise ValueError(f"SyntheticConfig.{name} = {v!r} must be finite and > 0")
        if not isinstance(self.position, PositionNoise):
            raise TypeError(f"SyntheticConfig.position must be a PositionNoise, got {type(self.position).__name__}")
        self.position.validate()

    def position_cov(self) -> np.ndarray:
        """The 2×2 covariance a filter is told for one position fix
        (``PositionNoise.reported_cov``, as in the navigation loop)."""
        return np.asarray(self.position.reported_cov())

    def params(self) -> BmmParams:
        """The true vehicle's BMM parameters with this data set's dt."""
        p = BmmParams()
        for spec in BmmParams.params():
            p.set_param(spec.name, self.dt if spec.name == "dt" else self.bmm.get_param(spec.name))
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


def synthetic_trajectory(config: SyntheticConfig | None = None, seed: int = 0) -> SyntheticTrajectory:
    """Generate one seeded synthetic trial ([SafeNav-ext §V-A3(i)])."""
    cfg = config or SyntheticConfig()
    seed = as_seed("seed", seed)
    t, speed, heading = command_profile(cfg)
    controls = np.column_stack([speed[1:], np.diff(heading)])
    x0 = np.array([0.0, 0.0, speed[0], heading[0]])
    states = Bmm(cfg.params()).simulate(x0, controls, _core.derive_seed(seed, 0))
    truth = states[1:]
    position = cfg.position.sample(truth[:, :2], _core.derive_seed(seed, 1))
    rng = np.random.default_rng(_core.derive_seed(seed, 2))
    n = cfg.n_steps
    speed_heading = None
    if cfg.imu:
        speed_heading = truth[:, 2:] + rng.standard_normal((n, 2)) * [cfg.speed_std, cfg.heading_std]
        speed_heading[:, 1] = wrap_angle(speed_heading[:, 1])
    ranges = bearings = None
    if cfg.landmarks is not None:
        lm = np.asarray(cfg.landmarks, dtype=float)
        d = lm[None, :, :] - truth[:, None, :2]
        ranges = np.hypot(d[..., 0], d[..., 1]) + rng.standard_normal((n, len(lm))) * cfg.range_std
        b = np.arctan2(d[..., 1], d[..., 0]) - truth[:, 3:4] + rng.standard_normal((n, len(lm))) * cfg.bearing_std
        bearings = wrap_angle(b)
    return SyntheticTrajectory(config=cfg, t=t, controls=controls, states=states, position=position,
                               speed_heading=speed_heading, ranges=ranges, bearings=bearings)

