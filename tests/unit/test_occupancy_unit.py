"""Ground-truth geometry at junctions: who is ahead of whom, in whose frame (railsim.engine.occupancy/routeview).

Here: the tests of it that start no process; the others are in ``tests/sumo/test_occupancy.py``.
"""

from __future__ import annotations

from railsim.engine.routeview import RouteView


def test_edge_near_is_edge_at_whatever_the_hint() -> None:
    """The forward-only edge pointer (RouteView.edge_near) answers exactly what the search does, for a good,
    a neighbouring or a wrong hint, before the route, on every edge boundary, inside edges, past the end and
    with zero-length edges."""
    from types import SimpleNamespace

    starts = (0.0, 100.0, 100.0, 250.5, 251.0, 900.0)
    route = SimpleNamespace(
        id="r", edges=tuple(f"e{i}" for i in range(len(starts))), edge_start_m=starts, speed_limits=(), gradients=()
    )
    view = RouteView(route)
    points = [-5.0, *starts, *(x + 1e-9 for x in starts), *(x - 1e-9 for x in starts), 50.0, 175.0, 600.0, 1e6]
    for x in points:
        for hint in range(-2, len(starts) + 2):
            assert view.edge_near(x, hint) == view.edge_at(x), (x, hint)


def test_remembered_limit_windows_are_the_scan() -> None:
    """limits_ahead remembers its answer per window; asked in any order, it is the plain scan's answer."""
    import bisect
    import random
    from types import SimpleNamespace

    limits = [(100.0, 400.0, 10.0), (350.0, 500.0, 15.0), (900.0, 1200.0, 30.0), (900.0, 950.0, 12.0)]
    limits += [(2000.0, 2300.0, 14.0), (2300.0, 2600.0, 13.0)]
    route = SimpleNamespace(id="r", edges=("e0",), edge_start_m=(0.0,), speed_limits=limits, gradients=())
    view = RouteView(route)
    rng = random.Random(3)
    for _ in range(3000):
        front = rng.uniform(-500.0, 3500.0)
        lo, hi = front - rng.choice([0.0, 120.0, 400.0]), front + rng.choice([0.0, 300.0, 5000.0])
        i = max(bisect.bisect_right(view.limit_starts, lo) - 1, 0)
        assert view.limits_ahead(lo, hi) == view._scan(i, lo, hi), (lo, hi)


def test_a_train_on_the_first_pass_of_an_edge_the_route_passes_twice_is_ahead_on_that_pass() -> None:
    """A route that passes edge ``e`` twice (out along the line and back, or a loop): a train standing 20 m into
    ``e`` is 20 m past the start of the observer's *next* pass of ``e``, not of its last one. Mapped onto the last
    pass, a tram 20 m ahead read as 320 m ahead, ran into it, and only SUMO saw the collisions (Jena)."""
    from types import SimpleNamespace

    from railsim.engine.occupancy import Occupancy

    def view(rid: str, edges: tuple[str, ...], starts: tuple[float, ...], length_m: float) -> RouteView:
        route = SimpleNamespace(
            id=rid, edges=edges, edge_start_m=starts, length_m=length_m, speed_limits=(), gradients=()
        )
        return RouteView(route)

    loop = view("loop", ("p", "e", "q", "r", "e", "s"), (0.0, 100.0, 200.0, 300.0, 400.0, 500.0), 600.0)
    short = view("short", ("e", "q"), (0.0, 100.0), 200.0)
    occ = Occupancy()
    # the observer 50 m into p (before its first pass of e), the other train's front 20 m into e, 10 m long
    occ.update_columns(["obs", "other"], [loop, short], [50.0, 20.0], [10.0, 10.0], [0, 0])
    a = occ.ahead("obs")
    assert a is not None and a.train_id == "other"
    assert (a.front_m, a.rear_m) == (120.0, 110.0)
    assert occ.ahead_all()[0] == a
    # past its first pass (on r), the same train on e is on the observer's second pass
    occ.update_columns(["obs", "other"], [loop, short], [350.0, 20.0], [10.0, 10.0], [3, 0])
    a = occ.ahead("obs")
    assert a is not None and (a.front_m, a.rear_m) == (420.0, 410.0)
    # what a follower knows from the train's reports maps the same way (RouteView.map_body, knowledge)
    assert loop.map_body(short, 20.0, 10.0, 0, 0) == (120.0, 110.0)
    assert loop.map_body(short, 20.0, 10.0, 0, 3) == (420.0, 410.0)
    assert loop.map_body(short, 20.0, 10.0, 0) == (420.0, 410.0)  # no observer pass given: the last pass
