"""``RouteView.map_body_memo`` gives :meth:`RouteView.map_body`'s answer, bit for bit (railsim/engine/routeview.py).

The memo reuses a pair's last frame change while the reported front and rear stay on the edges they were on. Held
here to ``map_body`` (the long way: both edges looked up, the frame change found for them) on random track: edges of
random length (some of length 0), routes that are random walks over them — so they merge, diverge, and some pass
an edge twice — and, per pair of routes, a train reporting step after step (fronts moving on by a few metres, now
and then a jump, a front or a rear exactly on an edge start, off either end of the route, a changed length, an
observer on another pass), in turn with a second train on another route under the same memory key. More than half
the answers come from memory (about 60 %).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from railsim.engine.routeview import RouteView

N_EDGES = 20


def _view(route_id: str, edges: tuple[str, ...], starts: tuple[float, ...], length_m: float) -> RouteView:
    route = SimpleNamespace(
        id=route_id, edges=edges, edge_start_m=starts, speed_limits=(), gradients=(), length_m=length_m
    )
    return RouteView(route)


def _views(rng: np.random.Generator) -> list[RouteView]:
    lengths = rng.uniform(30.0, 300.0, N_EDGES)
    lengths[rng.random(N_EDGES) < 0.1] = 0.0  # an edge of no length: two edges start at one chainage
    succ = {e: [int(x) for x in rng.choice(N_EDGES, size=2, replace=False)] for e in range(N_EDGES)}
    views = []
    for r in range(8):
        e = int(rng.integers(N_EDGES))
        walk = [e]
        for _ in range(int(rng.integers(1, 14))):
            e = succ[e][int(rng.integers(2))]
            walk.append(e)
        starts = np.concatenate([[0.0], np.cumsum(lengths[walk])[:-1]])
        edges = tuple(f"e{x}" for x in walk)
        views.append(_view(f"r{r}", edges, tuple(float(x) for x in starts), float(np.sum(lengths[walk]))))
    return views


def _reports(rng: np.random.Generator, other: RouteView, n: int) -> list[tuple[float, float]]:
    """``(front, length)`` step after step: mostly a few metres on, sometimes exactly at an edge start (front or
    rear), a jump, off the route's ends, a changed length."""
    starts = other.edge_start_m
    length_m = float(rng.uniform(20.0, 500.0))
    front_m = float(rng.uniform(-50.0, other.length_m + 50.0))
    out = []
    for _ in range(n):
        pick = rng.random()
        if pick < 0.7:
            front_m += float(rng.uniform(0.0, 25.0))
        elif pick < 0.78:
            front_m = starts[int(rng.integers(len(starts)))]
        elif pick < 0.86:
            front_m = starts[int(rng.integers(len(starts)))] + length_m  # the rear on an edge start
        elif pick < 0.92:
            front_m = float(rng.uniform(-600.0, other.length_m + 600.0))
        elif pick < 0.96:
            length_m = float(rng.uniform(20.0, 500.0))
        else:
            front_m -= float(rng.uniform(0.0, 40.0))
        out.append((front_m, length_m))
    return out


@pytest.mark.parametrize("seed", range(8))
def test_memo_is_map_body(seed: int, monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(seed)
    looked_up = [0]
    edge_near = RouteView.edge_near

    def counted(view: RouteView, chainage_m: float, hint: int) -> int:
        looked_up[0] += 1
        return edge_near(view, chainage_m, hint)

    monkeypatch.setattr(RouteView, "edge_near", counted)
    calls = hits = placed = twice = 0
    for _ in range(6):
        views = _views(rng)
        memory: dict = {}  # one for every observer: a key is reused by observers on other routes too
        for here in views:
            for other in views:
                # one key for two trains reporting in turn (a wrong memory must not be used): ``other`` and a decoy
                decoy = views[int(rng.integers(len(views)))]
                key = ("obs", int(rng.integers(3)))
                from_i = int(rng.integers(-1, len(here.edges)))
                mine, theirs = _reports(rng, other, 60), _reports(rng, decoy, 60)
                for k in range(60):
                    if rng.random() < 0.05:  # the observer moved on to another edge (a pass, on a twice route)
                        from_i = int(rng.integers(-1, len(here.edges)))
                    if rng.random() < 0.1:
                        other, decoy, mine, theirs = decoy, other, theirs, mine
                    front_m, length_m = mine[k]
                    hint = int(rng.integers(-2, len(other.edges) + 2))
                    long_way = here.map_body(other, front_m, length_m, hint, from_i)
                    before = looked_up[0]
                    memo = here.map_body_memo(memory, key, other, front_m, length_m, hint, from_i)
                    assert repr(memo) == repr(long_way), (here.route.id, other.route.id, front_m, length_m, from_i)
                    calls += 1
                    hits += looked_up[0] == before
                    placed += memo is not None
                    twice += not here.simple and memo is not None
    assert hits > calls // 2, "the memory is hardly ever used"
    assert placed > calls // 5 and twice > 50, "too few bodies on the observer's route to test anything"


def test_memo_follows_a_body_over_a_merge_and_a_diverge() -> None:
    """A train on a branch drives onto the main line (rear clamped to the switch until its tail is on), then off
    onto another branch (the frame change taken under its tail): every step the memo answers as map_body."""
    main = _view("main", ("m1", "m2", "m3", "m4"), (0.0, 500.0, 1000.0, 1500.0), 2000.0)
    branch = _view("branch", ("b1", "m2", "m3", "b4"), (0.0, 300.0, 800.0, 1300.0), 1800.0)
    seen = set()
    memory: dict = {}
    for k in range(400):
        front_m = 100.0 + 4.0 * k
        long_way = main.map_body(branch, front_m, 120.0)
        assert repr(main.map_body_memo(memory, "pair", branch, front_m, 120.0)) == repr(long_way)
        seen.add("none" if long_way is None else "clamped" if long_way[1] == 500.0 else "on")
    assert seen == {"none", "clamped", "on"}


def test_edge_span_is_where_edge_at_answers() -> None:
    view = _view("r", ("a", "b", "c", "d"), (0.0, 100.0, 100.0, 250.0), 400.0)
    for x in (-1e9, -0.0, 0.0, 99.999, 100.0, 249.999, 250.0, 1e9):
        i = view.edge_at(x)
        lo, hi = view.edge_span(i)
        assert lo <= x < hi
    assert view.edge_span(0) == (-np.inf, 100.0) and view.edge_span(3) == (250.0, np.inf)
