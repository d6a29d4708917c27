"""Trips: one train running one departure of a service, with its route, stops, dwell times and plan.

A *service* in a scenario (``from: yudong, to: jiangbei-airport-t2, departures: every 150 s``) expands into
*trips*, one per departure. A trip knows everything that is fixed before the run:

* its :class:`network.RouteInfo` (SUMO edges, route chainage of every edge, platforms, limits, switches);
* the stops it serves (the origin is where it is inserted, the destination is where its trip ends);
* the stopping mark of each stop: the train front halts 1 m before the platform end, so the whole train stands
  on the platform (SUMO accepts a halt with the front in ``[startPos + length, endPos]``). A **platform shorter
  than the train** (common on other people's nets: ``endPos="-10"`` stops on short edges) cannot hold the whole
  train: there the front halts at the platform end, in a window of :data:`SHORT_PLATFORM_WINDOW_M` that ends at
  the platform end (never before the platform's edge begins), and SUMO is given that window as a stop on the
  lane (``lane_stop_m``), because it would never register a trainStop the train does not fit on;
  A halt up to :data:`SHORT_PLATFORM_OVERRUN_M` past a short platform's end still serves it (``overrun_m``; SUMO's
  stop on the lane reaches that far): a sub-metre overrun of a 25 m stop is a stopping error, not a dropped stop;
* the dwell at each intermediate stop;
* the **planned** (timetable) times, from a free run of the same train with the same ATO and physics on an
  empty line (:func:`plan_free_run`). Delay = actual − planned, so delay measures what the other trains, the
  interlocking and the communication did to this train, not a guessed timetable.

Turnbacks: without rotations a trip ends at its destination platform and a return working is a separate train
from the opposite platform; with rotations the unit reverses and runs its next trip (``railsim.engine.turnback``
prepends the reversal to that trip's route and stops).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

STOP_MARK_BEFORE_END_M = 1.0  # the front halts this far before the platform end
SHORT_PLATFORM_WINDOW_M = 2.0  # a platform shorter than the train: the front halts in the last 2 m of it
SHORT_PLATFORM_OVERRUN_M = 1.0  # ... and a halt up to 1 m past its end still serves it (never a dropped stop)
REVERSAL = "reversal"  # TripStop.kind of the stop where a unit reverses (railsim.engine.turnback)


@dataclass(frozen=True)
class TripStop:
    """One platform a trip serves, in the trip's route frame (front chainage)."""

    station_id: str
    stop_id: str
    mark_m: float  # where the front should halt
    window_start_m: float  # front positions SUMO accepts: [platform start + train length, platform end]
    window_end_m: float
    dwell_s: float
    is_origin: bool = False
    is_destination: bool = False
    kind: str = "station"  # or REVERSAL: where a unit reverses before its trip (railsim.engine.turnback)
    # a platform shorter than the train: (start, end) lane positions [m] of the window on the platform's edge,
    # handed to SUMO as a stop on the lane; None for a platform the whole train fits on (SUMO's trainStop)
    lane_stop_m: tuple[float, float] | None = None
    platform_m: float = 0.0  # platform length [m]
    overrun_m: float = 0.0  # a halt this far past the window's end is still served (a short platform's overrun)

    @property
    def short_platform(self) -> bool:
        """The train is longer than the platform: it stands with its front at the platform end."""
        return self.lane_stop_m is not None

    @property
    def served_end_m(self) -> float:
        """The farthest front position at which a halt serves the stop: the window's end plus ``overrun_m``."""
        return self.window_end_m + self.overrun_m


def sumo_stops(
    stops: Sequence[TripStop],
    origin_until_s: float | None = None,
    origin_duration_s: float | None = None,
    route: Any = None,
    first_edge: int = 0,
) -> list[Any]:
    """The stops SUMO holds a train at (:class:`railsim.engine.sumo.StopSpec`): the origin and the destination
    for :data:`~railsim.engine.settings.DWELL_REGISTRATION_S` (the engine registers the halt; the departure is
    the engine's) or the origin for ``origin_duration_s`` if given, every other platform for its dwell; the origin
    held ``until`` ``origin_until_s`` if given. A reversal is no SUMO stop: SUMO turns the unit round by itself
    (``railsim.engine.turnback``).

    With the trip's ``route`` each stop names the pass of its platform's edge it is made on (``route_index``,
    counted from the route's edge ``first_edge``, where SUMO's copy of the route begins): a route can pass a
    platform's edge twice (a turnback path out along the line and back, a loop), and SUMO on its own matches a
    stop to the first pass (:meth:`railsim.engine.sumo.SumoBridge.reroute`)."""
    from railsim.engine.settings import DWELL_REGISTRATION_S
    from railsim.engine.sumo import StopSpec  # the bridge imports libsumo: only when a run needs it

    origin_s = DWELL_REGISTRATION_S if origin_duration_s is None else origin_duration_s
    return [
        StopSpec(
            s.stop_id,
            duration_s=origin_s if s.is_origin else (DWELL_REGISTRATION_S if s.is_destination else s.dwell_s),
            until_s=origin_until_s if s.is_origin else None,
            lane_stop_m=s.lane_stop_m,
            route_index=None if route is None else stop_edge_index(route, s) - first_edge,
        )
        for s in stops
        if s.kind != REVERSAL
    ]


