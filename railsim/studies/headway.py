"""Minimum feasible headway: the shortest departure interval a service pattern runs at without breaking down.

Given a base scenario and the override paths that set the headway of one or several services (e.g. both directions
of the Airport service, ``services[0].departures.headway_s`` and ``services[1].departures.headway_s``, all set to
the same value), :func:`find_min_headway` searches ``[lo_s, hi_s]`` for the smallest headway that is **feasible**:

* no collision (ours on ground truth, or SUMO's) and no switch passed without its lock,
* every scheduled stop served (none missed),
* every trip arrived before the end of the simulation,
* the arrival delay against the free-run plan (``trips.csv`` ``delay_s``, see :func:`railsim.studies.sweep.trip_metrics`)
  at most ``max_delay_s``; by default over the **maximum** of all arrived trips (``delay_stat="max"``). We chose the
  maximum because a headway is not sustainable if even one train falls behind by more than the threshold: that
  delay propagates to the next round of the timetable, and a p95 would hide exactly the train that queues behind
  the switch. ``delay_stat="p95"`` is offered for studies that accept an occasional outlier.

**Grid.** Headways are probed on the grid ``lo_s + k·tol_s`` (``hi_s`` itself is the last point), so the answer is
exact to the tolerance and probes are reproducible (the same case ids, see :func:`railsim.studies.sweep.case_id`).

**Search, and non-monotone feasibility.** In theory a longer headway is never harder; in a simulation it can be
(a different number of trains, a train arriving at a switch exactly when another holds the lock, random message
loss). We therefore define the answer conservatively: the smallest probed headway ``h`` such that **every probed
headway >= h is feasible**. The search probes ``hi`` and ``lo`` first (``hi`` infeasible: no answer; ``lo``
feasible: the answer is ``lo`` and may be smaller, ``at_lower_bound``), then repeatedly probes inside the bracket
``(a, b)`` where ``b`` is that conservative frontier and ``a`` the largest probed headway below it (infeasible by
construction): one midpoint per round with one worker (bisection), ``workers`` evenly spaced points per round
otherwise (the probes of a round run in parallel). A probe feasible below an infeasible one is reported in
``non_monotone`` and does not lower the answer. With ``scan`` every grid point is probed in the first round instead
(a study comparing regimes probes them all on the same points, and no non-monotone probe goes unseen). When the bracket is one grid step wide, the answer is **confirmed**
by re-running it with each of ``confirm_seeds`` (default: seed + 1; the random parts of a run are comm delays and
losses); if a confirmation fails, that headway counts as infeasible and the search goes on above it.

**Capacity at the answer.** ``trains_per_hour`` gives, per direction (``up`` = increasing chainage of the world,
from the origin and destination stations' km), the sum over services of ``3600 · (n − 1) / (last − first)``
of their planned departures in the scenario at the minimum headway (a service with one departure adds 0).

``railsim min-headway SCENARIO --path P [--path P2 ...] --lo S --hi S [--tol S] [--max-delay S]``
(:mod:`railsim.cli.headway`) prints the probe table and the answer; ``--out DIR`` writes ``headway.json``,
``probes.csv`` and keeps every probe as a resumable sweep row (``DIR/rows/``; with ``--keep-runs`` its full run
under ``DIR/runs/<case_id>``). Exit 0 when a feasible headway was found, 1 when none in the range is, 2 on bad input.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from railsim.errors import ConfigError
from railsim.record import output
from railsim.scenario.model import MAX_SEED
from railsim.studies.bounds import check_cases
from railsim.studies.sweep import Case, CaseTask, case_id, execute, read_rows, write_row

DELAY_STATS = ("max", "p95")


@dataclass(frozen=True)
class FeasibilityCriteria:
    """When a run counts as feasible (see the module docstring)."""

    max_delay_s: float = 120.0  # arrival delay threshold [s]
    delay_stat: str = "max"  # "max" | "p95" over the arrived trips


def feasibility(row: Mapping[str, Any], criteria: FeasibilityCriteria) -> tuple[bool, str]:
    """``(feasible, reason)`` of one case row (:func:`railsim.studies.sweep.run_case`); the reason names every violation."""
    if row.get("status") != "ok":
        return False, f"failed: {row.get('error', '')}"
    reasons = []
    collisions = int(row.get("collisions") or 0) + int(row.get("sumo_collisions") or 0)
    if collisions:
        reasons.append(f"{collisions} collision(s)")
    if int(row.get("switch_violations") or 0):
        reasons.append(f"{row['switch_violations']} switch violation(s)")
    missed = int(row.get("n_stops_missed") or 0)
    served, scheduled = row.get("n_stops_served"), row.get("n_stops_scheduled")
    if missed or served != scheduled:
        reasons.append(f"stops served {served}/{scheduled} (missed {missed})")
    if row.get("n_arrived") != row.get("n_trains"):
        reasons.append(f"arrived {row.get('n_arrived')}/{row.get('n_trains')}")
    delay = row.get(f"trips.arrival_delay_{criteria.delay_stat}_s")
    if delay is None or not math.isfinite(float(delay)):
        reasons.append("no arrival delay (no trip arrived)")
    elif float(delay) > criteria.max_delay_s:
        reasons.append(f"{criteria.delay_stat} delay {float(delay):.1f} s > {criteria.max_delay_s:g} s")
    return (not reasons), "; ".join(reasons) if reasons else "ok"


@dataclass(frozen=True)
class Probe:
    """One run of the search: a headway, a seed, and what came of it."""

    headway_s: float
    seed: int
    case_id: str
    feasible: bool
    reason: str
    round: int  # 0: the range ends, 1..: bracketing rounds, then confirmation rounds
    delay_s: float | None  # the delay statistic the criteria use
    n_trains: int | None
    wall_s: float | None


@dataclass(frozen=True)
class HeadwaySearchResult:
    """The answer of :func:`find_min_headway` with every probe behind it."""

    min_headway_s: float | None  # None: no headway in [lo_s, hi_s] is feasible
    lo_s: float
    hi_s: float
    tol_s: float
    headway_paths: tuple[str, ...]
    criteria: FeasibilityCriteria
    probes: tuple[Probe, ...]
    non_monotone: tuple[float, ...] = ()  # feasible headways below an infeasible probed one
    at_lower_bound: bool = False  # lo_s itself is feasible: the true minimum may be smaller
    confirmed_seeds: tuple[int, ...] = ()
    trains_per_hour: dict[str, float] = field(default_factory=dict)  # direction -> trains/h at the answer
    trains_per_hour_by_service: dict[str, float] = field(default_factory=dict)

    @property
    def feasible(self) -> bool:
        return self.min_headway_s is not None

    def probe_table(self) -> Any:
        """The probes as a pandas DataFrame, sorted by headway then seed."""
        import pandas as pd

        frame = pd.DataFrame([asdict(p) for p in self.probes])
        return frame.sort_values(["headway_s", "seed"]).reset_index(drop=True) if len(frame) else frame

    def to_dict(self) -> dict[str, Any]:
        data = asdict(self)
        data["criteria"] = asdict(self.criteria)
        return data

    def to_markdown(self) -> str:
        lines = [
            f"Minimum feasible headway over {', '.join(self.headway_paths)} in [{self.lo_s:g}, {self.hi_s:g}] s "
            f"(tolerance {self.tol_s:g} s; feasible = no collision, every stop served, every trip arrived, "
            f"{self.criteria.delay_stat} arrival delay <= {self.criteria.max_delay_s:g} s):",
            "",
        ]
        if self.min_headway_s is None:
            lines.append("**No feasible headway in the range.**")
        else:
            extra = " (the range's lower end: the minimum may be smaller)" if self.at_lower_bound else ""
            lines.append(
                f"**{self.min_headway_s:g} s**{extra}; confirmed with seeds "
                f"{', '.join(map(str, self.confirmed_seeds)) or '-'}; trains/h per direction: "
                + (", ".join(f"{d} {v:.1f}" for d, v in self.trains_per_hour.items()) or "-")
            )
        if self.non_monotone:
            lines.append(
                f"Non-monotone: feasible at {', '.join(f'{h:g}' for h in self.non_monotone)} s although a "
                "longer probed headway was not (the answer stays above them)."
            )
        lines += [
            "",
            "| headway s | seed | round | feasible | delay s | trains | reason |",
            "|---:|---:|---:|:---:|---:|---:|---|",
        ]
        for p in sorted(self.probes, key=lambda p: (p.headway_s, p.seed)):
            delay = "-" if p.delay_s is None else f"{p.delay_s:.1f}"
            lines.append(
                f"| {p.headway_s:g} | {p.seed} | {p.round} | {'yes' if p.feasible else 'no'} | {delay} | "
                f"{p.n_trains if p.n_trains is not None else '-'} | {p.reason} |"
            )
        return "\n".join(lines)


def _grid(lo_s: float, hi_s: float, tol_s: float) -> list[float]:
    n = int(math.ceil((hi_s - lo_s) / tol_s - 1e-9))
    return [round(min(lo_s + k * tol_s, hi_s), 9) for k in range(n + 1)]


def planned_probes(n_grid: int, workers: int, scan: bool, n_confirm: int) -> int:
    """How many probes a search usually runs (the progress bar's total): every grid point with ``scan``, else
    ``hi`` and ``lo`` plus ``workers`` points per round until the bracket is one step wide; then the confirmations.
    A failed confirmation or a non-monotone probe can add a few; a feasible ``lo`` or infeasible ``hi`` ends sooner.
    """
    if scan or n_grid <= 2:
        return n_grid + n_confirm
    rounds = math.ceil(math.log(n_grid - 1) / math.log(workers + 1) - 1e-9)
    return min(n_grid, 2 + workers * rounds) + n_confirm


def _frontier(state: Mapping[int, bool]) -> int | None:
    """Smallest probed grid index with every probed index >= it feasible (None if the top one is infeasible)."""
    best = None
    for k in sorted(state, reverse=True):
        if not state[k]:
            break
        best = k
    return best


def service_rates(scn: Any) -> tuple[dict[str, float], dict[str, float]]:
    """Trains/h per direction and per service of a scenario's planned departures (module docstring)."""
    km: dict[str, float] = {}
    if scn.world.kind != "net":
        import network

        name_or_path, params = scn.world.build_args()
        km = {sid: st.km for sid, st in network.build(name_or_path, **params).stations.items()}
    by_service: dict[str, float] = {}
    by_direction: dict[str, float] = {}
    for svc in scn.services:
        deps = sorted(svc.departures_s)
        rate = 3600.0 * (len(deps) - 1) / (deps[-1] - deps[0]) if len(deps) > 1 and deps[-1] > deps[0] else 0.0
        by_service[svc.id] = rate
        a, b = km.get(svc.from_station), km.get(svc.to_station)
        direction = "unknown" if a is None or b is None else ("up" if b > a else "down")
        by_direction[direction] = by_direction.get(direction, 0.0) + rate
    return dict(sorted(by_direction.items())), by_service


def find_min_headway(
    scenario_path: str | Path,
    headway_paths: Sequence[str],
    lo_s: float,
    hi_s: float,
    *,
    tol_s: float = 5.0,
    max_delay_s: float = 120.0,
    delay_stat: str = "max",
    overrides: Mapping[str, Any] | None = None,
    seed: int | None = None,
    confirm_seeds: Sequence[int] | None = None,
    workers: int = 1,
    dask_address: str | None = None,
    timeout_s: float | None = None,
    out_dir: str | Path | None = None,
    keep_runs: bool = False,
    progress: bool | None = None,
    scan: bool = False,
) -> HeadwaySearchResult:
    """Smallest feasible headway in ``[lo_s, hi_s]`` to ``tol_s`` (module docstring: criteria, search, answer).

    Every path of ``headway_paths`` is set to the probed headway [s]; ``overrides`` are applied to every probe as
    well. ``seed`` defaults to the scenario's; ``confirm_seeds`` to ``[seed + 1]`` (``[]``: no confirmation).
    Probes run through :func:`railsim.studies.sweep.run_case`, ``workers`` at a time (or on ``dask_address``). With
    ``out_dir`` every probe row is kept in ``out_dir/rows`` and reused by a later call with the same arguments.
    ``scan`` probes every grid point in the first round (no bisection), so every non-monotone probe is seen.
    """
    from railsim import scenario

    src = str(scenario_path)
    paths = tuple(headway_paths)
    if not paths:
        raise ConfigError(src, "headway_paths", "expected at least one override path that sets a headway")
    for name, value in (("lo_s", lo_s), ("hi_s", hi_s), ("tol_s", tol_s)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
            raise ConfigError(src, name, f"expected a number of seconds > 0, got {value!r}")
    if hi_s <= lo_s:
        raise ConfigError(src, "hi_s", f"expected hi_s > lo_s = {lo_s:g}, got {hi_s:g}")
    if delay_stat not in DELAY_STATS:
        raise ConfigError(src, "delay_stat", f"expected one of {', '.join(DELAY_STATS)}, got {delay_stat!r}")
    if not max_delay_s >= 0:
        raise ConfigError(src, "max_delay_s", f"expected a number of seconds >= 0, got {max_delay_s!r}")
    if workers < 1:
        raise ConfigError(src, "workers", f"expected an integer >= 1, got {workers}")
    base = dict(overrides or {})

    def overrides_at(h: float) -> dict[str, Any]:
        return {**base, **{p: h for p in paths}}

    def load_at(h: float) -> Any:
        try:
            return scenario.load(scenario_path, overrides_at(h))
        except ConfigError as err:
            raise ConfigError(src, f"headway {h:g} s", str(err).replace("<overrides>", "override")) from None

    from railsim.studies.world import run_checks

    check_cases(int(math.ceil((hi_s - lo_s) / tol_s - 1e-9)) + 1, src, "tol_s", "headways on the grid")
    for h in (lo_s, hi_s):  # the two ends stand for the grid: every check railsim run makes, before any probe
        checked = load_at(h)
        try:
            run_checks(checked)
        except ConfigError as err:
            raise ConfigError(src, f"headway {h:g} s", str(err).replace("<overrides>", "override")) from None
    scn_hi = checked
    seed = int(scn_hi.simulation.seed if seed is None else seed)
    confirm = [seed + 1] if confirm_seeds is None else [int(s) for s in confirm_seeds if int(s) != seed]
    for s in (seed, *confirm):
        if not 0 <= s <= MAX_SEED:
            raise ConfigError(src, "seed", f"expected seeds in [0, {MAX_SEED}] (SUMO's seed range), got {s}")
    criteria = FeasibilityCriteria(max_delay_s=float(max_delay_s), delay_stat=delay_stat)
    grid = _grid(float(lo_s), float(hi_s), float(tol_s))
    out = Path(out_dir) if out_dir is not None else None
    stored = read_rows(out) if out is not None else {}
    probes: list[Probe] = []
    feasible_at: dict[int, bool] = {}  # grid index -> feasible for every seed run there
    bar = None
    if progress or (progress is None and sys.stderr.isatty()):
        from tqdm import tqdm

        total = planned_probes(len(grid), workers, scan, len(confirm))
        bar = tqdm(total=total, unit="probe", desc=f"min headway ({len(grid)} grid points)")

    def run(indices: Sequence[int], seeds: Sequence[int], round_no: int) -> None:
        tasks, cached, index_of = [], [], {}
        for k in indices:
            for s in seeds:
                over = overrides_at(grid[k])
                case = Case(case_id(over, s), over, s, {"headway_s": grid[k]})
                index_of[case.case_id] = k
                if case.case_id in stored:
                    cached.append((k, case, stored[case.case_id]))
                else:
                    run_dir = out / "runs" / case.case_id if (out is not None and keep_runs) else None
                    tasks.append(CaseTask(Path(scenario_path), case, run_dir, timeout_s))
        results = list(cached)
        if bar is not None and cached:
            bar.update(len(cached))  # probes a previous call with the same --out already ran
        for task, row in execute(tasks, workers=workers, dask_address=dask_address):
            if out is not None:
                write_row(out, task.case.case_id, row)
            results.append((index_of[task.case.case_id], task.case, row))
            if bar is not None:
                bar.update(1)
        for k, case, row in sorted(results, key=lambda x: (x[0], x[1].seed)):
            ok, reason = feasibility(row, criteria)
            delay = row.get(f"trips.arrival_delay_{delay_stat}_s")
            probes.append(
                Probe(
                    grid[k],
                    case.seed,
                    case.case_id,
                    ok,
                    reason,
                    round_no,
                    None if delay is None else float(delay),
                    row.get("n_trains"),
                    row.get("wall_s"),
                )
            )
            feasible_at[k] = feasible_at.get(k, True) and ok

    try:
        top = len(grid) - 1
        run(list(range(top, -1, -1)) if scan else [top, 0], [seed], 0)
        confirmed: set[int] = set()
        round_no = 0
        while True:
            b = _frontier(feasible_at)
            if b is None:
                break
            below = [k for k in feasible_at if k < b]
            a = max(below) if below else None
            if a is not None and b - a > 1:
                n = min(workers, b - a - 1)
                points = sorted({a + max(1, min(b - a - 1, round((b - a) * j / (n + 1)))) for j in range(1, n + 1)})
                round_no += 1
                run([k for k in points if k not in feasible_at], [seed], round_no)
                continue
            if confirm and b not in confirmed:  # converged (or b is lo): confirm the answer with other seeds
                confirmed.add(b)
                round_no += 1
                run([b], confirm, round_no)
                continue
            break
    finally:
        if bar is not None:
            bar.total = bar.n  # the search is over: what it ran is the whole
            bar.refresh()
            bar.close()

    b = _frontier(feasible_at)
    min_h = grid[b] if b is not None else None
    non_mono = tuple(
        sorted(grid[k] for k, ok in feasible_at.items() if ok and any(not feasible_at[j] for j in feasible_at if j > k))
    )
    per_dir: dict[str, float] = {}
    per_svc: dict[str, float] = {}
    if min_h is not None:
        per_dir, per_svc = service_rates(load_at(min_h))
    result = HeadwaySearchResult(
        min_headway_s=min_h,
        lo_s=float(lo_s),
        hi_s=float(hi_s),
        tol_s=float(tol_s),
        headway_paths=paths,
        criteria=criteria,
        probes=tuple(probes),
        non_monotone=non_mono,
        at_lower_bound=(b == 0),
        confirmed_seeds=tuple(confirm) if b is not None and b in confirmed else (),
        trains_per_hour=per_dir,
        trains_per_hour_by_service=per_svc,
    )
    if out is not None:
        output.write_json(out / "headway.json", result.to_dict())
        table = result.probe_table()
        output.write_csv(out / "probes.csv", table.to_dict("records"), list(table.columns))
    return result
