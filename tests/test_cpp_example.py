"""The C++ core installs as a CMake package and a separate project embeds it.

Installs the shared ``safenav::core`` to a temporary prefix, then configures
``cpp/examples`` as its own CMake project with ``find_package(safenav)``,
builds the examples and runs them: ``vehicle_loop`` (a vehicle that
``Guidance`` steers round an obstacle on its path) and ``log_replay`` (a
``docs/replay.md`` log through the ``Localizer``, checked against
``safenav.replay.replay`` on the same log).  The consumer must link ``safenav::core``
alone: the exported link interface names imported targets (Eigen's), not the
absolute paths of OMPL, ODE, GMP, MPFR or OpenCV, and the consumer configures
with CGAL, OMPL, OpenCV and Boost hidden from CMake.

The core is installed from the build that produced the imported
``safenav._core`` when there is one (it holds the compiled objects already),
else from a standalone build under ``build/`` that reruns incrementally.
"""

from __future__ import annotations

import io
import math
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from safenav import _core

ROOT = Path(__file__).resolve().parents[1]
CMAKE = shutil.which("cmake")
GEN = ["-G", "Ninja"] if shutil.which("ninja") else []
# Libraries private to the shared core: no consumer may name them.
PRIVATE_LIBS = re.compile(r"ompl|opencv|gmp|mpfr|boost|cgal|libode|^-lode$", re.IGNORECASE)
HIDDEN = ["-DCMAKE_DISABLE_FIND_PACKAGE_" + pkg + "=ON" for pkg in ("CGAL", "ompl", "OpenCV", "Boost")]


def _run(*cmd, cwd=ROOT):
    proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    assert proc.returncode == 0, f"{' '.join(map(str, cmd))} failed:\n{proc.stdout}\n{proc.stderr}"
    return proc.stdout


def _module_build_dir() -> Path | None:
    """The CMake build of this tree that the imported ``safenav._core`` came from, if any."""
    for folder in Path(_core.__file__).resolve().parents:
        cache = folder / "CMakeCache.txt"
        if cache.is_file():
            home = re.search(r"^CMAKE_HOME_DIRECTORY:INTERNAL=(.*)$", cache.read_text(), re.MULTILINE)
            return folder if home and Path(home.group(1)).resolve() == ROOT else None
    return None


@pytest.fixture(scope="module")
def installed_prefix(tmp_path_factory):
    assert CMAKE, "cmake is required (pip install cmake, or apt-get install cmake)"
    build = _module_build_dir()
    if build is None:
        build = ROOT / "build" / "cpp-package-test" / "core"
        _run(CMAKE, "-S", str(ROOT), "-B", str(build), *GEN, "-DCMAKE_BUILD_TYPE=Release",
             "-DSAFENAV_BUILD_PYTHON=OFF")
    _run(CMAKE, "--build", str(build), "--target", "safenav_core", "--parallel", "2")
    prefix = tmp_path_factory.mktemp("prefix")
    _run(CMAKE, "--install", str(build), "--component", "cpp", "--prefix", str(prefix))
    return prefix


@pytest.fixture(scope="module")
def example_build(installed_prefix, tmp_path_factory):
    build = tmp_path_factory.mktemp("example")
    _run(CMAKE, "-S", str(ROOT / "cpp" / "examples"), "-B", str(build), *GEN, "-DCMAKE_BUILD_TYPE=Release",
         f"-DCMAKE_PREFIX_PATH={installed_prefix}", *HIDDEN)
    _run(CMAKE, "--build", str(build))
    return build


def _link_command(build: Path, target: str = "vehicle_loop") -> str:
    if GEN:
        return _run("ninja", "-C", str(build), "-t", "commands", target).strip().splitlines()[-1]
    return (build / "CMakeFiles" / f"{target}.dir" / "link.txt").read_text()


def test_installed_package_layout(installed_prefix):
    assert (installed_prefix / "include" / "safenav" / "filters.hpp").is_file()
    configs = list(installed_prefix.glob("lib*/cmake/safenav/safenavConfig.cmake"))
    assert configs, "safenavConfig.cmake was not installed"
    # The core ships as a shared library, not as a static archive.
    assert list(installed_prefix.glob("lib*/libsafenav_core.so*"))
    assert not list(installed_prefix.glob("lib*/*.a"))
    # Public headers expose only Eigen and the standard library.
    for header in (installed_prefix / "include" / "safenav").glob("*.hpp"):
        for line in header.read_text().splitlines():
            if line.startswith("#include <"):
                name = line.split("<")[1].split(">")[0]
                # Eigen, or a standard header (no directory, no extension).
                assert name.split("/")[0] == "Eigen" or ("/" not in name and "." not in name), (header, line)


