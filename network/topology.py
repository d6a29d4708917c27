"""The topology of a built world: stations, switches and routes with chainage that matches SUMO's odometer.

The network builder (:mod:`network.generator`) turns a line description into a SUMO net and a *track
graph*, a :class:`networkx.DiGraph` whose

* **nodes are the SUMO normal edges** (one-way track pieces). Attributes: ``line`` (line id), ``direction``
  (``'up'`` = increasing chainage, ``'down'``), ``length_m`` and ``speed_mps`` (read back from the .net.xml),
  ``from_node``/``to_node`` (SUMO junction ids), ``design_start_m`` (design chainage, metres, of lane
  position 0) and ``design_sign`` (+1 up, -1 down; design chainage = design_start_m + sign * lane_pos),
  ``station``/``stop_id`` (the platform on this piece, or None);
* **edges are SUMO connections** (a train may run from piece u to piece v). Attributes: ``node`` (SUMO
  junction), ``via`` (list of ``[internal_lane_id, length_m, speed_mps]`` in travel order, read from the
  .net.xml), ``switch`` (switch id or None) and ``leg`` (``'normal'``/``'reverse'`` or None).

``graph.graph`` holds ``name``, ``gradients`` (``{line: [[from_m, to_m, permille_up], ...]}``, design metres),
``points`` (``{point_id: [line, design_m]}``) and ``crossings`` (:func:`flat_crossings`).

**Flat crossings.** Where two movements through one SUMO node intersect while sharing no track, the node is a
crossing at grade (a diamond): at a double-track junction the track towards the branch crosses the opposite
main track (Bijin on Line 3), at a depot lead the movement to or from the far track crosses the near one.
SUMO knows it (the two internal lanes are *foes* in the node's request matrix, computed by netconvert from the
geometry) and reports a collision when two trains overlap there; railsim's interlocking must therefore hold the
crossing as a resource (:func:`railsim.engine.single_track.route_crossings`). :func:`flat_crossings` keeps the
foe pairs that are not already protected otherwise: movements that share an edge or its bidi partner are a
diverge, a merge or single track, each guarded by its own switch or section.

A :class:`RouteInfo` is computed from the graph alone (:func:`make_route`), so a bundle loaded from the
cache gives exactly the same routes as a fresh build. Route chainage is metres from the start of the
route's first edge and **includes the internal junction lanes**, which is what SUMO's odometer
(``vehicle.getDistance``) accumulates: a train inserted at lane position p on the first edge has
``chainage = p + odometer``.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import networkx as nx

from network.running_side import WRONG_LINE_FACTOR


@dataclass(frozen=True)
class PlatformInfo:
    """One platform (one direction) of a station: the SUMO trainStop and where it lies on its edge."""

    direction: str
    stop_id: str
    edge: str
    start_pos_m: float
    end_pos_m: float


@dataclass(frozen=True)
class StationInfo:
    id: str
    name: str
    line: str
    km: float  # design chainage of the platform centre
    platform_length_m: float
    turnback: bool
    platforms: tuple[PlatformInfo, ...]
    crossover_speed_mps: float | None = None  # speed over the turnback crossover, if one is recorded

    def platform(self, direction: str) -> PlatformInfo:
        for p in self.platforms:
            if p.direction == direction:
                return p
        raise KeyError(f"station {self.id!r} has no {direction!r} platform")


@dataclass(frozen=True)
class SwitchInfo:
    """A switch (turnout) for one direction of travel.

    ``kind`` is 'diverge' (one edge in, two out: ``normal_edge``/``reverse_edge`` are the outgoing legs) or
    'merge' (two in, one out: the legs are the incoming edges). ``trunk_edge`` is the common edge.
    """

    id: str
    sumo_node: str
    kind: str
    normal_edge: str
    reverse_edge: str
    trunk_edge: str
    throw_time_s: float
    diverging_speed_mps: float
    normal_speed_mps: float


@dataclass(frozen=True)
class RouteStop:
    station_id: str
    stop_id: str
    edge: str
    start_pos_m: float  # lane positions of the platform on that edge
    end_pos_m: float
    start_m: float  # route chainage of the platform start/end (front of a stopped train <= end_m)
    end_m: float


@dataclass(frozen=True)
class RouteSwitch:
    switch_id: str
    point_m: float  # route chainage of the switch node (toe of a diverge / fouling point of a merge)
    leg: str  # 'normal' | 'reverse'


@dataclass(frozen=True)
class RoutePoint:
    point_id: str
    point_m: float


@dataclass(frozen=True)
class RouteInfo:
    id: str
    edges: tuple[str, ...]
    edge_start_m: tuple[float, ...]
    length_m: float
    stops: tuple[RouteStop, ...]
    speed_limits: tuple[tuple[float, float, float], ...]
    gradients: tuple[tuple[float, float, float], ...]
    switches: tuple[RouteSwitch, ...]
    points: tuple[RoutePoint, ...] = ()
    # route chainage of the start of every internal junction edge (':J_3') on the route
    internal_start_m: tuple[tuple[str, float], ...] = ()

    @functools.cached_property
    def _starts(self) -> dict[str, float]:
        starts = dict(self.internal_start_m)
        starts.update(zip(self.edges, self.edge_start_m))
        return starts

    def chainage(self, edge_id: str, lane_pos_m: float) -> float:
        """Route chainage of lane position ``lane_pos_m`` on ``edge_id`` (normal or internal junction edge)."""
        try:
            return self._starts[edge_id] + float(lane_pos_m)
        except KeyError:
            raise KeyError(f"edge {edge_id!r} is not on route {self.id!r}") from None

    def stop(self, station_id: str) -> RouteStop:
        for s in self.stops:
            if s.station_id == station_id:
                return s
        raise KeyError(f"station {station_id!r} is not on route {self.id!r}")

    def speed_at(self, chainage_m: float) -> float:
        for a, b, v in self.speed_limits:
            if a <= chainage_m < b:
                return v
        return self.speed_limits[-1][2]

    def to_json(self) -> dict[str, Any]:
        return {
            "id": self.id,
            "edges": list(self.edges),
            "edge_start_m": list(self.edge_start_m),
            "length_m": self.length_m,
            "stops": [vars(s) for s in self.stops],
            "speed_limits": [list(x) for x in self.speed_limits],
            "gradients": [list(x) for x in self.gradients],
            "switches": [vars(s) for s in self.switches],
            "points": [vars(p) for p in self.points],
            "internal_start_m": [list(x) for x in self.internal_start_m],
        }

    @staticmethod
    def from_json(d: dict[str, Any]) -> RouteInfo:
        return RouteInfo(
            id=d["id"],
            edges=tuple(d["edges"]),
            edge_start_m=tuple(d["edge_start_m"]),
            length_m=d["length_m"],
            stops=tuple(RouteStop(**s) for s in d["stops"]),
            speed_limits=tuple(tuple(x) for x in d["speed_limits"]),  # type: ignore[misc]
            gradients=tuple(tuple(x) for x in d["gradients"]),  # type: ignore[misc]
            switches=tuple(RouteSwitch(**s) for s in d["switches"]),
            points=tuple(RoutePoint(**p) for p in d.get("points", [])),
            internal_start_m=tuple((a, b) for a, b in d.get("internal_start_m", [])),
        )


def _merge_runs(runs: Iterable[tuple[float, float, float]]) -> tuple[tuple[float, float, float], ...]:
    """Join adjacent (start, end, value) runs with equal values; drop empty ones."""
    out: list[list[float]] = []
    for a, b, v in runs:
        if b - a <= 1e-9:
            continue
        if out and abs(out[-1][2] - v) < 1e-9 and abs(out[-1][1] - a) < 1e-6:
            out[-1][1] = b
        else:
            out.append([a, b, v])
    return tuple((a, b, v) for a, b, v in out)


def _gradient_runs(
    line_grads: Sequence[Sequence[float]], d0: float, d1: float, r0: float, sign: int
) -> list[tuple[float, float, float]]:
    """Gradient runs over route chainage [r0, r0 + |d1 - d0|] where design position runs d0 -> d1."""
    lo, hi = min(d0, d1), max(d0, d1)
    cuts = {lo, hi}
    for a, b, _ in line_grads:
        for x in (a, b):
            if lo < x < hi:
                cuts.add(x)
    xs = sorted(cuts)
    runs = []
    for a, b in zip(xs, xs[1:]):
        mid = 0.5 * (a + b)
        g = next((p for ga, gb, p in line_grads if ga <= mid < gb), 0.0)
        # route chainage of design positions a and b
        ra, rb = sorted((r0 + sign * (a - d0), r0 + sign * (b - d0)))
        runs.append((ra, rb, sign * g + 0.0))  # + 0.0 turns -0.0 into 0.0
    runs.sort()
    return runs


def _edge_platforms(attrs: dict[str, Any]) -> list[tuple[str, str, float, float]]:
    """``(station, stop_id, start_pos_m, end_pos_m)`` of the platforms on one track piece, in lane order.

    A generated world has at most one (``station``/``stop_id`` attributes); an external net may have several
    on one edge (a ``stops`` list, see :mod:`network.external`).
    """
    if attrs.get("stops"):
        return [(s[0], s[1], s[2], s[3]) for s in attrs["stops"]]
    if attrs.get("stop_id"):
        return [(attrs["station"], attrs["stop_id"], attrs["stop_start_pos_m"], attrs["stop_end_pos_m"])]
    return []


def make_route(graph: nx.DiGraph, route_id: str, edges: Sequence[str]) -> RouteInfo:
    """Chainage, stops, speed limits, gradients, switches and named points of a path through the graph."""
    starts: list[float] = []
    internal: list[tuple[str, float]] = []
    speeds: list[tuple[float, float, float]] = []
    grads: list[tuple[float, float, float]] = []
    switches: list[RouteSwitch] = []
    points: list[RoutePoint] = []
    stops: list[RouteStop] = []
    line_grads: dict[str, list[list[float]]] = graph.graph.get("gradients", {})
    line_points: dict[str, list[Any]] = graph.graph.get("points", {})
    pos = 0.0
    for i, e in enumerate(edges):
        a = graph.nodes[e]
        seg_start = pos  # route chainage where this piece's design span begins (incl. the junction before it)
        if i > 0:
            prev = edges[i - 1]
            if not graph.has_edge(prev, e):
                raise ValueError(f"route {route_id!r}: no connection from {prev!r} to {e!r}")
            c = graph.edges[prev, e]
            if c.get("switch"):
                switches.append(RouteSwitch(c["switch"], pos, c["leg"]))
                switches.extend(RouteSwitch(sid, pos, leg) for sid, leg in c.get("also", ()))
            for lane_id, length, speed in c["via"]:
                internal.append((lane_id.rsplit("_", 1)[0], pos))
                speeds.append((pos, pos + length, speed))
                pos += length
        starts.append(pos)
        length = a["length_m"]
        speeds.append((pos, pos + length, a["speed_mps"]))
        # design position is linear in route chainage over [seg_start, pos + length] (the generator
        # shortens each piece by the internal lane in front of it, so the junction takes its design place)
        sign = a["design_sign"]
        d_at_pos = a["design_start_m"]
        d0 = d_at_pos - sign * (pos - seg_start)
        d1 = d_at_pos + sign * length
        grads += _gradient_runs(line_grads.get(a["line"], []), d0, d1, seg_start, sign)
        for pid, (pline, pm) in line_points.items():
            if pline == a["line"] and min(d0, d1) - 1e-6 <= pm <= max(d0, d1) + 1e-6:
                r = seg_start + sign * (pm - d0)
                if not any(p.point_id == pid for p in points):
                    points.append(RoutePoint(pid, r))
        for station, stop_id, sp, ep in _edge_platforms(a):
            stops.append(RouteStop(station, stop_id, e, sp, ep, pos + sp, pos + ep))
        pos += length
    grads.sort()
    return RouteInfo(
        id=route_id,
        edges=tuple(edges),
        edge_start_m=tuple(starts),
        length_m=pos,
        stops=tuple(stops),
        speed_limits=_merge_runs(speeds),
        gradients=_merge_runs(grads),
        switches=tuple(switches),
        points=tuple(points),
        internal_start_m=tuple(internal),
    )


@dataclass(frozen=True)
class NetworkBundle:
    """A built world: SUMO files plus the topology the engine and the planners need.

    ``routes`` holds the named through-routes (every free line end to every reachable free line end, per
    direction), e.g. ``"yudong->jiangbei-airport-t2"``; :meth:`route_between` makes service routes.
    """

    name: str
    net_file: Path
    stops_file: Path
    topology_file: Path
    graph: nx.DiGraph
    stations: dict[str, StationInfo]
    switches: dict[str, SwitchInfo]
    routes: dict[str, RouteInfo]
    cache_key: str = ""
    build_time_s: float = field(default=0.0, compare=False)
    # external nets (network.external): every additional file SUMO loads, the rail vClass our trains get,
    # what a scenario may call a station (name or stop id -> station id), and the rail-signal choice
    additional_files: tuple[Path, ...] = ()
    vclass: str = "rail_urban"
    station_aliases: dict[str, str] = field(default_factory=dict)
    signals: str = "none"  # generated worlds have none; external: "strip" | "keep"
    n_rail_signals: int = 0  # rail_signal nodes in the user's net

    @functools.cached_property
    def stop_stations(self) -> dict[str, str]:
        """Every platform's stop id -> its station id."""
        return {p.stop_id: sid for sid, st in self.stations.items() for p in st.platforms}

    def route_between(
        self,
        from_station: str,
        to_station: str,
        via: Sequence[str] = (),
        platforms: Mapping[str, str] | None = None,
    ) -> RouteInfo:
        """Route for a service from ``from_station`` to ``to_station`` (optionally through ``via`` stations).

        It starts on the edge holding ``from_station``'s platform in the travel direction (a train starting
        there is inserted with its front at the platform end minus 1 m) and ends on the edge holding
        ``to_station``'s platform. ``platforms`` pins stations to one platform (station id -> stop id); the
        others take the platform of the cheapest route (on an external net: metres, the wrong line of a double
        track costed up, :mod:`network.running_side`). Raises KeyError for an unknown station or platform,
        ValueError if unreachable.
        """
        pins = dict(platforms or {})
        for sid in (from_station, to_station, *via):
            if sid not in self.stations:
                raise KeyError(
                    f"unknown station {sid!r} in world {self.name!r}; known: {', '.join(sorted(self.stations))}"
                )
        for sid, stop_id in pins.items():
            if sid not in self.stations or all(p.stop_id != stop_id for p in self.stations[sid].platforms):
                known = ", ".join(p.stop_id for p in self.stations[sid].platforms) if sid in self.stations else ""
                raise KeyError(f"station {sid!r} has no platform {stop_id!r} (its platforms: {known})")
        if from_station == to_station:
            raise ValueError(f"a route needs two different stations, got {from_station!r} twice")
        chain = (from_station, *via, to_station)
        g = self.graph
        external = g.graph.get("kind") == "external"
        weight = "cost_m" if external else None  # metres; generated worlds: hops
        rid = f"{from_station}->{to_station}" + (f" via {','.join(via)}" if via else "")
        if pins:  # a route id names one path: a pinned route is another one
            rid += " at " + ",".join(pins[s] for s in dict.fromkeys(chain) if s in pins)

        def plats(sid: str) -> list[PlatformInfo]:
            return [p for p in self.stations[sid].platforms if sid not in pins or p.stop_id == pins[sid]]

        def first_cost(edge: str) -> float:
            factor = WRONG_LINE_FACTOR if external and g.nodes[edge].get("wrong_line") else 1.0
            return float(g.nodes[edge]["length_m"]) * factor

        def step_cost(a: str, b: str) -> float:
            return float(g.edges[a, b]["cost_m"]) if external else _step_m(g, a, b)

        # stage by stage over the stations named: the best partial route (cost, edges) ending at each
        # platform of the current station; a generated world has one platform per direction of travel
        partial = [(first_cost(p.edge), [p.edge]) for p in plats(from_station)]
        for sid in chain[1:]:
            extended: list[tuple[float, list[str]]] = []
            for plat in plats(sid):
                best: tuple[float, list[str]] | None = None
                for length, path in partial:
                    try:
                        step = nx.shortest_path(g, path[-1], plat.edge, weight=weight)[1:]
                    except nx.NetworkXNoPath:
                        continue
                    full = path + step
                    if len(set(full)) != len(full):
                        continue  # via stations out of order would revisit track
                    total = length + sum(step_cost(a, b) for a, b in zip(full[len(path) - 1 :], step))
                    if best is None or total < best[0] - 1e-9:
                        best = (total, full)
                if best is not None:
                    extended.append(best)
            partial = extended
        for _, path in sorted(partial, key=lambda c: c[0]):
            route = make_route(g, rid, path)
            if serves_in_order(route, chain):
                return route
        via_txt = f" via {', '.join(via)}" if via else ""
        hint = "end the trip at a turnback instead"
        if external:
            hint = "a service that needs a reversal must be split into two services at the reversal station"
            missing = _unconnected_leg(g, [plats(sid) for sid in chain], chain)
            if missing is not None:
                raise ValueError(
                    f"no route from {from_station!r} to {to_station!r}{via_txt} in world {self.name!r}: no track "
                    f"joins {missing[0]!r} and {missing[1]!r} (a missing connection, or track the trains' vClass may "
                    "not use): not a question of reversing"
                )
        if pins:
            hint = f"the pinned platforms ({', '.join(pins.values())}) may lie on tracks that do not connect; {hint}"
        raise ValueError(
            f"no route from {from_station!r} to {to_station!r}{via_txt} in world {self.name!r} "
            f"(trains do not reverse on the way; {hint})"
        )


