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

**Trains facing each other.** On ``bidi`` track one physical track is two SUMO edges, one per direction, and a
train running (or standing, turned back) the other way is on the partner edge: the index by edge never puts it
ahead of anybody. :meth:`Occupancy.facing` finds it (given the partner of every bidi edge and the edge lengths,
:meth:`Occupancy.set_bidi`): the nearest train on the partner edges of the track ahead, with the part of its body
there in this train's frame. A position ``x`` metres into an edge is ``length - x`` metres into its partner. The
safety check counts two such bodies overlapping as a head-on collision, and no movement authority reaches into
track a facing train stands on.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

from railsim.engine.routeview import RouteView
from railsim.engine.settings import FACING_DECEL_MPS2


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


class Facing(NamedTuple):
    """The nearest train on the track ahead running (or standing) the other way, in the observer's frame."""

    train_id: str
    near_m: float  # the end of its body nearest the observer's front (its front, facing us)
    far_m: float  # the other end


class Occupancy:
    """Per-step index of which train covers which edge."""

    def __init__(self) -> None:
        self._by_edge: dict[str, list[Body]] = {}
        self.bodies: dict[str, Body] = {}
        self._bidi: dict[str, tuple[str, float]] = {}  # bidi edge -> (its partner, the partner's length [m])

    @property
    def has_bidi(self) -> bool:
        """True if the track has bidi edges (only there can trains face each other on one track)."""
        return bool(self._bidi)

    def set_bidi(self, graph: Any) -> None:
        """The partner of every bidi edge of the track graph and its length (:meth:`facing`)."""
        nodes = graph.nodes
        self._bidi = {
            e: (a["bidi"], float(nodes[a["bidi"]]["length_m"]))
            for e, a in nodes(data=True)
            if a.get("bidi") is not None and a["bidi"] in nodes
        }

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

    def facing_within_braking(self, fronts: list[tuple[str, float, float]], floor_m: float) -> dict[str, float]:
        """For each ``(train, front_m, speed_mps)``, where the nearest train facing it begins (its frame), looked
        for as far as the train brakes from its speed at a mild :data:`FACING_DECEL_MPS2`, at least ``floor_m``
        (the sensor range); trains with none are left out. The route locks end authorities before it."""
        near: dict[str, float] = {}
        for train_id, front_m, speed_mps in fronts:
            hit = self.facing(train_id, front_m, floor_m + speed_mps**2 / (2.0 * FACING_DECEL_MPS2))
            if hit is not None:
                near[train_id] = hit.near_m
        return near

    def facing(self, train_id: str, from_m: float, lookahead_m: float) -> Facing | None:
        """The nearest train on the partner edges of this train's route from ``from_m`` on (within
        ``lookahead_m``) whose body lies there at or beyond ``from_m`` (module docstring): it runs or stands
        the other way on the same track. None on track without partners."""
        if not self._bidi:
            return None
        me = self.bodies[train_id]
        view = me.view
        j = view.edge_near(from_m, me.rear_i)
        limit = from_m + lookahead_m
        n = len(view.edges)
        best: Facing | None = None
        while j < n and view.edge_start_m[j] <= limit:
            partner = self._bidi.get(view.edges[j])
            if partner is not None:
                edge, length_m = partner
                for other in self._by_edge.get(edge, ()):
                    if other.train_id == train_id:
                        continue
                    span = _on_edge(other, edge)
                    if span is None:
                        continue
                    # x into the partner is length - x here (the part on the junction lane after it: at its end)
                    near = view.edge_start_m[j] + length_m - min(span[1], length_m)
                    far = view.edge_start_m[j] + length_m - min(span[0], length_m)
                    if far >= from_m and near <= limit and (best is None or near < best.near_m):
                        best = Facing(other.train_id, near, far)
            if best is not None:
                return best
            j += 1
        return None


def _on_edge(body: Body, edge: str) -> tuple[float, float] | None:
    """The part of ``body`` on ``edge`` as metres into that edge ``(from, to)``, or None (its route frame:
    ``Occupancy.update`` set the edges under its rear and front)."""
    view = body.view
    for i in range(body.rear_i, body.edge_i + 1):
        if view.edges[i] != edge:
            continue
        start = view.edge_start_m[i]
        end = view.edge_start_m[i + 1] if i + 1 < len(view.edge_start_m) else view.length_m
        lo = max(body.rear_m, start) - start
        hi = min(body.front_m, end) - start
        return lo, hi
    return None
