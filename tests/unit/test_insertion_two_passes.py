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