def _unconnected_leg(
    g: nx.DiGraph, platforms: Sequence[Sequence[PlatformInfo]], chain: Sequence[str]
) -> tuple[str, str] | None:
    """The first pair of consecutive stations of ``chain`` whose platforms no track joins at all, whatever the
    direction (an edge and its bidi partner are one track), or None when every leg is joined and only the direction
    of travel is wrong (a reversal would be needed)."""
    track = nx.Graph(g.edges())
    track.add_nodes_from(g.nodes)
    track.add_edges_from((n, b) for n, b in g.nodes(data="bidi") if b in g)
    for k in range(len(chain) - 1):
        sources = {p.edge for p in platforms[k]}
        targets = {p.edge for p in platforms[k + 1]}
        reach = set(nx.multi_source_dijkstra_path_length(track, sources)) if sources else set()
        if not reach & targets:
            return chain[k], chain[k + 1]
    return None


def _step_m(g: nx.DiGraph, a: str, b: str) -> float:
    """Metres run from the end of piece ``a`` to the end of piece ``b`` (internal lanes + ``b``)."""
    return sum(v[1] for v in g.edges[a, b]["via"]) + g.nodes[b]["length_m"]


def serves_in_order(route: RouteInfo, chain: Sequence[str]) -> bool:
    """The route's first edge holds the first station, its last edge the last, and all come in order."""
    chain = [c for i, c in enumerate(chain) if i == 0 or c != chain[i - 1]]  # "via" naming an end is harmless
    k = 0
    for rs in route.stops:
        if k < len(chain) and rs.station_id == chain[k] and (k > 0 or rs.edge == route.edges[0]):
            k += 1
    if k < len(chain):
        return False
    last = [rs for rs in route.stops if rs.station_id == chain[-1]]
    return any(rs.edge == route.edges[-1] for rs in last)


