"""Replay a timestamped log through the online :class:`~safenav.guidance.Localizer`.

:func:`replay` feeds a :class:`~safenav.logs.Log` (``docs/replay.md``) to the
localizer event by event, in time order — every range at its own timestamp —
exactly as a vehicle's loop would, and records the estimate after each motion
input.  When the log carries ground truth, :func:`replay` scores the
estimate at each truth time with the latest estimate at or before it
(causal: nothing after that time is used), through the core's one trajectory
accumulator (:class:`safenav.metrics.TrajectoryScore`, as the simulator's
trials): against the truth, the position RMSE (``truth_rmse``), ADE
(``truth_ade``, mean error, [SafeNav-ext eq. 21] with the truth as
reference), FDE (``truth_fde``, final error, eq. 22), the mean position NEES
(2 degrees of freedom; 2 for a consistent filter) and the share of poses
outside the 3σ ellipse, over the truth rows from the localizer's start on.
A replay never succeeds silently: :attr:`ReplayResult.reason` says why it
never started (the localizer's ``reason()``) or how many truth poses lie
before its start.

With ``innovations=True`` it also records each measurement input's
innovation (:attr:`ReplayResult.innovations`): its status, NIS
ν = yᵀS⁻¹y with its dimension, and log det S, both of the S that the
filter's own update used (``InputResult.log_det_s``: S = H P⁻ Hᵀ + R of the
EKF [SafeNav eq. 12], augmented states included; the particles' predictive
covariance plus R for the particle filter).  :mod:`safenav.tune` fits the
noise to these (innovation likelihood, Mehra 1970).

``safenav replay LOG`` is the command-line front end (``--help``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from . import _core
from .guidance import Localizer, LocalizerSettings, localizer_settings
from .logs import Log, load_plaza, read_log
from .validation import as_array

__all__ = ["ReplayResult", "replay", "INNOVATION_COLUMNS", "ODOMETRY_HEADINGS", "odometry_heading_inputs",
           "PLAZA_ODOMETRY_HEADING", "causal_index", "lag_label", "load", "score", "PRESETS",
           "preset_settings"]

#: Named localizer set-ups for replay.  Both take a log's motion rows as the
#: speed the vehicle *reported* (``bmm.unicycle``: signed, no acceleration
#: limit; docs/replay.md says why this departs from [SafeNav eq. 3]).
#: ``default``: otherwise the online defaults
#: (:func:`~safenav.guidance.localizer_settings`).  ``plaza``: the Plaza
#: range-only robot — odometry at 5 Hz (BMM Δt = 0.2 s with limits that do not
#: bind odometry; process noise 0.02 m, 0.05 m/s, 0.0007 rad per step), ranges
#: with σ 0.55 m that read ~7 % long (range-scale state k, prior 0.07) and a
#: heading-rate bias β, gate 0.999.  Tuned on Plaza1 (in-sample); Plaza2 was
#: held out.
PRESETS = ("default", "plaza")
#: σ of a Plaza file's ranges in the ``plaza`` preset [m]: their residual against the truth after the scale.
PLAZA_RANGE_STD = 0.55
#: How the Plaza files' odometry rows (``DR``: distance and heading change per interval) are read:
#: along the chord of each interval's arc (:func:`odometry_heading_inputs`; docs/replay.md, "Odometry
#: along the arc").  Chosen from Plaza1 and the geometry of an arc; Plaza2 was held out.
PLAZA_ODOMETRY_HEADING = "mid"


def preset_settings(name: str, *, filter: str = "ekf", n_particles: int = 1000, seed: int = 0,
                    gate: float | None = None, augment=()) -> LocalizerSettings:
    """The :data:`PRESETS` set-up ``name``; ``augment`` adds augmented states."""
    from .validation import choice

    choice("preset", name, dict.fromkeys(PRESETS))
    if name == "default":
        s = localizer_settings(filter=filter, n_particles=n_particles, seed=seed, gate=gate, augment=augment)
        s.bmm.unicycle = True
        return s
    bmm = _core.BmmParams(acceleration=100.0, deceleration=100.0, max_speed=100.0, max_heading_rate=100.0, dt=0.2,
                          terrain_effect=0.0, speed_noise=0.05, heading_noise=0.0007, position_noise=0.02,
                          unicycle=True)
    return localizer_settings(filter=filter, n_particles=n_particles, seed=seed, bmm=bmm,
                              gate=0.999 if gate is None else gate,
                              augment=("range_scale", "heading_rate_bias", *augment))

#: Columns of :attr:`ReplayResult.innovations`.
INNOVATION_COLUMNS = ("t", "kind", "status", "nis", "dim", "logdet_s")
#: Columns of :attr:`ReplayResult.trajectory`.
TRAJECTORY_COLUMNS = ("t", "x", "y", "speed", "heading", "var_x", "var_y", "cov_xy", "var_speed", "var_heading")


@dataclass
class ReplayResult:
    """The estimated trajectory and, with ground truth, its scores."""

    trajectory: pd.DataFrame        #: the start, then one row per motion input: TRAJECTORY_COLUMNS
    counts: dict                    #: the localizer's input counts (applied, rejected, late, buffered, motion)
    t_start: float                  #: time of the localizer's start (prior or from the data)
    started_from: str               #: "data" or "prior"
    #: truth_rmse, truth_ade, truth_fde, nees, nees_dof, outside_3sigma, n_scored, n_before_start, label
    metrics: dict = field(default_factory=dict)
    #: why the replay estimated less than the whole log: the localizer's
    #: :meth:`~safenav.guidance.Localizer.reason` when it never started
    #: ("waiting: ..."), or how many truth poses lie before its start; "" when
    #: every truth pose (or, without truth, every input) is covered.
    reason: str = ""
    #: with ``replay(..., innovations=True)``: one row per measurement input
    #: (INNOVATION_COLUMNS); NaN NIS and log det S before the start
    innovations: pd.DataFrame | None = None
    #: with ``replay(..., lag=L)``: the fixed-lag smoothed trajectory (TRAJECTORY_COLUMNS), one row
    #: at the start and at each motion input, each with the data up to its time + L (docs/replay.md,
    #: "Fixed-lag smoothing"); not causal
    smoothed: pd.DataFrame | None = None
    #: its scores (as :attr:`metrics`, label "fixed-lag L s")
    smoothed_metrics: dict = field(default_factory=dict)

    @property
    def estimated(self) -> bool:
        """Whether the localizer produced any estimate."""
        return len(self.trajectory) > 0


def load(path, *, range_std: float = 1.0) -> Log:
    """A log file (``.csv``/``.parquet``, :func:`~safenav.logs.read_log`) or a
    Plaza range-only ``.mat`` file (:func:`~safenav.logs.load_plaza`)."""
    from pathlib import Path

    p = Path(path)
    if p.suffix.lower() == ".mat":
        return load_plaza(p, range_std=range_std)
    return read_log(p)


#: How an ``odometry`` row's heading change enters the motion model (:func:`replay`'s ``odometry_heading``).
ODOMETRY_HEADINGS = ("end", "mid")


def odometry_heading_inputs(heading_change: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The heading changes to feed for odometry rows Δθ_0 … Δθ_{n-1} (in time order) so that the
    BMM, which moves at the heading *after* its step ([SafeNav eq. 7]), moves each row's distance
    at the heading of the middle of its interval: row k gets Δθ_{k−1}/2 + Δθ_k/2 (row 0: Δθ_0/2),
    which uses no later row.  Also returns what each row still owes the heading at its time
    (Δθ_k/2), which the reported heading adds back.

    This is the odometry motion model of Thrun, Burgard & Fox, *Probabilistic Robotics* (2005),
    §5.4 — a rotation δ_rot1, a translation δ_trans, a rotation δ_rot2 — with δ_rot1 = δ_rot2 = Δθ/2,
    the split of a constant-curvature arc: its chord leaves at half the heading change (the chord's
    length, d·sinc(Δθ/2), differs from the arc's d by less than 0.01 % for |Δθ| < 0.05 rad)."""
    d = np.asarray(heading_change, dtype=float)
    half = 0.5 * d
    fed = half.copy()
    fed[1:] += half[:-1]
    return fed, half


