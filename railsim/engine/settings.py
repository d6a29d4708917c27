"""The engine's operating rules (not any one controller's): distances and times the loop and its ports use.

A scenario's ``interlocking:`` section overrides some of :class:`EngineSettings` (:meth:`with_interlocking`: the
overlap is ``protection_margin_m``); the named constants below are rules that are not (yet) scenario knobs.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import Any

INF = float("inf")
FREE_RUN_MISSED_M = 0.5  # the planned free run passes a stop its front is this far beyond (the missed-stop tolerance)
INSERTION_REACTION_S = 1.0  # a train approaching a departure needs this long to react before it brakes
DWELL_REGISTRATION_S = 1.0  # SUMO dwell given to a destination stop (the trip ends when SUMO registers it)
FACING_DECEL_MPS2 = (
    0.5  # a train looks for trains facing it on its track as far as it brakes at this (and its sensor range)
)
# SUMO never drives our trains (speedMode 32), but it still checks insertion with the vType's Krauss model: its
# safe insertion speed is about gap/tau when decel·tau is large, so a tiny tau and a huge decel let a train be
# inserted exactly where and when the scenario says, at speed, close behind another (our occupancy check, not
# SUMO, judges safety). Without this SUMO silently delays the insertion.
PERMISSIVE_TAU_S = 0.001
PERMISSIVE_DECEL_MPS2 = 1000.0
PERMISSIVE_SPEED_FACTOR = 1.5  # the vType's max speed: above the vehicle's, so SUMO never caps our speed


@dataclass(frozen=True)
class EngineSettings:
    """Operating rules of the engine (not of any one controller); scenario ``engine:`` may override."""

    lock_request_distance_m: float = 1500.0
    protection_margin_m: float = 20.0  # the overlap: authority ends this far before what is not reserved
    clearance_m: float = 10.0
    max_message_age_s: float = 2.0
    decouple_distance_m: float = 2000.0
    lookahead_m: float = 5000.0
    separation_gap_m: float = 300.0  # formation decoupling completes at this true gap (front-to-rear)
    missed_stop_tolerance_m: float = 0.5
    final_approach_margin_m: float = 50.0  # coupled follower: hand the stop to the ATO this far before braking
    sensor_range_m: float = 400.0  # a train's own ranging sensor (collision avoidance) sees this far ahead
    insertion_margin_m: float = 50.0  # departures wait for this much room ahead and behind
    departure_retry_s: float = 1.0  # ... and is tried again after this long
    desync_tolerance_m: float = 0.05  # railsim's chainage and SUMO's lane position may differ this much
    stall_timeout_s: float = 300.0  # a train standing this long with no reason (no stop, no hold) stalls the run
    platform_berths: bool = True  # a train does not run into a platform the train ahead stands on (platforms.py)

    def __reduce__(self) -> tuple[type[EngineSettings], tuple[Any, ...]]:
        """Pickled and copied as a call of the constructor with the fields in order (compiled by
        :mod:`railsim.native`, a frozen dataclass has no way to set its fields back one by one)."""
        return (type(self), tuple(getattr(self, f.name) for f in fields(self)))

    def with_interlocking(self, spec: Any) -> EngineSettings:
        """These settings with a scenario's ``interlocking:`` knobs (an ``InterlockingSpec``) applied."""
        changes: dict[str, Any] = {}
        if spec.overlap_m is not None:
            changes["protection_margin_m"] = float(spec.overlap_m)
        if spec.stall_timeout_s is not None:
            changes["stall_timeout_s"] = float(spec.stall_timeout_s)
        if getattr(spec, "platform_berths", None) is not None:
            changes["platform_berths"] = bool(spec.platform_berths)
        return replace(self, **changes) if changes else self
