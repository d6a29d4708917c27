"""Platform berths: a train does not run into a platform that another train is still occupying.

A platform track is one berth. Moving-block separation alone would let a follower close up to its margin behind
a train standing at a long platform — inside the platform, where it would halt short of its mark and SUMO could
register the stop there (the depot day's unit at T2 was served 106 m short that way). As with a platform's
entry signal, the follower's movement authority ends the overlap (``protection_margin_m``) before the start of
the platform it is heading for while the train directly ahead stands — or is stopping there — with any part of
its body on that platform. Once that train moves off (its stop there is over), the follower may run in behind it,
kept back by its separation (as a CBTC movement authority follows a departing train's rear) — the station headway
moving block is known for.
Track-vacancy detection sees the truth, so the train ahead is taken from the ground-truth occupancy
(:class:`railsim.engine.occupancy.Ahead`). A follower coupling or coupled behind the train ahead is exempt: it
enters the platform behind its leader on purpose; so is a unit on its way to couple on departure behind the
train standing at its origin platform (called on, as a unit that attaches: ``FormationBook.joins``) — held at the
berth limit it stood 155 m behind its leader at Liugongli, beyond the 150 m from which the coupling is asked,
and the leader waited the whole coupling timeout for it. A formation partner that is not coupling is not exempt.
A train already past the berth's limit (it was let in, or it is standing at the platform) is not stopped again.

**Never inside the braking distance** (approach locking): a berth limit that appears when the follower could no
longer stop for it at its service deceleration is not imposed on that follower — it is let in, kept back by its
separation behind the occupant's rear as at any other point of the line. Once imposed, the limit holds while the
occupant stands (the follower then brakes for it along its own curve). On the depot day a unit running to the
airport without a stop at Bijin halted on Bijin's platform for the points ahead; the Airport train behind,
~155 m from the limit at 19 m/s (braking distance ~190 m), had its authority cut and braked in emergency for one
step before the unit moved on.

**On by default**; ``interlocking: {platform_berths: false}`` turns it off. A train standing at a berth limit
waits for the occupant: :attr:`Berths.waiting` tells the stall watchdog (:mod:`railsim.engine.watchdog`) so, as
an edge of its wait-for graph (resource ``platform:S``), and its wait is not a stall while the occupant itself
stands for a reason (dwells, or waits for its departure time).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

from railsim.engine.events.log import EventLog
from railsim.engine.occupancy import Ahead
from railsim.engine.settings import EngineSettings
from railsim.engine.train import TrainRuntime
from railsim.engine.trips import TripStop

BERTH_WAIT_M = 10.0  # a train standing this close to an occupied platform's limit waits for it (logged once)


class Berths:
    """The berth rule at run time: each train's authority cut at an occupied platform, its ``platform_occupied``
    event (once per train and station), and who stands waiting for whose platform (:attr:`waiting`, for the stall
    watchdog: the occupant is the train it waits for)."""

    def __init__(
        self,
        trains: Mapping[str, TrainRuntime],
        events: EventLog,
        settings: EngineSettings,
        coupled_behind: Callable[[str, str], bool],
        dt_s: float,
    ) -> None:
        self.trains = trains
        self.dt_s = dt_s
        self.events = events
        self.settings = settings
        self.coupled_behind = coupled_behind
        self.waiting: dict[str, tuple[str, str]] = {}  # train standing at a berth limit -> (station, occupant)
        self._logged: set[tuple[str, str]] = set()  # (train, station) whose platform_occupied was logged
        self._imposed: dict[str, str] = {}  # train -> station whose berth limit it was given (holds while standing)

    def authority_end_m(
        self, t: float, tr: TrainRuntime, stop: TripStop | None, a: Ahead | None, authority_m: float
    ) -> float:
        """``authority_m`` (the route locks' end of authority), cut short of the platform ``tr`` is heading for
        while the train ahead stands on it. Most calls end at the geometry of :func:`berth_limit_m` (no train
        ahead on the platform, or the train already past its limit): nothing is built for them."""
        tid = tr.train_id
        if self.waiting:
            self.waiting.pop(tid, None)
        if a is None or stop is None or not self.settings.platform_berths:
            if self._imposed:  # no limit now: one given before is no longer held
                self._imposed.pop(tid, None)
            return authority_m
        margin_m = self.settings.protection_margin_m
        berth_m = berth_limit_m(tr.front_m, tid, stop, a, self.trains, margin_m, self.coupled_behind)
        if berth_m is None:
            if self._imposed:
                self._imposed.pop(tid, None)
            return authority_m
        if self._imposed.get(tid) != stop.station_id:
            if berth_m - tr.front_m < service_braking_m(tr, self.dt_s):
                return authority_m  # too late to stop for it: let in (approach locking), separation keeps it back
            self._imposed[tid] = stop.station_id
        if berth_m >= authority_m:
            return authority_m
        if tr.plant.speed_mps == 0.0 and berth_m - tr.front_m < BERTH_WAIT_M:  # standing at the limit: it waits
            self.waiting[tid] = (stop.station_id, a.train_id)
            key = (tid, stop.station_id)
            if key not in self._logged:
                self._logged.add(key)
                self.events.record(t, "platform_occupied", tid, station=stop.station_id, by=a.train_id)
        return berth_m


def berth_limit_m(
    front_m: float,
    train_id: str,
    stop: TripStop | None,
    ahead: Ahead | None,
    trains: Mapping[str, TrainRuntime],
    overlap_m: float,
    coupled_behind: Callable[[str, str], bool],
) -> float | None:
    """The chainage (own route frame) where the train must stop short of an occupied platform, or None.

    ``stop`` is the stop the train is heading for, ``ahead`` the train directly ahead (its front and rear in the
    same frame), ``trains`` every train by id (the one ahead is looked up only once the geometry says it could
    matter: the cheap checks first, every train, every step — whether it stands there, then whether the train is
    coupled behind it)."""
    if ahead is None or stop is None or stop.kind != "station":
        return None
    window_end_m = stop.window_end_m
    platform_start_m = window_end_m - stop.platform_m
    limit_m = platform_start_m - overlap_m
    if front_m > limit_m + 1e-6:  # already let in (or standing at the platform)
        return None
    if ahead.rear_m >= window_end_m or ahead.front_m <= platform_start_m:
        return None  # the train ahead is clear of the platform (beyond it, or not on it yet)
    occupant = trains[ahead.train_id]
    if occupant.plant.speed_mps != 0.0 and not _stops_at(occupant, stop.station_id):
        return None  # a train ahead that is moving draws clear: the follower may run in behind it (separation)
    if coupled_behind(train_id, ahead.train_id):
        return None
    return limit_m


def service_braking_m(tr: TrainRuntime, dt_s: float) -> float:
    """How far ``tr`` runs before it stands if it brakes at its service deceleration now [m]: a control step and
    the brake's lag at the present speed, then ``v² / 2b`` — the distance inside which an authority cut is too
    late (the train would need its emergency brake)."""
    v = tr.plant.speed_mps
    vehicle = tr.trip.vehicle
    return v * (dt_s + vehicle.actuator_time_constant_s) + v * v / (2.0 * vehicle.service_decel_mps2)


def _stops_at(tr: TrainRuntime, station_id: str) -> bool:
    """True while ``tr`` is heading for (or standing at) a stop at ``station_id``: it will stand there, so the
    platform is occupied from the moment its body is on it, not only from its halt — a follower then meets the
    berth limit while still far enough back to brake for it (holding it only from the halt cut its authority
    short suddenly: 8 one-step emergency brakes on the Line 3 day, trains ~200 m behind a train halting at Bijin)."""
    return tr.next_stop < len(tr.trip.stops) and tr.trip.stops[tr.next_stop].station_id == station_id
