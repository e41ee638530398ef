"""``safenav experiment``: every experiment end to end at a small trial count,
summary tables recomputed from the raw tables, the report embedding every
figure, the paper's claims judged from the numbers, and bit-for-bit
reproducibility locally and on a Dask LocalCluster."""

from __future__ import annotations

import base64
import re

import numpy as np
import pandas as pd
import pytest

from safenav import cli, experiments as ex, results, runner

TRIALS = 3


@pytest.fixture(scope="module")
def run_all(tmp_path_factory):
    out = tmp_path_factory.mktemp("experiments")
    rc = cli.main(["experiment", "all", "--trials", str(TRIALS), "--camera-trials", "1", "--position-every", "30",
                   "--particles", "200", "--out", str(out), "--quiet"])
    assert rc == 0
    return out


def test_every_experiment_writes_raw_summary_and_figures(run_all):
    out = run_all
    for name, figs in (("field", ["fig1_field"]), ("synthetic", ["fig3_wrs"]), ("real-imitated", []),
                       ("navigation", ["fig4_chull", "fig5_centroid"])):
        folder = out / name
        for f in figs:
            assert (folder / f"{f}.png").stat().st_size > 10_000 and (folder / f"{f}.svg").stat().st_size > 10_000
        if name != "field":
            raw = pd.read_parquet(folder / "trials.parquet")
            assert len(raw) > 0 and not raw.isna().all(axis=None)
    for table in ("synthetic/table1", "real-imitated/table2", "real-imitated/table2_placed", "real-imitated/camera_loop",
                  "navigation/table3",
                  "navigation/table4", "navigation/camera_loop"):
        assert (out / f"{table}.csv").stat().st_size > 0
        md = (out / f"{table}.md").read_text()
        assert md.count("\n|") >= 2
    assert not list(out.rglob(".safenav-tmp-*"))
    # the manifest is written last and lists every file of the run
    m = results.verify_run(out)
    listed = {f["path"] for f in m["files"]}
    written = {p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file() and p.name != "manifest.json"}
    assert listed == written and {"report.html", "parameters.json", "navigation/trials_timings.csv"} <= listed
    assert m["command"][:3] == ["safenav", "experiment", "all"] and m["parameters"]["trials"] == TRIALS


def test_table1_has_the_papers_layout_and_is_the_mean_of_the_raw_table(run_all):
    raw = results.read_table(run_all / "synthetic" / "trials.parquet")
    assert "time ms" not in pd.read_csv(run_all / "synthetic" / "table1.csv")     # timings beside the table
    t1 = results.read_table(run_all / "synthetic" / "table1.csv")
    assert list(t1.columns) == ["Algorithm", "Filter", "ADE", "FDE", "AWRS", "paper ADE", "paper FDE",
                                "paper AWRS", "paper ms", "time ms"]
    # the paper's row order: DeepLocGPS, DeepLocGPSEKF, Sensor Fusion, LanBLoc-BMM; EKF then PF
    assert [a.split(" (")[0] for a in t1["Algorithm"][::2]] == ["DeepLoc-GPS", "DeepLoc-EKF-GPS", "Sensor Fusion",
                                                                 "LanBLoc-BMM"]
    assert list(t1["Filter"]) == ["EKF", "PF"] * 4
    assert all("(emulated)" in a for a in t1["Algorithm"][:6])
    for (src, filt), row in zip([(s, f) for s in ex.PAPER_SOURCES for f in ("ekf", "pf")], t1.itertuples()):
        g = raw[(raw["source"] == src) & (raw["filter"] == filt)]
        assert len(g) == TRIALS
        assert row.ADE == pytest.approx(g["truth_ade"].mean(), rel=1e-12)
        assert row.FDE == pytest.approx(g["truth_fde"].mean(), rel=1e-12)
        assert row.AWRS == pytest.approx(g["awrs"].mean(), rel=1e-12)
        assert getattr(row, "_10") == pytest.approx(g["ms_per_trial"].median(), rel=1e-12)
        assert getattr(row, "_6") == ex.PAPER_TABLE1[(src, filt)][0]


