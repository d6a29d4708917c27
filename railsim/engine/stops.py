"""Station stops on the train side: halts, SUMO's stop registration, dwell end, arrival and missed stops.

A controller brakes the train to a halt inside the platform window; SUMO registers the stop (~1 s later) and
keeps the dwell. This port watches both: the halt (our plant at 0 inside the window) gives the stopping error
(front − mark; a coupled follower's mark is behind its leader's, see :meth:`FormationBook.mark_offset_m`);
SUMO's registration counts the stop served (and ends the trip at the destination); SUMO releasing the train
ends the dwell (departure); a front beyond the window's end by more than the tolerance is a missed stop. SUMO
registering a *moving* train as stopped is logged as an error event (``stop_registered_moving``). A stop at a
platform shorter than the train (:mod:`railsim.engine.trips`) is served with the front at the platform end and
recorded as a ``stop_short_platform`` event (platform and train length), not as a missed stop; a halt up to
``overrun_m`` (1 m) past such a platform's end is served too (``stop_overrun_served``), as SUMO's stop on the lane
reaches that far: a train 0.7 m past a 25 m stop used to lose the stop (``stop_missed``). A train that halts
past the end of a platform it fits on, by no more than the missed-stop tolerance, is neither missed nor ever
registered by SUMO (a trainStop registers only a front inside it, and the front may already be on the junction
after the platform): the engine registers the halt itself, keeps the dwell, and the stop is served with the
overrun recorded (``stop_overrun_served``; a tram 0.11 m past a 30 m platform in Potsdam stood there until the
stall watchdog ended the run).

Far from the stop
-----------------
Almost every train, almost every step, runs between two platforms, where none of the above can happen: SUMO has
not registered a stop, the front is short of the window (no halt in it, no overrun of it) and the train can still
stop before the window's end plus the tolerance even with nothing but its emergency brake (the cheap screen of
:func:`surely_overruns_m`). :meth:`StopBook.bookkeeping` tests exactly these conditions first, against bounds
worked out once per train and stop (:class:`_FarBounds`; worked out anew when the train's stop index, its trip's
stops or its vehicle change: a stop served, missed or skipped, a turnback or a primary delay replacing the stops),
and returns at once when they hold — what the full pass would have done, for a few attribute reads.

Dwelling
--------
A train SUMO holds at its stop (registered, and still registered in this step) waits for the end of its dwell:
the full pass has nothing to do for it but at a reversal (which watches for SUMO flipping the train). So
:meth:`StopBook.bookkeeping` returns at once for it, too.

``StopBook.screen_far = False`` runs the full pass every step (the reference of ``tests/unit/test_stops_far.py``).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from typing import Any, NamedTuple, Protocol

from railsim.engine.coupling import FormationBook
from railsim.engine.events.log import EventLog
from railsim.engine.settings import EngineSettings
from railsim.engine.train import TrainRuntime
from railsim.engine.trips import Trip, TripStop
from railsim.engine.wiring import set_once, unwired
from railsim.physics import dynamics

log = logging.getLogger(__name__)
MOVING_REGISTRATION_MPS = 0.1  # SUMO registering a stop above this speed is an error event


class PlatformRoutes(Protocol):
    """What the stop book asks of the route locks (:class:`~railsim.engine.locking.RouteLocks`)."""

    def wanted_by_others(self, tr: TrainRuntime) -> bool:
        """Another train waits for a single-track section ``tr`` holds."""

    def clears_platform(self, tr: TrainRuntime, stop: TripStop) -> bool:
        """The route set beyond ``stop`` lets ``tr`` draw clear of the platform."""

    def release_all(self, tr: TrainRuntime) -> None:
        """``tr`` gives up every lock and section it holds."""


class PassengerDemand(Protocol):
    """Passenger demand at the platforms (:class:`~railsim.engine.passenger_dwell.DemandDwell`)."""

    def extension_s(self, t: float, trip: Trip, stop: TripStop) -> float:
        """The extra dwell [s] the demand adds to ``trip``'s stop registered at ``t``."""

    def departed(self, t: float, stop: TripStop) -> None:
        """A train left ``stop``'s platform at ``t`` (the next train's interval starts)."""


