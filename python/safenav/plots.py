"""Figures.  Plots live beside the metrics, not inside them (evo's habit)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_synthetic_trial(data, estimates: dict, path: str | Path, *, title: str | None = None) -> Path:
    """One synthetic trial: truth, LanBLoc fixes and filter estimates, plus position error over time.

    ``estimates`` maps a label ("EKF", "PF", …) to a :class:`~safenav.filters.FilterResult`.
    Writes a PNG (and an SVG beside it) and returns the PNG path."""
    plt = _pyplot()
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
    ax.set_title(title or "Synthetic trajectory (SafeNav V-A), LanBLoc-BMM")
    ax_err.set_xlabel("t [s]")
    ax_err.set_ylabel("position error [cm]")
    ax_err.set_yscale("log")
    ax_err.legend(fontsize=8)
    ax_err.grid(alpha=0.3)
    fig.tight_layout()
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=130)
    fig.savefig(out.with_suffix(".svg"))
    plt.close(fig)
    return out
