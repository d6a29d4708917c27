"""Line studies: virtual coupling vs moving block on one line, side by side (``railsim study vc-vs-mb``).

The question our users bring: *how many trains per hour does the line carry with virtual coupling, and what does
it cost?* The study runs the same service pattern under two operating regimes and reports them side by side:

* **(a) moving block** — every train is an independent moving-block train: the ``separation`` controller keeps
  the absolute braking distance (plus margin) to whatever runs ahead, so every unit occupies its own path.
  Default scenario: ``scenarios/chongqing_line3_peak_mb.yaml`` (Jurenba up units on their own 600 s timetable
  from Liugongli, interleaved with the Airport units on the trunk).
* **(b) virtual coupling** — the Airport/Jurenba units run virtually coupled on the trunk (relative braking
  distance, the ``coupled`` CACC role, 30 m target gap at standstill), couple when leaving Liugongli and decouple
  before the Bijin switch; a formation occupies *one* path and carries both units' passengers. Default scenario:
  ``scenarios/chongqing_line3_peak.yaml`` (the demo; every fourth Airport up unit leads a Jurenba unit).

Reading chosen for (b): relative braking distance applies **inside formations only**; consecutive independent
trains (one Airport unit behind another) keep the moving-block absolute braking distance in both regimes. Coupling
every consecutive trunk train into one endless platoon is a different operating concept (no timetable headway
left to search) and is not what the data's Airport/Jurenba pattern describes. So the regimes differ exactly where
the issue puts the difference: whether a Jurenba unit needs a path of its own on the trunk.

For each regime the study

1. searches the **minimum feasible headway** of the Airport service (both directions set together; override paths
   ``services[i].departures.headway_s`` of the services named in ``services``) with
   :func:`railsim.studies.headway.find_min_headway` (feasible = no collision, every stop served, every trip arrived,
   arrival delay at most ``max_delay_s``). The other services keep their timetable: the Jurenba down units and,
   in (a), the Jurenba up units run their own 600 s pattern; in (b) the Jurenba up units are re-timed to their
   leader. The (b) formations name Airport trips 0, 4, … 24, which exist for every headway ≤ 150 s in the
   07:30–08:30 window, so (b) is searched up to 150 s;
2. keeps the search's own probe **at that headway** (full outputs in ``DIR/<regime>/search/runs/<case_id>``; with
   ``headway_s`` given, a run in ``DIR/<regime>/run``) and reads it back:
   capacity per direction (:func:`railsim.analysis.capacity.analyse_run`: trains/h, paths/h, passengers/h over the busiest
   hour of the busiest section, UIC 406 occupancy), running time per service, traction energy (``trips.csv``
   ``energy_kwh``), gap statistics (the smallest true gap per trip; the coupled gap error of the formations);
3. writes ``DIR/vc_vs_mb.md`` with the two columns, the probe tables and the time-distance graphs
   (:func:`railsim.report.plots.line.time_distance`), and ``DIR/vc_vs_mb.json``.

``headway_s`` skips the search and runs both regimes at that headway (a quick look; the report says so).

Caveat for (a): its Jurenba up units keep fixed clock times (every 600 s from 07:30 at Liugongli) while the Airport
headway is varied, so the phase between the two patterns changes from probe to probe; a Jurenba unit that leaves
Liugongli just ahead of an Airport unit delays it, and feasibility is then *not monotone* in the headway. The search
(:mod:`railsim.studies.headway`) lists such probes and answers conservatively (every probed headway above the answer is
feasible). A planner would re-time the Jurenba units for every Airport headway; the scenario schema has no
"departure relative to another service" yet, and the headway search sets plain override paths, so the study does
not.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from railsim.errors import ConfigError
from railsim.record import output

ROOT = Path(__file__).resolve().parents[2]  # the repository (railsim/studies/<this file>)
DEFAULT_MB = ROOT / "scenarios" / "chongqing_line3_peak_mb.yaml"
DEFAULT_VC = ROOT / "scenarios" / "chongqing_line3_peak.yaml"
DEFAULT_SERVICES = ("airport_up", "airport_down")


@dataclass(frozen=True)
class Regime:
    """One side of the comparison: a scenario, the headway search range and a label."""

    key: str  # "mb" | "vc"
    label: str
    scenario: Path
    lo_s: float
    hi_s: float


@dataclass
class RegimeResult:
    regime: Regime
    headway_s: float | None  # the minimum feasible headway (or the given one); None: none feasible
    search: Any  # railsim.studies.headway.HeadwaySearchResult | None
    run_dir: Path | None
    metrics: dict[str, Any] = field(default_factory=dict)
    plots: list[Path] = field(default_factory=list)
    capacity_md: str = ""


def headway_paths(scenario_path: Path, services: Sequence[str]) -> list[str]:
    """The override paths ``services[i].departures.headway_s`` of the named services in ``scenario_path``
    (ConfigError naming the file if a service is missing or is not timetabled by ``first/last/headway_s``)."""
    from railsim import scenario

    scn = scenario.load(scenario_path)
    raw = scn.raw["services"]
    ids = [s["id"] for s in raw]
    paths = []
    for sid in services:
        if sid not in ids:
            raise ConfigError(
                scenario_path, "services", f"expected a service {sid!r} to set the headway of, found {', '.join(ids)}"
            )
        i = ids.index(sid)
        if "headway_s" not in raw[i]["departures"]:
            raise ConfigError(
                scenario_path,
                f"services[{i}].departures",
                f"service {sid!r} must be timetabled by first/last/headway_s for a headway study",
            )
        paths.append(f"services[{i}].departures.headway_s")
    return paths


# --------------------------------------------------------------------------------------------------------------
# Metrics of one run
# --------------------------------------------------------------------------------------------------------------


def run_metrics(run_dir: Path) -> tuple[dict[str, Any], str]:
    """Side-by-side numbers of one finished run, and its capacity report in Markdown."""
    from railsim.analysis.capacity import analyse_run
    from railsim.analysis.sections import read_summary, read_table

    summary = read_summary(run_dir)
    trips = read_table(run_dir, "trips")
    forms = read_table(run_dir, "formations")
    report = analyse_run(run_dir)
    m: dict[str, Any] = {
        "trains": summary["n_trains"],
        "arrived": summary["n_arrived"],
        "collisions": summary["collisions"],
        "stops_missed": summary["n_stops_missed"],
        "min_gap_m": summary["min_gap_m"],
    }
    for row in report.tables["directions"].itertuples(index=False):
        d = row.direction
        m[f"{d}.trains_per_h"] = row.trains_per_h
        m[f"{d}.paths_per_h"] = row.paths_per_h
        m[f"{d}.pax_per_h"] = row.pax_per_h
        m[f"{d}.busiest_section"] = row.busiest_section
        m[f"{d}.max_occupancy"] = row.max_occupancy
        m[f"{d}.max_occupancy_section"] = row.max_occupancy_section
    for svc, rt in summary["mean_running_time_s"].items():
        m[f"running_time_min.{svc}"] = rt / 60.0
    for svc, g in trips.groupby("service"):
        m[f"energy_kwh_per_trip.{svc}"] = float(g["energy_kwh"].mean())
    m["energy_kwh_total"] = float(trips["energy_kwh"].sum())
    m["delay_max_s"] = float(trips["delay_s"].max())
    m["delay_mean_s"] = float(trips["delay_s"].mean())
    gaps = trips["min_gap_m"].dropna()
    m["trip_min_gap_p50_m"] = float(gaps.median()) if len(gaps) else math.nan
    coupled = forms[forms["couple_successes"].fillna(0) > 0] if len(forms) else forms
    m["formations_coupled"] = f"{len(coupled)}/{len(forms)}"
    m["coupled_gap_error_p95_m"] = float(coupled["gap_error_p95_m"].max()) if len(coupled) else math.nan
    m["coupled_min_gap_m"] = float(coupled["min_gap_m"].min()) if len(coupled) else math.nan
    return m, report.to_markdown()


def _time_distance(run_dir: Path, stem: Path) -> list[Path]:
    """Time-distance graphs per direction (PNG and SVG files)."""
    from railsim.report.plots import line  # imported late: it loads matplotlib

    files: list[Path] = []
    for direction in ("up", "down"):
        files += [Path(p) for p in line.time_distance(run_dir, Path(f"{stem}_{direction}"), direction=direction)]
    return files


# --------------------------------------------------------------------------------------------------------------
# The study
# --------------------------------------------------------------------------------------------------------------


def vc_vs_mb(
    out_dir: str | Path,
    *,
    mb_scenario: str | Path = DEFAULT_MB,
    vc_scenario: str | Path = DEFAULT_VC,
    services: Sequence[str] = DEFAULT_SERVICES,
    lo_s: float = 60.0,
    mb_hi_s: float = 240.0,
    vc_hi_s: float = 150.0,
    tol_s: float = 10.0,
    max_delay_s: float = 120.0,
    workers: int = 1,
    headway_s: float | None = None,
    confirm: bool = True,
    progress: bool | None = None,
) -> dict[str, RegimeResult]:
    """Run the VC-vs-moving-block study into ``out_dir`` (module docstring); returns the two regimes' results."""
    from railsim import scenario
    from railsim.studies.headway import find_min_headway
    from railsim.studies.sweep import case_id, run_case

    out = Path(out_dir)
    regimes = [
        Regime("mb", "(a) moving block", Path(mb_scenario), lo_s, mb_hi_s),
        Regime("vc", "(b) virtual coupling", Path(vc_scenario), lo_s, vc_hi_s),
    ]
    if headway_s is not None and not (headway_s > 0 and math.isfinite(headway_s)):
        raise ConfigError("<study>", "headway_s", f"expected a number of seconds > 0, got {headway_s!r}")
    paths = {r.key: headway_paths(r.scenario, services) for r in regimes}  # validates both files first
    results: dict[str, RegimeResult] = {}
    for r in regimes:
        folder = out / r.key
        search = None
        h = headway_s
        if h is None:
            search = find_min_headway(
                r.scenario,
                paths[r.key],
                r.lo_s,
                r.hi_s,
                tol_s=tol_s,
                max_delay_s=max_delay_s,
                workers=workers,
                out_dir=folder / "search",
                confirm_seeds=None if confirm else [],
                keep_runs=True,
                progress=progress,
            )
            h = search.min_headway_s
        res = RegimeResult(r, h, search, None)
        if h is not None:
            seed = int(scenario.load(r.scenario).simulation.seed)
            overrides = {p: h for p in paths[r.key]}
            run_dir = folder / "search" / "runs" / case_id(overrides, seed)  # the search's own probe at h
            if not (run_dir / "summary.json").is_file():
                run_dir = folder / "run"
                row = run_case(r.scenario, overrides, seed, out_dir=run_dir)
                if row["status"] != "ok":
                    raise ConfigError(
                        r.scenario, f"headway {h:g} s", f"the run at the minimum headway failed: {row['error']}"
                    )
            res.run_dir = run_dir
            res.metrics, res.capacity_md = run_metrics(run_dir)
            res.plots = _time_distance(run_dir, out / f"{r.key}_time_distance")
        results[r.key] = res
    write_report(out, results, services, tol_s, max_delay_s, searched=headway_s is None)
    return results


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


