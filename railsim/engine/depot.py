"""Depot runs: a unit leaves a depot before its first trip and returns to one after its last.

With ``rotations: {depots: ...}`` (:class:`railsim.scenario.model.RotationSpec`) every unit of
:class:`railsim.engine.turnback.Turnbacks` gets two extra trips, run empty without service stops:

* **Where depots are.** A generated world's depots are lead tracks joined to both running tracks by one switch
  each (``network.generator``); ``graph.graph["depots"]`` names, per depot, the edge a unit starts its day on
  (``start_edge``, with the trainStop ``<id>.out``) and the one it ends it on (``end_edge``, ``<id>.in``). The
  depot is a *station* of the run's trips (``stops.csv`` lists it) but not of the line (no km, no sections).
* **Routes without a reversal of their own.** A depot run goes from the lead to a platform of the unit's first
  origin (a *depot-out* run), or from a platform of its last destination to the lead (*depot-in*), the shortest
  way on the track graph without reversing. If that platform is the one the trip departs from (the one the last
  trip arrived at) the unit stands there and runs on (``Turnbacks.link``: no turnback); if it is the opposite
  platform, the unit reverses exactly as between two service trips (turnback track, pocket or bidi platform:
  ``Turnbacks`` re-routes the successor, locks and minimum turnback included). So a depot run reverses at most
  once, and always the way every other turnback does.
* **Which depot.** ``depot: auto`` takes, per unit and separately for the start and the end of its day, the
  depot with the shortest track distance (depot run plus turnback, if any); a depot id takes that depot
  (``by_unit`` per unit). An id the world does not have, a unit that does not exist, or a named depot from
  which the unit's station cannot be reached is a :class:`ConfigError` naming the field (exit 2); with
  ``auto`` a unit no depot reaches keeps its old start and end (counted in the summary).
* **When.** A depot-out run is planned (free run, like every trip) to arrive at its platform
  :data:`DEPOT_OUT_SLACK_S` before the first departure, and the station's minimum turnback earlier still when it
  turns back there; a depot-in run leaves at the last trip's planned arrival, or the minimum turnback after it
  when it turns back first (``Turnbacks.handover`` holds both to max(plan, arrival + minimum); a unit that runs
  on where it stands has no minimum: it does not block a through platform). The dispatcher
  inserts a depot-out run on the lead like any departure (held while the lead or the line is occupied), never
  before the run starts (a first trip too early for that starts late); a depot-in run ends with its unit
  removed at the far end of the lead. ``late_first_departures`` counts units whose first trip left more than a
  minute after its scheduled departure.
* **In the outputs** a depot run is a trip of service ``depot_out`` / ``depot_in`` (``Trip.kind``): in
  ``trips.csv``, ``stops.csv``, the trace and the train graph, locking switches like any route, and counted in
  its unit's km, but not in the service counts of ``summary.json`` (trips, stops) nor in its turnback rows.
  :meth:`Depots.summary` adds to the ``fleet`` block: depot runs, empty km per unit, units per depot at the
  start and the end of the day.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

import networkx as nx

from network.topology import make_route
from railsim.engine.fleet import Fleet
from railsim.engine.train import TrainRuntime
from railsim.engine.trips import Trip, make_stops
from railsim.engine.turnback import Turnbacks, turnback_path
from railsim.errors import ConfigError

log = logging.getLogger(__name__)

DEPOT_OUT = "depot_out"
DEPOT_IN = "depot_in"
AUTO = "auto"
LATE_FIRST_S = 60.0  # a first trip leaving later than this after its schedule is a late start from the depot
DEPOT_OUT_SLACK_S = 60.0  # a depot-out run is planned this much earlier still: switch throws, the lead's release


def _half_lengths(g: nx.DiGraph) -> Callable[[str, str, dict[str, Any]], float]:
    """Arc weight = half of each edge's length: symmetric, so one reversed search measures "to the depot"."""
    return lambda a, b, _d: 0.5 * (float(g.nodes[a]["length_m"]) + float(g.nodes[b]["length_m"]))


