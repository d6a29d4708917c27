"""The fleet: every trip of the scenario as a :class:`~railsim.engine.train.TrainRuntime`, built once at set-up.

Building a trip resolves its route in the world, its stops and stopping marks, a start in motion (offset or
"distance before a switch"), its free-run timetable (the planned times delays are measured against) and one
controller per role. Afterwards the fleet answers the loop's and the ports' questions: which trains are on the
line, which train a scenario ``TripRef`` names, and whether every trip has finished.
"""

from __future__ import annotations

import bisect
from collections.abc import Callable
from operator import attrgetter, itemgetter
from typing import Any

import controllers as ctl
from railsim.engine.routeview import route_view
from railsim.engine.train import TrainRuntime
from railsim.engine.trips import Trip, make_stops, plan_free_run
from railsim.errors import ConfigError

ROLES = ("ato", "separation", "coupled", "ca")
ON_LINE = ("inserting", "running")  # a train's statuses while it is on the line
_ON_LINE_SET = frozenset(ON_LINE)
_TRAIN_ID = itemgetter(1)  # of an entry of Fleet._on_line
_STATUS = attrgetter("status")
FINISHED = ("arrived", "removed")  # once off it; a trip never comes back on the line


class Fleet:
    """All trips of a run, by trip id (insertion order = scenario order) and by service."""

    def __init__(self, source: Any) -> None:
        self.source = source  # the scenario file, for error messages
        self.trains: dict[str, TrainRuntime] = {}
        self._on_line: list[tuple[int, str]] = []  # (scenario rank, trip id) of the trains on the line, in order
        self._on_line_ids: dict[str, bool] = {}
        self._ranks: dict[str, int] = {}
        self._finished = 0  # trips that arrived or left the line
        self.trips_by_service: dict[str, list[Trip]] = {}

    # ------------------------------------------------------------------ queries
    def trip_ref(self, ref: Any, where: str) -> TrainRuntime:
        """The train a scenario ``TripRef`` (service + trip index) names; ConfigError naming ``where`` if none."""
        trips = self.trips_by_service.get(ref.service)
        if not trips or not (0 <= ref.trip < len(trips)):
            raise ConfigError(self.source, where, f"no trip {ref.trip} in service {ref.service!r}")
        return self.trains[trips[ref.trip].trip_id]

    def start(self, tr: TrainRuntime, status: str) -> None:
        """``tr`` comes on the line with ``status`` (``inserting``: handed to SUMO; ``running``: a unit's next trip,
        already there). The only way a trip goes on the line: the fleet keeps the trains on it in a list of their
        own, so the loop's questions cost the trains on the line, not the day's trips."""
        if status not in ON_LINE:
            raise ValueError(f"a train starts inserting or running, not {status!r}")
        tr.status = status
        if not self._on_line_ids.get(tr.train_id, False):
            rank = self._rank(tr)
            self._on_line_ids[tr.train_id] = True
            bisect.insort(self._on_line, (rank, tr.train_id), key=lambda e: e[0])

    def _rank(self, tr: TrainRuntime) -> int:
        """``tr``'s place in scenario order (trips added after set-up come after, in the order added)."""
        if len(self._ranks) != len(self.trains):
            self._ranks = {tid: k for k, tid in enumerate(self.trains)}
        return self._ranks[tr.train_id]

    def _prune(self) -> list[TrainRuntime]:
        """The trains on the line now; those that arrived or left since are dropped and counted finished."""
        live = list(map(self.trains.__getitem__, map(_TRAIN_ID, self._on_line)))
        if not _ON_LINE_SET.issuperset(map(_STATUS, live)):  # (C-level loops: every step, twice)
            kept = []
            for entry, tr in zip(self._on_line, live, strict=True):
                if tr.status in ON_LINE:
                    kept.append(entry)
                else:
                    del self._on_line_ids[tr.train_id]
                    self._finished += tr.status in FINISHED
            self._on_line = kept
            live = [tr for tr in live if tr.status in ON_LINE]
        return live

    def active(self) -> list[TrainRuntime]:
        """Trains on the line (inserted, not yet arrived or removed), in scenario order."""
        return self._prune()

    def n_finished(self) -> int:
        """Trips that arrived or left the line."""
        self._prune()
        return self._finished

    def all_done(self) -> bool:
        return self.n_finished() == len(self.trains)

    # ------------------------------------------------------------------ set-up
    def build(self, scenario: Any, bundle: Any, dt_s: float, step_method: str) -> None:
        """Create every trip of every service (see the module docstring)."""
        for svc in scenario.services:
            try:
                route = bundle.route_between(svc.from_station, svc.to_station, tuple(svc.via), svc.platforms)
            except (KeyError, ValueError) as exc:
                raise ConfigError(self.source, f"services[{svc.id}]", f"no route: {exc}") from None
            vehicle = scenario.vehicles[svc.vehicle]
            stops = make_stops(
                route,
                vehicle.length_m,
                tuple(svc.skip),
                svc.dwell_default_s,
                dict(svc.dwell_by_station),
                svc.from_station,
                svc.to_station,
            )
            if len(stops) < 2 or stops[0].station_id != svc.from_station or stops[-1].station_id != svc.to_station:
                raise ConfigError(
                    self.source,
                    f"services[{svc.id}]",
                    f"route from {svc.from_station} to {svc.to_station} does not serve both stations",
                )
            start_offset = self._start_offset(svc, route, stops)
            if start_offset > 0.0:  # a trip that starts in motion skips the stops already behind it
                start_m = stops[0].mark_m + start_offset
                stops = (stops[0],) + tuple(st for st in stops[1:] if st.window_end_m > start_m)
                if len(stops) < 2:
                    raise ConfigError(
                        self.source,
                        f"services[{svc.id}].start.offset_m",
                        f"starts beyond its destination {svc.to_station!r}",
                    )
            trips = []
            for k, (trip_id, dep) in enumerate(zip(svc.trip_ids, svc.departures_s)):
                trip = Trip(
                    trip_id=trip_id,
                    service_id=svc.id,
                    index=k,
                    vehicle_name=svc.vehicle,
                    vehicle=vehicle,
                    route=route,
                    depart_s=float(dep),
                    stops=stops,
                    roles=dict(svc.roles),
                    start_offset_m=start_offset,
                    start_speed_mps=float(svc.start_speed_mps),
                )
                self.add(trip, scenario, dt_s, step_method)
                trips.append(trip)
            self.trips_by_service[svc.id] = trips

    def add(self, trip: Trip, scenario: Any, dt_s: float, step_method: str) -> TrainRuntime:
        """Plan ``trip`` (free run from its ``depart_s``), give it its controllers and add it to the fleet."""
        factory = ato_factory(scenario, dict(trip.roles), trip.vehicle, step_method)
        arr, depm = plan_free_run(trip, factory, dt_s, step_method)
        trip.planned_arrival_s.update(arr)
        trip.planned_departure_s.update(depm)
        ctrls = {role: _controller(scenario, role, trip.roles, trip.vehicle, step_method) for role in ROLES}
        ctrls["ato_closing"] = _closing_ato(scenario, trip.roles, trip.vehicle, step_method)
        tr = TrainRuntime(trip=trip, view=route_view(trip.route), controllers=ctrls)
        self.trains[trip.trip_id] = tr
        return tr

    def _start_offset(self, svc: Any, route: Any, stops: tuple[Any, ...]) -> float:
        """How far beyond the origin's stopping mark the trip starts (0 for a start at the platform)."""
        start_offset = float(svc.start_offset_m)
        if svc.start_before_switch is None:
            return start_offset
        where = f"services[{svc.id}].start.before_switch"  # "the front starts distance_m before switch X"
        points = [rs.point_m for rs in route.switches if rs.switch_id == svc.start_before_switch]
        if not points:
            raise ConfigError(
                self.source,
                where,
                f"switch {svc.start_before_switch!r} is not on the route "
                f"{route.id} (its switches: {', '.join(rs.switch_id for rs in route.switches)})",
            )
        start_offset = points[0] - float(svc.start_distance_m) - stops[0].mark_m
        if start_offset < 0.0:
            raise ConfigError(
                self.source,
                f"services[{svc.id}].start.distance_m",
                f"{svc.start_distance_m:g} m before {svc.start_before_switch} lies behind the "
                f"origin's stopping mark (at most {points[0] - stops[0].mark_m:.1f} m)",
            )
        return start_offset


