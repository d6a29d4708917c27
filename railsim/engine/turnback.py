"""Turnbacks and rotations: one unit (one SUMO vehicle) runs a chain of trips and reverses between them.

Without rotations every trip is its own train: inserted at its origin, removed at its destination. With a
``rotations:`` section (:class:`railsim.scenario.model.RotationSpec`) trips are chained into **units**:

* **Chaining.** ``units: auto`` chains first-in-first-out at each station from the *planned* times: each
  departure, in time order, takes the unit that arrived there first among those whose planned arrival plus the
  station's minimum turnback is no later than the departure, and that can reverse from its arrival track onto
  the departure track within :data:`TURNBACK_SEARCH_M` in all; otherwise a new unit starts it. A unit that would
  wait longer than ``max_layover_s`` for its next departure leaves service at its arrival instead (it goes to the
  depot: it does not block a turnback track for hours between the peaks). An explicit list is checked the same
  way (a :class:`ConfigError` when the world has no way to turn a unit round there).
* **Reversal, the way SUMO does it.** SUMO reverses a rail vehicle whose route continues from an edge onto that
  edge's ``bidi`` partner through a turnaround connection: the moment it stands on the first edge, SUMO puts it
  on the partner with its front where its rear was, facing the other way (measured on SUMO 1.28: the flip is
  immediate at standstill anywhere on the edge, and the odometer then reads as if the train had run to the
  edge's end, through the turnaround and back to its new front). The world's usable turnarounds are
  ``graph.graph["reversals"]`` (``network.external``). The turnback path is the shortest path from the arrival
  track to the departure platform's track with exactly one such reversal: on a **bidi platform track** the unit
  reverses where it stands; with a **turnback track beyond the platform** it runs into the track, stops short of
  its end, reverses and runs back to the departure platform (crossover switches on the way are locked as on any
  route). Where no reversal reaches the departure track, a **turning loop** does: the unit runs on round the loop
  (at most :data:`LOOP_SEARCH_M`) to the departure platform and waits there for its departure, with no reversal
  stop (a tram terminus such as Jena's Zwätzen Schleife). A unit that arrives at the very platform its next
  trip departs from, facing the way it departs (a loop terminus with one platform, such as Jena's Winzerla),
  makes no turning move: it departs where it stands, after the station's minimum turnback — on a platform no
  trip runs through, and with ``units: auto`` only while no other trip is planned to arrive there or leave from
  there (a unit laying over would hold them up).
* **The successor's route** is that path followed by the trip's own route; its first stop is a *reversal stop*
  (:data:`REVERSAL`) on the edge before the turnaround. Because the route chainage runs through the
  turnaround's internal lane like SUMO's odometer, the successor's chainage stays equal to SUMO's position
  across the flip (the desync check runs throughout; only the "advance ≤ speed·dt" part is waived while the
  unit stands at its reversal stop).
* **Handover.** When a trip arrives and its unit has a next trip, the SUMO vehicle stays: it gets the
  successor's route and stops (the origin stop held ``until`` max(scheduled departure, arrival + minimum
  turnback)), and the successor is on the line at once, standing. A late incoming unit therefore delays the
  next trip by exactly what it lacks of its turnback minimum (knock-on), and the successor's ``departed_s`` is
  its departure from the origin platform.
* **First in, first out by the actual arrivals** (``units: auto`` only). The chaining is planned; a unit that
  arrives before another unit that was planned to arrive first at the same station on the same track takes the
  earlier departure: at the handover the arriving unit swaps the rest of its day with the unit whose planned
  next trip leaves earliest among those not yet arrived there (``unit_swapped`` event). Otherwise the early unit
  would stand on the departure platform (or in the turnback track) waiting for its later departure, and the unit
  meant for the earlier one would queue behind it — what a dispatcher never lets happen. Trips of a formation
  that couples across the turnback keep their units (their order is checked at set-up), and units of
  different vehicle types never swap. An explicit ``units:`` list is followed as written.

The port answers the loop (``handover``), the dispatcher (``chained``: trips it does not insert)
and the summary (:meth:`Turnbacks.summary`: units, peak units in service, km, traction energy and time coupled
per unit, turnback times achieved against the minimum, late starts caused by the incoming unit).
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable, Iterable, Sequence
from typing import Any, Protocol

import networkx as nx

from network.topology import make_route
from railsim.engine.events.log import EventLog
from railsim.engine.fleet import Fleet
from railsim.engine.routeview import route_view
from railsim.engine.settings import DWELL_REGISTRATION_S, INF
from railsim.engine.train import TrainRuntime
from railsim.engine.trips import REVERSAL, TripStop, sumo_stops
from railsim.engine.wiring import set_once, unwired
from railsim.errors import ConfigError

log = logging.getLogger(__name__)

REVERSAL_HOLD_S = 5.0  # a reversing unit stands at least this long after SUMO flipped it (cab change)
TURNBACK_SEARCH_M = 5000.0  # a turnback path longer than this is not a turnback
LOOP_SEARCH_M = 1500.0  # a path round a turning loop longer than this is a trip, not a turn
END_MARGIN_M = 1.0  # a unit stops this far short of the end of a turnback track
BOARDING_MARGIN_S = 60.0  # a reversed unit is at its departure platform this long before it departs


def reversal_graph(graph: nx.DiGraph) -> nx.DiGraph:
    """The track graph plus one arc per usable turnaround (``reversal=True``), for turnback paths only."""
    g = graph.copy()
    for edge, (bidi, via) in graph.graph.get("reversals", {}).items():
        if edge in g and bidi in g:
            g.add_edge(edge, bidi, node=None, via=via, switch=None, leg=None, reversal=True)
    return g


def _arc_m(g: nx.DiGraph) -> Callable[[str, str, dict[str, Any]], float]:
    return lambda a, b, d: float(g.nodes[b]["length_m"]) + sum(float(v[1]) for v in d.get("via", ()))


def turnback_path(g: nx.DiGraph, from_edge: str, to_edge: str) -> list[str] | None:
    """Shortest edge path ``from_edge`` → ``to_edge`` through exactly one reversal arc; where there is none, the
    shortest path round a **turning loop** (no reversal, at most :data:`LOOP_SEARCH_M`: a tram terminus where the
    track runs round and back to the departure platform); None if there is neither, or if the two are one edge."""
    if from_edge == to_edge:
        # the unit arrives on the very track it departs from, facing the way it departs: a turning move would take
        # it round a loop *and* through a reversal, off along the line and back (Jena's Winzerla, a platform on the
        # trunk at a loop's entrance: 7.6 km out through single track to a stub and back). It departs where it
        # stands (Turnbacks._path) or not at all.
        return None
    weight = _arc_m(g)
    plain = nx.subgraph_view(g, filter_edge=lambda a, b: not g.edges[a, b].get("reversal"))
    ahead = nx.single_source_dijkstra(plain, from_edge, cutoff=TURNBACK_SEARCH_M, weight=weight)
    reversals = {a: b for a, b, rev in g.edges(data="reversal") if rev}
    best: tuple[float, list[str]] | None = None
    if reversals:
        back = nx.single_source_dijkstra(plain.reverse(copy=False), to_edge, cutoff=TURNBACK_SEARCH_M, weight=weight)
        for a, b in sorted(reversals.items()):
            if a not in ahead[0] or b not in back[0]:
                continue
            total = ahead[0][a] + back[0][b]
            if best is None or total < best[0] - 1e-9:
                best = (total, ahead[1][a] + list(reversed(back[1][b])))
    if best is not None:
        return best[1]
    if to_edge != from_edge and ahead[0].get(to_edge, INF) <= LOOP_SEARCH_M:
        return list(ahead[1][to_edge])  # round the loop: the unit runs on to its departure platform
    return None


def _arrival_platform(tr: TrainRuntime) -> tuple[str, str | None]:
    """The edge a trip ends on and the stop it arrives at there (None if its plan has no destination stop)."""
    dest = next((s for s in reversed(tr.trip.stops) if s.is_destination), None)
    return tr.trip.route.edges[-1], None if dest is None else dest.stop_id


def _departure_platform(tr: TrainRuntime) -> tuple[str, str | None]:
    """The edge a trip begins on and the stop it departs from there (None if it has no origin stop)."""
    origin = next((s for s in tr.trip.stops if s.is_origin), None)
    return tr.trip.route.edges[0], None if origin is None else origin.stop_id


def _same_platform(pred: TrainRuntime, succ: TrainRuntime, through: set[str]) -> bool:
    """True if ``succ`` departs from the platform ``pred`` arrives at, in the direction it arrives in, and no trip
    runs through that platform's edge (``through``: the edges trips run over between their first and last): a tram
    terminus where the track runs round a loop past one platform, such as Jena's Winzerla. The unit departs where
    it stands; any turning move would take it off the platform and back to it (at Winzerla a 7.9 km run out along
    the line, through single-track sections, to a reversal and back). A platform other lines run through (a line
    that turns round a city block, such as Helsinki's 5 at Rautatieasema) is not a place to lay over: a unit
    standing there would hold up every tram behind it."""
    arrival = _arrival_platform(pred)
    return arrival[1] is not None and arrival[0] not in through and arrival == _departure_platform(succ)


def _platform_times(trains: Iterable[TrainRuntime]) -> dict[str, list[tuple[float, str]]]:
    """Per edge, the planned times trips arrive on it at their end and leave it at their start, with the trip."""
    times: dict[str, list[tuple[float, str]]] = {}
    for tr in trains:
        arrival_s = tr.trip.planned_arrival_s.get(tr.trip.destination.station_id)
        if arrival_s is not None:
            times.setdefault(tr.trip.route.edges[-1], []).append((arrival_s, tr.train_id))
        times.setdefault(tr.trip.route.edges[0], []).append((tr.trip.depart_s, tr.train_id))
    return times


class SumoReroute(Protocol):
    """What a handover asks of SUMO: the unit's next route and stops."""

    def reroute(self, train_id: str, edges: Sequence[str], stops: Sequence[Any]) -> None: ...


class Turnbacks:
    """Units, their chains of trips, and the handover between two trips of a unit (module docstring)."""

    def __init__(self, fleet: Fleet, graph: nx.DiGraph, spec: Any, events: EventLog, source: Any) -> None:
        """``spec`` is the scenario's :class:`RotationSpec`, or None: no units (every trip its own train)."""
        self.fleet = fleet
        self.spec = spec
        self.events = events
        self.source = source
        self.graph = reversal_graph(graph) if spec is not None else graph
        self.units: dict[str, list[str]] = {}  # unit id -> trip ids in running order
        self.next_of: dict[str, str] = {}  # trip id -> the unit's next trip
        self.prev_of: dict[str, str] = {}
        self.turnbacks: list[dict[str, Any]] = []  # one row per handover
        self._paths: dict[tuple[str, str], list[str] | None] = {}
        self._pinned: set[str] = set()  # trips whose unit is fixed: a formation coupling across their turnback
        self._loops: set[str] = set()  # trips whose unit turns round a loop (no reversal) before them
        self._standing: set[str] = set()  # trips whose unit arrives at their departure platform (no move at all)
        # edges some trip runs over between its first and its last (no unit lays over on them: _same_platform)
        self._through: set[str] = set()
        self._platform_times: dict[str, list[tuple[float, str]]] | None = None  # _platform_free, made when asked
        self.swaps = 0
        self.bridge: SumoReroute = unwired("Turnbacks", "bridge")  # exists while the run is under way: connect()
        if spec is None:
            return
        self._through = {e for tr in fleet.trains.values() for e in tr.trip.route.edges[1:-1]}
        self._chain()
        for uid, trips in self.units.items():
            for tid in trips:
                self.fleet.trains[tid].sumo_id = uid
                self.fleet.trains[tid].unit_id = uid
        for tid, pid in self.prev_of.items():
            self._reroute(self.fleet.trains[tid], self.fleet.trains[pid])

    # ------------------------------------------------------------------ chaining
    def _path(self, pred: TrainRuntime, succ: TrainRuntime) -> list[str] | None:
        if _same_platform(pred, succ, self._through):
            return [succ.trip.route.edges[0]]  # it stands at its departure platform already: no turning move
        return self._path_edges(pred.trip.route.edges[-1], succ.trip.route.edges[0])

    def _short_path(self, from_edge: str, to_edge: str) -> bool:
        """For ``units: auto``: a turnback path no longer than :data:`TURNBACK_SEARCH_M` in all (the search reaches
        that far out and as far back: Jena's Lobeda-West units ran 6.3 km out through single track and back)?"""
        path = self._path_edges(from_edge, to_edge)
        return path is not None and sum(float(self.graph.nodes[e]["length_m"]) for e in path[1:]) <= TURNBACK_SEARCH_M

    def _path_edges(self, from_edge: str, to_edge: str) -> list[str] | None:
        key = (from_edge, to_edge)
        if key not in self._paths:
            self._paths[key] = turnback_path(self.graph, *key)
        return self._paths[key]

    def _platform_free(self, pred: TrainRuntime, succ: TrainRuntime) -> bool:
        """For ``units: auto``: may ``pred``'s unit stand at its arrival platform until ``succ`` departs from it?
        Not where it would stand there (:func:`_same_platform`) while another trip is planned to arrive there or
        leave from there: the platform is the plan's until the unit leaves. Four Potsdam lines ending at one loop
        platform (Platz der Einheit), each unit laying over there for minutes with the next ones queued behind it,
        held each other up round the loop until none could move. Units that turn any other way always may."""
        if not _same_platform(pred, succ, self._through):
            return True
        if self._platform_times is None:
            self._platform_times = _platform_times(self.fleet.trains.values())
        t0 = pred.trip.planned_arrival_s.get(pred.trip.destination.station_id, INF)
        t1 = succ.trip.depart_s
        return not any(
            t0 < t < t1 and other not in (pred.train_id, succ.train_id)
            for t, other in self._platform_times.get(pred.trip.route.edges[-1], ())
        )

    def _ready_s(self, tr: TrainRuntime) -> float:
        """When the unit of ``tr`` may leave again by the plan: planned arrival + minimum turnback (never, for a
        trip whose plan has no arrival: chaining it from its departure time would invent a turnback)."""
        dest = tr.trip.destination.station_id
        arrival_s = tr.trip.planned_arrival_s.get(dest)
        if arrival_s is None:
            return INF
        return arrival_s + self.spec.turnback_min_at(dest)

    def _warn_unturnable(self, order: list[TrainRuntime]) -> None:
        """One warning line per terminus where trips arrive and later trips depart but no arriving unit can turn
        onto any departure (``units: auto`` then starts a new unit for each), naming the reason; and one per trip
        whose plan has no arrival (it is never chained)."""
        for tr in order:
            if tr.trip.destination.station_id not in tr.trip.planned_arrival_s:
                log.warning(
                    "rotations: %s is not chained to a next trip: its plan never reaches %s (no planned arrival)",
                    tr.train_id,
                    tr.trip.destination.station_id,
                )
        arriving: dict[str, set[str]] = {}
        departing: dict[str, set[str]] = {}
        in_place: set[str] = set()  # stations where a unit can depart from the platform it arrives at
        platforms: dict[str, tuple[set[Any], set[Any]]] = {}
        for tr in order:
            arriving.setdefault(tr.trip.destination.station_id, set()).add(tr.trip.route.edges[-1])
            departing.setdefault(tr.trip.origin.station_id, set()).add(tr.trip.route.edges[0])
            platforms.setdefault(tr.trip.destination.station_id, (set(), set()))[0].add(_arrival_platform(tr))
            platforms.setdefault(tr.trip.origin.station_id, (set(), set()))[1].add(_departure_platform(tr))
        for station, (ins_p, outs_p) in platforms.items():
            if any(p[1] is not None and p[0] not in self._through for p in ins_p & outs_p):
                in_place.add(station)
        reversals = {a for a, _, rev in self.graph.edges(data="reversal") if rev}
        plain = nx.subgraph_view(self.graph, filter_edge=lambda a, b: not self.graph.edges[a, b].get("reversal"))
        weight = _arc_m(self.graph)
        for station in sorted(set(arriving) & set(departing)):
            ins, outs = sorted(arriving[station]), sorted(departing[station])
            if station in in_place or any(self._short_path(a, d) for a in ins for d in outs):
                continue
            reach: set[str] = set()
            for a in ins:
                reach |= set(nx.single_source_dijkstra_path_length(plain, a, cutoff=TURNBACK_SEARCH_M, weight=weight))
            shared = sorted(set(ins) & set(outs) & self._through)
            if shared:
                why = (
                    f"units arrive on the track they leave by ({', '.join(shared)}), and other trips run through "
                    "that platform: a unit does not lay over there"
                )
            elif not reach & reversals:
                why = (
                    f"dead end: no turnaround within {TURNBACK_SEARCH_M:g} m of the arrival track "
                    f"({', '.join(ins)}; a unit reverses on a bidi edge with a turnaround)"
                )
            else:
                why = (
                    f"the arrival platforms ({', '.join(ins)}) and departure platforms ({', '.join(outs)}) lie on "
                    "different tracks with no turnaround between them"
                )
            log.warning("rotations: no unit can turn at %s: %s; every departure there starts a new unit", station, why)

    def _chain(self) -> None:
        trains = self.fleet.trains
        if self.spec.units is not None:
            for uid, chain in self.spec.units.items():
                for k in range(1, len(chain)):
                    pred, succ = trains[chain[k - 1]], trains[chain[k]]
                    ends, starts = pred.trip.destination.station_id, succ.trip.origin.station_id
                    if ends != starts:
                        raise ConfigError(
                            self.source,
                            f"rotations.units.{uid}[{k}]",
                            f"trip {succ.train_id!r} starts at {starts!r}, but the unit ends {pred.train_id!r} at {ends!r}",
                        )
                    if self._path(pred, succ) is None:
                        raise ConfigError(
                            self.source,
                            f"rotations.units.{uid}[{k}]",
                            f"the world has no turnaround from {pred.trip.route.edges[-1]!r} (where {pred.train_id} "
                            f"arrives) to {succ.trip.route.edges[0]!r} (where {succ.train_id} departs)",
                        )
                    self.next_of[pred.train_id], self.prev_of[succ.train_id] = succ.train_id, pred.train_id
                self.units[uid] = list(chain)
            return
        waiting: dict[str, list[TrainRuntime]] = {}  # station -> units' last trips, in arrival order
        order = sorted(trains.values(), key=lambda tr: (tr.trip.depart_s, tr.train_id))
        self._warn_unturnable(order)
        busy: dict[str, int] = {}  # station -> departures not given a unit standing at their platform (_platform_free)
        for tr in order:
            pool = waiting.setdefault(tr.trip.origin.station_id, [])
            for gone in [p for p in pool if tr.trip.depart_s - self._ready_s(p) > self.spec.max_layover_s]:
                pool.remove(gone)  # nothing to run within its layover: it leaves service (to the depot)
            pick = next(
                (
                    p
                    for p in pool
                    if self._ready_s(p) <= tr.trip.depart_s + 1e-9
                    and (
                        _same_platform(p, tr, self._through)
                        or self._short_path(p.trip.route.edges[-1], tr.trip.route.edges[0])
                    )
                    and self._platform_free(p, tr)
                ),
                None,
            )
            if pick is None:
                uid = f"unit{len(self.units) + 1:02d}"
                self.units[uid] = [tr.train_id]
                if any(self._ready_s(p) <= tr.trip.depart_s + 1e-9 and not self._platform_free(p, tr) for p in pool):
                    busy[tr.trip.origin.station_id] = busy.get(tr.trip.origin.station_id, 0) + 1
            else:
                pool.remove(pick)
                uid = next(u for u, c in self.units.items() if c[-1] == pick.train_id)
                self.units[uid].append(tr.train_id)
                self.next_of[pick.train_id], self.prev_of[tr.train_id] = tr.train_id, pick.train_id
            dest_pool = waiting.setdefault(tr.trip.destination.station_id, [])
            dest_pool.append(tr)
            dest_pool.sort(key=lambda p: (p.trip.planned_arrival_s.get(p.trip.destination.station_id, 0.0), p.train_id))
        for station, n in sorted(busy.items()):
            log.warning(
                "rotations: at %s a unit could depart from the platform it arrives at, but other trips are planned "
                "to arrive there or leave from there while it would stand there: %d departure(s) start a new unit",
                station,
                n,
            )

    def link(self, pred: TrainRuntime, succ: TrainRuntime) -> None:
        """Chain ``succ`` right after ``pred`` in the unit one of them already belongs to (a depot run,
        ``railsim.engine.depot``). The unit turns back between them (the caller checked a turnback path exists),
        or, when ``pred`` ends on the edge ``succ`` starts from, ``succ`` departs where the unit stands."""
        uid = pred.unit_id or succ.unit_id
        assert uid is not None
        chain = self.units[uid]
        if succ.unit_id == uid:  # a run before the unit's first trip
            chain.insert(0, pred.train_id)
        else:
            chain.append(succ.train_id)
        self.next_of[pred.train_id], self.prev_of[succ.train_id] = succ.train_id, pred.train_id
        for tr in (pred, succ):
            tr.sumo_id = tr.unit_id = uid
        if pred.trip.route.edges[-1] != succ.trip.route.edges[0]:
            self._reroute(succ, pred)

    def connect(self, bridge: SumoReroute) -> None:
        """The SUMO bridge, once the run has started it."""
        set_once(self, "bridge", bridge)

    def chained(self, train_id: str) -> bool:
        """True for a trip that starts by its unit's reversal (the dispatcher does not insert it)."""
        return train_id in self.prev_of

    def _in_place(self, succ: TrainRuntime) -> bool:
        """True if the unit that starts chained trip ``succ`` reverses where it stands (a bidi platform), not on a
        track beyond it: its route (the turnback path first) turns round on its very first edge."""
        edges = succ.trip.route.edges
        return len(edges) > 1 and bool(self.graph.edges[edges[0], edges[1]].get("reversal"))

    def check_formation_order(
        self, pairs: list[tuple[str, TrainRuntime, TrainRuntime]], leader_id: Callable[[str], str | None]
    ) -> None:
        """A formation of two trips that both start by a turnback must name as leader the unit that stands in front
        afterwards: the first to arrive, when the units turn on a track beyond the platform (first in, first out).
        Two units cannot both reverse where they stand on one bidi track (a SUMO limit, measured: the message
        says so). ``pairs``: (scenario field, leader, follower); ``leader_id(trip)``: the trip's leader in a
        formation (the arrival order of a coupled pair)."""
        for where, lead, fol in pairs:
            if not (self.chained(lead.train_id) and self.chained(fol.train_id)):
                continue
            pl, pf = self.fleet.trains[self.prev_of[lead.train_id]], self.fleet.trains[self.prev_of[fol.train_id]]
            st_l, st_f = pl.trip.destination.station_id, pf.trip.destination.station_id
            if st_l != st_f:
                continue  # the leader comes through from elsewhere: the follower waits for it (FormationBook)
            # arrival order: planned arrival, a coupled pair's follower behind its leader
            key_l = (pl.trip.planned_arrival_s.get(st_l, pl.trip.depart_s), int(leader_id(pl.train_id) == pf.train_id))
            key_f = (pf.trip.planned_arrival_s.get(st_l, pf.trip.depart_s), int(leader_id(pf.train_id) == pl.train_id))
            first, last = (pl, pf) if key_l <= key_f else (pf, pl)
            self._pinned.update((lead.train_id, fol.train_id))
            if self._in_place(lead) and self._in_place(fol):
                raise ConfigError(
                    self.source,
                    where,
                    f"both units would reverse where they stand at {st_l!r}, one behind the other on one bidi track: "
                    "SUMO 1.28 then keeps them on the lane in their old order and reports them colliding until they "
                    "leave it; turn them on a track beyond the platform, or run the trips as separate trains",
                )
            if first is not pl:  # first in, first out through the track beyond the platform
                raise ConfigError(
                    self.source,
                    where,
                    f"after the turnback at {st_l!r} the unit of {self.next_of[first.train_id]!r} stands in front "
                    f"(first in, first out): make {self.next_of[first.train_id]!r} the leader",
                )

    # ------------------------------------------------------------------ the successor's route
    def _reroute(self, succ: TrainRuntime, pred: TrainRuntime) -> None:
        path = self._path(pred, succ)
        assert path is not None  # _chain only chains trips it found a path for
        trip = succ.trip
        if _same_platform(pred, succ, self._through):  # it departs where it stands: the trip's own route and stops
            self._standing.add(succ.train_id)
            return
        edges = path + list(trip.route.edges[1:])
        route = make_route(self.graph, f"{pred.trip.route.edges[-1]}~>{trip.route.id}", edges)
        k0 = len(path) - 1  # the old route's first edge in the new route
        shift_m = route.edge_start_m[k0] - trip.route.edge_start_m[0]
        moved = tuple(
            dataclasses.replace(
                s,
                mark_m=s.mark_m + shift_m,
                window_start_m=s.window_start_m + shift_m,
                window_end_m=s.window_end_m + shift_m,
            )
            for s in trip.stops
        )
        trip.route = route
        trip.frame_shift_m = shift_m
        succ.view = route_view(route)
        succ.next_stop = 0
        kr = next((i for i in range(len(edges) - 1) if self.graph.edges[edges[i], edges[i + 1]].get("reversal")), None)
        if kr is None:  # round a turning loop: no reversal, the unit runs on to its departure platform
            self._loops.add(succ.train_id)
            trip.stops = moved
            return
        end_m = route.edge_start_m[kr] + self.graph.nodes[edges[kr]]["length_m"]
        length_m = trip.vehicle.length_m
        reversal = TripStop(
            station_id=trip.origin.station_id,
            stop_id=edges[kr + 1],  # the edge SUMO puts the unit on when it reverses
            mark_m=end_m - END_MARGIN_M,
            window_start_m=route.edge_start_m[kr] + length_m,
            window_end_m=end_m,
            dwell_s=REVERSAL_HOLD_S,
            kind=REVERSAL,
        )
        trip.stops = (reversal, *moved)

    # ------------------------------------------------------------------ run time
    def handover(self, t: float, pred: TrainRuntime) -> TrainRuntime | None:
        """``pred`` arrived; its unit starts the next trip where it stands (module docstring). None if its unit
        has no next trip (it leaves the line)."""
        if pred.train_id not in self.next_of:
            return None
        if self.spec.units is None:
            self._first_in_first_out(t, pred)
        succ = self.fleet.trains[self.next_of[pred.train_id]]
        trip = succ.trip
        lane_pos_m = pred.front_m - pred.view.edge_start_m[-1]
        front_m = succ.view.edge_start_m[0] + lane_pos_m
        rev = trip.stops[0]
        reverses = rev.kind == REVERSAL  # else it runs round a loop, or departs where it stands (``link``)
        loops = succ.train_id in self._loops
        standing = succ.train_id in self._standing  # it arrived at its departure platform: a turnback in place
        if reverses and front_m >= rev.window_start_m - 1e-6:  # on the reversal edge already: it reverses here
            trip.stops = (dataclasses.replace(rev, mark_m=front_m), *trip.stops[1:])
        arrival_s = pred.arrived_s if pred.arrived_s is not None else t
        # a unit that runs on where it stands (into or out of a depot run) does not turn back: no minimum
        turns = reverses or loops or standing
        min_s = self.spec.turnback_min_at(pred.trip.destination.station_id) if turns else 0.0
        until_s = max(trip.depart_s + trip.departure_delay_s, arrival_s + min_s)  # a primary late start too
        # standing where it arrived, SUMO runs the new origin stop as the one it is at: hold it by its duration;
        # a unit that runs to its departure platform first is held there by ``until``
        origin_s = DWELL_REGISTRATION_S if reverses or loops else max(DWELL_REGISTRATION_S, until_s - t)
        stops = sumo_stops(trip.stops, origin_until_s=until_s, origin_duration_s=origin_s, route=trip.route)
        self.bridge.reroute(succ.sumo_id, trip.route.edges, stops)
        odometer_m = pred.front_m - pred.depart_chainage_m
        succ.depart_chainage_m = front_m - odometer_m
        succ.front_m = succ.start_front_m = front_m
        succ.plant = pred.plant
        self.fleet.start(succ, "running")
        succ.inserted_s = t
        succ.next_stop = 0
        succ.reversing = reverses
        succ.hold_until_s = until_s - _positioning_s(succ) if reverses else None  # wait off the platform while early
        self.turnbacks.append(
            {
                "unit": succ.unit_id,
                "station": pred.trip.destination.station_id,
                "from_trip": pred.train_id,
                "to_trip": succ.train_id,
                "arrived_s": arrival_s,
                "scheduled_departure_s": trip.depart_s,
                "min_s": min_s,
                "earliest_departure_s": until_s,
                "knock_on_s": max(0.0, arrival_s + min_s - trip.depart_s),
            }
        )
        self.events.record(
            t,
            "unit_turnback",
            succ.train_id,
            unit=succ.unit_id,
            after=pred.train_id,
            station=pred.trip.destination.station_id,
            earliest_departure_s=round(until_s, 3),
            **({"loop": True} if loops else {}),
            **({"in_place": True} if standing else {}),
        )
        return succ

    def _first_in_first_out(self, t: float, pred: TrainRuntime) -> None:
        """``pred`` arrived: if a unit planned to arrive here before it on the same track has not, and that
        unit's next trip leaves before ``pred``'s, the two units swap the rest of their days (module docstring)."""
        trains = self.fleet.trains
        succ = trains[self.next_of[pred.train_id]]
        if succ.train_id in self._pinned:
            return
        end_edge = pred.trip.route.edges[-1]
        best: tuple[tuple[float, str], str] | None = None  # ((departure, next trip), the late predecessor)
        for p_id, c_id in self.next_of.items():
            p, c = trains[p_id], trains[c_id]
            if (
                p_id == pred.train_id
                or p.arrived_s is not None
                or p.status == "removed"
                or c_id in self._pinned
                or p.trip.route.edges[-1] != end_edge
                or c.trip.vehicle_name != succ.trip.vehicle_name
                or c.trip.depart_s >= succ.trip.depart_s
            ):
                continue
            if best is None or (c.trip.depart_s, c_id) < best[0]:
                best = ((c.trip.depart_s, c_id), p_id)
        if best is None:
            return
        late = trains[best[1]]
        uid_a, uid_b = pred.unit_id, late.unit_id
        assert uid_a is not None and uid_b is not None
        chain_a, chain_b = self.units[uid_a], self.units[uid_b]
        ia, ib = chain_a.index(pred.train_id), chain_b.index(late.train_id)
        tail_a, tail_b = chain_a[ia + 1 :], chain_b[ib + 1 :]
        self.units[uid_a], self.units[uid_b] = chain_a[: ia + 1] + tail_b, chain_b[: ib + 1] + tail_a
        for uid, tail in ((uid_a, tail_b), (uid_b, tail_a)):
            for tid in tail:
                trains[tid].sumo_id = trains[tid].unit_id = uid
        self.next_of[pred.train_id], self.prev_of[tail_b[0]] = tail_b[0], pred.train_id
        self.next_of[late.train_id], self.prev_of[tail_a[0]] = tail_a[0], late.train_id
        self.swaps += 1
        self.events.record(
            t,
            "unit_swapped",
            pred.train_id,
            unit=uid_a,
            takes=tail_b[0],
            instead_of=tail_a[0],
            late_unit=uid_b,
            late_trip=late.train_id,
            station=pred.trip.destination.station_id,
        )

    # ------------------------------------------------------------------ results
    def summary(self) -> dict[str, Any]:
        """Fleet and turnback KPIs (module docstring)."""
        trains = self.fleet.trains
        spans: list[tuple[float, int]] = []
        km: dict[str, float] = {}
        energy_kwh: dict[str, float] = {}
        coupled_s: dict[str, float] = {}
        for uid, chain in self.units.items():
            first, last = trains[chain[0]], trains[chain[-1]]
            start = first.inserted_s
            end = last.arrived_s if last.arrived_s is not None else None
            km[uid] = round(sum(_run_m(trains[tid]) for tid in chain) / 1000.0, 3)
            energy_kwh[uid] = round(sum(trains[tid].energy_j for tid in chain) / 3.6e6, 3)
            coupled_s[uid] = round(sum(trains[tid].coupled_s for tid in chain), 3)
            if start is not None:
                spans += [(start, 1), (end if end is not None else float("inf"), -1)]
        peak = cur = 0
        for _, d in sorted(spans, key=lambda x: (x[0], x[1])):
            cur += d
            peak = max(peak, cur)
        rows: list[dict[str, Any]] = []
        for row in self.turnbacks:
            if trains[row["from_trip"]].trip.kind != "service" or trains[row["to_trip"]].trip.kind != "service":
                continue  # into or out of a depot run: the depot block counts those (railsim.engine.depot)
            succ = trains[row["to_trip"]]
            dep = succ.departed_s
            achieved = None if dep is None else dep - row["arrived_s"]
            rows.append(
                {
                    **{k: (round(v, 3) if isinstance(v, float) else v) for k, v in row.items()},
                    "departed_s": None if dep is None else round(dep, 3),
                    "achieved_s": None if achieved is None else round(achieved, 3),
                }
            )
        achieved_ok = all(r["achieved_s"] is None or r["achieved_s"] >= r["min_s"] - 1e-6 for r in rows)
        late = [r for r in rows if r["knock_on_s"] > 0.0]
        return {
            "units_used": len(self.units),
            "peak_units_in_service": peak,
            "km_per_unit": km,
            "energy_kwh_per_unit": energy_kwh,  # traction energy of all its trips (trips.csv has each trip's)
            "coupled_s_per_unit": coupled_s,  # time it ran virtually coupled behind a leader (trips.csv)
            "trips_per_unit": {u: len(c) for u, c in self.units.items()},
            "turnbacks": rows,
            "turnback_min_respected": achieved_ok,
            "late_starts_from_incoming_unit": len(late),
            "units_swapped": self.swaps,
            "knock_on_delay_s": round(sum(r["knock_on_s"] for r in late), 3),
        }


def _positioning_s(tr: TrainRuntime) -> float:
    """How long before its departure a reversed unit leaves its reversal point: the run to its origin platform
    (accelerate to the stretch's lowest limit, run, brake) plus :data:`BOARDING_MARGIN_S`."""
    rev, origin = tr.trip.stops[0], tr.trip.origin
    distance_m = max(0.0, origin.mark_m - rev.window_end_m)
    veh = tr.trip.vehicle
    v = min(tr.trip.route.speed_at(rev.window_end_m), tr.trip.route.speed_at(origin.mark_m), veh.max_speed_mps)
    accel = veh.traction_max_force_n / veh.effective_mass_kg
    return distance_m / v + v / (2.0 * accel) + v / (2.0 * veh.service_decel_mps2) + BOARDING_MARGIN_S


def _run_m(tr: TrainRuntime) -> float:
    """How far a trip's train ran (0 if it never ran)."""
    if tr.inserted_s is None:
        return 0.0
    return max(0.0, tr.front_m - tr.start_front_m)
