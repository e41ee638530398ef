"""The experiments' report: one self-contained HTML file with every table
(ours beside the paper's), every figure (embedded), the parameters, seeds and
software versions, the departures from the paper and the verdicts on the
paper's claims; and the Markdown tables written beside the CSVs."""

from __future__ import annotations

import base64
import html
import json
import time
from dataclasses import fields
from pathlib import Path

import numpy as np
import pandas as pd

from .. import navigation as nav
from ..results import versions, write_text
from ..runner import SEED_RULE
from .claims import BOOTSTRAP, CONFIDENCE, MIN_TRIALS
from .synthetic import SyntheticConfig


def parameters(opts) -> dict:
    """The run's parameters and seeds as plain values (``parameters.json`` and the report)."""
    sc = opts.scenario
    return {
        "options": opts.describe(),
        "seeds": {"trials (base)": int(opts.seed), "world": sc.seeds.world, "planner": sc.seeds.planner,
                  "rule": SEED_RULE},
        "scenario": {k: v for k, v in sc.to_dict().items() if k not in ("world", "path_types")},
        "path_types": {p.name: list(p.clusters) for p in sc.path_types},
        "synthetic": _synthetic_parameters(SyntheticConfig()),
        "sources": {k: {"label": s.label, "std": list(s.std), "bias_std": s.bias_std,
                        "bias_walk_std": s.bias_walk_std, "outlier_probability": s.outlier_probability,
                        "outlier_std": s.outlier_std, "emulated": s.emulated, "note": s.note}
                    for k, s in nav.SOURCES.items()},
    }


def _synthetic_parameters(cfg: SyntheticConfig) -> dict:
    """The synthetic set's parameters as JSON values (core objects by their declared parameters)."""
    out = {f.name: getattr(cfg, f.name) for f in fields(cfg) if f.name not in ("landmarks", "position", "bmm")}
    out["bmm"] = {sp.name: cfg.bmm.get_param(sp.name) for sp in cfg.bmm.params()}
    out["position"] = cfg.position.name
    return out


#: Where we depart from the paper (the report's list; README "Where we depart from the papers" and
#: docs/reproduce.md "Departures from the paper" give the reasoning).
DEPARTURES = (
    "DeepLoc-GPS, DeepLoc-EKF-GPS and Sensor Fusion are emulated: error profiles we chose (white noise, bias, bias "
    "walk, outliers; see Parameters), not the original trained networks and GNSS/INS fusion, which cannot be had "
    "here. None was tuned to land on a number of the paper's.",
    "LanBLoc at the measurement level uses the paper's own RMSE (0.0142 m X, 0.039 m Y) as white noise, with fixes "
    "only while at least the scenario's minimum number of landmarks is in range and in view. The camera-loop "
    "variant replaces it with the real vision pipeline on rendered images.",
    "ADE of the navigation tables (path_ade) is the mean cross-track distance of the estimate to the safe path "
    "(SafeNav-ext eq. 21 pairs points by time, but the safe path has no time stamps); FDE (goal_fde) is the final "
    "estimate's distance to the destination. Tables I and II's ADE and FDE are against the true trajectory "
    "(truth_ade, truth_fde).",
    "WRS follows eq. 18 as written: inside zone j, WRS = d·(d / w_j), which falls at zone borders.",
    "Line 10 of SafeNav-conf's Algorithm 1 (line 13 of SafeNav-ext's), 'or next_hull is not None', is read as "
    "'inside the current or the next hull'; outside both adjacent hulls the vehicle steps back. Algorithm 2 steers "
    "to the nearest sub-segment centroid ahead.",
    "The heading command is atan2(Δy, Δx) minus the heading, wrapped (the paper prints arctan(Δx/Δy)).",
    "The real-imitated world is generated from the scenario's seed to the paper's description (200×200 m, 25 "
    "obstacles, 25 hazards, landmark clusters); it is not the paper's world, which was not published.",
    "Noise levels the paper does not give (IMU speed and heading, process noise, the synthetic trajectory's length "
    "and initial speed, PF particle count, the prior) are ours, listed under Parameters.",
    "Times are wall times on this machine of compiled C++ (the paper's are Python); we also report time per step, "
    "since the paper does not say how long its trials are.",
)


