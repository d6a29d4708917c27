"""The flat-crossing truth check looks only at the crossings a train's body can span, and finds what a full scan finds.

``SafetyMonitor.crossing_checks`` (railsim/engine/safety.py) keeps, per train, where its route passes each flat
crossing (a span of route chainage, one after the other along the route) and, each step, looks only from the first
span that ends beyond the train's rear up to its front. The reference here is the full scan over every span of
every train. Random routes (a crossing passed twice, spans close together, trains of several lengths), random
fronts step after step (forward, standing, jumping), random foes: the collisions recorded — which pairs, in which
order, at which crossing and time — must be the same.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import networkx as nx
import numpy as np
import pytest

from railsim.engine.events.clock import EventLayer
from railsim.engine.events.log import EventLog
from railsim.engine.safety import SafetyMonitor
from railsim.engine.settings import EngineSettings


class FullScan(SafetyMonitor):
    """The reference: every span of every train, every step."""

    def crossing_checks(self, t: float, active: list[Any]) -> None:
        inside: dict[str, list[tuple[Any, tuple[str, str]]]] = {}
        for tr in active:
            rear_m = tr.front_m - tr.trip.vehicle.length_m
            for node, move, start_m, end_m in self._crossings.get(tr.train_id, ()):
                if tr.front_m > start_m and rear_m < end_m:
                    inside.setdefault(node, []).append((tr, move))
        for node, here in inside.items():
            for i, (tr, move) in enumerate(here):
                for other, move2 in here[i + 1 :]:
                    if move2 not in self._foes[node][move]:
                        continue
                    pair = (min(tr.train_id, other.train_id), max(tr.train_id, other.train_id))
                    if pair in self._colliding_pairs:
                        continue
                    self._colliding_pairs.add(pair)
                    self.collisions.append(
                        {
                            "t_s": t,
                            "follower": tr.train_id,
                            "leader": other.train_id,
                            "overlap_m": 0.0,
                            "chainage_m": tr.front_m,
                            "crossing": node,
                        }
                    )


def _world(rng: np.random.Generator, n_trains: int) -> tuple[nx.DiGraph, dict[str, Any]]:
    """Edges e0..e39 of random lengths; crossings X0..X5, each joining movements (a, b) between random edges; every
    train's route a random walk over the edges that passes some crossings (some twice)."""
    graph = nx.DiGraph()
    lengths = {f"e{k}": float(rng.uniform(5.0, 300.0)) for k in range(40)}
    for edge, length in lengths.items():
        graph.add_node(edge, length_m=length)
    edges = list(lengths)
    moves_at: dict[str, list[tuple[str, str]]] = {f"X{k}": [] for k in range(6)}
    routes = []
    for _ in range(n_trains):
        walk = [str(rng.choice(edges)) for _ in range(int(rng.integers(3, 25)))]
        for a, b in zip(walk, walk[1:]):
            if not graph.has_edge(a, b):
                node = f"X{int(rng.integers(0, 6))}" if rng.random() < 0.5 else f"J{a}{b}"
                graph.add_edge(a, b, node=node)
                if node in moves_at:
                    moves_at[node].append((a, b))
        routes.append(walk)
    foes: dict[str, dict[tuple[str, str], set[tuple[str, str]]]] = {}
    for node, moves in moves_at.items():
        foes[node] = {m: {o for o in moves if o != m and rng.random() < 0.7} for m in moves}
    graph.graph["crossings"] = foes
    trains = {}
    for k, walk in enumerate(routes):
        gaps = rng.choice([0.0, 0.0, rng.uniform(0.0, 20.0)], size=len(walk))
        starts = np.concatenate([[0.0], np.cumsum([lengths[e] + g for e, g in zip(walk[:-1], gaps[:-1])])])
        route = SimpleNamespace(edges=walk, edge_start_m=starts)
        vehicle = SimpleNamespace(length_m=float(rng.choice([20.0, 118.0, 240.0])))
        trains[f"t{k}"] = SimpleNamespace(
            train_id=f"t{k}", front_m=0.0, trip=SimpleNamespace(route=route, vehicle=vehicle)
        )
    return graph, trains


