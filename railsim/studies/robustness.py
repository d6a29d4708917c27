"""Monte-Carlo robustness: does a timetable survive primary delays? (``railsim robustness``)

A scenario with a ``disturbances:`` section (:mod:`railsim.scenario.disturbances`; or one given with
``--disturbances FILE``) runs ``runs`` times with seeds ``first_seed … first_seed + runs − 1`` at every headway of
``headways_s`` (the override paths of the named services' ``departures.headway_s``, moved together) and every
``intensities`` value (``disturbances.intensity``). It is one sweep (:mod:`railsim.studies.sweep`): each run in its
own process, locally or on Dask, resumable (re-run the same command: finished runs are skipped), one row per run
holding the run's ``robustness.*`` KPIs (:mod:`railsim.analysis.punctuality`). A second, small sweep runs the
same headways undisturbed (intensity 0, ``baseline_runs`` seeds): the secondary delay a timetable has without any
disturbance (a plan tighter than the line can run) is subtracted to give the **knock-on** the disturbances cause:

    knock-on [min] = secondary minutes (disturbed run) − mean secondary minutes (undisturbed, same headway)
    excess propagation factor = knock-on ÷ primary minutes

Per (headway, intensity) every KPI gets its mean, standard deviation and a 95 % confidence interval of the mean
(Student t, ``n − 1`` degrees of freedom; runs are independent seeds). **Recovering** at a headway means the mean
excess propagation factor is below 1 (the line absorbs more of each injected minute than it passes on); the
*stability limit* is the largest probed headway that does not recover. A point counts as recovering (or not) only
when the whole 95 % interval lies below (above) 1; an interval spanning 1 is "unclear". Common random numbers: every trip's
primary delays depend only on the seed and the trip id (:mod:`railsim.engine.primary_delays`), so two regimes or
two headways run with the same seeds see the same primary delays for the same trips.

``DIR/robustness.json`` and ``DIR/robustness.md`` hold the table; the plots (:mod:`railsim.report.plots.robustness`)
are the delay CDF, the stability curve (knock-on and propagation factor vs headway or intensity) and the
punctuality per station along the line.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from railsim.errors import ConfigError
from railsim.record import output

KPIS: tuple[tuple[str, str], ...] = (
    ("robustness.within_1min", "arrivals ≤ 1 min late"),
    ("robustness.within_3min", "arrivals ≤ 3 min late"),
    ("robustness.within_5min", "arrivals ≤ 5 min late"),
    ("robustness.mean_delay_s", "mean arrival delay [s]"),
    ("robustness.p95_delay_s", "p95 arrival delay [s]"),
    ("robustness.primary_min", "primary delay [min]"),
    ("robustness.secondary_min", "secondary delay [min]"),
    ("robustness.propagation_factor", "propagation factor"),
    ("knock_on_min", "knock-on delay [min]"),
    ("excess_propagation_factor", "excess propagation factor"),
    ("robustness.recovery_max_s", "longest recovery [s]"),
)
PAIRED_KPIS = ("knock_on_min", "robustness.mean_delay_s", "robustness.within_3min", "excess_propagation_factor")
RECOVERING_BELOW = 1.0  # excess propagation factor below this: the line recovers


@dataclass(frozen=True)
class RobustnessPlan:
    """What to run: a scenario, its disturbances, seeds, and the headway/intensity axes."""

    scenario: Path
    runs: int
    first_seed: int = 1
    headway_paths: tuple[str, ...] = ()
    headways_s: tuple[float, ...] = ()
    intensities: tuple[float, ...] = ()
    disturbances: Mapping[str, Any] | None = None  # replaces the scenario's own section
    disturbances_source: Path | None = None  # the file it came from (named in messages)
    baseline_runs: int = 1
    label: str = ""


def headway_paths(scenario_path: Path, services: Sequence[str] | None) -> tuple[str, ...]:
    """Override paths of the services' ``departures.headway_s`` (all services timetabled by headway if None)."""
    from railsim import scenario

    raw = scenario.load(scenario_path).raw["services"]
    ids = [s["id"] for s in raw]
    wanted = list(services) if services else [s["id"] for s in raw if "headway_s" in s["departures"]]
    out = []
    for sid in wanted:
        if sid not in ids:
            raise ConfigError(scenario_path, "services", f"expected a service {sid!r}, found {', '.join(ids)}")
        i = ids.index(sid)
        if "headway_s" not in raw[i]["departures"]:
            raise ConfigError(
                scenario_path, f"services[{i}].departures", f"service {sid!r} is not timetabled by headway_s"
            )
        out.append(f"services[{i}].departures.headway_s")
    if not out:
        raise ConfigError(scenario_path, "services", "no service is timetabled by headway_s: nothing to vary")
    return tuple(out)


