"""Figures of the landmark placement paper (matplotlib, Agg): the route with
its landmarks [Placement Figs. 6–7], the EIF errors with ±3σ [Placement
Figs. 8–9], the corner coverage demonstration and [Placement Table I]'s
counts."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..results import pyplot, save_figure
from .algorithm import PAPER_AREA, PAPER_SPACING, CameraParams, PlacementResult, candidate_grid, place_along_route
from .study import SimulationResult, corner_gap_demo, random_instance, simulate, table_one
from .tour import plan_tour


def plot_placement(result: PlacementResult, path, *, simulation: SimulationResult | None = None,
                   title: str | None = None) -> Path:
    """Route, candidates, placed landmarks (numbered) and, if given, the true
    and estimated paths (the paper's Figs. 6–7).  Writes a PNG; returns its path."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(5.2, 7.0))
    c, lm, r = result.candidates, result.landmarks, result.route
    ax.plot(c[:, 0], c[:, 1], ".", ms=1.5, color="0.8", label="candidates")
    ax.plot(r[:, 0], r[:, 1], "-", color="tab:blue", lw=1.2, label="route")
    ax.plot(r[:, 0], r[:, 1], "o", color="tab:blue", ms=6, label="targets (waypoints)")
    for i, p in enumerate(r):
        ax.annotate(str(i + 1), p, textcoords="offset points", xytext=(4, 4), fontsize=8, color="tab:blue")
    ax.plot(lm[:, 0], lm[:, 1], "^", color="tab:red", ms=6, label=f"landmarks ({result.count})")
    for i, p in enumerate(lm):
        ax.annotate(str(i + 1), p, textcoords="offset points", xytext=(3, -8), fontsize=6, color="tab:red")
    if simulation is not None:
        ax.plot(simulation.truth[:, 0], simulation.truth[:, 1], "k-", lw=1.0, label="true path")
        ax.plot(simulation.estimate[:, 0], simulation.estimate[:, 1], "--", color="tab:green", lw=1.0,
                label="EIF estimate")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(loc="best", fontsize=7)
    cam = result.camera
    ax.set_title(title or f"{result.method}: {result.count} landmarks, k = {result.k}\n"
                 f"R = {cam.range} m, alpha = {cam.angle_deg} deg, p = {cam.clearance} m", fontsize=9)
    fig.tight_layout()
    return save_figure(fig, path, dpi=130)


def plot_simulation(sim: SimulationResult, path, *, title: str | None = None) -> Path:
    """X, Y and heading errors with ±3σ bounds over time (the paper's Figs. 8–9),
    with the number of landmarks in view.  Writes a PNG; returns its path."""
    plt = pyplot()
    fig, axes = plt.subplots(4, 1, figsize=(7.5, 8.0), sharex=True)
    err, sig = sim.errors, sim.sigmas
    inside = sim.inside_3sigma()
    for i, (name, unit) in enumerate((("x", "m"), ("y", "m"), ("heading", "rad"))):
        ax = axes[i]
        ax.plot(sim.t, err[:, i], color="tab:blue", lw=0.9, label=f"error {name}")
        ax.plot(sim.t, 3 * sig[:, i], "r--", lw=0.8, label="+3σ")
        ax.plot(sim.t, -3 * sig[:, i], "r--", lw=0.8, label="-3σ")
        ax.set_ylabel(f"{name} error [{unit}]")
        ax.set_title(f"{100 * inside[name]:.1f}% of the time within ±3σ", fontsize=8, loc="right")
        if i == 0:
            ax.legend(loc="upper left", fontsize=7, ncol=3)
    axes[3].step(sim.t, sim.n_in_view, where="post", color="0.3", lw=0.8)
    axes[3].axhline(2, color="tab:red", lw=0.6, ls=":")
    axes[3].fill_between(sim.t, 0, sim.n_in_view.max() + 1, where=sim.turning, color="tab:orange", alpha=0.2,
                         step="post", label="turning in place")
    axes[3].set_ylabel("in view")
    axes[3].set_xlabel("time [s]")
    axes[3].legend(loc="upper right", fontsize=7)
    fig.suptitle(title or "Bearing-only EIF on the placed landmarks", fontsize=10)
    fig.tight_layout()
    return save_figure(fig, path, dpi=130)


def plot_corner_gap(demo: dict, path) -> Path:
    """Landmarks in view and heading 3σ over time without and with corner
    coverage (:func:`corner_gap_demo`).  Writes a PNG; returns its path."""
    plt = pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(10, 5.2), sharex="col")
    for j, key in enumerate(("plain", "corners")):
        d = demo[key]
        sim, pl = d["simulation"], d["placement"]
        ax = axes[0, j]
        ax.step(sim.t, sim.n_in_view, where="post", color="0.25", lw=0.8)
        ax.axhline(2, color="tab:red", ls=":", lw=0.8)
        ax.fill_between(sim.t, 0, sim.n_in_view.max() + 1, where=sim.turning, step="post", color="tab:orange",
                        alpha=0.25, label="turning in place")
        ax.set_ylabel("landmarks in view")
        ax.set_title(f"{'with' if key == 'corners' else 'without'} corner coverage: {pl.count} landmarks; "
                     f"< 2 in view {100 * d['turn_gap']:.0f}% of turning time", fontsize=8)
        ax.legend(loc="upper right", fontsize=7)
        ax = axes[1, j]
        ax.plot(sim.t, 3 * sim.sigmas[:, 2], color="tab:purple", lw=0.9, label="3σ heading")
        ax.plot(sim.t, np.abs(sim.errors[:, 2]), color="tab:blue", lw=0.7, label="|heading error|")
        ax.set_ylabel("rad")
        ax.set_xlabel("time [s]")
        ax.legend(loc="upper right", fontsize=7)
    fig.tight_layout()
    return save_figure(fig, path, dpi=120)