def test_table2_is_the_path_average_of_per_path_localization_errors(run_all):
    raw = pd.read_parquet(run_all / "real-imitated" / "trials.parquet")
    t2 = pd.read_csv(run_all / "real-imitated" / "table2.csv")
    assert len(t2) == 8 and set(raw["path_type"]) == {"P1", "P2", "P3"} and set(raw["method"]) == {"centroid"}
    row = t2[(t2["Algorithm"] == "LanBLoc-BMM") & (t2["Filter"] == "PF")].iloc[0]
    ok = raw[(raw["source"] == "lanbloc") & (raw["filter"] == "pf") & raw["success"]]
    per_path = ok.groupby("path_type")
    assert row["ADE"] == pytest.approx(per_path["truth_ade"].mean().mean(), rel=1e-12)
    assert row["FDE"] == pytest.approx(per_path["truth_fde"].mean().mean(), rel=1e-12)
    assert row["AWRS"] == pytest.approx(per_path["awrs"].mean().mean(), rel=1e-12)
    assert row["paper ms"] == ex.PAPER_TABLE2[("lanbloc", "pf")][3]


def test_placed_landmarks_give_lanbloc_a_fix_at_almost_every_step(run_all):
    raw = pd.read_parquet(run_all / "real-imitated" / "trials.parquet")
    placed = pd.read_parquet(run_all / "real-imitated" / "placed_trials.parquet")
    own = raw[raw["source"] == "lanbloc"].reset_index(drop=True)
    assert list(placed["seed"]) == list(own["seed"])          # the same trials
    share = lambda df: (df["position_fixes"] / df["steps"]).mean()  # noqa: E731
    assert share(own) < 0.5 < 0.95 < share(placed)
    t = pd.read_csv(run_all / "real-imitated" / "table2_placed.csv")
    row = t[(t["Filter"] == "EKF") & t["Landmarks"].str.startswith("clusters + placed")].iloc[0]
    ok = placed[(placed["filter"] == "ekf") & placed["success"]]
    assert row["ADE"] == pytest.approx(ok.groupby("path_type")["truth_ade"].mean().mean(), rel=1e-12)
    assert row["fix share"] == pytest.approx(share(placed[placed["filter"] == "ekf"]), rel=1e-12)


def test_tables3_and_4_are_recomputed_from_the_raw_table(run_all):
    raw = results.read_table(run_all / "navigation" / "trials.parquet")
    t3 = pd.read_csv(run_all / "navigation" / "table3.csv")
    t4 = results.read_table(run_all / "navigation" / "table4.csv")
    assert list(t3.columns) == ["Approach", "P1", "paper P1", "P2", "paper P2", "P3", "paper P3", "Average",
                                "paper Average"]
    assert list(t3["Approach"]) == ["SafeNav-CHull", "SafeNav-Centroid"]
    for method, label in (("chull", "SafeNav-CHull"), ("centroid", "SafeNav-Centroid")):
        ok = raw[(raw["method"] == method) & raw["success"]]
        per_path = ok.groupby("path_type")["path_error_percent"].mean()
        r3 = t3[t3["Approach"] == label].iloc[0]
        for p in ("P1", "P2", "P3"):
            assert r3[p] == pytest.approx(per_path[p], rel=1e-12)
        assert r3["Average"] == pytest.approx(per_path.mean(), rel=1e-12)
        r4 = t4[(t4["Approach"] == label) & (t4["Path"] == "P2")].iloc[0]
        g = raw[(raw["method"] == method) & (raw["path_type"] == "P2")]
        assert r4["ADE"] == pytest.approx(g[g["success"]]["path_ade"].mean(), rel=1e-12)
        assert r4["time ms"] == pytest.approx(g["time_ms"].median(), rel=1e-12)
        assert r4["paper ADE"] == ex.PAPER_NAVIGATION[method]["P2"][0]


def test_camera_variant_runs_the_vision_pipeline_on_the_same_trials(run_all):
    raw = pd.read_parquet(run_all / "navigation" / "camera_trials.parquet")
    assert set(raw["source"]) == {"lanbloc", "lanbloc-camera"}
    meas, cam = raw[raw["source"] == "lanbloc"], raw[raw["source"] == "lanbloc-camera"]
    assert list(meas["seed"]) == list(cam["seed"])          # paired: the same trials
    # the camera made fixes; with occlusion and a frame only every 30 steps, a trial may see no three
    # whole markers at once in any of its frames.  P1 starts out of sight of every landmark with
    # sigma = 1 m: the guard (k = 4.6 from the risk budget) holds there, turning toward landmarks that
    # the camera may never show whole; such a trial ends at the step limit, never in a collision.
    blind = cam[cam["position_fixes"] == 0]
    assert cam["position_fixes"].sum() > 0
    assert (blind["path_type"] == "P1").sum() >= len(blind) - 1
    assert not (blind["outcome"] == "collision").any()
    # the camera's fixes are not the measurement-level ones
    assert not np.allclose(meas["truth_ade"].to_numpy(), cam["truth_ade"].to_numpy())


