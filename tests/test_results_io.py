"""The one result writer (safenav.results): exclusive temporary files, no
symlink following, the user's umask, clean-up on failure, SIGTERM and stale
files from a kill -9, the manifest written last, and tables whose bytes do not
depend on the number of workers."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import safenav
from safenav import cli, results, runner
from safenav.scenario import default_scenario

PLACE_INPUT = Path(__file__).resolve().parents[1] / "python" / "safenav" / "data" / "placement_example.toml"


def _temps(folder: Path) -> list:
    return [p for p in folder.rglob("*") if p.name.startswith(results.TEMP_PREFIX) or p.suffix == ".tmp"]


@pytest.fixture
def umask():
    """Set a umask for the test; restore the old one after."""
    old = os.umask(0o022)
    os.umask(old)
    yield lambda m: os.umask(m)
    os.umask(old)


# --------------------------------------------------------------------------- symlinks

def test_a_symlink_planted_at_the_old_fixed_temp_names_is_not_followed(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    out = tmp_path / "plan"
    out.mkdir()
    (out / "safe_paths.json.tmp").symlink_to(victim)
    assert cli.main(["plan", "--path-types", "P3", "--iterations", "300", "--out", str(out), "--quiet"]) == 0
    assert victim.read_text() == "precious"
    assert '"P3"' in (out / "safe_paths.json").read_text()
    place = tmp_path / "place"
    place.mkdir()
    (place / "placement.json.tmp").symlink_to(victim)
    assert cli.main(["place", str(PLACE_INPUT), "--out", str(place), "--quiet"]) == 0
    assert victim.read_text() == "precious"
    assert '"landmarks"' in (place / "placement.json").read_text()


def test_a_symlink_at_the_target_is_replaced_not_followed(tmp_path):
    victim = tmp_path / "elsewhere" / "victim.txt"
    victim.parent.mkdir()
    victim.write_text("precious")
    out = tmp_path / "out"
    out.mkdir()
    (out / "report.html").symlink_to(victim)
    results.write_text(out / "report.html", "<html></html>")
    assert victim.read_text() == "precious"
    assert not (out / "report.html").is_symlink() and (out / "report.html").read_text() == "<html></html>"


def test_temporary_names_are_fresh_and_exclusive(tmp_path):
    seen = []

    def write(fh):
        (tmp,) = _temps(tmp_path)
        seen.append(tmp)
        fh.write(b"x")
    for _ in range(3):
        results.atomic_write(tmp_path / "a.txt", write)
    assert len(set(seen)) == 3 and all(p.parent == tmp_path and p.name.startswith(results.TEMP_PREFIX)
                                       for p in seen)
    assert not _temps(tmp_path)


# --------------------------------------------------------------------------- permissions

@pytest.mark.parametrize("mask, mode", [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_result_files_follow_the_umask(tmp_path, umask, mask, mode):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    umask(mask)
    df = pd.DataFrame({"path_type": ["P1"], "trial": [0], "ade": [0.5], "time_ms": [1.0]})
    files = results.write_table(df, tmp_path / "trials", markdown="t")
    files.append(results.write_text(tmp_path / "report.html", "<html></html>"))
    fig, ax = plt.subplots()
    ax.plot([0, 1])
    files.append(results.save_figure(fig, tmp_path / "fig.png", svg=True))
    files.append(tmp_path / "fig.svg")
    files.append(safenav.save_scenario(default_scenario(), tmp_path / "s.toml"))
    assert len(files) == 8
    for f in files:
        assert (f.stat().st_mode & 0o777) == mode, f


# --------------------------------------------------------------------------- failure and interruption

@pytest.mark.parametrize("exc", [RuntimeError("disk full"), KeyboardInterrupt()])
def test_a_failed_write_leaves_no_temp_file_and_keeps_the_old_target(tmp_path, exc):
    target = tmp_path / "t.csv"
    target.write_text("old")

    def write(fh):
        fh.write(b"half")
        raise exc
    with pytest.raises(type(exc)):
        results.atomic_write(target, write)
    assert target.read_text() == "old" and not _temps(tmp_path)


_WRITER = """
import signal, sys, time
from safenav import cli, results
signal.signal(signal.SIGTERM, cli._raise_exit)
def write(fh):
    fh.write(b"partial")
    fh.flush()
    print("writing", flush=True)
    time.sleep(60)
