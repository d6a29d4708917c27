"""``units: auto`` chains a unit only over a turnback path no longer than ``TURNBACK_SEARCH_M`` in all.

The search reaches that far out to a turnaround and as far back from it, so a path out along the line and back could
be twice as long: Jena's Lobeda-West units ran 6.3 km out through single track to a stub and back, holding the
sections on the way against the trams of three lines. Such a departure starts a unit of its own.
"""

from __future__ import annotations

import networkx as nx

from railsim.engine.turnback import TURNBACK_SEARCH_M, Turnbacks


def _book(lengths_m: dict[str, float], path: list[str]) -> Turnbacks:
    book = Turnbacks.__new__(Turnbacks)
    book.graph = nx.DiGraph()
    for edge, length_m in lengths_m.items():
        book.graph.add_node(edge, length_m=length_m)
    book._paths = {(path[0], path[-1]): path}
    return book


def test_a_turnback_within_the_reach_in_all_chains() -> None:
    book = _book({"arr": 500.0, "out": 2000.0, "back": 2000.0, "dep": 1000.0}, ["arr", "out", "back", "dep"])
    assert 2000.0 + 2000.0 + 1000.0 <= TURNBACK_SEARCH_M
    assert book._short_path("arr", "dep")


def test_a_run_out_along_the_line_and_back_does_not() -> None:
    book = _book({"arr": 500.0, "out": 3100.0, "back": 3100.0, "dep": 100.0}, ["arr", "out", "back", "dep"])
    assert not book._short_path("arr", "dep")


def test_no_path_is_no_turnback() -> None:
    book = _book({"arr": 500.0, "dep": 100.0}, ["arr", "dep"])
    book._paths = {("arr", "dep"): None}
    assert not book._short_path("arr", "dep")