def test_report_embeds_every_figure_and_lists_claims_departures_params_versions(run_all):
    report = (run_all / "report.html").read_text()
    pngs = sorted(run_all.rglob("*.png"))
    assert [p.name for p in pngs] == ["fig1_field.png", "fig4_chull.png", "fig5_centroid.png", "fig3_wrs.png"]
    embedded = re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', report)
    assert sorted(base64.b64decode(e) for e in embedded) == sorted(p.read_bytes() for p in pngs)
    for title in ("Table I", "Table II", "Table III", "Table IV", "camera in the loop"):
        assert title in report
    verdicts = re.findall(r"<li><span class='(\w+)'><b>([a-z ]+)</b></span>: Table (I|II|III|IV):", report)
    assert len(verdicts) >= 15
    # 3 trials per cell: nothing is judged; the CI is shown all the same
    assert {(cls, w) for cls, w, _ in verdicts} == {("na", "too few trials to judge"), ("na", "not comparable")}
    assert {t for _, _, t in verdicts} == {"I", "II", "III", "IV"}
    assert f"fewer than {ex.MIN_TRIALS} trials per cell" in report and "95% CI [" in report
    assert "Where we depart from the paper" in report and "emulated" in report
    assert "Parameters and seeds" in report and '&quot;seed&quot;: ' in report
    assert "numpy" in report and "python" in report
    assert (run_all / "parameters.json").stat().st_size > 0


def _nav_raw(means: dict, n: int, sd: float = 0.1, seed: int = 0) -> pd.DataFrame:
    """A navigation raw table: ``means[method][metric]`` is a value or a {path: value} dict; trial 0 of every
    cell did not arrive (its huge numbers must not count)."""
    rng = np.random.default_rng(seed)
    rows = []
    for method, ms in means.items():
        for p in ("P1", "P2", "P3"):
            for t in range(n):
                row = {"path_type": p, "method": method, "trial": t, "success": t != 0, "time_ms": 15.0}
                for k, v in ms.items():
                    v = v[p] if isinstance(v, dict) else v
                    row[k] = 1e3 if t == 0 else v + sd * rng.standard_normal()
                rows.append(row)
    return pd.DataFrame(rows)


GOOD = {"chull": {"path_error_percent": {"P1": 5.0, "P2": 7.0, "P3": 6.0}, "path_ade": 2.0, "goal_fde": 3.0, "awrs": 1.3},
        "centroid": {"path_error_percent": {"P1": 4.0, "P2": 6.0, "P3": 5.0}, "path_ade": 1.0, "goal_fde": 0.9, "awrs": 1.0}}


def _verdicts(claims):
    return {c.text.split(":")[1].strip()[:45]: c.verdict for c in claims}


