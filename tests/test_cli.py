"""The command line: one-line errors checked before any work, --version,
--quiet/--verbose and --scenario on every command, progress without carriage
returns off a terminal, one table numbering, manifests."""

from __future__ import annotations

import io
import sys

import pytest

import safenav
from safenav import cli, console, navigation, results, runner

COMMANDS = {"demo": [], "run": [], "plan": [], "synthetic": [], "experiment": ["all"],
            "place": ["in.toml"], "verify": ["folder"], "tune": ["log.csv"]}
SCENARIO_COMMANDS = ("demo", "run", "plan", "experiment")


@pytest.fixture
def no_work(monkeypatch):
    """Planning or running trials fails the test: errors must come before."""
    def forbidden(*a, **k):
        raise AssertionError("work started before the arguments were checked")
    for mod, name in ((navigation, "plan_safe_path"), (runner, "plan_safe_paths"), (runner, "run_sweep")):
        monkeypatch.setattr(mod, name, forbidden)


BAD = [
    (["plan", "--path-types", "P9"], "'P9' is not a path type"),
    (["run", "--path-types", "P9", "--trials", "1"], "'P9' is not a path type"),
    (["demo", "--workers", "0"], "argument --workers: must be an integer >= 1, got 0"),
    (["experiment", "all", "--workers", "0"], "argument --workers: must be an integer >= 1, got 0"),
    (["run", "--trials", "0"], "argument --trials: must be an integer >= 1, got 0"),
    (["experiment", "field", "--trials", "x"], "argument --trials: 'x' is not an integer"),
    (["synthetic", "--seed", "-1"], "argument --seed: must be an integer >= 0, got -1"),
    (["demo", "--particles", "0"], "argument --particles: must be an integer >= 1"),
    (["plan", "--iterations", "0"], "argument --iterations: must be an integer >= 1"),
    (["place", "in.toml", "--k", "0"], "argument --k: must be an integer >= 1, got 0"),
    (["demo", "--methods", "astar"], "argument --methods: invalid choice: 'astar'"),
    (["experiment", "table9"], "experiment 'table9' is unknown"),
    (["run", "--scenario", "missing.toml"], "missing.toml"),
    (["run", "a.toml", "--scenario", "b.toml"], "scenario given twice"),
    (["demo", "--quiet", "--verbose"], "not allowed with argument"),
    (["verify", "no/such/folder"], "does not exist"),
    (["frobnicate"], "invalid choice: 'frobnicate'"),
    ([], "the following arguments are required: command"),
]


@pytest.mark.parametrize("argv, message", BAD, ids=[" ".join(a) or "(none)" for a, _ in BAD])
def test_every_bad_argument_gives_one_error_line_and_status_2_before_any_work(argv, message, capsys, no_work,
                                                                             tmp_path):
    assert cli.main([*argv, *(["--out", str(tmp_path / "o")] if argv and argv[0] in ("demo", "run") else [])]) == 2
    cap = capsys.readouterr()
    assert cap.err.startswith("safenav: error: ") and cap.err.count("\n") == 1, cap.err
    assert message in cap.err
    assert not (tmp_path / "o").exists()


def test_a_scheduler_without_dask_is_rejected_before_planning(monkeypatch, capsys, no_work, tmp_path):
    monkeypatch.setitem(sys.modules, "distributed", None)        # import distributed -> ImportError
    for argv in (["run", "--scheduler", "tcp://h:8786", "--out", str(tmp_path / "r")],
                 ["experiment", "all", "--scheduler", "tcp://h:8786", "--out", str(tmp_path / "e")]):
        assert cli.main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "needs Dask, which is not installed" in err
    assert not list(tmp_path.iterdir())


def test_version(capsys):
    assert cli.main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"safenav {safenav.__version__}"


@pytest.mark.parametrize("command", COMMANDS)
def test_every_command_takes_quiet_and_verbose(command):
    p = cli.build_parser()
    for flag, q, v in (("--quiet", True, False), ("-q", True, False), ("--verbose", False, True),
                       ("-v", False, True)):
        a = p.parse_args([command, *COMMANDS[command], flag])
        assert (a.quiet, a.verbose) == (q, v)


