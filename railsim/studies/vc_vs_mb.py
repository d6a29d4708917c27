"""Line studies: virtual coupling vs moving block on one line, side by side (``railsim study vc-vs-mb``).

The question our users bring: *how many trains per hour does the line carry with virtual coupling, and what does
it cost?* — and the questions a planner asks back: is the comparison fair, is the number plausible, and under which
conditions does it hold? The study runs one service pattern under three regimes:

* **(a) moving block** — every train an independent moving-block train: the ``separation`` controller keeps the
  absolute braking distance (plus margin) to whatever runs ahead. Default: ``scenarios/chongqing_line3_peak_mb.yaml``.
* **(b) virtual coupling** — the same scenario plus formations: the Airport/Jurenba up units run virtually coupled
  Liugongli → Bijin (relative braking distance, the ``coupled`` CACC role, 30 m target gap at standstill) and
  decouple before the Bijin switch; a formation occupies *one* path. Default:
  ``scenarios/chongqing_line3_peak_vc.yaml`` (a ``pairs`` formation: one per Jurenba unit at any headway).
* **(c) the control** — (b) with relative braking switched off (:func:`control_overrides`: no formation couples,
  the ``coupled`` role is the separation controller). If (c) reproduces (a) — same answer, the same verdict at
  every probe, per-trip running times within a step — the two scenarios differ only in the separation rule and
  (b) − (a) is the effect of relative braking; the report says which.

Relative braking applies **inside formations only**; consecutive independent trains keep the absolute braking
distance in every regime (coupling every trunk train into one endless platoon leaves no timetable headway to
search and is not what the Airport/Jurenba pattern describes).

**Fair search.** The branch services depart *relative* to the searched Airport services (``departures: {after:
...}``, :mod:`railsim.scenario.validate_services`), so every probed headway keeps the same pattern (before, the
Jurenba units kept fixed clock times and their phase moved from probe to probe). Every regime is searched on the
same grid (``lo_s + k·tol_s`` up to ``hi_s``) with the same feasibility definition
(:func:`railsim.studies.headway.feasibility`: no collision, every stop served, every trip arrived, max arrival delay
≤ ``max_delay_s``); with ``scan`` (default) every grid point of (a) and (b) is probed, so a non-monotone probe cannot
hide (the control bisects the same grid: each of its probes is compared with (a)'s verdict there); the answer stays
conservative (every longer probe feasible) and is confirmed with a second seed. For the **first
infeasible probe** (the largest infeasible headway) :func:`railsim.studies.binding.binding_constraint` names the
rule and place that broke it.

**Beside each answer**: the analytic floors of the regime (:mod:`railsim.studies.floor`: braking distance, train or
formation length, margin, approach, dwell and clearing at the critical station; strict and cycle floors of the
pattern) with the simulated/floor ratio; the **conditions** (offered trains/h per service, dwell, delay threshold,
comm delay/loss, target gap, formation share); optionally a **sensitivity** block
(:mod:`railsim.studies.vc_sensitivity`: target gap, t2t delay, formation share). At each answer the search's own
probe is read back (capacity per direction by :func:`railsim.analysis.capacity.analyse_run`, running time, energy,
gaps) and drawn as time-distance graphs; ``DIR/vc_vs_mb.md`` and ``DIR/vc_vs_mb.json`` hold it all.

``headway_s`` skips the search and runs every regime at that headway (a quick look; the report says so).
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
DEFAULT_VC = ROOT / "scenarios" / "chongqing_line3_peak_vc.yaml"
DEFAULT_SERVICES = ("airport_up", "airport_down")


@dataclass(frozen=True)
class Regime:
    """One side of the comparison: a scenario, the overrides that make the regime, and a label."""

    key: str  # "mb" | "vc" | "control"
    label: str
    scenario: Path
    overrides: dict[str, Any] = field(default_factory=dict)


@dataclass
class RegimeResult:
    regime: Regime
    headway_s: float | None  # the minimum feasible headway (or the given one); None: none feasible
    search: Any  # railsim.studies.headway.HeadwaySearchResult | None
    run_dir: Path | None
    metrics: dict[str, Any] = field(default_factory=dict)
    plots: list[Path] = field(default_factory=list)
    capacity_md: str = ""
    binding: Any = None  # railsim.studies.binding.Binding of the first infeasible probe
    binding_headway_s: float | None = None
    floor: Any = None  # railsim.studies.floor.RegimeFloor
    conditions: dict[str, Any] = field(default_factory=dict)


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


def control_overrides(vc_scenario: Path) -> dict[str, Any]:
    """Regime (c), the control: the VC scenario with relative braking switched off — no formation couples (every
    ``formations[i].couple`` removed, so each follower keeps the moving-block separation of the ``separation``
    role) and the ``coupled`` role itself set to the separation controller. The formations stay registered and the
    timetable is untouched, so (c) differs from (b) only in the separation rule of the formation followers."""
    from railsim import scenario
    from railsim.scenario.loading import parse_yaml, read_text

    raw = parse_yaml(read_text(Path(vc_scenario), str(vc_scenario)), str(vc_scenario))
    forms = raw.get("formations") if isinstance(raw, dict) else None
    n = len(forms) if isinstance(forms, list) else 0
    if n == 0:
        raise ConfigError(vc_scenario, "formations", "expected the virtual-coupling scenario to have formations")
    overrides: dict[str, Any] = {f"formations[{i}].couple": None for i in range(n)}
    overrides["roles.coupled"] = scenario.load(vc_scenario).roles["separation"]
    return overrides


def conditions(scn: Any, search: Any, max_delay_s: float, delay_stat: str) -> dict[str, Any]:
    """The traffic and system conditions behind a regime's number: offered trains/h per service at the answer,
    dwell times, the delay threshold, comm delay/loss, target gaps and the formation share."""
    from railsim.studies.floor import _mean_delay_s

    comm = {}
    for name, ch in scn.faults.comm.items():
        comm[name] = {
            "delay": ch.delay.dist + " " + ", ".join(f"{k} {v:g}" for k, v in ch.delay.params.items()) + " s",
            "mean_delay_s": _mean_delay_s(ch.delay),
            "loss_prob": ch.loss_prob,
        }
    svc0 = scn.services[0]
    shares = {
        s.id: f"1 per {s.departures_after.every} {s.departures_after.service}"
        for s in scn.services
        if s.departures_after is not None
    }
    return {
        "offered_trains_per_h": dict(search.trains_per_hour_by_service) if search is not None else {},
        "offered_trains_per_h_by_direction": dict(search.trains_per_hour) if search is not None else {},
        "dwell_default_s": svc0.dwell_default_s,
        "dwell_by_station_s": dict(svc0.dwell_by_station),
        "max_delay_s": max_delay_s,
        "delay_stat": delay_stat,
        "comm": comm,
        "target_gap_m": sorted({f.target_gap_m for f in scn.formations if f.couple is not None}),
        "formations": sum(1 for f in scn.formations if f.couple is not None),
        "relative_departures": shares,
        "step_s": scn.simulation.step_s,
        "seed": scn.simulation.seed,
    }


def first_infeasible(search: Any) -> Any:
    """The probe that limits the answer: the largest infeasible probed headway (the first infeasible one coming down
    the grid; a failed confirmation counts), or None when every probe was feasible."""
    bad = [p for p in search.probes if not p.feasible]
    return max(bad, key=lambda p: (p.headway_s, -p.seed)) if bad else None


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


def regimes(mb_scenario: Path, vc_scenario: Path, control: bool = True) -> list[Regime]:
    """(a) moving block, (b) virtual coupling and, with ``control``, (c) the control (:func:`control_overrides`)."""
    out = [
        Regime("mb", "(a) moving block", mb_scenario),
        Regime("vc", "(b) virtual coupling", vc_scenario),
    ]
    if control:
        out.append(Regime("control", "(c) VC, relative braking off", vc_scenario, control_overrides(vc_scenario)))
    return out


def vc_vs_mb(
    out_dir: str | Path,
    *,
    mb_scenario: str | Path = DEFAULT_MB,
    vc_scenario: str | Path = DEFAULT_VC,
    services: Sequence[str] = DEFAULT_SERVICES,
    lo_s: float = 70.0,
    hi_s: float = 200.0,
    tol_s: float = 10.0,
    max_delay_s: float = 120.0,
    workers: int = 1,
    dask_address: str | None = None,
    headway_s: float | None = None,
    confirm: bool = True,
    scan: bool = True,
    control: bool = True,
    sensitivity: bool = False,
    progress: bool | None = None,
) -> dict[str, RegimeResult]:
    """Run the VC-vs-moving-block study into ``out_dir`` (module docstring); returns the regimes' results."""
    from railsim import scenario
    from railsim.studies.binding import binding_constraint
    from railsim.studies.floor import regime_floor
    from railsim.studies.headway import find_min_headway
    from railsim.studies.sweep import case_id, run_case

    out = Path(out_dir)
    regs = regimes(Path(mb_scenario), Path(vc_scenario), control)
    if headway_s is not None and not (headway_s > 0 and math.isfinite(headway_s)):
        raise ConfigError("<study>", "headway_s", f"expected a number of seconds > 0, got {headway_s!r}")
    paths = {r.key: headway_paths(r.scenario, services) for r in regs}  # validates the files first
    if paths["mb"] != paths["vc"]:
        raise ConfigError(
            vc_scenario, "services", f"expected the headway services at the same places as in {mb_scenario}"
        )
    results: dict[str, RegimeResult] = {}
    for r in regs:
        folder = out / r.key
        search = None
        h = headway_s
        if h is None:
            search = find_min_headway(
                r.scenario,
                paths[r.key],
                lo_s,
                hi_s,
                tol_s=tol_s,
                max_delay_s=max_delay_s,
                overrides=r.overrides,
                workers=workers,
                dask_address=dask_address,
                out_dir=folder / "search",
                confirm_seeds=None if confirm else [],
                keep_runs=True,
                progress=progress,
                scan=scan and r.key != "control",  # the control bisects: each of its probes checks (a)'s verdict
            )
            h = search.min_headway_s
        res = RegimeResult(r, h, search, None)
        seed = int(scenario.load(r.scenario, r.overrides).simulation.seed)
        at = h if h is not None else hi_s
        scn_at = scenario.load(r.scenario, {**r.overrides, **{p: at for p in paths[r.key]}})
        res.floor = regime_floor(scn_at, tuple(services))
        res.conditions = conditions(scn_at, search, max_delay_s, "max")
        if search is not None:
            bad = first_infeasible(search)
            if bad is not None:
                bad_dir = folder / "search" / "runs" / bad.case_id
                res.binding_headway_s = bad.headway_s
                if (bad_dir / "summary.json").is_file():
                    res.binding = binding_constraint(bad_dir)
        if h is not None:
            overrides = {**r.overrides, **{p: h for p in paths[r.key]}}
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
    control_check = compare_control(
        results, out, paths["mb"], seed_of=lambda r: int(scenario.load(r.scenario).simulation.seed)
    )
    sens = None
    if sensitivity and headway_s is None:
        from railsim.studies.vc_sensitivity import run_sensitivity

        sens = run_sensitivity(
            out / "sensitivity",
            results,
            paths["mb"],
            lo_s=lo_s,
            hi_s=hi_s,
            tol_s=tol_s,
            max_delay_s=max_delay_s,
            workers=workers,
            dask_address=dask_address,
            progress=progress,
        )
    write_report(
        out,
        results,
        services,
        lo_s,
        hi_s,
        tol_s,
        max_delay_s,
        searched=headway_s is None,
        control=control_check,
        sensitivity=sens,
        scan=scan,
    )
    return results


