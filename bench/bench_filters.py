#!/usr/bin/env python
"""Filter benchmarks: safenav against peers, side by side in one process.

Run from the repository root::

    python bench/bench_filters.py            # full run (9 interleaved repeats)
    python bench/bench_filters.py --quick    # 3 repeats, fewer synthetic trials

What is compared (same trajectory, same prior, same noise parameters):

1. EKF — ``safenav.filter_trajectory(filter="ekf", position=...)`` (one C++
   call, position fixes only) against FilterPy's ``ExtendedKalmanFilter``
   driven step by step from Python, with ``predict_x`` overridden by the BMM
   and F (Jacobian) and Q = G Σ Gᵀ set every step.  Both use the Joseph-form
   covariance update, so their estimates must agree to rounding; the script
   checks that.  Our per-step Python API (``safenav.Ekf`` predict/update in a
   Python loop) is timed too, for information.  Target: ours ≥ 100× faster.
2. PF, 1000 particles — ``filter_trajectory(filter="pf", bandwidth_scale=0)``,
   the bootstrap (SIR) filter that the peer implements, against a
   vectorised NumPy particle filter written here with the same model (noisy
   BMM per particle, Gaussian position log-likelihood, log-weights normalised
   with logsumexp, systematic resampling when ESS < 0.5 N, weighted mean with
   a circular mean for θ and weighted covariance every step), kept in one
   (6, N) array with cos/sin of θ cached and in-place updates, so that it is a
   strong peer.  The random streams differ, so the estimates differ; the
   script compares their ADE against the truth.  Target: ours ≥ 10× faster,
   judged on the median over repeats of the per-repeat ratio (NumPy time /
   our time, the two run back to back).  Our default, regularised PF (kernel
   update and covariance floor, a different algorithm) is timed too, for
   information.
3. The regularised PF's prediction and IMU update, µs per call at the same
   particle count (for information).
4. Time per trial on the synthetic data set (``experiments.run_synthetic``,
   the paper's setting: 200 steps, position fixes + IMU, 1000 particles) beside
   the paper's Table figures (EKF 3.98 ms, PF 9551 ms per trial).

Every timing is repeated; ours and the peer alternate within each repeat
(order flipped every repeat) and medians are reported with the min–max range.
"""

from __future__ import annotations

import argparse
import math
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import safenav
from safenav.experiments import PAPER_SYNTHETIC, PRIOR_STD, run_synthetic
from safenav.measurement import LANBLOC_STD

try:
    from filterpy.kalman import ExtendedKalmanFilter
except ImportError:  # pragma: no cover - filterpy is a test extra
    sys.exit("bench_filters.py needs FilterPy: pip install filterpy (or pip install -e .[test])")

SEED = 20240601
TWO_PI = 2.0 * math.pi
EKF_TARGET = 100.0   # ours >= 100x faster per step than FilterPy
PF_TARGET = 10.0     # ours >= 10x faster per step than the NumPy PF


# ---------------------------------------------------------------------------
# Data
# ---------------------------------------------------------------------------

def make_case(n_steps: int, seed: int):
    """A synthetic trajectory with position fixes only (no IMU), and a noisy prior.

    The acceleration amplitude is scaled by 200/n_steps so that the commanded
    speed profile has the same range as the default 200-step data set (the
    paper's a(t) = 3 sin(4πt/T) integrates to a larger swing for longer T)."""
    cfg = safenav.SyntheticConfig(n_steps=n_steps, imu=False, accel_amplitude=3.0 * 200 / n_steps)
    data = safenav.synthetic_trajectory(cfg, seed)
    rng = np.random.default_rng(seed + 1)
    x0 = data.x0 + rng.standard_normal(4) * PRIOR_STD
    P0 = np.diag(PRIOR_STD**2)
    R = cfg.position_cov()
    return cfg.params(), data, x0, P0, R


def wrap(a):
    return (a + math.pi) % TWO_PI - math.pi


def ade(est_xy, truth_xy) -> float:
    return float(np.mean(np.hypot(*(est_xy - truth_xy).T)))


# ---------------------------------------------------------------------------
# Peer 1: FilterPy EKF with the BMM
# ---------------------------------------------------------------------------

