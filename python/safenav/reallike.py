"""Real-like replay logs from a simulated robot (test and tuning data).

:func:`reallike_log` simulates the kind of run that real landmark data sets
record (robots among barcoded landmarks, e.g. a small indoor arena): a
unicycle robot drives a smooth wandering path through a field of landmarks
while

* its **motion rows** are the *commanded* speed and turn rate (``motion``
  kind: ``speed`` = v_cmd, negative while it backs up to a ``reverse_share``
  of its waypoints; ``heading_change`` = ω_cmd·Δt) at ``motion_rate``
  Hz with timing jitter.  The robot does not do exactly what it is told: its
  actual speed is v = (1 + s_v)·v_cmd + N(0, σ_v²) and its actual turn rate
  ω = (1 + s_ω)·ω_cmd + b_ω + N(0, σ_ω²), where the scale errors s_v, s_ω
  and the gyro-like turn bias b_ω are drawn once per run;
* a **forward camera** (field of view ``fov_deg``, range ``max_range``) sees
  landmarks at ``camera_rate`` Hz, each one in view with probability
  ``detection_probability``, and reports at most ``max_sightings`` (the
  nearest) as ``range_bearing`` rows with σ_r = ``range_std`` +
  ``range_std_per_m``·r and σ_b = ``bearing_std_deg`` (the σ written in the
  row is the true one);
* **truth rows** (motion capture) give the pose at ``truth_rate`` Hz.

The unicycle is integrated at each motion row with the actual (v, ω) over the
row's interval (heading first, then position: the same order as the BMM's
eq. 7).  Everything is drawn from ``numpy.random.default_rng(seed)``, so a
seed gives the same log, bit for bit.  The result is a
:class:`safenav.logs.Log`; :func:`safenav.logs.write_log` writes it as CSV or
Parquet.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from .logs import EVENT_COLUMNS, TRUTH_COLUMNS, Log
from .validation import as_seed

__all__ = ["RealLikeConfig", "reallike_log", "first_sighting"]


@dataclass(frozen=True)
class RealLikeConfig:
    """The simulated run.  Defaults: a 16 m × 10 m arena with 15 landmarks
    near its walls and inside, a robot at 0.1–0.35 m/s, 67 Hz commands, a
    60° camera that sees 5 m."""

    duration: float = 120.0            #: [s] length of the run
    arena: tuple[float, float] = (16.0, 10.0)  #: [m] width and height of the arena
    n_landmarks: int = 15              #: landmarks on a jittered grid over the arena
    idle: float = 2.0                  #: [s] the robot stands still this long at the start
    speed_range: tuple[float, float] = (0.1, 0.35)  #: [m/s] commanded cruise speeds, drawn per waypoint
    reverse_share: float = 0.0         #: share of waypoints the robot backs up to (commanded speed < 0)
    max_turn_rate: float = 0.8         #: [rad/s] |ω_cmd| limit
    turn_gain: float = 1.5             #: ω_cmd = gain · heading error toward the waypoint
    motion_rate: float = 67.0          #: [Hz] command rows
    motion_jitter: float = 0.1         #: command interval jitter, ± this fraction (uniform)
    speed_scale_std: float = 0.05      #: σ of s_v, drawn once
    turn_scale_std: float = 0.05       #: σ of s_ω, drawn once
    turn_bias_std: float = 0.01        #: [rad/s] σ of b_ω, drawn once
    speed_noise: float = 0.02          #: [m/s] σ_v, per command row
    turn_noise: float = 0.05           #: [rad/s] σ_ω, per command row
    camera_rate: float = 5.0           #: [Hz] camera frames
    fov_deg: float = 60.0              #: full horizontal field of view
    max_range: float = 5.0             #: [m]
    min_range: float = 0.3             #: [m] closer landmarks are not recognised
    detection_probability: float = 0.8 #: each landmark in view, per frame
    max_sightings: int = 2             #: at most this many (the nearest) per frame
    range_std: float = 0.1             #: [m] σ_r = range_std + range_std_per_m · r
    range_std_per_m: float = 0.03
    bearing_std_deg: float = 2.5       #: σ_b [deg]
    truth_rate: float = 20.0           #: [Hz] motion-capture rows

    def validate(self) -> None:
        """Raises ValueError naming the first bad field."""
        positive = ("duration", "n_landmarks", "max_turn_rate", "turn_gain", "motion_rate", "camera_rate",
                    "fov_deg", "max_range", "truth_rate", "bearing_std_deg", "range_std", "max_sightings")
        for name in positive:
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"RealLikeConfig.{name} = {v!r}: must be finite and > 0")
        for name in ("idle", "motion_jitter", "speed_scale_std", "turn_scale_std", "turn_bias_std", "speed_noise",
                     "turn_noise", "min_range", "range_std_per_m"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"RealLikeConfig.{name} = {v!r}: must be finite and >= 0")
        if not 0 <= self.reverse_share <= 1:
            raise ValueError(f"RealLikeConfig.reverse_share = {self.reverse_share!r}: must be in [0, 1]")
        if not 0 < self.detection_probability <= 1:
            raise ValueError(f"RealLikeConfig.detection_probability = {self.detection_probability!r}: "
                             "must be in (0, 1]")
        if not self.motion_jitter < 1:
            raise ValueError(f"RealLikeConfig.motion_jitter = {self.motion_jitter!r}: must be < 1")
        lo, hi = self.speed_range
        if not (0 < lo <= hi):
            raise ValueError(f"RealLikeConfig.speed_range = {self.speed_range!r}: need 0 < low <= high")
        w, h = self.arena
        if not (w > 2 and h > 2):
            raise ValueError(f"RealLikeConfig.arena = {self.arena!r}: both sides must be > 2 m")


def _landmarks(cfg: RealLikeConfig, rng: np.random.Generator) -> np.ndarray:
    """``n_landmarks`` positions on a jittered grid covering the arena."""
    w, h = cfg.arena
    n = cfg.n_landmarks
    cols = max(1, int(round(np.sqrt(n * w / h))))
    rows = int(np.ceil(n / cols))
    gx = (np.arange(cols) + 0.5) * w / cols
    gy = (np.arange(rows) + 0.5) * h / rows
    grid = np.array([(x, y) for y in gy for x in gx])[:n]
    jitter = rng.uniform(-0.3, 0.3, size=grid.shape) * np.array([w / cols, h / rows])
    return grid + jitter


def _commands(cfg: RealLikeConfig, rng: np.random.Generator):
    """Times, commands and the true path.  Returns (t, v_cmd, w_cmd, pose)
    with pose[i] the true (x, y, θ) at t[i] (pose[0] is the start)."""
    w, h = cfg.arena
    margin = 1.0
    period = 1.0 / cfg.motion_rate
    n = int(np.ceil(cfg.duration * cfg.motion_rate)) + 1
    dts = period * (1.0 + rng.uniform(-cfg.motion_jitter, cfg.motion_jitter, size=n))
    t = np.concatenate([[0.0], np.cumsum(dts)])
    t = t[t <= cfg.duration]
    s_v = rng.normal(0.0, cfg.speed_scale_std)
    s_w = rng.normal(0.0, cfg.turn_scale_std)
    b_w = rng.normal(0.0, cfg.turn_bias_std)
    pose = np.empty((len(t), 3))
    pose[0] = (rng.uniform(margin, w - margin), rng.uniform(margin, h - margin), rng.uniform(-np.pi, np.pi))
    v_cmd = np.zeros(len(t))
    w_cmd = np.zeros(len(t))

    def waypoint():
        goal = np.array([rng.uniform(margin, w - margin), rng.uniform(margin, h - margin)])
        cruise = rng.uniform(*cfg.speed_range)
        # backing up: the rear (θ + π) steers toward the goal, at a negative speed
        # (no draw without reversing, so that such logs stay as they were)
        back = cfg.reverse_share > 0 and rng.uniform() < cfg.reverse_share
        return goal, cruise, (-1.0 if back else 1.0)

    goal, cruise, sign = waypoint()
    for i in range(1, len(t)):
        x, y, th = pose[i - 1]
        if np.hypot(goal[0] - x, goal[1] - y) < 0.5:
            goal, cruise, sign = waypoint()
        if t[i] > cfg.idle:
            facing = th if sign > 0 else th + np.pi
            err = np.angle(np.exp(1j * (np.arctan2(goal[1] - y, goal[0] - x) - facing)))
            w_cmd[i] = np.clip(cfg.turn_gain * err, -cfg.max_turn_rate, cfg.max_turn_rate)
            v_cmd[i] = sign * cruise * max(0.2, np.cos(err))   # slow down in sharp turns
        dt = t[i] - t[i - 1]
        moving = v_cmd[i] != 0.0 or w_cmd[i] != 0.0
        v = (1.0 + s_v) * v_cmd[i] + (rng.normal(0.0, cfg.speed_noise) if moving else 0.0)
        om = (1.0 + s_w) * w_cmd[i] + (b_w + rng.normal(0.0, cfg.turn_noise) if moving else 0.0)
        th_new = th + om * dt                      # heading first, then position (BMM eq. 7's order)
        pose[i] = (x + v * dt * np.cos(th_new), y + v * dt * np.sin(th_new), np.angle(np.exp(1j * th_new)))
    return t, v_cmd, w_cmd, pose


def _interp_pose(t, pose, tq):
    """The true pose at times ``tq`` (linear; heading unwrapped then wrapped)."""
    th = np.unwrap(pose[:, 2])
    x = np.interp(tq, t, pose[:, 0])
    y = np.interp(tq, t, pose[:, 1])
    h = np.angle(np.exp(1j * np.interp(tq, t, th)))
    return x, y, h


def _sightings(cfg: RealLikeConfig, rng, t, pose, lm):
    """Camera rows: (t, landmark row, range, bearing, σ_r, σ_b)."""
    frames = np.arange(1.0 / cfg.camera_rate, t[-1], 1.0 / cfg.camera_rate)
    x, y, h = _interp_pose(t, pose, frames)
    half = np.deg2rad(cfg.fov_deg) / 2
    sb = np.deg2rad(cfg.bearing_std_deg)
    out = []
    for k, tf in enumerate(frames):
        d = lm - np.array([x[k], y[k]])
        r = np.hypot(d[:, 0], d[:, 1])
        b = np.angle(np.exp(1j * (np.arctan2(d[:, 1], d[:, 0]) - h[k])))
        seen = (r <= cfg.max_range) & (r >= cfg.min_range) & (np.abs(b) <= half)
        seen &= rng.uniform(size=len(lm)) < cfg.detection_probability
        idx = np.flatnonzero(seen)
        idx = idx[np.argsort(r[idx], kind="stable")][:cfg.max_sightings]
        for j in idx:
            sr = cfg.range_std + cfg.range_std_per_m * r[j]
            out.append((tf, j, max(0.0, r[j] + rng.normal(0.0, sr)),
                        float(np.angle(np.exp(1j * (b[j] + rng.normal(0.0, sb))))), sr, sb))
    return out


def reallike_log(seed: int = 0, config: RealLikeConfig | None = None) -> Log:
    """A real-like log (module doc) for ``seed``: landmark ids 0…n−1,
    ``motion`` rows (commanded v, ω·Δt), ``range_bearing`` rows, ``truth``
    rows with heading.  Deterministic for a seed."""
    cfg = config or RealLikeConfig()
    cfg.validate()
    rng = np.random.default_rng(as_seed("seed", seed))
    lm = _landmarks(cfg, rng)
    t, v_cmd, w_cmd, pose = _commands(cfg, rng)
    seen = _sightings(cfg, rng, t, pose, lm)

    n_m, n_o = len(t) - 1, len(seen)
    ev = {c: np.full(n_m + n_o, np.nan) for c in EVENT_COLUMNS if c not in ("kind", "landmark")}
    kind = np.array(["motion"] * n_m + ["range_bearing"] * n_o, dtype=object)
    landmark = np.full(n_m + n_o, -1, dtype=np.int64)
    ev["t"][:n_m] = t[1:]
    ev["speed"][:n_m] = v_cmd[1:]
    ev["heading_change"][:n_m] = w_cmd[1:] * np.diff(t)
    if n_o:
        s = np.array(seen, dtype=float)
        ev["t"][n_m:] = s[:, 0]
        landmark[n_m:] = s[:, 1].astype(np.int64)
        ev["range"][n_m:], ev["bearing"][n_m:] = s[:, 2], s[:, 3]
        ev["range_std"][n_m:], ev["bearing_std"][n_m:] = s[:, 4], s[:, 5]
    order = np.argsort(ev["t"], kind="stable")    # at equal times the motion row first
    events = pd.DataFrame({c: (kind[order] if c == "kind" else
                               pd.array(np.where(landmark[order] >= 0, landmark[order], 0), dtype="Int64")
                               if c == "landmark" else ev[c][order]) for c in EVENT_COLUMNS})
    events.loc[events["kind"] != "range_bearing", "landmark"] = pd.NA
    events["kind"] = events["kind"].astype(str)

    tt = np.arange(0.0, t[-1] + 1e-9, 1.0 / cfg.truth_rate)
    x, y, h = _interp_pose(t, pose, tt)
    truth = pd.DataFrame({"t": tt, "x": x, "y": y, "heading": h}, columns=list(TRUTH_COLUMNS))
    landmarks = {i: (float(lm[i, 0]), float(lm[i, 1])) for i in range(len(lm))}
    return Log(landmarks=landmarks, events=events.reset_index(drop=True), truth=truth)


def first_sighting(log: Log, *, distinct: int = 1) -> float:
    """The time at which observations of ``distinct`` different landmarks
    have been seen (NaN when never): with ``distinct=2``, the first time the
    data could fix the whole pose by range and bearing."""
    ev = log.events
    obs = ev[ev["kind"].isin(("range", "bearing", "range_bearing"))]
    seen: set[int] = set()
    for tt, lid in zip(obs["t"].to_numpy(float), obs["landmark"].to_numpy()):
        seen.add(int(lid))
        if len(seen) >= distinct:
            return float(tt)
    return float("nan")