results.atomic_write(sys.argv[1], write)
"""


def _start_writer(target: Path) -> subprocess.Popen:
    proc = subprocess.Popen([sys.executable, "-c", textwrap.dedent(_WRITER), str(target)], stdout=subprocess.PIPE,
                            text=True, env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    assert proc.stdout.readline().strip() == "writing"
    return proc


def test_sigterm_removes_the_temporary_file(tmp_path):
    proc = _start_writer(tmp_path / "out.csv")
    assert len(_temps(tmp_path)) == 1
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=30) == 128 + signal.SIGTERM
    assert not _temps(tmp_path) and not (tmp_path / "out.csv").exists()


def test_a_temp_file_left_by_kill_9_is_removed_by_the_next_write_once_stale(tmp_path):
    proc = _start_writer(tmp_path / "out.csv")
    proc.kill()
    proc.wait(timeout=30)
    (left,) = _temps(tmp_path)                       # kill -9 cannot be caught
    results.write_text(tmp_path / "other.txt", "x")
    assert left.exists()                             # it might be another writer's: young files stay
    old = time.time() - results.STALE_TEMP_S - 1
    os.utime(left, (old, old))
    results.write_text(tmp_path / "other.txt", "y")
    assert not left.exists()


# --------------------------------------------------------------------------- manifest

def test_the_manifest_lists_every_file_with_size_and_hash_and_is_written_last(tmp_path):
    out = tmp_path / "run"
    with results.RunFolder(out, command=["safenav", "x"], parameters={"trials": 3}, seed=7):
        a = results.write_text(out / "a.txt", "alpha")
        b = results.write_json(out / "sub" / "b.json", {"k": 1})
        results.write_text(tmp_path / "outside.txt", "not in the run")
        assert not (out / results.MANIFEST).exists()
    m = results.verify_run(out)
    assert [f["path"] for f in m["files"]] == ["a.txt", "sub/b.json"]
    assert m["files"][0]["bytes"] == 5 and m["seed"] == 7 and m["parameters"] == {"trials": 3}
    assert m["command"] == ["safenav", "x"] and "numpy" in m["versions"]
    import hashlib
    assert m["files"][1]["sha256"] == hashlib.sha256(b.read_bytes()).hexdigest()
    assert (out / results.MANIFEST).stat().st_mtime_ns >= a.stat().st_mtime_ns
    b.write_text("tampered")
    with pytest.raises(results.IncompleteRunError, match="sub/b.json changed since the run"):
        results.verify_run(out)


def test_an_interrupted_run_has_no_manifest_and_no_temp_files_and_says_so(tmp_path, capsys):
    out = tmp_path / "run"
    with results.RunFolder(out, command=["safenav"]):
        results.write_text(out / "a.txt", "first run")
    results.verify_run(out)

    def boom(fh):
        fh.write(b"half")
        raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt):
        with results.RunFolder(out, command=["safenav"]):   # the rerun removes the old manifest first
            results.write_text(out / "a.txt", "second run")
            results.atomic_write(out / "b.txt", boom)
    assert not (out / results.MANIFEST).exists() and not _temps(out)
    with pytest.raises(results.IncompleteRunError, match="incomplete run: it has no manifest.json"):
        results.verify_run(out)
    assert cli.main(["verify", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("safenav: error: ") and "incomplete run" in err and err.count("\n") == 1


def test_a_command_that_fails_midway_leaves_no_manifest(tmp_path, monkeypatch):
    from safenav.experiments import figures as plots

    def broken(*a, **k):
        raise RuntimeError("figure failed")
    monkeypatch.setattr(plots, "plot_navigation", broken)
    out = tmp_path / "plan"
    assert cli.main(["plan", "--path-types", "P3", "--iterations", "300", "--out", str(out), "--quiet"]) == 2
    assert (out / "safe_paths.json").exists() and not (out / results.MANIFEST).exists() and not _temps(out)


@pytest.mark.parametrize("manifest", [
    '{"files": [{"path": "a.txt"}]}',                       # no sha256
    '{"files": {"path": "a.txt"}}',                         # not a list
    '[1, 2]',                                               # not an object
    '{"files": [{"path": "../outside.txt", "sha256": "0"}]}',   # outside the folder
    '{"files": [{"path": "/etc/passwd", "sha256": "0"}]}',
])
def test_a_malformed_manifest_is_an_incomplete_run_not_a_traceback(tmp_path, capsys, manifest):
    out = tmp_path / "run"
    out.mkdir()
    (out / "a.txt").write_text("x")
    (out / results.MANIFEST).write_text(manifest)
    with pytest.raises(results.IncompleteRunError, match="not a safenav manifest"):
        results.verify_run(out)
    assert cli.main(["verify", str(out)]) == 2
    assert capsys.readouterr().err.count("\n") == 1


def test_a_bad_scheduler_leaves_the_previous_runs_manifest(tmp_path, capsys):
    out = tmp_path / "exp"
    with results.RunFolder(out, command=["safenav"]):
        results.write_text(out / "a.txt", "complete")
    assert cli.main(["experiment", "field", "--scheduler", "tcp://127.0.0.1:9", "--out", str(out)]) == 2
    assert "cannot connect" in capsys.readouterr().err
    results.verify_run(out)       # still complete


def test_a_failing_item_cancels_the_queued_ones():
    import threading

    ran = []
    lock = threading.Lock()

    def fn(i):
        with lock:
            ran.append(i)
        if i == 0:
            raise RuntimeError("item 0 failed")
        time.sleep(0.05)
    with pytest.raises(RuntimeError, match="item 0 failed"):
        runner.map_ordered(fn, range(200), workers=1)
    assert len(ran) < 5          # before: all 200 ran before the error got out


# --------------------------------------------------------------------------- tables

def test_timings_are_kept_beside_the_table_and_read_back(tmp_path):
    df = pd.DataFrame({"path_type": ["P1", "P2"], "method": ["chull", "centroid"], "trial": [0, 1],
                       "ade": [0.123456789012345, 2.0], "success": [True, False],
                       "time_ms": [1.5, 2.25], "time_per_step_us": [3.0, 4.0]})
    files = results.write_table(df, tmp_path / "trials")
    assert sorted(f.name for f in files) == ["trials.csv", "trials.parquet", "trials_timings.csv"]
    assert "time" not in (tmp_path / "trials.csv").read_text()
    assert list(pd.read_parquet(tmp_path / "trials.parquet").columns) == ["path_type", "method", "trial", "ade",
                                                                         "success"]
    assert list(pd.read_csv(tmp_path / "trials_timings.csv").columns) == ["path_type", "method", "trial", "time_ms",
                                                                         "time_per_step_us"]
    for name in ("trials.parquet", "trials.csv"):
        pd.testing.assert_frame_equal(results.read_table(tmp_path / name), df)
    # a rewrite without wall times drops the old timings instead of having them joined back
    results.write_table(df.drop(columns=["time_ms", "time_per_step_us"]).assign(ade=[5.0, 6.0]), tmp_path / "trials")
    assert not (tmp_path / "trials_timings.csv").exists()
    assert "time_ms" not in results.read_table(tmp_path / "trials.parquet").columns


def test_tables_are_byte_identical_with_one_or_two_workers(tmp_path):
    sweep = runner.Sweep(default_scenario(), path_types=("P3",), methods=("centroid",), filters=("ekf", "pf"),
                         trials=4, chunk=1, seed=2, n_particles=50)
    safe = runner.plan_safe_paths(sweep.scenario, ["P3"])
    for w in (1, 2):
        raw = runner.run_sweep(sweep, workers=w, safe_paths=safe)
        results.write_table(raw, tmp_path / f"w{w}" / "trials")
        results.write_table(runner.summarize(raw), tmp_path / f"w{w}" / "summary", markdown="summary")
    for name in ("trials.csv", "trials.parquet", "summary.csv", "summary.parquet", "summary.md"):
        assert (tmp_path / "w1" / name).read_bytes() == (tmp_path / "w2" / name).read_bytes(), name
    # the timings differ (wall times), and the table is not trivially empty
    t = [pd.read_csv(tmp_path / f"w{w}" / "trials_timings.csv")["time_ms"].to_numpy() for w in (1, 2)]
    assert not np.array_equal(*t)
    assert len(pd.read_csv(tmp_path / "w1" / "trials.csv")) == 8