class BmmEkf(ExtendedKalmanFilter):
    """FilterPy EKF whose prediction is the BMM (eqs. 3, 4, 7/9).

    ``predict_x`` computes f(x, u) and, from the same intermediates, sets
    ``self.F`` (∂f/∂x) and ``self.Q`` (G Σ_ε Gᵀ) which FilterPy's ``predict``
    then uses in P = F P Fᵀ + Q."""

    def __init__(self, params, x0, P0, R):
        super().__init__(dim_x=4, dim_z=2)
        p = params
        self.a, self.d, self.vmax = p.acceleration, p.deceleration, p.max_speed
        self.dt = p.dt
        self.lim = p.max_heading_rate * p.dt
        self.k = p.dt / (1.0 + p.terrain_effect)
        self.sigma2 = np.array([p.position_noise**2, p.position_noise**2, p.speed_noise**2, p.heading_noise**2])
        self.x = np.asarray(x0, float).reshape(4, 1).copy()
        self.P = np.asarray(P0, float).copy()
        self.R = np.asarray(R, float).copy()

    def predict_x(self, u=0):
        x, y, v, th = self.x[:, 0]
        desired, dth = u
        a_dt, d_dt = self.a * self.dt, self.d * self.dt
        if desired > v:
            up = v + a_dt
            v1 = max(0.0, min(up, desired, self.vmax))
            dv = 1.0 if (up <= desired and up <= self.vmax and up >= 0.0) else 0.0
        else:
            down = v - d_dt
            v1 = min(self.vmax, max(down, desired, 0.0))
            dv = 1.0 if (down >= desired and down >= 0.0 and down <= self.vmax) else 0.0
        th1 = wrap(th + min(max(dth, -self.lim), self.lim))
        k = self.k
        c, s = math.cos(th1), math.sin(th1)
        self.F = np.array([[1.0, 0.0, k * c * dv, -k * v1 * s],
                           [0.0, 1.0, k * s * dv, k * v1 * c],
                           [0.0, 0.0, dv, 0.0],
                           [0.0, 0.0, 0.0, 1.0]])
        G = np.array([[1.0, 0.0, k * c, -k * v1 * s],
                      [0.0, 1.0, k * s, k * v1 * c],
                      [0.0, 0.0, 1.0, 0.0],
                      [0.0, 0.0, 0.0, 1.0]])
        self.Q = (G * self.sigma2) @ G.T
        self.x = np.array([[x + k * v1 * c], [y + k * v1 * s], [v1], [th1]])


_H_POS = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])


def _h_jacobian(x):
    return _H_POS


def _hx(x):
    return x[:2]


def filterpy_ekf(params, controls, position, x0, P0, R) -> np.ndarray:
    ekf = BmmEkf(params, x0, P0, R)
    out = np.empty((len(controls) + 1, 4))
    out[0] = ekf.x[:, 0]
    for i in range(len(controls)):
        ekf.predict(u=controls[i])
        ekf.update(position[i].reshape(2, 1), _h_jacobian, _hx)
        out[i + 1] = ekf.x[:, 0]
    return out


# ---------------------------------------------------------------------------
# Ours, per-step Python API (information only)
# ---------------------------------------------------------------------------

def ours_ekf_steps(params, controls, position, x0, P0, R) -> np.ndarray:
    ekf = safenav.Ekf(params, x0, P0)
    model = safenav.MeasurementModel.position(R)
    out = np.empty((len(controls) + 1, 4))
    out[0] = ekf.x
    for i in range(len(controls)):
        ekf.predict(controls[i])
        ekf.update(model, position[i])
        out[i + 1] = ekf.x
    return out


def ours_ekf_batch(params, controls, position, x0, P0, R):
    return safenav.filter_trajectory(controls, x0, P0, params=params, filter="ekf",
                                     position=position, position_cov=R)


def ours_pf_batch(params, controls, position, x0, P0, R, n, seed, bandwidth_scale=0.0):
    """Our PF; by default the bootstrap (SIR) filter, the peer's algorithm (bandwidth_scale = 0)."""
    return safenav.filter_trajectory(controls, x0, P0, params=params, filter="pf", position=position,
                                     position_cov=R, n_particles=n, seed=seed, bandwidth_scale=bandwidth_scale)