Crossings = dict[str, dict[tuple[str, str], list[tuple[str, str]]]]


def flat_crossings(graph: nx.DiGraph, foes: Callable[[str, tuple[str, str], tuple[str, str]], bool]) -> Crossings:
    """The flat crossings of ``graph`` (module docstring): node id -> ``{(from edge, to edge): [foe movements]}``.

    ``foes(node, move1, move2)`` says whether SUMO's foe matrix of ``node`` has the two movements intersect.
    """
    by_node: dict[str, list[tuple[str, str]]] = {}
    for a, b, node in graph.edges(data="node"):
        by_node.setdefault(node, []).append((a, b))
    out: Crossings = {}
    for node_id, moves in sorted(by_node.items()):
        for i, (a, b) in enumerate(moves):
            track1 = {a, b, graph.nodes[a].get("bidi"), graph.nodes[b].get("bidi")}
            for c, d in moves[i + 1 :]:
                if c in track1 or d in track1 or not foes(node_id, (a, b), (c, d)):
                    continue
                at = out.setdefault(node_id, {})
                at.setdefault((a, b), []).append((c, d))
                at.setdefault((c, d), []).append((a, b))
    return out


def _crossings_to_json(crossings: Crossings) -> dict[str, list[list[Any]]]:
    """JSON has no tuple keys: ``{node: [[from, to, [[from, to], ...]], ...]}``."""
    return {n: [[a, b, [list(f) for f in fs]] for (a, b), fs in moves.items()] for n, moves in crossings.items()}


