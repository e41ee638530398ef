#!/usr/bin/env python
"""Online-API benchmarks: the per-tick cost of Localizer and Guidance, against FilterPy.

Run from the repository root::

    python bench/bench_guidance.py            # full run (9 interleaved repeats)
    python bench/bench_guidance.py --quick    # 3 repeats, fewer ticks

A *tick* is what a vehicle's loop does every control period: one motion input
(desired speed, heading change over Δt = 0.05 s) and one landmark
range-bearing observation (landmark k mod 4, σ_r = 0.3 m, σ_b = 0.02 rad),
from a prior.  Same script, same model, same noise for every filter:

1. Python, per tick — ``safenav.guidance.Localizer`` (``motion`` +
   ``observe`` with scalars) against FilterPy's ``ExtendedKalmanFilter``
   step by step: ``predict`` with the BMM (``bench_filters.BmmEkf``: F and
   Q = G Σ Gᵀ set each step) and ``update(z, HJacobian, Hx, args=…,
   hx_args=…, residual=…)`` with the range-bearing model and a wrapped
   bearing residual, the usual FilterPy way.  Both Joseph form, χ² gate off,
   so the estimates must agree to rounding; the script checks it.  Our old
   per-step path (``safenav.filters.Ekf`` predict/update with a fresh
   ``MeasurementModel.range_bearing`` per step) is timed for comparison, and
   the Localizer with its default 99 % gate for information.
   Target: ours ≤ 10 µs/tick.
2. C++, per tick — ``cpp/examples/tick_bench`` (built here from an install of
   ``safenav::core``, as tests/test_cpp_example.py does): the same tick in
   C++ (motion + observe; target ≤ 2 µs), the full guidance tick
   (``Guidance::command`` with SafeNav-Centroid and no replanning + motion +
   observe), ``command()`` alone with and without the obstacle check, and
   the heap allocations per tick after warm-up (counted by replacing global
   operator new in that program; 0 expected for the EKF tick).

Every Python timing is repeated; ours and the peers alternate within each
repeat (order flipped every repeat) and medians are reported with the
min–max range.  The C++ figures are medians over tick_bench's own repeats.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import safenav
from safenav import _core
from safenav.guidance import Localizer, localizer_settings

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_filters import BmmEkf, interleave, med, print_header, spread, wrap  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SEED = 20240601
PY_TARGET_US = 10.0    # ours <= 10 us per tick from Python
CPP_TARGET_US = 2.0    # ours <= 2 us per tick in C++
LANDMARKS = np.array([[0.0, 0.0], [60.0, 0.0], [60.0, 60.0], [0.0, 60.0]])
RANGE_STD, BEARING_STD = 0.3, 0.02
X0 = np.array([30.0, 10.0, 2.0, 0.0])
P0 = np.diag([0.1, 0.1, 0.1, 0.03]) ** 2


# ---------------------------------------------------------------------------
# Data: a vehicle circling the landmark field
# ---------------------------------------------------------------------------

def make_script(n: int, seed: int):
    """Controls (n, 2), observed landmark rows (n,), observations (n, 2): the
    true vehicle follows the BMM with process noise; each tick sees landmark
    k mod 4 with range and bearing noise."""
    params = safenav.BmmParams()
    k = np.arange(n)
    u = np.column_stack([np.full(n, 2.0), 0.02 * np.sin(0.01 * k) + 0.01])
    truth = safenav.Bmm(params).simulate(X0, u, seed)[1:]
    rng = np.random.default_rng(seed)
    ids = k % len(LANDMARKS)
    d = LANDMARKS[ids] - truth[:, :2]
    z = np.column_stack([np.hypot(d[:, 0], d[:, 1]) + RANGE_STD * rng.standard_normal(n),
                         wrap(np.arctan2(d[:, 1], d[:, 0]) - truth[:, 3] + BEARING_STD * rng.standard_normal(n))])
    return params, u, ids, z, truth


# ---------------------------------------------------------------------------
# Ours: the online Localizer, one motion + one observation per tick
# ---------------------------------------------------------------------------

def ours_localizer(params, u, ids, z, gate=0.0):
    loc = Localizer(localizer_settings(bmm=params, gate=gate), LANDMARKS)
    loc.initialize(0.0, X0, P0)
    dt = params.dt
    us, hs = u[:, 0].tolist(), u[:, 1].tolist()
    ids_, rs, bs = ids.tolist(), z[:, 0].tolist(), z[:, 1].tolist()
    motion, observe = loc.motion, loc.observe
    for i in range(len(us)):
        t = (i + 1) * dt
        motion(t, us[i], hs[i])
        observe(t, ids_[i], rs[i], bs[i], RANGE_STD, BEARING_STD)
    return loc.x


def ours_ekf_steps(params, u, ids, z):
    """The old per-step path: safenav.filters.Ekf with a fresh range-bearing model per step."""
    ekf = safenav.Ekf(params, X0, P0)
    for i in range(len(u)):
        ekf.predict(u[i])
        model = safenav.MeasurementModel.range_bearing(LANDMARKS[ids[i]:ids[i] + 1], RANGE_STD, BEARING_STD)
        ekf.update(model, z[i])
    return ekf.x


# ---------------------------------------------------------------------------
# Peer: FilterPy EKF with the BMM and the range-bearing model
# ---------------------------------------------------------------------------

def _hx(x, lm):
    dx, dy = lm[0] - x[0, 0], lm[1] - x[1, 0]
    return np.array([[math.hypot(dx, dy)], [math.atan2(dy, dx) - x[3, 0]]])


def _h_jacobian(x, lm):
    dx, dy = lm[0] - x[0, 0], lm[1] - x[1, 0]
    r2 = dx * dx + dy * dy
    r = math.sqrt(r2)
    return np.array([[-dx / r, -dy / r, 0.0, 0.0], [dy / r2, -dx / r2, 0.0, -1.0]])


def _residual(a, b):
    y = a - b
    y[1, 0] = wrap(y[1, 0])
    return y


def filterpy_ekf(params, u, ids, z):
    ekf = BmmEkf(params, X0, P0, np.diag([RANGE_STD**2, BEARING_STD**2]))
    zs = z.reshape(-1, 2, 1)
    lms = [LANDMARKS[i] for i in ids]
    for i in range(len(u)):
        ekf.predict(u=u[i])
        ekf.update(zs[i], _h_jacobian, _hx, args=(lms[i],), hx_args=(lms[i],), residual=_residual)
    return ekf.x[:, 0]


# ---------------------------------------------------------------------------
# C++: tick_bench
# ---------------------------------------------------------------------------

def _run(*cmd, cwd=ROOT):
    proc = subprocess.run([str(c) for c in cmd], cwd=cwd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(map(str, cmd))} failed:\n{proc.stdout}\n{proc.stderr}")
    return proc.stdout


def _module_build_dir() -> Path | None:
    """The CMake build of this tree that the imported ``safenav._core`` came from, if any."""
    for folder in Path(_core.__file__).resolve().parents:
        cache = folder / "CMakeCache.txt"
        if cache.is_file():
            home = re.search(r"^CMAKE_HOME_DIRECTORY:INTERNAL=(.*)$", cache.read_text(), re.MULTILINE)
            return folder if home and Path(home.group(1)).resolve() == ROOT else None
    return None


def build_tick_bench() -> Path:
    """Install safenav::core from the module's build (or a standalone Release
    build under build/) and build cpp/examples' tick_bench against it, under
    build/bench-guidance/ (reruns are incremental)."""
    cmake = shutil.which("cmake")
    if not cmake:
        raise RuntimeError("cmake is required to build tick_bench")
    gen = ["-G", "Ninja"] if shutil.which("ninja") else []
    work = ROOT / "build" / "bench-guidance"
    core = _module_build_dir()
    if core is None:
        core = work / "core"
        if not (core / "CMakeCache.txt").is_file():
            _run(cmake, "-S", ROOT, "-B", core, *gen, "-DCMAKE_BUILD_TYPE=Release", "-DSAFENAV_BUILD_PYTHON=OFF")
    _run(cmake, "--build", core, "--target", "safenav_core", "--parallel", "2")
    prefix = work / "prefix"
    _run(cmake, "--install", core, "--component", "cpp", "--prefix", prefix)
    examples = work / "examples"
    if not (examples / "CMakeCache.txt").is_file():
        _run(cmake, "-S", ROOT / "cpp" / "examples", "-B", examples, *gen, "-DCMAKE_BUILD_TYPE=Release",
             f"-DCMAKE_PREFIX_PATH={prefix}")
    _run(cmake, "--build", examples, "--target", "tick_bench")
    return examples / "tick_bench"


# ---------------------------------------------------------------------------
# Benchmarks
# ---------------------------------------------------------------------------

def bench_python(n_ticks, repeats):
    params, u, ids, z, truth = make_script(n_ticks, SEED)
    # Correctness first: the Localizer (gate off), FilterPy and the old per-step path agree.
    ours = ours_localizer(params, u, ids, z)
    fp = filterpy_ekf(params, u, ids, z)
    old = ours_ekf_steps(params, u, ids, z)
    d_fp = np.abs(ours - fp)
    d_fp[3] = abs(wrap(ours[3] - fp[3]))
    print(f"Python {n_ticks} ticks: final |Localizer - FilterPy| = {d_fp.max():.2e}, "
          f"|Localizer - old per-step Ekf| = {np.abs(ours - old).max():.2e}, "
          f"final position error {np.hypot(*(ours[:2] - truth[-1, :2])):.3f} m")
    if d_fp.max() > 1e-6:
        print("  WARNING: ours and FilterPy disagree by more than 1e-6 — check the models match")
    times = interleave({
        "ours": lambda: ours_localizer(params, u, ids, z),
        "filterpy": lambda: filterpy_ekf(params, u, ids, z),
        "old": lambda: ours_ekf_steps(params, u, ids, z),
        "ours_gated": lambda: ours_localizer(params, u, ids, z, gate=0.99),
    }, repeats)
    return {k: [t * 1e6 / n_ticks for t in v] for k, v in times.items()}


def bench_cpp(exe: Path, n_ticks, repeats):
    return json.loads(_run(exe, n_ticks, repeats))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="3 repeats, 2000 Python ticks, 20000 C++ ticks")
    ap.add_argument("--repeats", type=int, default=None, help="interleaved repeats (default 9, --quick 3)")
    ap.add_argument("--ticks", type=int, default=None, help="Python ticks per run (default 5000, --quick 2000)")
    ap.add_argument("--cpp-ticks", type=int, default=None, help="C++ ticks per repeat (default 200000, --quick 20000)")
    ap.add_argument("--tick-bench", type=Path, default=None, help="a built tick_bench to run instead of building one")
    args = ap.parse_args(argv)
    repeats = args.repeats or (3 if args.quick else 9)
    ticks = args.ticks or (2000 if args.quick else 5000)
    cpp_ticks = args.cpp_ticks or (20000 if args.quick else 200000)

    print_header(repeats, SEED)
    t_start = time.perf_counter()

    py = bench_python(ticks, repeats)
    exe = args.tick_bench or build_tick_bench()
    cpp = bench_cpp(exe, cpp_ticks, repeats)

    ours, fp, old, gated = (med(py[k]) for k in ("ours", "filterpy", "old", "ours_gated"))
    c_loc, c_gui = cpp["localizer_ns_per_tick"] / 1e3, cpp["guidance_ns_per_tick"] / 1e3
    c_cmd, c_chk = cpp["command_ns"] / 1e3, cpp["command_checked_ns"] / 1e3

    print()
    hdr = f"{'per tick (motion + range-bearing obs.)':<44}{'us/tick':>10}{'FilterPy/ours':>15}{'target':>9}{'met':>5}"
    print(hdr)
    print("-" * len(hdr))
    print(f"{'Python: Localizer (gate off)':<44}{ours:>10.2f}{fp / ours:>14.1f}x{'<=10us':>9}"
          f"{'yes' if ours <= PY_TARGET_US else 'NO':>5}")
    print(f"{'Python: Localizer, 99% gate (info)':<44}{gated:>10.2f}{fp / gated:>14.1f}x{'-':>9}{'-':>5}")
    print(f"{'Python: old Ekf + fresh MeasurementModel':<44}{old:>10.2f}{fp / old:>14.1f}x{'-':>9}{'-':>5}")
    print(f"{'Python: FilterPy ExtendedKalmanFilter':<44}{fp:>10.2f}{1.0:>14.1f}x{'-':>9}{'-':>5}")
    print(f"{'C++: Localizer (99% gate)':<44}{c_loc:>10.3f}{fp / c_loc:>14.0f}x{'<=2us':>9}"
          f"{'yes' if c_loc <= CPP_TARGET_US else 'NO':>5}")
    print(f"{'C++: Guidance tick (command+motion+obs.)':<44}{c_gui:>10.3f}{fp / c_gui:>14.0f}x{'-':>9}{'-':>5}")
    print(f"{'C++: command() alone, Centroid, no replan':<44}{c_cmd:>10.3f}{'-':>15}{'-':>9}{'-':>5}")
    print(f"{'C++: command() with the obstacle check':<44}{c_chk:>10.3f}{'-':>15}{'-':>9}{'-':>5}")
    print(f"  ranges [min-max] us/tick: Localizer {spread(py['ours'], 1)}, FilterPy {spread(py['filterpy'], 1)}, "
          f"old Ekf {spread(py['old'], 1)}; C++ Localizer {cpp['localizer_ns_min'] / 1e3:.3g}-"
          f"{cpp['localizer_ns_max'] / 1e3:.3g}, Guidance {cpp['guidance_ns_min'] / 1e3:.3g}-"
          f"{cpp['guidance_ns_max'] / 1e3:.3g}")
    print(f"  C++: {cpp['ticks']} ticks x {cpp['repeats']} repeats after 1000 warm-up ticks; "
          f"{cpp['localizer_applied_fraction']:.0%} of the observations applied")
    print()
    print("heap allocations per tick after warm-up (C++, counting operator new):")
    print(f"  Localizer motion + observe (EKF):          {cpp['localizer_allocs_per_tick']:g}"
          f"  {'(ok: none)' if cpp['localizer_allocs_per_tick'] == 0 else '(EXPECTED 0)'}")
    print(f"  Guidance command + motion + observe:       {cpp['guidance_allocs_per_tick']:g}")
    print(f"  command() alone / with the obstacle check: {cpp['command_allocs_per_call']:g} / "
          f"{cpp['command_checked_allocs_per_call']:g}")
    print(f"  (constructing one Guidance: {cpp['guidance_construction_allocs']} allocations)")
    print(f"\n(total {time.perf_counter() - t_start:.1f} s)")


if __name__ == "__main__":
    main()