def _controller(scenario: Any, role: str, trip_roles: dict[str, str], vehicle: Any, step_method: str) -> Any:
    name = trip_roles.get(role)
    if name is None:
        return None
    spec = scenario.controllers[name]
    return _for_plant(ctl.create(spec.type, dict(spec.params or {}), vehicle), step_method)


def _for_plant(controller: Any, step_method: str) -> Any:
    """``controller``, told how the plant and SUMO update positions if it plans with that (the line ATO's stop
    predictor: :meth:`controllers.ato.Ato.use_position_update`)."""
    tell = getattr(controller, "use_position_update", None)
    if tell is not None:
        tell(step_method)
    return controller


def ato_factory(scenario: Any, roles: dict[str, str], vehicle: Any, step_method: str) -> Callable[[], Any]:
    """A maker of fresh ATOs of a trip (its free-run plans run each on its own)."""
    return lambda: _controller(scenario, "ato", roles, vehicle, step_method)


def _closing_ato(scenario: Any, trip_roles: dict[str, str], vehicle: Any, step_method: str) -> Any:
    """The follower's ATO while coupled: the same ATO without its cruise margin below the line speed.

    Both units of a formation otherwise cruise at the same speed (line speed − margin) and a follower that fell
    back while accelerating could never close up; without the margin it closes at up to that margin and still
    never exceeds the line speed or a restriction. ATOs without a ``speed_margin_mps`` parameter are used as
    they are.
    """
    spec = scenario.controllers[trip_roles["ato"]]
    try:
        closing = ctl.create(spec.type, {**dict(spec.params or {}), "speed_margin_mps": 0.0}, vehicle)
    except (ValueError, TypeError):
        return None
    return _for_plant(closing, step_method)
