"""Minimum feasible headway search (railsim.studies.headway): the feasibility rule on rows, the conservative frontier, and a
real search on the small corridor checked against an independent scan of every grid headway run directly."""

from __future__ import annotations

import pytest

from railsim.errors import ConfigError
from railsim.studies import headway
from tests.helpers import ROOT

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