def _crossings_from_json(d: dict[str, list[list[Any]]]) -> Crossings:
    return {n: {(a, b): [(f[0], f[1]) for f in fs] for a, b, fs in rows} for n, rows in d.items()}


def bundle_to_json(bundle: NetworkBundle) -> dict[str, Any]:
    g = bundle.graph
    graph_json = nx.node_link_data(g, edges="links")
    if "crossings" in g.graph:
        graph_json["graph"] = {**g.graph, "crossings": _crossings_to_json(g.graph["crossings"])}
    return {
        "name": bundle.name,
        "cache_key": bundle.cache_key,
        "net_file": bundle.net_file.name,
        "stops_file": bundle.stops_file.name,
        "stations": {
            k: {
                **{
                    f: getattr(v, f)
                    for f in ("id", "name", "line", "km", "platform_length_m", "turnback", "crossover_speed_mps")
                },
                "platforms": [vars(p) for p in v.platforms],
            }
            for k, v in bundle.stations.items()
        },
        "switches": {k: vars(v) for k, v in bundle.switches.items()},
        "routes": {k: v.to_json() for k, v in bundle.routes.items()},
        "graph": graph_json,
    }


def bundle_from_json(d: dict[str, Any], folder: Path, topology_file: Path) -> NetworkBundle:
    graph = nx.node_link_graph(d["graph"], directed=True, edges="links")
    if "crossings" in graph.graph:
        graph.graph["crossings"] = _crossings_from_json(graph.graph["crossings"])
    stations = {}
    for k, v in d["stations"].items():
        plats = tuple(PlatformInfo(**p) for p in v.pop("platforms"))
        stations[k] = StationInfo(**v, platforms=plats)
    return NetworkBundle(
        name=d["name"],
        net_file=folder / d["net_file"],
        stops_file=folder / d["stops_file"],
        topology_file=topology_file,
        graph=graph,
        stations=stations,
        switches={k: SwitchInfo(**v) for k, v in d["switches"].items()},
        routes={k: RouteInfo.from_json(v) for k, v in d["routes"].items()},
        cache_key=d.get("cache_key", ""),
    )