def test_exported_link_interface_names_targets_not_paths(installed_prefix):
    (targets,) = installed_prefix.glob("lib*/cmake/safenav/safenavTargets.cmake")
    text = "".join(p.read_text() for p in targets.parent.glob("safenavTargets*.cmake"))
    interface = re.findall(r'INTERFACE_LINK_LIBRARIES "([^"]*)"', text)
    assert interface == ["Eigen3::Eigen"], interface
    # No absolute path (our own library is found relative to the prefix), and
    # no library file but ours.
    code = re.sub(r"#.*", "", text)
    assert not re.findall(r'(?:^|[\s";:])(/[^\s";>]+)', code, re.MULTILINE)
    libraries = re.findall(r"[\w.+-]+\.(?:so|a)\b[\w.]*", code)
    assert libraries and all(lib.startswith("libsafenav_core.so") for lib in libraries), libraries
    # The package config looks for Eigen only.
    config = re.sub(r"#.*", "", (targets.parent / "safenavConfig.cmake").read_text())
    assert not PRIVATE_LIBS.search(config), config


@pytest.mark.parametrize("target", ["vehicle_loop", "log_replay", "tick_bench"])
def test_consumer_links_only_safenav_core(example_build, target):
    link = _link_command(example_build, target).split()
    assert any("libsafenav_core.so" in tok for tok in link), link
    assert not [tok for tok in link if PRIVATE_LIBS.search(Path(tok).name)], link


def test_example_builds_against_installed_package_and_runs(example_build):
    exe = example_build / "vehicle_loop"
    out = _run(str(exe), "2000")
    fields = dict(kv.split("=", 1) for kv in out.split() if "=" in kv)
    # Guidance saw the obstacle on the path, planned a detour and arrived without touching it.
    assert "events=detour_planned,path_spliced" in out
    assert fields["status"] == "arrived" and fields["detour"] == "yes" and fields["collision"] == "no"
    assert int(fields["replans"]) >= 1
    assert 0 < int(fields["steps"]) < 2000
    assert float(fields["goal_distance"].rstrip("m")) < 2.0
    assert int(fields["observations"]) > 1000
    assert int(fields["rejected"]) < 0.05 * int(fields["observations"])   # the 99% gate rejects few
    assert float(fields["error"].rstrip("m")) < 0.3
    # Too few steps to arrive: reported as a failure, not a crash.
    short = subprocess.run([str(exe), "100"], capture_output=True, text=True)
    assert short.returncode == 1 and "status=guiding" in short.stdout
    # A bad argument is reported, not a crash.
    bad = subprocess.run([str(exe), "0"], capture_output=True, text=True)
    assert bad.returncode == 2 and "steps must be > 0" in bad.stderr


# --------------------------------------------------------------------------- log_replay

def _synthetic_log(seed: int = 3):
    """A vehicle driving past 4 landmarks at 2 m/s for 30 s: motion rows every
    0.1 s, range-bearing sightings of each landmark within 30 m every 0.3 s
    (between two motion rows), truth every 0.1 s."""
    from safenav.logs import Log

    rng = np.random.default_rng(seed)
    landmarks = {3: (10.0, 6.0), 7: (25.0, -16.0), 11: (40.0, 9.0), 12: (55.0, -12.0)}
    dt, v = 0.1, 2.0
    x, y, th = 0.0, -3.0, 0.0
    events, truth = [], [dict(t=0.0, x=x, y=y, heading=th)]
    for k in range(1, 301):
        t = round(k * dt, 10)
        dth = 0.02 * math.sin(0.05 * k)
        th += dth
        x += v * dt * math.cos(th)
        y += v * dt * math.sin(th)
        events.append(dict(t=t, kind="motion", speed=v + 0.05 * rng.standard_normal(), heading_change=dth))
        truth.append(dict(t=t, x=x, y=y, heading=th))
        if k % 3 == 0:
            ts = t + 0.05
            xs, ys = x + v * 0.05 * math.cos(th), y + v * 0.05 * math.sin(th)
            for i, (lx, ly) in landmarks.items():
                r = math.hypot(lx - xs, ly - ys)
                if r < 30.0:
                    b = (math.atan2(ly - ys, lx - xs) - th + math.pi) % (2 * math.pi) - math.pi
                    events.append(dict(t=ts, kind="range_bearing", landmark=i, range=r + 0.1 * rng.standard_normal(),
                                       bearing=b + 0.01 * rng.standard_normal(), range_std=0.1, bearing_std=0.01))
    return Log(landmarks, pd.DataFrame(events), pd.DataFrame(truth))


@pytest.fixture(scope="module")
def synthetic_log_path(tmp_path_factory):
    from safenav.logs import write_log

    return write_log(_synthetic_log(), tmp_path_factory.mktemp("log") / "drive.csv")


def _fields(text: str) -> dict:
    return dict(kv.split("=", 1) for kv in text.split() if "=" in kv)


