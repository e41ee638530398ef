"""The SafeNav paper's numbers for every table, and the table layouts that
print ours beside them.

Table numbers follow the *conference* version throughout (I synthetic, II
real-imitated, III % path-length error, IV ADE/FDE/AWRS/time); the extended
version numbers them one higher, e.g. [SafeNav-conf Table I] = [SafeNav-ext
Table II]."""

from __future__ import annotations

import numpy as np
import pandas as pd

#: The localization methods of Tables I and II, in the paper's row order
#: (keys of :data:`safenav.navigation.SOURCES`).
PAPER_SOURCES = ("deeploc-gps", "deeploc-ekf-gps", "sensor-fusion", "lanbloc")

#: [SafeNav-conf Table I] (= [SafeNav-ext Table II]), synthetic trajectories:
#: (source, filter) -> ADE, FDE [m] against the true trajectory, AWRS, time per
#: trial [ms].
PAPER_TABLE1 = {
    ("deeploc-gps", "ekf"): (0.6069, 0.5495, 0.3926, 5.02), ("deeploc-gps", "pf"): (1.1335, 1.7614, 2.1414, 9815.0),
    ("deeploc-ekf-gps", "ekf"): (0.5621, 0.4818, 0.3590, 4.57),
    ("deeploc-ekf-gps", "pf"): (1.4864, 1.5709, 1.7823, 10054.0),
    ("sensor-fusion", "ekf"): (1.3546, 0.5714, 0.3513, 4.90), ("sensor-fusion", "pf"): (1.9155, 3.1229, 2.9387, 10103.0),
    ("lanbloc", "ekf"): (0.4972, 0.4675, 0.3492, 3.98), ("lanbloc", "pf"): (0.9471, 0.8177, 1.2612, 9551.0),
}
#: [SafeNav-conf Table II] (= [SafeNav-ext Table III]), real-imitated
#: trajectories, the mean over P1-P3: (source, filter) -> ADE, FDE [m] against
#: the true vehicle, AWRS, time per trial [ms].
PAPER_TABLE2 = {
    ("deeploc-gps", "ekf"): (0.3041, 0.3103, 0.2009, 20.58), ("deeploc-gps", "pf"): (1.6928, 2.8891, 4.3586, 192621.0),
    ("deeploc-ekf-gps", "ekf"): (0.2869, 0.2969, 0.1906, 18.94),
    ("deeploc-ekf-gps", "pf"): (2.0672, 7.1665, 3.6346, 197250.0),
    ("sensor-fusion", "ekf"): (0.2998, 0.3115, 0.1749, 22.31), ("sensor-fusion", "pf"): (1.6831, 4.2886, 5.4116, 198790.0),
    ("lanbloc", "ekf"): (0.2393, 0.3095, 0.1528, 14.94), ("lanbloc", "pf"): (1.5162, 1.4024, 3.1623, 185502.0),
}
#: The LanBLoc-BMM rows of Table I by filter (kept for the filter benchmark).
PAPER_SYNTHETIC = {f: dict(zip(("truth_ade", "truth_fde", "awrs", "ms_per_trial"), PAPER_TABLE1[("lanbloc", f)]))
                   for f in ("ekf", "pf")}

#: [SafeNav-conf Table III] (= [SafeNav-ext Table IV]): % path-length error per
#: path type.
PAPER_PERCENT_ERROR = {
    "chull": {"P1": 5.755, "P2": 7.42, "P3": 6.35, "Average": 6.51},
    "centroid": {"P1": 5.32, "P2": 5.60, "P3": 5.47, "Average": 5.46},
}
#: [SafeNav-conf Table IV] (= [SafeNav-ext Table V]): ADE (to the safe path),
#: FDE (to the destination) [m], AWRS and time per trial [ms].
PAPER_NAVIGATION = {
    "chull": {"P1": (2.73, 3.16, 1.31, 14.93), "P2": (2.72, 3.08, 1.11, 14.84), "P3": (3.46, 3.57, 1.71, 15.98),
              "Average": (2.97, 3.27, 1.38, 15.25)},
    "centroid": {"P1": (1.06, 0.87, 1.01, 16.74), "P2": (1.13, 1.03, 1.01, 16.94), "P3": (1.15, 1.06, 1.01, 16.97),
                 "Average": (1.11, 0.99, 1.01, 16.88)},
}
METHOD_LABELS = {"chull": "SafeNav-CHull", "centroid": "SafeNav-Centroid"}



def source_label(source: str) -> str:
    """The table label of a position source ("LanBLoc-BMM", "DeepLoc-GPS (emulated)", ...)."""
    from ..navigation import SOURCES

    if source == "lanbloc":
        return "LanBLoc-BMM"
    if source == "lanbloc-camera":
        return "LanBLoc-BMM (camera loop)"
    return SOURCES[source].label if source in SOURCES else source


