"""Seeded fuzz test of the public API (issue #12, item 4).

The rule for every call: it returns a result whose floats are all finite, or
it raises an ordinary exception (``ValueError``, ``TypeError``,
``IndexError``, ``KeyError``, ``RuntimeError``, ``OverflowError``) with a
short message.  Anything else fails: a crash (segfault, abort), a hang or a
call slower than ``CALL_LIMIT_S``, a NaN or inf in the result,
``MemoryError``, ``SystemError`` or any other exception type, or a message
longer than ``MAX_MESSAGE`` characters (pybind11's own TypeError for
arguments of the wrong type lists the signatures and is allowed as it is).
``FilterResult.nis`` is NaN by design on steps without an update; only its
other entries are checked.  The online ``Localizer`` (EKF or particle filter,
plain or augmented) gets sequences of inputs at hostile timestamps (jumps of
1e8 and 1e12 s, repeats, steps back, ±1e300): an input that raises must leave
the localizer exactly as it was, and one that returns must leave a finite
estimate with a symmetric, positive semi-definite covariance.  Localization (``trilaterate``,
``triangulate_bearings``) is not fuzzed here: it reports failures as a
status with a NaN position, by design of that module.

Each call draws its arguments from ``np.random.default_rng([seed, i])``: valid
values most of the time (so calls get past validation into the numerics) and
hostile ones otherwise (NaN, ±inf, ±1e308, 1e-310, 0, negatives, empty and
wrongly shaped arrays, None, strings, bools, huge integers, values scaled by
1e308 or 1e-310).  A call depends on its index alone, so any one reproduces
by itself::

    python tests/test_fuzz.py SEED I I+1      # prints the call and its outcome

The calls run in batches in a child process (this file run as a script).  The
child reports each call before and after running it, so the parent knows
which call crashed or hung; it then starts a new child at the next call.
"""

from __future__ import annotations

import json
import os
import queue
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from dataclasses import fields, is_dataclass

import numpy as np
import pytest

SEED = 12
CALL_LIMIT_S = 10.0         # a call slower than this (measured in the child) fails
HANG_S = 60.0               # no word from the child for this long: the call hung
MAX_MESSAGE = 400
PYBIND_GENERIC = "incompatible"  # pybind11's "incompatible function/constructor arguments"

from fuzz_calls import ALLOWED, NAMES, TARGETS, Draw  # noqa: E402  (the calls and their arguments)

# ---------------------------------------------------------------------------
# Checking one call
# ---------------------------------------------------------------------------

def nonfinite(obj, where="result", depth=0):
    """Where ``obj`` holds a NaN or inf (a path like ``result[2].x``), or None."""
    if depth > 4 or obj is None or isinstance(obj, (bool, str, int, np.integer, np.bool_)):
        return None
    if isinstance(obj, (float, np.floating, complex, np.complexfloating)):
        return None if np.isfinite(obj) else f"{where} = {obj}"
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind in "fc" and not np.isfinite(obj).all():
            return f"{where} has {np.count_nonzero(~np.isfinite(obj))} non-finite entries"
        return None
    if isinstance(obj, (list, tuple)):
        return next((w for j, v in enumerate(obj) if (w := nonfinite(v, f"{where}[{j}]", depth + 1))), None)
    if isinstance(obj, dict):
        return next((w for k, v in obj.items() if (w := nonfinite(v, f"{where}[{k!r}]", depth + 1))), None)
    if is_dataclass(obj):
        if hasattr(obj, "nis_dof"):  # FilterResult: NaN NIS marks a step without an update (documented)
            obj = {"states": obj.states, "covariances": obj.covariances, "nis": obj.nis[obj.nis_dof > 0]}
            return nonfinite(obj, where, depth + 1)
        return next((w for f in fields(obj) if (w := nonfinite(getattr(obj, f.name), f"{where}.{f.name}",
                                                               depth + 1))), None)
    if type(obj).__module__.startswith("safenav"):
        for name in dir(obj):
            if name.startswith("_"):
                continue
            v = getattr(obj, name)
            if not callable(v) and (w := nonfinite(v, f"{where}.{name}", depth + 1)):
                return w
    return None


def run_call(seed: int, i: int, verbose: bool = False) -> dict:
    """Run call ``i``; return its outcome: ok, raised (allowed) or fail (with why)."""
    d = Draw(seed, i)
    name = NAMES[int(d.rng.integers(len(NAMES)))]
    t0 = time.perf_counter()
    try:
        result = TARGETS[name](d)
    except ALLOWED as exc:
        msg = str(exc)
        out = {"out": "raised", "kind": type(exc).__name__}
        if isinstance(exc, TypeError) and PYBIND_GENERIC in msg:
            out["kind"] = "pybind11 TypeError"  # its own wording, with the signatures: allowed at any length
        elif len(msg) > MAX_MESSAGE:
            out = {"out": "fail", "why": f"{type(exc).__name__} message of {len(msg)} chars: {msg[:200]}..."}
    except BaseException as exc:  # noqa: BLE001 - any other exception is what we look for
        out = {"out": "fail", "why": f"{type(exc).__name__}: {str(exc)[:300]}"}
    else:
        bad = nonfinite(result)
        out = {"out": "fail", "why": f"non-finite result: {bad}"} if bad else {"out": "ok"}
    sec = time.perf_counter() - t0
    if sec > CALL_LIMIT_S and out["out"] != "fail":
        out = {"out": "fail", "why": f"took {sec:.1f} s (limit {CALL_LIMIT_S} s)"}
    out.update(i=i, target=name, sec=round(sec, 4))
    if out["out"] == "fail" or verbose:
        out["args"] = d.log
    return out


