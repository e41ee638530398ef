"""Figures of the experiments and of ``safenav demo``/``run``.  Plots live
beside the metrics, not inside them (evo's habit)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import navigation as nav
from .. import runner
from ..results import pyplot
from .paper import METHOD_LABELS


def plot_synthetic_trial(data, estimates: dict, path: str | Path, *, title: str | None = None) -> Path:
    """One synthetic trial: truth, LanBLoc fixes and filter estimates, plus position error over time.

    ``estimates`` maps a label ("EKF", "PF", …) to a :class:`~safenav.filters.FilterResult`.
    Writes a PNG (and an SVG beside it) and returns the PNG path."""
    plt = pyplot()
    fig, (ax, ax_err) = plt.subplots(1, 2, figsize=(11, 4.6), gridspec_kw={"width_ratios": [1.35, 1]})
    ax.plot(data.states[:, 0], data.states[:, 1], "k-", lw=2.0, label="truth")
    fix = data.position[~np.isnan(data.position[:, 0])]
    ax.plot(fix[:, 0], fix[:, 1], ".", ms=2.5, color="0.55", label="LanBLoc fixes")
    colors = {"EKF": "tab:blue", "PF": "tab:orange", "EIF": "tab:green"}
    for label, res in estimates.items():
        ax.plot(res.states[:, 0], res.states[:, 1], "--", lw=1.3, color=colors.get(label), label=label)
        err = np.hypot(*(res.states[:, :2] - data.states[:, :2]).T)
        sig = np.sqrt(res.covariances[:, 0, 0] + res.covariances[:, 1, 1])
        ax_err.plot(data.t, err * 100, color=colors.get(label), lw=1.2, label=f"{label} error")
        ax_err.plot(data.t, 3 * sig * 100, ":", color=colors.get(label), lw=1.0, label=f"{label} 3σ")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(loc="best", fontsize=8)
    ax.set_title(title or "Synthetic trajectory (SafeNav-ext V-A3(i)), LanBLoc-BMM")
    ax_err.set_xlabel("t [s]")
    ax_err.set_ylabel("position error [cm]")
    ax_err.set_yscale("log")
    ax_err.legend(fontsize=8)
    ax_err.grid(alpha=0.3)
    fig.tight_layout()
    return _save(fig, path, dpi=130)


def _draw_world(ax, world, *, hazard_label=None, obstacle_label=None) -> None:
    """Hazards (orange, darker = riskier) and obstacles (grey) of ``world``."""
    from matplotlib.patches import Circle as _Circle, Polygon as _Polygon

    from ..world import Circle

    for i, h in enumerate(world.hazards):
        patch = (_Circle(tuple(h.shape.center), h.shape.radius) if isinstance(h.shape, Circle)
                 else _Polygon(h.shape.array(), closed=True))
        patch.set(facecolor="tab:orange", alpha=0.18 + 0.1 * min(h.risk, 5) / 5, edgecolor="none",
                  label=hazard_label if i == 0 else None)
        ax.add_patch(patch)
    for i, o in enumerate(world.obstacles):
        patch = _Circle(tuple(o.center), o.radius) if isinstance(o, Circle) else _Polygon(o.array(), closed=True)
        patch.set(facecolor="0.25", edgecolor="k", lw=0.5, label=obstacle_label if i == 0 else None)
        ax.add_patch(patch)


def corridor_lines(corridor, samples: int = 400) -> list[tuple[float, np.ndarray]]:
    """The safe buffer of a ``_core.Corridor`` as lines: ``(offset, (samples, 2) points)``
    for each zone border and the two edges (offset ±half-width), the central path left out."""
    W = corridor.half_width
    off = np.linspace(-W, W, 2 * corridor.zone_count + 1)
    pts = np.asarray(corridor.points_at(np.linspace(0, corridor.length, samples)))
    tang = np.gradient(pts, axis=0)
    tang /= np.maximum(np.linalg.norm(tang, axis=1, keepdims=True), 1e-12)
    normal = np.c_[-tang[:, 1], tang[:, 0]]
    return [(float(o), pts + o * normal) for o in off if o != 0]


def _draw_corridor(ax, corridor, *, color="tab:green", label=None) -> None:
    """The safe buffer of a ``_core.Corridor``: its edges (bold) and zone borders (thin)."""
    W = corridor.half_width
    for o, edge in corridor_lines(corridor):
        ax.plot(edge[:, 0], edge[:, 1], "-", color=color, lw=0.9 if abs(o) == W else 0.4,
                alpha=0.8 if abs(o) == W else 0.4, label=label if o == W else None)


def _save(fig, path, dpi=120) -> Path:
    """Write ``path`` (PNG) and an SVG beside it with the one result writer; close the figure."""
    from ..results import save_figure

    return save_figure(fig, path, dpi=dpi, svg=True)


def plot_field(scenario, safe_paths: dict, path: str | Path, *, title: str | None = None) -> Path:
    """[SafeNav-ext Fig. 1]: the field with its landmark clusters (numbered at their
    centroids), obstacles, hazards and, per path type, the safe path with its
    buffer (the risk-zone corridor).  ``safe_paths`` maps a path type name to
    its (M, 2) safe path.  Writes a PNG and an SVG; returns the PNG path."""
    from .. import _core

    plt = pyplot()
    world = scenario.world
    fig, ax = plt.subplots(figsize=(8.2, 7.6))
    b = world.field.bounds
    from matplotlib.patches import Rectangle

    ax.add_patch(Rectangle(tuple(b[0]), *(b[1] - b[0]), fill=False, edgecolor="k", lw=0.8))
    _draw_world(ax, world, hazard_label="hazard", obstacle_label="obstacle")
    cmap = plt.get_cmap("tab20")
    for i, (cid, lms) in enumerate(sorted(world.clusters().items())):
        xy = np.array([lm.xy for lm in lms])
        ax.plot(xy[:, 0], xy[:, 1], "^", ms=4, color=cmap(i % 20), label="landmarks (by cluster)" if i == 0 else None)
        c = world.cluster_centroid(cid)
        ax.annotate(str(cid), c, fontsize=7, ha="center", va="center", color="k",
                    bbox=dict(boxstyle="circle,pad=0.15", fc="w", ec=cmap(i % 20), lw=0.8))
    zones = scenario.risk_zones()
    colors = ("tab:green", "tab:blue", "tab:purple", "tab:red", "tab:brown")
    for k, (name, sp) in enumerate(safe_paths.items()):
        col = colors[k % len(colors)]
        _draw_corridor(ax, _core.Corridor(np.asarray(sp, dtype=float), zones), color=col)
        sp = np.asarray(sp)
        ax.plot(sp[:, 0], sp[:, 1], "-", color=col, lw=1.4, label=f"{name} safe path and buffer")
        ax.plot(*sp[0], "o", color=col, ms=6)
    dest = [np.asarray(sp)[-1] for sp in safe_paths.values()]
    if dest:
        ax.plot(*dest[0], "*", color="tab:red", ms=12, label="destination")
    ax.set_xlim(b[0][0], b[1][0])
    ax.set_ylim(b[0][1], b[1][1])
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(loc="upper left", fontsize=7, framealpha=0.85)
    ax.set_title(title or f"{scenario.name}: field, landmark clusters, obstacles, hazards and safe paths", fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


def plot_wrs_comparison(wrs_mean: dict, t, path: str | Path, *, labels: dict | None = None,
                        title: str | None = None) -> Path:
    """[SafeNav-ext Fig. 3]: weighted risk score [SafeNav eq. 18] over time, the mean over
    the trials.  Top row: (a) every method with the EKF, (b) with the PF.
    Bottom row: per method, EKF against PF.  ``wrs_mean`` maps (source,
    filter) to a per-step mean WRS array; ``t`` is the time of each step."""
    plt = pyplot()
    labels = labels or {}
    sources = list(dict.fromkeys(s for s, _ in wrs_mean))
    n = max(len(sources), 2)
    fig = plt.figure(figsize=(3.4 * n, 6.4))
    gs = fig.add_gridspec(2, 2 * n)
    top = [fig.add_subplot(gs[0, :n]), fig.add_subplot(gs[0, n:])]
    cmap = plt.get_cmap("tab10")
    t = np.asarray(t)
    for ax, filt, tag in zip(top, ("ekf", "pf"), ("(a)", "(b)")):
        for i, src in enumerate(sources):
            if (src, filt) in wrs_mean:
                w = np.asarray(wrs_mean[(src, filt)])
                ax.plot(t[: len(w)], w, color=cmap(i), lw=1.1, label=labels.get(src, src))
        ax.set_title(f"{tag} {filt.upper()}: mean WRS per step", fontsize=9)
        ax.set_xlabel("t [s]")
        ax.set_ylabel("WRS")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    for i, src in enumerate(sources):
        ax = fig.add_subplot(gs[1, 2 * i: 2 * i + 2])
        for filt, style in (("ekf", "-"), ("pf", "--")):
            if (src, filt) in wrs_mean:
                w = np.asarray(wrs_mean[(src, filt)])
                ax.plot(t[: len(w)], w, style, color=cmap(i), lw=1.1, label=filt.upper())
        ax.set_title(f"({chr(ord('c') + i)}) {labels.get(src, src)}", fontsize=8)
        ax.set_xlabel("t [s]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


def plot_navigation(scenario, trials: dict, path: str | Path, *, title: str | None = None,
                    show_hulls: bool = True) -> Path:
    """[SafeNav-ext Figs. 4–5] (= [SafeNav-conf Figs. 2–3]): per path type, the field (obstacles, hazards),
    the safe-path corridor with its risk zones, the segment hulls (CHull) or
    sub-segment centroids (Centroid), and the true and estimated trajectories.

    ``trials`` maps a path type name to ``(navigator, trial_result)``.  Writes
    a PNG and an SVG beside it; returns the PNG path."""
    from matplotlib.patches import Polygon as _Polygon

    from .. import _core

    plt = pyplot()
    n = len(trials)
    fig, axes = plt.subplots(1, n, figsize=(5.2 * n, 5.4), squeeze=False)
    world = scenario.world
    for ax, (name, (navigator, trial)) in zip(axes[0], trials.items()):
        _draw_world(ax, world)
        segs = navigator.segments
        corridor = _core.Corridor(navigator.problem.path, navigator.problem.zones)
        W = corridor.half_width
        safe = np.asarray(corridor.path)
        _draw_corridor(ax, corridor)
        if show_hulls and navigator.settings.method == _core.NavigationMethod.CHULL:
            for k in range(segs.size):
                hull = np.asarray(segs.hull(k))
                ax.add_patch(_Polygon(hull, closed=True, fill=False, edgecolor="tab:purple", lw=0.6, alpha=0.6))
        else:
            c = np.asarray(segs.centroids)
            ax.plot(c[:, 0], c[:, 1], "+", color="tab:purple", ms=4, mew=0.8, label="sub-segment centroids")
        lm = world.landmark_array()
        ax.plot(lm[:, 0], lm[:, 1], "^", color="tab:blue", ms=4, label="landmarks")
        ax.plot(safe[:, 0], safe[:, 1], "-", color="tab:green", lw=1.0, label="safe path")
        gt = scenario.path_polyline(name)
        ax.plot(gt[:, 0], gt[:, 1], ":", color="0.4", lw=1.0, label="cluster polyline")
        ax.plot(trial.truth[:, 0], trial.truth[:, 1], "k-", lw=1.4, label="true")
        ax.plot(trial.estimate[:, 0], trial.estimate[:, 1], "--", color="tab:red", lw=1.2, label="estimated")
        ax.plot(*safe[0], "o", color="tab:green", ms=6)
        ax.plot(*safe[-1], "*", color="tab:red", ms=10)
        pad = 2 * W
        lo, hi = safe.min(axis=0) - pad, safe.max(axis=0) + pad
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal")
        m = trial.metrics
        ax.set_title(f"{name}: {trial.outcome_name}, ADE {m['path_ade']:.2f} m, FDE {m['goal_fde']:.2f} m", fontsize=10)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
    axes[0][0].legend(loc="best", fontsize=7)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, path)


def recorded_trials(scenario, safe: dict, sweep, *, paper: bool = False) -> dict:
    """Trial 0 of each method and path type of ``sweep``, recorded (trajectories
    kept), with the sweep's first filter and source (the measurement-level
    LanBLoc stands in for the camera loop) and the sweep's loop (``paper``:
    the papers' loop, as :func:`safenav.runner.run_sweep`): ``{(method, path
    type): (navigator, trial result)}``.  What Figs. 4–5 draw and ``--view`` writes."""
    out = {}
    source = sweep.sources[0] if sweep.sources[0] in nav.SOURCES else "lanbloc"
    for method in sweep.methods:
        for name in sweep.path_types:
            navigator = nav.make_navigator(scenario, safe[name], method=method, filter=sweep.filters[0],
                                           source=source, n_particles=sweep.n_particles, paper=paper)
            seed = runner.trial_seeds(sweep.seed, sweep.path_index(name), 1)[0]
            out[(method, name)] = (navigator, navigator.run(int(seed)))
    return out


def navigation_figures(scenario, safe: dict, sweep, folder: Path, recorded: dict | None = None) -> list:
    """[SafeNav-ext Figs. 4–5] (CHull, Centroid): trial 0 of each path type,
    recorded (:func:`recorded_trials`, or ``recorded`` when given)."""
    figs = []
    recorded = recorded if recorded is not None else recorded_trials(scenario, safe, sweep)
    for method in sweep.methods:
        trials = {name: recorded[(method, name)] for name in sweep.path_types}
        fig_name = {"chull": "fig4_chull", "centroid": "fig5_centroid"}.get(method, f"fig_{method}")
        figs.append(plot_navigation(scenario, trials, Path(folder) / f"{fig_name}.png",
                                    title=f"{METHOD_LABELS.get(method, method)} with RAw-RRT*, "
                                          f"LanBLoc-BMM({sweep.filters[0].upper()}): trial 0"))
    return figs
