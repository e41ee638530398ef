"""Timestamped logs for ``safenav replay``: the one table format, its reader and
writer, and a reader for the Plaza range-only ``.mat`` files.

A log is ONE table (CSV, or Parquet when the name ends in ``.parquet``) with
the columns :data:`COLUMNS`; each row is one input, its ``kind`` says which
cells it uses (:data:`KINDS`) and every other cell is empty.  Units: metres,
seconds, radians; angles counter-clockwise; a bearing is measured from the
vehicle's heading.  ``docs/replay.md`` documents the format.

* :func:`read_log` checks everything and returns a :class:`Log`; each error
  is one ``ValueError`` on one line that names the file and, for a bad cell
  (a :class:`~safenav.validation.ScenarioError`), the row (1-based, the
  header not counted; a CSV row ``r`` is on line ``r + 1``), the column and
  the value.
* :func:`write_log` writes a :class:`Log` with
  :func:`safenav.results.atomic_write`; ``read_log`` gives it back exactly.
* :func:`load_plaza` reads a Plaza range-only ``.mat`` file (``GT``, ``DR``,
  ``TD``, ``TL``) into a :class:`Log`; :func:`plaza1_path` is Plaza1's copy in
  the gtsam wheel.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .results import atomic_write
from .validation import INT32_MAX, MAX_LANDMARKS, ScenarioError, as_array, cut, fail, real

__all__ = ["Log", "read_log", "write_log", "parse_table", "load_plaza", "plaza1_path", "COLUMNS", "KINDS", "EVENT_KINDS",
           "OBSERVATION_KINDS", "EVENT_COLUMNS", "TRUTH_COLUMNS", "PLAZA_ARRAYS"]

#: The columns of a log file, in this order.
COLUMNS = ("t", "kind", "landmark", "x", "y", "heading", "speed", "distance", "heading_change", "range",
           "bearing", "range_std", "bearing_std", "std_x", "std_y")

#: kind -> (required cells, optional cells); every other cell of the row must be empty.
KINDS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "landmark": (("landmark", "x", "y"), ()),
    "odometry": (("t", "distance", "heading_change"), ()),
    "motion": (("t", "speed", "heading_change"), ()),
    "range": (("t", "landmark", "range", "range_std"), ()),
    "bearing": (("t", "landmark", "bearing", "bearing_std"), ()),
    "range_bearing": (("t", "landmark", "range", "bearing", "range_std", "bearing_std"), ()),
    "fix": (("t", "x", "y", "std_x", "std_y"), ()),
    "truth": (("t", "x", "y"), ("heading",)),
}
#: The kinds fed to the localizer, in :attr:`Log.events`.
EVENT_KINDS = ("odometry", "motion", "range", "bearing", "range_bearing", "fix")
#: The kinds that observe a landmark of the map.
OBSERVATION_KINDS = ("range", "bearing", "range_bearing")
#: The columns of :attr:`Log.events` (``heading`` is used by truth rows only).
EVENT_COLUMNS = tuple(c for c in COLUMNS if c != "heading")
#: The columns of :attr:`Log.truth`.
TRUTH_COLUMNS = ("t", "x", "y", "heading")

_POSITIVE = ("range_std", "bearing_std", "std_x", "std_y")
_NUMERIC = tuple(c for c in COLUMNS if c != "kind")
_SUFFIXES = (".csv", ".parquet")


@dataclass(frozen=True, eq=False)
class Log:
    """A log: the map, the inputs in time order and the ground truth.

    * ``landmarks`` — ``{id: (x, y)}`` from the ``landmark`` rows, in file order.
    * ``events`` — one row per input (kinds :data:`EVENT_KINDS`), columns
      :data:`EVENT_COLUMNS`, sorted by ``t`` stably (rows with equal ``t``
      keep their order in the file), index ``0..n-1``.  ``kind`` is a string,
      ``landmark`` a nullable integer (``Int64``: ``<NA>`` where the kind has
      none), every other column float64 with NaN in the cells the kind does
      not use.
    * ``truth`` — the ``truth`` rows, columns :data:`TRUTH_COLUMNS` (float64,
      ``heading`` NaN where not given), sorted by ``t`` stably, index
      ``0..n-1``; ``None`` when the log has none.  Never fed to a filter.

    Build one with :func:`read_log` or :func:`load_plaza`; :func:`write_log`
    checks one built by hand as :func:`read_log` would.
    """

    landmarks: dict[int, tuple[float, float]]
    events: pd.DataFrame
    truth: pd.DataFrame | None = None

    def __repr__(self) -> str:
        n_truth = 0 if self.truth is None else len(self.truth)
        return f"Log({len(self.landmarks)} landmarks, {len(self.events)} events, {n_truth} truth rows)"


# --------------------------------------------------------------------------- checking a table

class _Table:
    """A raw log table being checked: where its rows are, for messages."""

    def __init__(self, df: pd.DataFrame, source: str, csv: bool):
        self.df = df.reset_index(drop=True)
        self.source = source
        self.csv = csv

    def where(self, i: int, column: str) -> str:
        line = f" (CSV line {i + 2})" if self.csv else ""
        return f"{self.source}: row {i + 1}{line}, column {column!r}"

    def fail(self, i: int, column: str, value, problem: str):
        if isinstance(value, np.generic):
            value = value.item()
        fail(self.where(i, column), value, problem)

    def numeric(self, column: str) -> np.ndarray:
        """The column as float64 (NaN where empty; all NaN when the file has no such column)."""
        if column not in self.df.columns:
            return np.full(len(self.df), np.nan)
        s = self.df[column]
        if pd.api.types.is_numeric_dtype(s) and not pd.api.types.is_bool_dtype(s):
            return s.to_numpy(dtype=np.float64, na_value=np.nan)
        out = np.empty(len(s))
        for i, v in enumerate(s.tolist()):
            if v is None or v is pd.NA or (isinstance(v, float) and np.isnan(v)) \
                    or (isinstance(v, str) and not v.strip()):
                out[i] = np.nan
                continue
            try:
                if isinstance(v, (bool, np.bool_)) or not isinstance(v, (str, int, float, np.integer, np.floating)):
                    raise TypeError
                out[i] = float(v)
            except (TypeError, ValueError, OverflowError):
                self.fail(i, column, v, "not a number")
        return out


def _first(mask: np.ndarray) -> int:
    """The first True index of ``mask``, or len(mask) when none."""
    hits = np.flatnonzero(mask)
    return int(hits[0]) if len(hits) else len(mask)


def parse_table(df: pd.DataFrame, source: str, *, csv: bool = False) -> Log:
    """Check a raw log table (the file's columns, ``COLUMNS``; ``source`` names it in errors) and build the
    :class:`Log`: what :func:`read_log` does after reading a file, for tables built in memory (a ROS bag)."""
    unknown = [c for c in df.columns if c not in COLUMNS]
    if unknown:
        raise ScenarioError(f"{source}: unknown column {cut(unknown[0])} (the columns are: {', '.join(COLUMNS)})")
    if "kind" not in df.columns:
        raise ScenarioError(f"{source}: no 'kind' column (every log has one; the columns are: {', '.join(COLUMNS)})")
    if len(df) == 0:
        raise ScenarioError(f"{source}: empty log: the table has no rows")
    tab = _Table(df, source, csv)
    kinds = tab.df["kind"].astype(object).to_numpy()
    for i, k in enumerate(kinds):
        if not isinstance(k, str) or k not in KINDS:
            missing = k is None or k is pd.NA or (isinstance(k, float) and np.isnan(k))
            tab.fail(i, "kind", k, "missing" if missing else f"unknown kind (the kinds are: {', '.join(KINDS)})")
    kinds = kinds.astype(str)
    values = {c: tab.numeric(c) for c in _NUMERIC}
    _check_values(tab, kinds, values)
    landmarks = _landmark_map(tab, kinds, values)

    # the inputs and the truth, each sorted stably by time
    rows = np.flatnonzero(np.isin(kinds, EVENT_KINDS))
    if len(rows) == 0:
        raise ScenarioError(f"{source}: empty log: no input rows (kinds {', '.join(EVENT_KINDS)})")
    rows = rows[np.argsort(values["t"][rows], kind="stable")]
    events = pd.DataFrame({c: kinds[rows] if c == "kind" else values[c][rows] for c in EVENT_COLUMNS})
    events["landmark"] = events["landmark"].astype("Int64")
    rows = np.flatnonzero(kinds == "truth")
    truth = None
    if len(rows):
        rows = rows[np.argsort(values["t"][rows], kind="stable")]
        truth = pd.DataFrame({c: values[c][rows] for c in TRUTH_COLUMNS})
    return Log(landmarks=landmarks, events=events, truth=truth)


def _check_values(tab: "_Table", kinds: np.ndarray, values: dict) -> None:
    """Each row's columns against its kind, finiteness, signs and ids; the
    earliest offending row is reported (on one row, the first check)."""
    checks: list[tuple[np.ndarray, str, str]] = []   # (rows that break it, column, problem)
    for kind, (required, optional) in KINDS.items():
        rows = kinds == kind
        if not rows.any():
            continue
        uses = ", ".join(required + optional)
        for c in _NUMERIC:
            empty = np.isnan(values[c])
            if c in required:
                checks.append((rows & empty, c, f"missing: {kind} rows need {uses}"))
            elif c not in optional:
                checks.append((rows & ~empty, c, f"must be empty in {kind} rows (they use {uses})"))
    for c in _NUMERIC:
        checks.append((np.isinf(values[c]), c, "not finite"))
    for c in _POSITIVE:
        checks.append((values[c] <= 0, c, "must be > 0"))
    checks.append((values["range"] < 0, "range", "must be >= 0"))
    ids = values["landmark"]
    with np.errstate(invalid="ignore"):
        checks.append((~np.isnan(ids) & ((ids != np.floor(ids)) | (ids < 0) | (ids > INT32_MAX)), "landmark",
                       f"a landmark id must be an integer in [0, {INT32_MAX}]"))
    firsts = [_first(mask) for mask, _, _ in checks]
    if firsts and min(firsts) < len(kinds):
        n = int(np.argmin(firsts))
        i, (_, c, problem) = firsts[n], checks[n]
        tab.fail(i, c, tab.df[c].iloc[i] if c in tab.df.columns else np.nan, problem)


def _landmark_map(tab: "_Table", kinds: np.ndarray, values: dict) -> dict[int, tuple[float, float]]:
    """The map from the landmark rows (ids distinct); every observation must
    name a landmark of it."""
    ids = values["landmark"]
    landmarks: dict[int, tuple[float, float]] = {}
    first_row: dict[int, int] = {}
    for i in np.flatnonzero(kinds == "landmark"):
        lid = int(ids[i])
        if lid in landmarks:
            tab.fail(i, "landmark", lid, f"duplicate landmark id (first defined on row {first_row[lid] + 1})")
        landmarks[lid] = (float(values["x"][i]), float(values["y"][i]))
        first_row[lid] = int(i)
    if len(landmarks) > MAX_LANDMARKS:
        raise ScenarioError(f"{tab.source}: {len(landmarks)} landmarks, at most {MAX_LANDMARKS} allowed")
    observed = np.isin(kinds, OBSERVATION_KINDS)
    if observed.any():
        i = _first(observed)
        if not landmarks:
            tab.fail(i, "landmark", int(ids[i]), f"a {kinds[i]} observation, but the log has no landmark rows "
                                                 "(the map)")
        known = np.isin(ids, np.fromiter(landmarks, dtype=np.float64, count=len(landmarks)))
        i = _first(observed & ~known)
        if i < len(kinds):
            tab.fail(i, "landmark", int(ids[i]), f"unknown landmark id (the map has {cut(sorted(landmarks))})")
    return landmarks


def _table(log: Log) -> pd.DataFrame:
    """The file table of ``log``: its landmark rows, its events, then its truth rows."""
    if not isinstance(log, Log):
        raise TypeError(f"write_log needs a Log, got {type(log).__name__}")
    parts = []
    ids = list(log.landmarks)
    xy = np.array([log.landmarks[i] for i in ids], dtype=np.float64).reshape(-1, 2)
    parts.append(pd.DataFrame({"kind": ["landmark"] * len(ids), "landmark": np.array(ids, dtype=np.float64),
                               "x": xy[:, 0], "y": xy[:, 1]}))
    for name, df, allowed in (("events", log.events, EVENT_COLUMNS), ("truth", log.truth, TRUTH_COLUMNS)):
        if df is None:
            continue
        extra = [c for c in df.columns if c not in allowed]
        if extra:
            raise ValueError(f"Log.{name} has column {str(extra[0])!r}; its columns are {', '.join(allowed)}")
        df = df.reset_index(drop=True)
        if name == "truth":
            df = df.assign(kind="truth")
        parts.append(df)
    parts = [p for p in parts if len(p)]
    table = pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=list(COLUMNS))
    return table.reindex(columns=list(COLUMNS))


# --------------------------------------------------------------------------- files

def _suffix(path: Path) -> str:
    suffix = path.suffix.lower()
    if suffix not in _SUFFIXES:
        raise ValueError(f"{path}: a log file's name ends in .csv or .parquet, got {suffix or 'no suffix'!r}")
    return suffix


def read_log(path) -> Log:
    """Read and check a log file (CSV, or Parquet when the name ends in ``.parquet``).

    Columns missing from the file are read as empty; an unknown column, an
    unknown kind, a missing or extra cell for the row's kind, a non-numeric or
    non-finite number, a standard deviation <= 0, a negative range, a landmark
    id that is not an integer in [0, 2**31 - 1], a duplicate landmark id, an
    observation of a landmark the map does not have, and a log without inputs
    are each a ``ValueError`` naming the file, row, column and value.  Rows
    need not be in time order (:class:`Log` sorts them stably).
    """
    path = Path(path)
    suffix = _suffix(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such log file")
    try:
        if suffix == ".csv":
            df = pd.read_csv(path, dtype={"kind": object})
        else:
            df = pd.read_parquet(path)
    except pd.errors.EmptyDataError:
        raise ValueError(f"{path}: empty log: the file has no header") from None
    except (pd.errors.ParserError, UnicodeDecodeError, ValueError, OSError) as exc:
        raise ValueError(f"{path}: not a {'CSV' if suffix == '.csv' else 'Parquet'} log table ({exc})") from exc
    return parse_table(df, str(path), csv=suffix == ".csv")


def write_log(log: Log, path) -> Path:
    """Write ``log`` to ``path`` (CSV, or Parquet when the name ends in
    ``.parquet``) with :func:`~safenav.results.atomic_write`: the landmark
    rows, then the events in time order, then the truth rows.  The log is
    checked first as :func:`read_log` checks a file, so every written log reads
    back, and ``read_log(write_log(log, path))`` equals ``log`` exactly (a log
    built by hand comes back with its rows sorted as :class:`Log` says).
    Returns ``path``."""
    path = Path(path)
    suffix = _suffix(path)
    log = parse_table(_table(log), f"log for {path}")        # checked, and its rows in time order
    table = _table(log)
    table["landmark"] = table["landmark"].astype("Int64")    # ids are written as integers
    if suffix == ".csv":
        return atomic_write(path, lambda fh: fh.write(table.to_csv(index=False).encode()))
    return atomic_write(path, lambda fh: table.to_parquet(fh, index=False))


# --------------------------------------------------------------------------- Plaza range-only files

#: The arrays of a Plaza range-only ``.mat`` file and their columns.
PLAZA_ARRAYS = {"GT": ("t", "x", "y", "heading"), "DR": ("t", "distance", "heading_change"),
                "TD": ("t", "robot", "beacon", "range"), "TL": ("id", "x", "y")}


def plaza1_path() -> Path:
    """Plaza1's ``Plaza1_.mat`` in the gtsam wheel; ``FileNotFoundError`` (with
    how to get it) when gtsam is not installed."""
    try:
        import gtsam
    except ImportError as exc:  # optional test dependency
        raise FileNotFoundError("Plaza1 ships in the gtsam wheel; pip install gtsam") from exc
    path = Path(gtsam.__file__).parent / "Data" / "Plaza1_.mat"
    if not path.is_file():
        raise FileNotFoundError(f"{path} is missing from the gtsam wheel")
    return path


def _plaza_arrays(path: Path) -> dict[str, np.ndarray]:
    """The four arrays of a Plaza ``.mat`` file, checked (:data:`PLAZA_ARRAYS`)."""
    from scipy.io import loadmat
    from scipy.io.matlab import MatReadError

    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such Plaza .mat file")
    try:
        m = loadmat(str(path))
    except (MatReadError, ValueError, TypeError, OSError, NotImplementedError) as exc:
        raise ValueError(f"{path}: not a MATLAB .mat file ({exc})") from exc
    out = {}
    for key, cols in PLAZA_ARRAYS.items():
        if key not in m:
            raise ValueError(f"{path}: no {key} array (a Plaza .mat file holds {', '.join(PLAZA_ARRAYS)})")
        try:
            out[key] = as_array(f"{path}: {key}", m[key], (None, len(cols)))
        except ValueError as exc:
            raise ValueError(f"{exc} (its columns: {', '.join(cols)})") from None
    tl, td = out["TL"], out["TD"]
    ids: dict[int, int] = {}
    for i, b in enumerate(tl[:, 0]):
        if b != np.floor(b) or not 0 <= b <= INT32_MAX:
            fail(f"{path}: TL[{i}, 0]", float(b), f"a beacon id must be an integer in [0, {INT32_MAX}]")
        if int(b) in ids:
            fail(f"{path}: TL[{i}, 0]", int(b), f"duplicate beacon id (also TL[{ids[int(b)]}, 0])")
        ids[int(b)] = i
    unknown = _first(~np.isin(td[:, 2], tl[:, 0]))
    if unknown < len(td):
        fail(f"{path}: TD[{unknown}, 2]", float(td[unknown, 2]), f"a range to a beacon TL does not have (TL's ids: "
                                                           f"{cut(sorted(ids))})")
    negative = _first(td[:, 3] < 0)
    if negative < len(td):
        fail(f"{path}: TD[{negative}, 3]", float(td[negative, 3]), "a range must be >= 0")
    return out


def load_plaza(path, *, range_std: float = 1.0) -> Log:
    """Read a Plaza range-only ``.mat`` file (Plaza1, Plaza2, ... — no gtsam needed).

    The arrays (:data:`PLAZA_ARRAYS`): ``GT`` (t, x, y, θ) → ``truth`` rows;
    ``DR`` (t, Δd, Δθ) → ``odometry`` rows (Δd in ``distance``, Δθ in
    ``heading_change``); ``TD`` (t, robot, beacon, range) → ``range`` rows
    with σ = ``range_std`` (the robot column is not used); ``TL`` (id, x, y)
    → the landmarks.  At equal times an odometry row comes before a range
    row.  Each array's presence, column count and values are checked; a range
    to a beacon ``TL`` does not list is an error.
    """
    path = Path(path)
    range_std = real("range_std", range_std, lo=0.0, hi=np.inf, lo_open=True)
    a = _plaza_arrays(path)
    gt, dr, td, tl = a["GT"], a["DR"], a["TD"], a["TL"]
    blocks = [
        {"kind": "landmark", "landmark": tl[:, 0], "x": tl[:, 1], "y": tl[:, 2]},
        {"kind": "odometry", "t": dr[:, 0], "distance": dr[:, 1], "heading_change": dr[:, 2]},
        {"kind": "range", "t": td[:, 0], "landmark": td[:, 2], "range": td[:, 3],
         "range_std": np.full(len(td), range_std)},
        {"kind": "truth", "t": gt[:, 0], "x": gt[:, 1], "y": gt[:, 2], "heading": gt[:, 3]},
    ]
    n = [len(next(v for v in b.values() if isinstance(v, np.ndarray))) for b in blocks]
    table = {c: np.full(sum(n), np.nan) for c in _NUMERIC}
    kind = np.empty(sum(n), dtype=object)
    start = 0
    for b, size in zip(blocks, n):
        for c, v in b.items():
            if c == "kind":
                kind[start:start + size] = v
            else:
                table[c][start:start + size] = v
        start += size
    return parse_table(pd.DataFrame({"kind": kind, **table}), str(path))