class _FarBounds(NamedTuple):
    """What :meth:`StopBook.bookkeeping` needs to know a train is far from its next stop, for one stop of one trip."""

    stops: tuple[TripStop, ...]  # the trip's stops it was worked out for (compared by identity)
    stop_i: int  # the stop's index in them (the train's ``next_stop``)
    vehicle: Any  # the trip's vehicle (by identity)
    front_below_m: float  # the front short of this: no halt in the window, no overrun of it (-inf: never far)
    end_m: float  # the window's served end plus the missed-stop tolerance (surely_overruns_m's end + tolerance)
    decel_mps2: float  # the vehicle's emergency deceleration


class StopBook:
    """Per-train stop progress (``next_stop``, halt, dwell) and the stop records."""

    def __init__(
        self,
        formations: FormationBook,
        routes: PlatformRoutes,
        events: EventLog,
        settings: EngineSettings,
        record_stop: Callable[..., None],
        passengers: PassengerDemand | None,
        euler_dt_s: float = 0.0,
    ) -> None:
        """``euler_dt_s``: the step length when SUMO moves trains by Euler positions (a step's advance is the new
        speed times the step), else 0 (:func:`surely_overruns_m`)."""
        self.formations = formations
        self.euler_dt_s = euler_dt_s
        self.events = events
        self.settings = settings
        self.record_stop = record_stop
        self.release_locks = routes.release_all
        # the SUMO bridge's (train, stop id, lane window), once the run has started it: connect()
        self.drop_stop: Callable[[str, str, tuple[float, float] | None], None] = unwired("StopBook", "drop_stop")
        # another unit waits for the turnback track this unit holds
        self.track_wanted = routes.wanted_by_others
        # a unit that couples behind a leader at its origin waits for it (FormationBook.waits_for_leader); a leader
        # stays at a platform until the unit coupling behind it is there (FormationBook.holds_departure)
        self.wait_for_leader, self.hold_departure = formations.turnback_waits()
        # the route beyond the stop lets the train draw clear of the platform
        self.route_set = routes.clears_platform
        self.passengers = passengers  # passenger demand that lengthens dwells (None: the timetable's dwells)
        self._held: set[tuple[str, int]] = set()  # (train, stop index) whose hold was logged
        self.screen_far = True  # False: the full pass every step (the reference of the far screen)
        self._far: dict[str, _FarBounds] = {}  # train -> the bounds of its next stop (see "Far from the stop")

    def connect(self, drop_stop: Callable[[str, str, tuple[float, float] | None], None]) -> None:
        """The SUMO bridge's ``drop_stop``, once the run has started it."""
        set_once(self, "drop_stop", drop_stop)

    def current(self, tr: TrainRuntime) -> tuple[TripStop | None, float]:
        """The stop the train is heading for or standing at, and how far behind its mark it halts."""
        i = tr.next_stop
        stops = tr.trip.stops
        if i >= len(stops):
            return None, 0.0
        stop = stops[i]
        if tr.train_id not in self.formations.of_follower:  # mark_offset_m's own first test: no follower, no offset
            return stop, 0.0
        return stop, self.formations.mark_offset_m(tr, stop)

    def _far_bounds(self, tr: TrainRuntime) -> _FarBounds:
        """The bounds of "far from the stop" for the train's next stop (see the module's notes)."""
        trip = tr.trip
        stops, i, veh = trip.stops, tr.next_stop, trip.vehicle
        if i >= len(stops):  # no stop left: the full pass returns at once anyway
            return _FarBounds(stops, i, veh, -math.inf, -math.inf, 0.0)
        stop = stops[i]
        if stop.kind == "reversal":
            return _FarBounds(stops, i, veh, -math.inf, -math.inf, 0.0)
        tolerance_m = self.settings.missed_stop_tolerance_m
        served_end_m = stop.served_end_m
        # each the exact expression of the test it rules out: front < this makes that test false
        front_below_m = min(stop.window_start_m - 1e-6, stop.window_end_m + 1e-6, served_end_m + tolerance_m)
        return _FarBounds(stops, i, veh, front_below_m, served_end_m + tolerance_m, veh.emergency_decel_mps2)

    def bookkeeping(self, t: float, tr: TrainRuntime) -> None:
        """A train's stop progress at ``t``: halt, registration, dwell end and departure, missed stop, reversal."""
        if not self.screen_far:
            self._full_pass(t, tr)
            return
        if tr.sumo_stopped:
            if tr.sumo_stopped_now:  # dwelling (see "Dwelling"): the full pass acts only at a reversal
                i, stops = tr.next_stop, tr.trip.stops
                if i >= len(stops) or stops[i].kind != "reversal":
                    return
        elif not tr.sumo_stopped_now:
            far = self._far.get(tr.train_id)
            trip = tr.trip
            if (
                far is None
                or far.stops is not trip.stops
                or far.stop_i != tr.next_stop
                or far.vehicle is not trip.vehicle
            ):
                far = self._far[tr.train_id] = self._far_bounds(tr)
            front_m = tr.front_m
            if front_m < far.front_below_m:
                v = tr.plant.speed_mps
                # surely_overruns_m's cheap screen, the same expression: it can still stop in time
                if (far.end_m - front_m) * 2.0 * far.decel_mps2 >= v * v:
                    return
        self._full_pass(t, tr)

    def _full_pass(self, t: float, tr: TrainRuntime) -> None:
        stop, offset = self.current(tr)
        if stop is None:
            return
        if stop.kind == "reversal":
            self._reversal(t, tr, stop)
            return
        stopped_now = tr.sumo_stopped_now
        v = tr.plant.speed_mps
        mark = stop.mark_m - offset
        if stopped_now and not tr.sumo_stopped:
            if stop.is_origin and tr.front_m < stop.window_start_m - self.settings.missed_stop_tolerance_m:
                return  # a unit still standing at its last trip's end, to run round a loop to its platform
            self._registered(t, tr, stop, mark, v)
            return
        if tr.sumo_stopped and not stopped_now:  # dwell over: departure
            if tr.dwell_until_s is not None and t < tr.dwell_until_s:
                return  # SUMO's dwell is over; more passengers than planned are still boarding (the ATO holds it)
            if self.hold_departure(t, tr):  # SUMO's dwell is over; it stays (the ATO holds it) for its follower
                if (tr.train_id, tr.next_stop) not in self._held:
                    self._held.add((tr.train_id, tr.next_stop))
                    self.events.record(t, "departure_held_for_follower", tr.train_id, station=stop.station_id)
                return
            tr.held_for_route = not self.route_set(tr, stop)
            if tr.held_for_route:  # as behind a starting signal at danger: the route is not set yet
                if (tr.train_id, tr.next_stop) not in self._held:
                    self._held.add((tr.train_id, tr.next_stop))
                    self.events.record(t, "departure_held_for_route", tr.train_id, station=stop.station_id)
                return
            tr.sumo_stopped = False
            tr.dwell_until_s = None
            if self.passengers is not None:
                self.passengers.departed(t, stop)
            self._record(tr, stop, tr.halted_s, t, tr.halt_error_m)
            self.events.record(t, "stop_departed", tr.train_id, station=stop.station_id)
            if stop.is_origin and tr.departed_s is None:  # a unit's next trip leaves its origin platform
                tr.departed_s = t
                self.events.record(t, "train_departed", tr.train_id, station=stop.station_id)
            self.formations.on_departed_station(tr, stop)
            tr.next_stop += 1
            tr.halted_s = None
            tr.halt_error_m = None
            return
        if (
            not tr.sumo_stopped
            and tr.halted_s is None
            and v == 0.0
            and stop.window_start_m - 1e-6 <= tr.front_m <= stop.served_end_m + 1e-6
        ):
            tr.halted_s = t
            tr.halt_error_m = tr.front_m - mark
        if (
            not tr.sumo_stopped
            and v == 0.0
            and stop.lane_stop_m is None
            and stop.window_end_m + 1e-6 < tr.front_m <= stop.served_end_m + self.settings.missed_stop_tolerance_m
        ):  # halted just past a platform it fits on: SUMO never registers that trainStop (nor one on a junction)
            self.drop_stop(tr.sumo_id, stop.stop_id, None)  # if SUMO has not dropped it as run past already
            self._registered(t, tr, stop, mark, v)
            tr.dwell_until_s = t + stop.dwell_s  # the engine keeps the dwell (the ATO holds it on its stop point)
            return
        if not tr.sumo_stopped and tr.front_m > stop.served_end_m + self.settings.missed_stop_tolerance_m:
            self._missed(t, tr, stop)
        elif not tr.sumo_stopped and tr.halted_s is None and v > 0.0:
            tolerance_m = self.settings.missed_stop_tolerance_m
            overrun_m = surely_overruns_m(tr, stop.served_end_m, tolerance_m, v, self.euler_dt_s)
            if overrun_m is not None:  # missed now: SUMO would halt it at the stop's end, harder than it can brake
                self._missed(t, tr, stop, overrun_m)

    def _registered(self, t: float, tr: TrainRuntime, stop: TripStop, mark: float, v: float) -> None:
        tr.sumo_stopped = True
        tr.dwell_started_s = t
        if v > MOVING_REGISTRATION_MPS:
            self.events.record(t, "stop_registered_moving", tr.train_id, station=stop.station_id, speed_mps=v)
            log.error("SUMO registered %s as stopped at %s while moving at %.2f m/s", tr.train_id, stop.station_id, v)
        if tr.halted_s is None:  # SUMO saw the halt before we did (same step)
            tr.halted_s = t
            tr.halt_error_m = tr.front_m - mark
        if stop.is_origin:  # a unit after its reversal: it boards where it stands, no stopping error
            tr.halt_error_m = None
        if not stop.is_origin:
            tr.stops_served += 1
        self.events.record(t, "stop_registered", tr.train_id, station=stop.station_id)
        # arrival = the halt, as the plan counts it
        extra_s = self.passengers.extension_s(tr.halted_s, tr.trip, stop) if self.passengers is not None else 0.0
        if extra_s > 0.0:
            tr.dwell_until_s = t + stop.dwell_s + extra_s
            self.events.record(t, "dwell_extended_demand", tr.train_id, station=stop.station_id, extra_s=extra_s)
        if stop.short_platform:  # served, with the front at the platform end and the rest of the train behind it
            self.events.record(
                t,
                "stop_short_platform",
                tr.train_id,
                station=stop.station_id,
                platform_m=round(stop.platform_m, 3),
                train_m=tr.trip.vehicle.length_m,
            )
        if tr.front_m > stop.window_end_m + 1e-6:  # a sub-metre overrun of a short platform: served all the same
            overrun_m = round(tr.front_m - stop.window_end_m, 3)
            self.events.record(t, "stop_overrun_served", tr.train_id, station=stop.station_id, overrun_m=overrun_m)
        if stop.is_destination:
            tr.arrived_s = tr.halted_s
            tr.status = "arrived"
            self._record(tr, stop, tr.halted_s, None, tr.halt_error_m)
            self.events.record(t, "train_arrived", tr.train_id, station=stop.station_id)
            self.release_locks(tr)

    def _reversal(self, t: float, tr: TrainRuntime, stop: TripStop) -> None:
        """A unit reverses (``railsim.engine.turnback``): it halts on the reversal edge and SUMO flips it onto the
        ``bidi`` edge (``stop.stop_id``) — SUMO decides the moment (at standstill by its own threshold), so the
        flip itself counts as the halt. It then stands at least ``stop.dwell_s`` and until ``tr.hold_until_s``
        (a unit early for its next departure waits here, off the platform, unless another unit waits for this
        turnback track: then it goes on to wait at its platform) before it runs on. A unit that couples on
        departure behind a leader waits here until that leader stands at its platform (``wait_for_leader``)."""
        flipped = tr.sumo_edge == stop.stop_id
        if tr.halted_s is None:
            in_window = stop.window_start_m - 1e-6 <= tr.front_m <= stop.window_end_m + 1e-6
            if flipped or (tr.plant.speed_mps == 0.0 and in_window):
                tr.halted_s = t
                self.events.record(t, "reversal_halt", tr.train_id, station=stop.station_id)
            elif tr.front_m > stop.window_end_m + self.settings.missed_stop_tolerance_m:
                self.events.record(
                    t, "reversal_missed", tr.train_id, overrun_m=round(tr.front_m - stop.window_end_m, 3)
                )
                log.error("%s ran past its reversal point at %s", tr.train_id, stop.station_id)
            return
        if self.wait_for_leader(tr):
            return  # it comes out behind its leader, once the leader stands at the platform
        hold_until_s = max(tr.halted_s + stop.dwell_s, tr.hold_until_s or 0.0)
        if tr.hold_until_s is not None and t >= tr.halted_s + stop.dwell_s and self.track_wanted(tr):
            hold_until_s = t  # another unit waits for this turnback track: wait at the platform instead
        if flipped and t >= hold_until_s:
            self.events.record(t, "reversed", tr.train_id, station=stop.station_id, edge=stop.stop_id)
            tr.reversing = False
            tr.halted_s = None
            tr.hold_until_s = None
            tr.next_stop += 1

    def _missed(self, t: float, tr: TrainRuntime, stop: TripStop, overrun_m: float | None = None) -> None:
        """A stop the train ran past (``overrun_m`` None: its front is beyond the window) or will run past whatever
        it does (``overrun_m``: the least overrun, :func:`surely_overruns_m`)."""
        past_m = tr.front_m - stop.window_end_m if overrun_m is None else overrun_m
        detail = {"overrun_m": round(past_m, 3)} if overrun_m is None else {"least_overrun_m": round(past_m, 3)}
        self.events.record(t, "stop_missed", tr.train_id, station=stop.station_id, **detail)
        log.warning("%s overran the platform at %s by %s%.2f m", tr.train_id, stop.station_id,
                    "" if overrun_m is None else "at least ", past_m)  # fmt: skip
        self._record(tr, stop, None, None, None, missed=True)
        self.drop_stop(tr.sumo_id, stop.stop_id, stop.lane_stop_m)
        tr.next_stop += 1
        tr.halted_s = None
        if stop.is_destination:
            tr.status = "arrived"
            tr.arrived_s = t

    def _record(
        self,
        tr: TrainRuntime,
        stop: TripStop,
        arrival_s: float | None,
        departure_s: float | None,
        error_m: float | None,
        missed: bool = False,
    ) -> None:
        self.record_stop(
            trip_id=tr.train_id,
            service=tr.trip.service_id,
            station=stop.station_id,
            planned_arrival_s=tr.trip.planned_arrival_s.get(stop.station_id),
            arrival_s=arrival_s,
            departure_s=departure_s,
            error_m=error_m,
            missed=missed,
        )


