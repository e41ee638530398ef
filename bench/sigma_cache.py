"""The σ-profile calibration of bench_certified.py, with the Monte Carlo cached.

The trials of a cell do not depend on the belief: only the prediction does.
So each cell's recorded trials are run once (``record``), and their
squared-error sums and step counts per arc-length bin are cached; a change
to the belief model is then scored against the cache in seconds
(``score``), through ``sigma_calibration``'s own ``_calibration``.

A cell is ``W:P:M:F``: the world (``d`` for the default, or a generated
world's seed), the path type, the method (``chull`` / ``centroid``) and the
measurements (``clean`` / ``faulty``).  Its scenario and path are those of
bench_certified.py: each world's path types certified with the belief
planner and driven in the world with every proposed landmark.  The
certified paths are cached per world the first time (``world_W.pkl``), so
that the cached trials stay those of the same path when the model changes
(the certificate's planner depends on it).  The trial seeds are
bench_certified's (``runner.trial_seeds(sc.seeds.trials, stream, n)``):
with ``--trials 10000`` a cell's figures are those of ``--recheck 10000``.
The cache also keeps each trial's outcome, guard-hold steps, steps and
least clearance. ``--filter pf`` drives the cell with the particle filter
(cached apart); the prediction is the same for both filters.

    python bench/sigma_cache.py record 13:P3:centroid:faulty [--trials 10000] [--filter ekf] [--cache DIR] [--workers 2]
    python bench/sigma_cache.py score  13:P3:centroid:faulty ... [--filter ekf] [--cache DIR] [--save FILE] [--base FILE]
    python bench/sigma_cache.py predict --worlds d 13 17 23 29 31 37 [--save FILE] [--base FILE]

``score`` prints each cell's kept bins' ratio range (MC RMS / predicted),
the bins outside ±25 % and the trials' outcomes, then the share of all
bins within the band, clean and faulty apart; ``predict`` prints no ratio,
only how far each cell's predicted bins moved against ``--base`` (a file
that ``--save`` wrote), to find the cells that a change moves and that
need a Monte Carlo.
"""

from __future__ import annotations

import argparse
import pickle
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_certified import (METHODS, TARGET_RATIO, _kept_bins, _out_of_band, certify_one, nominal_profile,  # noqa: E402
                             print_certificates, worlds)
from bench_safety import faulty  # noqa: E402

from safenav import navigation as nav  # noqa: E402
from safenav import results, runner  # noqa: E402
from safenav.belief import _calibration, binned_trials, calibration_edges, sigma_calibration  # noqa: E402
from safenav.generate import DEFAULT_SEED  # noqa: E402

BIN_M = 10.0
BATCH = 250
#: What the cache keeps of each trial besides its bin sums.
TRIAL = ("outcome", "guard_hold", "steps", "min_clearance")


def _world_key(w: str) -> str:
    return f"default({DEFAULT_SEED})" if w == "d" else f"seed {int(w)}"


def world(w: str, cache: Path) -> dict:
    """{"scenario": the driven scenario, "paths": {name: (stream, path)}} of world ``w``, certified once."""
    f = cache / f"world_{w}.pkl"
    if f.exists():
        return pickle.loads(f.read_bytes())
    sc = worlds([] if w == "d" else [int(w)], gap=False)[_world_key(w)]
    missions = [certify_one((_world_key(w), sc, i, p.name)) for i, p in enumerate(sc.path_types)]
    driven = print_certificates(missions)[_world_key(w)]
    out = {"scenario": driven, "paths": {m.cert.name: (m.stream, np.asarray(m.cert.path)) for m in missions
                                         if len(m.cert.path)}}
    results.atomic_write(f, lambda fh: pickle.dump(out, fh))
    return out


def cell(spec: str, cache: Path):
    """(scenario as measured, stream, path, method) of ``W:P:M:F``."""
    try:
        w, p, m, f = spec.split(":")
    except ValueError:
        raise SystemExit(f"cell {spec!r}: expected W:P:M:F, e.g. 13:P3:centroid:faulty") from None
    if m not in METHODS or f not in ("clean", "faulty"):
        raise SystemExit(f"cell {spec!r}: method must be one of {METHODS}, measurements clean or faulty")
    wd = world(w, cache)
    if p not in wd["paths"]:
        raise SystemExit(f"cell {spec!r}: world {w} has no certified path {p!r} (has {sorted(wd['paths'])})")
    stream, path = wd["paths"][p]
    sc = wd["scenario"] if f == "clean" else faulty(wd["scenario"])
    return sc, stream, path, m


