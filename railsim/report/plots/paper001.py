"""Paper B figures: force, force rate, speed error and displacement error of carriage 1 (Fig. 5/7 panels).

Plotting is I/O, so it lives here; the closed-loop runs themselves are pure (:mod:`controllers.ato_mpc.sim`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from controllers.ato_mpc.sim import RunResult
from railsim.physics.multipoint import MultipointParams


def plot_runs(runs: list[RunResult], path: Path, p: MultipointParams = MultipointParams()) -> Path:
    """Force, force rate, speed error and displacement error of carriage 1 (the paper's Fig. 5/7 panels)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = p.n_cars
    fig, axes = plt.subplots(5, 1, figsize=(10, 13), sharex=True)
    for r in runs:
        t = r.t_s
        u = r.forces_n[:, 0]
        rate = np.diff(np.concatenate([[0.0], u])) / r.period_s
        axes[0].plot(t, r.rel[:, n], label=f"{r.controller} v1")
        axes[1].plot(t, u / 1e3, label=r.controller)
        axes[2].plot(t, rate / 1e3, label=r.controller, lw=0.8)
        axes[3].plot(t, r.v_ref_mps - r.rel[:, n], label=r.controller)
        axes[4].plot(t, r.x_ref_m - r.rel[:, 0], label=r.controller)
    if runs:
        axes[0].plot(runs[0].t_s, runs[0].v_ref_mps, "k--", lw=0.8, label="reference (time)")
        axes[0].plot(runs[0].t_s, runs[0].v_max_mps, "k:", lw=0.8, label="v_max")
    for lim in (p.force_max_n, p.force_min_n):
        axes[1].axhline(lim / 1e3, color="r", ls=":", lw=0.8)
    for lim in (p.force_rate_max_n_per_s, p.force_rate_min_n_per_s):
        axes[2].axhline(lim / 1e3, color="r", ls=":", lw=0.8)
    labels = [
        "speed carriage 1 [m/s]",
        "force u_1 [kN]",
        "force rate du_1/T [kN/s]",
        "speed error [m/s]",
        "displacement error [m]",
    ]
    for ax, lab in zip(axes, labels):
        ax.set_ylabel(lab)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=7)
    axes[-1].set_xlabel("time [s]")
    title = f"Paper B scenario {runs[0].scenario}, T = {runs[0].period_s} s" if runs else ""
    fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
