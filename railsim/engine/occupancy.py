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

from railsim.engine.routeview import RouteView


@dataclass
class Body:
    """A train's body for occupancy: front chainage in its own route frame and its length."""

    train_id: str
    view: RouteView
    front_m: float
    length_m: float

    @property
    def rear_m(self) -> float:
        return self.front_m - self.length_m


@dataclass(frozen=True)
class Ahead:
    """The train directly ahead of a follower, in the follower's frame (ground truth)."""

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
            i0 = view.edge_at(b.rear_m)
            i1 = view.edge_at(b.front_m)
            for i in range(i0, i1 + 1):
                by_edge.setdefault(view.edges[i], []).append(b)
        self._by_edge = by_edge
        self.bodies = {b.train_id: b for b in bodies}

    def ahead(self, train_id: str, lookahead_m: float = 5000.0) -> Ahead | None:
        """The nearest train whose front is ahead of ``train_id``'s front on its route, within ``lookahead_m``."""
        me = self.bodies[train_id]
        view = me.view
        j = view.edge_at(me.front_m)
        limit = me.front_m + lookahead_m
        n = len(view.edges)
        while j < n and view.edge_start_m[j] <= limit:
            edge = view.edges[j]
            best: Ahead | None = None
            for other in self._by_edge.get(edge, ()):
                if other.train_id == train_id:
                    continue
                mapped = view.map_body(other.view, other.front_m, other.length_m)
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
