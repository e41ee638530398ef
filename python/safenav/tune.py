"""Noise identification from a logged run (``safenav tune LOG``).

:func:`tune` estimates the localizer's process noise — the BMM's per-step
σ of speed, heading and position (``BmmParams.speed_noise``,
``heading_noise``, ``position_noise``, [SafeNav-ext eqs. 6–7], per nominal
step ``bmm.dt``) — and the measurement σ of each observation kind in the log
(range, bearing, position fix) by maximum likelihood, replaying the log
through the same online :class:`~safenav.guidance.Localizer` that a vehicle
runs (:func:`safenav.replay.replay`) for each candidate.

The criterion, per log:

* **innovation-only** (no truth, or ``use_truth=False``): the innovation
  likelihood of Mehra (1970), the prediction-error form of the Gaussian
  likelihood of the measurements, averaged over the measurement inputs::

      J_inn = mean_i ½ (ν_i + log det S_i + m_i log 2π),   ν_i = y_iᵀ S_i⁻¹ y_i

  with y_i the innovation, S_i = H P⁻ Hᵀ + R its covariance and m_i its
  dimension (replay's ``innovations=True``).  It needs no truth and fits Q
  and R together: a too-small R or Q makes ν large, a too-large one makes
  log det S large.
* **truth-based** (the log has truth rows): J_inn plus the discriminative
  criterion of Abbeel et al. (2005, "Discriminative training of Kalman
  filters", the likelihood of the true states under the filter's belief),
  here on the position at each truth time (causal, as
  :func:`safenav.replay.score`)::

      J_truth = mean_k ½ (e_kᵀ P_k⁻¹ e_k + log det P_k + 2 log 2π)

  J_truth rewards what the estimate is used for (a small error with a
  covariance that matches it); J_inn keeps each observation kind's σ
  consistent with its own innovations.

Consistency is reported, not optimised: the mean NIS of each observation
kind against its dimension, and with truth the mean position NEES against
2, each with the two-sided 95 % χ² band of Bar-Shalom, Li & Kirubarajan
(2001, §5.4.2) for N independent samples (successive filter errors are
correlated, so the NEES band is optimistic).

The search runs in log-space with scipy's bounded Nelder–Mead: a replay is
a discontinuous function of the noise (gates, the start from the data), so
no gradients.  Bounds come from each BMM parameter's declared range
(``BmmParams.params()``); σ scales of the observations lie in
:data:`SCALE_RANGE`.

Several runs of one vehicle can be tuned together (``tune([log_a, log_b])``):
their likelihoods are pooled, averaging out what is constant within a run.

Observation σ are overrides of the σ in the log's rows
(:class:`NoiseOverrides`): a scale (``range_std_scale``: the row's σ times
it, so a σ that grows with range keeps its shape) or an absolute σ
(``range_std``).  :func:`save_preset` writes settings and overrides as a
TOML preset file; :func:`load_preset` reads it back (also JSON) for
``safenav replay --preset FILE`` and for a vehicle's own loop.
"""

from __future__ import annotations

import dataclasses
import json
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import optimize, stats

from . import _core
from .guidance import FILTERS, LocalizerSettings
from .logs import Log
from .replay import causal_index, preset_settings, replay

__all__ = ["NoiseOverrides", "TuneResult", "tune", "consistency", "save_preset", "load_preset", "is_preset_file",
           "preset_base", "report", "PROCESS_NOISE", "SCALE_RANGE", "PRESET_FORMAT"]

#: The BMM process-noise parameters that :func:`tune` estimates (σ per nominal step bmm.dt).
PROCESS_NOISE = ("speed_noise", "heading_noise", "position_noise")
#: Range of an observation σ scale (dimensionless).
SCALE_RANGE = (1e-2, 1e2)
#: The smallest process-noise σ searched, as a share of the parameter's upper bound (log-space needs > 0).
FLOOR_SHARE = 1e-6
PRESET_FORMAT = "safenav-preset"
PRESET_VERSION = 1
_OBS = ("range", "bearing", "fix")          # the σ of an observation kind
_LOG_2PI = math.log(2.0 * math.pi)
_PENALTY = 1e3                               # J of a replay that never started (no innovations)