@pytest.mark.parametrize("prior", [False, True], ids=["from-data", "prior-from-truth"])
def test_log_replay_matches_python_replay(example_build, synthetic_log_path, tmp_path, prior):
    from safenav import replay as rp
    from safenav.logs import read_log

    exe = example_build / "log_replay"
    args = [str(exe), str(synthetic_log_path), "-o", str(tmp_path / "traj.csv")] + (["--prior-from-truth"] * prior)
    info = _fields(_run(*args))
    ours = pd.read_csv(tmp_path / "traj.csv")

    log = read_log(synthetic_log_path)
    start = None
    if prior:
        t0, x, y, h = log.truth.iloc[0][["t", "x", "y", "heading"]]
        start = (t0, np.array([x, y, 0.0, h]), np.diag([0.1, 0.1, 0.5, 0.02]) ** 2)   # as `safenav replay`
    ref = rp.replay(log, prior=start)

    # (a) the C++ replay localizes well against the truth.
    assert info["started_from"] == ref.started_from
    assert float(info["truth_rmse"]) < 0.2
    assert int(info["n_scored"]) == ref.metrics["n_scored"] and int(info["n_before_start"]) == ref.metrics[
        "n_before_start"]
    # (b) same Localizer, same inputs in the same order: the same numbers.
    assert list(ours.columns) == list(rp.TRAJECTORY_COLUMNS)
    assert ours.shape == ref.trajectory.shape and len(ours) > 100
    np.testing.assert_allclose(ours.to_numpy(), ref.trajectory.to_numpy(), rtol=1e-9, atol=1e-12)
    for key in ("truth_rmse", "truth_ade", "truth_fde", "nees"):
        assert float(info[key]) == pytest.approx(ref.metrics[key], rel=1e-9)
    for key in ("motion", "applied", "rejected", "late", "buffered"):
        assert int(info[key]) == ref.counts[key]
    assert float(info["t_start"]) == pytest.approx(ref.t_start, rel=1e-12)


def test_log_replay_to_stdout_and_errors(example_build, synthetic_log_path, tmp_path):
    exe = str(example_build / "log_replay")
    proc = subprocess.run([exe, str(synthetic_log_path)], capture_output=True, text=True)
    assert proc.returncode == 0
    traj = pd.read_csv(io.StringIO(proc.stdout))      # the trajectory on stdout, the summary on stderr
    assert len(traj) > 100 and "truth_rmse=" in proc.stderr
    # A log with no truth rows: a trajectory and no scores.
    no_truth = tmp_path / "no_truth.csv"
    table = pd.read_csv(synthetic_log_path)
    table[table["kind"] != "truth"].to_csv(no_truth, index=False)
    proc = subprocess.run([exe, str(no_truth), "-o", str(tmp_path / "t.csv")], capture_output=True, text=True)
    assert proc.returncode == 0 and "truth_rmse=" not in proc.stdout and "rows=" in proc.stdout
    proc = subprocess.run([exe, str(no_truth), "--prior-from-truth"], capture_output=True, text=True)
    assert proc.returncode == 2 and "no truth rows" in proc.stderr
    # A log with nothing to start from (motion only): the reason, and a failure (as `safenav replay`).
    blind = tmp_path / "blind.csv"
    table[table["kind"].isin(["landmark", "motion", "odometry", "truth"])].to_csv(blind, index=False)
    proc = subprocess.run([exe, str(blind), "-o", str(tmp_path / "b.csv")], capture_output=True, text=True)
    assert proc.returncode == 3 and "never started:" in proc.stderr and "rows=0" in proc.stdout, proc.stderr
    # Bad files are one-line errors naming the line, not crashes.
    bad = tmp_path / "bad.csv"
    bad.write_text("t,kind,landmark,x,y\n,landmark,0,1.0,2.0\n0.5,odom,,,\n")
    proc = subprocess.run([exe, str(bad)], capture_output=True, text=True)
    assert proc.returncode == 2 and "line 3" in proc.stderr and "unknown kind 'odom'" in proc.stderr
    bad.write_text("t,kind,landmark,x,y,range,range_std\n,landmark,0,1.0,2.0,,\n0.5,range,0,,,noon,1\n")
    proc = subprocess.run([exe, str(bad)], capture_output=True, text=True)
    assert proc.returncode == 2 and "'range' = 'noon'" in proc.stderr
    proc = subprocess.run([exe, str(tmp_path / "missing.csv")], capture_output=True, text=True)
    assert proc.returncode == 2 and "cannot open" in proc.stderr
    proc = subprocess.run([exe], capture_output=True, text=True)
    assert proc.returncode == 2 and "usage" in proc.stderr


def test_tick_bench_localizer_tick_allocates_nothing(example_build):
    import json

    res = json.loads(_run(str(example_build / "tick_bench"), "2000", "1"))
    assert res["guidance_construction_allocs"] > 0          # the counter sees the library's allocations
    assert res["localizer_allocs_per_tick"] == 0             # EKF motion + observe after construction
    assert res["localizer_applied_fraction"] == 1.0
    assert res["command_allocs_per_call"] == 0 and res["guidance_allocs_per_tick"] == 0
    assert res["events"] == 0 and res["guidance_guiding_fraction"] == 1.0
