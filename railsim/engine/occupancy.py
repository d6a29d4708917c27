"""Ground truth: which train is directly ahead of which, the true gaps, and overlaps (collisions).

This module sees the world as it *is* (positions from SUMO's odometer), never as a train knows it. The engine
uses it for three things only:

* the recorder's gaps and collision detection (an overlap of two trains on the same track is a collision,
  whatever SUMO's own checks say);
* deciding *whose* messages a train listens to for separation (the train physically ahead on its route) —
  the *contents* a controller sees still come through the communication layer, delayed and lossy;
* feeding formations their true gap (coupling completes on the real gap, not a believed one).

Trains are indexed by the SUMO edges their body covers (rear to front, in their own route frame). A follower
walks its own route forward from the edge under its front; the first edge holding any part of another train
ahead gives the predecessor. Frames are changed on the shared track only (:meth:`RouteView.map_body`): the tail
of a train that is merging from the other leg is not on our track, so it is not "ahead" of a train waiting at
the switch — the interlocking, not the gap, protects the junction itself.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

from railsim.engine.routeview import RouteView


@dataclass(slots=True)
class Body:
    """A train's body for occupancy: front chainage in its own route frame and its length; ``edge_i`` is the
    route edge under the front (a hint: :meth:`RouteView.edge_near`), ``rear_i`` is set by :meth:`Occupancy.update`."""

    train_id: str
    view: RouteView
    front_m: float
    length_m: float
    edge_i: int = 0
    rear_i: int = 0

    @property
    def rear_m(self) -> float:
        return self.front_m - self.length_m


class Ahead(NamedTuple):
    """The train directly ahead of a follower, in the follower's frame (ground truth). (Immutable; a named tuple
    rather than a frozen dataclass because one is built per train and step.)"""

    train_id: str
    front_m: float
    rear_m: float
    gap_m: float  # front-to-rear: rear of the train ahead minus front of the follower (negative = overlap)
    offset_m: float  # add to the leader's own chainage to get the follower's frame


class Occupancy:
    """Per-step index of which train covers which edge."""

    def __init__(self) -> None:
        self._by_edge: dict[str, list[Body]] = {}
        self.bodies: dict[str, Body] = {}

    def update(self, bodies: list[Body]) -> None:
        by_edge: dict[str, list[Body]] = {}
        for b in bodies:
            view = b.view
            i1 = b.edge_i = view.edge_near(b.front_m, b.edge_i)
            i0 = b.rear_i = view.edge_near(b.front_m - b.length_m, i1)
            edges = view.edges
            for i in range(i0, i1 + 1):
                on_edge = by_edge.get(edges[i])
                if on_edge is None:
                    by_edge[edges[i]] = [b]
                else:
                    on_edge.append(b)
        self._by_edge = by_edge
        self.bodies = {b.train_id: b for b in bodies}

    def ahead(self, train_id: str, lookahead_m: float = 5000.0) -> Ahead | None:
        """The nearest train whose front is ahead of ``train_id``'s front on its route, within ``lookahead_m``."""
        me = self.bodies[train_id]
        view = me.view
        j = me.edge_i
        limit = me.front_m + lookahead_m
        n = len(view.edges)
        while j < n and view.edge_start_m[j] <= limit:
            edge = view.edges[j]
            best: Ahead | None = None
            for other in self._by_edge.get(edge, ()):
                if other.train_id == train_id:
                    continue
                mapped = view.map_body(other.view, other.front_m, other.length_m, other.edge_i)
                if mapped is None:
                    continue
                front, rear = mapped
                if front <= me.front_m:
                    continue  # behind us (or level: the one behind is its follower's problem)
                if best is None or front < best.front_m:
                    best = Ahead(other.train_id, front, rear, rear - me.front_m, front - other.front_m)
            if best is not None:
                return best
            j += 1
        return None