def replay(log: Log, settings: LocalizerSettings | None = None, *, prior=None,
           innovations: bool = False, delays=None, lag: float | None = None, smoother: str = "rts",
           iterations: int = 1, odometry_heading: str = "end") -> ReplayResult:
    """Run ``log`` through a :class:`Localizer` with ``settings`` (default:
    the ``default`` preset, :func:`preset_settings`).  ``prior`` = ``(t, x0, P0)``
    starts it from a prior; by default it starts from the data.
    ``innovations`` records each measurement input's NIS and log det S
    (:attr:`ReplayResult.innovations`; the module doc).  ``delays`` (one
    per event row, seconds ≥ 0) delivers each row at its time plus its delay,
    as a vehicle receives late measurements (in the order of arrival; the
    rows keep their own times): the trajectory is still the estimate each
    motion input had when it arrived (causal).  ``lag`` (seconds, finite and
    ≥ 0; EKF only) also runs the fixed-lag smoother beside the causal filter
    (:attr:`ReplayResult.smoothed`, :attr:`ReplayResult.smoothed_metrics`);
    ``smoother`` is its kind, ``"rts"`` or ``"iterated"`` (``iterations``
    Gauss–Newton passes per output; docs/replay.md, "Fixed-lag smoothing").
    The causal trajectory and its scores stay as they are.  ``odometry_heading``
    says where in an ``odometry`` row's interval its heading change happens:
    ``"end"`` (the default) feeds the row as it is, so the BMM moves the
    distance at the heading after the change (eq. 7); ``"mid"`` moves it at the
    heading of the interval's middle, along the chord of the arc
    (:func:`odometry_heading_inputs`; docs/replay.md, "Odometry along the arc"),
    and the trajectories report the heading at each row's time."""
    from .validation import choice

    choice("odometry_heading", odometry_heading, dict.fromkeys(ODOMETRY_HEADINGS))
    ids = sorted(log.landmarks)
    landmarks = np.array([log.landmarks[i] for i in ids], dtype=float).reshape(-1, 2)
    loc = Localizer(settings or preset_settings("default"), landmarks, ids)
    if lag is not None:
        loc.set_lag(float(lag), smoother, int(iterations))  # ValueError naming lag (negative, NaN, not the EKF) or smoother
    if prior is not None:
        t0, x0, P0 = prior
        loc.initialize(float(t0), np.asarray(x0, dtype=float), np.asarray(P0, dtype=float))
    kinds, t, lm, cols, owed = _event_columns(log, odometry_heading)
    odo = kinds == "odometry"
    rows, inno = [], []
    order = range(len(kinds))
    if delays is not None:
        d = as_array("delays", delays, (len(kinds),))
        if not (np.isfinite(d).all() and (d >= 0).all()):
            bad = int(np.flatnonzero(~(np.isfinite(d) & (d >= 0)))[0])
            raise ValueError(f"delays[{bad}] = {float(d[bad])!r}: each delay must be finite and >= 0")
        order = np.argsort(t + d, kind="stable")

    def record():
        x, P = loc.x, loc.P
        rows.append((loc.time, x[0], x[1], x[2], x[3], P[0, 0], P[1, 1], P[0, 1], P[2, 2], P[3, 3]))

    t_start = math.nan
    if loc.initialized:
        t_start = loc.time
        record()
    for i in order:
        res = _feed(loc, kinds[i], t[i], int(lm[i]), cols, i)
        if res is None:  # a motion input: the estimate after it
            if loc.initialized and not math.isnan(t_start):
                record()
        elif innovations:
            inno.append((t[i], kinds[i], res.status.name.lower(), res.nis, res.dim, res.log_det_s))
        if math.isnan(t_start) and loc.initialized:  # started from the data: its first estimate
            t_start = loc.time
            record()
    traj = pd.DataFrame(rows, columns=list(TRAJECTORY_COLUMNS))
    if odometry_heading == "mid":
        _add_owed_heading(traj, t[odo], owed[odo])
    c = loc.counts
    result = ReplayResult(trajectory=traj, t_start=t_start, started_from="prior" if prior is not None else "data",
                          counts={"motion": c.motion, "applied": c.applied, "rejected": c.rejected, "late": c.late,
                                  "buffered": c.buffered, "ignored": c.ignored})
    if innovations:
        result.innovations = pd.DataFrame(inno, columns=list(INNOVATION_COLUMNS))
    _score_into(result, loc, log, lag, smoother, (t[odo], owed[odo]) if odometry_heading == "mid" else None)
    return result