def _img(path: Path) -> str:
    data = base64.b64encode(Path(path).read_bytes()).decode()
    return (f'<figure><img alt="{html.escape(Path(path).name)}" src="data:image/png;base64,{data}">'
            f'<figcaption>{html.escape(Path(path).name)} (SVG beside it)</figcaption></figure>')


def _table_html(df: pd.DataFrame) -> str:
    def fmt(v):
        return "—" if isinstance(v, float) and np.isnan(v) else f"{v:.4g}"
    return df.to_html(index=False, float_format=fmt, border=0, classes="t", na_rep="—")


_CSS = """body{font-family:system-ui,sans-serif;max-width:1200px;margin:2em auto;padding:0 1em;color:#222}
table.t{border-collapse:collapse;font-size:12px;margin:.5em 0 1.5em}table.t td,table.t th{padding:3px 7px;
border-bottom:1px solid #ddd;text-align:right}table.t th{background:#f3f3f3}img{max-width:100%}
figure{margin:1em 0}figcaption{font-size:11px;color:#666}.yes{color:#080}.no{color:#b00}.na{color:#777}
pre{background:#f6f6f6;padding:.8em;font-size:11px;overflow-x:auto}"""


def write_report(results, opts, path=None) -> Path:
    """One self-contained HTML file (figures embedded as PNG) with every
    table, figure, the parameters and seeds, software versions, departures
    from the paper and the paper's claims with our verdicts.  Written
    atomically to ``path`` (default ``<out>/report.html``)."""
    path = Path(path) if path is not None else opts.out / "report.html"
    e = html.escape
    parts = [f"<!doctype html><html><head><meta charset='utf-8'><title>safenav: SafeNav paper reproduction</title>"
             f"<style>{_CSS}</style></head><body>",
             "<h1>SafeNav paper reproduction</h1>",
             f"<p>Generated by <code>safenav experiment</code> on {e(time.strftime('%Y-%m-%d %H:%M:%S'))}: "
             f"{opts.trials} trials per cell, seed {int(opts.seed)}, scenario <code>{e(opts.scenario.name)}</code>. "
             "Table numbers are the conference version's (the extended version numbers them one higher). "
             "'paper …' columns are the paper's numbers; the others are ours.</p>"]
    claims = [c for r in results for c in r.claims]
    if claims:
        parts.append("<h2>The paper's claims</h2>"
                     f"<p>Each judged claim compares one quantity with a threshold. Its {CONFIDENCE:.0%} interval is "
                     f"a percentile bootstrap over trials ({BOOTSTRAP} resamples, paired: every cell is resampled "
                     "with the same trials, since every cell runs the same trials; seeded). A claim <b>holds</b> "
                     "when the whole interval lies above the threshold, <b>does not hold</b> when it lies at or "
                     "below it, and is <b>undecided</b> when the interval spans it. With fewer than "
                     f"{MIN_TRIALS} trials per cell a claim is <b>too few trials to judge</b>.</p><ul>")
        for c in claims:
            cls = {True: "yes", False: "no", None: "na"}[c.holds]
            parts.append(f"<li><span class='{cls}'><b>{e(c.verdict)}</b></span>: {e(c.text)}. "
                         f"<i>{e(c.evidence)}</i></li>")
        parts.append("</ul>")
    for r in results:
        parts.append(f"<h2>{e(r.title)}</h2><p>Experiment <code>{e(r.name)}</code>, {r.wall_s:.1f} s.</p>")
        for title, df in r.tables.items():
            parts.append(f"<h3>{e(title)}</h3>{_table_html(df)}")
        for f in r.figures:
            parts.append(_img(f))
        for n in r.notes:
            parts.append(f"<p class='note'>{e(n)}</p>")
    parts.append("<h2>Where we depart from the paper</h2><ul>")
    parts += [f"<li>{e(d)}</li>" for d in DEPARTURES]
    parts.append("</ul>")
    parts.append(f"<h2>Parameters and seeds</h2><pre>{e(json.dumps(parameters(opts), indent=1, default=str))}</pre>")
    parts.append("<h2>Software</h2><table class='t'>" + "".join(
        f"<tr><th>{e(k)}</th><td>{e(str(v))}</td></tr>" for k, v in versions().items()) + "</table>")
    parts.append("</body></html>")
    text = "\n".join(parts)
    return write_text(path, text)