def load_disturbances(path: Path) -> dict[str, Any]:
    """A disturbances file: a YAML mapping, either the section itself or ``{disturbances: {...}}``."""
    from railsim.scenario.loading import parse_yaml, read_text

    data = parse_yaml(read_text(Path(path), str(path)), str(path))
    if isinstance(data, dict) and set(data) == {"disturbances"}:
        data = data["disturbances"]
    if not isinstance(data, dict):
        raise ConfigError(path, None, "expected a mapping (the disturbances: section)")
    return data


def _sweep_mapping(plan: RobustnessPlan, seeds: Sequence[int], baseline: bool) -> dict[str, Any]:
    grid: dict[str, list[Any]] = {}
    link: dict[str, str] = {}
    if plan.headways_s:
        grid[plan.headway_paths[0]] = [float(h) for h in plan.headways_s]
        link = {p: plan.headway_paths[0] for p in plan.headway_paths[1:]}
    case: dict[str, Any] = {}
    if plan.disturbances is not None:
        case["disturbances"] = dict(plan.disturbances)
    if baseline:
        case["disturbances.intensity"] = 0.0
    elif plan.intensities:
        grid["disturbances.intensity"] = [float(x) for x in plan.intensities]
    label = {"kind": "undisturbed" if baseline else "disturbed"}
    return {
        "name": f"robustness{'_' + plan.label if plan.label else ''}{'_baseline' if baseline else ''}",
        "base": str(Path(plan.scenario).resolve()),
        "grid": grid,
        "link": link,
        "cases": [{"label": label, **case}],
        "seeds": list(seeds),
    }


def _spec(plan: RobustnessPlan, folder: Path, seeds: Sequence[int], baseline: bool) -> Any:
    from railsim.studies.sweep import load_sweep

    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "robustness_sweep.yaml"
    output.write_yaml(path, _sweep_mapping(plan, seeds, baseline))
    return load_sweep(path)


def check_plan(plan: RobustnessPlan) -> None:
    """Bad input as one line, before anything runs: too few or too many runs, seeds beyond SUMO's range,
    non-positive headways, a scenario without disturbances, and a disturbances file the scenario refuses (named
    as the user's file, not the sweep file generated from it)."""
    from railsim import scenario
    from railsim.scenario.model import MAX_SEED
    from railsim.studies.bounds import check_cases

    if plan.runs < 2:
        raise ConfigError("<command line>", "--runs", f"expected at least 2 runs (for an interval), got {plan.runs}")
    points = max(1, len(plan.headways_s)) * max(1, len(plan.intensities))
    check_cases(
        plan.runs * points + max(1, plan.baseline_runs) * max(1, len(plan.headways_s)),
        "<command line>",
        "--runs",
        "runs",
    )
    if plan.first_seed < 0 or plan.first_seed + plan.runs - 1 > MAX_SEED:
        raise ConfigError(
            "<command line>",
            "--first-seed",
            f"expected seeds in [0, {MAX_SEED}] (SUMO's seed range), got {plan.first_seed} … "
            f"{plan.first_seed + plan.runs - 1}",
        )
    for h in plan.headways_s:
        if not (math.isfinite(h) and h > 0):
            raise ConfigError("<command line>", "--headways", f"expected headways in seconds > 0, got {h!r}")
    for x in plan.intensities:
        if not (math.isfinite(x) and 0 <= x <= 100):
            raise ConfigError("<command line>", "--intensities", f"expected intensities in [0, 100], got {x!r}")
    if plan.disturbances is None:
        if scenario.load(plan.scenario).disturbances is None:
            raise ConfigError(
                plan.scenario, "disturbances", "the scenario has no disturbances: section (or give a file)"
            )
        return
    check_disturbances_file(plan.scenario, plan.disturbances, plan.disturbances_source or "<disturbances>")


def check_disturbances_file(
    scenario_path: Path, disturbances: Mapping[str, Any], source: Path | str, world_check: bool = True
) -> None:
    """Every check ``railsim run`` makes on ``scenario_path`` with its ``disturbances:`` section replaced by
    ``disturbances`` (``world_check``: those against the built world too); an error in that section is reported
    against ``source``, the user's file, never the sweep file a study generates from it."""
    from railsim import scenario
    from railsim.studies.world import run_checks

    try:
        scn = scenario.load(scenario_path, {"disturbances": dict(disturbances)})
        if world_check:
            run_checks(scn)
    except ConfigError as err:
        if err.field is not None and err.field.startswith("disturbances"):
            raise ConfigError(source, err.field, err.message) from None
        raise


