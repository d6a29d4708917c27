"""The dispatcher: trains enter the world (SUMO) when due, leave it when they arrive or leave the line.

* A departure is a simpy event at the trip's departure time. A follower that couples ``on_departure`` is
  instead inserted behind its leader: at once when both start at the same station (the leader is inserted,
  then the follower at the target gap behind the leader's rear), else by
  :class:`~railsim.engine.coupling.FormationBook` once the leader stands at the follower's origin.
* **A valid position.** SUMO reads a negative ``departPos`` as "from the lane's end" and clamps one past the
  end, so a wrong start chainage would put the train somewhere railsim does not believe it is. The start
  chainage must lie on the route (``0 ≤ front ≤ route length``) and a follower's whole body must fit behind its
  leader on the track (rear ≥ 0); a same-origin formation that does not fit is a :class:`ConfigError` at set-up.
* **Holding a departure.** A train starting at a platform occupies ``[front − length, front]`` at once. If
  another train's body overlaps that ("track occupied by X") or a train approaching on shared track could not
  stop short of its rear (service braking distance + one reaction time + ``insertion_margin_m``: "approaching
  train X could not stop"), or the rear of a train ahead lies less than ``insertion_margin_m`` beyond its front
  ("X ahead is less than 50 m clear": a train is not put on the track nose to tail behind a leaving train; a
  follower that couples on departure is put on at its target gap by ``insert_behind``, not here — only a
  collision course holds it (below: a train approaching from behind that could not stop for it) — and never
  faster than its leader: a start speed above the leader's is limited to it, a ``start_speed_limited`` event), the
  departure waits. A train started *in motion* (``services[].start``) is held only on a collision course
  (:meth:`Dispatcher.collision_course`: closer to a train ahead, or a train behind closer to it, than the one
  behind's least stopping distance less the one ahead's — found by fuzzing: a train put on at 60 km/h 71 m behind
  a standing one collided whatever it did); a platoon put on in motion at one speed is not held. Held
  departures log a ``departure_held`` event with the ``reason`` (again each
  time the reason changes), retried every ``departure_retry_s``. Each rule is asked only of the trains near the spot
  (:class:`~railsim.engine.insertion_reach.NearTrains`, an index of the trains on the line by edge, with the bound
  on how far each rule looks): the answer of asking every train on the line, the first in scenario order, with
  frame changes for the trains near it only. The dispatcher, not the follower, is
  responsible for a train appearing on the track. A train never inserted by the end of the run is reported
  (:meth:`Dispatcher.report_never_inserted`: one ``never_inserted`` event each; the CLI exits 3).
* **Inserting** hands SUMO the route (trimmed to begin at the edge holding the start chainage), the stops with
  their dwells, and the start speed; extensions hook in (``on_inserted``: exact plants, …) and the formation
  partners register (:meth:`Knowledge.handshake`).
* **Waiting in SUMO's queue.** SUMO puts a train on only once its spot is free, which can be minutes later; every
  step a *standing* train still in the queue is checked again against trains approaching from behind (the rule
  above), and withdrawn (``train_withdrawn``), held and retried if one could not stop for it
  (:meth:`Dispatcher.guard_pending`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, Protocol

from railsim.engine.coupling import FormationBook
from railsim.engine.events.clock import EventLayer
from railsim.engine.events.log import EventLog
from railsim.engine.extensions.base import ExtensionSet
from railsim.engine.fleet import Fleet
from railsim.engine.insertion_reach import NearTrains, approach_needed_m
from railsim.engine.routeview import RouteView
from railsim.engine.settings import EngineSettings
from railsim.engine.train import TrainRuntime
from railsim.engine.trips import sumo_stops
from railsim.engine.wiring import set_once, unwired
from railsim.errors import ConfigError, SimulationError
from railsim.physics import dynamics

# before inserting train at (t, train, start chainage): a reason to hold its departure, or None
Admission = Callable[[float, TrainRuntime, float], str | None]


class SumoInsertion(Protocol):
    """What the dispatcher asks of SUMO: routes, trains put on and taken off."""

    def add_route(self, route_id: str, edges: Sequence[str]) -> None: ...

    def add_train(
        self,
        train_id: str,
        route_id: str,
        type_id: str,
        depart_pos_m: float,
        stops: Sequence[Any] = (),
        controlled: bool = True,
        depart_speed_mps: float = 0.0,
    ) -> None: ...

    def remove(self, train_id: str) -> None: ...


class Dispatcher:
    """Departures, insertion into SUMO, and removal."""

    def __init__(
        self,
        fleet: Fleet,
        layer: EventLayer,
        events: EventLog,
        settings: EngineSettings,
        formations: FormationBook,
        handshake: Callable[[TrainRuntime], None],
        release_locks: Callable[[TrainRuntime], None],
        chained: Callable[[str], bool],
        admission: Sequence[Admission],
        extensions: ExtensionSet,
    ) -> None:
        self.fleet = fleet
        self.layer = layer
        self.events = events
        self.settings = settings
        self.formations = formations
        self.handshake = handshake
        self.release_locks = release_locks
        self.chained = chained  # rotations: trips their unit's turnback starts (not inserted here)
        self.admission = tuple(admission)  # before inserting: a reason to hold the departure, or None
        self.extensions = extensions  # on_inserted: exact plants, …
        self.bridge: SumoInsertion = unwired("Dispatcher", "bridge")  # exists while the run is under way: connect()
        self._held: dict[str, str] = {}  # trip -> the reason its departure is held (logged when it changes)
        self._retries: dict[str, int] = {}  # trip -> retries of its held departure (only the first is logged)
        self._stop_memo: dict[str, tuple[float, float, float, float]] = {}  # train -> (t, v, front, least stop)
        # the trains near a departure (the rules below compare it with those only: the same answer as all of them)
        self.near = NearTrains(fleet, settings.insertion_margin_m)
        self._unchanged: tuple[float, set[str]] | None = None  # guard_pending's instant and trains: blocker_at_front

    def connect(self, bridge: SumoInsertion) -> None:
        """The SUMO bridge, once the run has started it."""
        set_once(self, "bridge", bridge)

    def schedule_departures(self) -> None:
        """Schedule every departure; check that same-origin formations fit (ConfigError naming the formation)."""
        for tr in self.fleet.trains.values():
            if self.formations.couples_on_departure(tr.train_id) or self.chained(tr.train_id):
                continue  # inserted behind its leader (module docstring), or started by its unit's turnback
            self.layer.at(
                tr.trip.depart_s + tr.trip.departure_delay_s, self._inserter(tr), "departure_due", tr.train_id
            )
        for leader in self.fleet.trains.values():
            for f, follower in self._starting_behind(leader):
                leader_m = self._planned_start_m(leader)
                depart_m = (
                    None if leader_m is None else self.behind_chainage_m(follower, leader, leader_m, f.target_gap_m)
                )
                rear_m = None if depart_m is None else depart_m - follower.trip.vehicle.length_m
                if rear_m is None or rear_m < 0.0:
                    why = "their routes share no track" if rear_m is None else f"its rear would be at {rear_m:.1f} m"
                    raise ConfigError(
                        self.fleet.source,
                        "formations",
                        f"formation {f.id!r}: follower {follower.train_id} cannot start {f.target_gap_m:g} m behind "
                        f"leader {leader.train_id} at {follower.trip.origin.station_id!r}: {why}, before the start "
                        "of its route (no room on the platform's edge; couple it later, e.g. "
                        "couple: {at_station: ...}, or start the pair where the track behind has room)",
                    )
        self._check_followers_joining_on_the_way()

    def _check_followers_joining_on_the_way(self) -> None:
        """A follower that couples on departure at a station its leader only calls at is put on behind the
        leader standing there (:class:`~railsim.engine.coupling.FormationBook`). If the platform's edge is too
        short for that (the follower's front would lie before the start of its route) it could never be put on:
        it used to wait until the end of the run (``never_inserted``, exit 3). Refused here, naming the reason."""
        for leader in self.fleet.trains.values():
            for f in self.formations.of_leader.get(leader.train_id, ()):
                follower = self.formations.follower_of(f)
                station = follower.trip.origin.station_id
                if (
                    not self.formations.couples_on_departure(follower.train_id)
                    or self.chained(follower.train_id)
                    or station == leader.trip.origin.station_id
                ):
                    continue
                stop = next((s for s in leader.trip.stops if s.station_id == station and s.kind == "station"), None)
                if stop is None:
                    continue  # the leader does not call there: the formation book reports it at run time
                depart_m = self.behind_chainage_m(follower, leader, stop.mark_m, f.target_gap_m)
                if depart_m is None or depart_m < 0.0:
                    why = (
                        "their routes share no track there"
                        if depart_m is None
                        else f"its front would be {-depart_m:.1f} m before the start of its route"
                    )
                    raise ConfigError(
                        self.fleet.source,
                        "formations",
                        f"formation {f.id!r}: follower {follower.train_id} cannot be put on {f.target_gap_m:g} m "
                        f"behind leader {leader.train_id} standing at {station!r}: {why} (the platform's edge is "
                        "too short for both trains; start the follower where its leader starts, or shorten "
                        "target_gap_m)",
                    )

    def _planned_start_m(self, tr: TrainRuntime) -> float | None:
        """Where ``tr``'s front starts: its platform mark, or behind its leader in a same-origin chain."""
        f = self.formations.of_follower.get(tr.train_id)
        if f is not None:
            leader = self.formations.leader_of(f)
            if any(follower is tr for _, follower in self._starting_behind(leader)):
                leader_m = self._planned_start_m(leader)
                return None if leader_m is None else self.behind_chainage_m(tr, leader, leader_m, f.target_gap_m)
        return tr.trip.depart_chainage_m

    def _starting_behind(self, leader: TrainRuntime) -> list[tuple[Any, TrainRuntime]]:
        """Formations whose follower couples on departure at the station where ``leader`` starts."""
        out = []
        for f in self.formations.of_leader.get(leader.train_id, ()):
            follower = self.formations.follower_of(f)
            if (
                self.formations.couples_on_departure(follower.train_id)
                and not self.chained(follower.train_id)  # its unit comes round by its turnback
                and follower.trip.origin.station_id == leader.trip.origin.station_id
            ):
                out.append((f, follower))
        return out

    @staticmethod
    def behind_chainage_m(tr: TrainRuntime, behind: TrainRuntime, front_m: float, gap_m: float) -> float | None:
        """``tr``'s front chainage ``gap_m`` behind the rear of ``behind`` (front at ``front_m``), or None if
        their routes share no track there."""
        length_m = behind.trip.vehicle.length_m
        off = behind.view.offset_to(tr.view, front_m - length_m)
        return None if off is None else front_m + off - length_m - float(gap_m)

    def _inserter(self, tr: TrainRuntime) -> Callable[[float], None]:
        """A clock callback that inserts ``tr`` (or holds it again)."""

        def call(_t: float) -> None:
            self.insert(tr)

        return call

    def insert_behind(self, tr: TrainRuntime, behind: TrainRuntime, gap_m: float) -> bool:
        return self.insert(tr, behind, gap_m)

    def insert(self, tr: TrainRuntime, behind: TrainRuntime | None = None, gap_m: float = 0.0) -> bool:
        """Insert ``tr`` now (behind ``behind`` at ``gap_m`` if given); False if it must wait (module docstring)."""
        trip = tr.trip
        if tr.status != "scheduled":
            return False
        depart_m = trip.depart_chainage_m
        start_mps = trip.start_speed_mps
        if behind is not None:
            behind_m = self.behind_chainage_m(tr, behind, behind.front_m, gap_m)
            if behind_m is None:
                raise SimulationError(f"{tr.train_id} cannot start behind {behind.train_id}: routes share no track")
            depart_m = behind_m
            leader_mps = behind.plant.speed_mps  # at its gap behind a slower leader: no faster than the leader
            reason = self.collision_course(tr, depart_m, min(start_mps, leader_mps), approaching_only=True)
            if reason is not None:  # a train approaching from behind could not stop for it: not now
                self._log_held(tr, reason)  # (the formation book tries again while the leader stands there)
                return False
            if leader_mps < start_mps:
                self.events.record(
                    self.layer.now_s,
                    "start_speed_limited",
                    tr.train_id,
                    leader=behind.train_id,
                    start_mps=round(start_mps, 3),
                    speed_mps=round(behind.plant.speed_mps, 3),
                )
                start_mps = behind.plant.speed_mps
            if depart_m < trip.origin.window_start_m:
                self.events.record(
                    self.layer.now_s,
                    "platform_too_short",
                    tr.train_id,
                    detail=f"front {depart_m:.1f} m < window {trip.origin.window_start_m:.1f} m",
                )
        else:
            standing = trip.start_speed_mps == 0.0 and trip.start_offset_m == 0.0
            reason = self.blocker(tr, depart_m) if standing else self.collision_course(tr, depart_m, start_mps)
            if reason is not None:
                self._hold(tr, reason)
                return False
        for admit in self.admission:  # the interlocking reserves what the train starts in (single track)
            reason = admit(self.layer.now_s, tr, depart_m)
            if reason is not None:
                if behind is None:
                    self._hold(tr, reason)
                else:  # the formation book tries again while the leader stands there
                    self._log_held(tr, reason)
                return False
        if not 0.0 <= depart_m <= tr.view.length_m:
            reason = f"no valid position on the first edge (front at {depart_m:.1f} m of its route)"
            if behind is None:
                self._hold(tr, reason)
            else:  # the formation book tries again while the leader stands there
                self._log_held(tr, reason)
            return False
        # SUMO inserts a vehicle on its route's first edge: a train starting further along (a start offset in
        # motion) gets the route trimmed to begin at the edge that holds its start chainage
        k = tr.view.edge_at(depart_m)
        # it is inserted at its origin: SUMO holds it at the others
        stops = sumo_stops(trip.stops[1:], route=trip.route, first_edge=k)
        route_id = trip.route.id if k == 0 else f"{trip.route.id}@{k}"
        self.bridge.add_route(route_id, trip.route.edges[k:])
        self.bridge.add_train(
            tr.sumo_id,
            route_id,
            trip.vehicle_name,
            depart_m - tr.view.edge_start_m[k],
            stops,
            controlled=True,
            depart_speed_mps=start_mps,
        )
        self.fleet.start(tr, "inserting")
        tr.front_m = depart_m
        tr.plant = dynamics.PlantState(speed_mps=start_mps)
        self.near.inserted(tr)
        self.extensions.on_inserted(self.layer.now_s, tr, depart_m)
        self.handshake(tr)
        tr.depart_chainage_m = tr.start_front_m = depart_m
        tr.inserted_s = self.layer.now_s
        self._held.pop(tr.train_id, None)
        self._report_retries(tr.train_id)
        self.events.record(
            self.layer.now_s, "train_inserted", tr.train_id, service=trip.service_id, chainage_m=round(depart_m, 3)
        )
        for f, follower in self._starting_behind(tr):  # partners that start where this train stands
            if self.insert(follower, tr, float(f.target_gap_m)):
                self.formations.manager.request_couple(f.id)
        return True

    def _log_held(self, tr: TrainRuntime, reason: str) -> None:
        if self._held.get(tr.train_id) != reason:
            self._held[tr.train_id] = reason
            self.events.record(self.layer.now_s, "departure_held", tr.train_id, reason=reason)

    def _hold(self, tr: TrainRuntime, reason: str) -> None:
        """The departure waits (module docstring): logged when the reason changes, retried later. Only the first
        retry is a ``departure_retry`` event; the rest are counted and summarised once the train is inserted or
        the run ends (``departure_retries`` with ``count``): a train held for an hour at a 1 s retry used to
        write 3,600 identical rows."""
        self._log_held(tr, reason)
        n = self._retries.get(tr.train_id, 0)
        self._retries[tr.train_id] = n + 1
        self.layer.at(
            self.layer.now_s + self.settings.departure_retry_s,
            self._inserter(tr),
            "departure_retry" if n == 0 else None,
            tr.train_id,
        )

    def _report_retries(self, train_id: str) -> None:
        count = self._retries.pop(train_id, 0)
        if count > 1:
            self.events.record(self.layer.now_s, "departure_retries", train_id, count=count)

    def report_never_inserted(self, t: float) -> list[str]:
        """End of the run: one ``never_inserted`` event per trip that never entered the world; their ids."""
        ids = [tr.train_id for tr in self.fleet.trains.values() if tr.status == "scheduled"]
        for tid in ids:
            default = (
                "its unit never arrived from its previous trip"
                if self.chained(tid)
                else "its departure never came (its leader never stood at its origin)"
            )
            reason = self._held.get(tid, default)
            self._report_retries(tid)
            self.events.record(t, "never_inserted", tid, reason=reason)
        return ids

    def blocker_at_front(self, tr: TrainRuntime) -> str | None:
        """Why ``tr``'s spot (its front where it was handed to SUMO) is not free: :meth:`blocker` there.

        The loop asks this of every train still in SUMO's queue right after :meth:`guard_pending` looked at the
        line for the same trains at the same instant (the stall watchdog, nothing in between): each of those is
        answered once from that look, not by comparing the whole line again (a queue of 3,000 trains at t = 0
        would compare it 3,000 times). Any other question ends that."""
        unchanged = self._unchanged
        trusted = unchanged is not None and unchanged[0] == self.layer.now_s and tr.train_id in unchanged[1]
        if trusted and unchanged is not None:
            unchanged[1].discard(tr.train_id)
        return self._blocker(tr, tr.front_m, trusted)

    def blocker(self, tr: TrainRuntime, depart_m: float) -> str | None:
        """Why a departure at ``depart_m`` would put a train on the line in danger, or None (module docstring):
        the first train on the line, in scenario order, that :meth:`blocker_of` names. Only the trains near the
        spot are asked (:class:`~railsim.engine.insertion_reach.NearTrains`; the others pass every rule)."""
        return self._blocker(tr, depart_m, False)

    def _blocker(self, tr: TrainRuntime, depart_m: float, trusted: bool) -> str | None:
        if not trusted:
            self._unchanged = None
        length = tr.trip.vehicle.length_m
        for other in self.near.near(tr, depart_m, length, self.settings.insertion_margin_m, trusted):
            reason = self.blocker_of(tr, depart_m, other)
            if reason is not None:
                return reason
        return None

    def blocker_of(self, tr: TrainRuntime, depart_m: float, other: TrainRuntime) -> str | None:
        """Why ``other`` holds a departure of ``tr`` at ``depart_m``, or None (module docstring)."""
        pair = self._in_one_frame(tr, depart_m, tr.trip.vehicle.length_m, other)
        if pair is None:
            return None
        front_o, rear_o, other_front_m, other_rear_m, to_other_m = pair
        if front_o <= other_rear_m:  # it lies behind the other train's rear: the other one is ahead
            clear_m = other_rear_m - front_o
            if clear_m < self.settings.insertion_margin_m:  # (a follower put on at its target gap: insert_behind)
                return f"{other.train_id} ahead is less than {self.settings.insertion_margin_m:g} m clear"
            return None
        if rear_o < other_front_m:
            return f"track occupied by {other.train_id}"
        if self._cannot_stop_behind(other, rear_o - other_front_m):
            return f"approaching train {other.train_id} could not stop"
        held = self._locked_ahead_of(other, rear_o + to_other_m)
        if held is not None and not self.formations.partners(tr.train_id, other.train_id):
            # the train behind holds the route through this spot: a train put in between would wait for that
            # lock in front of its holder, for ever (a deadlock by insertion)
            return f"{other.train_id} holds the route through here (switch {held})"
        return None

    @staticmethod
    def _in_one_frame(
        tr: TrainRuntime, depart_m: float, length_m: float, other: TrainRuntime, hint: int = 0
    ) -> tuple[float, float, float, float, float] | None:
        """``tr``'s body (front at ``depart_m`` in its frame) and ``other``'s body in one route frame:
        ``(tr front, tr rear, other front, other rear, offset to other's frame)``, or None if they share no track.

        Usually ``other``'s frame (``tr``'s body mapped onto ``other``'s route). A train standing at a platform
        shorter than itself has its tail on track before its route begins (SUMO puts it on at the platform; the
        tail lies on the edges behind): ``tr`` put on there shares no edge of ``other``'s route, yet ``other``'s
        tail is on ``tr``'s track. Then ``other``'s body is mapped onto ``tr``'s route instead (found on SUMO's
        ``tools/game/bs3d`` OSM net: a train put on at one short platform 25 m into the tail of a train that had
        just left the next one)."""
        other_length_m = other.trip.vehicle.length_m
        other_rear_m = other.front_m - other_length_m
        mapped = _nearest_pass(
            other.view, (other_rear_m, other.front_m, other.edge_i), tr.view, depart_m, length_m, hint
        )
        if mapped is not None:
            return mapped[0], mapped[1], other.front_m, other_rear_m, 0.0
        near = (depart_m - length_m, depart_m, tr.edge_i)
        back = _nearest_pass(tr.view, near, other.view, other.front_m, other_length_m, other.edge_i)
        if back is None:
            return None
        return depart_m, depart_m - length_m, back[0], back[1], other.front_m - back[0]

    def _cannot_stop_behind(self, other: TrainRuntime, gap_m: float) -> bool:
        """Could ``other`` (behind, ``gap_m`` short of a rear) not stop short of it with its service brake, after
        :data:`~railsim.engine.settings.INSERTION_REACTION_S` and with the insertion margin to spare?"""
        return gap_m < approach_needed_m(other, self.settings.insertion_margin_m)

    def guard_pending(self, pending: list[TrainRuntime]) -> None:
        """Every step, for the trains handed to SUMO that it has not put on yet (SUMO fills a spot only once it is
        free, possibly much later): a standing one that a train now approaching from behind could not stop for is
        withdrawn from SUMO's queue and its departure held (retried as a standing departure from its origin; a
        follower still to couple is also put on behind its leader again by the formation book, whichever comes
        first). Else SUMO put a follower on, 330 s after it was handed over, 12 m in front of a train running at
        24 km/h (fuzz variant 275: a collision); ``tests/sumo/test_pending_insertion.py``."""
        self._unchanged = None
        if not pending:
            return
        # one look at the line for all of them: in between, trains only leave it (withdrawn here)
        self.near.check(self.settings.insertion_margin_m)
        for tr in pending:
            if tr.plant.speed_mps > 0.0:
                continue  # a start in motion is put on at the next step (or refused by SUMO: held, reported)
            length_m = tr.trip.vehicle.length_m
            for other in self.near.near(tr, tr.front_m, length_m, 0.0, trusted=True):  # (the others: far enough)
                if other.status != "running":
                    continue
                mapped = other.view.map_body(tr.view, tr.front_m, length_m)
                if mapped is None or mapped[1] < other.front_m:
                    continue  # not on its track or not in front of it
                if not self._cannot_stop_behind(other, mapped[1] - other.front_m):
                    continue  # far enough ahead
                self.bridge.remove(tr.sumo_id)
                tr.status, tr.inserted_s = "scheduled", None
                self.events.record(self.layer.now_s, "train_withdrawn", tr.train_id, approaching=other.train_id)
                self._hold(tr, f"approaching train {other.train_id} could not stop")
                break
        # blocker_at_front, asked of those still waiting right after this, answers them from the same look
        self._unchanged = (self.layer.now_s, {tr.train_id for tr in pending if tr.status == "inserting"})

    def collision_course(
        self, tr: TrainRuntime, depart_m: float, v_mps: float, approaching_only: bool = False
    ) -> str | None:
        """Why a train put on at ``depart_m`` already moving at ``v_mps`` (a start in motion) would be on a collision
        course, or None: some part of another train's body where it would stand, or a train ahead (behind) closer
        than the least stopping distance of the one behind less that of the one ahead
        (:func:`railsim.physics.dynamics.least_stop_distance_m`: both on their emergency brakes at once) — then no
        braking at all avoids the collision. Trains put on in motion close behind each other at one speed (a
        paper's platoon) are not held: their difference is 0. ``approaching_only``: only trains approaching from
        behind count (a follower put on behind its leader: a spot still occupied SUMO itself fills only once
        free)."""
        self._unchanged = None
        veh = tr.trip.vehicle
        own_stop_m = dynamics.least_stop_distance_m(veh, v_mps, tr.view.gradient_at(depart_m))
        for other in self.near.near(tr, depart_m, veh.length_m, max(own_stop_m, 0.0)):
            reason = self.collision_course_with(tr, depart_m, own_stop_m, other, approaching_only)
            if reason is not None:
                return reason
        return None

    def collision_course_with(
        self, tr: TrainRuntime, depart_m: float, own_stop_m: float, other: TrainRuntime, approaching_only: bool
    ) -> str | None:
        """Why ``tr`` put on at ``depart_m`` (least stopping distance ``own_stop_m``) would be on a collision course
        with ``other``, or None (:meth:`collision_course`)."""
        hint = tr.view.edge_at(depart_m)
        pair = self._in_one_frame(tr, depart_m, tr.trip.vehicle.length_m, other, hint)
        if pair is None:
            return None
        front_o, rear_o, other_front_m, other_rear_m, _ = pair
        if approaching_only and (front_o <= other_rear_m or rear_o < other_front_m):
            return None
        if front_o <= other_rear_m:  # the other one is ahead (its stopping distance is >= 0: asked only if
            gap_m = other_rear_m - front_o  # ours alone could not stop within the gap)
            if gap_m < own_stop_m and gap_m < own_stop_m - self._least_stop_m(other):
                return f"{other.train_id} ahead is {gap_m:.0f} m clear: it could not stop behind it"
        elif rear_o < other_front_m:
            return f"track occupied by {other.train_id}"
        elif rear_o - other_front_m < self._least_stop_m(other) - own_stop_m:
            return f"approaching train {other.train_id} could not stop"
        return None

    def _least_stop_m(self, other: TrainRuntime) -> float:
        """``other``'s least stopping distance now (remembered for the instant: a whole timetable is put on at
        t = 0, each insertion asking it of every train already on)."""
        now = self.layer.now_s
        known = self._stop_memo.get(other.train_id)
        if known is not None and known[0] == now and known[1] == other.plant.speed_mps and known[2] == other.front_m:
            return known[3]
        stop_m = dynamics.least_stop_distance_m(
            other.trip.vehicle, other.plant.speed_mps, other.view.gradient_at(other.front_m)
        )
        self._stop_memo[other.train_id] = (now, other.plant.speed_mps, other.front_m, stop_m)
        return stop_m

    @staticmethod
    def _locked_ahead_of(other: TrainRuntime, chainage_m: float) -> str | None:
        """A switch beyond ``chainage_m`` (``other``'s route frame) whose lock ``other`` holds, or None."""
        for rs in other.trip.route.switches:
            if rs.point_m > chainage_m and rs.switch_id in other.locks and rs.switch_id not in other.released:
                return rs.switch_id
        return None

    def leave(self, tr: TrainRuntime) -> None:
        """A train leaves the line (to another track, the depot): removed from the world now, logged."""
        if tr.status not in ("inserting", "running"):
            return
        self.release_locks(tr)
        self.bridge.remove(tr.sumo_id)
        tr.status = "removed"
        self.formations.on_off_line(self.layer.now_s, tr)
        self.events.record(self.layer.now_s, "train_left", tr.train_id, chainage_m=round(tr.front_m, 3))


def _nearest_pass(
    onto: RouteView,
    near: tuple[float, float, int],
    source: RouteView,
    front_m: float,
    length_m: float,
    hint: int,
) -> tuple[float, float] | None:
    """A body on ``source``'s route (front at ``front_m``, ``length_m`` long; ``hint`` an edge index of ``source``
    next to its front) as ``(front, rear)`` in ``onto``'s frame, on the pass of ``onto``'s route nearest the body
    ``near`` = (rear, front, an edge index next to its front) already in that frame. A route that runs over a spot
    twice (a unit's turnback path prepended to its trip, out and back through one stub) holds it at two chainages;
    the last pass, which the mapping takes by default, put a departure 7,968 m away from a turned unit standing on
    the very spot (Jena, Lobeda-West: the departure was put on 1 m inside it; SUMO refused to insert it). Each pass
    that can hold the body is tried — the first, the one from ``near``'s rear on, the last — and the one closest to
    ``near`` is kept. Used both ways: a departure mapped onto another train's route, and that train's body mapped
    onto the departure's route where they share no edge of the other's route (:meth:`Dispatcher._in_one_frame`)."""
    if onto.simple:
        return onto.map_body(source, front_m, length_m, hint)
    near_rear_m, near_front_m, near_i = near
    rear_i = onto.edge_near(max(near_rear_m, 0.0), near_i)
    best: tuple[float, tuple[float, float]] | None = None
    for from_i in (0, rear_i, -1):
        mapped = onto.map_body(source, front_m, length_m, hint, from_i)
        if mapped is None:
            continue
        apart_m = max(0.0, mapped[1] - near_front_m, near_rear_m - mapped[0])
        if best is None or apart_m < best[0]:
            best = (apart_m, mapped)
    return None if best is None else best[1]