@dataclass(frozen=True)
class NoiseOverrides:
    """Observation σ overrides of a preset: each σ of a log row (or of a
    vehicle's own measurement) becomes ``<kind>_std`` when set, else the
    row's σ times ``<kind>_std_scale``."""

    range_std_scale: float = 1.0
    bearing_std_scale: float = 1.0
    fix_std_scale: float = 1.0
    range_std: float | None = None    #: [m] absolute σ_r
    bearing_std: float | None = None  #: [rad] absolute σ_b
    fix_std: float | None = None      #: [m] absolute σ of each fix coordinate

    def __post_init__(self):
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if v is None and not f.name.endswith("_scale"):
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v > 0):
                raise ValueError(f"{f.name} = {v!r}: must be a finite number > 0")

    def std(self, kind: str, row_std):
        """The σ to use for ``kind`` ("range", "bearing" or "fix") given the row's σ."""
        absolute = getattr(self, f"{kind}_std")
        if absolute is not None:
            return np.where(np.isnan(row_std), row_std, absolute) if np.ndim(row_std) else float(absolute)
        return row_std * getattr(self, f"{kind}_std_scale")

    def apply(self, log: Log) -> Log:
        """``log`` with its rows' σ overridden (a copy; NaN σ of what a row does not measure stay NaN)."""
        if self == NoiseOverrides():
            return log
        ev = log.events.copy()
        for kind, cols in (("range", ("range_std",)), ("bearing", ("bearing_std",)), ("fix", ("std_x", "std_y"))):
            for c in cols:
                ev[c] = self.std(kind, ev[c].to_numpy(float))
        return Log(landmarks=log.landmarks, events=ev, truth=log.truth)

    def as_dict(self) -> dict:
        return {k: v for k, v in dataclasses.asdict(self).items() if v is not None}


@dataclass
class TuneResult:
    """What :func:`tune` found, and the consistency before and after."""

    settings: LocalizerSettings  #: the tuned localizer settings
    noise: NoiseOverrides        #: the tuned observation σ overrides
    parameters: dict             #: name → tuned value (the searched ones)
    start: dict                  #: name → value at the start
    method: str                  #: "truth-based" or "innovation-only"
    before: dict                 #: :func:`consistency` with the start
    after: dict                  #: :func:`consistency` with the tuned values
    evaluations: int             #: replays the search ran
    base: str = "default"        #: the named preset the settings started from
    message: str = ""            #: the optimiser's


def _chi2_band(n: int, dof: float, p: float = 0.95) -> tuple[float, float]:
    """Two-sided ``p`` band of the mean of n χ²(dof) samples [Bar-Shalom et al. 2001, §5.4.2]."""
    if n <= 0 or not dof > 0:
        return (math.nan, math.nan)
    a = (1.0 - p) / 2.0
    return (float(stats.chi2.ppf(a, n * dof)) / n, float(stats.chi2.ppf(1.0 - a, n * dof)) / n)


def _truth_nll(result, truth) -> tuple[float, float]:
    """(J_truth, mean position NEES) of a replay's trajectory at the truth times (module doc)."""
    tr = result.trajectory
    j, ok = causal_index(tr["t"].to_numpy(float), truth["t"].to_numpy(float))
    j = j[ok]
    if not len(j):
        return math.nan, math.nan
    e = tr[["x", "y"]].to_numpy(float)[j] - truth[["x", "y"]].to_numpy(float)[ok]
    a, b, c = (tr[k].to_numpy(float)[j] for k in ("var_x", "cov_xy", "var_y"))
    det = a * c - b * b
    if not np.all(det > 0):
        return math.nan, math.nan
    nees = (c * e[:, 0] ** 2 - 2 * b * e[:, 0] * e[:, 1] + a * e[:, 1] ** 2) / det   # eᵀP⁻¹e, 2×2 inverse
    nll = 0.5 * (nees + np.log(det) + 2 * _LOG_2PI)
    if "heading" in truth and np.isfinite(truth["heading"].to_numpy(float)[ok]).all():
        # the heading as a term of its own: the trajectory keeps no position-heading covariance
        eh = np.angle(np.exp(1j * (tr["heading"].to_numpy(float)[j] - truth["heading"].to_numpy(float)[ok])))
        vh = tr["var_heading"].to_numpy(float)[j]
        if np.all(vh > 0):
            nll = nll + 0.5 * (eh ** 2 / vh + np.log(vh) + _LOG_2PI)
    return float(np.mean(nll)), float(np.mean(nees))