def write_report(
    out: Path,
    results: dict[str, RegimeResult],
    services: Sequence[str],
    tol_s: float,
    max_delay_s: float,
    searched: bool = True,
) -> Path:
    """``vc_vs_mb.md`` and ``vc_vs_mb.json`` in ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    cols = [results[k] for k in ("mb", "vc") if k in results]
    lines = [
        "# Virtual coupling vs moving block",
        "",
        f"Scenarios: (a) `{cols[0].regime.scenario.name}`, (b) `{cols[1].regime.scenario.name}`. Headway of "
        f"{', '.join(services)} (both set together) "
        + (
            f"searched in [{cols[0].regime.lo_s:g}, {cols[0].regime.hi_s:g}] s for (a) and "
            f"[{cols[1].regime.lo_s:g}, {cols[1].regime.hi_s:g}] s for (b), tolerance {tol_s:g} s, feasible = "
            f"no collision, every stop served, every trip arrived, max arrival delay ≤ {max_delay_s:g} s; "
            "each regime then run once at its minimum headway."
            if searched
            else "given (no search): both regimes run at the same headway."
        ),
        "In (b) relative braking distance applies inside the Airport/Jurenba formations only; consecutive "
        "independent trains keep the moving-block absolute braking distance (see railsim/study.py). Capacity "
        "over the busiest hour of the busiest section per direction; a formation is one path carrying both "
        "units' passengers.",
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
    output.write_json(
        out / "vc_vs_mb.json",
        {
            r.regime.key: {
                "label": r.regime.label,
                "scenario": str(r.regime.scenario),
                "headway_s": r.headway_s,
                "metrics": r.metrics,
                "search": r.search.to_dict() if r.search is not None else None,
                "run_dir": str(r.run_dir) if r.run_dir else None,
            }
            for r in cols
        },
    )
    return md
