"""Passenger-driven dwell: a train that finds more passengers than planned dwells longer (``disturbances.demand``).

Passengers arrive at a platform at the demand table's rate (:class:`railsim.scenario.disturbances.DemandSpec`),
so the number waiting when a train arrives grows with the time since the previous train left that platform.
The timetable's dwell is sized for the *planned* interval; a train arriving after a longer interval boards
``rate/3600 × (actual − planned interval)`` more passengers, which takes ``s_per_passenger`` each::

    extension = intensity × s_per_passenger × rate(station, clock at arrival)/3600 × max(0, I_actual − I_planned)

    I_actual  = this train's arrival (its halt, as the plan counts it) − the last departure from that platform
    I_planned = this trip's planned arrival − the latest planned departure of another trip from that platform

A platform is a station's stop (``TripStop.stop_id``: one per track and direction). Only trains calling at it
count (a trip's origin and destination are left alone, as by the dwell rules); the first train at a platform
and a train planned first there get no extension; an interval shorter than planned never shortens the dwell. A late train
therefore gets later by its own lateness and the train behind it catches up: the bunching mechanism of metro
lines. The extension is decided when the stop is registered and served by holding the train at the platform
after SUMO's dwell (:class:`railsim.engine.stops.StopBook`); it counts as the train's own (primary) delay in the
delay accounting (:mod:`railsim.engine.primary_delays`), its own column ``dwell_demand_s`` in ``delays.csv``.
"""

from __future__ import annotations

import bisect
from collections.abc import Iterable

from railsim.engine.trips import Trip, TripStop
from railsim.scenario.disturbances import DemandSpec


class DemandDwell:
    """Platform intervals and the dwell extensions they cause (module docstring)."""

    def __init__(self, spec: DemandSpec, intensity: float, start_time_s: float, trips: Iterable[Trip]) -> None:
        self.spec = spec
        self.intensity = float(intensity)
        self.start_time_s = float(start_time_s)  # clock time of t = 0 [s after midnight]
        # platform (station, stop id) -> planned departures from it, sorted, with their trips
        planned: dict[tuple[str, str], list[tuple[float, str]]] = {}
        for trip in trips:
            for s in trip.stops:
                dep = trip.planned_departure_s.get(s.station_id)
                if s.kind == "station" and not (s.is_origin or s.is_destination) and dep is not None:
                    planned.setdefault((s.station_id, s.stop_id), []).append((dep, trip.trip_id))
        self._planned = {key: sorted(v) for key, v in planned.items()}
        self._last_departure_s: dict[tuple[str, str], float] = {}
        self.extensions_s: dict[str, dict[str, float]] = {}  # trip -> station -> extension [s]
        self.passengers: dict[str, dict[str, float]] = {}  # trip -> station -> extra boarding passengers

    def planned_interval_s(self, trip: Trip, stop: TripStop) -> float | None:
        """This trip's planned arrival minus the latest planned departure of another trip from the platform."""
        arrival = trip.planned_arrival_s.get(stop.station_id)
        deps = self._planned.get((stop.station_id, stop.stop_id), [])
        if arrival is None:
            return None
        k = bisect.bisect_right(deps, (arrival, "\uffff"))
        earlier = [d for d, tid in deps[:k] if tid != trip.trip_id]
        return arrival - earlier[-1] if earlier else None

    def extension_s(self, t: float, trip: Trip, stop: TripStop) -> float:
        """The extra dwell [s] of ``trip`` at ``stop`` where it halted at ``t`` (module docstring); recorded."""
        if stop.kind != "station" or stop.is_origin or stop.is_destination:
            return 0.0
        last = self._last_departure_s.get((stop.station_id, stop.stop_id))
        planned = self.planned_interval_s(trip, stop)
        if last is None or planned is None:
            return 0.0
        late_s = (t - last) - planned
        rate = self.spec.rate_per_h(stop.station_id, self.start_time_s + t)
        if late_s <= 0.0 or rate <= 0.0:
            return 0.0
        pax = rate / 3600.0 * late_s * self.intensity
        extra_s = self.spec.s_per_passenger * pax
        self.extensions_s.setdefault(trip.trip_id, {})[stop.station_id] = extra_s
        self.passengers.setdefault(trip.trip_id, {})[stop.station_id] = pax
        return extra_s

    def departed(self, t: float, stop: TripStop) -> None:
        """A train left ``stop``'s platform at ``t``: the next train's interval starts now. Only trains calling
        there count (not one starting its trip there), on both sides of the interval."""
        if stop.kind == "station" and not (stop.is_origin or stop.is_destination):
            self._last_departure_s[(stop.station_id, stop.stop_id)] = t
