"""A station whose platforms a route runs along one after the other is served once (``trips.make_stops``).

OpenStreetMap maps some stations with a stop position and a platform on the same track (São Paulo's São Bento: two
200 m platforms 54 m apart along the northbound track); a train stopping at both dwelt twice and the first stop
was registered 54 m short. One stop per visit: the last platform of the run the train fits on, else the longest;
origin and destination keep the platform their route begins and ends on.
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


def test_two_platforms_in_a_row_are_one_stop_at_the_last_that_fits() -> None:
    route = _route(("a", 0, 200), ("b", 570, 770), ("b", 625, 825), ("c", 1700, 1900))
    assert _served(route) == [("a", "a_0"), ("b", "b_2"), ("c", "c_3")]


def test_a_platform_the_train_fits_on_wins_over_a_later_one_it_does_not() -> None:
    route = _route(("a", 0, 200), ("b", 500, 700), ("b", 720, 800), ("c", 1700, 1900))
    assert _served(route) == [("a", "a_0"), ("b", "b_1"), ("c", "c_3")]
    too_short = _route(("a", 0, 200), ("b", 500, 600), ("b", 620, 700), ("c", 1700, 1900))
    assert _served(too_short) == [("a", "a_0"), ("b", "b_1"), ("c", "c_3")]  # neither fits: the longer


def test_a_station_passed_twice_apart_is_two_stops_and_the_destination_keeps_its_platform() -> None:
    route = _route(("a", 0, 200), ("b", 500, 700), ("d", 900, 1100), ("b", 1200, 1400))
    route.stops.append(RouteStop("c", "c_4", "e", 1700, 1900, 1700, 1900))
    route.stops.append(RouteStop("c", "c_5", "e", 1750, 1950, 1750, 1950))
    served = _served(route)
    assert [s for s, _ in served] == ["a", "b", "d", "b", "c"]
    assert served[-1] == ("c", "c_4")  # the destination: the first platform of it, where its route ends
