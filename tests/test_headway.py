"""Minimum feasible headway search (railsim.studies.headway): the feasibility rule on rows, the conservative frontier, and a
real search on the small corridor checked against an independent scan of every grid headway run directly."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from helpers import ROOT, run_railsim

from railsim.errors import ConfigError
from railsim.studies import headway, sweep

BASE = ROOT / "scenarios" / "sweeps" / "corridor_small.yaml"
PATHS = ("services[0].departures.headway_s", "services[1].departures.headway_s")

OK_ROW = {
    "status": "ok",
    "collisions": 0,
    "sumo_collisions": 0,
    "switch_violations": 0,
    "n_stops_missed": 0,
    "n_stops_served": 36,
    "n_stops_scheduled": 36,
    "n_arrived": 12,
    "n_trains": 12,
    "trips.arrival_delay_max_s": 100.0,
    "trips.arrival_delay_p95_s": 50.0,
}


@pytest.mark.parametrize(
    ("change", "stat", "feasible", "words"),
    [
        ({}, "max", True, "ok"),
        ({"trips.arrival_delay_max_s": 121.0}, "max", False, "max delay 121.0 s > 120 s"),
        ({"trips.arrival_delay_max_s": 121.0}, "p95", True, "ok"),
        ({"collisions": 1}, "max", False, "1 collision(s)"),
        ({"sumo_collisions": 2}, "max", False, "2 collision(s)"),
        ({"switch_violations": 1}, "max", False, "1 switch violation(s)"),
        ({"n_stops_missed": 1, "n_stops_served": 35}, "max", False, "stops served 35/36 (missed 1)"),
        ({"n_arrived": 11}, "max", False, "arrived 11/12"),
        ({"trips.arrival_delay_max_s": None}, "max", False, "no arrival delay"),
        ({"status": "failed", "error": "boom"}, "max", False, "failed: boom"),
    ],
)
def test_feasibility_names_every_violation(change: dict, stat: str, feasible: bool, words: str) -> None:
    ok, reason = headway.feasibility({**OK_ROW, **change}, headway.FeasibilityCriteria(120.0, stat))
    assert ok is feasible and words in reason


def test_frontier_is_conservative_under_non_monotone_feasibility() -> None:
    assert headway._frontier({0: False, 4: True, 8: True}) == 4
    assert headway._frontier({0: True, 3: False, 5: True, 8: True}) == 5  # feasible at 0 does not count
    assert headway._frontier({0: True, 8: False}) is None
    assert headway._frontier({0: True, 8: True}) == 0
    assert headway._grid(60, 100, 15) == [60, 75, 90, 100]


def test_planned_probes_is_bisection_rounds_plus_confirmations() -> None:
    # 37 grid points (60..240 s every 5 s), one worker: hi, lo, then ceil(log2 36) = 6 midpoints, 1 confirmation
    assert headway.planned_probes(37, 1, False, 1) == 2 + 6 + 1
    # two workers: ceil(log3 36) = 4 rounds of 2 points
    assert headway.planned_probes(37, 2, False, 1) == 2 + 8 + 1
    assert headway.planned_probes(37, 1, True, 2) == 37 + 2  # scan: every point, then the confirmations
    assert headway.planned_probes(4, 8, False, 0) == 4  # never more than the grid


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"lo_s": 100, "hi_s": 60}, "hi_s"),
        ({"lo_s": -1, "hi_s": 60}, "lo_s"),
        ({"lo_s": 30, "hi_s": 60, "tol_s": 0}, "tol_s"),
        ({"lo_s": 30, "hi_s": 60, "delay_stat": "p50"}, "delay_stat"),
    ],
)
def test_bad_search_parameters(kwargs: dict, field: str) -> None:
    with pytest.raises(ConfigError) as info:
        headway.find_min_headway(BASE, PATHS, **kwargs)
    assert info.value.field == field


def test_cli_bad_path_exit_2(tmp_path: Path) -> None:
    res = run_railsim(
        ["min-headway", str(BASE), "--path", "services[4].departures.headway_s", "--lo", "30", "--hi", "60"],
        timeout=120,
    )
    assert res.returncode == 2
    assert res.stderr.strip() == (
        f"railsim: error: {BASE}: headway 30 s: override: services[4].departures.headway_s: "
        "index 4 out of range (services has 2 items)"
    )


@pytest.mark.sumo
@pytest.mark.slow
def test_search_matches_an_independent_scan_of_every_grid_headway(tmp_path: Path) -> None:
    lo, hi, tol, max_delay = 30.0, 120.0, 15.0, 60.0
    result = headway.find_min_headway(
        BASE, PATHS, lo, hi, tol_s=tol, max_delay_s=max_delay, workers=2, out_dir=tmp_path / "search", progress=False
    )
    criteria = headway.FeasibilityCriteria(max_delay, "max")
    # independent scan: every grid headway run directly (same seed), feasibility judged on the rows
    grid = [lo + k * tol for k in range(int((hi - lo) / tol) + 1)]
    tasks = [
        sweep.CaseTask(BASE, sweep.Case(sweep.case_id({p: h for p in PATHS}, 3), {p: h for p in PATHS}, 3))
        for h in grid
    ]
    scan = {
        task.case.overrides[PATHS[0]]: headway.feasibility(row, criteria)[0]
        for task, row in sweep.execute(tasks, workers=2)
    }
    expected = min(h for h in grid if all(scan[g] for g in grid if g >= h))
    assert not scan[lo] and scan[hi]  # the range brackets the answer
    assert result.min_headway_s == expected and not result.at_lower_bound
    # every search probe agrees with the direct run of the same headway and seed (determinism)
    for p in result.probes:
        if p.seed == 3:
            assert p.feasible == scan[p.headway_s]
    assert {p.headway_s for p in result.probes} < set(grid)  # the search probed fewer headways than the scan
    assert len(result.probes) <= headway.planned_probes(len(grid), 2, False, 1)  # the progress bar's total
    # the answer was confirmed with another seed, and the probe just below it was infeasible
    assert result.confirmed_seeds == (4,)
    assert any(p.headway_s == expected and p.seed == 4 and p.feasible for p in result.probes)
    assert not scan[expected - tol]
    # trains/h at the answer: departures 0, h, ..., <= 600 s, so (n - 1)·3600 / ((n - 1)·h) = 3600 / h per direction
    assert result.trains_per_hour == {"down": pytest.approx(3600 / expected), "up": pytest.approx(3600 / expected)}
    saved = json.loads((tmp_path / "search" / "headway.json").read_text(encoding="utf-8"))
    assert saved["min_headway_s"] == expected and len(saved["probes"]) == len(result.probes)
    assert (tmp_path / "search" / "probes.csv").read_text(encoding="utf-8").count("\n") == len(result.probes) + 1
    # a second call with the same folder reuses every stored probe (no new rows)
    n_rows = len(list((tmp_path / "search" / "rows").glob("*.json")))
    again = headway.find_min_headway(
        BASE, PATHS, lo, hi, tol_s=tol, max_delay_s=max_delay, workers=2, out_dir=tmp_path / "search", progress=False
    )
    assert again.min_headway_s == expected
    assert len(list((tmp_path / "search" / "rows").glob("*.json"))) == n_rows
    assert "| yes |" in result.to_markdown() and math.isfinite(result.probes[0].wall_s)


@pytest.mark.sumo
def test_cli_reports_lower_bound_and_no_feasible_range(tmp_path: Path) -> None:
    # 150-180 s is easily feasible on the corridor: the answer is the range's lower end
    res = run_railsim(
        [
            "min-headway",
            str(BASE),
            "--path",
            PATHS[0],
            "--path",
            PATHS[1],
            "--lo",
            "150",
            "--hi",
            "180",
            "--tol",
            "30",
            "--max-delay",
            "60",
            "--confirm-seed",
            "9",
            "--out",
            str(tmp_path / "a"),
        ],
        timeout=300,
    )
    assert res.returncode == 0, res.stderr
    assert "**150 s** (the range's lower end" in res.stdout and "confirmed with seeds 9" in res.stdout
    # 20-30 s with a 10 s delay limit is not
    res = run_railsim(
        ["min-headway", str(BASE), "--path", PATHS[0], "--lo", "20", "--hi", "30", "--tol", "10", "--max-delay", "10"],
        timeout=300,
    )
    assert res.returncode == 1, res.stderr
    assert "No feasible headway in the range" in res.stdout