def stop_edge_index(route: Any, stop: TripStop) -> int:
    """Index in ``route.edges`` of the edge the front halts on at ``stop``: the edge whose chainage holds the mark
    (a mark exactly on an edge's start belongs to the edge before it: a platform ends on its own edge)."""
    k = int(np.searchsorted(np.asarray(route.edge_start_m, dtype=float), stop.mark_m, side="left")) - 1
    return min(max(k, 0), len(route.edges) - 1)


@dataclass
class Trip:
    """A train's whole journey. Mutable runtime progress lives in :class:`railsim.engine.loop` (TrainRuntime)."""

    trip_id: str
    service_id: str
    index: int  # departure index within the service
    vehicle_name: str
    vehicle: Any  # VehicleParams
    route: Any  # network RouteInfo
    depart_s: float
    stops: tuple[TripStop, ...]
    roles: dict[str, str]  # role -> controller instance name
    planned_arrival_s: dict[str, float] = field(default_factory=dict)  # station -> planned arrival
    planned_departure_s: dict[str, float] = field(default_factory=dict)
    start_offset_m: float = 0.0  # starts this far beyond the origin's mark (experiments that begin in motion)
    # a unit's next trip: its route starts with the turnback, this much longer than the service's own route
    # before its first edge (the trace reports chainage in the service's frame: turnback moves lie behind it)
    frame_shift_m: float = 0.0
    start_speed_mps: float = 0.0
    kind: str = "service"  # or "depot_out" / "depot_in": an empty run of a unit (railsim.engine.depot)
    departure_delay_s: float = 0.0  # a primary delay (railsim.engine.primary_delays): leaves this much late

    @property
    def origin(self) -> TripStop:
        """The platform the trip departs from (after its unit's reversal stop, if it starts with one)."""
        first = self.stops[0]
        return first if first.kind == "station" else self.stops[1]

    @property
    def n_stops_scheduled(self) -> int:
        """Stops the trip serves after leaving its origin (its unit's reversal and the origin not counted)."""
        return sum(1 for s in self.stops if s.kind == "station" and not s.is_origin)

    @property
    def destination(self) -> TripStop:
        return self.stops[-1]

    @property
    def depart_chainage_m(self) -> float:
        return self.origin.mark_m + self.start_offset_m


def make_stops(
    route: Any,
    length_m: float,
    skip: Sequence[str],
    dwell_default_s: float,
    dwell_by_station: dict[str, float],
    from_station: str,
    to_station: str,
) -> tuple[TripStop, ...]:
    """Stops served on ``route`` between ``from_station`` and ``to_station`` (inclusive), skipping ``skip``; one
    platform where an intermediate station's platforms overlap (:func:`_overlapping_platforms_merged`)."""
    stops: list[TripStop] = []
    started = False
    for rs in _overlapping_platforms_merged(route.stops, length_m, (from_station, to_station)):
        if rs.station_id == from_station:
            started = True
        if not started:
            continue
        is_origin = rs.station_id == from_station
        is_dest = rs.station_id == to_station
        if rs.station_id in skip and not (is_origin or is_dest):
            continue
        mark, window_start, lane_stop = _stop_window(rs, length_m)
        overrun_m = 0.0
        if lane_stop is not None:  # SUMO's stop on the lane reaches as far past the platform as the edge allows
            overrun_m = max(0.0, min(SHORT_PLATFORM_OVERRUN_M, _edge_end_m(route, rs) - rs.end_m))
            lane_stop = (lane_stop[0], lane_stop[1] + overrun_m)
        stops.append(
            TripStop(
                station_id=rs.station_id,
                stop_id=rs.stop_id,
                mark_m=mark,
                window_start_m=window_start,
                window_end_m=rs.end_m,
                lane_stop_m=lane_stop,
                platform_m=rs.end_m - rs.start_m,
                dwell_s=0.0 if (is_origin or is_dest) else float(dwell_by_station.get(rs.station_id, dwell_default_s)),
                is_origin=is_origin,
                is_destination=is_dest,
                overrun_m=overrun_m,
            )
        )
        if is_dest:
            break
    return tuple(stops)