# ---------------------------------------------------------------------------
# Peer 2: vectorised NumPy particle filter with the same model
# ---------------------------------------------------------------------------

def _pf_particles(x0, P0, n, rng):
    """The particles drawn from N(x0, P0) in one (6, n) array: x, y, v (>= 0), θ (wrapped), cos θ, sin θ."""
    init = x0 + rng.standard_normal((n, 4)) @ np.linalg.cholesky(P0).T
    S = np.empty((6, n))
    S[:4] = init.T
    np.maximum(S[2], 0.0, out=S[2])
    S[3] = wrap(S[3])
    np.cos(S[3], out=S[4])
    np.sin(S[3], out=S[5])
    return S


def _pf_predict(S, eps, p, desired, dth):
    """The noisy BMM (eqs. 3, 4, 6, 7/9) on the particles in place, as Bmm::transition;
    ``eps`` holds the step's scaled noise (x, y, v, θ)."""
    x, y, v, th, c, s = S
    a_dt, d_dt, vmax = p.acceleration * p.dt, p.deceleration * p.dt, p.max_speed
    lim = p.max_heading_rate * p.dt
    v_up = np.clip(np.minimum(v + a_dt, desired), 0.0, vmax)
    v_down = np.clip(np.maximum(v - d_dt, desired), 0.0, vmax)
    v1 = np.where(desired > v, v_up, v_down)
    v1 += eps[2]
    np.clip(v1, 0.0, vmax, out=v)
    th += min(max(dth, -lim), lim)
    th += eps[3]
    th[th > math.pi] -= TWO_PI
    th[th <= -math.pi] += TWO_PI
    np.cos(th, out=c)
    np.sin(th, out=s)
    kv = (p.dt / (1.0 + p.terrain_effect)) * v
    x += kv * c
    x += eps[0]
    y += kv * s
    y += eps[1]


def numpy_pf(params, controls, position, x0, P0, R, n, seed, threshold=0.5):
    """Bootstrap PF on the noisy BMM; returns (states (N+1,4), covs (N+1,4,4), n_resampled).

    Written to be a strong peer: the particles live in one (6, n) array (x, y,
    v, θ, cos θ, sin θ) so that resampling is a single fancy index, cos/sin
    computed in the prediction are reused by the estimate, the noise goes into
    a preallocated buffer and updates are in place where NumPy allows."""
    p = params
    rng = np.random.default_rng(seed)
    S = _pf_particles(x0, P0, n, rng)
    logw = np.full(n, -math.log(n))
    w = np.full(n, 1.0 / n)
    sig = np.array([p.position_noise, p.position_noise, p.speed_noise, p.heading_noise])[:, None]
    Ri = np.linalg.inv(R)
    ri00, ri01, ri11 = Ri[0, 0], 2.0 * Ri[0, 1], Ri[1, 1]
    steps = len(controls)
    states = np.empty((steps + 1, 4))
    covs = np.empty((steps + 1, 4, 4))
    pointers = np.arange(n, dtype=float)
    eps = np.empty((4, n))
    dev = np.empty((4, n))
    n_resampled = 0

    def estimate(row, S, w):
        m = S[:3] @ w
        mth = math.atan2(S[5] @ w, S[4] @ w)  # circular mean
        np.subtract(S[:3], m[:, None], out=dev[:3])
        d3 = dev[3]
        np.subtract(S[3], mth, out=d3)
        d3[d3 > math.pi] -= TWO_PI
        d3[d3 <= -math.pi] += TWO_PI
        states[row] = (*m, mth)
        covs[row] = (dev * w) @ dev.T

    estimate(0, S, w)
    for i in range(steps):
        desired, dth = controls[i]
        rng.standard_normal(out=eps)
        eps *= sig
        _pf_predict(S, eps, p, desired, dth)
        # Update: Gaussian log-likelihood of the position fix.
        z = position[i]
        if np.isfinite(z[0]):
            d0, d1 = z[0] - S[0], z[1] - S[1]
            logw -= 0.5 * (ri00 * d0 * d0 + ri01 * d0 * d1 + ri11 * d1 * d1)
            mx = logw.max()
            e = np.exp(logw - mx)
            total = e.sum()
            logw -= mx + math.log(total)            # logsumexp normalisation
            w = e / total
            if 1.0 / (w @ w) < threshold * n:       # systematic resampling below the ESS threshold
                cum = np.cumsum(w)
                cum[-1] = 1.0
                S = S[:, np.searchsorted(cum, (rng.random() + pointers) / n)]
                logw = np.full(n, -math.log(n))
                w = np.full(n, 1.0 / n)
                n_resampled += 1
        estimate(i + 1, S, w)
    return states, covs, n_resampled


