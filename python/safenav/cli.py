"""The ``safenav`` command line."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def _synthetic(args) -> int:
    from .experiments import run_synthetic, summarize_synthetic

    raw = run_synthetic(args.trials, filters=args.filters, seed=args.seed, n_particles=args.particles)
    table = summarize_synthetic(raw)
    print(f"Synthetic data set (SafeNav V-A), LanBLoc-BMM, {args.trials} trials, seed {args.seed}; "
          f"time = median per trial")
    print(table.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        _atomic_csv(raw, out / "synthetic_trials.csv")
        _atomic_csv(table, out / "synthetic_summary.csv")
        fig = _synthetic_figure(args, out / "synthetic_trial.png")
        print(f"wrote {out / 'synthetic_trials.csv'}, {out / 'synthetic_summary.csv'} and {fig}")
    return 0


def _synthetic_figure(args, path: Path) -> Path:
    """Figure of trial 0 (same seeds as the Monte Carlo's first trial)."""
    from .experiments import synthetic_trial
    from .plots import plot_synthetic_trial

    data, results = synthetic_trial(0, filters=args.filters, seed=args.seed, n_particles=args.particles)
    return plot_synthetic_trial(data, {k.upper(): v for k, v in results.items()}, path)


def _atomic_csv(df, path: Path) -> None:
    tmp = path.with_name(path.name + ".tmp")
    df.to_csv(tmp, index=False)
    tmp.replace(path)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="safenav", description="GPS-denied safe navigation experiments.")
    sub = p.add_subparsers(dest="command", required=True)
    for name, help_ in (("demo", "the main job (for now: the synthetic data set, EKF and PF)"),
                        ("synthetic", "filter the synthetic data set (SafeNav V-A) with EKF and PF")):
        s = sub.add_parser(name, help=help_)
        s.add_argument("--trials", type=int, default=100, help="Monte Carlo trials (default 100)")
        s.add_argument("--filters", nargs="+", default=["ekf", "pf"], choices=["ekf", "pf", "eif"])
        s.add_argument("--particles", type=int, default=1000, help="PF particles (default 1000)")
        s.add_argument("--seed", type=int, default=0)
        s.add_argument("--out", default="out/demo" if name == "demo" else None,
                       help="folder for the per-trial and summary CSV files and a figure"
                            + (" (default out/demo)" if name == "demo" else ""))
        s.set_defaults(func=_synthetic)
    from .placement_cli import register as register_place
    register_place(sub)
    return p


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except ValueError as exc:
        print(f"safenav: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