def _overlapping_platforms_merged(route_stops: Sequence[Any], length_m: float, ends: tuple[str, str]) -> list[Any]:
    """The route's platforms with platforms of one intermediate station that overlap along the route made one.

    OpenStreetMap maps some stations with a stop position and a platform on the same track, and the import writes
    a stop for each: two stops over one stretch of track (São Paulo's São Bento: two 200 m platforms overlapping by
    146 m). The timetable names the station once, and there is one platform there, so the train stops once: at
    the one of them the whole train fits on that ends further along, else at the longer. Platforms of a station
    that follow each other without overlapping are two stops, as before (Jena's Löbstedt: two 30 m platforms on
    consecutive edges). The trip's origin and destination (``ends``) keep the platform their route was chosen by
    (the route begins and ends on it)."""
    out: list[Any] = []
    for rs in route_stops:
        prev = out[-1] if out else None
        if prev is None or prev.station_id != rs.station_id or rs.station_id in ends or rs.start_m >= prev.end_m:
            out.append(rs)
            continue
        if _platform_choice(rs, length_m) >= _platform_choice(prev, length_m):
            out[-1] = rs
    return out


def _platform_choice(rs: Any, length_m: float) -> tuple[bool, float]:
    """How well a platform serves a train ``length_m`` long: the whole train fits, then its length (a later
    platform wins a tie)."""
    platform_m = rs.end_m - rs.start_m
    return (platform_m >= length_m, platform_m if platform_m < length_m else 0.0)


def _edge_end_m(route: Any, rs: Any) -> float:
    """Route chainage of the end of the edge a platform lies on (where the next internal or normal edge begins)."""
    edge_start_m = rs.start_m - rs.start_pos_m
    later = [float(x) for x in route.edge_start_m if x > edge_start_m + 1e-6]
    later += [float(x) for _, x in route.internal_start_m if x > edge_start_m + 1e-6]
    return min(later, default=float(route.length_m))


def _stop_window(rs: Any, length_m: float) -> tuple[float, float, tuple[float, float] | None]:
    """``(mark, window start, lane stop)`` of one platform for a train ``length_m`` long (module docstring)."""
    if rs.end_m - rs.start_m >= length_m:
        return rs.end_m - STOP_MARK_BEFORE_END_M, rs.start_m + length_m, None
    edge_start_m = rs.start_m - rs.start_pos_m
    start = max(rs.start_m, rs.end_m - SHORT_PLATFORM_WINDOW_M)
    mark = max(rs.end_m - STOP_MARK_BEFORE_END_M, 0.5 * (start + rs.end_m))
    return mark, start, (start - edge_start_m, rs.end_pos_m)


def plan_free_run(
    trip: Trip, controller_factory: Any, dt_s: float, step_method: str = "euler", max_time_s: float = 6 * 3600.0
) -> tuple[dict[str, float], dict[str, float]]:
    """Planned arrival/departure per station from a free run (no other trains) of the trip's ATO.

    The same controller and plant as the simulation, integrated with the same step (:func:`free_run`), so the
    plan is achievable by construction. Returns ``(arrival_by_station, departure_by_station)`` in absolute
    simulation seconds. Cached per (route, vehicle, stops, controller) so 48 identical trips cost one run.
    """
    key = (
        trip.route.id,
        trip.vehicle,
        trip.stops,
        dt_s,
        step_method,
        trip.roles.get("ato"),
        trip.start_offset_m,
        trip.start_speed_mps,
    )
    rel_arr, rel_dep = _free_run_cached(key, trip, controller_factory, dt_s, step_method, max_time_s)
    return ({k: v + trip.depart_s for k, v in rel_arr.items()}, {k: v + trip.depart_s for k, v in rel_dep.items()})


_FREE_RUN_CACHE: dict[Any, tuple[dict[str, float], dict[str, float]]] = {}


def _free_run_cached(
    key: Any, trip: Trip, controller_factory: Any, dt_s: float, step_method: str, max_time_s: float
) -> tuple[dict[str, float], dict[str, float]]:
    if key in _FREE_RUN_CACHE:
        return _FREE_RUN_CACHE[key]
    result = free_run(trip, controller_factory(), dt_s, step_method, max_time_s)
    _FREE_RUN_CACHE[key] = result
    return result