def paper_figures(folder="docs/figures", *, seed: int = 0) -> dict:
    """Regenerate the figures of docs/placement.md: [Placement Figs. 6–9]
    (6 and 7 targets: route, landmarks, true and EIF paths; X/Y/heading errors
    with ±3σ), the corner-coverage demonstration, and Table I's counts.
    Returns the numbers quoted in the docs."""
    folder = Path(folder)
    cam = CameraParams()
    cand = candidate_grid((0, 0), PAPER_AREA, PAPER_SPACING, margin=cam.range)
    rng = np.random.default_rng(seed)
    numbers = {}
    for n in (6, 7):
        while True:  # first feasible instance of this size
            targets = random_instance(n, rng)
            route = targets[plan_tour(targets)]
            pl = place_along_route(route, cand, cam, allow_uncovered=True)
            if pl.covered:
                break
        sim = simulate(route, pl.landmarks, cam, seed=seed)
        plot_placement(pl, folder / f"placement_route{n}.png", simulation=sim,
                       title=f"{n} targets, {pl.count} landmarks (greedy, k = 2)")
        plot_simulation(sim, folder / f"placement_errors{n}.png",
                        title=f"{n} targets, {pl.count} landmarks: EIF errors with ±3σ")
        numbers[f"targets{n}"] = {"landmarks": pl.count, "duration_s": float(sim.t[-1]),
                                  "inside_3sigma": sim.inside_3sigma(), "below_2_in_view": sim.gap_fraction(2)}
    demo = corner_gap_demo(seed=3, n_targets=6)
    plot_corner_gap(demo, folder / "placement_corners.png")
    numbers["corners"] = {k: {"landmarks": v["placement"].count, "turn_gap": v["turn_gap"], "gap": v["gap"],
                              "inside_3sigma": v["inside_3sigma"]} for k, v in demo.items()}
    df = table_one(seed=seed)
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 3.4))
    idx = np.arange(len(df))
    cols = (("paper", "paper (its own instances)", "0.6"), ("greedy_paper", "greedy (Alg. 1)", "tab:blue"),
            ("optimal", "ILP optimum", "tab:green"), ("greedy_corners", "greedy + corners", "tab:orange"),
            ("optimal_corners", "ILP + corners", "tab:red"))
    w = 0.16
    for j, (c, label, color) in enumerate(cols):
        ax.bar(idx + (j - 2) * w, df[c].astype(float), w, label=label, color=color)
    ax.set_xticks(idx, [f"#{i}\n{t} targets" for i, t in zip(df.instance, df.targets)], fontsize=7)
    ax.set_ylabel("landmarks")
    ax.set_title(f"Table I: nine random instances (seed {seed}) beside the paper's counts", fontsize=9)
    ax.legend(fontsize=7, ncol=3)
    fig.tight_layout()
    save_figure(fig, folder / "placement_table1.png", dpi=120)
    numbers["table_one"] = df
    return numbers