def _logs(log) -> list[Log]:
    """``log`` as a non-empty list of logs (one Log, or several)."""
    logs = [log] if isinstance(log, Log) else list(log)
    if not logs or not all(isinstance(g, Log) for g in logs):
        raise ValueError(f"log = {log!r:.80}: must be a Log or a non-empty sequence of Logs")
    return logs


def consistency(log, settings: LocalizerSettings, noise: NoiseOverrides | None = None, *,
                use_truth: bool = True) -> dict:
    """Replay ``log`` (one :class:`~safenav.logs.Log` or several, pooled) with
    ``settings`` and ``noise`` and measure: per observation kind the mean
    NIS, its dimension, count and 95 % band; the objective terms J_inn and
    (with truth) J_truth; RMSE and mean position NEES against the truth."""
    parts = [_consistency_one(g, settings, noise, use_truth) for g in _logs(log)]
    if len(parts) == 1:
        return parts[0]
    out = {"started": all(p["started"] for p in parts), "nis": {},
           "n_innovations": sum(p["n_innovations"] for p in parts)}
    for kind in sorted({k for p in parts for k in p["nis"]}):
        got = [p["nis"][kind] for p in parts if kind in p["nis"]]
        n = sum(g["n"] for g in got)
        dof = sum(g["dof"] * g["n"] for g in got) / n
        out["nis"][kind] = {"mean": sum(g["mean"] * g["n"] for g in got) / n, "dof": dof, "n": n,
                            "band": _chi2_band(n, dof)}

    def pooled(key, weight, square=False):
        got = [(p[key], p[weight]) for p in parts if math.isfinite(p.get(key, math.nan)) and p[weight] > 0]
        w = sum(n for _, n in got)
        if not got or len(got) < len(parts):
            return math.nan
        v = sum((x * x if square else x) * n for x, n in got) / w
        return math.sqrt(v) if square else v

    out["j_inn"] = pooled("j_inn", "n_innovations")
    if all("rmse" in p for p in parts):
        n = sum(p["n_scored"] for p in parts)
        out.update(j_truth=pooled("j_truth", "n_scored"), rmse=pooled("rmse", "n_scored", square=True),
                   nees=pooled("nees", "n_scored"), nees_dof=2, n_scored=n, nees_band=_chi2_band(n, 2))
    return out


def _consistency_one(log: Log, settings: LocalizerSettings, noise, use_truth: bool) -> dict:
    """:func:`consistency` of one log."""
    res = replay((noise or NoiseOverrides()).apply(log), settings, innovations=True)
    inn = res.innovations
    inn = inn[np.isfinite(inn["nis"].to_numpy(float)) & np.isfinite(inn["logdet_s"].to_numpy(float))]
    out = {"started": res.estimated, "nis": {}, "n_innovations": len(inn)}
    for kind, g in inn.groupby("kind", sort=True):
        dof = float(g["dim"].mean())
        out["nis"][kind] = {"mean": float(g["nis"].mean()), "dof": dof, "n": len(g),
                            "band": _chi2_band(len(g), dof)}
    terms = inn["nis"].to_numpy(float) + inn["logdet_s"].to_numpy(float) + inn["dim"].to_numpy(float) * _LOG_2PI
    out["j_inn"] = float(np.mean(0.5 * terms)) if len(inn) else math.nan
    if use_truth and log.truth is not None and res.estimated:
        out["j_truth"], _ = _truth_nll(res, log.truth)
        m = res.metrics
        out.update(rmse=m["truth_rmse"], nees=m["nees"], nees_dof=m["nees_dof"], n_scored=m["n_scored"],
                   nees_band=_chi2_band(m["n_scored"], m["nees_dof"]))
    return out