def compare_control(
    results: dict[str, RegimeResult], out: Path, paths: Sequence[str], seed_of: Any
) -> dict[str, Any] | None:
    """(a) against (c): the same answer, the same feasibility at every probed headway, and per-trip running times at
    (a)'s answer (``trips.csv`` ``travel_time_s``; both runs are kept by the scan)."""
    import pandas as pd

    from railsim.studies.sweep import case_id

    a, c = results.get("mb"), results.get("control")
    if a is None or c is None:
        return None
    check: dict[str, Any] = {"same_headway": a.headway_s == c.headway_s}
    if a.search is not None and c.search is not None:
        fa = {(p.headway_s, p.seed): p.feasible for p in a.search.probes}
        fc = {(p.headway_s, p.seed): p.feasible for p in c.search.probes}
        common = sorted(set(fa) & set(fc))
        check["probes_compared"] = len(common)
        check["probes_differing"] = [k[0] for k in common if fa[k] != fc[k]]
    h = a.headway_s
    if h is not None and a.run_dir is not None:
        c_dir = (
            out
            / "control"
            / "search"
            / "runs"
            / case_id({**c.regime.overrides, **{p: h for p in paths}}, seed_of(c.regime))
        )
        if (c_dir / "trips.csv").is_file():
            ta = pd.read_csv(a.run_dir / "trips.csv").set_index("trip_id")
            tc = pd.read_csv(c_dir / "trips.csv").set_index("trip_id")
            both = ta.index.intersection(tc.index)
            diff = (ta.loc[both, "travel_time_s"] - tc.loc[both, "travel_time_s"]).abs()
            check.update(
                at_headway_s=h,
                trips_compared=int(len(both)),
                trips_only_one_side=int(len(ta.index.symmetric_difference(tc.index))),
                max_running_time_diff_s=float(diff.max()) if len(diff) else math.nan,
            )
    return check


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
