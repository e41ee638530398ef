"""Replay logs (safenav.logs): exact CSV/Parquet round trips over generated
tables (equal and unsorted times included), one test per malformed input
naming its row, column and value, and the Plaza .mat reader on a synthetic
file (no gtsam) and on the real Plaza1 (with gtsam)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings, strategies as st

from safenav.logs import (COLUMNS, EVENT_COLUMNS, EVENT_KINDS, TRUTH_COLUMNS, Log, load_plaza, plaza1_path,
                          read_log, write_log)
from safenav.results import RunFolder, TEMP_PREFIX
from safenav.validation import INT32_MAX


def table(rows) -> pd.DataFrame:
    return pd.DataFrame(rows).reindex(columns=list(COLUMNS))


def write_raw(rows, path):
    """Write ``rows`` as a log file by hand (not with write_log), in the given order."""
    df = table(rows)
    if path.suffix == ".csv":
        df.to_csv(path, index=False)
    else:
        df.to_parquet(path, index=False)
    return path


def assert_logs_equal(a: Log, b: Log):
    assert a.landmarks == b.landmarks
    pd.testing.assert_frame_equal(a.events, b.events, check_exact=True)
    if a.truth is None or b.truth is None:
        assert a.truth is None and b.truth is None
    else:
        pd.testing.assert_frame_equal(a.truth, b.truth, check_exact=True)


# --------------------------------------------------------------------------- round trips

finite = st.floats(allow_nan=False, allow_infinity=False)
positive = st.floats(min_value=0.0, exclude_min=True, allow_infinity=False)
nonnegative = st.floats(min_value=0.0, allow_infinity=False)
times = st.one_of(st.sampled_from([0.0, 0.5, 1.0]), finite)     # ties are likely


@st.composite
def raw_logs(draw):
    """Rows of a valid log in a random file order: landmarks, inputs and truth mixed, times unsorted."""
    ids = draw(st.lists(st.integers(0, INT32_MAX), min_size=1, max_size=4, unique=True))
    lm = st.sampled_from(ids)
    rows = [dict(kind="landmark", landmark=i, x=draw(finite), y=draw(finite)) for i in ids]
    event = st.one_of(
        st.fixed_dictionaries(dict(kind=st.just("odometry"), t=times, distance=finite, heading_change=finite)),
        st.fixed_dictionaries(dict(kind=st.just("motion"), t=times, speed=finite, heading_change=finite)),
        st.fixed_dictionaries(dict(kind=st.just("range"), t=times, landmark=lm, range=nonnegative,
                                   range_std=positive)),
        st.fixed_dictionaries(dict(kind=st.just("bearing"), t=times, landmark=lm, bearing=finite,
                                   bearing_std=positive)),
        st.fixed_dictionaries(dict(kind=st.just("range_bearing"), t=times, landmark=lm, range=nonnegative,
                                   bearing=finite, range_std=positive, bearing_std=positive)),
        st.fixed_dictionaries(dict(kind=st.just("fix"), t=times, x=finite, y=finite, std_x=positive,
                                   std_y=positive)),
    )
    truth = st.fixed_dictionaries(dict(kind=st.just("truth"), t=times, x=finite, y=finite),
                                  optional=dict(heading=finite))
    rows += draw(st.lists(event, min_size=1, max_size=12)) + draw(st.lists(truth, max_size=4))
    return draw(st.permutations(rows))


def expected_events(rows) -> pd.DataFrame:
    ev = table([r for r in rows if r["kind"] in EVENT_KINDS]).reindex(columns=list(EVENT_COLUMNS))
    ev = ev.sort_values("t", kind="stable").reset_index(drop=True)
    ev["landmark"] = ev["landmark"].astype("Int64")
    return ev.astype({c: np.float64 for c in EVENT_COLUMNS if c not in ("kind", "landmark")})


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
@settings(max_examples=40, deadline=None)
@given(rows=raw_logs())
def test_round_trip_is_exact_and_sorts_stably(tmp_path_factory, suffix, rows):
    folder = tmp_path_factory.mktemp("rt")
    log = read_log(write_raw(rows, folder / f"raw{suffix}"))
    assert log.landmarks == {r["landmark"]: (r["x"], r["y"]) for r in rows if r["kind"] == "landmark"}
    pd.testing.assert_frame_equal(log.events, expected_events(rows), check_exact=True)
    truth = [r for r in rows if r["kind"] == "truth"]
    if truth:
        want = table(truth).reindex(columns=list(TRUTH_COLUMNS)).astype(np.float64)
        pd.testing.assert_frame_equal(log.truth, want.sort_values("t", kind="stable").reset_index(drop=True),
                                      check_exact=True)
    else:
        assert log.truth is None
    for out in (".csv", ".parquet"):
        again = read_log(write_log(log, folder / f"log{out}"))
        assert_logs_equal(again, log)


def test_write_log_is_atomic_and_recorded_by_the_run_folder(tmp_path):
    log = read_log(write_raw(ROWS, tmp_path / "raw.csv"))
    with RunFolder(tmp_path / "run", command=["test"]) as run:
        write_log(log, tmp_path / "run" / "log.parquet")
        write_log(log, tmp_path / "run" / "log.csv")
    assert sorted(run.files) == ["log.csv", "log.parquet"]
    assert not list((tmp_path / "run").glob(TEMP_PREFIX + "*"))
    text = (tmp_path / "run" / "log.csv").read_text().splitlines()
    assert text[0] == ",".join(COLUMNS)
    assert text[1].startswith(",landmark,0,")          # landmarks first, t empty, ids as integers


def test_write_log_checks_a_hand_built_log(tmp_path):
    log = read_log(write_raw(ROWS, tmp_path / "raw.csv"))
    bad = log.events.copy()
    bad.loc[bad["kind"] == "range", "range_std"] = -1.0
    with pytest.raises(ValueError, match=r"column 'range_std' = -1\.0: must be > 0"):
        write_log(Log(log.landmarks, bad, log.truth), tmp_path / "bad.csv")
    with pytest.raises(ValueError, match=r"Log\.events has column 'speeed'"):
        write_log(Log(log.landmarks, log.events.assign(speeed=1.0), None), tmp_path / "bad.csv")
    with pytest.raises(ValueError, match=r"column 'landmark' = 9: unknown landmark id \(the map has \[0, 1\]\)"):
        write_log(Log(log.landmarks, log.events.replace({"landmark": {1: 9}}), None), tmp_path / "bad.csv")
    frac = log.events.astype({"landmark": np.float64}).replace({"landmark": {1.0: 0.5}})
    with pytest.raises(ValueError, match=r"column 'landmark' = 0\.5: a landmark id must be an integer"):
        write_log(Log(log.landmarks, frac, None), tmp_path / "bad.csv")
    with pytest.raises(ValueError, match=r"ends in \.csv or \.parquet, got '\.txt'"):
        write_log(log, tmp_path / "log.txt")
    assert not (tmp_path / "bad.csv").exists()
    backwards = Log(log.landmarks, log.events.iloc[::-1], log.truth)       # a hand-built log out of time order
    again = read_log(write_log(backwards, tmp_path / "sorted.csv"))
    assert list(again.events["t"]) == sorted(log.events["t"])


# --------------------------------------------------------------------------- malformed files

ROWS = [
    dict(kind="landmark", landmark=0, x=0.0, y=0.0),                                            # row 1
    dict(kind="landmark", landmark=1, x=10.0, y=0.0),                                           # row 2
    dict(kind="odometry", t=0.2, distance=0.5, heading_change=0.01),                            # row 3
    dict(kind="range", t=0.2, landmark=1, range=9.5, range_std=0.5),                            # row 4
    dict(kind="bearing", t=0.1, landmark=0, bearing=3.0, bearing_std=0.05),                     # row 5
    dict(kind="range_bearing", t=0.3, landmark=0, range=1.0, bearing=0.2, range_std=0.5, bearing_std=0.05),
    dict(kind="motion", t=0.4, speed=2.0, heading_change=0.0),                                  # row 7
    dict(kind="fix", t=0.4, x=0.8, y=0.1, std_x=1.0, std_y=1.5),                                # row 8
    dict(kind="truth", t=0.0, x=0.0, y=0.0, heading=0.0),                                       # row 9
    dict(kind="truth", t=0.4, x=0.8, y=0.0),                                                    # row 10
]


def test_the_valid_example_reads(tmp_path):
    log = read_log(write_raw(ROWS, tmp_path / "log.csv"))
    assert log.landmarks == {0: (0.0, 0.0), 1: (10.0, 0.0)}
    assert list(log.events["kind"]) == ["bearing", "odometry", "range", "range_bearing", "motion", "fix"]
    assert list(log.events["landmark"].astype(object).fillna(-1)) == [0, -1, 1, 0, -1, -1]
    assert log.truth["heading"].isna().tolist() == [False, True]
    assert repr(log) == "Log(2 landmarks, 6 events, 2 truth rows)"


def changed(row: int, **cells):
    """ROWS with the cells of 1-based ``row`` replaced (None empties a cell)."""
    rows = [dict(r) for r in ROWS]
    rows[row - 1].update(cells)
    return rows


MALFORMED = {
    "unknown kind": (changed(3, kind="odom"), r"row 3 \(CSV line 4\), column 'kind' = 'odom': unknown kind"),
    "missing kind": (changed(3, kind=None), r"row 3 \(CSV line 4\), column 'kind' = nan: missing"),
    "missing std": (changed(4, range_std=None), r"row 4 \(CSV line 5\), column 'range_std' = nan: missing: range rows "
                                                r"need t, landmark, range, range_std"),
    "negative std": (changed(4, range_std=-0.5), r"row 4 \(CSV line 5\), column 'range_std' = -0\.5: must be > 0"),
    "zero bearing std": (changed(5, bearing_std=0.0),
                         r"row 5 \(CSV line 6\), column 'bearing_std' = 0\.0: must be > 0"),
    "zero fix std": (changed(8, std_y=0.0), r"row 8 \(CSV line 9\), column 'std_y' = 0\.0: must be > 0"),
    "negative range": (changed(6, range=-1.0), r"row 6 \(CSV line 7\), column 'range' = -1\.0: must be >= 0"),
    "unknown landmark": (changed(5, landmark=7), r"row 5 \(CSV line 6\), column 'landmark' = 7: unknown landmark id "
                                                r"\(the map has \[0, 1\]\)"),
    "duplicate landmark": (changed(2, landmark=0), r"row 2 \(CSV line 3\), column 'landmark' = 0: duplicate landmark "
                                                  r"id \(first defined on row 1\)"),
    "fractional id": (changed(1, landmark=0.5), r"row 1 \(CSV line 2\), column 'landmark' = 0\.5: a landmark id must "
                                               r"be an integer"),
    "negative id": (changed(1, landmark=-3), r"row 1 \(CSV line 2\), column 'landmark' = -3(\.0)?: a landmark id must"),
    "infinite t": (changed(7, t=np.inf), r"row 7 \(CSV line 8\), column 't' = inf: not finite"),
    "non-numeric t": (changed(7, t="noon"), r"row 7 \(CSV line 8\), column 't' = 'noon': not a number"),
    "missing t": (changed(3, t=None), r"row 3 \(CSV line 4\), column 't' = nan: missing: odometry rows need t"),
    "missing landmark x": (changed(1, x=None), r"row 1 \(CSV line 2\), column 'x' = nan: missing: landmark rows need "
                                               r"landmark, x, y"),
    "infinite position": (changed(8, x=-np.inf), r"row 8 \(CSV line 9\), column 'x' = -inf: not finite"),
    "cell of another kind": (changed(3, speed=1.0), r"row 3 \(CSV line 4\), column 'speed' = 1\.0: must be empty in "
                                                    r"odometry rows \(they use t, distance, heading_change\)"),
    "landmark with a time": (changed(2, t=5.0), r"row 2 \(CSV line 3\), column 't' = 5\.0: must be empty in landmark "
                                                r"rows"),
    "no map": (ROWS[2:], r"row 2 \(CSV line 3\), column 'landmark' = 1: a range observation, but the log has no "
                         r"landmark rows"),
    "no inputs": (ROWS[:2] + ROWS[8:], r"empty log: no input rows"),
}


@pytest.mark.parametrize("case", MALFORMED, ids=str)
def test_malformed_csv_names_the_row_column_and_value(tmp_path, case):
    rows, message = MALFORMED[case]
    path = write_raw(rows, tmp_path / "bad.csv")
    with pytest.raises(ValueError, match=r"^" + str(path).replace(".", r"\.") + ": " + message):
        read_log(path)


def test_malformed_parquet_names_the_row(tmp_path):
    path = write_raw(changed(4, range_std=-0.5), tmp_path / "bad.parquet")
    with pytest.raises(ValueError, match=r"bad\.parquet: row 4, column 'range_std' = -0\.5: must be > 0"):
        read_log(path)
    df = table(changed(7, t="noon"))
    df["t"] = [None if pd.isna(v) else str(v) for v in df["t"]]          # a text column of times
    path = tmp_path / "text.parquet"
    df.to_parquet(path, index=False)
    with pytest.raises(ValueError, match=r"text\.parquet: row 7, column 't' = 'noon': not a number"):
        read_log(path)


@pytest.mark.parametrize("text, message", [
    ("", r"empty log: the file has no header"),
    (",".join(COLUMNS) + "\n", r"empty log: the table has no rows"),
    ("t,kind,speeed\n0,motion,1\n", r"unknown column 'speeed' \(the columns are: t, kind,"),
    ("t,distance\n0,1\n", r"no 'kind' column \(every log has one"),
])
def test_malformed_tables(tmp_path, text, message):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        read_log(path)


def test_missing_columns_read_as_empty(tmp_path):
    path = tmp_path / "short.csv"
    path.write_text("t,kind,landmark,x,y,distance,heading_change,range,range_std\n"
                    ",landmark,3,1.5,-2\n0.2,odometry,,,,0.5,0.01\n0.1,range,3,,,,,4.2,0.3\n")
    log = read_log(path)
    assert log.landmarks == {3: (1.5, -2.0)}
    assert list(log.events["kind"]) == ["range", "odometry"] and log.truth is None
    assert list(log.events.columns) == list(EVENT_COLUMNS)


def test_suffix_and_missing_file(tmp_path):
    with pytest.raises(ValueError, match=r"ends in \.csv or \.parquet"):
        read_log(tmp_path / "log.json")
    with pytest.raises(FileNotFoundError, match="no such log file"):
        read_log(tmp_path / "absent.csv")
    (tmp_path / "junk.parquet").write_bytes(b"not parquet")
    with pytest.raises(ValueError, match=r"junk\.parquet: not a Parquet log table"):
        read_log(tmp_path / "junk.parquet")


# --------------------------------------------------------------------------- Plaza .mat files

def plaza_arrays():
    gt = np.array([[0.0, 0.0, 0.0, 0.1], [1.0, 1.0, 0.0, 0.1], [2.0, 2.0, 0.1, 0.2], [3.0, 3.0, 0.2, 0.2]])
    dr = np.array([[1.0, 1.0, 0.0], [2.0, 1.0, 0.1], [3.0, 1.0, 0.0]])
    td = np.array([[0.5, 2, 7, 7.1], [2.5, 2, 3, 4.0], [2.0, 2, 7, 5.2],     # out of order; 2.0 ties an odometry row
                   [2.7, 2, 3, 3.3], [0.2, 2, 3, 4.4]])
    tl = np.array([[7, 8.0, 0.5], [3, -1.0, 4.0]])
    return dict(GT=gt, DR=dr, TD=td, TL=tl)


def save_plaza(tmp_path, **arrays):
    from scipy.io import savemat

    path = tmp_path / "plaza.mat"
    savemat(str(path), arrays)
    return path


def test_load_plaza_on_a_synthetic_file(tmp_path):
    a = plaza_arrays()
    log = load_plaza(save_plaza(tmp_path, **a), range_std=0.5)
    assert log.landmarks == {7: (8.0, 0.5), 3: (-1.0, 4.0)}
    ev = log.events
    assert list(ev["t"]) == [0.2, 0.5, 1.0, 2.0, 2.0, 2.5, 2.7, 3.0]
    assert list(ev["kind"]) == ["range", "range", "odometry", "odometry", "range", "range", "range", "odometry"]
    rg = ev[ev["kind"] == "range"]
    assert list(rg["landmark"]) == [3, 7, 7, 3, 3] and list(rg["range"]) == [4.4, 7.1, 5.2, 4.0, 3.3]
    assert (rg["range_std"] == 0.5).all()
    od = ev[ev["kind"] == "odometry"]
    np.testing.assert_array_equal(od[["t", "distance", "heading_change"]].to_numpy(), a["DR"])
    np.testing.assert_array_equal(log.truth.to_numpy(), a["GT"])
    # the experiments' Plaza1 loader shares the parser: same arrays, ranges sorted by time
    from safenav.experiments.real import load_plaza1

    p = load_plaza1(tmp_path / "plaza.mat")
    np.testing.assert_array_equal(p.gt, a["GT"])
    np.testing.assert_array_equal(p.odometry, a["DR"])
    td = a["TD"][np.argsort(a["TD"][:, 0], kind="stable")]
    np.testing.assert_array_equal(p.ranges, td[:, [0, 2, 3]])
    assert p.beacons == log.landmarks
    assert_logs_equal(read_log(write_log(log, tmp_path / "plaza.parquet")), log)


@pytest.mark.parametrize("change, message", [
    (dict(TL=None), r"plaza\.mat: no TL array \(a Plaza \.mat file holds GT, DR, TD, TL\)"),
    (dict(TD=plaza_arrays()["TD"][:, :3]), r"plaza\.mat: TD must have shape \(N, 4\), got \(5, 3\) \(its columns: "
                                           r"t, robot, beacon, range\)"),
    (dict(DR=np.where(np.eye(3, dtype=bool), np.nan, plaza_arrays()["DR"])),
     r"plaza\.mat: DR\[\(0, 0\)\] = nan is not finite \(its columns: t, distance, heading_change\)"),
    (dict(TD=np.vstack([plaza_arrays()["TD"], [3.0, 2, 9, 1.0]])),
     r"plaza\.mat: TD\[5, 2\] = 9\.0: a range to a beacon TL does not have \(TL's ids: \[3, 7\]\)"),
    (dict(TL=np.array([[7, 8.0, 0.5], [7, -1.0, 4.0]])), r"TL\[1, 0\] = 7: duplicate beacon id \(also TL\[0, 0\]\)"),
    (dict(TL=np.array([[7.5, 8.0, 0.5]])), r"TL\[0, 0\] = 7\.5: a beacon id must be an integer"),
    (dict(TD=plaza_arrays()["TD"] * [1, 1, 1, -1]), r"TD\[0, 3\] = -7\.1: a range must be >= 0"),
])
def test_load_plaza_checks_the_layout(tmp_path, change, message):
    a = {**plaza_arrays(), **change}
    path = save_plaza(tmp_path, **{k: v for k, v in a.items() if v is not None})
    with pytest.raises(ValueError, match=message):
        load_plaza(path)


def test_load_plaza_arguments(tmp_path, monkeypatch):
    path = save_plaza(tmp_path, **plaza_arrays())
    with pytest.raises(ValueError, match=r"range_std = 0\.0: must be in \(0, inf\]"):
        load_plaza(path, range_std=0.0)
    (tmp_path / "junk.mat").write_bytes(b"junk")
    with pytest.raises(ValueError, match=r"junk\.mat: not a MATLAB \.mat file"):
        load_plaza(tmp_path / "junk.mat")
    with pytest.raises(FileNotFoundError, match="no such Plaza"):
        load_plaza(tmp_path / "absent.mat")
    monkeypatch.setitem(__import__("sys").modules, "gtsam", None)      # gtsam not installed
    with pytest.raises(FileNotFoundError, match="pip install gtsam"):
        plaza1_path()


def test_load_plaza_on_the_real_plaza1(tmp_path):
    pytest.importorskip("gtsam")
    log = load_plaza(plaza1_path())
    ev = log.events
    assert sorted(log.landmarks) == [0, 1, 5, 6]
    assert (ev["kind"] == "range").sum() == 3529
    assert len(log.truth) == (ev["kind"] == "odometry").sum() + 1
    assert set(ev["kind"]) == {"range", "odometry"}
    assert np.all(np.diff(ev["t"]) >= 0) and np.all(np.diff(log.truth["t"]) >= 0)
    assert_logs_equal(read_log(write_log(log, tmp_path / "plaza1.csv")), log)


def test_the_example_in_the_docs_reads(tmp_path):
    import re
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[1] / "docs" / "replay.md").read_text()
    (tmp_path / "example.csv").write_text(re.search(r"```csv\n(.*?)```", doc, re.S).group(1))
    log = read_log(tmp_path / "example.csv")
    assert log.landmarks == {0: (0.0, 0.0), 1: (10.0, 0.0)} and len(log.truth) == 2
    assert list(log.events["kind"]) == ["odometry", "range", "bearing", "motion", "fix"]
