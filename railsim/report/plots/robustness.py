"""Robustness figures a planner reads (``railsim robustness``, ``railsim study vc-vs-mb --disturbances``).

All three take one or more aggregated studies (:func:`railsim.studies.robustness.aggregate`, one per regime) and
overlay them:

* **delay CDF** — the share of arrivals at most *x* late, one line per regime and headway (mean over the runs);
* **stability curve** — knock-on delay [min] and the excess propagation factor (knock-on ÷ primary minutes) vs
  headway (or vs disturbance intensity when no headway was varied), with 95 % intervals; the dashed line at 1
  separates recovering (below) from propagating (above);
* **punctuality per station** — the share of arrivals ≤ 3 min late at each station along the line.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

DPI = 130


def _label(regime: str, g: Mapping[str, Any], many: bool) -> str:
    parts = [regime] if many else []
    if g.get("headway_s") is not None:
        parts.append(f"{g['headway_s']:g} s")
    if g.get("intensity", 1.0) != 1.0:
        parts.append(f"×{g['intensity']:g}")
    return ", ".join(parts) or regime


def _save(fig: Any, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


def delay_cdf(results: Mapping[str, Mapping[str, Any]], path: Path) -> Path:
    fig, ax = plt.subplots(figsize=(7, 4.5))
    many = len(results) > 1
    for regime, res in results.items():
        for g in res["groups"]:
            pts = sorted((int(t), v) for t, v in g["cdf"].items() if v is not None)
            if pts:
                ax.plot([t / 60.0 for t, _ in pts], [v for _, v in pts], marker=".", label=_label(regime, g, many))
    for m in (1, 3, 5):
        ax.axvline(m, color="0.8", lw=0.8, zorder=0)
    ax.set_xlabel("arrival delay [min]")
    ax.set_ylabel("share of arrivals at most this late")
    ax.set_ylim(0, 1.01)
    ax.set_title("Delay CDF (mean over Monte-Carlo runs)")
    ax.legend(fontsize=7)
    return _save(fig, path)


def stability_curve(results: Mapping[str, Mapping[str, Any]], path: Path) -> Path:
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4.2))
    x_key = "headway_s"
    for res in results.values():
        if all(g.get("headway_s") is None for g in res["groups"]):
            x_key = "intensity"
    for regime, res in results.items():
        gs = [g for g in res["groups"] if g.get(x_key) is not None]
        xs = [g[x_key] for g in gs]
        for ax, kpi in ((ax1, "knock_on_min"), (ax2, "excess_propagation_factor")):
            means = [g["kpis"][kpi]["mean"] for g in gs]
            errs = [g["kpis"][kpi]["ci95"] or 0.0 for g in gs]
            pts = [(x, m, e) for x, m, e in zip(xs, means, errs) if m is not None]
            if pts:
                ax.errorbar(
                    [p[0] for p in pts],
                    [p[1] for p in pts],
                    yerr=[p[2] for p in pts],
                    marker="o",
                    capsize=3,
                    label=regime,
                )
    ax2.axhline(1.0, color="k", ls="--", lw=0.8)
    xlabel = "headway [s]" if x_key == "headway_s" else "disturbance intensity"
    ax1.set(xlabel=xlabel, ylabel="knock-on delay at destinations [min/run]", title="Knock-on delay")
    ax2.set(xlabel=xlabel, ylabel="knock-on ÷ primary minutes", title="Excess propagation factor (1 = break-even)")
    for ax in (ax1, ax2):
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
    return _save(fig, path)


def punctuality_by_station(results: Mapping[str, Mapping[str, Any]], path: Path) -> Path:
    fig, ax = plt.subplots(figsize=(11, 4.5))
    many = len(results) > 1
    order: list[str] = []
    for res in results.values():
        for g in res["groups"]:
            order += [s for s in g["by_station"] if s not in order]
    for regime, res in results.items():
        for g in res["groups"]:
            ys = [g["by_station"].get(s) for s in order]
            ax.plot(
                range(len(order)),
                [y if y is not None else float("nan") for y in ys],
                marker=".",
                label=_label(regime, g, many),
            )
    ax.set_xticks(range(len(order)))
    ax.set_xticklabels(order, rotation=80, fontsize=6)
    ax.set_ylabel("arrivals ≤ 3 min late")
    ax.set_ylim(0, 1.01)
    ax.set_title("Punctuality per station along the line (mean over runs)")
    ax.legend(fontsize=7)
    return _save(fig, path)


def robustness_figures(results: Mapping[str, Mapping[str, Any]] | Mapping[str, Any], out_dir: Path) -> list[Path]:
    """The three figures as PNG files in ``out_dir``; ``results`` is one study or ``{regime: study}``."""
    if "groups" in results:  # one study
        results = {str(results.get("label") or "run"): results}
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    return [
        delay_cdf(results, out_dir / "robustness_delay_cdf.png"),
        stability_curve(results, out_dir / "robustness_stability.png"),
        punctuality_by_station(results, out_dir / "robustness_by_station.png"),
    ]