def _objective_value(c: dict, use_truth: bool) -> float:
    """J_inn (+ J_truth) of a :func:`consistency` dict; a large finite penalty when undefined."""
    j = c["j_inn"] + (c.get("j_truth", math.nan) if use_truth else 0.0)
    return j if math.isfinite(j) else _PENALTY


def _searched(logs: list[Log], settings: LocalizerSettings) -> list[tuple[str, float, float, float]]:
    """(name, start, low, high) of each searched parameter: the BMM process
    noise (bounds from BmmParams.params()) and the σ scale of each observation
    kind present in the log."""
    specs = {p.name: p for p in _core.BmmParams.params()}
    out = []
    for name in PROCESS_NOISE:
        sp = specs[name]
        lo = max(sp.lo, FLOOR_SHARE * sp.hi)
        out.append((name, float(np.clip(settings.bmm.get_param(name), lo, sp.hi)), lo, sp.hi))
    present = {"range": any(np.isfinite(g.events["range"].to_numpy(float)).any() for g in logs),
               "bearing": any(np.isfinite(g.events["bearing"].to_numpy(float)).any() for g in logs),
               "fix": any(bool((g.events["kind"] == "fix").any()) for g in logs)}
    out += [(f"{k}_std_scale", 1.0, *SCALE_RANGE) for k in _OBS if present[k]]
    return out


def _candidate(settings: LocalizerSettings, noise: NoiseOverrides, names, values):
    """Copies of ``settings`` and ``noise`` with the searched ``names`` set to ``values``."""
    s = _copy_settings(settings)
    changed = {}
    for name, v in zip(names, values):
        if name in PROCESS_NOISE:
            s.bmm.set_param(name, float(v))
            continue
        absolute = name.replace("_scale", "")       # an absolute σ in the start is scaled itself
        key = absolute if getattr(noise, absolute) is not None else name
        changed[key] = float(v) * getattr(noise, key)
    return s, dataclasses.replace(noise, **changed)


def _copy_settings(settings: LocalizerSettings) -> LocalizerSettings:
    """A copy of ``settings`` (its attributes are references into it), through the preset tables."""
    return _settings_from_tables(_settings_tables(settings), "settings")


def _scale_line_search(objective, x0: np.ndarray, scales: list[int], bounds) -> np.ndarray:
    """A start for the search: all observation σ scales times 3^k together,
    k chosen by a line search.  Under-stated σ keep the localizer from
    starting from the data (its fit's residuals, in σ, exceed the limit),
    which leaves the objective flat: the search first climbs in σ until the
    replay starts, then walks either way while J falls."""
    if not scales:
        return x0
    step = np.zeros_like(x0)
    step[scales] = math.log(3.0)
    lo, hi = np.array([b[0] for b in bounds]), np.array([b[1] for b in bounds])
    best_x, best_j = x0, objective(x0)
    for _ in range(4):                      # climb until it starts
        if best_j < _PENALTY:
            break
        best_x = np.clip(best_x + step, lo, hi)
        best_j = objective(best_x)
    for direction in (step, -step):
        for _ in range(3):
            x = np.clip(best_x + direction, lo, hi)
            j = objective(x)
            if not j < best_j:
                break
            best_x, best_j = x, j
    return best_x


