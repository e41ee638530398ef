"""The ``safenav`` command line."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np


def _synthetic(args) -> int:
    from .experiments import run_synthetic, summarize_synthetic

    raw = run_synthetic(args.trials, filters=args.filters, seed=args.seed, n_particles=args.particles)
    table = summarize_synthetic(raw)
    print(f"Synthetic data set (SafeNav V-A), LanBLoc-BMM, {args.trials} trials, seed {args.seed}; "
          f"time = median per trial")
    print(table.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    if args.out:
        from .runner import write_table

        out = Path(args.out)
        write_table(raw, out / "synthetic_trials", parquet=False)
        write_table(table, out / "synthetic_summary", parquet=False)
        fig = _synthetic_figure(args, out / "synthetic_trial.png")
        print(f"wrote {out / 'synthetic_trials.csv'}, {out / 'synthetic_summary.csv'} and {fig}")
    return 0


def _synthetic_figure(args, path: Path) -> Path:
    """Figure of trial 0 (same seeds as the Monte Carlo's first trial)."""
    from .experiments import synthetic_trial
    from .plots import plot_synthetic_trial

    data, results = synthetic_trial(0, filters=args.filters, seed=args.seed, n_particles=args.particles)
    return plot_synthetic_trial(data, {k.upper(): v for k, v in results.items()}, path)


def _load(args):
    from .scenario import default_scenario, load_scenario

    return default_scenario() if args.scenario in (None, "default") else load_scenario(args.scenario)


def _navigation(args, *, demo: bool) -> int:
    """Plan the safe paths, run the Monte Carlo sweep, print the paper's
    Tables III/IV layouts, write the raw and summary tables and Figs. 4-5."""
    import time

    from . import navigation as nv
    from . import runner
    from .experiments import markdown_table, navigation_table, percent_error_table
    from .reproduce import navigation_figures

    t0 = time.perf_counter()
    scenario = _load(args)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    sweep = runner.Sweep(scenario, path_types=tuple(args.path_types or ()), methods=tuple(args.methods),
                         filters=tuple(args.filters), sources=tuple(args.sources), trials=args.trials,
                         seed=args.seed if args.seed is not None else scenario.seeds.trials,
                         n_particles=args.particles,
                         position_every=args.position_every or (10 if "lanbloc-camera" in args.sources else 1))
    print(f"safenav {'demo' if demo else 'run'}: scenario {scenario.name!r}, path types {list(sweep.path_types)}, "
          f"{sweep.trials} trials per cell, seed {sweep.seed}")
    safe = runner.plan_safe_paths(scenario, sweep.path_types)
    t_plan = time.perf_counter() - t0
    for name, path in safe.items():
        from .metrics import path_length
        print(f"  safe path {name}: RAw-RRT*, {len(path)} waypoints, {path_length(path):.1f} m")
    raw = runner.run_sweep(sweep, workers=args.workers, scheduler=args.scheduler, safe_paths=safe,
                           progress=not args.quiet)
    t_run = time.perf_counter() - t0 - t_plan
    summary = runner.summarize(raw)
    written = runner.write_table(raw, out / "trials")
    written += runner.write_table(summary, out / "summary", parquet=False)
    for (filt, source), part in summary.groupby(["filter", "source"], sort=False):
        label = (f"LanBLoc-BMM({filt.upper()})" if source == "lanbloc" else
                 f"LanBLoc camera loop, {filt.upper()}" if source == "lanbloc-camera" else
                 f"{nv.SOURCES[source].label}, {filt.upper()}")
        pe = percent_error_table(part)
        nt = navigation_table(part)
        fmt = lambda v: f"{v:.3g}"  # noqa: E731
        print(f"\n% path-length error (eq. 23), {label}; paper = SafeNav Table IV (extended version)")
        print(pe.to_string(index=False, float_format=fmt))
        print(f"\nADE / FDE [m], AWRS, median time per trial, {label}; paper = SafeNav Table V (extended version)")
        print(nt.to_string(index=False, float_format=fmt))
        tag = f"{filt}_{source}"
        for name, df in ((f"table_percent_error_{tag}", pe), (f"table_navigation_{tag}", nt)):
            written += runner.write_table(df, out / name, parquet=False)
            text = markdown_table(df)
            written.append(runner.atomic_write(out / f"{name}.md", lambda p: Path(p).write_text(text)))
    failures = raw[~raw["success"]]
    if len(failures):
        print(f"\n{len(failures)} of {len(raw)} trials did not arrive: "
              + ", ".join(f"{k} {v}" for k, v in failures["outcome"].value_counts().items()))
    # Figs. 4 and 5: one recorded trial (trial 0) per method and path type.
    figs = navigation_figures(scenario, safe, sweep, out)
    total = time.perf_counter() - t0
    print(f"\nplanning {t_plan:.1f} s, {len(raw)} trials {t_run:.1f} s, total {total:.1f} s")
    print("wrote " + ", ".join(str(p) for p in [*written, *figs]))
    return 0


def _plan(args) -> int:
    import json

    from . import navigation as nv
    from .metrics import path_length
    from .plots import plot_navigation

    scenario = _load(args)
    names = args.path_types or [p.name for p in scenario.path_types]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    result, trials = {}, {}
    for name in names:
        r = nv.plan_safe_path(scenario, name, iterations=args.iterations)
        path = np.asarray(r.path)
        result[name] = {"path": path.round(4).tolist(), "length_m": path_length(path), "risk": r.cost.risk,
                        "cost": r.cost.total, "iterations": int(r.iterations)}
        print(f"{name}: {len(path)} waypoints, length {path_length(path):.1f} m, risk {r.cost.risk:.2f}, "
              f"cost {r.cost.total:.1f} ({r.iterations} iterations)")
        navigator = nv.make_navigator(scenario, path, method="chull")
        trials[name] = (navigator, navigator.run(0))
    tmp = out / "safe_paths.json.tmp"
    tmp.write_text(json.dumps(result, indent=1))
    tmp.replace(out / "safe_paths.json")
    fig = plot_navigation(scenario, trials, out / "safe_paths.png", title=f"{scenario.name}: safe paths (RAw-RRT*)")
    print(f"wrote {out / 'safe_paths.json'} and {fig}")
    return 0


def _experiment(args) -> int:
    from . import reproduce

    opts = reproduce.ExperimentOptions(
        trials=args.trials, camera_trials=args.camera_trials, camera_position_every=args.position_every,
        particles=args.particles, workers=args.workers, scheduler=args.scheduler, seed=args.seed, out=args.out,
        scenario=_load(args), path_types=tuple(args.path_types or ()), placement=not args.no_placement,
        progress=not args.quiet)
    results = reproduce.run_experiments(args.names, opts)
    report = reproduce.write_report(results, opts)
    files = [f for r in results for f in (*r.files, *r.figures)]
    print(f"\nwrote {len(files)} files under {opts.out} and the report {report}")
    bad = [c for r in results for c in r.claims if c.holds is False]
    if bad:
        print(f"{len(bad)} of the paper's claims do not hold here (see the report)")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="safenav", description="GPS-denied safe navigation experiments.")
    sub = p.add_subparsers(dest="command", required=True)

    def navigation_options(s, *, demo: bool):
        s.add_argument("--trials", type=int, default=300 if demo else 1000,
                       help=f"Monte Carlo trials per path type and method (default {300 if demo else 1000})")
        s.add_argument("--methods", nargs="+", default=["chull", "centroid"], choices=["chull", "centroid"])
        s.add_argument("--filters", nargs="+", default=["ekf"], choices=["ekf", "pf"])
        s.add_argument("--sources", nargs="+", default=["lanbloc"],
                       choices=["lanbloc", "lanbloc-camera", "deeploc-gps", "deeploc-ekf-gps", "sensor-fusion"],
                       help="position source: LanBLoc at the measurement level, LanBLoc through the camera loop "
                            "(rendered stereo pairs, detection, SGBM, trilateration; slow), or an emulated baseline")
        s.add_argument("--position-every", type=int, default=None,
                       help="a position fix every n steps (default 1; 10 for lanbloc-camera)")
        s.add_argument("--path-types", nargs="+", default=None, help="default: all of the scenario's")
        s.add_argument("--particles", type=int, default=500, help="PF particles (default 500)")
        s.add_argument("--workers", type=int, default=None, help="local worker threads (default: all cores)")
        s.add_argument("--scheduler", default=None, help="Dask scheduler address: run the trials on that cluster")
        s.add_argument("--seed", type=int, default=None, help="trial seed (default: the scenario's seeds.trials)")
        s.add_argument("--out", default="out/demo" if demo else "out/run", help="output folder")
        s.add_argument("--quiet", action="store_true", help="no progress bar")
        s.set_defaults(func=lambda a: _navigation(a, demo=demo))

    s = sub.add_parser("demo", help="the main job: SafeNav-CHull and SafeNav-Centroid with LanBLoc-BMM(EKF) on "
                                    "the default scenario's three path types, beside the paper's Tables III-IV")
    s.set_defaults(scenario=None)
    navigation_options(s, demo=True)

    s = sub.add_parser("run", help="run a scenario file's navigation sweep")
    s.add_argument("scenario", help="scenario .toml or .json ('default' = the built-in one)")
    navigation_options(s, demo=False)

    s = sub.add_parser("plan", help="plan and draw the safe paths of a scenario (RAw-RRT*)")
    s.add_argument("scenario", nargs="?", default="default", help="scenario .toml or .json (default: built-in)")
    s.add_argument("--path-types", nargs="+", default=None)
    s.add_argument("--iterations", type=int, default=None, help="RAw-RRT* iterations (default: the scenario's)")
    s.add_argument("--out", default="out/plan")
    s.set_defaults(func=_plan)

    s = sub.add_parser("synthetic", help="filter the synthetic data set (SafeNav V-A) with EKF and PF")
    s.add_argument("--trials", type=int, default=100, help="Monte Carlo trials (default 100)")
    s.add_argument("--filters", nargs="+", default=["ekf", "pf"], choices=["ekf", "pf", "eif"])
    s.add_argument("--particles", type=int, default=1000, help="PF particles (default 1000)")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--out", default=None, help="folder for the per-trial and summary CSV files and a figure")
    s.set_defaults(func=_synthetic)

    s = sub.add_parser("experiment", help="reproduce the SafeNav paper's tables and figures, with a report.html",
                       description="Experiments: all, field (Fig. 1), synthetic (Table I, Fig. 3), real-imitated "
                                   "(Table II), navigation (Tables III-IV, Figs. 4-5); the paper's names "
                                   "table1..table4, fig1, fig3, fig4, fig5 work too.")
    s.add_argument("names", nargs="+", metavar="NAME", help="experiment name(s), or 'all'")
    s.add_argument("--trials", type=int, default=1000, help="Monte Carlo trials per cell (default 1000, as the paper)")
    s.add_argument("--camera-trials", type=int, default=20,
                   help="trials per cell of the camera-in-the-loop variants of Tables II and IV (default 20; 0 = skip)")
    s.add_argument("--position-every", type=int, default=10, help="camera loop: a fix every n steps (default 10)")
    s.add_argument("--particles", type=int, default=1000, help="PF particles (default 1000)")
    s.add_argument("--no-placement", action="store_true",
                   help="skip Table II's variant with landmarks placed along the safe paths (ILP, ~1 min)")
    s.add_argument("--path-types", nargs="+", default=None, help="default: all of the scenario's")
    s.add_argument("--workers", type=int, default=None, help="local worker threads (default: all cores)")
    s.add_argument("--scheduler", default=None, help="Dask scheduler address: run the trials on that cluster")
    s.add_argument("--seed", type=int, default=None, help="base seed (default: the scenario's seeds.trials)")
    s.add_argument("--scenario", default=None, help="scenario .toml or .json (default: the built-in one)")
    s.add_argument("--out", default="out/experiments", help="output folder (default out/experiments)")
    s.add_argument("--quiet", action="store_true", help="no progress bars")
    s.set_defaults(func=_experiment)

    from .placement_cli import register as register_place
    register_place(sub)
    return p


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (ValueError, RuntimeError, OSError) as exc:
        print(f"safenav: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
