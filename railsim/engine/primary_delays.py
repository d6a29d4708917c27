"""Primary delays injected into the trips (the scenario's ``disturbances:``) and what each train owes to them.

**Drawing.** Every trip gets its own random stream, seeded from the run's seed, a fixed tag and the trip id
(``numpy.random.default_rng([seed, TAG, crc32(trip_id)])``): the run's main generator is never touched (a
scenario without the section draws nothing, so its outputs are unchanged), and a trip's draws depend only on
the seed, its id and its stops — the same trip gets the same primary delays under moving block and virtual
coupling (common random numbers) and at every headway where it exists. Per trip, in this order: one
(probability, delay) pair per departure rule, one pair per dwell rule at each intermediate stop, one uniform for
the performance factor. A pair is drawn whether or not its rule applies there, so the streams stay aligned.
Poisson incidents (``rate_per_h``) have one stream per rule (``[seed, TAG, 2**32 + k]``); each incident holds
the first train *planned* to leave one of the rule's stations at or after the incident time.
``intensity`` scales every delay, and the performance factor as ``1 − intensity·(1 − f)``.

**Injecting** (:meth:`PrimaryDelays.apply`, after the formations are known, before departures are scheduled):

* a dwell extension or an incident hold at a stop lengthens that stop's dwell (``TripStop.dwell_s``: SUMO holds
  the train that much longer);
* a departure delay sets ``Trip.departure_delay_s`` (the dispatcher, or the turnback for a unit's next trip,
  lets the trip leave that much after its scheduled time; a follower that couples on departure leaves with its
  leader, so it gets none);
* passenger demand (``demand:``) is decided at run time, when a train reaches a platform
  (:mod:`railsim.engine.passenger_dwell`): it holds the train there after SUMO's dwell;
* the performance factor ``f`` scales the trip's vehicle: top speed, tractive force and power times ``f``
  (drawn to 0.01, so free runs are shared). The ATO reads the vehicle it is given, so it cruises lower too.

**What each train owes to its own disturbances** — the *primary* part of its delay at each stop — is the delay
of a free run (``railsim.engine.trips.plan_free_run``) with only its own disturbances: the departure delay,
plus every extra dwell before the stop (passenger-demand extensions included), plus the running-time loss of a free run with the scaled vehicle.
Whatever else the train is late by is *secondary* (knock-on: waiting for authority, a held departure, a late
incoming unit). :meth:`PrimaryDelays.rows` joins this with the recorded stops into ``delays.csv``.
"""

from __future__ import annotations

import dataclasses
import math
import zlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from railsim.engine.fleet import Fleet, ato_factory
from railsim.engine.passenger_dwell import DemandDwell
from railsim.engine.trips import Trip, plan_free_run
from railsim.errors import ConfigError
from railsim.scenario.disturbances import DelayRule, DisturbanceSpec

STREAM_TAG = 0x0D15_7A8B  # separates these streams from any other use of the run's seed
FACTOR_STEP = 0.01  # performance factors are drawn to this resolution (free runs are cached per factor)
MIN_FACTOR = 0.05

DELAY_COLUMNS = [
    "trip_id",
    "service",
    "station",
    "planned_arrival_s",
    "arrival_s",
    "arrival_delay_s",
    "primary_s",
    "secondary_s",
    "planned_departure_s",
    "departure_s",
    "departure_delay_s",
    "dwell_extra_s",
    "dwell_demand_s",
    "incident_s",
    "missed",
]


@dataclass
class TripPrimary:
    """The primary delays drawn for one trip."""

    departure_s: float = 0.0  # late departure from the origin
    dwell_extra_s: dict[str, float] = field(default_factory=dict)  # station -> extra dwell (dwell rules)
    incident_s: dict[str, float] = field(default_factory=dict)  # station -> incident hold
    demand_s: dict[str, float] = field(default_factory=dict)  # station -> passenger-demand extension (at run time)
    factor: float = 1.0  # performance factor on the traction/speed envelope
    running_loss_s: dict[str, float] = field(default_factory=dict)  # station -> free-run arrival loss from factor
    stations: tuple[str, ...] = ()  # intermediate stops and destination, in order

    def extra_at(self, station: str) -> float:
        return (
            self.dwell_extra_s.get(station, 0.0) + self.incident_s.get(station, 0.0) + self.demand_s.get(station, 0.0)
        )

    def primary_arrival_s(self) -> dict[str, float]:
        """Station -> the arrival delay a free run with only these disturbances has there."""
        out: dict[str, float] = {}
        carried = self.departure_s
        for st in self.stations:
            out[st] = carried + self.running_loss_s.get(st, 0.0)
            carried += self.extra_at(st)
        return out