def tune(log, settings: LocalizerSettings | None = None, *, noise: NoiseOverrides | None = None,
         use_truth="auto", base: str = "default", max_evaluations: int = 150) -> TuneResult:
    """Estimate the process noise and the observation σ of ``log`` (module
    doc; a :class:`~safenav.logs.Log`, or several runs of one vehicle,
    whose objectives are pooled), starting from ``settings`` (default: the
    ``base`` preset) and ``noise`` (default: the log's own σ).
    ``use_truth``: "auto" (truth-based when every log has truth), True
    (requires truth) or False (innovation-only)."""
    log = _logs(log)
    has_truth = all(g.truth is not None for g in log)
    if use_truth == "auto":
        use_truth = has_truth
    elif use_truth is not True and use_truth is not False:
        raise ValueError(f"use_truth = {use_truth!r}: must be 'auto', True or False")
    if use_truth and not has_truth:
        raise ValueError("use_truth = True: a log has no truth rows")
    if isinstance(max_evaluations, bool) or not isinstance(max_evaluations, int) or max_evaluations < 1:
        raise ValueError(f"max_evaluations = {max_evaluations!r}: must be an integer >= 1")
    settings = _copy_settings(settings if settings is not None else preset_settings(base))
    noise = noise or NoiseOverrides()
    space = _searched(log, settings)
    names = [s[0] for s in space]
    # scales are relative to the start's overrides: search them around 1
    x0 = np.log([s[1] for s in space])
    bounds = [(math.log(s[2]), math.log(s[3])) for s in space]
    count = [0]

    def objective(z):
        count[0] += 1
        cand = _candidate(settings, noise, names, np.exp(z))
        return _objective_value(consistency(log, *cand, use_truth=use_truth), use_truth)

    x0 = _scale_line_search(objective, x0, [i for i, n in enumerate(names) if n.endswith("_scale")], bounds)
    simplex = np.vstack([x0] + [x0 + math.log(3.0) * np.eye(len(x0))[i] for i in range(len(x0))])
    simplex = np.clip(simplex, [b[0] for b in bounds], [b[1] for b in bounds])
    opt = optimize.minimize(objective, x0, method="Nelder-Mead", bounds=bounds,
                            options={"maxfev": max_evaluations, "initial_simplex": simplex,
                                     "xatol": 0.01, "fatol": 1e-4})
    best_s, best_n = _candidate(settings, noise, names, np.exp(opt.x))
    keys = [n if n in PROCESS_NOISE or getattr(noise, n.replace("_scale", "")) is None
            else n.replace("_scale", "") for n in names]
    start = {n: (settings.bmm.get_param(n) if n in PROCESS_NOISE else getattr(noise, n)) for n in keys}
    found = {n: (best_s.bmm.get_param(n) if n in PROCESS_NOISE else getattr(best_n, n)) for n in keys}
    # reported against the truth wherever the log has it, even when the search did not use it
    return TuneResult(settings=best_s, noise=best_n, parameters=found, start=start,
                      method="truth-based" if use_truth else "innovation-only",
                      before=consistency(log, settings, noise), after=consistency(log, best_s, best_n),
                      evaluations=count[0], base=base, message=str(opt.message))


def _consistency_line(label: str, c: dict) -> str:
    if not c["started"]:
        return f"  {label}: the localizer never started from the data (no innovations)"
    parts = [f"{k} NIS {v['mean']:.2f} (dof {v['dof']:g}, 95% band {v['band'][0]:.2f}-{v['band'][1]:.2f}, "
             f"n {v['n']})" for k, v in c["nis"].items()]
    if "nees" in c:
        lo, hi = c["nees_band"]
        parts.append(f"position NEES {c['nees']:.2f} (dof 2, band {lo:.2f}-{hi:.2f} if independent), "
                     f"RMSE {c['rmse']:.3f} m")
    return f"  {label}: " + "; ".join(parts)


def report(result: TuneResult) -> str:
    """The text report of a :func:`tune` result: method, parameters, consistency before and after."""
    how = ("truth-based: innovation likelihood + likelihood of the true poses (Mehra 1970; Abbeel et al. 2005)"
           if result.method == "truth-based" else "innovation-only: innovation likelihood (Mehra 1970)")
    lines = [f"method: {how}; {result.evaluations} replays ({result.message})", "parameters (start -> tuned):"]
    units = {p.name: p.unit for p in _core.BmmParams.params()}
    for name, v in result.parameters.items():
        unit = f" {units[name]} per step of {result.settings.bmm.dt:g} s" if name in units else ""
        lines.append(f"  {name:>17} {result.start[name]:.4g} -> {v:.4g}{unit}")
    lines += ["consistency:", _consistency_line("before", result.before), _consistency_line("after", result.after)]
    return "\n".join(lines)


