"""When does a unit depart from the platform it arrived at (``turnback._same_platform``)?

Only where its next trip leaves from the very stop it arrived at, on the same edge (it faces the way it leaves),
and only where no trip runs through that platform: a tram that turns round a city block and "ends" at a platform
other lines pass (Helsinki's line 5 at Rautatieasema) must not lay over there — standing for its turnback it held
up every tram behind it (Helsinki 07:00-09:00 every 300 s: 396 of 480 arrived, 64 never inserted).
"""

from __future__ import annotations

import logging
from types import SimpleNamespace

import networkx as nx
import pytest

from railsim.engine.turnback import Turnbacks, _same_platform


def _trip(edges: tuple[str, ...], origin: str, destination: str) -> SimpleNamespace:
    stops = (
        SimpleNamespace(stop_id=origin, is_origin=True, is_destination=False),
        SimpleNamespace(stop_id=destination, is_origin=False, is_destination=True),
    )
    return SimpleNamespace(trip=SimpleNamespace(route=SimpleNamespace(edges=edges), stops=stops))


ARRIVES = _trip(("a", "b", "P"), "s_a", "s_p")  # ends on the loop's platform edge P at stop s_p


def test_a_unit_departs_where_it_stands_from_the_stop_it_arrived_at() -> None:
    assert _same_platform(ARRIVES, _trip(("P", "c", "a2"), "s_p", "s_a2"), set())  # type: ignore[arg-type]


def test_not_from_another_stop_or_another_edge() -> None:
    assert not _same_platform(ARRIVES, _trip(("P", "c"), "s_other", "s_c"), set())  # type: ignore[arg-type]
    assert not _same_platform(ARRIVES, _trip(("-P", "c"), "s_p", "s_c"), set())  # type: ignore[arg-type]


def test_not_on_a_platform_another_trip_runs_through() -> None:
    assert not _same_platform(ARRIVES, _trip(("P", "c", "a2"), "s_p", "s_a2"), {"x", "P"})  # type: ignore[arg-type]


def _planned(
    tid: str, edges: tuple[str, ...], origin: str, destination: str, depart_s: float, arrive_s: float
) -> SimpleNamespace:
    tr = _trip(edges, origin, destination)
    tr.train_id = tid
    tr.trip.depart_s = depart_s
    tr.trip.destination = SimpleNamespace(station_id=destination)
    tr.trip.planned_arrival_s = {destination: arrive_s}
    return tr


def _free(*others: SimpleNamespace) -> bool:
    """Whether ``in`` (arriving at P at 1,000 s) may lay over at P until ``out`` leaves it at 1,400 s."""
    pred = _planned("in", ("a", "b", "P"), "s_a", "s_p", 0.0, 1000.0)
    succ = _planned("out", ("P", "c", "a2"), "s_p", "s_a2", 1400.0, 2000.0)
    book = Turnbacks.__new__(Turnbacks)
    book.fleet = SimpleNamespace(trains={t.train_id: t for t in (pred, succ, *others)})  # type: ignore[assignment]
    book._through, book._platform_times = set(), None
    return book._platform_free(pred, succ)  # type: ignore[arg-type]


def test_a_unit_lays_over_at_its_platform_only_while_no_other_trip_arrives_or_leaves_there() -> None:
    """Potsdam's Platz der Einheit: four lines end at one loop platform; units laying over there deadlocked."""
    assert _free()
    assert not _free(_planned("other_in", ("x", "P"), "s_x", "s_p", 400.0, 1200.0))  # arrives while it stands
    assert _free(_planned("later_in", ("x", "P"), "s_x", "s_p", 900.0, 1500.0))  # arrives once it has left
    assert not _free(_planned("other_out", ("P", "y"), "s_p", "s_y", 1300.0, 1900.0))  # leaves from there meanwhile
    assert _free(_planned("elsewhere", ("x", "Q"), "s_x", "s_q", 400.0, 1200.0))  # another platform


def test_the_warning_names_through_traffic_where_a_unit_would_lay_over_on_the_trunk(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """Jena's Winzerla: line 2 ends and starts on the platform edge lines 1, 3 and 34 run through."""
    arrive = _planned("in", ("a", "b", "P"), "s_a", "s_p", 0.0, 1000.0)
    leave = _planned("out", ("P", "c", "a2"), "s_p", "s_a2", 1400.0, 2000.0)
    for tr, origin in ((arrive, "a_st"), (leave, "p_st")):
        tr.trip.origin = SimpleNamespace(station_id=origin)
    arrive.trip.destination = SimpleNamespace(station_id="p_st")
    book = Turnbacks.__new__(Turnbacks)
    book.graph = nx.DiGraph()
    book.graph.add_nodes_from(("a", "b", "P", "c", "a2"), length_m=100.0)
    book._through, book._paths = {"P"}, {}
    with caplog.at_level(logging.WARNING):
        book._warn_unturnable([arrive, leave])  # type: ignore[list-item]
    assert "no unit can turn at p_st: units arrive on the track they leave by (P)" in caplog.text
