"""The one way safenav writes a result file, and the run folder's manifest.

Every file safenav writes (tables, figures, reports, JSON) goes through
:func:`atomic_write`:

1. a temporary file is created *exclusively* in the target's folder
   (:func:`tempfile.mkstemp`: ``O_CREAT | O_EXCL``, a random name with the
   prefix ``.safenav-tmp-``), so a symlink planted at a temporary name is
   never followed and no fixed name can be raced;
2. the writer fills it through the open file handle; it is flushed and
   fsync'ed, and its mode set to ``0o666 & ~umask`` (mkstemp creates 0600;
   result files follow the user's umask like any file the user writes);
3. it is renamed over the target (``os.replace``): a symlink at the target is
   replaced itself, never followed, so a result cannot land outside the
   folder;
4. it is removed on any exception, on KeyboardInterrupt and on SIGTERM (the
   command line turns SIGTERM into ``SystemExit``).

A ``kill -9`` cannot be caught and may leave a ``.safenav-tmp-*`` file behind:
the next write into that folder removes such files older than
:data:`STALE_TEMP_S`, and the killed run has no manifest.

:class:`RunFolder` records every file written under its folder while it is
open and, when the run finishes without an exception, writes
``manifest.json`` *last*: each file's size and SHA-256, the command line,
parameters, seed and software versions.  A folder without a manifest is an
interrupted or failed run; :func:`verify_run` says so.

Tables (:func:`write_table`) keep wall-time columns (:data:`TIMING_COLUMNS`)
out of the table itself, in a ``<name>_timings.csv`` beside it, so that a
table of a fixed-seed run is byte-identical whatever the number of workers or
the scheduler; :func:`read_table` joins them back.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import platform
import subprocess
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["atomic_write", "write_text", "write_json", "write_table", "markdown_table", "read_table", "save_figure",
           "RunFolder", "IncompleteRunError", "verify_run", "versions", "TIMING_COLUMNS", "MANIFEST", "TEMP_PREFIX",
           "STALE_TEMP_S"]

TEMP_PREFIX = ".safenav-tmp-"
#: A temporary file this old (seconds since its last write) is left from a killed run and is removed.
STALE_TEMP_S = 600.0
MANIFEST = "manifest.json"
#: Wall-time columns: the only ones that differ between runs with one seed.
TIMING_COLUMNS = ("time_ms", "time_per_step_us", "ms_per_trial", "us_per_step", "time ms", "µs/step",
                  "camera ms/trial")

_LOCK = threading.Lock()
_RUNS: list["RunFolder"] = []          # the open run folders (a stack)


class IncompleteRunError(ValueError):
    """A run folder without a valid manifest: the run was interrupted or failed, or its files changed since."""


def _umask() -> int:
    """The process umask, read without changing it (Linux); else set and restored under a lock."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    with _LOCK:
        mask = os.umask(0o022)
        os.umask(mask)
    return mask


def _remove_stale_temps(folder: Path) -> None:
    now = time.time()
    for p in folder.glob(TEMP_PREFIX + "*"):
        try:
            if p.is_file() and not p.is_symlink() and now - p.stat().st_mtime > STALE_TEMP_S:
                p.unlink()
        except OSError:
            pass


def atomic_write(path, write) -> Path:
    """Write ``path`` by calling ``write(fh)`` with a binary file handle on a
    fresh temporary file beside it, then renaming it over ``path`` (see the
    module docstring).  Readers never see a half-written file; a failed or
    interrupted write leaves nothing behind.  Returns ``path``."""
    path = Path(path)
    folder = path.parent
    folder.mkdir(parents=True, exist_ok=True)
    _remove_stale_temps(folder)
    fd, tmp = tempfile.mkstemp(prefix=TEMP_PREFIX + path.name + ".", dir=folder)
    try:
        with os.fdopen(fd, "w+b") as fh:
            write(fh)
            fh.flush()
            os.fchmod(fh.fileno(), 0o666 & ~_umask())
            os.fsync(fh.fileno())
            size = fh.seek(0, io.SEEK_END)
            fh.seek(0)
            digest = hashlib.file_digest(fh, "sha256").hexdigest()
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    _record(path, size, digest)
    return path