# ---------------------------------------------------------------------------
# Timing helpers
# ---------------------------------------------------------------------------

def timed(fn, inner=1):
    """Seconds per call of fn (mean over `inner` back-to-back calls) and the last result."""
    t0 = time.perf_counter()
    for _ in range(inner):
        res = fn()
    return (time.perf_counter() - t0) / inner, res


def interleave(fns: dict, repeats: int, inner: dict | None = None):
    """Run each fn once per repeat, order flipped every repeat; returns {name: [seconds]}."""
    inner = inner or {}
    names = list(fns)
    times = {k: [] for k in names}
    for name in names:  # warm-up (first-call costs, caches)
        fns[name]()
    for r in range(repeats):
        for name in (names if r % 2 == 0 else names[::-1]):
            times[name].append(timed(fns[name], inner.get(name, 1))[0])
    return times


def med(xs):
    return float(np.median(xs))


def spread(xs, scale):
    return f"{min(xs) * scale:.3g}-{max(xs) * scale:.3g}"


def git_info() -> str:
    root = Path(__file__).resolve().parents[1]
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=root, capture_output=True,
                              text=True, timeout=5).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--", "cpp", "python"], cwd=root,
                               capture_output=True, text=True, timeout=5).stdout.strip()
        return f"{head}{' (cpp/python modified)' if dirty else ''}"
    except Exception:  # noqa: BLE001 - informational only
        return "unknown"


def print_header(repeats: int, seed: int) -> None:
    """The versions, the commit, the machine and the repeat count, as every benchmark here prints them."""
    print(f"safenav {safenav.__version__} @ {git_info()} | numpy {np.__version__} | "
          f"python {platform.python_version()} | {platform.machine()} | {platform.processor() or ''} "
          f"| cores: {__import__('os').cpu_count()}")
    print(f"seed {seed}, {repeats} interleaved repeats, medians [min-max]\n")


# ---------------------------------------------------------------------------
# Benchmarks
# ---------------------------------------------------------------------------

def bench_ekf(n_steps, repeats):
    params, data, x0, P0, R = make_case(n_steps, SEED)
    u, z = data.controls, data.position
    # Correctness first: FilterPy and ours must agree (both Joseph form).
    ref = ours_ekf_batch(params, u, z, x0, P0, R).states
    fp = filterpy_ekf(params, u, z, x0, P0, R)
    st = ours_ekf_steps(params, u, z, x0, P0, R)
    d_fp = np.abs(ref - fp)
    d_fp[:, 3] = np.abs(wrap(ref[:, 3] - fp[:, 3]))
    d_st = np.max(np.abs(ref - st))
    print(f"EKF  {n_steps} steps: max |ours - FilterPy| = {d_fp.max():.2e}, "
          f"max |batch - per-step API| = {d_st:.2e}, ADE ours {ade(ref[:, :2], data.states[:, :2]):.4f} m, "
          f"FilterPy {ade(fp[:, :2], data.states[:, :2]):.4f} m")
    if d_fp.max() > 1e-6:
        print("  WARNING: ours and FilterPy disagree by more than 1e-6 — check the models match")
    # One batch call is sub-millisecond: time 20 back-to-back calls per repeat.
    times = interleave({
        "ours": lambda: ours_ekf_batch(params, u, z, x0, P0, R),
        "filterpy": lambda: filterpy_ekf(params, u, z, x0, P0, R),
        "ours_step": lambda: ours_ekf_steps(params, u, z, x0, P0, R),
        # information: the same batch call with no measurements (prediction only)
        "ours_predict": lambda: safenav.filter_trajectory(u, x0, P0, params=params, filter="ekf"),
    }, repeats, inner={"ours": 20, "ours_predict": 20})
    return {k: [t * 1e6 / n_steps for t in v] for k, v in times.items()}


