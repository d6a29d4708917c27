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
    from railsim.studies.vc_report import write_report

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