def surely_overruns_m(
    tr: TrainRuntime, end_m: float, tolerance_m: float, v_mps: float, euler_dt_s: float = 0.0
) -> float | None:
    """How far past ``end_m`` (a stop window's end) the front runs at the least, if that is more than
    ``tolerance_m`` (a missed stop); None if it may still stop within it.

    The least stopping distance (:func:`railsim.physics.dynamics.least_stop_distance_m`: the emergency brake at
    once, resistance and gradient helping; no lag, no jerk ramp, no reaction step) is shorter than any real one
    when positions follow the speed continuously: beyond the limit, the stop is missed whatever the train does.
    (SUMO would otherwise halt it at the stop's end at once, from any speed: a hidden overrun,
    :meth:`railsim.engine.safety.SafetyMonitor.speed_imposed`.) SUMO's Euler positions (``euler_dt_s`` > 0: each
    step advances the train by its *new* speed times the step) run a braking train short of that distance: for a
    constant deceleration ``b`` from ``v``, ``dt·Σ_k max(v − k·b·dt, 0) = v²/(2b) − v·dt/2 + b·dt²·f(1−f)/2``
    (``f`` the fractional part of ``v/(b·dt)``), never less than ``v²/(2b) − v·dt/2``: that is the bound then. A
    tram 1.2 m past its mark at 3.75 m/s, on the service brake, was declared 0.52 m past its stop's tolerance and
    stood 0.24 m past the platform's end (Dresden, Zschertnitz)."""
    veh = tr.trip.vehicle
    room_m = end_m + tolerance_m - tr.front_m
    if room_m * 2.0 * veh.emergency_decel_mps2 >= v_mps * v_mps:  # the cheap screen: it stops in time without drag
        return None
    least_m = dynamics.least_stop_distance_m(veh, v_mps, tr.view.gradient_at(tr.front_m)) - 0.5 * v_mps * euler_dt_s
    return least_m - (end_m - tr.front_m) if least_m > room_m else None