def run_robustness(
    plan: RobustnessPlan,
    out_dir: str | Path,
    workers: int | None = None,
    dask_address: str | None = None,
    progress: bool | None = None,
) -> dict[str, Any]:
    """Run the disturbed and the undisturbed sweeps into ``out_dir`` and aggregate them (module docstring)."""
    from railsim.studies.sweep import run_sweep

    check_plan(plan)
    out = Path(out_dir)
    seeds = list(range(plan.first_seed, plan.first_seed + plan.runs))
    runs_spec = _spec(plan, out / "runs", seeds, baseline=False)
    base_spec = _spec(plan, out / "baseline", seeds[: max(1, plan.baseline_runs)], baseline=True)
    res = {}
    for key, spec in (("runs", runs_spec), ("baseline", base_spec)):
        res[key] = run_sweep(spec, out / key, workers=workers, dask_address=dask_address, progress=progress)
    result = aggregate(plan, runs_spec, out / "runs", base_spec, out / "baseline")
    result["wall_s"] = {k: r.wall_s for k, r in res.items()}
    output.write_json(out / "robustness.json", result)
    from railsim.report.plots.robustness import robustness_figures

    result["plots"] = [str(p) for p in robustness_figures(result, out)]
    (out / "robustness.md").write_text(markdown(result), encoding="utf-8")
    output.write_json(out / "robustness.json", result)
    return result


def ci95(values: Sequence[float | None]) -> dict[str, Any]:
    """Mean, standard deviation and the 95 % confidence half-width of the mean (Student t)."""
    from scipy import stats

    x = np.asarray([v for v in values if v is not None and math.isfinite(v)], dtype=float)
    n = len(x)
    if n == 0:
        return {"n": 0, "mean": None, "sd": None, "ci95": None}
    sd = float(np.std(x, ddof=1)) if n > 1 else 0.0
    half = float(stats.t.ppf(0.975, n - 1) * sd / math.sqrt(n)) if n > 1 else None
    return {"n": n, "mean": float(np.mean(x)), "sd": sd, "ci95": half}


def _rows_by_group(spec: Any, folder: Path, axes: Sequence[str]) -> dict[tuple[Any, ...], list[dict[str, Any]]]:
    """The finished runs' rows per point of ``axes``, each with its case's seed (``_seed``)."""
    from railsim.studies.sweep import read_rows

    rows = read_rows(folder)
    groups: dict[tuple[Any, ...], list[dict[str, Any]]] = {}
    for case in spec.cases:
        row = rows.get(case.case_id)
        if row is None:
            continue
        key = tuple(case.overrides.get(a) for a in axes)
        groups.setdefault(key, []).append({**row, "_seed": case.seed})
    return groups


def _num(row: Mapping[str, Any], key: str) -> float | None:
    v = row.get(key)
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) else None


def aggregate(plan: RobustnessPlan, spec: Any, folder: Path, base_spec: Any, base_folder: Path) -> dict[str, Any]:
    """Per (headway, intensity): every KPI's mean and 95 % interval, the baseline, the stability verdict."""
    h_axis = plan.headway_paths[0] if plan.headways_s else None
    axes = [a for a in (h_axis, "disturbances.intensity" if plan.intensities else None) if a]
    groups = _rows_by_group(spec, folder, axes)
    base_groups = _rows_by_group(base_spec, base_folder, [h_axis] if h_axis else [])
    out_groups = []
    for key, rows in groups.items():
        point = dict(zip(axes, key))
        headway = point.get(h_axis) if h_axis else None
        base_rows = [r for r in base_groups.get((headway,) if h_axis else (), []) if r.get("status") == "ok"]
        base_secondary = [_num(r, "robustness.secondary_min") for r in base_rows]
        base_sec = float(np.mean([b for b in base_secondary if b is not None])) if base_rows else 0.0
        ok = [r for r in rows if r.get("status") == "ok"]
        for r in ok:
            sec, prim = _num(r, "robustness.secondary_min"), _num(r, "robustness.primary_min")
            r["knock_on_min"] = None if sec is None else sec - base_sec
            r["excess_propagation_factor"] = (
                None if (sec is None or not prim) else (sec - base_sec) / prim  # prim > 0
            )
        kpis = {k: ci95([_num(r, k) for r in ok]) for k, _ in KPIS}
        stations = station_order(ok[0]) if ok else []
        cdf_cols = sorted(c for c in (ok[0] if ok else {}) if c.startswith("robustness.cdf.le_"))
        out_groups.append(
            {
                "headway_s": headway,
                "intensity": point.get("disturbances.intensity", 1.0),
                "n_runs": len(rows),
                "n_ok": len(ok),
                "n_failed": len(rows) - len(ok),
                "collisions": int(sum(_num(r, "collisions") or 0 for r in ok)),
                "runs_with_unarrived_trips": sum(1 for r in ok if _num(r, "n_arrived") != _num(r, "n_trains")),
                "engine_wall_s": ci95([_num(r, "engine_wall_s") for r in ok]),
                "baseline": {"n": len(base_rows), "secondary_min": base_sec},
                "kpis": kpis,
                "by_station": {s: ci95([_num(r, f"robustness.by_station.{s}") for r in ok])["mean"] for s in stations},
                "cdf": {int(c[-5:-1]): ci95([_num(r, c) for r in ok])["mean"] for c in cdf_cols},
                "recovers": verdict(kpis["excess_propagation_factor"]),
                # per seed, for comparisons under common random numbers (railsim.studies.vc_robustness)
                "per_seed": {str(r["_seed"]): {k: _num(r, k) for k in PAIRED_KPIS} for r in ok},
            }
        )
    out_groups.sort(key=lambda g: (g["headway_s"] or 0.0, g["intensity"]))
    limits = [g["headway_s"] for g in out_groups if g["recovers"] is False and g["headway_s"] is not None]
    return {
        "scenario": str(plan.scenario),
        "label": plan.label,
        "runs": plan.runs,
        "seeds": [plan.first_seed, plan.first_seed + plan.runs - 1],
        "headway_paths": list(plan.headway_paths),
        "groups": out_groups,
        "stability_limit_s": max(limits) if limits else None,
    }