class PrimaryDelays:
    """Draws (at construction), injects (:meth:`apply`) and accounts for (:meth:`rows`) the primary delays."""

    def __init__(
        self,
        spec: DisturbanceSpec,
        fleet: Fleet,
        scenario: Any,
        seed: int,
        horizon_s: float,
        dt_s: float,
        aliases: Mapping[str, str] | None = None,
    ) -> None:
        self.spec = with_station_ids(spec, aliases or {})
        self.seed = int(seed)
        self.trips: dict[str, TripPrimary] = {}
        self.events: list[tuple[float, str, str, float]] = []  # (planned time, trip, station, hold) of incidents
        self._check_stations(fleet, scenario)
        for tid, tr in fleet.trains.items():
            self.trips[tid] = self._draw_trip(tr.trip)
        self._incidents(fleet, horizon_s)
        self._running_losses(fleet, scenario, dt_s)
        self.demand: DemandDwell | None = None
        if self.spec.demand is not None:
            trips = (tr.trip for tr in fleet.trains.values())
            start_s = scenario.simulation.start_time_s
            self.demand = DemandDwell(self.spec.demand, self.spec.intensity, start_s, trips)

    # ------------------------------------------------------------------ drawing
    def _check_stations(self, fleet: Fleet, scenario: Any) -> None:
        known = {s.station_id for tr in fleet.trains.values() for s in tr.trip.stops}
        for sid, path in self.spec.station_ids():
            if sid not in known:
                raise ConfigError(scenario.source, path, f"station {sid!r} is served by no trip of this scenario")
        for k, inc in enumerate(self.spec.incidents):
            if inc.trip is None:
                continue
            trip = fleet.trains[inc.trip].trip
            if inc.station not in {s.station_id for s in trip.stops} or inc.station == trip.destination.station_id:
                raise ConfigError(
                    scenario.source,
                    f"disturbances.incidents[{k}].station",
                    f"trip {inc.trip} does not stop at {inc.station!r} before its destination",
                )

    def _draw(self, rng: np.random.Generator, rule: DelayRule, applies: bool) -> float:
        """One (probability, delay) pair, drawn whether or not the rule applies (module docstring)."""
        fires = float(rng.random()) < rule.prob
        delay = rule.delay.draw(rng)
        return delay * self.spec.intensity if (applies and fires) else 0.0

    def _draw_trip(self, trip: Trip) -> TripPrimary:
        rng = np.random.default_rng([self.seed, STREAM_TAG, zlib.crc32(trip.trip_id.encode())])
        tp = TripPrimary()
        origin = trip.origin.station_id
        for rule in self.spec.departure:
            planned = trip.planned_departure_s.get(origin, trip.depart_s)
            tp.departure_s += self._draw(rng, rule, rule.matches(trip.service_id, None, planned))
        tp.stations = tuple(s.station_id for s in trip.stops if s.kind == "station" and not s.is_origin)
        for s in trip.stops:
            if s.kind != "station" or s.is_origin or s.is_destination:
                continue
            planned = trip.planned_arrival_s.get(s.station_id, trip.depart_s)
            for rule in self.spec.dwell:
                extra = self._draw(rng, rule, rule.matches(trip.service_id, s.station_id, planned))
                if extra > 0.0:
                    tp.dwell_extra_s[s.station_id] = tp.dwell_extra_s.get(s.station_id, 0.0) + extra
        perf = self.spec.running_time
        u = float(rng.random())
        if not perf.services or trip.service_id in perf.services:
            f = perf.low + (perf.high - perf.low) * u
            f = 1.0 - self.spec.intensity * (1.0 - f)
            tp.factor = max(MIN_FACTOR, round(f / FACTOR_STEP) * FACTOR_STEP)
        for inc in self.spec.incidents:
            if inc.trip == trip.trip_id and inc.station is not None:
                self._hold(tp, trip, inc.station, inc.hold_s * self.spec.intensity)
        return tp

    def _hold(self, tp: TripPrimary, trip: Trip, station: str, hold_s: float) -> None:
        if hold_s <= 0.0:
            return
        if station == trip.origin.station_id:
            tp.departure_s += hold_s
        else:
            tp.incident_s[station] = tp.incident_s.get(station, 0.0) + hold_s
        self.events.append((trip.planned_departure_s.get(station, trip.depart_s), trip.trip_id, station, hold_s))

    def _incidents(self, fleet: Fleet, horizon_s: float) -> None:
        """Poisson incidents (module docstring)."""
        for k, inc in enumerate(self.spec.incidents):
            if inc.trip is not None or inc.rate_per_h <= 0.0:
                continue
            rng = np.random.default_rng([self.seed, STREAM_TAG, 2**32 + k])
            candidates = sorted(
                (tr.trip.planned_departure_s[s.station_id], tid, s.station_id)
                for tid, tr in fleet.trains.items()
                for s in tr.trip.stops
                if s.kind == "station"
                and not s.is_destination
                and (s.station_id in inc.stations if inc.stations else not s.is_origin)
                and s.station_id in tr.trip.planned_departure_s
            )
            t = inc.from_s
            end_s = min(inc.until_s, horizon_s)
            while True:
                t += float(rng.exponential(3600.0 / inc.rate_per_h))
                if t >= end_s:
                    break
                hit = next((c for c in candidates if c[0] >= t), None)
                if hit is not None:
                    _, tid, station = hit
                    self._hold(self.trips[tid], fleet.trains[tid].trip, station, inc.hold_s * self.spec.intensity)

    def _running_losses(self, fleet: Fleet, scenario: Any, dt_s: float) -> None:
        """Free-run arrival losses of every trip whose performance factor is below 1 (module docstring)."""
        step_method = scenario.simulation.step_method
        for tid, tp in self.trips.items():
            if tp.factor >= 1.0:
                continue
            trip = fleet.trains[tid].trip
            slow = dataclasses.replace(
                trip, vehicle=scaled_vehicle(trip.vehicle, tp.factor), planned_arrival_s={}, planned_departure_s={}
            )
            factory = ato_factory(scenario, dict(trip.roles), trip.vehicle, step_method)
            arr, _ = plan_free_run(slow, factory, dt_s, step_method)
            tp.running_loss_s = {
                st: arr[st] - trip.planned_arrival_s[st]
                for st in tp.stations
                if st in arr and st in trip.planned_arrival_s
            }

    # ------------------------------------------------------------------ injecting
    def apply(self, fleet: Fleet, couples_on_departure: Any) -> None:
        """Lengthen dwells, delay departures and slow vehicles down (module docstring); passenger demand is
        handed to the stop book (:func:`passenger_demand`, :mod:`railsim.engine.passenger_dwell`)."""
        for tid, tp in self.trips.items():
            trip = fleet.trains[tid].trip
            if couples_on_departure(tid):
                tp.departure_s = 0.0  # it leaves behind its leader
            trip.departure_delay_s = tp.departure_s
            if tp.dwell_extra_s or tp.incident_s:
                trip.stops = tuple(
                    dataclasses.replace(s, dwell_s=s.dwell_s + tp.extra_at(s.station_id))
                    if s.kind == "station" and not (s.is_origin or s.is_destination) and tp.extra_at(s.station_id)
                    else s
                    for s in trip.stops
                )
            if tp.factor < 1.0:
                trip.vehicle = scaled_vehicle(trip.vehicle, tp.factor)

    # ------------------------------------------------------------------ accounting
    def rows(self, stop_records: list[dict[str, Any]], trains: dict[str, Any]) -> list[dict[str, Any]]:
        """``delays.csv``: one row per recorded stop after the origin (module docstring)."""
        self._collect_demand()
        primary = {tid: tp.primary_arrival_s() for tid, tp in self.trips.items()}
        out = []
        for rec in stop_records:
            tid, st = rec["trip_id"], rec["station"]
            trip = trains[tid].trip
            if st == trip.origin.station_id or st not in primary.get(tid, {}):
                continue
            tp = self.trips[tid]
            planned_arr = rec["planned_arrival_s"]
            arr = rec["arrival_s"]
            delay = None if (arr is None or planned_arr is None) else arr - planned_arr
            p = primary[tid][st]
            planned_dep = trip.planned_departure_s.get(st)
            dep = rec["departure_s"]
            out.append(
                {
                    "trip_id": tid,
                    "service": rec["service"],
                    "station": st,
                    "planned_arrival_s": planned_arr,
                    "arrival_s": arr,
                    "arrival_delay_s": delay,
                    "primary_s": p,
                    "secondary_s": None if delay is None else delay - p,
                    "planned_departure_s": planned_dep,
                    "departure_s": dep,
                    "departure_delay_s": None if (dep is None or planned_dep is None) else dep - planned_dep,
                    "dwell_extra_s": tp.dwell_extra_s.get(st, 0.0),
                    "dwell_demand_s": tp.demand_s.get(st, 0.0),
                    "incident_s": tp.incident_s.get(st, 0.0),
                    "missed": rec["missed"],
                }
            )
        return out

    def _collect_demand(self) -> None:
        """The passenger-demand extensions decided during the run, into each trip's primary delays."""
        if self.demand is not None:
            for tid, ext in self.demand.extensions_s.items():
                self.trips[tid].demand_s = dict(ext)

    def summary(self) -> dict[str, Any]:
        """What was injected (the engine's part of ``summary.json``'s ``robustness`` block)."""
        self._collect_demand()
        tps = self.trips.values()
        demand = {}
        if self.demand is not None:
            demand = {
                "injected_demand_s": math.fsum(math.fsum(tp.demand_s.values()) for tp in tps),
                "extra_passengers": math.fsum(math.fsum(p.values()) for p in self.demand.passengers.values()),
            }
        return {
            **demand,
            "intensity": self.spec.intensity,
            "injected_departure_s": math.fsum(tp.departure_s for tp in tps),
            "injected_dwell_s": math.fsum(math.fsum(tp.dwell_extra_s.values()) for tp in tps),
            "injected_incident_s": math.fsum(math.fsum(tp.incident_s.values()) for tp in tps),
            "trips_slowed": sum(1 for tp in tps if tp.factor < 1.0),
            "mean_factor": float(np.mean([tp.factor for tp in tps])) if self.trips else 1.0,
            "incidents": [
                {"planned_s": t, "trip": tid, "station": st, "hold_s": h} for t, tid, st, h in sorted(self.events)
            ],
        }