def test_navigation_claims_are_judged_by_their_confidence_interval():
    good = ex.navigation_claims(_nav_raw(GOOD, 40))
    judged = [c for c in good if c.interval is not None]
    assert len(good) == 7 and len(judged) == 4
    assert all(c.verdict == "holds" and c.holds is True and c.interval[0] > 0 for c in judged)
    assert all("95% CI [" in c.evidence for c in judged)
    # FDE claims measure the arrival radius, not the method: never judged
    assert [c.verdict for c in good if "FDE" in c.text] == ["not comparable"] * 2
    bad = ex.navigation_claims(_nav_raw({"chull": GOOD["centroid"], "centroid": {
        **GOOD["chull"], "path_error_percent": {"P1": 7.0, "P2": 5.0, "P3": 6.0}}}, 40))
    assert [c.verdict for c in bad if c.interval is not None] == ["does not hold"] * 4
    assert [c.holds for c in bad if c.interval is not None] == [False] * 4
    # 3 % lower with noisy trials: the interval spans the 5 % threshold
    close = {m: {**v, "path_ade": a} for (m, v), a in zip(GOOD.items(), (1.03, 1.0))}
    c = [c for c in ex.navigation_claims(_nav_raw(close, 40, sd=0.3)) if "ADE is 1.67" in c.text][0]
    assert c.verdict == "undecided" and c.holds is None and c.interval[0] < 1.05 < c.interval[1]
    # below MIN_TRIALS nothing is judged, whatever the numbers
    few = ex.navigation_claims(_nav_raw(GOOD, ex.MIN_TRIALS - 1))
    assert [c.verdict for c in few if c.interval is not None] == ["too few trials to judge"] * 4
    # the point estimates are the tables' (means over arrived trials, averaged over path types)
    raw = _nav_raw(GOOD, 40)
    ok = raw[raw["success"]]
    ratio = [c for c in good if "ADE is 1.67" in c.text][0]
    expect = (ok[ok.method == "chull"].groupby("path_type")["path_ade"].mean().mean()
              / ok[ok.method == "centroid"].groupby("path_type")["path_ade"].mean().mean())
    assert f"ours: {expect:.2f}× lower" in ratio.evidence
    # deterministic: the same table gives the same intervals
    assert [c.interval for c in ex.navigation_claims(raw)] == [c.interval for c in good]


def _loc_raw(means: dict, n: int = 40, sd: float = 0.005) -> pd.DataFrame:
    """A Table I raw table: means[(source, filter)] = (ADE, FDE, AWRS, ms per trial)."""
    rng = np.random.default_rng(1)
    return pd.DataFrame([{"source": s, "filter": f, "trial": t,
                          **{k: v + sd * rng.standard_normal() for k, v in zip(("truth_ade", "truth_fde", "awrs"), m)},
                          "ms_per_trial": m[3]}
                         for (s, f), m in means.items() for t in range(n)])


def test_localization_claims_are_judged_by_their_confidence_interval():
    means = {("deeploc-gps", "ekf"): (0.5, 0.5, 0.3, 1.0), ("deeploc-gps", "pf"): (0.9, 0.9, 0.9, 50.0),
             ("lanbloc", "ekf"): (0.4, 0.6, 0.2, 0.9), ("lanbloc", "pf"): (0.8, 0.8, 0.8, 40.0)}
    cols = ("truth_ade", "truth_fde", "awrs", "ms_per_trial")
    claims = {c.text: c for c in ex.localization_claims(_loc_raw(means), "Table I", paper=ex.PAPER_TABLE1,
                                                                 columns=cols)}
    assert claims["Table I: LanBLoc-BMM(EKF) has the lowest ADE of all rows"].verdict == "holds"
    assert claims["Table I: LanBLoc-BMM(EKF) has the lowest FDE of all rows"].verdict == "does not hold"
    assert claims["Table I: the EKF has a lower ADE than the PF for every method"].verdict == "holds"
    assert [c.verdict for k, c in claims.items() if "orders of magnitude" in k] == ["does not hold"]   # 44-50x
    assert claims["Table I: LanBLoc-BMM(EKF) has the lowest runtime"].verdict == "not comparable"
    dear = {k: (*v[:3], v[3] * 10 if k[1] == "pf" else v[3]) for k, v in means.items()}
    claims = ex.localization_claims(_loc_raw(dear), "Table I", paper=ex.PAPER_TABLE1, columns=cols)
    assert [c.verdict for c in claims if "orders of magnitude" in c.text] == ["holds"]                # 444-500x
    noise = {**means, ("deeploc-gps", "pf"): (0.51, 0.9, 0.9, 50.0)}                                   # a 2 % gap
    claims = ex.localization_claims(_loc_raw(noise), "Table I", paper=ex.PAPER_TABLE1, columns=cols)
    assert [c.verdict for c in claims if "lower ADE than the PF" in c.text] == ["does not hold"]
    few = ex.localization_claims(_loc_raw(means, n=5), "Table I", paper=ex.PAPER_TABLE1, columns=cols)
    assert {c.verdict for c in few} == {"too few trials to judge", "not comparable"}


