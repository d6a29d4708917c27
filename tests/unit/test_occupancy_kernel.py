"""The compiled occupancy pass (railsim/engine/occupancy_kernel.py) gives its interpreted form's answers, bit for bit.

The occupancy index, the train-ahead search and the facing-train search run as compiled passes over per-train
arrays; their interpreted form (the module loaded with the JIT off, ``tests.helpers.interpreted``) is the
reference. On random track — edges of random length, routes that are random walks over them (so they merge,
diverge, and some pass an edge twice), bidi partners on some edges — with random bodies (fronts anywhere on their
route, lengths spanning several edges, hints right, off by one or far off; more routes appearing in a later step),
an :class:`Occupancy` run on the compiled kernels must answer every ``ahead`` and ``facing`` question exactly as on
the interpreted ones, place every body on the same edges, and place the trains ahead where their reports put them
(``reported_rears``) the same way. The search itself is held to the geometry by ``tests/sumo/test_occupancy.py`` and
``tests/unit/test_facing_trains.py``.
"""

from __future__ import annotations

from types import SimpleNamespace

import networkx as nx
import numpy as np
import pytest

from railsim.engine import occupancy as occupancy_module, occupancy_kernel
from railsim.engine.occupancy import Body, Occupancy
from railsim.engine.routeview import RouteView
from tests.helpers import interpreted

N_EDGES = 24


def _world(rng: np.random.Generator) -> tuple[list[RouteView], nx.DiGraph]:
    lengths = rng.uniform(40.0, 400.0, N_EDGES)
    succ = {e: [int(x) for x in rng.choice(N_EDGES, size=2, replace=False)] for e in range(N_EDGES)}
    views = []
    for r in range(8):
        e = int(rng.integers(N_EDGES))
        walk = [e]
        for _ in range(int(rng.integers(2, 12))):
            e = succ[e][int(rng.integers(2))]
            walk.append(e)
        edges = tuple(f"e{x}" for x in walk)
        starts = np.concatenate([[0.0], np.cumsum(lengths[walk])[:-1]])
        route = SimpleNamespace(
            id=f"r{r}",
            edges=edges,
            edge_start_m=tuple(float(x) for x in starts),
            speed_limits=(),
            gradients=(),
            length_m=float(np.sum(lengths[walk])),
        )
        views.append(RouteView(route))
    graph = nx.DiGraph()
    for e in range(N_EDGES):
        graph.add_node(f"e{e}", length_m=float(lengths[e]))
    for e in range(0, N_EDGES - 6, 2):  # partners: e0/e1, e2/e3, ...
        graph.nodes[f"e{e}"]["bidi"] = f"e{e + 1}"
        graph.nodes[f"e{e + 1}"]["bidi"] = f"e{e}"
    return views, graph


def _bodies(rng: np.random.Generator, views: list[RouteView], n: int) -> list[Body]:
    out = []
    for k in range(n):
        view = views[int(rng.integers(len(views)))]
        front_m = float(rng.uniform(-20.0, view.length_m + 20.0))
        true_i = view.edge_at(front_m)
        hint = int(rng.choice([true_i, true_i - 1, true_i + 1, int(rng.integers(-2, len(view.edges) + 2))]))
        out.append(Body(f"t{k}", view, front_m, float(rng.uniform(20.0, 600.0)), hint))
    return out


def _answers(occ: Occupancy, bodies: list[Body], rng: np.random.Generator) -> list[str]:
    occ.update(bodies[: len(bodies) // 2])  # a step with some of the routes, then one where more appear
    occ.update(bodies)
    queries = [
        (b.train_id, b.front_m - float(rng.uniform(0.0, 300.0)), float(rng.uniform(0.0, 3000.0))) for b in bodies
    ]
    out = [repr([(b.edge_i, b.rear_i) for b in bodies])]
    out.append(repr(occ.ahead_all(float(rng.choice([500.0, 5000.0])))))
    out.append(repr([occ.ahead(b.train_id, 800.0) for b in bodies]))
    out.append(repr(occ.facing_all(queries)))
    out.append(repr([occ.facing(*q) for q in queries[:5]]))
    out.append(repr(occ.facing_within_braking([float(v) for v in rng.uniform(0.0, 30.0, len(bodies))], 150.0)))
    out.append(repr(occ.facing_own_bodies()))
    # the trains ahead placed where reports sent some time ago put them (some never reported: NaN)
    sent = np.array([b.front_m - float(rng.uniform(0.0, 80.0)) for b in bodies])
    sent[rng.random(len(bodies)) < 0.2] = np.nan
    out.append(repr([a.tolist() for a in occ.reported_rears(9.0, sent, rng.uniform(0.0, 10.0, len(bodies)))]))
    return out  # repr: the exact floats (round trip, the sign of a zero)


@pytest.mark.parametrize("seed", range(6))
def test_compiled_occupancy_is_its_interpreted_form(seed: int, monkeypatch: pytest.MonkeyPatch) -> None:
    slow = interpreted(occupancy_kernel)
    found_ahead = found_facing = 0
    for trial in range(25):
        rng = np.random.default_rng(1000 * seed + trial)
        views, graph = _world(rng)
        n = int(rng.integers(1, 40))
        answers = []
        for kernel in (occupancy_kernel, slow):
            monkeypatch.setattr(occupancy_module, "occupancy_kernel", kernel)
            occ = Occupancy()
            occ.set_bidi(graph)
            answers.append(_answers(occ, _bodies(np.random.default_rng(trial), views, n), np.random.default_rng(7)))
        assert answers[0] == answers[1]
        found_ahead += answers[0][1].count("Ahead(")
        found_facing += answers[0][3].count("Facing(")
    assert found_ahead > 100 and found_facing > 20  # the searches found trains, not only None


def test_compiled_edge_near_is_edge_at_whatever_the_hint() -> None:
    rng = np.random.default_rng(5)
    for _ in range(200):
        starts = np.concatenate([[0.0], np.cumsum(rng.uniform(1.0, 100.0, int(rng.integers(1, 12))))])
        view = RouteView(
            SimpleNamespace(
                id="r",
                edges=tuple(f"e{k}" for k in range(len(starts))),
                edge_start_m=tuple(starts),
                speed_limits=(),
                gradients=(),
                length_m=float(starts[-1] + 50.0),
            )
        )
        for _ in range(20):
            x = float(rng.choice([rng.uniform(-10.0, starts[-1] + 60.0), starts[int(rng.integers(len(starts)))]]))
            hint = int(rng.integers(-2, len(starts) + 2))
            assert occupancy_kernel.edge_near(starts, x, hint) == view.edge_near(x, hint) == view.edge_at(x)
