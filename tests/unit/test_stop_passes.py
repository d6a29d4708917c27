"""Which stops SUMO can be told now on a route that passes a platform's edge twice (railsim.engine.stop_passes).

SUMO matches a stop handed over by TraCI to the first pass of its edge at or after the train's route index,
whatever stops it holds already. Jena's Winzerla turnback path started on the departure platform's edge and came
back onto it 61 edges later: the origin stop, handed over at once, went on the pass the unit stood on; at
Lobeda-West the stops after the origin went on a first pass of their edges 2 km before it.
"""

from __future__ import annotations

from types import SimpleNamespace

from railsim.engine.stop_passes import stops_now
from railsim.engine.trips import TripStop, stop_edge_index

RING = ["q0", "q1", "q2", "q3", "q0", "q1", "q2"]


def test_a_route_through_each_edge_once_hands_every_stop_over_at_once() -> None:
    assert stops_now(["a", "b", "c"], ["b", "c"], [1, 2], 0) == (2, None)
    assert stops_now(["a", "b", "c"], ["b", "c"], [None, None], 0) == (2, None)


def test_a_stop_meant_for_the_second_pass_waits_with_the_stops_after_it() -> None:
    # a stop on q1's first pass, then one on its second: the second (and any after it) waits until past index 1
    assert stops_now(RING, ["q1", "q1", "q2"], [1, 5, 6], 0) == (1, 1)
    # a stop on q2, then one on q0's second pass: SUMO searches from the train, not from the stop before, so the
    # q0 stop would go on index 0; it waits until the train is past it
    assert stops_now(RING, ["q2", "q0"], [2, 4], 0) == (1, 0)
    assert stops_now(RING, ["q2", "q0"], [2, 4], 1) == (2, None)
    # the first stop meant for q0's second pass while the train is on q0: nothing can be handed over yet
    assert stops_now(RING, ["q0", "q2"], [4, 6], 0) == (0, 0)
    assert stops_now(RING, ["q0", "q2"], [4, 6], 1) == (1, 2)  # q2's first pass from index 1 is index 2, not 6


def test_the_lobeda_west_case_hands_the_origin_over_first_and_the_rest_later() -> None:
    # on the way to its origin platform (index 5), the unit passes the edge of the next platform (index 1) first
    route = ["a", "n", "x", "y", "z", "p", "q", "n", "m"]
    assert stops_now(route, ["p", "n", "m"], [5, 7, 8], 0) == (1, 1)
    assert stops_now(route, ["n", "m"], [7, 8], 2) == (2, None)


def test_the_winzerla_case_waits_until_the_train_has_left_the_platform_edge() -> None:
    route = ["p", "x", "y", "p", "z"]
    assert stops_now(route, ["p", "z"], [3, 4], 0) == (0, 0)  # standing on p: the origin stop is for p's 2nd pass
    assert stops_now(route, ["p", "z"], [3, 4], 1) == (2, None)  # off p: both stops go on their passes


def test_a_stop_whose_pass_is_unknown_or_not_its_edge_is_handed_over_as_before() -> None:
    route = ["p", "x", "p"]
    assert stops_now(route, ["p"], [None], 0) == (1, None)
    assert stops_now(route, ["p"], [1], 0) == (1, None)  # index 1 is not p: SUMO's own choice stands


def test_the_pass_of_a_stop_is_the_edge_that_holds_its_mark() -> None:
    route = SimpleNamespace(edges=("p", "x", "p", "z"), edge_start_m=(0.0, 100.0, 300.0, 400.0))

    def stop(mark_m: float) -> TripStop:
        return TripStop("s", "s", mark_m, mark_m - 10.0, mark_m, 20.0)

    assert stop_edge_index(route, stop(50.0)) == 0
    assert stop_edge_index(route, stop(350.0)) == 2
    assert stop_edge_index(route, stop(400.0)) == 2  # a mark on the end of an edge: the platform's own edge
    assert stop_edge_index(route, stop(450.0)) == 3
