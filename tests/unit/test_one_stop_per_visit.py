"""Platforms of one station that overlap along a route are one stop (``trips.make_stops``).

OpenStreetMap maps some stations with a stop position and a platform on the same track (São Paulo's São Bento: two
200 m platforms overlapping by 146 m); a train stopping at both dwelt twice and the first stop was registered 54 m
short. One stop there: the one the whole train fits on that ends further along, else the longer. Platforms of a
station that follow each other without overlapping stay two stops; origin and destination keep the platform their
route begins and ends on.
"""

from __future__ import annotations

from types import SimpleNamespace

from network.topology import RouteStop
from railsim.engine.trips import make_stops


def _route(*platforms: tuple[str, float, float]) -> SimpleNamespace:
    """A straight route over one 2 km edge with these platforms ``(station, start, end)`` in route chainage."""
    stops = [RouteStop(st, f"{st}_{k}", "e", a, b, a, b) for k, (st, a, b) in enumerate(platforms)]
    return SimpleNamespace(stops=stops, edge_start_m=[0.0], internal_start_m=[], length_m=2000.0)


def _served(route: SimpleNamespace, length_m: float = 140.0) -> list[tuple[str, str]]:
    return [(s.station_id, s.stop_id) for s in make_stops(route, length_m, (), 20.0, {}, "a", "c")]


def test_two_overlapping_platforms_are_one_stop_at_the_one_ending_further() -> None:
    route = _route(("a", 0, 200), ("b", 570, 770), ("b", 625, 825), ("c", 1700, 1900))
    assert _served(route) == [("a", "a_0"), ("b", "b_2"), ("c", "c_3")]


def test_a_platform_the_train_fits_on_wins_over_an_overlapping_one_it_does_not() -> None:
    route = _route(("a", 0, 200), ("b", 500, 700), ("b", 650, 720), ("c", 1700, 1900))
    assert _served(route) == [("a", "a_0"), ("b", "b_1"), ("c", "c_3")]
    too_short = _route(("a", 0, 200), ("b", 500, 600), ("b", 560, 690), ("c", 1700, 1900))
    assert _served(too_short) == [("a", "a_0"), ("b", "b_2"), ("c", "c_3")]  # neither fits: the longer


def test_platforms_that_follow_each_other_stay_two_stops_and_the_destination_keeps_its_platform() -> None:
    route = _route(("a", 0, 200), ("b", 500, 530), ("b", 560, 590), ("d", 900, 1100))
    route.stops.append(RouteStop("c", "c_4", "e", 1700, 1900, 1700, 1900))
    route.stops.append(RouteStop("c", "c_5", "e", 1750, 1950, 1750, 1950))
    served = _served(route, 27.0)
    assert served == [("a", "a_0"), ("b", "b_1"), ("b", "b_2"), ("d", "d_3"), ("c", "c_4")]
