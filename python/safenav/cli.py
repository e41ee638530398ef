"""The ``safenav`` command line.

One set of rules for every command:

* the scenario is ``--scenario PATH`` (omitted or ``default``: the built-in
  one); ``run`` and ``plan`` still take it as a positional argument too;
* ``--quiet`` and ``--verbose`` (see :mod:`safenav.console`): results go to
  standard output; status lines and progress to standard error;
* every argument is checked before any work starts: a bad one gives one
  ``safenav: error: ...`` line and exit status 2;
* output folders are written through :mod:`safenav.results` and end with
  ``manifest.json`` (``safenav verify FOLDER`` checks one);
* ``replay`` exits 3 when the localizer never started (its files are still
  written; the error line and ``replay.json`` say why);
* table numbers are the conference version's (I synthetic, II real-imitated,
  III % path-length error, IV ADE/FDE/AWRS/time); the extended version
  numbers them one higher.  Figure numbers are the extended version's
  (``docs/paper_map.md``).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import signal
import sys
import threading
from pathlib import Path

import numpy as np

from . import __version__, console, foxglove
from .results import RunFolder, verify_run, write_json, write_table
from .validation import arg_at_least, arg_probability

#: The paper's navigation tables, in the one numbering safenav uses (the conference version's).
TABLE_NUMBERING = "conference numbering; the extended version's Table {ext}"


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors: ``safenav: error: ...``, exit status 2."""

    def error(self, message):
        self.exit(2, f"safenav: error: {message}\n")


def _load(args):
    """The scenario of ``--scenario`` (or the positional one of ``run``/``plan``)."""
    from .scenario import default_scenario, load_scenario

    path = args.scenario
    positional = getattr(args, "scenario_file", None)
    if positional is not None:
        if path is not None and path != positional:
            raise ValueError(f"scenario given twice: {positional!r} and --scenario {path!r}")
        path = positional
    return default_scenario() if path in (None, "default") else load_scenario(path)


def _run_folder(args, out, *, seed=None) -> RunFolder:
    """The output folder of this command, with its manifest's command line and parameters."""
    params = {k: v for k, v in vars(args).items() if k not in ("func", "argv")}
    return RunFolder(out, command=["safenav", *args.argv], parameters=params, seed=seed)


def _wrote(run: RunFolder) -> None:
    console.info(f"wrote {len(run.files)} files and manifest.json under {run.folder}")
    console.detail("\n".join(f"  {f}" for f in sorted(run.files)))


# --------------------------------------------------------------------------- commands