def _event_columns(log: Log, odometry_heading: str):
    """The log's events as arrays: kinds, times, landmark ids (−1 for none),
    the value columns, and the heading change still owed at each odometry
    row's time (``"mid"``: the rows' heading changes are then the ones fed,
    :func:`odometry_heading_inputs`)."""
    ev = log.events
    kinds = ev["kind"].to_numpy()
    t = ev["t"].to_numpy(float)
    lm = ev["landmark"].fillna(-1).to_numpy(np.int64)
    cols = {c: ev[c].to_numpy(float) for c in ("x", "y", "speed", "distance", "heading_change", "range", "bearing",
                                                "range_std", "bearing_std", "std_x", "std_y")}
    odo = kinds == "odometry"
    owed = np.zeros(len(ev))
    if odometry_heading == "mid" and odo.any():
        fed, half = odometry_heading_inputs(cols["heading_change"][odo])
        cols["heading_change"] = cols["heading_change"].copy()
        cols["heading_change"][odo] = fed
        owed[odo] = half
    return kinds, t, lm, cols, owed


def _feed(loc, kind: str, t: float, landmark: int, cols: dict, i: int):
    """Event row ``i`` (its values in ``cols``) into the localizer: None for
    a motion input, else the measurement's ``InputResult``."""
    if kind == "odometry":
        loc.odometry(t, cols["distance"][i], cols["heading_change"][i])
        return None
    if kind == "motion":
        loc.motion(t, cols["speed"][i], cols["heading_change"][i])
        return None
    if kind == "fix":
        R = np.diag([cols["std_x"][i] ** 2, cols["std_y"][i] ** 2])
        return loc.fix(t, cols["x"][i], cols["y"][i], R)
    # range, bearing, range_bearing: read_log requires the σ of whatever a row measures; the other one is NaN and unused
    return loc.observe(t, landmark, cols["range"][i], cols["bearing"][i], cols["range_std"][i], cols["bearing_std"][i])