# --------------------------------------------------------------------------- preset files

#: LocalizerSettings declares its nested structs' parameters too (bmm_*, augment_*, filter_*); a preset
#: keeps each in its own table, once, so that an edit in one table is never overridden by another.
_NESTED_PREFIXES = ("bmm_", "augment_", "filter_")


def _table_params() -> dict[str, list[str]]:
    """The declared parameters each preset table holds (gate_probability in [localizer], as documented)."""
    return {"filter": [p.name for p in _core.FilterOptions.params() if p.name != "gate_probability"],
            "bmm": [p.name for p in _core.BmmParams.params()],
            "localizer": [p.name for p in LocalizerSettings.params() if not p.name.startswith(_NESTED_PREFIXES)],
            "augment": [p.name for p in _core.AugmentedStates.params()]}


def _settings_tables(settings: LocalizerSettings) -> dict:
    """The preset tables of ``settings``: every declared parameter by name, once, the filter type and
    seed, and the augmented states."""
    f = settings.filter
    aug = settings.augment
    names = _table_params()
    return {
        "filter": {"type": f.type.name.lower(), "seed": int(f.seed), **{n: f.get_param(n) for n in names["filter"]}},
        "bmm": {n: settings.bmm.get_param(n) for n in names["bmm"]},
        "localizer": {n: settings.get_param(n) for n in names["localizer"]},
        "augment": {"states": [n for n in ("range_scale", "heading_rate_bias", "range_bias") if getattr(aug, n)],
                    **{n: aug.get_param(n) for n in names["augment"]}},
    }


def _set(obj, table: str, key: str, value, where: str) -> None:
    """``obj.set_param(key, value)`` with an error naming the file, table and key."""
    try:
        obj.set_param(key, value)
    except (ValueError, TypeError, KeyError, IndexError) as exc:
        raise ValueError(f"{where}: [{table}] {key} = {value!r}: {exc}") from None


def _known(table: str, data: dict, keys, where: str) -> None:
    for k in data:
        if k not in keys:
            raise ValueError(f"{where}: [{table}] {k!r} is not a known key (known: {sorted(keys)})")


def _settings_from_tables(tables: dict, where: str) -> LocalizerSettings:
    """:class:`LocalizerSettings` from preset tables (each key optional; the rest default)."""
    s = LocalizerSettings()
    names = _table_params()
    f = dict(tables.get("filter", {}))
    _known("filter", f, ["type", "seed", *names["filter"]], where)
    if "type" in f:
        types = {k.lower(): v for k, v in FILTERS.items()}
        if f["type"] not in types:
            raise ValueError(f"{where}: [filter] type = {f['type']!r}: must be one of {sorted(types)}")
        s.filter.type = types[f.pop("type")]
    if "seed" in f:   # 64 bits: not a declared (double) parameter
        seed = f.pop("seed")
        if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**64:
            raise ValueError(f"{where}: [filter] seed = {seed!r}: must be an integer in [0, 2**64)")
        s.filter.seed = seed
    for table, obj in (("filter", s.filter), ("bmm", s.bmm), ("localizer", s)):
        data = f if table == "filter" else tables.get(table, {})
        _known(table, data, names[table], where)
        for k, v in data.items():
            _set(obj, table, k, v, where)
    aug = dict(tables.get("augment", {}))
    states = aug.pop("states", [])
    _known("augment", aug, names["augment"], where)
    if not isinstance(states, list) or any(n not in ("range_scale", "heading_rate_bias", "range_bias") for n in states):
        raise ValueError(f"{where}: [augment] states = {states!r}: must be a list of range_scale, "
                         "heading_rate_bias, range_bias")
    for n in states:
        setattr(s.augment, n, True)
    for k, v in aug.items():
        _set(s.augment, "augment", k, v, where)
    try:
        s.validate()
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None
    return s


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return repr(float(v)) if math.isfinite(v) else ("nan" if math.isnan(v) else ("inf" if v > 0 else "-inf"))
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"no TOML form for {v!r}")


