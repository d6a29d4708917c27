"""Reproductions of Paper C's Fig. 3–6 from a :class:`~controllers.distributed.reference.SimulationLog`.

* Fig. 3 — positions ``x_i(k)``;
* Fig. 4 — position differences ``x_ij(k)`` per edge, each in its own panel with ``d_ij`` (dashed) and the band
  ``[γ̲_ij, γ̄_ij]`` (shaded, edges drawn);
* Fig. 5 — speeds ``v_i(k)`` with ``v_r`` and ``[ρ̲, ρ̄]``;
* Fig. 6 — inputs ``u_i(k)`` with ``[μ̲, μ̄]``.

A train (an edge) is drawn only while it is present (active): the log holds NaN elsewhere, which matplotlib
leaves blank. Bounds that differ between trains are drawn per train. Uses the non-interactive Agg backend and
writes PNGs only when asked (:func:`write_figures`); the ``figure_*`` functions return figures for notebooks.
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from controllers.distributed.reference import SimulationLog  # noqa: E402


def _time_s(log: SimulationLog) -> np.ndarray:
    return log.k * log.scenario.sample_time_s


def _per_train(ax, log: SimulationLog, values: np.ndarray, ylabel: str) -> None:
    t = _time_s(log)
    for n, i in enumerate(log.train_ids):
        ax.plot(t, values[:, n], lw=1.3, label=f"train {i}")
    ax.set_xlabel("time kT [s]")
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)


def _bounds(ax, log: SimulationLog, lo_name: str, hi_name: str, label: str) -> None:
    """Horizontal bound lines; one pair when all trains share them, else one pair per train (dotted)."""
    lo, hi = log.param_array(lo_name), log.param_array(hi_name)
    if np.all(lo == lo[0]) and np.all(hi == hi[0]):
        ax.axhline(lo[0], color="red", ls="--", lw=1.2, label=f"{label} bounds")
        ax.axhline(hi[0], color="red", ls="--", lw=1.2)
    else:
        for n, _i in enumerate(log.train_ids):
            ax.axhline(lo[n], color=f"C{n}", ls=":", lw=1.0)
            ax.axhline(hi[n], color=f"C{n}", ls=":", lw=1.0)


def figure_positions(log: SimulationLog) -> Figure:
    """Fig. 3: ``x_i(k)``."""
    fig, ax = plt.subplots(figsize=(8, 4.5), constrained_layout=True)
    _per_train(ax, log, log.x_m / 1000.0, "position x_i [km]")
    ax.set_title(f"Fig. 3 — positions ({log.scenario.name})")
    ax.legend(fontsize=8)
    return fig


def figure_position_differences(log: SimulationLog) -> Figure:
    """Fig. 4: one panel per edge with ``x_ij``, ``d_ij`` and the ``γ`` band (only while the edge is active)."""
    n_ed = len(log.edge_ids)
    cols = 2 if n_ed > 1 else 1
    rows = max(1, math.ceil(n_ed / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(6.5 * cols, 2.6 * rows), constrained_layout=True, squeeze=False)
    t = _time_s(log)
    for n, (i, j) in enumerate(log.edge_ids):
        ax = axes[n // cols][n % cols]
        lo, hi, d = log.edge_gamma_lo_m[:, n], log.edge_gamma_hi_m[:, n], log.edge_d_m[:, n]
        active = log.edge_active[:, n]
        ax.fill_between(t, lo, hi, where=active, color="tab:green", alpha=0.15, step="mid", label="[γ̲, γ̄]")
        ax.plot(t, lo, color="tab:red", lw=1.0, ls="--")
        ax.plot(t, hi, color="tab:red", lw=1.0, ls="--", label="γ̲, γ̄")
        ax.plot(t, d, color="black", lw=1.0, ls=":", label="d_ij")
        ax.plot(t, log.x_rel_m[:, n], color="tab:blue", lw=1.5, label=f"x_{i},{j}")
        ax.set_title(f"edge {i}-{j}", fontsize=9)
        ax.set_ylabel("x_i − x_j [m]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    for n in range(n_ed, rows * cols):
        axes[n // cols][n % cols].set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel("time kT [s]")
    fig.suptitle(f"Fig. 4 — position differences with d_ij and γ bounds ({log.scenario.name})")
    return fig


def figure_speeds(log: SimulationLog) -> Figure:
    """Fig. 5: ``v_i(k)`` with ``v_r`` and ``[ρ̲, ρ̄]``."""
    fig, ax = plt.subplots(figsize=(8, 4.5), constrained_layout=True)
    _per_train(ax, log, log.v_mps, "speed v_i [m/s]")
    ax.axhline(log.scenario.v_ref_mps, color="black", ls=":", lw=1.2, label="v_r")
    _bounds(ax, log, "speed_min_mps", "speed_max_mps", "ρ")
    lo, hi = log.param_array("speed_min_mps").min(), log.param_array("speed_max_mps").max()
    pad = 0.08 * (hi - lo)
    ax.set_ylim(lo - pad, hi + pad)
    ax.set_title(f"Fig. 5 — speeds ({log.scenario.name})")
    ax.legend(fontsize=8, ncol=2)
    return fig


def figure_inputs(log: SimulationLog) -> Figure:
    """Fig. 6: ``u_i(k)`` with ``[μ̲, μ̄]``."""
    fig, ax = plt.subplots(figsize=(8, 4.5), constrained_layout=True)
    _per_train(ax, log, log.u_mps2, "input u_i [m/s²]")
    _bounds(ax, log, "input_min_mps2", "input_max_mps2", "μ")
    ax.set_title(f"Fig. 6 — inputs ({log.scenario.name})")
    ax.legend(fontsize=8, ncol=2)
    return fig


FIGURES = {
    "fig3_positions": figure_positions,
    "fig4_position_differences": figure_position_differences,
    "fig5_speeds": figure_speeds,
    "fig6_inputs": figure_inputs,
}


def write_figures(log: SimulationLog, folder: str | Path, dpi: int = 110) -> list[Path]:
    """Write Fig. 3–6 as ``<folder>/<name>.png`` (folder created) and return the paths."""
    out_dir = Path(folder)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, make in FIGURES.items():
        fig = make(log)
        path = out_dir / f"{name}.png"
        fig.savefig(path, dpi=dpi)
        plt.close(fig)
        paths.append(path)
    return paths