class Depots:
    """The depot runs of every unit (module docstring)."""

    def __init__(
        self,
        fleet: Fleet,
        turnbacks: Turnbacks,
        bundle: Any,
        scenario: Any,
        dt_s: float,
        step_method: str,
    ) -> None:
        self.fleet = fleet
        self.turnbacks = turnbacks
        self.spec = scenario.rotations
        self.source = scenario.source
        self.graph: nx.DiGraph = bundle.graph
        self.stations = bundle.stations
        self.runs: dict[str, dict[str, str]] = {}  # unit -> {"out": trip id, "in": trip id, "out_depot", "in_depot"}
        self.unreached: list[str] = []  # units (auto) no depot reaches
        if self.spec is None or self.spec.depot is None:
            return
        self.depots: dict[str, dict[str, Any]] = dict(self.graph.graph.get("depots", {}))
        self._check_names()
        weight = _half_lengths(self.graph)
        self._from_depot = {
            d: nx.single_source_dijkstra(self.graph, v["start_edge"], weight=weight) for d, v in self.depots.items()
        }
        self._to_depot = {
            d: nx.single_source_dijkstra(self.graph.reverse(copy=False), v["end_edge"], weight=weight)
            for d, v in self.depots.items()
        }
        for uid, chain in list(turnbacks.units.items()):
            self._add_runs(uid, fleet.trains[chain[0]], fleet.trains[chain[-1]], scenario, dt_s, step_method)

    # ------------------------------------------------------------------ set-up
    def _check_names(self) -> None:
        known = sorted(self.depots)
        if not known:
            raise ConfigError(self.source, "rotations.depots", "expected a world with depots, got none in this world")
        wanted = [("rotations.depots.depot", self.spec.depot)]
        wanted += [(f"rotations.depots.by_unit.{u}", d) for u, d in self.spec.depot_by_unit.items()]
        for where, name in wanted:
            if name != AUTO and name not in self.depots:
                raise ConfigError(
                    self.source, where, f"expected 'auto' or a depot of the world ({', '.join(known)}), got {name!r}"
                )
        for uid in self.spec.depot_by_unit:
            if uid not in self.turnbacks.units:
                raise ConfigError(
                    self.source,
                    f"rotations.depots.by_unit.{uid}",
                    f"expected a unit of the rotations ({len(self.turnbacks.units)} units, e.g. "
                    f"{', '.join(list(self.turnbacks.units)[:3])}), got {uid!r}",
                )

    def _turn_m(self, from_edge: str, to_edge: str) -> float | None:
        """0 when the unit stands on ``to_edge`` already; the turnback path's length; None if it cannot turn."""
        if from_edge == to_edge:
            return 0.0
        path = turnback_path(self.turnbacks.graph, from_edge, to_edge)
        return None if path is None else sum(float(self.graph.nodes[e]["length_m"]) for e in path[1:])

    def _out_route(self, depot: str, first: TrainRuntime) -> tuple[float, list[str]] | None:
        """(track distance, edges) of the shortest depot-out run to ``first``'s origin station, or None."""
        dist, paths = self._from_depot[depot]
        best: tuple[float, list[str]] | None = None
        for plat in self.stations[first.trip.origin.station_id].platforms:
            turn_m = self._turn_m(plat.edge, first.trip.route.edges[0]) if plat.edge in dist else None
            if turn_m is not None and (best is None or dist[plat.edge] + turn_m < best[0] - 1e-9):
                best = (dist[plat.edge] + turn_m, paths[plat.edge])
        return best

    def _in_route(self, depot: str, last: TrainRuntime) -> tuple[float, list[str]] | None:
        """(track distance, edges) of the shortest depot-in run from ``last``'s destination station, or None."""
        dist, paths = self._to_depot[depot]
        best: tuple[float, list[str]] | None = None
        for plat in self.stations[last.trip.destination.station_id].platforms:
            turn_m = self._turn_m(last.trip.route.edges[-1], plat.edge) if plat.edge in dist else None
            if turn_m is not None and (best is None or dist[plat.edge] + turn_m < best[0] - 1e-9):
                best = (dist[plat.edge] + turn_m, list(reversed(paths[plat.edge])))
        return best

    def _choose(
        self, uid: str, find: Callable[[str], tuple[float, list[str]] | None], what: str
    ) -> tuple[str, list[str]] | None:
        """The depot (and route) for one end of a unit's day: the named one, or the nearest (module docstring)."""
        name = self.spec.depot_by_unit.get(uid, self.spec.depot)
        if name != AUTO:
            found = find(name)
            if found is None:
                where = (
                    f"rotations.depots.by_unit.{uid}" if uid in self.spec.depot_by_unit else "rotations.depots.depot"
                )
                raise ConfigError(self.source, where, f"depot {name!r} has no track to {what} of unit {uid!r}")
            return name, found[1]
        options = [(found[0], d, found[1]) for d in sorted(self.depots) if (found := find(d)) is not None]
        if not options:
            return None
        _, depot, edges = min(options, key=lambda o: (o[0], o[1]))
        return depot, edges

    def _add_runs(
        self, uid: str, first: TrainRuntime, last: TrainRuntime, scenario: Any, dt_s: float, step_method: str
    ) -> None:
        out = self._choose(
            uid, lambda d: self._out_route(d, first), f"the first origin {first.trip.origin.station_id!r}"
        )
        back = self._choose(
            uid, lambda d: self._in_route(d, last), f"from the last stop {last.trip.destination.station_id!r}"
        )
        if out is None or back is None:
            self.unreached.append(uid)
            log.warning("unit %s: no depot reaches its first origin or last destination; it runs no depot runs", uid)
            return
        origin = first.trip.origin.station_id
        turns = out[1][-1] != first.trip.route.edges[0]  # it reaches the opposite platform: it turns back there
        turn_s = self.spec.turnback_min_at(origin) if turns else 0.0
        ready_s = first.trip.depart_s - turn_s - DEPOT_OUT_SLACK_S
        run_out = self._run(DEPOT_OUT, uid, out[1], out[0], origin, first.trip, scenario, dt_s, step_method, ready_s)
        dest = last.trip.destination.station_id
        turns = back[1][0] != last.trip.route.edges[-1]
        leave_s = last.trip.planned_arrival_s.get(dest, last.trip.depart_s)
        leave_s += self.spec.turnback_min_at(dest) if turns else 0.0
        run_in = self._run(DEPOT_IN, uid, back[1], dest, back[0], last.trip, scenario, dt_s, step_method, None, leave_s)
        self.turnbacks.link(run_out, first)
        self.turnbacks.link(last, run_in)
        self.runs[uid] = {"out": run_out.train_id, "in": run_in.train_id, "out_depot": out[0], "in_depot": back[0]}

    def _run(
        self,
        kind: str,
        uid: str,
        edges: list[str],
        from_station: str,
        to_station: str,
        like: Trip,
        scenario: Any,
        dt_s: float,
        step_method: str,
        arrive_by_s: float | None,
        depart_s: float = 0.0,
    ) -> TrainRuntime:
        """One depot run as a trip of the fleet: departing at ``depart_s``, or planned to arrive by ``arrive_by_s``."""
        route = make_route(self.graph, f"{kind}:{edges[0]}->{edges[-1]}", edges)
        passed = {rs.station_id for rs in route.stops} - {from_station, to_station}
        stops = make_stops(route, like.vehicle.length_m, tuple(sorted(passed)), 0.0, {}, from_station, to_station)
        assert stops[0].station_id == from_station and stops[-1].station_id == to_station, (kind, uid, edges)
        trip = Trip(
            trip_id=f"{uid}.{kind}",
            service_id=kind,
            index=len(self.runs),
            vehicle_name=like.vehicle_name,
            vehicle=like.vehicle,
            route=route,
            depart_s=depart_s,
            stops=stops,
            roles=dict(like.roles),
            kind=kind,
        )
        tr = self.fleet.add(trip, scenario, dt_s, step_method)
        if arrive_by_s is not None:  # shift the plan so that it arrives when the unit must be ready
            shift_s = arrive_by_s - trip.planned_arrival_s[to_station]
            if shift_s < 0.0:  # not before the run starts: the first trip starts late (its delay shows it)
                log.warning("%s would leave its depot %.1f s before the run starts; it leaves at 0 s", uid, -shift_s)
                shift_s = 0.0
            trip.depart_s += shift_s
            for times in (trip.planned_arrival_s, trip.planned_departure_s):
                times.update({k: v + shift_s for k, v in times.items()})
        return tr

    # ------------------------------------------------------------------ results
    def summary(self) -> dict[str, Any]:
        """Depot KPIs for the ``fleet`` block (module docstring)."""
        trains = self.fleet.trains
        rows: list[dict[str, Any]] = []
        empty_km: dict[str, float] = {}
        start: dict[str, int] = {}
        end: dict[str, int] = {}
        for run in self.runs.values():
            start[run["out_depot"]] = start.get(run["out_depot"], 0) + 1
            end[run["in_depot"]] = end.get(run["in_depot"], 0) + 1
            for key, depot in (("out", run["out_depot"]), ("in", run["in_depot"])):
                tr = trains[run[key]]
                uid = tr.unit_id or ""  # the unit that ran it (units may swap their days: Turnbacks)
                ran_m = 0.0 if tr.inserted_s is None else max(0.0, tr.front_m - tr.start_front_m)
                empty_km[uid] = empty_km.get(uid, 0.0) + ran_m / 1000.0
                rows.append(
                    {
                        "unit": uid,
                        "trip": tr.train_id,
                        "kind": tr.trip.kind,
                        "depot": depot,
                        "planned_departure_s": round(tr.trip.depart_s, 3),
                        "inserted_s": None if tr.inserted_s is None else round(tr.inserted_s, 3),
                        "arrived_s": None if tr.arrived_s is None else round(tr.arrived_s, 3),
                        "km": round(ran_m / 1000.0, 3),
                    }
                )
        empty_km = {u: round(km, 3) for u, km in sorted(empty_km.items())}
        late = 0
        for run in self.runs.values():
            first = trains[self.turnbacks.next_of[run["out"]]]
            late += first.departed_s is not None and first.departed_s > first.trip.depart_s + LATE_FIRST_S
        return {
            "depot_runs": len(rows),
            "late_first_departures": late,
            "depot_runs_arrived": sum(1 for r in rows if r["arrived_s"] is not None),
            "empty_km_per_unit": empty_km,
            "units_per_depot": {"start_of_day": dict(sorted(start.items())), "end_of_day": dict(sorted(end.items()))},
            "units_without_depot_runs": list(self.unreached),
            "depot_run_rows": rows,
        }
