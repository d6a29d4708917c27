"""A departure is compared with a train whose route runs over the departure spot twice on the pass where that train
stands (``insertion._nearest_pass``).

A unit that turned back has its turnback path prepended to its next trip, so its route can hold the departure
platform at two chainages. Mapped onto the last pass, a departure at the spot where the unit stood came out
thousands of metres away from it and was put on inside it (Jena, Lobeda-West: SUMO refused the insertion and the run
stalled). The mapping now keeps the pass closest to the other train's body.
"""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from railsim.engine.insertion import Dispatcher
from railsim.engine.routeview import RouteView


def _view(route_id: str, edges: tuple[str, ...], starts: tuple[float, ...], length_m: float) -> RouteView:
    route = SimpleNamespace(
        id=route_id, edges=edges, edge_start_m=starts, speed_limits=(), gradients=(), length_m=length_m
    )
    return RouteView(route)


def _train(view: RouteView, front_m: float, length_m: float = 27.0) -> SimpleNamespace:
    return SimpleNamespace(
        view=view,
        front_m=front_m,
        edge_i=view.edge_at(front_m),
        trip=SimpleNamespace(vehicle=SimpleNamespace(length_m=length_m)),
    )


DEPARTING = _view("trip", ("s", "x", "y"), (0.0, 100.0, 200.0), 300.0)
# the turned unit: out over s and x, round a loop, back over s again 5 km on
TURNED = _view("unit", ("s", "x", "loop", "s", "w"), (0.0, 100.0, 200.0, 5000.0, 5100.0), 5200.0)


def test_the_departure_is_compared_on_the_pass_where_the_unit_stands() -> None:
    assert not TURNED.simple
    unit = _train(TURNED, 64.7)
    frame = Dispatcher._in_one_frame(_train(DEPARTING, 0.0), 65.45, 27.0, unit)  # type: ignore[arg-type]
    assert frame is not None
    front_m, rear_m, other_front_m, other_rear_m, _ = frame
    assert front_m == pytest.approx(65.45) and rear_m == pytest.approx(38.45)
    assert rear_m < other_front_m and front_m > other_rear_m  # the bodies overlap: the spot is not free
    assert TURNED.map_body(DEPARTING, 65.45, 27.0)[0] == pytest.approx(5065.45)  # the last pass: far away


def test_a_unit_on_the_later_pass_is_compared_there() -> None:
    unit = _train(TURNED, 5070.0)
    frame = Dispatcher._in_one_frame(_train(DEPARTING, 0.0), 40.0, 27.0, unit)  # type: ignore[arg-type]
    assert frame is not None and frame[0] == pytest.approx(5040.0)  # right behind it on its own pass


def test_a_train_on_no_edge_of_the_other_route_is_placed_on_the_nearest_pass_of_its_own() -> None:
    # the departure stands on the edge "tail", which the other train's route does not use; the other train stands on
    # "s", which the departing route passes twice (100 m and 5,000 m on): its body is placed on the pass next to the
    # departure, 35 m ahead of it, not on the last one
    departing_route = _view("trip", ("tail", "s", "loop", "s", "w"), (0.0, 100.0, 200.0, 5000.0, 5100.0), 5200.0)
    other = _train(_view("other", ("s", "z"), (0.0, 100.0), 200.0), 50.0)
    frame = Dispatcher._in_one_frame(_train(departing_route, 65.0), 65.0, 27.0, other)  # type: ignore[arg-type]
    assert frame is not None
    front_m, rear_m, other_front_m, other_rear_m, to_other_m = frame
    assert (front_m, rear_m) == pytest.approx((65.0, 38.0))
    assert (other_front_m, other_rear_m) == pytest.approx((150.0, 123.0))
    assert to_other_m == pytest.approx(50.0 - 150.0)
    assert departing_route.map_body(other.view, 50.0, 27.0)[0] == pytest.approx(5050.0)  # the last pass: far away