def _batch(job) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The batch's per-trial bin sums and step counts, and per trial its outcome, guard-hold steps, steps
    and least clearance (the ``TRIAL`` columns)."""
    spec, cache, seeds, edges, nominal_xy, filt = job
    sc, _, path, m = cell(spec, cache)
    rec = nav.make_navigator(sc, path, method=m, filter=filt, record=True)
    runs = [rec.run(int(s)) for s in seeds]
    sq, n = binned_trials(nominal_xy, edges, [r.truth for r in runs], [r.estimate for r in runs])
    trial = np.array([(int(r.outcome), r.guard_hold, r.steps, r.metrics["min_clearance"]) for r in runs],
                     dtype=float).reshape(-1, len(TRIAL))
    return sq, n, trial


def _cached(spec: str, cache: Path, trials: int, filt: str) -> Path:
    """The cache file of the cell's first ``trials`` trials with filter ``filt`` (the EKF's unmarked)."""
    return cache / f"mc_{spec.replace(':', '_')}{'' if filt == 'ekf' else '_' + filt}_{trials}.npz"


def record(spec: str, trials: int, cache: Path, workers: int, filt: str = "ekf") -> Path:
    """Run the cell's first ``trials`` recorded trials and cache their per-bin sums."""
    sc, stream, path, m = cell(spec, cache)
    rec = nav.make_navigator(sc, path, method=m, filter=filt, record=True)
    nominal_xy = np.asarray(rec.nominal_trajectory(), dtype=float)[:, :2]
    edges = calibration_edges(nominal_xy, BIN_M)
    seeds = runner.trial_seeds(sc.seeds.trials, stream, trials)
    jobs = [(spec, cache, seeds[a:a + BATCH], edges, nominal_xy, filt) for a in range(0, trials, BATCH)]
    parts = runner.map_ordered(_batch, jobs, workers=workers, processes=workers > 1)
    f = _cached(spec, cache, trials, filt)
    trial = np.concatenate([c for _, _, c in parts])
    results.atomic_write(f, lambda fh: np.savez(fh, sq=np.concatenate([a for a, _, _ in parts]),
                                               n=np.concatenate([b for _, b, _ in parts]), edges=edges,
                                               nominal_xy=nominal_xy, **dict(zip(TRIAL, trial.T))))
    return f


def outcomes(mc) -> str:
    """The cached trials' collisions, arrivals, other outcomes, guard holds and least clearance (a cache
    recorded before these were kept: empty)."""
    if "outcome" not in mc:
        return ""
    o = np.asarray([nav.OUTCOMES[k] for k in mc["outcome"].astype(int)])
    other = {k: int(np.sum(o == k)) for k in np.unique(o) if k not in ("arrived", "collision")}
    return (f"  [coll {int(np.sum(o == 'collision'))}, arrived {int(np.sum(o == 'arrived'))}/{len(o)}"
            + "".join(f", {k} {v}" for k, v in other.items())
            + f", hold {int(np.sum(mc['guard_hold'] > 0))}, clearance min {np.nanmin(mc['min_clearance']):.2f} m]")


def predicted(spec: str, cache: Path, **belief):
    """The expected belief along the method's nominal run, as bench_certified's calibration takes it
    (``belief``: settings of the belief to change, e.g. ``deviation_free_strata``)."""
    sc, _, path, m = cell(spec, cache)
    return nominal_profile(sc, path, nav.make_navigator(sc, path, method=m, filter="ekf", record=True), **belief)


def predicted_bins(spec: str, cache: Path, **belief) -> np.ndarray:
    prof = predicted(spec, cache, **belief)
    return sigma_calibration(prof, [], [], bin_m=BIN_M).predicted


def score(spec: str, cache: Path, trials: int, filt: str = "ekf", **belief):
    """The cell's calibration against its cached trials with filter ``filt`` (the prediction is the same
    for both filters), and a line of their outcomes."""
    f = _cached(spec, cache, trials, filt)
    if not f.exists():
        raise SystemExit(f"{f}: no cached Monte Carlo; run `record {spec} --trials {trials} --filter {filt}` "
                         "first")
    mc = np.load(f)
    prof = predicted(spec, cache, **belief)
    if not np.array_equal(np.asarray(prof.positions)[:, :2], mc["nominal_xy"]):
        raise SystemExit(f"{spec}: the nominal run differs from the cached one; record it again")
    pred = sigma_calibration(prof, [], [], bin_m=BIN_M).predicted
    return _calibration(mc["edges"], pred, mc["sq"], mc["n"]), outcomes(mc)


