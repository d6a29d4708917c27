"""Dispatching: departures that fall due at exact timetable times.

The timetable says a trip leaves at 08:00:00; SUMO steps at 0.5 s. The dispatcher turns each planned
departure into a simpy process that wakes at exactly the planned time, logs ``departure_due`` (subject =
trip id) and calls the engine's callback, which then inserts or releases the train. What the engine does
with it — and whether the train actually leaves on time (a locked route, an occupied platform) — is
recorded separately; the log keeps the *due* time, so delay against the timetable is ``actual − due``.

Callbacks run inside ``layer.advance_to``; they are called as ``callback(trip_id, t_s)``.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from railsim.engine.events.clock import EventLayer, ScheduledCall


class Dispatcher:
    """Planned departures of one simulation."""

    def __init__(self, layer: EventLayer) -> None:
        self._layer = layer
        self._planned: dict[str, ScheduledCall] = {}

    def schedule_departure(self, t_s: float, trip_id: str, callback: Callable[[str, float], object]) -> ScheduledCall:
        """At exactly ``t_s`` log ``departure_due`` for ``trip_id`` and call ``callback(trip_id, t_s)``.

        A trip id may be planned once (ValueError otherwise); ``t_s`` before now raises ValueError.
        """
        if trip_id in self._planned:
            raise ValueError(f"trip {trip_id!r} already has a departure planned")
        t_s = float(t_s)
        if not math.isfinite(t_s) or t_s < self._layer.now_s:
            raise ValueError(f"trip {trip_id!r}: departure at {t_s!r} s is before now ({self._layer.now_s} s)")
        handle = self._layer.at(t_s, lambda t: callback(trip_id, t), kind="departure_due", subject=trip_id)
        self._planned[trip_id] = handle
        return handle

    def cancel(self, trip_id: str) -> None:
        """Drop a planned departure that has not fallen due yet (KeyError for an unknown trip)."""
        self._planned[trip_id].cancel()

    def pending(self) -> tuple[str, ...]:
        """Trip ids planned, not cancelled and not yet due, sorted by due time then id."""
        items = [(h.t_s, tid) for tid, h in self._planned.items() if not h.cancelled and h.fired_count == 0]
        return tuple(tid for _, tid in sorted(items))