def free_run(
    trip: Trip, ato: Any, dt_s: float, step_method: str, max_time_s: float, loop: Any = None
) -> tuple[dict[str, float], dict[str, float]]:
    """Arrival and departure per station of a free run of ``ato`` (times relative to the departure), by the one
    loop :func:`railsim.engine.free_run_kernel.free_run`: compiled for the line ATO (its law compiled into the
    loop), interpreted with the controller's :class:`~controllers.base.Observation` for any other (the same
    values either way, as in the simulation's control stage). ``loop``: the loop function to call instead
    (the tests pass the interpreted module's, the reference)."""
    from controllers.ato import Ato
    from railsim.engine import free_run_kernel
    from railsim.engine.routeview import route_view
    from railsim.physics import plant_kernel

    veh = trip.vehicle
    if step_method not in plant_kernel.STEP_METHODS:
        raise ValueError(f"step_method must be one of {', '.join(plant_kernel.STEP_METHODS)}, got {step_method!r}")
    view = route_view(trip.route)
    stops = np.array(
        [
            (s.mark_m, s.window_start_m, s.window_end_m, s.dwell_s, float(s.is_destination), s.served_end_m)
            for s in trip.stops
        ],
        dtype=np.float64,
    ).reshape(-1, 6)
    if type(ato) is Ato:
        law, ato_p = None, ato.packed(veh, dt_s)
        loop = loop or free_run_kernel.free_run
    else:
        law, ato_p = _observed_law(ato, trip, view, dt_s), np.zeros(0)
        loop = free_run_kernel.free_run.py_func  # a Python controller: the loop as written, interpreted
    arr_t, dep_t, ok = loop(
        law,
        ato_p,
        plant_kernel.pack(veh, dt_s),
        plant_kernel.method_index(step_method),
        dt_s,
        veh.length_m,
        view.line_speed_mps,
        np.array(view.grade_starts, dtype=np.float64),
        np.array(view.grades, dtype=np.float64).reshape(-1, 3),
        np.array([(lim.start_m, lim.end_m, lim.speed_mps) for lim in view.limits], dtype=np.float64).reshape(-1, 3),
        stops,
        float(trip.depart_chainage_m),
        float(trip.start_speed_mps),
        max_time_s,
    )
    if not ok:
        raise ValueError(
            f"trip {trip.trip_id}: the {type(ato).__name__} controller gave a NaN command in the free run that plans it "
            "(refusing to propagate it)"
        )
    arrivals: dict[str, float] = {trip.origin.station_id: 0.0}
    departures: dict[str, float] = {trip.origin.station_id: 0.0}
    for k in range(1, len(trip.stops)):  # in stop order
        stop = trip.stops[k]
        if arr_t[k] == arr_t[k]:
            arrivals[stop.station_id] = float(arr_t[k])
        if dep_t[k] == dep_t[k]:
            departures[stop.station_id] = float(dep_t[k])
    return arrivals, departures


# (t, stop index, x, v, applied accel, gradient, restrictions window (n, 3), dwelling) -> (accel, emergency)
FreeRunLaw = Callable[[float, int, float, float, float, float, Any, bool], tuple[float, bool]]


def _observed_law(ato: Any, trip: Trip, view: Any, dt_s: float) -> FreeRunLaw:
    """A controller other than the line ATO, asked through its :class:`~controllers.base.Observation` in the
    free run's interpreted loop."""
    from controllers.base import Observation, OwnState, SpeedLimit, StopTarget

    veh = trip.vehicle

    def observed(t: float, idx: int, x: float, v: float, a: float, grad: float, window: Any, dwelling: bool) -> Any:
        stop = trip.stops[idx]
        obs = Observation(
            t_s=t,
            dt_s=dt_s,
            own=OwnState(trip.trip_id, x, v, a, veh.length_m, grad),
            vehicle=veh,
            route_length_m=trip.route.length_m,
            speed_limits=tuple(SpeedLimit(float(r[0]), float(r[1]), float(r[2])) for r in window),
            line_speed_mps=view.line_speed_mps,
            next_stop=StopTarget(
                stop.station_id, stop.mark_m, stop.window_start_m, stop.window_end_m, dwelling=dwelling
            ),
        )
        cmd = ato.command(obs)
        return cmd.accel_mps2, cmd.emergency

    return observed