def bench_pf(n_steps, n_particles, repeats):
    params, data, x0, P0, R = make_case(n_steps, SEED)
    u, z = data.controls, data.position
    truth = data.states[:, :2]
    acc = {"ours": [], "numpy": [], "regularised": []}
    resampled = {"ours": [], "numpy": [], "regularised": []}
    times = {"ours": [], "numpy": [], "regularised": []}
    # warm-up
    ours_pf_batch(params, u, z, x0, P0, R, n_particles, 0)
    numpy_pf(params, u, z, x0, P0, R, n_particles, 0)
    for r in range(repeats):
        seed = 1000 + r  # a different PF seed each repeat: accuracy is a median over seeds
        order = ["ours", "numpy", "regularised"] if r % 2 == 0 else ["regularised", "numpy", "ours"]
        for name in order:
            if name != "numpy":
                h = 1.0 if name == "regularised" else 0.0
                t, res = timed(lambda: ours_pf_batch(params, u, z, x0, P0, R, n_particles, seed, h))
                states, nres = res.states, res.n_resampled
            else:
                t, (states, _, nres) = timed(lambda: numpy_pf(params, u, z, x0, P0, R, n_particles, seed))
            times[name].append(t * 1e6 / n_steps)
            acc[name].append(ade(states[:, :2], truth))
            resampled[name].append(nres)
    ekf_states = ours_ekf_batch(params, u, z, x0, P0, R).states
    print(f"PF   {n_steps} steps, {n_particles} particles: ADE vs truth (median over {repeats} seeds) "
          f"ours {med(acc['ours']):.4f} m [{spread(acc['ours'], 1)}], "
          f"NumPy {med(acc['numpy']):.4f} m [{spread(acc['numpy'], 1)}], "
          f"ours regularised {med(acc['regularised']):.4f} m, "
          f"(EKF on the same data {ade(ekf_states[:, :2], truth):.4f} m); "
          f"resamplings/run ours {med(resampled['ours']):.0f}, NumPy {med(resampled['numpy']):.0f}")
    return times, acc


def bench_pf_passes(n_particles, repeats, calls=300):
    """The regularised PF's two per-step passes, µs per call (median over repeats): the noisy
    prediction with its moment-matched draws, and the IMU's (v, θ) ensemble update."""
    params = safenav.BmmParams()
    pf = safenav.ParticleFilter(params, [0.0, 0.0, 2.0, 0.2], np.diag([1.0, 1.0, 0.04, 0.01]),
                                n_particles=n_particles, seed=3)
    imu = safenav.MeasurementModel.speed_heading(np.diag([0.01, 0.0004]))
    u, z = np.array([2.0, 0.01]), np.array([2.0, 0.2])
    for _ in range(50):
        pf.predict(u)
        pf.update(imu, z)
    out = {"predict": [], "imu": []}
    for _ in range(repeats):
        out["predict"].append(timed(lambda: [pf.predict(u) for _ in range(calls)])[0] * 1e6 / calls)
        out["imu"].append(timed(lambda: [pf.update(imu, z) for _ in range(calls)])[0] * 1e6 / calls)
    return out