def _score_into(result: ReplayResult, loc, log: Log, lag, smoother: str, owed) -> None:
    """The replay's scores against the log's truth (causal, and the smoothed
    trajectory's at its lag), and the reason where it never started or
    started after some truth poses."""
    traj = result.trajectory
    if log.truth is not None and len(traj):
        result.metrics = score(traj, log.truth)
    if lag is not None:
        result.smoothed = _smoothed(loc)
        if owed is not None:
            _add_owed_heading(result.smoothed, *owed)
        if log.truth is not None and len(result.smoothed):
            result.smoothed_metrics = score(result.smoothed, log.truth, label=lag_label(lag))
            result.smoothed_metrics["smoother"] = smoother
    if not len(traj):
        result.reason = f"never started: {loc.reason()}"
    elif result.metrics and result.metrics["n_before_start"] > 0:
        n, m = result.metrics["n_before_start"], len(log.truth)
        result.reason = f"{n} of {m} truth poses lie before the start, unscored; {loc.reason()}"


def _add_owed_heading(trajectory: pd.DataFrame, t_odometry: np.ndarray, owed: np.ndarray) -> None:
    """Adds to each row at an odometry row's time the heading change that row still owes ("mid")."""
    if not len(trajectory) or not len(t_odometry):
        return
    tt = trajectory["t"].to_numpy(float)
    j = np.clip(np.searchsorted(t_odometry, tt), 0, len(t_odometry) - 1)
    at = np.abs(t_odometry[j] - tt) <= 1e-9
    h = trajectory["heading"].to_numpy(float) + np.where(at, owed[j], 0.0)
    trajectory["heading"] = np.arctan2(np.sin(h), np.cos(h))


def lag_label(lag: float) -> str:
    """The label of a fixed-lag smoothed result (``"fixed-lag 2 s"``)."""
    return f"fixed-lag {float(lag):g} s"


def _smoothed(loc) -> pd.DataFrame:
    """Every smoothed estimate of ``loc`` (the rest smoothed with all the data) as TRAJECTORY_COLUMNS."""
    loc.finish_smoothing()
    t, x, P = loc.take_smoothed()
    return pd.DataFrame({"t": t, "x": x[:, 0], "y": x[:, 1], "speed": x[:, 2], "heading": x[:, 3],
                         "var_x": P[:, 0], "var_y": P[:, 5], "cov_xy": P[:, 1], "var_speed": P[:, 10],
                         "var_heading": P[:, 15]}, columns=list(TRAJECTORY_COLUMNS))


def causal_index(t_estimates: np.ndarray, t_truth: np.ndarray):
    """(j, ok): the row of the latest estimate at or before each truth time, and where there is one."""
    j = np.searchsorted(t_estimates, t_truth + 1e-9, side="right") - 1
    return j, j >= 0


def score(trajectory: pd.DataFrame, truth: pd.DataFrame, label: str = "causal") -> dict:
    """Scores of ``trajectory`` against ``truth`` (see the module doc), each truth pose with the latest
    estimate at or before it; ``label`` says what the estimate is ("causal", or :func:`lag_label`'s)."""
    gt = truth[["t", "x", "y"]].to_numpy(float)
    j, ok = causal_index(trajectory["t"].to_numpy(float), gt[:, 0])
    j = j[ok]
    vx, vy, cxy = (trajectory[c].to_numpy(float)[j] for c in ("var_x", "var_y", "cov_xy"))
    covariances = np.column_stack([vx, cxy, cxy, vy])   # 2x2 row-major per pose
    acc = _core.TrajectoryScore(len(j))
    acc.add_rows(np.ascontiguousarray(trajectory[["x", "y"]].to_numpy(float)[j]), covariances,
                 np.ascontiguousarray(gt[ok, 1:3]))
    return {"label": label, "truth_rmse": acc.truth_rmse, "truth_ade": acc.truth_ade, "truth_fde": acc.truth_fde,
            "nees": acc.position_nees, "nees_dof": 2, "outside_3sigma": acc.outside_3sigma,
            "n_scored": int(acc.size), "n_before_start": int((~ok).sum())}