# ---------------------------------------------------------------------------
# Supervision: calls run in child processes
# ---------------------------------------------------------------------------

def _child(seed, start, stop, stderr):
    return subprocess.Popen([sys.executable, __file__, str(seed), str(start), str(stop)], stdout=subprocess.PIPE,
                            stderr=stderr, text=True, env=dict(os.environ, OMP_NUM_THREADS="1"))


def _supervise(seed: int, start: int, stop: int) -> tuple[Counter, list[dict]]:
    """Run calls start … stop−1 in child processes, a new child after each crash or hang."""
    counts: Counter = Counter()
    failures: list[dict] = []
    i = start
    while i < stop:
        first, started = i, None
        err = tempfile.TemporaryFile("w+")
        proc = _child(seed, i, stop, err)
        lines: queue.Queue = queue.Queue()
        threading.Thread(target=lambda p=proc: [lines.put(x) for x in p.stdout] + [lines.put(None)],
                         daemon=True).start()
        while True:
            try:
                line = lines.get(timeout=HANG_S)
            except queue.Empty:
                proc.kill()
                proc.wait()
                why = f"hang: no result within {HANG_S} s"
                break
            if line is None:
                proc.wait()
                why = f"child died (exit code {proc.returncode})"
                break
            try:
                rec = json.loads(line)
            except json.JSONDecodeError:
                continue  # something the library printed
            if "start" in rec:
                started = rec["start"]
                continue
            started = None
            counts[rec["out"]] += 1
            counts[f"{rec['target']}:{rec['out']}"] += 1
            if rec["out"] == "raised":
                counts[f"raised {rec['kind']}"] += 1
            if rec["out"] == "fail":
                failures.append(rec)
            i = rec["i"] + 1
        if started is not None:  # the call that crashed or hung fails; go on after it
            counts["fail"] += 1
            failures.append({"i": started, "why": why})
            i = started + 1
        elif i == first and i < stop:  # not a single call ran: the child cannot start
            err.seek(0)
            raise RuntimeError(f"fuzz child ({why}) ran no call: {err.read()[-2000:]}")
        proc.stdout.close()
        err.close()
    return counts, failures


def fuzz(seed: int, n_calls: int, batch: int = 2500, jobs: int = 2) -> tuple[Counter, list[dict]]:
    """Run calls 0 … n_calls−1 in batches, ``jobs`` children at a time; return the counts and the failures."""
    ranges = [(a, min(a + batch, n_calls)) for a in range(0, n_calls, batch)]
    with ThreadPoolExecutor(jobs) as pool:
        results = list(pool.map(lambda r: _supervise(seed, *r), ranges))
    counts: Counter = sum((c for c, _ in results), Counter())
    return counts, sorted((f for _, fs in results for f in fs), key=lambda f: f["i"])


def _report(seed, counts, failures):
    lines = [f"fuzz seed {seed}: {counts['ok']} returned finite results, {counts['raised']} raised an allowed "
             f"error, {counts['fail']} failed"]
    for f in failures[:20]:
        lines.append(f"  call {f.get('i')} ({f.get('target', '?')}): {f['why']}  args={f.get('args')}")
        lines.append(f"    reproduce: python tests/test_fuzz.py {seed} {f.get('i')} {(f.get('i') or 0) + 1}")
    return "\n".join(lines)


def test_fuzz_public_api():
    """10⁴ seeded calls of the public API, each finite or an allowed error."""
    counts, failures = fuzz(SEED, 10_000)
    print(_report(SEED, counts, failures))
    assert counts["ok"] + counts["raised"] + counts["fail"] == 10_000
    assert not failures, _report(SEED, counts, failures)
    # The draw reaches the numerics, not only the validation: most calls return.
    assert counts["ok"] > 3_000 and counts["raised"] > 1_000


@pytest.mark.slow
def test_fuzz_public_api_long():
    """10⁵ seeded calls (another seed), behind the slow marker."""
    counts, failures = fuzz(SEED + 1, 100_000, batch=10_000)
    print(_report(SEED + 1, counts, failures))
    assert not failures, _report(SEED + 1, counts, failures)


def test_supervisor_counts_a_crash_and_goes_on(monkeypatch):
    """A call that kills its process is a failure, and the calls after it still run."""
    monkeypatch.setenv("SAFENAV_FUZZ_CRASH_AT", "3")
    counts, failures = fuzz(SEED, 6, batch=6, jobs=1)
    assert [f["i"] for f in failures] == [3]
    assert "child died" in failures[0]["why"]
    assert counts["ok"] + counts["raised"] == 5


def _main(argv):
    import safenav.navigation  # noqa: F401 - import before the clock runs: the first call is timed too

    seed, start, stop = (int(a) for a in argv[:3])
    crash_at = int(os.environ.get("SAFENAV_FUZZ_CRASH_AT", -1))
    for i in range(start, stop):
        print(json.dumps({"start": i}), flush=True)
        if i == crash_at:
            os.abort()
        rec = run_call(seed, i, verbose=stop - start == 1)
        print(json.dumps(rec), flush=True)


if __name__ == "__main__":
    _main(sys.argv[1:])