def verdict(stat: Mapping[str, Any]) -> bool | None:
    """Recovering (True) when the whole 95 % interval of the excess propagation factor lies below 1, not (False)
    when it lies above, None when it spans 1 or is unknown."""
    mean, half = stat.get("mean"), stat.get("ci95")
    if mean is None or half is None:
        return None
    if mean + half < RECOVERING_BELOW:
        return True
    return False if mean - half > RECOVERING_BELOW else None


def station_order(row: Mapping[str, Any]) -> list[str]:
    """The stations of a row's ``robustness.by_station.*`` columns, in line order when the row has it."""
    cols = [c[len("robustness.by_station.") :] for c in row if c.startswith("robustness.by_station.")]
    order = [s for s in str(row.get("robustness.station_order") or "").split(",") if s in cols]
    return order + [s for s in cols if s not in order]


def _fmt(stat: Mapping[str, Any], digits: int = 2, pct: bool = False) -> str:
    if stat.get("mean") is None:
        return "–"
    scale = 100.0 if pct else 1.0
    mean = stat["mean"] * scale
    half = stat.get("ci95")
    text = f"{mean:.{digits}f}"
    return text + (f" ± {half * scale:.{digits}f}" if half is not None else "")


def markdown(result: Mapping[str, Any], title: str = "Robustness") -> str:
    """The KPI table (means ± 95 % half-widths) and the stability verdict."""
    lines = [f"## {title}: {result.get('label') or Path(str(result['scenario'])).name}", ""]
    lines.append(
        f"{result['runs']} Monte-Carlo runs per point (seeds {result['seeds'][0]}–{result['seeds'][1]}); "
        "mean ± 95 % confidence half-width (Student t). Knock-on = secondary minutes minus the undisturbed "
        "run's at the same headway; recovering = excess propagation factor < 1."
    )
    lines.append("")
    head = (
        "| headway [s] | intensity | runs ok | ≤1 min [%] | ≤3 min [%] | ≤5 min [%] | mean delay [s] | p95 delay [s] |"
    )
    head += " primary [min] | knock-on [min] | propagation | excess propagation | recovers |"
    lines += [head, "|" + "---:|" * 13]
    for g in result["groups"]:
        k = g["kpis"]
        cells = [
            "–" if g["headway_s"] is None else f"{g['headway_s']:g}",
            f"{g['intensity']:g}",
            f"{g['n_ok']}/{g['n_runs']}",
            _fmt(k["robustness.within_1min"], 1, pct=True),
            _fmt(k["robustness.within_3min"], 1, pct=True),
            _fmt(k["robustness.within_5min"], 1, pct=True),
            _fmt(k["robustness.mean_delay_s"], 1),
            _fmt(k["robustness.p95_delay_s"], 1),
            _fmt(k["robustness.primary_min"], 1),
            _fmt(k["knock_on_min"], 1),
            _fmt(k["robustness.propagation_factor"]),
            _fmt(k["excess_propagation_factor"]),
            {True: "yes", False: "**no**", None: "unclear"}[g["recovers"]],
        ]
        lines.append("| " + " | ".join(cells) + " |")
    lim = result.get("stability_limit_s")
    lines += [
        "",
        f"Stability limit (largest probed headway whose interval lies above 1): {lim if lim is not None else 'none'}",
    ]
    for g in result["groups"]:
        if g["collisions"] or g["n_failed"] or g["runs_with_unarrived_trips"]:
            lines.append(
                f"- headway {g['headway_s']}: {g['collisions']} collisions, {g['n_failed']} failed runs, "
                f"{g['runs_with_unarrived_trips']} runs with trips that never arrived"
            )
    for p in result.get("plots", []):
        lines.append(f"![{Path(p).stem}]({Path(p).name})")
    return "\n".join(lines) + "\n"
