"""The dynamic communication graph of Paper C (spec 002 §2.2, Assumption 2.2, §7.1) and its topology events.

Trains talk over an **undirected** graph ``𝒢 = (𝒱, ℰ)``. Every edge carries three numbers, stated once for one
orientation ``(i, j)``:

* ``d_m`` = d_ij, the desired position difference ``x_i − x_j`` (positive when i runs ahead of j);
* ``gamma_lo_m`` = γ̲_ij and ``gamma_hi_m`` = γ̄_ij, the bounds ``γ̲_ij ≤ x_i − x_j ≤ γ̄_ij`` (objective O1).

Assumption 2.2 asks that the reverse orientation be the mirror image: ``d_ji = −d_ij`` and ``γ̲_ji = −γ̄_ij``
(hence ``γ̄_ji = −γ̲_ij``). :class:`CommGraph` stores each edge once and *derives* the reverse view
(:meth:`CommGraph.oriented`), so the mirror property holds by construction and cannot be mis-typed; what can still
go wrong — ``γ̲ < d < γ̄``, zero sum of ``d`` around every cycle, connectivity — is checked by
:mod:`controllers.distributed.validate`.

The graph is immutable: topology changes (a train joins with its initial state, a train leaves, an edge appears
or disappears) are :class:`TopologyEvent` values applied at a given step ``k`` by :func:`apply_event`, which
returns a new graph. The simulator re-validates the preconditions after every step that had events
(:func:`controllers.distributed.validate.check_event_preconditions`).

Train identifiers are strings (as everywhere in railsim). Edge keys are ``frozenset({i, j})``.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field

from controllers.distributed.model import TrainParams


@dataclass(frozen=True)
class EdgeData:
    """Per-edge data seen from the first train of the orientation: ``(d_ij, γ̲_ij, γ̄_ij)`` [m]."""

    d_m: float
    gamma_lo_m: float
    gamma_hi_m: float

    def reversed(self) -> EdgeData:
        """The same edge seen from the other end (Assumption 2.2): ``(−d, −γ̄, −γ̲)``."""
        return EdgeData(d_m=-self.d_m, gamma_lo_m=-self.gamma_hi_m, gamma_hi_m=-self.gamma_lo_m)

    def as_tuple(self) -> tuple[float, float, float]:
        return (self.d_m, self.gamma_lo_m, self.gamma_hi_m)


@dataclass(frozen=True)
class Edge:
    """An edge as the user states it: ``data`` oriented from ``i`` to ``j``."""

    i: str
    j: str
    data: EdgeData

    @property
    def key(self) -> frozenset[str]:
        return frozenset((self.i, self.j))


@dataclass(frozen=True)
class CommGraph:
    """An undirected graph of train ids with oriented per-edge data (immutable; events return new graphs)."""

    nodes: frozenset[str] = frozenset()
    edges: Mapping[frozenset[str], Edge] = field(default_factory=dict)

    @staticmethod
    def build(nodes: Iterable[str], edges: Iterable[Edge]) -> CommGraph:
        """A graph from a node list and edges; raises ValueError for self-loops, unknown ends or duplicates."""
        node_set = frozenset(str(n) for n in nodes)
        table: dict[frozenset[str], Edge] = {}
        for e in edges:
            _check_edge(e, node_set, table)
            table[e.key] = e
        return CommGraph(node_set, table)

    # ------------------------------------------------------------------ queries

    def neighbours(self, i: str) -> tuple[str, ...]:
        """``𝒩_i`` in a deterministic (sorted) order."""
        return tuple(sorted(j for key in self.edges if i in key for j in key if j != i))

    def degree(self, i: str) -> int:
        return sum(1 for key in self.edges if i in key)

    def has_edge(self, i: str, j: str) -> bool:
        return frozenset((i, j)) in self.edges

    def oriented(self, i: str, j: str) -> EdgeData:
        """``(d_ij, γ̲_ij, γ̄_ij)`` seen from ``i`` (KeyError if there is no edge)."""
        e = self.edges[frozenset((i, j))]
        return e.data if e.i == i else e.data.reversed()

    def oriented_edges(self) -> Iterator[tuple[str, str, EdgeData]]:
        """Every edge once, in its stated orientation, sorted by key (deterministic logs)."""
        for key in sorted(self.edges, key=lambda k: tuple(sorted(k))):
            e = self.edges[key]
            yield e.i, e.j, e.data

    def components(self) -> list[frozenset[str]]:
        """Connected components (sorted by their smallest id)."""
        seen: set[str] = set()
        out: list[frozenset[str]] = []
        adj = {n: self.neighbours(n) for n in self.nodes}
        for start in sorted(self.nodes):
            if start in seen:
                continue
            comp = {start}
            queue = deque([start])
            while queue:
                n = queue.popleft()
                for m in adj[n]:
                    if m not in comp:
                        comp.add(m)
                        queue.append(m)
            seen |= comp
            out.append(frozenset(comp))
        return out

    def is_connected(self) -> bool:
        return len(self.components()) <= 1

    def node_offsets(self) -> tuple[dict[str, float], list[tuple[str, str, float]]]:
        """Potentials ``d_i`` with ``d_ij = d_i − d_j`` along a BFS spanning forest, and the inconsistent edges.

        Returns ``(offsets, mismatches)``; each mismatch is ``(i, j, cycle_sum_m)`` where ``cycle_sum_m`` is the
        sum of the (oriented) ``d`` around the cycle this non-tree edge closes — zero for a d-consistent graph
        (Assumption 2.2, "transitivity", which on a general graph means zero sum around every cycle). The first
        node of each component gets offset 0.
        """
        offsets: dict[str, float] = {}
        for comp in self.components():
            root = min(comp)
            offsets[root] = 0.0
            queue = deque([root])
            while queue:
                n = queue.popleft()
                for m in self.neighbours(n):
                    if m not in offsets:
                        offsets[m] = offsets[n] - self.oriented(n, m).d_m  # d_nm = d_n − d_m
                        queue.append(m)
        mismatches = []
        for i, j, data in self.oriented_edges():
            cycle = data.d_m - (offsets[i] - offsets[j])
            if cycle != 0.0:
                mismatches.append((i, j, cycle))
        return offsets, mismatches

    # ------------------------------------------------------------------ changes (new graphs)

    def with_node(self, i: str) -> CommGraph:
        if i in self.nodes:
            raise ValueError(f"train {i!r} is already in the graph")
        return CommGraph(self.nodes | {i}, dict(self.edges))

    def without_node(self, i: str) -> CommGraph:
        """Remove train ``i`` and every edge at it."""
        if i not in self.nodes:
            raise ValueError(f"train {i!r} is not in the graph")
        return CommGraph(self.nodes - {i}, {k: e for k, e in self.edges.items() if i not in k})

    def with_edge(self, edge: Edge) -> CommGraph:
        table = dict(self.edges)
        _check_edge(edge, self.nodes, table)
        table[edge.key] = edge
        return CommGraph(self.nodes, table)

    def without_edge(self, i: str, j: str) -> CommGraph:
        key = frozenset((i, j))
        if key not in self.edges:
            raise ValueError(f"there is no edge {i}-{j}")
        return CommGraph(self.nodes, {k: e for k, e in self.edges.items() if k != key})


def _check_edge(e: Edge, nodes: frozenset[str], table: Mapping[frozenset[str], Edge]) -> None:
    if e.i == e.j:
        raise ValueError(f"edge {e.i}-{e.j}: self-loops are not allowed")
    for end in (e.i, e.j):
        if end not in nodes:
            raise ValueError(f"edge {e.i}-{e.j}: train {end!r} is not in the graph")
    if e.key in table:
        raise ValueError(f"edge {e.i}-{e.j}: stated twice (state each edge once; the reverse is derived)")


# ---------------------------------------------------------------------------------------------- events


@dataclass(frozen=True)
class TrainJoin:
    """At step ``k`` train ``train_id`` enters with state ``(x_m, v_mps)`` and the given edges to present trains.

    The train's state is the state *at* ``k``; the control computed at ``k`` already uses the new graph
    (spec 002 erratum A5).
    """

    k: int
    train_id: str
    x_m: float
    v_mps: float
    params: TrainParams
    edges: tuple[Edge, ...] = ()


@dataclass(frozen=True)
class TrainLeave:
    """At step ``k`` train ``train_id`` leaves the system with every edge at it (before the controls of ``k``)."""

    k: int
    train_id: str


@dataclass(frozen=True)
class EdgeAdd:
    k: int
    edge: Edge


@dataclass(frozen=True)
class EdgeRemove:
    k: int
    i: str
    j: str


TopologyEvent = TrainJoin | TrainLeave | EdgeAdd | EdgeRemove

# Within one step, events apply in this order so "train 2 leaves, train 5 joins with an edge to 4" and
# "edge removed, then re-added with new data" both work regardless of how the user listed them.
_EVENT_ORDER = {EdgeRemove: 0, TrainLeave: 1, TrainJoin: 2, EdgeAdd: 3}


def sort_events(events: Iterable[TopologyEvent]) -> list[TopologyEvent]:
    """Events by step, then removals before additions (stable otherwise)."""
    return sorted(events, key=lambda e: (e.k, _EVENT_ORDER[type(e)]))


def apply_event(graph: CommGraph, event: TopologyEvent) -> CommGraph:
    """The graph after ``event`` (states and parameters of a joining train are kept by the simulator)."""
    if isinstance(event, TrainJoin):
        g = graph.with_node(event.train_id)
        for e in event.edges:
            if event.train_id not in (e.i, e.j):
                raise ValueError(f"join of {event.train_id}: edge {e.i}-{e.j} does not touch the joining train")
            g = g.with_edge(e)
        return g
    if isinstance(event, TrainLeave):
        return graph.without_node(event.train_id)
    if isinstance(event, EdgeAdd):
        return graph.with_edge(event.edge)
    if isinstance(event, EdgeRemove):
        return graph.without_edge(event.i, event.j)
    raise TypeError(f"not a topology event: {event!r}")
