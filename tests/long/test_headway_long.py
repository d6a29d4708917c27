"""Minimum feasible headway search (railsim.studies.headway): the feasibility rule on rows, the conservative frontier, and a
real search on the small corridor checked against an independent scan of every grid headway run directly.

Here: the tests of it that take minutes; the others are in ``tests/unit/test_headway.py``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from railsim.studies import headway, sweep
from tests.unit.test_headway import BASE, PATHS


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