def _synthetic(args) -> int:
    from .experiments import summarize_synthetic, synthetic_experiment
    from .results import write_table

    folder = _run_folder(args, args.out, seed=args.seed) if args.out else contextlib.nullcontext()
    with folder as run:
        raw = synthetic_experiment(args.trials, filters=args.filters, seed=args.seed, n_particles=args.particles,
                                   progress=True).raw
        table = summarize_synthetic(raw)
        print(f"Synthetic data set (SafeNav-ext §V-A3(i)), LanBLoc-BMM, {args.trials} trials, seed {args.seed}; "
              f"time = median per trial; paper = SafeNav Table I ({TABLE_NUMBERING.format(ext='II')})")
        print(table.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
        if args.out:
            out = Path(args.out)
            write_table(raw, out / "synthetic_trials", parquet=False)
            write_table(table, out / "synthetic_summary", parquet=False)
            with console.task("figure of trial 0"):
                _synthetic_figure(args, out / "synthetic_trial.png")
            _wrote(run)
    return 0


def _synthetic_figure(args, path: Path) -> Path:
    """Figure of trial 0 (same seeds as the Monte Carlo's first trial)."""
    from .experiments import synthetic_trial
    from .experiments.figures import plot_synthetic_trial

    data, results = synthetic_trial(0, filters=args.filters, seed=args.seed, n_particles=args.particles)
    return plot_synthetic_trial(data, {k.upper(): v for k, v in results.items()}, path)


def _navigation(args, *, demo: bool) -> int:
    """Plan the safe paths, run the Monte Carlo sweep, print the paper's
    Tables III and IV layouts, write the raw and summary tables and Figs. 4-5."""
    import time

    from . import navigation as nv
    from . import runner
    from .experiments import navigation_figures, navigation_table, percent_error_table
    from .experiments.figures import recorded_trials
    from .metrics import path_length
    from .results import write_table

    t0 = time.perf_counter()
    scenario = _load(args)
    if args.faults is not None:
        scenario = nv.with_faults(scenario, *args.faults)
    sweep = runner.Sweep(scenario, path_types=tuple(args.path_types or ()), methods=tuple(args.methods),
                         filters=tuple(args.filters), sources=tuple(args.sources), trials=args.trials,
                         seed=args.seed if args.seed is not None else scenario.seeds.trials,
                         n_particles=args.particles,
                         position_every=args.position_every or (10 if "lanbloc-camera" in args.sources else 1))
    out = Path(args.out)
    with runner.connect(args.scheduler) as client, _run_folder(args, out, seed=sweep.seed) as run:
        console.info(f"safenav {'demo' if demo else 'run'}: scenario {scenario.name!r}, path types "
                     f"{list(sweep.path_types)}, {sweep.trials} trials per cell, seed {sweep.seed}")
        safe = runner.plan_safe_paths(scenario, sweep.path_types, progress=True, paper=args.loop == "paper")
        t_plan = time.perf_counter() - t0
        for name, path in safe.items():
            console.detail(f"  safe path {name}: RAw-RRT*, {len(path)} waypoints, {path_length(path):.1f} m")
        raw = runner.run_sweep(sweep, workers=args.workers, scheduler=client, safe_paths=safe, progress=True,
                               paper=args.loop == "paper")
        t_run = time.perf_counter() - t0 - t_plan
        summary = runner.summarize(raw)
        write_table(raw, out / "trials")
        write_table(summary, out / "summary", parquet=False)
        for (filt, source), part in summary.groupby(["filter", "source"], sort=False):
            label = (f"LanBLoc-BMM({filt.upper()})" if source == "lanbloc" else
                     f"LanBLoc camera loop, {filt.upper()}" if source == "lanbloc-camera" else
                     f"{nv.SOURCES[source].label}, {filt.upper()}")
            pe = percent_error_table(part)
            nt = navigation_table(part)
            fmt = lambda v: f"{v:.3g}"  # noqa: E731
            print(f"\n% path-length error (SafeNav-ext eq. 23), {label}; paper = SafeNav Table III "
                  f"({TABLE_NUMBERING.format(ext='IV')})")
            print(pe.to_string(index=False, float_format=fmt))
            print(f"\nADE (estimate to the safe path) / FDE (final estimate to the destination) [m], AWRS, "
                  f"median time per trial, {label}; paper = SafeNav Table IV "
                  f"({TABLE_NUMBERING.format(ext='V')})")
            print(nt.to_string(index=False, float_format=fmt))
            tag = f"{filt}_{source}"
            for name, df in ((f"table_percent_error_{tag}", pe), (f"table_navigation_{tag}", nt)):
                write_table(df, out / name, parquet=False, markdown="")
        print("\n" + runner.safety_line(raw, args.loop, scenario))
        failures = raw[~raw["success"]]
        if len(failures):
            print(f"\n{len(failures)} of {len(raw)} trials did not arrive: "
                  + ", ".join(f"{k} {v}" for k, v in failures["outcome"].value_counts().items()))
        # Figs. 4 and 5: one recorded trial (trial 0) per method and path type.
        with console.task("Figs. 4-5 (trial 0 of each path type, recorded)"):
            recorded = recorded_trials(scenario, safe, sweep, paper=args.loop == "paper")
            navigation_figures(scenario, safe, sweep, out, recorded)
        foxglove.navigation_view(args.view, scenario, safe, recorded, command=args.command, seed=sweep.seed)
        console.info(f"planning {t_plan:.1f} s, {len(raw)} trials {t_run:.1f} s, "
                     f"total {time.perf_counter() - t0:.1f} s")
        _wrote(run)
    return 0


def _plan(args) -> int:
    from . import certify, certify_report
    from . import navigation as nv
    from .metrics import path_length
    from .experiments.figures import plot_navigation

    scenario = _load(args)
    have = [p.name for p in scenario.path_types]
    names = args.path_types or have
    for n in names:
        if n not in have:
            raise ValueError(f"--path-types: {n!r} is not a path type of the scenario (have: {have})")
    out = Path(args.out)
    with _run_folder(args, out, seed=scenario.seeds.planner) as run:
        result, trials, paths = {}, {}, {}
        with console.progress(len(names), "planning", unit="path") as bar:
            for name in names:
                r = certify.plan_or_none(scenario, name, args.iterations)
                if r is None:                   # no path: the certificate says so
                    paths[name] = None
                    bar.update()
                    continue
                path = paths[name] = np.asarray(r.path)
                sf = r.safety
                hz = np.asarray(sf.hazard_length)
                inside = {str(k): round(float(hz[k]), 6) for k in np.flatnonzero(hz > 0)}
                result[name] = {"path": path.round(4).tolist(), "length_m": path_length(path), "risk": r.cost.risk,
                                "cost": r.cost.total, "iterations": int(r.iterations),
                                "safety": {"min_clearance_m": float(sf.min_clearance),
                                           "hazard_length_m": inside, "exposure_m": float(sf.exposure)}}
                print(f"{name}: {len(path)} waypoints, length {path_length(path):.1f} m, risk {r.cost.risk:.2f}, "
                      f"cost {r.cost.total:.1f} ({r.iterations} iterations)")
                where = ", ".join(f"#{k} {v:.1f} m" for k, v in inside.items()) or "none"
                print(f"  safety: min clearance {sf.min_clearance:.2f} m, exposure {sf.exposure:.2f} m "
                      f"(sum of risk x length); inside hazards: {where}")
                navigator = nv.make_navigator(scenario, path, method="chull")
                trials[name] = (navigator, navigator.run(0))
                bar.update()
        write_json(out / "safe_paths.json", result)
        if trials:
            plot_navigation(scenario, trials, out / "safe_paths.png", title=f"{scenario.name}: safe paths (RAw-RRT*)")
        foxglove.plan_view(args.view, scenario, trials)
        certify_report.plan_certificates(args, scenario, paths, out)
        _wrote(run)
    return 0


def _replay_preset(args):
    """(preset, settings, observation σ overrides or None, base named preset) of replay's --preset: a named
    preset (safenav.replay.PRESETS) or a preset file (safenav.tune.load_preset) with the command's options."""
    from . import replay as rp
    from . import tune as tn
    from .guidance import FILTERS, localizer_settings

    preset = args.preset or ("plaza" if Path(args.log).suffix.lower() == ".mat" else "default")
    if not tn.is_preset_file(preset):
        if preset not in rp.PRESETS:
            raise ValueError(f"--preset {preset!r}: neither a named preset ({', '.join(rp.PRESETS)}) nor a "
                             ".toml or .json preset file (safenav tune writes one)")
        return preset, rp.preset_settings(preset, filter=args.filter, gate=args.gate, n_particles=args.particles,
                                          seed=args.seed, augment=args.augment or ()), None, preset
    settings, noise = tn.load_preset(preset)
    opts = localizer_settings(filter=args.filter, gate=args.gate, n_particles=args.particles, seed=args.seed,
                              augment=args.augment or ())
    settings.filter.type = FILTERS[args.filter]
    settings.filter.n_particles, settings.filter.seed = opts.filter.n_particles, opts.filter.seed
    if args.gate is not None:
        settings.set_param("gate_probability", float(args.gate))
    for name in args.augment or ():
        setattr(settings.augment, name, True)
    return preset, settings, noise, tn.preset_base(preset)


def _tune(args) -> int:
    from . import replay as rp
    from . import tune as tn

    base = args.preset or ("plaza" if Path(args.logs[0]).suffix.lower() == ".mat" else "default")
    range_std = args.range_std if args.range_std is not None else (rp.PLAZA_RANGE_STD if base == "plaza" else 1.0)
    settings = rp.preset_settings(base, filter=args.filter, gate=args.gate)
    logs = [rp.load(p, range_std=range_std) for p in args.logs]
    blind = [p for p, g in zip(args.logs, logs) if g.truth is None]
    if blind and not args.no_truth:
        console.info(f"{', '.join(blind)}: no truth rows: innovation-only")
    use_truth = not (args.no_truth or blind)
    result = tn.tune(logs, settings, use_truth=use_truth, base=base, max_evaluations=args.evaluations)
    print(f"{', '.join(args.logs)}: {sum(len(g.events) for g in logs)} inputs, starting from preset {base}, "
          f"{args.filter}")
    print(tn.report(result))
    comment = f"safenav tune {' '.join(args.logs)}\n" + tn.report(result)
    tn.save_preset(args.out, result.settings, result.noise, base=base, comment=comment)
    console.info(f"wrote {args.out} (safenav replay LOG --preset {args.out})")
    return 0


def _replay(args) -> int:
    from . import bags, replay as rp
    from .bags_write import write_trajectory

    preset, settings, noise, base = _replay_preset(args)
    range_std = args.range_std if args.range_std is not None else (rp.PLAZA_RANGE_STD if base == "plaza" else 1.0)
    log = bags.load(args, range_std)   # a log file, a Plaza .mat file or a ROS bag
    if noise is not None:
        log = noise.apply(log)
    prior = None
    if args.prior_from_truth:
        if log.truth is None:
            raise ValueError(f"--prior-from-truth: {args.log} has no truth rows")
        t0, x, y, h = log.truth.iloc[0][["t", "x", "y", "heading"]]
        if np.isnan(h):
            raise ValueError(f"--prior-from-truth: the first truth row of {args.log} has no heading")
        prior = (t0, np.array([x, y, 0.0, h]), np.diag([0.1, 0.1, 0.5, 0.02]) ** 2)
    heading = args.odometry_heading or (rp.PLAZA_ODOMETRY_HEADING if base == "plaza" else "end")
    result = rp.replay(log, settings, prior=prior, innovations=args.view is not None, lag=args.lag,
                       smoother=args.smoother, odometry_heading=heading)
    out = Path(args.out)
    with _run_folder(args, out, seed=args.seed) as run:
        write_trajectory(out, result, log)   # trajectory.csv, .tum, .mcap; truth.tum
        if result.smoothed is not None:      # the fixed-lag smoother's, beside the causal one
            write_table(result.smoothed, out / "trajectory_lag.csv", parquet=False)
        summary = {"log": str(args.log), "preset": preset, "filter": args.filter,
                   "augmented": [n for n in ("range_scale", "heading_rate_bias", "range_bias")
                                 if getattr(settings.augment, n)],
                   "started_from": result.started_from,
                   "t_start": result.t_start if result.estimated else None, "counts": result.counts, "metrics": result.metrics,
                   "reason": result.reason,
                   "odometry_heading": heading,
                   "lag": args.lag, "smoother": args.smoother if args.lag is not None else None,
                   "smoothed_metrics": result.smoothed_metrics}
        write_json(out / "replay.json", summary)
        foxglove.replay_view(args.view, log, result, source=str(args.log))
        c = result.counts
        started = (f"started from the {result.started_from} at t = {result.t_start:.2f} s" if result.estimated
                   else "never started")
        print(f"{args.log}: {len(log.events)} inputs, preset {preset}, {args.filter}, augmented states "
              f"{summary['augmented'] or 'none'}; {started}; updates applied {c['applied']}, rejected "
              f"{c['rejected']}, late {c['late']}, before the start {c['buffered']}, ignored {c['ignored']}")
        if result.reason:
            print(f"{'safenav: error: ' if not result.estimated else ''}{result.reason}",
                  file=sys.stderr if not result.estimated else sys.stdout)
        for m in (result.metrics, result.smoothed_metrics):
            if m:
                print(f"against the truth ({m['label']}, {m['n_scored']} poses, {m['n_before_start']} before the "
                      f"start): RMSE {m['truth_rmse']:.3f} m, ADE {m['truth_ade']:.3f} m, FDE {m['truth_fde']:.3f} m, "
                      f"NEES {m['nees']:.2f} (2 if consistent)")
        _wrote(run)
    return 0 if result.estimated else 3   # 3: nothing was estimated (the files say why)


def _experiment(args) -> int:
    from . import experiments, runner

    experiments.resolve(args.names)
    opts = experiments.ExperimentOptions(
        trials=args.trials, camera_trials=args.camera_trials, camera_position_every=args.position_every,
        particles=args.particles, workers=args.workers, scheduler=args.scheduler, seed=args.seed, out=args.out,
        scenario=_load(args), path_types=tuple(args.path_types or ()), placement=not args.no_placement,
        progress=True)
    # connected before the run folder is opened: a bad address leaves a previous run's manifest alone
    with runner.connect(opts.scheduler) as client, _run_folder(args, opts.out, seed=int(opts.seed)) as run:
        results = experiments.run_experiments(args.names, dataclasses.replace(opts, scheduler=client))
        report = experiments.write_report(results, opts)
        _wrote(run)
    print(f"report: {report}")
    bad = [c for r in results for c in r.claims if c.holds is False]
    if bad:
        print(f"{len(bad)} of the paper's claims do not hold here (see the report)")
    return 0


def _verify(args) -> int:
    m = verify_run(args.folder)
    print(f"{args.folder}: complete; the {len(m['files'])} files of its manifest match "
          f"(command: {' '.join(map(str, m.get('command') or ['?']))})")
    return 0


# --------------------------------------------------------------------------- parser

def _common() -> argparse.ArgumentParser:
    """The options of every command: --quiet, --verbose."""
    c = argparse.ArgumentParser(add_help=False)
    g = c.add_mutually_exclusive_group()
    g.add_argument("-q", "--quiet", action="store_true", help="no status lines or progress (results and errors only)")
    g.add_argument("-v", "--verbose", action="store_true", help="more detail (per-path numbers, every file written)")
    return c


def _with_scenario(common) -> argparse.ArgumentParser:
    s = argparse.ArgumentParser(add_help=False, parents=[common])
    s.add_argument("--scenario", default=None, metavar="PATH",
                   help="scenario .toml or .json (default: the built-in one)")
    return s


def _dask_options(s) -> None:
    s.add_argument("--workers", type=arg_at_least(1), default=None, help="local worker threads (default: all cores)")
    s.add_argument("--scheduler", default=None, help="Dask scheduler address: run the trials on that cluster")


def _navigation_options(s, *, demo: bool) -> None:
    """The options of demo and run."""
    s.add_argument("--trials", type=arg_at_least(1), default=300 if demo else 1000,
                   help=f"Monte Carlo trials per path type and method (default {300 if demo else 1000})")
    s.add_argument("--methods", nargs="+", default=["chull", "centroid"], choices=["chull", "centroid"])
    s.add_argument("--filters", nargs="+", default=["ekf"], choices=["ekf", "pf"])
    s.add_argument("--sources", nargs="+", default=["lanbloc"],
                   choices=["lanbloc", "lanbloc-camera", "deeploc-gps", "deeploc-ekf-gps", "sensor-fusion"],
                   help="position source: LanBLoc at the measurement level, LanBLoc through the camera loop "
                        "(rendered stereo pairs, detection, SGBM, trilateration; slow), or an emulated baseline")
    s.add_argument("--position-every", type=arg_at_least(1), default=None,
                   help="a position fix every n steps (default 1; 10 for lanbloc-camera)")
    s.add_argument("--path-types", nargs="+", default=None, help="default: all of the scenario's")
    s.add_argument("--particles", type=arg_at_least(1), default=500, help="PF particles (default 500)")
    s.add_argument("--loop", choices=["ours", "paper"], default="ours",
                   help="ours (default): the uncertainty-aware guard and the chi-square gate on; paper: the "
                        "papers' loop, neither (docs/safety.md)")
    s.add_argument("--faults", nargs=3, type=arg_probability, default=None,
                   metavar=("DROPOUT", "OUTLIER", "MISASSOCIATION"),
                   help="landmark faults: probabilities of a missed detection, an outlier range "
                        "(noise.outlier_magnitude, 5 m) and a wrong landmark id; fixes then come from "
                        "single landmark ranges (noise.fix_model = 'ranges')")
    _dask_options(s)
    s.add_argument("--seed", type=arg_at_least(0), default=None,
                   help="trial seed (default: the scenario's seeds.trials)")
    s.add_argument("--out", default="out/demo" if demo else "out/run", help="output folder")
    foxglove.add_view_argument(s)
    s.set_defaults(func=lambda a: _navigation(a, demo=demo))



def _add_experiment_commands(sub, common, scenario) -> None:
    """demo, run, plan, synthetic and experiment."""
    s = sub.add_parser("demo", parents=[scenario],
                       help="the main job: SafeNav-CHull and SafeNav-Centroid with LanBLoc-BMM(EKF) on the default "
                            "scenario's three path types, beside the paper's Tables III-IV (conference numbering)")
    _navigation_options(s, demo=True)

    s = sub.add_parser("run", parents=[scenario], help="run a scenario's navigation sweep")
    s.add_argument("scenario_file", nargs="?", default=None, help=argparse.SUPPRESS)   # the old positional form
    _navigation_options(s, demo=False)

    s = sub.add_parser("plan", parents=[scenario], help="plan and draw the safe paths of a scenario (RAw-RRT*), "
                       "certify them against the risk budget and propose landmarks where needed")
    s.add_argument("scenario_file", nargs="?", default=None, help=argparse.SUPPRESS)   # the old positional form
    s.add_argument("--path-types", nargs="+", default=None)
    s.add_argument("--iterations", type=arg_at_least(1), default=None,
                   help="RAw-RRT* iterations (default: the scenario's)")
    s.add_argument("--out", default="out/plan")
    foxglove.add_view_argument(s)
    from .certify_report import add_arguments as add_certify_arguments
    add_certify_arguments(s)
    s.set_defaults(func=_plan)

    s = sub.add_parser("synthetic", parents=[common],
                       help="filter the synthetic data set (SafeNav-ext §V-A3(i); SafeNav-conf Table I = ext "
                            "Table II) with EKF and PF")
    s.add_argument("--trials", type=arg_at_least(1), default=100, help="Monte Carlo trials (default 100)")
    s.add_argument("--filters", nargs="+", default=["ekf", "pf"], choices=["ekf", "pf", "eif"])
    s.add_argument("--particles", type=arg_at_least(1), default=1000, help="PF particles (default 1000)")
    s.add_argument("--seed", type=arg_at_least(0), default=0)
    s.add_argument("--out", default=None, help="folder for the per-trial and summary CSV files and a figure")
    s.set_defaults(func=_synthetic)

    s = sub.add_parser("experiment", parents=[scenario],
                       help="reproduce the SafeNav paper's tables and figures, with a report.html",
                       description="Experiments: all, field (Fig. 1), synthetic (Table I, Fig. 3), real-imitated "
                                   "(Table II), navigation (Tables III-IV, Figs. 4-5); the paper's names "
                                   "table1..table4, fig1, fig3, fig4, fig5 work too (tables: conference "
                                   "numbering; figures: extended numbering).")
    s.add_argument("names", nargs="+", metavar="NAME", help="experiment name(s), or 'all'")
    s.add_argument("--trials", type=arg_at_least(1), default=1000,
                   help="Monte Carlo trials per cell (default 1000, as the paper)")
    from .experiments.run import ExperimentOptions
    s.add_argument("--camera-trials", type=arg_at_least(0), default=ExperimentOptions.camera_trials,
                   help="trials per cell of the camera-in-the-loop variants of Tables II and IV "
                        f"(default {ExperimentOptions.camera_trials}; 0 = skip)")
    s.add_argument("--position-every", type=arg_at_least(1), default=10,
                   help="camera loop: a fix every n steps (default 10)")
    s.add_argument("--particles", type=arg_at_least(1), default=1000, help="PF particles (default 1000)")
    s.add_argument("--no-placement", action="store_true",
                   help="skip Table II's variant with landmarks placed along the safe paths (ILP, with obstacles "
                        "hiding landmarks, and again without for comparison; minutes)")
    s.add_argument("--path-types", nargs="+", default=None, help="default: all of the scenario's")
    _dask_options(s)
    s.add_argument("--seed", type=arg_at_least(0), default=None,
                   help="base seed (default: the scenario's seeds.trials)")
    s.add_argument("--out", default="out/experiments", help="output folder (default out/experiments)")
    s.set_defaults(func=_experiment)



def _add_tune_command(sub, common) -> None:
    """tune: noise identification from a logged run (safenav.tune)."""
    s = sub.add_parser("tune", parents=[common],
                       help="estimate the process noise and each observation kind's sigma from a logged run "
                            "(maximum likelihood; truth-based or innovation-only) and write a preset file for "
                            "safenav replay --preset")
    s.add_argument("logs", nargs="+", metavar="LOG",
                   help="log files (.csv, .parquet or Plaza-layout .mat); several runs are tuned together")
    s.add_argument("--out", default="out/tune/preset.toml", help="preset file to write (default out/tune/preset.toml)")
    s.add_argument("--no-truth", action="store_true",
                   help="innovation-only even when the log has truth (as on a vehicle without ground truth)")
    s.add_argument("--filter", choices=["ekf"], default="ekf",
                   help="the filter tuned (ekf: the innovation likelihood needs its Gaussian S)")
    s.add_argument("--preset", choices=["default", "plaza"], default=None,
                   help="the named preset to start from (default: plaza for a .mat file, else default)")
    s.add_argument("--gate", type=float, default=None, help="chi-square gate probability (default: the preset's)")
    s.add_argument("--range-std", type=float, default=None,
                   help="range sigma for a .mat file's ranges (default: 0.55 m with the plaza preset, else 1 m)")
    s.add_argument("--evaluations", type=arg_at_least(1), default=150, help="replays the search may run (default 150)")
    s.set_defaults(func=_tune)


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="safenav", description="GPS-denied safe navigation experiments.")
    p.add_argument("--version", action="version", version=f"safenav {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    common = _common()
    _add_experiment_commands(sub, common, _with_scenario(common))

    s = sub.add_parser("replay", parents=[common],
                       help="run a timestamped log (docs/replay.md; or a Plaza range-only .mat file) through the "
                            "online localizer; with ground truth, print RMSE, ADE, FDE and NEES (causal)")
    s.add_argument("log", help="a log file (.csv or .parquet), a Plaza-layout .mat file or a ROS bag")
    s.add_argument("--filter", choices=["ekf", "pf"], default="ekf")
    s.add_argument("--particles", type=arg_at_least(1), default=1000, help="PF particles (default 1000)")
    s.add_argument("--gate", type=float, default=None,
                   help="chi-square gate probability of every update (default 0.99; 0 = off)")
    s.add_argument("--preset", default=None, metavar="NAME|FILE",
                   help="localizer set-up: default, plaza (safenav.replay.PRESETS) or a preset file that "
                        "safenav tune wrote (.toml/.json); default: plaza for a .mat file, else default")
    s.add_argument("--augment", nargs="+", choices=["range_scale", "heading_rate_bias", "range_bias"],
                   help="augmented states to add (the plaza preset has range_scale and heading_rate_bias)")
    s.add_argument("--range-std", type=float, default=None,
                   help="range sigma of a .mat file's ranges and of a bag's Range messages without variance "
                        "(default: 0.55 m with the plaza preset, else 1 m)")
    s.add_argument("--prior-from-truth", action="store_true",
                   help="start from the first truth pose instead of from the data (for comparison only)")
    s.add_argument("--seed", type=arg_at_least(0), default=0, help="particle filter seed")
    s.add_argument("--lag", type=float, default=None, metavar="SECONDS", help="also run the fixed-lag smoother "
                   "(EKF; docs/replay.md): trajectory_lag.csv, scored as 'fixed-lag SECONDS s' (not causal)")
    s.add_argument("--odometry-heading", choices=["end", "mid"], default=None,
                   help="where an odometry row's heading change happens: at the end of its interval (as fed), or "
                        "in its middle, along the arc's chord (default: mid for the plaza preset, else end)")
    s.add_argument("--smoother", choices=["rts", "iterated"], default="rts",
                   help="the fixed-lag smoother with --lag: an RTS pass over the filter's linearisation, or the "
                        "iterated window solve (docs/replay.md, 'Fixed-lag smoothing'; default rts)")
    s.add_argument("--out", default="out/replay", help="output folder (default out/replay)")
    foxglove.add_view_argument(s)
    s.set_defaults(func=_replay)
    from . import bags
    bags.add_bag_arguments(s)
    bags.add_convert_command(sub, [common], _run_folder, _wrote)
    _add_tune_command(sub, common)

    from .placement.cli import register as register_place
    register_place(sub, parents=[common], positive=arg_at_least(1), run_folder=_run_folder, wrote=_wrote)

    s = sub.add_parser("verify", parents=[common],
                       help="check that a run folder is complete: its manifest.json and the files it lists")
    s.add_argument("folder", help="an output folder of demo, run, plan, synthetic, experiment or place")
    s.set_defaults(func=_verify)
    return p


def _raise_exit(signum, frame):
    raise SystemExit(128 + signum)


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:   # --help, --version, or a bad argument (one "safenav: error:" line)
        return exc.code if isinstance(exc.code, int) else 2
    args.argv = argv
    console.configure(console.QUIET if args.quiet else console.VERBOSE if args.verbose else console.NORMAL)
    # SIGTERM as SystemExit: temporary files are removed and no manifest is written
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _raise_exit) if main_thread else None
    try:
        return args.func(args)
    except (ValueError, RuntimeError, OSError) as exc:
        print(f"safenav: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("safenav: interrupted; the output folder has no manifest.json", file=sys.stderr)
        return 130
    finally:
        if main_thread:
            signal.signal(signal.SIGTERM, previous)
        console.configure(console.NORMAL)


if __name__ == "__main__":
    sys.exit(main())