def write_text(path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` with :func:`atomic_write`."""
    return atomic_write(path, lambda fh: fh.write(text.encode("utf-8")))


def write_json(path, data) -> Path:
    """Write ``data`` as indented JSON (non-JSON values as ``str``) with :func:`atomic_write`."""
    return write_text(path, json.dumps(data, indent=1, default=str) + "\n")


def _key_columns(df: pd.DataFrame) -> list:
    """The columns that name a row: the non-numeric ones, and ``trial``."""
    return [c for c in df.columns if c == "trial" or not pd.api.types.is_numeric_dtype(df[c])]


def markdown_table(df: pd.DataFrame, digits: int = 3) -> str:
    """A DataFrame as a GitHub Markdown table (floats to ``digits`` significant digits)."""
    def cell(v):
        if isinstance(v, (float, np.floating)):
            return "—" if np.isnan(v) else f"{v:.{digits}g}"
        return str(v)
    lines = ["| " + " | ".join(map(str, df.columns)) + " |", "|" + "---|" * len(df.columns)]
    lines += ["| " + " | ".join(cell(v) for v in row) + " |" for row in df.itertuples(index=False)]
    return "\n".join(lines) + "\n"


def write_table(df: pd.DataFrame, path, *, parquet: bool = True, markdown: str | None = None) -> list[Path]:
    """Write ``df`` as ``<name>.csv`` (and ``.parquet``; and ``.md`` headed by
    ``markdown`` when given) next to ``path`` (suffix replaced), each with
    :func:`atomic_write`.  Wall-time columns (:data:`TIMING_COLUMNS`) go to
    ``<name>_timings.csv`` with the row's key columns instead, so the table
    itself is deterministic.  Returns the paths written."""
    path = Path(path)
    timing = [c for c in df.columns if c in TIMING_COLUMNS]
    table = df.drop(columns=timing)
    out = [atomic_write(path.with_suffix(".csv"), lambda fh: fh.write(table.to_csv(index=False).encode()))]
    if parquet:
        out.append(atomic_write(path.with_suffix(".parquet"), lambda fh: table.to_parquet(fh, index=False)))
    if markdown is not None:
        text = (f"**{markdown}**\n\n" if markdown else "") + markdown_table(table, 4)
        out.append(write_text(path.with_suffix(".md"), text))
    times_path = path.with_name(path.stem + "_timings.csv")
    if timing:
        times = df[_key_columns(table) + timing]
        out.append(atomic_write(times_path, lambda fh: fh.write(times.to_csv(index=False).encode())))
    else:       # an older run's timings must not be joined to this table by read_table
        times_path.unlink(missing_ok=True)
    return out


def read_table(path) -> pd.DataFrame:
    """Read a table written by :func:`write_table` (``.parquet`` or ``.csv``),
    with its wall-time columns joined back from ``<name>_timings.csv``."""
    path = Path(path)
    df = pd.read_parquet(path) if path.suffix == ".parquet" else pd.read_csv(path)
    times_path = path.with_name(path.stem + "_timings.csv")
    if times_path.exists():
        times = pd.read_csv(times_path)
        timing = [c for c in times.columns if c in TIMING_COLUMNS]
        if len(times) != len(df):
            raise ValueError(f"{times_path}: {len(times)} rows, but {path} has {len(df)}")
        df = pd.concat([df, times[timing]], axis=1)
    return df


def pyplot():
    """matplotlib.pyplot on the non-interactive Agg backend (figures are only
    ever written to files)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig, path, *, dpi: int = 120, svg: bool = False) -> Path:
    """Write ``fig`` to ``path`` as PNG (and an SVG beside it) with
    :func:`atomic_write`, without time stamps in the files; close the figure.
    Returns the PNG path."""
    import matplotlib.pyplot as plt

    out = Path(path)
    try:
        atomic_write(out, lambda fh: fig.savefig(fh, dpi=dpi, format="png"))
        if svg:
            with plt.rc_context({"svg.hashsalt": "safenav"}):
                atomic_write(out.with_suffix(".svg"), lambda fh: fig.savefig(fh, format="svg",
                                                                             metadata={"Date": None}))
    finally:
        plt.close(fig)
    return out


# --------------------------------------------------------------------------- manifest

def _record(path: Path, size: int, digest: str) -> None:
    with _LOCK:
        for run in _RUNS:
            run._add(path, size, digest)


class RunFolder:
    """A run's output folder: ``with RunFolder(out, command=..., parameters=..., seed=...) as run:``.

    On entry the folder is created, a manifest left from an earlier run in it
    is removed (the folder is being rewritten) and so are stale temporary
    files.  Every file written with :func:`atomic_write` under the folder
    while it is open is recorded.  On a clean exit ``manifest.json`` is written
    last; after an exception (or an interrupt) there is none.  ``parameters``
    and ``seed`` may be set on the object before the end."""

    def __init__(self, folder, *, command, parameters: dict | None = None, seed: int | None = None):
        self.folder = Path(folder)
        self.command = list(command)
        self.parameters = dict(parameters or {})
        self.seed = seed
        self.files: dict[str, dict] = {}

    def _add(self, path: Path, size: int, digest: str) -> None:
        try:
            rel = path.resolve().relative_to(self.folder.resolve())
        except ValueError:
            return
        self.files[rel.as_posix()] = {"bytes": size, "sha256": digest}

    def __enter__(self) -> "RunFolder":
        self.folder.mkdir(parents=True, exist_ok=True)
        (self.folder / MANIFEST).unlink(missing_ok=True)
        for sub in (self.folder, *(p for p in self.folder.rglob("*") if p.is_dir() and not p.is_symlink())):
            _remove_stale_temps(sub)
        with _LOCK:
            _RUNS.append(self)
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        with _LOCK:
            _RUNS.remove(self)
        if exc_type is None:
            self.write_manifest()

    def write_manifest(self) -> Path:
        """Write ``manifest.json`` (called on a clean exit)."""
        data = {"safenav_manifest": 1, "complete": True,
                "finished_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
                "command": self.command, "parameters": self.parameters, "seed": self.seed,
                "versions": versions(),
                "files": [{"path": k, **v} for k, v in sorted(self.files.items())]}
        return write_json(self.folder / MANIFEST, data)


def verify_run(folder) -> dict:
    """Check a run folder against its manifest and return the manifest.

    Raises :class:`IncompleteRunError` (a ``ValueError``) when the folder has
    no manifest (the run was interrupted or failed: its files may be partial
    or stale) or a listed file is missing or changed since the run."""
    folder = Path(folder)
    if not folder.is_dir():
        raise ValueError(f"run folder {str(folder)!r} does not exist")
    m = folder / MANIFEST
    if not m.is_file():
        raise IncompleteRunError(f"{folder} is an incomplete run: it has no {MANIFEST} (the run was interrupted "
                                 "or failed, so its files may be partial or stale)")
    try:
        data = json.loads(m.read_text(encoding="utf-8"))
        files = data["files"]
        if not isinstance(files, list) or not all(
                isinstance(f, dict) and isinstance(f.get("path"), str) and isinstance(f.get("sha256"), str)
                and not Path(f["path"]).is_absolute() and ".." not in Path(f["path"]).parts for f in files):
            raise TypeError("'files' must list {path, sha256} entries inside the folder")
    except (ValueError, KeyError, TypeError) as exc:
        raise IncompleteRunError(f"{m}: not a safenav manifest ({exc})") from exc
    for f in files:
        p = folder / f["path"]
        if not p.is_file():
            raise IncompleteRunError(f"{folder}: {f['path']} is listed in {MANIFEST} but missing")
        with p.open("rb") as fh:
            digest = hashlib.file_digest(fh, "sha256").hexdigest()
        if digest != f["sha256"]:
            raise IncompleteRunError(f"{folder}: {f['path']} changed since the run (sha256 {digest[:12]}…, "
                                     f"manifest {f['sha256'][:12]}…)")
    return data


def versions() -> dict:
    """Python, the platform, safenav and its main packages, and the Debian C++ libraries the core was built against."""
    import importlib.metadata as md

    out = {"python": platform.python_version(), "platform": platform.platform()}
    for pkg in ("safenav", "numpy", "scipy", "pandas", "matplotlib", "opencv-python-headless", "pybind11",
                "distributed"):
        try:
            out[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            pass
    try:
        q = subprocess.run(["dpkg-query", "-W", "-f", "${Package} ${Version}\n", "libeigen3-dev", "libcgal-dev",
                            "libompl-dev", "libopencv-dev"], capture_output=True, text=True, timeout=10)
        for line in q.stdout.splitlines():
            name, _, ver = line.partition(" ")
            if ver:
                out[name] = ver
    except (OSError, subprocess.SubprocessError):
        pass
    return out
