"""The report of ``railsim study vc-vs-mb``: ``vc_vs_mb.md`` and ``vc_vs_mb.json`` from the regimes' results.

:func:`write_report` lays out what :mod:`railsim.studies.vc_vs_mb` measured, in the order a planner reads it: the
answer per regime with the binding constraint of its first infeasible probe, the VC gain, the control experiment's
verdict ((c) against (a)), the conditions behind every number, the analytic floors beside the simulated minima
(:mod:`railsim.studies.floor`), the sensitivity block if any, the side-by-side metrics at each answer, then per
regime the probe table, the time-distance graphs and the capacity report. The results are
:class:`railsim.studies.vc_vs_mb.RegimeResult` objects (typed ``Any`` here: this module is imported by that one).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from railsim.record import output

RegimeResult = Any  # railsim.studies.vc_vs_mb.RegimeResult


def _fmt(v: Any) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "–"
    if isinstance(v, float):
        return f"{v:,.3f}" if abs(v) < 10 else f"{v:,.1f}"
    return str(v)


ROWS = [
    ("minimum feasible headway [s]", "headway_s"),
    ("trains (units) run", "trains"),
    ("collisions", "collisions"),
    ("stops missed", "stops_missed"),
    ("up: trains/h, busiest section", "up.trains_per_h"),
    ("up: paths/h", "up.paths_per_h"),
    ("up: passengers/h", "up.pax_per_h"),
    ("up: busiest section", "up.busiest_section"),
    ("up: max UIC 406 occupancy", "up.max_occupancy"),
    ("up: at section", "up.max_occupancy_section"),
    ("down: trains/h, busiest section", "down.trains_per_h"),
    ("down: paths/h", "down.paths_per_h"),
    ("down: passengers/h", "down.pax_per_h"),
    ("down: max UIC 406 occupancy", "down.max_occupancy"),
    ("down: at section", "down.max_occupancy_section"),
    ("arrival delay max / mean [s]", "delay"),
    ("traction energy, all trips [kWh]", "energy_kwh_total"),
    ("smallest true gap, whole run [m]", "min_gap_m"),
    ("median of per-trip smallest gap [m]", "trip_min_gap_p50_m"),
    ("formations coupled", "formations_coupled"),
    ("coupled gap error p95, worst formation [m]", "coupled_gap_error_p95_m"),
]


def _conditions_md(cols: list[RegimeResult]) -> list[str]:
    """The conditions table: one row per condition, one column per regime."""

    def comm(c: dict[str, Any], ch: str) -> str:
        x = c["comm"].get(ch)
        return f"{x['delay']}, loss {x['loss_prob']:g}" if x else "–"

    rows = [
        (
            "offered trains/h per service at the answer",
            lambda c: ", ".join(f"{k} {v:.1f}" for k, v in c["offered_trains_per_h"].items()) or "–",
        ),
        (
            "offered trains/h per direction",
            lambda c: ", ".join(f"{k} {v:.1f}" for k, v in c["offered_trains_per_h_by_direction"].items()) or "–",
        ),
        (
            "branch units (relative departures)",
            lambda c: "; ".join(f"{k}: {v}" for k, v in c["relative_departures"].items()) or "–",
        ),
        (
            "dwell [s]",
            lambda c: (
                f"{c['dwell_default_s']:g} ("
                + ", ".join(f"{k} {v:g}" for k, v in c["dwell_by_station_s"].items())
                + ")"
                if c["dwell_by_station_s"]
                else f"{c['dwell_default_s']:g}"
            ),
        ),
        ("feasible: arrival delay threshold", lambda c: f"{c['delay_stat']} ≤ {c['max_delay_s']:g} s"),
        ("comm t2t (train to train)", lambda c: comm(c, "t2t")),
        ("comm t2g (train to ground)", lambda c: comm(c, "t2g")),
        (
            "formations coupling / target gap at standstill",
            lambda c: f"{c['formations']} / " + (", ".join(f"{g:g} m" for g in c["target_gap_m"]) or "–"),
        ),
        ("step / seed", lambda c: f"{c['step_s']:g} s / {c['seed']}"),
    ]
    lines = ["| condition | " + " | ".join(r.regime.label for r in cols) + " |", "|---|" + "---|" * len(cols)]
    for label, fn in rows:
        lines.append(f"| {label} | " + " | ".join(fn(r.conditions) if r.conditions else "–" for r in cols) + " |")
    return lines


def _floor_md(cols: list[RegimeResult]) -> list[str]:
    """Analytic floors beside the simulated minima, and the critical station per searched service."""
    lines = [
        "| | simulated minimum [s] | cycle floor [s] | strict floor [s] | simulated / cycle floor | floor set by |",
        "|---|---:|---:|---:|---:|---|",
    ]
    for r in cols:
        f = r.floor
        if f is None:
            continue
        p, st = f.binding("cycle")
        ratio = r.headway_s / f.cycle_s if r.headway_s is not None else math.nan
        where = f"{p.reference} at {st.station}" + (f" with {st.dependent}" if st.dependent else "")
        lines.append(
            f"| {r.regime.label} | {_fmt(r.headway_s)} | {f.cycle_s:.1f} | {f.strict_s:.1f} | {_fmt(ratio)} | {where} |"
        )
    lines += [
        "",
        "Per searched service (the critical station of each):",
        "",
        "| regime | service | station | line km/h | dwell s | H(unit) s | H(formation) s | dependent | cycle floor s | strict floor s |",
        "|---|---|---|---:|---:|---:|---:|---|---:|---:|",
    ]
    for r in cols:
        if r.floor is None:
            continue
        for p in r.floor.patterns:
            st = p.critical
            lines.append(
                f"| {r.regime.label} | {p.reference} | {st.station} | {st.line_kmh:.0f} | {st.dwell_s:g} | {st.path_s:.1f} | "
                f"{_fmt(st.formation_s)} | {st.dependent or '–'} | {st.cycle_s:.1f} | {p.critical_strict.strict_s:.1f} |"
            )
    a: dict[str, Any] = next((r.floor.assumptions for r in cols if r.floor is not None), {})
    if a:
        first = next(iter(a.values()))
        lines += [
            "",
            f"Floor inputs: separation dead time T = {first['dead_time_s']:.2f} s (reaction + t2g age + step + "
            f"actuator lag + half the jerk ramp), margin {first['margin_m']:g} m, formation lag "
            f"{first['formation_lag_s']:.2f} s; line speed = the route's limit at each platform; closed forms in "
            "`railsim/studies/floor.py`.",
        ]
    return lines


def write_report(
    out: Path,
    results: dict[str, RegimeResult],
    services: Sequence[str],
    lo_s: float,
    hi_s: float,
    tol_s: float,
    max_delay_s: float,
    searched: bool = True,
    control: dict[str, Any] | None = None,
    sensitivity: Any = None,
    scan: bool = True,
) -> Path:
    """``vc_vs_mb.md`` and ``vc_vs_mb.json`` in ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    cols = [results[k] for k in ("mb", "vc", "control") if k in results]
    by = {r.regime.key: r for r in cols}
    lines = [
        "# Virtual coupling vs moving block",
        "",
        f"Scenarios: (a) `{by['mb'].regime.scenario.name}`, (b) `{by['vc'].regime.scenario.name}`"
        + (
            ", (c) = (b) with overrides " + ", ".join(f"`{k}: {v}`" for k, v in by["control"].regime.overrides.items())
            if "control" in by
            else ""
        )
        + f". Headway of {', '.join(services)} (set together) "
        + (
            f"searched on one grid for every regime, [{lo_s:g}, {hi_s:g}] s every {tol_s:g} s "
            + ("(every grid point probed for (a) and (b); (c) bisects the same grid)" if scan else "(bisection)")
            + f"; feasible = no collision, every stop served, every trip arrived, max arrival delay ≤ {max_delay_s:g} s; "
            "the answer is the smallest probed headway with every longer probe feasible, confirmed with a second seed."
            if searched
            else "given (no search): every regime runs at the same headway."
        ),
        "In (b) relative braking distance applies inside the formations only; consecutive independent trains keep "
        "the moving-block absolute braking distance. Dependent (branch) services depart relative to the searched "
        "service, so every probe keeps the same pattern. Capacity over the busiest hour of the busiest section per "
        "direction; a formation is one path carrying both units' passengers.",
        "",
        "## Answer",
        "",
        "| | minimum feasible headway [s] | first infeasible probe [s] | binding constraint there |",
        "|---|---:|---:|---|",
    ]
    for r in cols:
        h = _fmt(r.headway_s) if r.headway_s is not None else "none feasible"
        lines.append(
            f"| {r.regime.label} | {h} | {_fmt(r.binding_headway_s)} | {r.binding.text if r.binding else '–'} |"
        )
    a, b = by.get("mb"), by.get("vc")
    if a is not None and b is not None and a.headway_s and b.headway_s:
        gain = a.headway_s / b.headway_s - 1.0
        lines += [
            "",
            f"**VC gain**: (a) {a.headway_s:g} s → (b) {b.headway_s:g} s, {100 * gain:+.0f} % trains/h of the searched "
            f"services (conditions below; the analytic floors say where the limit sits).",
        ]
    if control is not None:
        ok = (
            control.get("same_headway")
            and not control.get("probes_differing")
            and control.get("max_running_time_diff_s", math.inf) <= by["mb"].conditions.get("step_s", 0.0)
        )
        lines += [
            "",
            "## Control experiment: (c) against (a)",
            "",
            f"(c) is (b) with relative braking switched off. Same answer: **{'yes' if control.get('same_headway') else 'no'}**; "
            f"probes with a different verdict: {', '.join(f'{h:g} s' for h in control.get('probes_differing', [])) or 'none'} "
            f"of {control.get('probes_compared', 0)} compared; largest per-trip running-time difference at "
            f"{_fmt(control.get('at_headway_s'))} s: {_fmt(control.get('max_running_time_diff_s'))} s over "
            f"{control.get('trips_compared', 0)} trips ({control.get('trips_only_one_side', 0)} on one side only).",
            "",
            (
                "(c) = (a): the two scenarios differ only in the formations' separation rule, so the difference "
                "(b) − (a) is the effect of relative braking inside the formations."
                if ok
                else "(c) ≠ (a): something other than the separation rule differs between the regimes; the (b) − (a) "
                "difference is not relative braking alone."
            ),
        ]
    lines += ["", "## Conditions", ""] + _conditions_md(cols)
    lines += ["", "## Analytic floors", ""] + _floor_md(cols)
    if sensitivity is not None:
        lines += ["", "## Sensitivity", ""] + sensitivity.to_markdown_lines()
    lines += [
        "",
        "## Side by side at each regime's minimum headway",
        "",
        "| | " + " | ".join(r.regime.label for r in cols) + " |",
        "|---|" + "---:|" * len(cols),
    ]
    for label, key in ROWS:
        vals = []
        for r in cols:
            if key == "headway_s":
                vals.append(_fmt(r.headway_s) if r.headway_s is not None else "none feasible")
            elif key == "delay":
                vals.append(f"{_fmt(r.metrics.get('delay_max_s'))} / {_fmt(r.metrics.get('delay_mean_s'))}")
            else:
                vals.append(_fmt(r.metrics.get(key)))
        lines.append(f"| {label} | " + " | ".join(vals) + " |")
    run_keys = sorted({k for r in cols for k in r.metrics if k.startswith(("running_time_min.", "energy_kwh_per"))})
    for key in run_keys:
        name = key.replace("running_time_min.", "mean running time [min] ").replace(
            "energy_kwh_per_trip.", "traction energy per trip [kWh] "
        )
        lines.append(f"| {name} | " + " | ".join(_fmt(r.metrics.get(key)) for r in cols) + " |")
    for r in cols:
        lines += ["", f"## {r.regime.label}", ""]
        if r.search is not None:
            lines += [r.search.to_markdown(), ""]
        for p in r.plots:
            if p.suffix == ".png":
                lines.append(f"![{r.regime.label} {p.stem}]({p.relative_to(out) if p.is_relative_to(out) else p})")
        if r.capacity_md:
            lines += ["", r.capacity_md.replace("## Capacity", f"### Capacity at {_fmt(r.headway_s)} s", 1)]
        if r.run_dir is not None:
            lines.append(f"Run outputs: `{r.run_dir.relative_to(out) if r.run_dir.is_relative_to(out) else r.run_dir}`")
    md = out / "vc_vs_mb.md"
    output.write_bytes(md, ("\n".join(lines) + "\n").encode("utf-8"))
    data: dict[str, Any] = {
        r.regime.key: {
            "label": r.regime.label,
            "scenario": str(r.regime.scenario),
            "overrides": r.regime.overrides,
            "headway_s": r.headway_s,
            "metrics": r.metrics,
            "search": r.search.to_dict() if r.search is not None else None,
            "run_dir": str(r.run_dir) if r.run_dir else None,
            "binding": r.binding.to_dict() if r.binding else None,
            "binding_headway_s": r.binding_headway_s,
            "floor": _floor_dict(r.floor),
            "conditions": r.conditions,
        }
        for r in cols
    }
    data["control_check"] = control
    if sensitivity is not None:
        data["sensitivity"] = sensitivity.to_dict()
    output.write_json(out / "vc_vs_mb.json", data)
    return md


def _floor_dict(f: Any) -> dict[str, Any] | None:
    if f is None:
        return None
    from dataclasses import asdict

    p, st = f.binding("cycle")
    return {
        "cycle_s": f.cycle_s,
        "strict_s": f.strict_s,
        "critical": {"service": p.reference, "station": st.station},
        "patterns": [asdict(x) for x in f.patterns],
        "assumptions": f.assumptions,
    }
