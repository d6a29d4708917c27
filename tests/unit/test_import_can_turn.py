"""The timetable import chains a unit only where the engine will turn it (``railsim.timetable._Routes.can_turn``).

The engine makes no turning move from an edge back onto itself (``turnback.turnback_path``), and a unit departs where
it stands only where no trip runs through that platform and the plan leaves it to the unit. An import that wrote
such a pair into an explicit ``units:`` list would make the run refuse the scenario ("the world has no turnaround").
So the import does not chain a trip that begins on the edge the last one ends on: it chains fewer units, never one the
engine cannot turn.
"""

from __future__ import annotations

from railsim.timetable import _Routes


def _routes(ends: dict[tuple[str, ...], tuple[str, str]], turns: dict[tuple[str, str], bool]) -> _Routes:
    routes = _Routes.__new__(_Routes)
    routes._ends = dict(ends)  # (first edge, last edge) of the route through each chain of stations
    routes._turn = dict(turns)  # what the turnaround search answered for (arrival edge, departure edge)
    return routes


def test_no_unit_is_chained_from_an_edge_back_onto_itself() -> None:
    routes = _routes({("a", "b"): ("e1", "P"), ("b", "a"): ("P", "e2")}, {("P", "P"): True})
    assert not routes.can_turn(["a", "b"], ["b", "a"])


def test_a_turnaround_between_two_edges_still_chains() -> None:
    routes = _routes({("a", "b"): ("e1", "P"), ("b", "a"): ("-P", "e2")}, {("P", "-P"): True})
    assert routes.can_turn(["a", "b"], ["b", "a"])