def _against_full_scan(rng: np.random.Generator, graph: nx.DiGraph, trains: dict[str, Any], steps: int) -> int:
    """Run the check and the full scan side by side on random moves; the collisions must agree every step. Returns
    how often a body spanned a crossing."""
    monitors = []
    for cls in (SafetyMonitor, FullScan):
        layer = EventLayer(t0_s=0.0, rng=np.random.default_rng(1))
        monitor = cls(trains, layer, EventLog(), EngineSettings())  # type: ignore[arg-type]
        monitor.set_up_crossings(graph)
        monitors.append(monitor)
    fast, full = monitors
    assert fast._crossings == full._crossings and fast._crossings  # crossings on some routes
    ends = {tid: float(tr.trip.route.edge_start_m[-1]) + 50.0 for tid, tr in trains.items()}
    spanned = 0
    for step in range(steps):
        for tid, tr in trains.items():  # forward most steps; standing, jumps and a step back now and then
            move = rng.choice(["run", "run", "run", "stand", "jump", "back"])
            if move == "run":
                tr.front_m += float(rng.uniform(0.0, 25.0))
            elif move == "jump":
                tr.front_m = float(rng.uniform(0.0, ends[tid]))
            elif move == "back":
                tr.front_m = max(0.0, tr.front_m - float(rng.uniform(0.0, 30.0)))
        active = [trains[tid] for tid in rng.permutation(sorted(trains))]
        for monitor in (fast, full):
            monitor.crossing_checks(float(step), active)
        spanned += sum(
            tr.front_m > s and tr.front_m - tr.trip.vehicle.length_m < e
            for tr in active
            for _, _, s, e in fast._crossings.get(tr.train_id, ())
        )
        assert fast.collisions == full.collisions, f"step {step}"
    return spanned


@pytest.mark.parametrize("seed", range(12))
def test_the_windowed_check_finds_what_the_full_scan_finds(seed: int) -> None:
    rng = np.random.default_rng(seed)
    graph, trains = _world(rng, int(rng.integers(2, 12)))
    assert _against_full_scan(rng, graph, trains, 400) > 50  # trains were on crossings often enough to matter


def test_a_route_whose_spans_are_out_of_order_is_scanned_whole() -> None:
    """Spans that do not lie one after the other (a route's chainages out of step with the net's lengths) keep the
    full scan for that train: the window would miss a span after a later-starting one."""
    rng = np.random.default_rng(5)
    graph, trains = _world(rng, 6)
    monitor = SafetyMonitor(trains, EventLayer(t0_s=0.0, rng=rng), EventLog(), EngineSettings())  # type: ignore[arg-type]
    for tr in trains.values():  # a route drawn shorter than its edges: the spans' starts run backwards
        tr.trip.route.edge_start_m = tr.trip.route.edge_start_m * 0.1
    monitor.set_up_crossings(graph)
    disordered = [
        tid for tid, spans in monitor._crossings.items() if [s[2] for s in spans] != sorted(s[2] for s in spans)
    ]
    assert disordered and all(monitor._crossing_of[tid][1] is None for tid in disordered)


@pytest.mark.parametrize("seed", range(6))
def test_trains_whose_spans_are_out_of_order_find_what_the_full_scan_finds(seed: int) -> None:
    rng = np.random.default_rng(50 + seed)
    graph, trains = _world(rng, int(rng.integers(4, 12)))
    for tr in trains.values():  # a route drawn shorter than its edges: the spans' starts run backwards
        tr.trip.route.edge_start_m = tr.trip.route.edge_start_m * 0.1
    assert _against_full_scan(rng, graph, trains, 300) > 50