@pytest.mark.parametrize("command", SCENARIO_COMMANDS)
def test_every_scenario_command_takes_the_scenario_the_same_way(command, tmp_path):
    p = cli.build_parser()
    a = p.parse_args([command, *COMMANDS[command], "--scenario", "s.toml"])
    assert a.scenario == "s.toml"
    f = tmp_path / "s.toml"
    sc = safenav.default_scenario()
    safenav.save_scenario(sc, f)
    assert cli._load(p.parse_args([command, *COMMANDS[command], "--scenario", str(f)])).name == sc.name
    if command in ("run", "plan"):                  # the old positional form still works
        assert cli._load(p.parse_args([command, str(f)])).name == sc.name


def test_quiet_normal_and_verbose_output(tmp_path, capsys):
    argv = ["synthetic", "--trials", "2", "--particles", "50", "--filters", "ekf"]
    assert cli.main([*argv, "--out", str(tmp_path / "q"), "--quiet"]) == 0
    quiet = capsys.readouterr()
    assert cli.main([*argv, "--out", str(tmp_path / "n")]) == 0
    normal = capsys.readouterr()
    assert cli.main([*argv, "--out", str(tmp_path / "v"), "--verbose"]) == 0
    verbose = capsys.readouterr()
    assert quiet.err == "" and "paper_truth_ade" in quiet.out          # results only
    assert len({len(c.out.splitlines()) for c in (quiet, normal, verbose)}) == 1     # the same table
    assert "wrote 6 files and manifest.json" in normal.err and "synthetic_trials.csv" not in normal.err
    assert "synthetic_trials.csv" in verbose.err
    for c in (normal, verbose):
        assert "\r" not in c.err                                     # stderr is not a terminal here
    for d in ("q", "n", "v"):
        results.verify_run(tmp_path / d)


def test_progress_is_plain_lines_off_a_terminal_and_a_bar_on_one(monkeypatch):
    class Tty(io.StringIO):
        def isatty(self):
            return True
    for stream, bar in ((io.StringIO(), False), (Tty(), True)):
        monkeypatch.setattr(sys, "stderr", stream)
        with console.progress(20, "trials", unit="chunk") as p:
            for _ in range(20):
                p.update()
        text = stream.getvalue()
        assert ("\r" in text) == bar
        if not bar:
            assert text.splitlines() == [l for l in text.splitlines() if l.startswith("trials: ")]
            assert len(text.splitlines()) == 10 and "20/20 chunk" in text
    monkeypatch.setattr(sys, "stderr", io.StringIO())
    console.configure(console.QUIET)
    try:
        with console.progress(5, "x") as p:
            p.update(5)
    finally:
        console.configure(console.NORMAL)
    assert sys.stderr.getvalue() == ""


def test_run_shows_progress_for_planning_and_trials_and_one_table_numbering(tmp_path, capsys):
    assert cli.main(["run", "--trials", "2", "--methods", "centroid", "--path-types", "P3",
                     "--out", str(tmp_path)]) == 0
    cap = capsys.readouterr()
    assert "planning: 1/1 path" in cap.err and "trials: 1/1 chunk" in cap.err and "Figs. 4-5" in cap.err
    assert "\r" not in cap.err
    assert "paper = SafeNav Table III (conference numbering; the extended version's Table IV)" in cap.out
    assert "paper = SafeNav Table IV (conference numbering; the extended version's Table V)" in cap.out
    m = results.verify_run(tmp_path)
    listed = {f["path"] for f in m["files"]}
    assert {"trials.csv", "trials.parquet", "trials_timings.csv", "summary.csv", "fig5_centroid.png",
            "fig5_centroid.svg", "table_navigation_ekf_lanbloc.md"} <= listed
    assert m["command"][:2] == ["safenav", "run"] and m["seed"] == 0 and m["parameters"]["trials"] == 2


def test_place_shows_progress_and_writes_a_manifest(tmp_path, capsys):
    from test_results_io import PLACE_INPUT

    assert cli.main(["place", str(PLACE_INPUT), "--out", str(tmp_path), "--simulate"]) == 0
    err = capsys.readouterr().err
    assert "placing landmarks (greedy" in err and "bearing-only EIF along the route: done in" in err
    assert {f["path"] for f in results.verify_run(tmp_path)["files"]} == {"placement.json", "placement.png",
                                                                          "placement_errors.png"}
