"""Where routes share track head-on or across: single-track sections and flat crossings, found in the track graph.

The track graph (:class:`network.topology.NetworkBundle`.graph) has one node per SUMO edge with its ``bidi``
partner (external nets). A **section** is a maximal set of bidi edges joined at plain nodes: consecutive edges
connected without a switch, together with their partners. Switch nodes (a passing loop's ends, a junction) end a
section, because there trains can pass each other. Each edge gets an **orientation** (0/1) within its section:
an edge and its bidi partner have opposite orientations, consecutive edges the same — two trains whose routes
cross a section with different orientations meet head-on.

:func:`route_sections` lists, for one route, each section it runs through: where its front enters
(``start_m``), where its rear has left (``end_m``), and its **protection point** ``guard_m``: the switch point in
front of the section if the section begins at a switch (a train waiting for a section must not stand on the
switch another train needs to leave the section), else the section's start.

A route that runs both ways through a section reverses inside it (a unit on a turnback track, a bidi platform):
its direction is :data:`REVERSING`, and each such train holds the section alone (the route locks give it a
direction of its own), since a second train in a turnback track would meet it head-on after the flip. A route that
runs out through a section into a stub right beyond it, reverses there and comes back through the section is shut in
behind that section the same way: :func:`kept_through_reversal` makes the two times through one entry, held alone
from the first entry until the rear has left on the way back.

**Crossings** (:func:`route_crossings`): movements through one SUMO node that SUMO's foe matrix says intersect
while sharing no track (``graph.graph["crossings"]``, from :func:`network.topology.flat_crossings`: a diamond in an
external net, the track to a branch crossing the opposite main track at a generated junction) are one resource
per node, held by one movement at a time (trains on the same movement may follow each other through). It spans
the node's internal lanes: from the end of the edge in front to the start of the edge behind. Its protection
point is the node itself, the point of a switch there too: a train asks for the crossing before that switch.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import networkx as nx

ADJACENT_SWITCH_M = 60.0  # a switch point this close before a section's start protects the section
REVERSING = -1  # the direction of a route that reverses inside a section (a unit turning back): it needs it alone


@dataclass(frozen=True)
class RouteSection:
    """One single-track section on one route (route chainage [m])."""

    section_id: str
    direction: int
    start_m: float
    end_m: float
    guard_m: float


def section_map(graph: nx.DiGraph) -> dict[str, tuple[str, int]]:
    """Every bidi edge of the graph → ``(section id, orientation)`` (empty for nets without bidi track)."""
    bidi = {e: a.get("bidi") for e, a in graph.nodes(data=True) if a.get("bidi") in graph}
    if not bidi:
        return {}
    links = nx.Graph()
    for e, partner in bidi.items():
        links.add_edge(e, partner, flip=1)
    for a, b, attrs in graph.edges(data=True):
        if a in bidi and b in bidi and attrs.get("switch") is None:
            links.add_edge(a, b, flip=0)
    out: dict[str, tuple[str, int]] = {}
    for component in nx.connected_components(links):
        root = min(component)
        orientation = {root: 0}
        for u, v in nx.bfs_edges(links, root):
            orientation[v] = orientation[u] ^ links.edges[u, v]["flip"]
        for e in component:
            out[e] = (f"track:{root}", orientation[e])
    return out


def route_sections(route: Any, smap: dict[str, tuple[str, int]]) -> list[RouteSection]:
    """The sections ``route`` runs through, in route order (see the module docstring)."""
    runs: list[RouteSection] = []
    edges, starts = route.edges, route.edge_start_m
    i = 0
    while i < len(edges):
        if edges[i] not in smap:
            i += 1
            continue
        sid, direction = smap[edges[i]]
        j = i
        while j + 1 < len(edges) and smap.get(edges[j + 1], ("", 0))[0] == sid:
            j += 1
            if smap[edges[j]][1] != direction:  # it runs both ways in it: it reverses there
                direction = REVERSING
        start = float(starts[i])
        end = float(starts[j + 1]) if j + 1 < len(edges) else float(route.length_m)
        guard = start
        for rs in route.switches:
            if start - ADJACENT_SWITCH_M <= rs.point_m <= start:
                guard = min(guard, float(rs.point_m))
        runs.append(RouteSection(sid, direction, start, end, guard))
        i = j + 1
    return runs


def kept_through_reversal(
    sections: list[RouteSection], direction: int, length_m: float, clear_m: float
) -> list[RouteSection]:
    """``sections`` (one route's, in route order) with each single-track section the route runs out through into a
    stub right beyond it (a section it reverses inside, :data:`REVERSING`) and back through the other way, with no
    passing place on either side of the stub (less than the train's ``length_m`` from the end of one section to the
    protection point of the next, less ``clear_m``: its clearance behind and overlap in front), as one entry in
    ``direction`` (the train's own) from its first start and protection point to its second end. Another train let
    into it between the two times through, in either direction, stands between this train and its way back (Jena,
    Lobeda-Ost: a tram granted the approach the way the unit had gone out stood at the platform and passed it to
    its next trip, which waited for the stub the unit was turning in)."""
    track = [s for s in sections if s.section_id.startswith("track:")]
    kept: dict[int, RouteSection] = {}  # id() of the first time through -> the entry for both
    back: set[int] = set()  # id() of the time back through
    for out, turn, again in zip(track, track[1:], track[2:]):
        if (
            turn.direction == REVERSING
            and again.section_id == out.section_id
            and REVERSING not in (out.direction, again.direction)
            and out.direction != again.direction
            and all(b.guard_m - a.end_m - clear_m < length_m for a, b in ((out, turn), (turn, again)))
        ):
            kept[id(out)] = replace(out, direction=direction, end_m=again.end_m)
            back.add(id(again))
    if not kept:
        return sections
    return [kept.get(id(s), s) for s in sections if id(s) not in back]


def contested(per_train: dict[str, list[RouteSection]]) -> set[str]:
    """Sections that trains use in both directions (only those can see a head-on conflict)."""
    seen: dict[str, set[int]] = {}
    for sections in per_train.values():
        for s in sections:
            seen.setdefault(s.section_id, set()).add(s.direction)
    return {sid for sid, dirs in seen.items() if len(dirs) > 1 or REVERSING in dirs}


def route_crossings(route: Any, graph: nx.DiGraph) -> list[RouteSection]:
    """The flat crossings ``route`` passes (see the module docstring), as one-movement-at-a-time resources."""
    crossings: dict[str, dict[tuple[str, str], list[tuple[str, str]]]] = graph.graph.get("crossings", {})
    if not crossings:
        return []
    at_node = {move: (node, sorted(moves).index(move)) for node, moves in crossings.items() for move in moves}
    out = []
    for k in range(len(route.edges) - 1):
        move = (route.edges[k], route.edges[k + 1])
        if move not in at_node:
            continue
        node, index = at_node[move]
        start = float(route.edge_start_m[k]) + float(graph.nodes[move[0]]["length_m"])
        out.append(RouteSection(f"crossing:{node}", index, start, float(route.edge_start_m[k + 1]), start))
    return out
