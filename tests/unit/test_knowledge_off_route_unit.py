"""A train ahead whose last report has it off our track still separates us (railsim/engine/knowledge.py).

Here: the tests of it that start no process; the others are in ``tests/sumo/test_knowledge_off_route.py``.
"""

from __future__ import annotations

from types import SimpleNamespace

from railsim.engine.routeview import RouteView


def _view(route_id: str, edges: list[str], starts: list[float]) -> RouteView:
    route = SimpleNamespace(id=route_id, edges=edges, edge_start_m=starts, speed_limits=[], gradients=[], length_m=0.0)
    return RouteView(route)


def test_join_point_is_where_the_other_route_first_runs_on_ours() -> None:
    branch = _view("branch", ["b1", "b2", "m3", "m4"], [0.0, 500.0, 900.0, 1400.0])
    main = _view("main", ["m1", "m2", "m3", "m4"], [0.0, 1000.0, 2000.0, 2500.0])
    assert branch.join_m(main, 100.0) == 2000.0  # on the branch: it joins main where m3 starts in main's frame
    assert branch.join_m(main, 950.0) == 2000.0  # on m3 already: that edge's start
    assert branch.join_m(main, 1500.0) == 2500.0
    spur = _view("spur", ["s1", "s2"], [0.0, 300.0])
    assert spur.join_m(main, 0.0) is None  # never on main's track