def _line(spec: str, cal, trials: int, base=None) -> str:
    """The kept bins' ratio range and the bins outside the band; with ``base``
    (predicted bins of another build) the range that build's prediction gave."""
    kept = _kept_bins(cal, trials)
    r = cal.ratio[kept]
    out = [f"{cal.edges[b]:.0f} m {cal.ratio[b]:.2f}" for b in np.flatnonzero(_out_of_band(cal, trials))]
    s = f"{spec:26} {r.min():.2f}-{r.max():.2f}" + (f"  OUT: {', '.join(out)}" if out else "")
    if base is not None and spec in base and len(base[spec]) == len(cal.predicted):
        with np.errstate(invalid="ignore", divide="ignore"):
            rb = (cal.observed / np.asarray(base[spec]))[kept]
        s += f"   (base {np.nanmin(rb):.2f}-{np.nanmax(rb):.2f})"
    return s


def _summary(what: str, ratios: list[np.ndarray]) -> str:
    """The kept bins of ``ratios`` (one array per cell): their count, the share within ±25 %, and their
    least, median and greatest ratio."""
    r = np.concatenate(ratios)
    inside = np.abs(r - 1) <= TARGET_RATIO
    return (f"{what}: {len(ratios)} cells, {len(r)} bins, {100 * inside.mean():.1f} % within "
            f"±{100 * TARGET_RATIO:.0f} % ({np.count_nonzero(~inside)} outside); "
            f"min {r.min():.2f}, median {np.median(r):.2f}, max {r.max():.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("what", choices=("record", "score", "predict"))
    ap.add_argument("cells", nargs="*")
    ap.add_argument("--trials", type=int, default=10000)
    ap.add_argument("--cache", type=Path, default=Path("/tmp/safenav_sigma_cache"))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--filter", choices=("ekf", "pf"), default="ekf", help="the driven vehicles' filter "
                    "(record, score); the prediction is the same for both")
    ap.add_argument("--worlds", nargs="*", default=["d", "13", "17", "23", "29", "31", "37"])
    ap.add_argument("--save", type=Path, help="write each cell's predicted bins here (pickle)")
    ap.add_argument("--base", type=Path, help="predicted bins of another build (--save), to compare")
    ap.add_argument("--free", type=int, help="the mixture's free strata (deviation_free_strata; default: the "
                    "setting's)")
    ap.add_argument("--moved", type=float, default=0.05, help="predict: list cells whose bins moved more than this")
    a = ap.parse_args()
    a.cache.mkdir(parents=True, exist_ok=True)
    belief = {} if a.free is None else {"deviation_free_strata": a.free}
    base = pickle.loads(a.base.read_bytes()) if a.base else None
    saved = {}
    t = time.perf_counter()
    if a.what == "record":
        for spec in a.cells:
            print(f"{spec}: {record(spec, a.trials, a.cache, a.workers, a.filter)} "
                  f"({time.perf_counter() - t:.0f} s)",
                  flush=True)
    elif a.what == "score":
        ratios: dict[str, list[np.ndarray]] = {"clean": [], "faulty": []}
        for spec in a.cells:
            cal, trials = score(spec, a.cache, a.trials, a.filter, **belief)
            saved[spec] = cal.predicted
            ratios[spec.rsplit(":", 1)[-1]].append(cal.ratio[_kept_bins(cal, a.trials)])
            print(_line(spec, cal, a.trials, base) + trials, flush=True)
        for f, rs in ratios.items():
            if rs:
                print(_summary(f, rs))
    else:
        specs = a.cells or [f"{w}:{p}:{m}:{f}" for w in a.worlds for p in sorted(world(w, a.cache)["paths"])
                            for m in METHODS for f in ("clean", "faulty")]
        for spec in specs:
            t0 = time.perf_counter()
            saved[spec] = predicted_bins(spec, a.cache, **belief)
            moved = ""
            if base is not None and spec in base:
                b = np.asarray(base[spec])
                with np.errstate(invalid="ignore", divide="ignore"):
                    d = saved[spec][:len(b)] / b[:len(saved[spec])] - 1
                worst = np.nanargmax(np.abs(d)) if np.isfinite(d).any() else None
                if worst is not None and abs(d[worst]) > a.moved:
                    moved = f"  MOVED {100 * d[worst]:+.1f} % at {BIN_M * worst:.0f} m"
            print(f"{spec:26} {time.perf_counter() - t0:5.2f} s{moved}", flush=True)
    if a.save:
        results.atomic_write(a.save, lambda fh: pickle.dump(saved, fh))
    print(f"total {time.perf_counter() - t:.0f} s")


if __name__ == "__main__":
    main()
