"""VC vs moving block, disturbed: the robustness half of ``railsim study vc-vs-mb --disturbances FILE``.

The capacity study (:mod:`railsim.studies.vc_vs_mb`) says how many trains per hour each regime carries; this
says at what punctuality. Both regimes' scenarios run the same Monte-Carlo plan
(:mod:`railsim.studies.robustness`): the same disturbances file, the same headways (the searched services'
``headway_s``, moved together) and the **same seeds** — common random numbers: every trip's primary delays depend
only on the seed and the trip id, so the two regimes see the same dwell extensions, late starts, slow drivers and
incidents (one exception, by construction: a VC follower that couples on departure leaves with its leader and
gets no late start of its own). Differences between the regimes are then differences in how the line absorbs
the same disturbances, and their confidence intervals are narrower than with independent draws.

Writes ``DIR/robustness/{mb,vc}/`` (each a robustness study), ``DIR/robustness/vc_vs_mb_robustness.md`` and the
overlaid figures, and returns the Markdown section the study report appends.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from railsim.record import output
from railsim.studies.robustness import RobustnessPlan, check_plan, ci95, markdown, run_robustness
from railsim.studies.vc_vs_mb import headway_paths

REGIMES = (("mb", "(a) moving block"), ("vc", "(b) virtual coupling"))


def regime_plans(
    mb_scenario: Path,
    vc_scenario: Path,
    disturbances: Mapping[str, Any],
    headways_s: Sequence[float],
    services: Sequence[str],
    runs: int,
    first_seed: int = 1,
    baseline_runs: int = 1,
    intensities: Sequence[float] = (),
    disturbances_source: Path | None = None,
) -> dict[str, RobustnessPlan]:
    """The robustness plan of each regime (``mb``, ``vc``): same disturbances, headways and seeds."""
    plans = {}
    for key, label in REGIMES:
        scn = Path(mb_scenario if key == "mb" else vc_scenario)
        plans[key] = RobustnessPlan(
            scenario=scn,
            runs=runs,
            first_seed=first_seed,
            headway_paths=tuple(headway_paths(scn, services)),
            headways_s=tuple(headways_s),
            intensities=tuple(intensities),
            disturbances=disturbances,
            disturbances_source=disturbances_source,
            baseline_runs=baseline_runs,
            label=label,
        )
    return plans


def compare_robustness(
    out_dir: str | Path,
    mb_scenario: Path,
    vc_scenario: Path,
    disturbances: Mapping[str, Any],
    headways_s: Sequence[float],
    services: Sequence[str],
    runs: int,
    first_seed: int = 1,
    baseline_runs: int = 1,
    intensities: Sequence[float] = (),
    workers: int | None = None,
    dask_address: str | None = None,
    progress: bool | None = None,
) -> str:
    """Run both regimes (module docstring); return the report section (Markdown)."""
    from railsim.report.plots.robustness import robustness_figures

    out = Path(out_dir) / "robustness"
    plans = regime_plans(
        mb_scenario, vc_scenario, disturbances, headways_s, services, runs, first_seed, baseline_runs, intensities
    )
    for plan in plans.values():  # both regimes checked before either runs
        check_plan(plan)
    results: dict[str, Any] = {}
    for key, label in REGIMES:
        plan = plans[key]
        results[label] = run_robustness(plan, out / key, workers=workers, dask_address=dask_address, progress=progress)
    plots = robustness_figures(results, out)
    lines = ["## Robustness under primary delays (same seeds in both regimes)", ""]
    lines.append(
        f"Disturbances as given (`--disturbances`); {runs} runs per regime and headway, seeds "
        f"{first_seed}–{first_seed + runs - 1} in both regimes (common random numbers)."
    )
    for label, res in results.items():
        lim = res.get("stability_limit_s")
        lines.append(f"- {label}: stability limit {f'{lim:g} s' if lim is not None else 'none among the probes'}")
    lines.append("")
    lines += paired_markdown(results)
    for res in results.values():
        lines.append(markdown({**res, "plots": []}).replace("## ", "### ", 1))
    for p in plots:
        lines.append(f"![{p.stem}](robustness/{p.name})")
    text = "\n".join(lines) + "\n"
    (out / "vc_vs_mb_robustness.md").write_text(text.replace("](robustness/", "]("), encoding="utf-8")
    output.write_json(out / "vc_vs_mb_robustness.json", results)
    return text


def paired_differences(mb: Mapping[str, Any], vc: Mapping[str, Any]) -> list[dict[str, Any]]:
    """Per headway (and intensity): VC − moving block on the same seeds — the paired comparison common random
    numbers make sharp. For each KPI of :data:`railsim.studies.robustness.PAIRED_KPIS`: the mean difference
    with its 95 % interval over the seeds both regimes finished, and on how many seeds VC is higher."""
    out = []
    vc_groups = {(g["headway_s"], g["intensity"]): g for g in vc.get("groups", [])}
    for g_mb in mb.get("groups", []):
        g_vc = vc_groups.get((g_mb["headway_s"], g_mb["intensity"]))
        if g_vc is None:
            continue
        seeds = sorted(set(g_mb.get("per_seed", {})) & set(g_vc.get("per_seed", {})), key=int)
        kpis = {}
        for k in g_mb.get("per_seed", {}).get(seeds[0], {}) if seeds else {}:
            pairs = [(g_mb["per_seed"][s][k], g_vc["per_seed"][s][k]) for s in seeds]
            diffs = [b - a for a, b in pairs if a is not None and b is not None]
            kpis[k] = {**ci95(diffs), "vc_higher": sum(1 for d in diffs if d > 0)}
        out.append({"headway_s": g_mb["headway_s"], "intensity": g_mb["intensity"], "n_pairs": len(seeds), **kpis})
    return out


def paired_markdown(results: Mapping[str, Any]) -> list[str]:
    """The paired table (:func:`paired_differences`) as Markdown lines."""
    mb, vc = (results.get(label, {}) for _, label in REGIMES)
    rows = paired_differences(mb, vc)
    if not rows:
        return []
    cols: tuple[tuple[str, str], ...] = (
        ("knock_on_min", "knock-on [min]"),
        ("robustness.mean_delay_s", "mean delay [s]"),
    )
    cols += (("robustness.within_3min", "≤ 3 min [share]"), ("excess_propagation_factor", "excess prop. factor"))
    lines = [
        "Paired on the same seeds (VC − moving block; mean ± 95 % half-width, and on how many seeds VC is higher):",
        "",
        "| headway [s] | intensity | pairs | " + " | ".join(c for _, c in cols) + " |",
        "|---:|---:|---:|" + "---:|" * len(cols),
    ]
    for r in rows:
        cells = []
        for k, _ in cols:
            st = r.get(k) or {}
            if st.get("mean") is None:
                cells.append("–")
                continue
            half = f" ± {st['ci95']:.3g}" if st.get("ci95") is not None else ""
            cells.append(f"{st['mean']:.3g}{half} ({st['vc_higher']}/{st['n']})")
        lines.append(f"| {r['headway_s']:g} | {r['intensity']:g} | {r['n_pairs']} | " + " | ".join(cells) + " |")
    return lines + [""]