# ---- the loop's four calls (each a no-op without a disturbances: section) -----------------------------------


def draw(scenario: Any, fleet: Fleet, seed: int, dt_s: float, aliases: Mapping[str, str]) -> PrimaryDelays | None:
    """The run's primary delays, drawn right after the fleet is built; None without a ``disturbances:`` section."""
    if scenario.disturbances is None:
        return None
    horizon_s = float(scenario.simulation.duration_s)
    return PrimaryDelays(scenario.disturbances, fleet, scenario, seed, horizon_s, dt_s, aliases)


def apply(primary: PrimaryDelays | None, fleet: Fleet, couples_on_departure: Any) -> None:
    """Inject them (:meth:`PrimaryDelays.apply`) once the formations are known."""
    if primary is not None:
        primary.apply(fleet, couples_on_departure)


def passenger_demand(primary: PrimaryDelays | None) -> DemandDwell | None:
    """The run's passenger demand at the platforms (the stop book lengthens dwells by it), or None."""
    return primary.demand if primary is not None else None


def summary(primary: PrimaryDelays | None) -> dict[str, Any]:
    """``{"disturbances": what was injected}`` for ``summary.json``, or nothing."""
    return {} if primary is None else {"disturbances": primary.summary()}


def tables(
    primary: PrimaryDelays | None, stop_records: list[dict[str, Any]], trains: dict[str, Any]
) -> dict[str, tuple[list[dict[str, Any]], list[str]]]:
    """``{"delays": (rows, columns)}`` for ``delays.csv``, or nothing."""
    return {} if primary is None else {"delays": (primary.rows(stop_records, trains), DELAY_COLUMNS)}


