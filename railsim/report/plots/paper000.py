"""Figures of Paper A (spec 000 §7 "Plots") from railsim output folders.

* :func:`figure_run` — one run (Fig. 3, 4, 8, 13 style): speeds of all units, ``Δv_i = v_{i−1} − v_i`` and
  ``ΔS_i − D^(e)_i`` per follower, the late-phase start (A7, 300 s) marked;
* :func:`figure_comparison` — several runs of the same initial conditions (Fig. 10 / Fig. 14 style): one row per
  follower, columns ``Δv_i`` and ``ΔS_i − D^(e)_i``, one line per run label (e.g. MCF-DMPC, OPO-MCF-DMPC, DMPC),
  optionally zoomed (y-range ±3× the late-phase extreme, transient clipped) so that steady-state differences of
  a few metres are visible next to kilometre-scale transients; the full range is in the per-run figure.

Everything is read through :func:`railsim.analysis.paper000.follower_series` (paper time, front-to-front ΔS, D^(e) of
Eq. 5), so the figures and the metric tables agree by construction. Agg backend; PNG files only when asked.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from railsim.analysis.paper000 import FollowerSeries, follower_series  # noqa: E402

__all__ = ["figure_comparison", "figure_run", "write_figures"]

LATE_START_S = 300.0
KMH_PER_MPS = 3.6


def figure_run(out_dir: Path | str, title: str = "", late_start_s: float | None = LATE_START_S) -> Figure:
    """Speeds and per-follower tracking errors of one run."""
    series = follower_series(out_dir)
    has_j = any(fs.objective is not None and np.isfinite(fs.objective).any() for fs in series)
    fig, axes = plt.subplots(4 if has_j else 3, 1, figsize=(9, 12 if has_j else 9), sharex=True)
    ax_v, ax_dv, ax_e = axes[:3]
    if has_j:  # the MPC objective J_i(t) (Paper A Fig. 5/10)
        for fs in series:
            if fs.objective is not None:
                axes[3].plot(fs.t_s, fs.objective, lw=1.0, label=fs.follower)
        axes[3].set_ylabel(r"objective $J_i$")
        axes[3].set_yscale("symlog")
    first = series[0]
    ax_v.plot(first.t_s, first.v_lead_mps * KMH_PER_MPS, lw=1.4, label=f"{first.leader} (leader)")
    for fs in series:
        ax_v.plot(fs.t_s, fs.v_fol_mps * KMH_PER_MPS, lw=1.2, label=f"{fs.follower} ({fs.controller})")
        ax_dv.plot(fs.t_s, fs.v_lead_mps - fs.v_fol_mps, lw=1.0, label=fs.follower)
        ax_e.plot(fs.t_s, fs.spacing_m - fs.desired_m, lw=1.0, label=fs.follower)
    ax_v.set_ylabel("speed [km/h]")
    ax_dv.set_ylabel(r"$\Delta v_i = v_{i-1} - v_i$ [m/s]")
    ax_e.set_ylabel(r"$\Delta S_i - D^{(e)}_i$ [m]")
    axes[-1].set_xlabel("time t [s]")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="best")
        if late_start_s is not None and first.t_s[-1] > late_start_s:
            ax.axvline(late_start_s, color="0.5", ls=":", lw=1.0)
    ax_e.axhline(0.0, color="k", lw=0.6)
    fig.suptitle(title or Path(out_dir).name)
    fig.tight_layout()
    return fig


def _late_limits(values: list[np.ndarray], t: list[np.ndarray], late_start_s: float) -> tuple[float, float] | None:
    late = [v[tt >= late_start_s] for v, tt in zip(values, t) if np.any(tt >= late_start_s)]
    if not late:
        return None
    hi = max(float(np.max(np.abs(v))) for v in late if v.size)
    return -3.0 * hi, 3.0 * hi


def figure_comparison(
    out_dirs: Mapping[str, Path | str], title: str = "", zoom: bool = True, late_start_s: float | None = LATE_START_S
) -> Figure:
    """Per follower: Δv and ΔS − D^(e) of every run in ``out_dirs`` (label → folder), on common axes; the zoom
    uses the late phase from ``late_start_s`` (None: the second half of the run)."""
    runs: dict[str, list[FollowerSeries]] = {label: follower_series(d) for label, d in out_dirs.items()}
    n_fol = max(len(s) for s in runs.values())
    fig, axes = plt.subplots(n_fol, 2, figsize=(12, 3.6 * n_fol), squeeze=False, sharex=True)
    for i in range(n_fol):
        ax_dv, ax_e = axes[i]
        dvs, errs, ts = [], [], []
        for label, series in runs.items():
            if i >= len(series):
                continue
            fs = series[i]
            dv, err = fs.v_lead_mps - fs.v_fol_mps, fs.spacing_m - fs.desired_m
            ax_dv.plot(fs.t_s, dv, lw=1.0, label=label)
            ax_e.plot(fs.t_s, err, lw=1.0, label=label)
            dvs.append(dv)
            errs.append(err)
            ts.append(fs.t_s)
        name = next(s[i].follower for s in runs.values() if i < len(s))
        ax_dv.set_ylabel(f"{name}: " + r"$\Delta v$ [m/s]")
        ax_e.set_ylabel(f"{name}: " + r"$\Delta S - D^{(e)}$ [m]")
        if zoom and ts:
            start = late_start_s if late_start_s is not None else 0.5 * float(ts[0][-1])
            for ax, vals in ((ax_dv, dvs), (ax_e, errs)):
                lim = _late_limits(vals, ts, start)
                if lim is not None and lim[1] > 0.0:
                    ax.set_ylim(*lim)
                    ax.set_title("zoom: ±3× the late-phase extreme (transient clipped)", fontsize=8)
        for ax in (ax_dv, ax_e):
            ax.grid(alpha=0.3)
            ax.axhline(0.0, color="k", lw=0.6)
            ax.legend(fontsize=8)
            if late_start_s is not None and ts and ts[0][-1] > late_start_s:
                ax.axvline(late_start_s, color="0.5", ls=":", lw=1.0)
    for ax in axes[-1]:
        ax.set_xlabel("time t [s]")
    fig.suptitle(title or "comparison")
    fig.tight_layout()
    return fig


def write_figures(
    out_dirs: Mapping[str, Path | str], dest: Path | str, late_start_s: float | None = LATE_START_S
) -> list[Path]:
    """One ``<label>.png`` per run, plus ``comparison.png`` (full range) and ``comparison_zoom.png`` when more
    than one run is given. ``late_start_s``: the A7 late-phase marker (None for S-E). Returns the files."""
    dest = Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    for label, d in out_dirs.items():
        fig = figure_run(d, title=label, late_start_s=late_start_s)
        path = dest / f"{_safe(label)}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)
    if len(out_dirs) > 1:
        for zoom, stem in ((False, "comparison"), (True, "comparison_zoom")):
            fig = figure_comparison(
                out_dirs,
                title="comparison" + (" (late-phase zoom)" if zoom else ""),
                zoom=zoom,
                late_start_s=late_start_s,
            )
            path = dest / f"{stem}.png"
            fig.savefig(path, dpi=110)
            plt.close(fig)
            written.append(path)
    return written


def _safe(label: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in label)