def bench_synthetic(trials):
    df = run_synthetic(trials, filters=("ekf", "pf"), seed=SEED)
    return {f: df.loc[df["filter"] == f, "ms_per_trial"].to_numpy() for f in ("ekf", "pf")}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="3 repeats and 10 synthetic trials")
    ap.add_argument("--repeats", type=int, default=None, help="interleaved repeats (default 9, --quick 3)")
    ap.add_argument("--ekf-steps", type=int, default=2000)
    ap.add_argument("--pf-steps", type=int, default=300)
    ap.add_argument("--particles", type=int, default=1000)
    ap.add_argument("--trials", type=int, default=None, help="synthetic trials (default 20, --quick 10)")
    args = ap.parse_args(argv)
    repeats = args.repeats or (3 if args.quick else 9)
    trials = args.trials or (10 if args.quick else 20)

    print_header(repeats, SEED)
    t_start = time.perf_counter()

    ekf = bench_ekf(args.ekf_steps, repeats)
    pf, _ = bench_pf(args.pf_steps, args.particles, repeats)
    passes = bench_pf_passes(args.particles, repeats)
    syn = bench_synthetic(trials)

    e_ours, e_fp, e_step = med(ekf["ours"]), med(ekf["filterpy"]), med(ekf["ours_step"])
    p_ours, p_np = med(pf["ours"]), med(pf["numpy"])
    p_ratios = [t_np / t_ours for t_np, t_ours in zip(pf["numpy"], pf["ours"])]  # paired, per repeat
    e_ratio, p_ratio = e_fp / e_ours, med(p_ratios)

    print()
    hdr = f"{'benchmark':<38}{'ours us/step':>16}{'peer us/step':>16}{'speed-up':>10}{'target':>9}{'met':>5}"
    print(hdr)
    print("-" * len(hdr))
    print(f"{f'EKF batch vs FilterPy EKF ({args.ekf_steps} st)':<38}{e_ours:>16.3f}{e_fp:>16.2f}"
          f"{e_ratio:>9.0f}x{'>=100x':>9}{'yes' if e_ratio >= EKF_TARGET else 'NO':>5}")
    print(f"{'EKF per-step API vs FilterPy (info)':<38}{e_step:>16.2f}{e_fp:>16.2f}{e_fp / e_step:>9.1f}x"
          f"{'-':>9}{'-':>5}")
    print(f"{'EKF batch, predict only (info)':<38}{med(ekf['ours_predict']):>16.3f}{'-':>16}{'-':>10}"
          f"{'-':>9}{'-':>5}")
    print(f"{f'PF {args.particles} batch vs NumPy PF ({args.pf_steps} st)':<38}{p_ours:>16.2f}{p_np:>16.2f}"
          f"{p_ratio:>9.1f}x{'>=10x':>9}{'yes' if p_ratio >= PF_TARGET else 'NO':>5}")
    print(f"{'PF regularised (the default; info)':<38}{med(pf['regularised']):>16.2f}{p_np:>16.2f}"
          f"{p_np / med(pf['regularised']):>9.1f}x{'-':>9}{'-':>5}")
    print(f"  PF speed-up is the median of {len(p_ratios)} per-repeat ratios "
          f"[{min(p_ratios):.1f}-{max(p_ratios):.1f}]; ratio of the medians {p_np / p_ours:.1f}x")
    print("  ranges [min-max] us/step: "
          f"EKF ours {spread(ekf['ours'], 1)}, FilterPy {spread(ekf['filterpy'], 1)}, "
          f"per-step API {spread(ekf['ours_step'], 1)}; PF ours {spread(pf['ours'], 1)}, "
          f"NumPy {spread(pf['numpy'], 1)}")
    print(f"{f'PF regularised predict, per call (info)':<38}{med(passes['predict']):>16.2f}{'-':>16}{'-':>10}"
          f"{'-':>9}{'-':>5}")
    print(f"{f'PF regularised IMU update (info)':<38}{med(passes['imu']):>16.2f}{'-':>16}{'-':>10}"
          f"{'-':>9}{'-':>5}")
    print()
    hdr2 = f"{f'synthetic data set, {trials} trials':<38}{'ours ms/trial':>16}{'paper ms/trial':>16}{'paper/ours':>12}"
    print(hdr2)
    print("-" * len(hdr2))
    for f in ("ekf", "pf"):
        ours_ms, paper_ms = med(syn[f]), PAPER_SYNTHETIC[f]["ms_per_trial"]
        print(f"{f.upper():<38}{ours_ms:>16.3f}{paper_ms:>16.2f}{paper_ms / ours_ms:>11.0f}x")
    print(f"\n(total {time.perf_counter() - t_start:.1f} s)")


if __name__ == "__main__":
    main()
