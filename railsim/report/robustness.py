"""The robustness section of a run report (a run with ``disturbances:``): punctuality, delay split, figures.

Reads the ``robustness`` and ``disturbances`` blocks of ``summary.json`` (:mod:`railsim.analysis.punctuality`,
:mod:`railsim.engine.primary_delays`) and draws the run's delay CDF and punctuality per station with the same
figure code as the Monte-Carlo study (:mod:`railsim.report.plots.robustness`), the run being one "group".
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any


def _as_group(rob: Mapping[str, Any]) -> dict[str, Any]:
    return {
        "headway_s": None,
        "intensity": 1.0,
        "cdf": {int(k[3:7]): v for k, v in (rob.get("cdf") or {}).items()},
        "by_station": {
            s: (rob.get("by_station") or {})[s]
            for s in str(rob.get("station_order") or "").split(",")
            if s in (rob.get("by_station") or {})
        },
    }


def run_section(summary: Mapping[str, Any], run: Path, fig_dir: Path) -> list[str]:
    """Markdown blocks: the KPI table, what was injected, and two figures (links relative to ``run``)."""
    from railsim.report.plots.robustness import delay_cdf, punctuality_by_station

    rob = summary.get("robustness")
    if not rob:
        return []
    inj = summary.get("disturbances") or {}

    def pct(key: str) -> str:
        v = rob.get(key)
        return "–" if v is None else f"{100 * v:.1f} %"

    def num(v: Any, fmt: str = ".1f") -> str:
        return "–" if v is None else format(v, fmt)

    rows = [
        ("arrivals", str(rob.get("n_arrivals"))),
        ("within 1 / 3 / 5 min", f"{pct('within_1min')} / {pct('within_3min')} / {pct('within_5min')}"),
        ("mean / p95 arrival delay [s]", f"{num(rob.get('mean_delay_s'))} / {num(rob.get('p95_delay_s'))}"),
        (
            "primary / secondary delay at destinations [min]",
            f"{num(rob.get('primary_min'))} / {num(rob.get('secondary_min'))}",
        ),
        ("propagation factor (secondary ÷ primary)", num(rob.get("propagation_factor"), ".2f")),
        ("recovery after incidents [s]", ", ".join(f"{x:.0f}" for x in rob.get("recovery_s") or []) or "–"),
        (
            "injected: late starts / dwell / incidents [s]",
            f"{num(inj.get('injected_departure_s'), '.0f')} / {num(inj.get('injected_dwell_s'), '.0f')} / "
            f"{num(inj.get('injected_incident_s'), '.0f')}",
        ),
        ("trips slowed (performance factor < 1)", str(inj.get("trips_slowed", "–"))),
    ]
    if "injected_demand_s" in inj:  # passenger demand (disturbances.demand): decided during the run
        rows.append(
            (
                "passenger demand: extra dwell [s] / extra passengers",
                f"{num(inj['injected_demand_s'], '.0f')} / {num(inj.get('extra_passengers'), '.0f')}",
            )
        )
    table = ["| KPI | value |", "|---|---:|"] + [f"| {k} | {v} |" for k, v in rows]
    fig_dir.mkdir(parents=True, exist_ok=True)
    one = {"run": {"groups": [_as_group(rob)]}}
    cdf = delay_cdf(one, fig_dir / "delay_cdf.png")
    by_station = punctuality_by_station(one, fig_dir / "punctuality_by_station.png")
    return [
        "## Robustness (primary and knock-on delay)",
        "Delay against the free-run plan, split into primary (this train's own injected disturbances) and "
        "secondary (knock-on from other trains); `delays.csv` has it per trip and stop.",
        "\n".join(table),
        f"![delay CDF]({cdf.relative_to(run).as_posix()})\n\n*Share of arrivals at most x late.*",
        f"![punctuality per station]({by_station.relative_to(run).as_posix()})\n\n*Arrivals ≤ 3 min late per station.*",
    ]