#: Safety columns (ours) that every navigation table carries after the paper's:
#: summary column -> table label (see :func:`safenav.runner.safety_summary`).
SAFETY_COLUMNS = {"collision_rate": "collisions", "min_clearance_p5": "clearance p5 m", "exposure": "exposure m",
                  "nees": "NEES", "outside_3sigma": "out 3σ", "guard_share": "guard"}


def _safety(row: dict, r) -> dict:
    """``row`` with the safety columns of summary row ``r`` (those it has)."""
    for k, label in SAFETY_COLUMNS.items():
        if k in r:
            row[label] = r[k]
    return row


def localization_table(summary: pd.DataFrame, paper: dict) -> pd.DataFrame:
    """[SafeNav-conf Tables I–II] layout (= [SafeNav-ext Tables II–III]): one row
    per (algorithm, filter) in the paper's order, ADE and FDE against the true
    trajectory, AWRS and the median time per trial, with the paper's numbers
    beside. ``summary`` has columns source, filter, truth_ade, truth_fde, awrs
    and ms_per_trial (one row per source and filter)."""
    order = {s: i for i, s in enumerate((*PAPER_SOURCES, "lanbloc-camera"))}
    s = summary.assign(_o=summary["source"].map(lambda v: order.get(v, len(order))),
                       _f=summary["filter"].map({"ekf": 0, "pf": 1})).sort_values(["_o", "_f"], kind="stable")
    rows = []
    for _, r in s.iterrows():
        p = paper.get((r["source"], r["filter"]), (np.nan,) * 4)
        row = {"Algorithm": source_label(r["source"]), "Filter": r["filter"].upper(),
               "ADE": r["truth_ade"], "FDE": r["truth_fde"], "AWRS": r["awrs"], "time ms": r["ms_per_trial"],
               "paper ADE": p[0], "paper FDE": p[1], "paper AWRS": p[2], "paper ms": p[3]}
        if "success_rate" in r:
            row["arrived"] = r["success_rate"]   # metrics are over the arrived trials
        rows.append(_safety(row, r))
    return pd.DataFrame(rows)


def _with_average(summary: pd.DataFrame) -> pd.DataFrame:
    cols = ["path_ade", "goal_fde", "awrs", "path_error_percent", "time_ms", "time_per_step_us", "success_rate",
            "steps", *(k for k in SAFETY_COLUMNS if k in summary)]
    avg = summary.groupby("method", sort=False)[cols].mean().reset_index()
    avg["path_type"] = "Average"
    return pd.concat([summary[["method", "path_type", *cols]], avg[["method", "path_type", *cols]]],
                     ignore_index=True)


def percent_error_table(summary: pd.DataFrame) -> pd.DataFrame:
    """[SafeNav-conf Table III] layout (= [SafeNav-ext Table IV]) of the %
    path-length error [SafeNav-ext eq. 23]: one row per method, one column per
    path type plus the average; the paper's value beside each of ours (``paper
    P1`` …). ``summary`` is :func:`safenav.runner.summarize` output for one
    filter and source."""
    s = _with_average(summary)
    rows = []
    for method, g in s.groupby("method", sort=False):
        row = {"Approach": METHOD_LABELS.get(method, method)}
        for _, r in g.iterrows():
            row[r["path_type"]] = r["path_error_percent"]
            row[f"paper {r['path_type']}"] = PAPER_PERCENT_ERROR.get(method, {}).get(r["path_type"], np.nan)
        rows.append(row)
    return pd.DataFrame(rows)


def navigation_table(summary: pd.DataFrame) -> pd.DataFrame:
    """[SafeNav-conf Table IV] layout (= [SafeNav-ext Table V]): per method and
    path type (plus the average), ADE (mean distance of the estimate to the
    safe path), FDE (final estimate to the destination), AWRS and the median
    time per trial, with the paper's numbers beside, then our success rate,
    steps and time per step."""
    s = _with_average(summary)
    rows = []
    for _, r in s.iterrows():
        paper = PAPER_NAVIGATION.get(r["method"], {}).get(r["path_type"], (np.nan,) * 4)
        rows.append({
            "Approach": METHOD_LABELS.get(r["method"], r["method"]), "Path": r["path_type"],
            "ADE": r["path_ade"], "FDE": r["goal_fde"], "AWRS": r["awrs"], "time ms": r["time_ms"],
            "paper ADE": paper[0], "paper FDE": paper[1], "paper AWRS": paper[2], "paper ms": paper[3],
            "success": r["success_rate"], "steps": r["steps"], "µs/step": r["time_per_step_us"],
        })
        _safety(rows[-1], r)
    return pd.DataFrame(rows)