def save_preset(path, settings: LocalizerSettings, noise: NoiseOverrides | None = None, *, base: str = "default",
                comment: str = "") -> Path:
    """Write ``settings`` and ``noise`` as a preset file (TOML; the format is in
    ``docs/tuning.md``) through the one atomic writer
    (:func:`safenav.results.write_text`).  ``comment`` lines head the file."""
    from .results import write_text

    tables = {"preset": {"format": PRESET_FORMAT, "version": PRESET_VERSION, "base": base},
              **_settings_tables(settings), "observations": (noise or NoiseOverrides()).as_dict()}
    lines = [f"# {c}".rstrip() for c in comment.splitlines()]
    for name, data in tables.items():
        lines.append(f"\n[{name}]")
        lines += [f"{k} = {_toml_value(v)}" for k, v in data.items()]
    return write_text(path, "\n".join(lines).lstrip("\n") + "\n")


def is_preset_file(name) -> bool:
    """Whether ``name`` names a preset file (a .toml or .json path) rather than a named preset."""
    return Path(str(name)).suffix.lower() in (".toml", ".json")


def _read_tables(path: Path) -> dict:
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ValueError(f"preset file {path}: {exc.strerror or exc}") from None
    try:
        data = json.loads(text) if path.suffix.lower() == ".json" else tomllib.loads(text)
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path}: not a valid {path.suffix.lstrip('.').upper()} file: {exc}") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: a preset file holds tables, got {type(data).__name__}")
    return data


def load_preset(path) -> tuple[LocalizerSettings, NoiseOverrides]:
    """(settings, observation σ overrides) of a preset file written by
    :func:`save_preset` (TOML, or JSON with the same tables).  Errors name the
    file, the table and the key."""
    path = Path(path)
    data = _read_tables(path)
    where = str(path)
    tables = ("preset", "filter", "bmm", "localizer", "augment", "observations")
    for t, v in data.items():
        if t not in tables:
            raise ValueError(f"{where}: [{t}] is not a known table (known: {list(tables)})")
        if not isinstance(v, dict):
            raise ValueError(f"{where}: {t} must be a table, got {v!r}")
    head = data.get("preset")
    if head is None:
        raise ValueError(f"{where}: missing table [preset] (format = {PRESET_FORMAT!r}, version = {PRESET_VERSION})")
    for key, want in (("format", PRESET_FORMAT), ("version", PRESET_VERSION)):
        if key not in head:
            raise ValueError(f"{where}: [preset] is missing the key {key!r} (= {want!r})")
        if head[key] != want or isinstance(head[key], bool):
            raise ValueError(f"{where}: [preset] {key} = {head[key]!r}: must be {want!r}")
    _known("preset", head, ("format", "version", "base"), where)
    if "bmm" not in data:
        raise ValueError(f"{where}: missing table [bmm] (the process noise: {', '.join(PROCESS_NOISE)})")
    missing = [k for k in PROCESS_NOISE if k not in data["bmm"]]
    if missing:
        raise ValueError(f"{where}: [bmm] is missing the key {missing[0]!r}")
    settings = _settings_from_tables(data, where)
    obs = data.get("observations", {})
    _known("observations", obs, [f.name for f in dataclasses.fields(NoiseOverrides)], where)
    try:
        noise = NoiseOverrides(**obs)
    except ValueError as exc:
        raise ValueError(f"{where}: [observations] {exc}") from None
    return settings, noise


def preset_base(path) -> str:
    """The ``base`` named preset recorded in a preset file ("default" when absent)."""
    return str(_read_tables(Path(path)).get("preset", {}).get("base", "default"))
