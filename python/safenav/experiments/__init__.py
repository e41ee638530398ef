"""The SafeNav paper's experiments: every table and figure from one command,
with a self-contained report (``safenav experiment NAME|all``).

Experiments (table numbers of the conference version; the extended version
numbers them one higher.  Figure numbers are the extended version's: SafeNav-conf
has no field or WRS figure, and its Figs. 2–3 are Figs. 4–5 here;
``docs/paper_map.md``):

``field``          Fig. 1: the field, landmark clusters, obstacles, hazards and
                   the safe paths with their buffers.
``synthetic``      Table I and Fig. 3: four localization sources (LanBLoc and the
                   three *emulated* baselines) × EKF/PF on the synthetic data set.
``real-imitated``  Table II: the same grid on the real-imitated world, averaged
                   over the path types P1-P3; plus LanBLoc through the camera loop.
``navigation``     Tables III and IV, Figs. 4 and 5: SafeNav-CHull against
                   SafeNav-Centroid (with RAw-RRT*) per path type; plus LanBLoc
                   through the camera loop.

Each experiment writes to ``<out>/<name>/`` (through :mod:`safenav.results`):
the raw per-trial table (``trials.parquet`` and ``.csv``, its wall times in
``trials_timings.csv``), summary tables (CSV and Markdown, timings beside
them) and figures (PNG and SVG), and returns an :class:`ExperimentResult`;
:func:`write_report` turns the results into ``<out>/report.html``, one file
with every table (ours beside the paper's), every figure (embedded), the
parameters, seeds and software versions, the departures from the paper and
which of the paper's claims hold, each with a bootstrap confidence interval
(:class:`Claim`).

Every experiment runs its trials through :func:`safenav.runner.run_trials`
(navigation through :func:`safenav.runner.run_sweep`), under the one seed
rule documented in :mod:`safenav.runner`.  With a fixed seed every per-trial
number except the wall times is identical whatever the number of workers,
locally or on a Dask cluster, and every table file is byte-identical.

The package: :mod:`~safenav.experiments.run` (options, the experiments,
:func:`run_experiments`), :mod:`~safenav.experiments.synthetic` (the
synthetic data set's Monte Carlo), :mod:`~safenav.experiments.real` (real
data: Middlebury stereo, Plaza1 ranges), :mod:`~safenav.experiments.paper`
(the paper's numbers and table layouts), :mod:`~safenav.experiments.claims`,
:mod:`~safenav.experiments.report` and :mod:`~safenav.experiments.figures`.

Example::

    from safenav import experiments
    opts = experiments.ExperimentOptions(trials=50, out="out/experiments")
    results = experiments.run_experiments(["synthetic", "navigation"], opts)
    experiments.write_report(results, opts)
"""

from ..results import markdown_table
from .claims import BOOTSTRAP, CONFIDENCE, MIN_TRIALS, Claim, localization_claims, navigation_claims
from .figures import navigation_figures
from .paper import (METHOD_LABELS, PAPER_NAVIGATION, PAPER_PERCENT_ERROR, PAPER_SOURCES, PAPER_SYNTHETIC,
                    PAPER_TABLE1, PAPER_TABLE2, localization_table, navigation_table, percent_error_table,
                    source_label)
from .report import DEPARTURES, parameters, write_report
from .run import ALIASES, EXPERIMENTS, ExperimentOptions, ExperimentResult, placed_scenario, resolve, run_experiments
from .synthetic import (PRIOR_STD, SyntheticResult, run_synthetic, source_config, summarize_synthetic,
                        synthetic_experiment, synthetic_trial)

__all__ = [
    "ExperimentOptions", "ExperimentResult", "EXPERIMENTS", "ALIASES", "resolve", "run_experiments", "write_report",
    "placed_scenario", "navigation_figures", "parameters", "DEPARTURES", "markdown_table",
    "Claim", "localization_claims", "navigation_claims", "MIN_TRIALS", "BOOTSTRAP", "CONFIDENCE",
    "PAPER_SOURCES", "PAPER_TABLE1", "PAPER_TABLE2", "PAPER_SYNTHETIC", "PAPER_PERCENT_ERROR", "PAPER_NAVIGATION",
    "METHOD_LABELS", "source_label", "localization_table", "navigation_table", "percent_error_table",
    "PRIOR_STD", "SyntheticResult", "source_config", "synthetic_experiment", "synthetic_trial", "run_synthetic",
    "summarize_synthetic",
]