def with_station_ids(spec: DisturbanceSpec, aliases: Mapping[str, str]) -> DisturbanceSpec:
    """``spec`` with stations named by an alias (an external net's station name or stop id) replaced by ids."""
    if not aliases:
        return spec

    def ids(names: tuple[str, ...]) -> tuple[str, ...]:
        return tuple(aliases.get(n, n) for n in names)

    demand = spec.demand
    if demand is not None:
        demand = dataclasses.replace(demand, rates=tuple((aliases.get(sid, sid), st) for sid, st in demand.rates))
    return dataclasses.replace(
        spec,
        demand=demand,
        dwell=tuple(dataclasses.replace(r, stations=ids(r.stations)) for r in spec.dwell),
        incidents=tuple(
            dataclasses.replace(
                i, stations=ids(i.stations), station=None if i.station is None else aliases.get(i.station, i.station)
            )
            for i in spec.incidents
        ),
    )


def scaled_vehicle(vehicle: Any, factor: float) -> Any:
    """``vehicle`` with top speed, tractive force and power times ``factor`` (a slower driver or ATO setting)."""
    return dataclasses.replace(
        vehicle,
        max_speed_mps=vehicle.max_speed_mps * factor,
        traction_max_force_n=vehicle.traction_max_force_n * factor,
        traction_max_power_w=vehicle.traction_max_power_w * factor,
    )