def test_runs_are_bit_for_bit_reproducible_locally_and_on_dask(tmp_path):
    distributed = pytest.importorskip("distributed")
    runs = {(w, c): ex.synthetic_experiment(4, sources=("lanbloc", "sensor-fusion"), seed=5, n_particles=100,
                                            workers=w, chunk=c) for w, c in ((1, 1), (2, 3))}
    syn = {w: runs[(w, c)].raw for w, c in runs}
    # Fig. 3's curves too: the same bits whatever the chunking
    for k, v in runs[(1, 1)].wrs_mean.items():
        np.testing.assert_array_equal(runs[(2, 3)].wrs_mean[k], v)
    opts = ex.ExperimentOptions(trials=4, particles=100, seed=5, path_types=("P2",), out="unused", workers=1)
    safe = runner.plan_safe_paths(opts.scenario, ["P2"])
    sweep = opts.sweep(methods=("centroid",), filters=("ekf", "pf"), sources=("deeploc-ekf-gps",),
                             trials=4, chunk=1)
    nav = {1: runner.run_sweep(sweep, workers=1, safe_paths=safe), 2: runner.run_sweep(sweep, workers=2, safe_paths=safe)}
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cl, \
            distributed.Client(cl) as client:
        nav["dask"] = runner.run_sweep(sweep, scheduler=client, safe_paths=safe)
        syn["dask"] = ex.synthetic_experiment(4, sources=("lanbloc", "sensor-fusion"), seed=5, n_particles=100,
                                              scheduler=client, chunk=1).raw
    drop = lambda df: df.drop(columns=[c for c in results.TIMING_COLUMNS if c in df])  # noqa: E731
    for runs in (syn, nav):
        ref = drop(runs[1])
        for k, df in runs.items():
            pd.testing.assert_frame_equal(drop(df), ref, check_exact=True)
    # the written tables are byte-identical (the wall times go beside them)
    for name, runs in (("syn", syn), ("nav", nav)):
        written = {}
        for k, df in runs.items():
            folder = tmp_path / f"{name}_{k}"
            results.write_table(df, folder / "trials", markdown="t")
            written[k] = {f: (folder / f).read_bytes() for f in ("trials.csv", "trials.parquet", "trials.md")}
        assert written[1] == written[2] == written["dask"]
    # different seeds give different numbers (the comparison above can fail)
    other = ex.synthetic_experiment(4, sources=("lanbloc",), seed=6, n_particles=100).raw
    assert not np.array_equal(other["truth_ade"].to_numpy(), syn[1][syn[1]["source"] == "lanbloc"]["truth_ade"].to_numpy())


def test_a_subset_of_path_types_runs_the_same_trials_as_a_full_run():
    opts = ex.ExperimentOptions(trials=2, seed=3, out="unused")
    safe = runner.plan_safe_paths(opts.scenario)
    full = runner.run_sweep(opts.sweep(methods=("centroid",), filters=("ekf",), sources=("lanbloc",),
                                             trials=2), safe_paths=safe)
    only = runner.run_sweep(runner.Sweep(opts.scenario, path_types=("P3",), methods=("centroid",), trials=2, seed=3),
                            safe_paths=safe)
    drop = ["time_ms", "time_per_step_us"]
    pd.testing.assert_frame_equal(only.drop(columns=drop),
                                  full[full["path_type"] == "P3"].drop(columns=drop).reset_index(drop=True))
    assert not np.array_equal(full[full["path_type"] == "P1"]["seed"], only["seed"])


def test_bad_experiment_arguments_give_clear_errors(capsys, tmp_path):
    assert cli.main(["experiment", "table9", "--out", str(tmp_path)]) == 2
    assert "experiment 'table9' is unknown" in capsys.readouterr().err
    assert cli.main(["experiment", "field", "--trials", "0", "--out", str(tmp_path)]) == 2
    assert "argument --trials: must be an integer >= 1, got 0" in capsys.readouterr().err
    assert cli.main(["experiment", "field", "--path-types", "P9", "--out", str(tmp_path)]) == 2
    assert "'P9' is not a path type" in capsys.readouterr().err
    assert cli.main(["experiment", "all", "--workers", "0", "--out", str(tmp_path)]) == 2
    assert "argument --workers: must be" in capsys.readouterr().err and not (tmp_path / "field").exists()
    assert ex.resolve(["table4", "fig1", "table3"]) == ["field", "navigation"]
    with pytest.raises(ValueError, match="source = .gps.: unknown position source"):
        ex.synthetic_experiment(1, sources=("gps",))
