"""Formation bookkeeping: which trains form pairs, when they couple and decouple, and what coupling means for
stopping, restrictions and the state machine (the engine side of :mod:`railsim.engine.events.formations`).

* **Registration.** :meth:`FormationBook.add` registers a scenario formation (or one the junction planner forms
  at run time); a follower that couples ``on_departure`` is re-timed to its leader's departure at its origin.
* **Every step** (:meth:`FormationBook.bookkeeping`): a follower waiting to couple on departure is inserted
  behind its leader once the leader stands at the follower's origin; a follower that couples ``after_switch`` (a
  merge) is asked to couple once its front is past that switch with its leader ahead on its track; a formation
  whose leader approaches the switch it must decouple before is asked to decouple; the state machine is fed the true gap (judged against
  the coupled controller's effective target) and the closing speed; coupled time is counted.
* **Across a turnback** (rotations): a formation whose follower is a trip its unit's turnback starts
  (``chained``) couples ``on_departure`` without an insertion: the follower's unit comes round by itself and
  runs to its platform as a free train; within reach of its leader standing there the couple request goes out
  (:meth:`_couples_after_turnback`) and the follower halts at the target gap behind it like any coupled
  follower. Until its leader
  stands at that platform the follower's unit waits at its reversal point (:meth:`waits_for_leader`): a leader
  that comes through from elsewhere finds the platform free and the follower comes out behind it; the leader
  stays at the platform after its dwell until the two are coupled (:meth:`holds_departure`; at most one
  coupling timeout), so the pair leaves together. Which unit leads
  is the scenario's choice, checked against the order the units stand in after the turnback
  (:meth:`railsim.engine.turnback.Turnbacks.check_formation_order`).
* **Joining at a station** (``couple: {at_station: X}``): the leader stays at ``X`` after its dwell, with no
  route set beyond it, until the pair is coupled and the follower's dwell there is over (at most one coupling
  timeout) and the follower asks to couple on its final approach and halts the target gap behind it
  (:mod:`railsim.engine.joins`). The pair must fit on the platform (checked at registration).
* **Nothing silent.** A formation that cannot couple where it asked (at a station, after a switch) is a
  ``coupling_failed`` event with the reason (``timeout``, ``wrong_order``, ``blocked``, ``aborted``,
  ``not_reached``; :meth:`railsim.engine.joins.Joins.where_asked`).
* **Coupling changes geometry.** A coupled follower stops ``leader length + target gap`` behind the leader's
  mark (:meth:`mark_offset_m`, recursive for chains); a coupled leader keeps a restriction until its formation's
  tail clears it (:meth:`tail_m`).
* **Departing together** (a formation's ``depart_together``): at every station both units of a coupled pair
  serve, the leader stays after its own dwell until its follower's dwell there has ended
  (:meth:`holds_departure`), so the pair leaves as one with the longer of the two dwells — as one coupled train
  would. Without it each unit keeps its own dwell: a follower that dwells longer drops behind and, planned in its
  leader's slot, then uses each platform after it (the robustness study measures what that costs).

Paper-specific follower logic (Paper D's state machine) plugs in as an extension's ``follower_step(t, tr,
formation, ahead)``, run before the state machine is fed (:mod:`railsim.engine.extensions.base`).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from typing import Any, Protocol

from railsim.engine.events.formations import Formation, FormationManager
from railsim.engine.extensions.base import ExtensionSet
from railsim.engine.fleet import Fleet
from railsim.engine.joins import COUPLE_REACH_M, STANDING_MPS, Joins, trig
from railsim.engine.occupancy import Ahead
from railsim.engine.settings import EngineSettings
from railsim.engine.train import TrainRuntime
from railsim.engine.trips import TripStop
from railsim.engine.wiring import set_once, unwired
from railsim.errors import ConfigError

log = logging.getLogger(__name__)

COUPLED_STATES = ("coupling", "coupled")


class InsertsBehind(Protocol):
    """The dispatcher, asked to put a follower on the track behind its leader."""

    def insert_behind(self, tr: TrainRuntime, behind: TrainRuntime, gap_m: float) -> bool:
        """Insert ``tr`` ``gap_m`` behind ``behind``'s rear; False if it cannot go yet."""


class KnowsStops(Protocol):
    """The stop book, asked where a train stops next."""

    def current(self, tr: TrainRuntime) -> tuple[TripStop | None, float]:
        """The stop ``tr`` heads for or stands at, and how far behind its mark it halts."""


class FormationBook:
    """The engine's view of formations: leader/follower maps over the formation state machine."""

    def __init__(
        self,
        fleet: Fleet,
        manager: FormationManager,
        settings: EngineSettings,
        dt_s: float,
        chained: Callable[[str], bool],
        extensions: ExtensionSet,
    ) -> None:
        self.not_coupling: dict[str, str] = {}  # formation id -> why it cannot couple (depot_start_reasons)
        self.fleet = fleet
        self.manager = manager
        self.settings = settings
        self.dt_s = dt_s
        self.of_follower: dict[str, Any] = {}  # follower id -> FormationSpec
        self.of_leader: dict[str, list[Any]] = {}  # leader id -> [FormationSpec]
        self.extensions = extensions  # follower_step: per follower and step, before the state machine is fed
        self._merged: set[str] = set()  # formations whose after_switch couple request was made
        # two questions whose answerers are built after this book and ask it back (wire()): insert a train behind
        # another (the dispatcher), a train's current stop and how far behind its mark it halts (the stop book)
        self.insert_behind: Callable[[TrainRuntime, TrainRuntime, float], bool] = unwired(
            "FormationBook", "insert_behind"
        )
        self.current_stop: Callable[[TrainRuntime], tuple[TripStop | None, float]] = unwired(
            "FormationBook", "current_stop"
        )
        self.chained = chained  # rotations: trips their unit's turnback starts
        self._asked_after_turnback: set[str] = set()  # formations whose couple request went out after a turnback
        self._cut_off: set[str] = set()  # formations whose follower cannot reach its leader (_join_cut_off)
        self._held_since_s: dict[str, float] = {}  # formation -> when its leader's dwell ended (held for the follower)
        # (formation, leader's stop index) -> when the leader's dwell ended there (held for a convoy's follower)
        self._convoy_held_since_s: dict[tuple[str, int], float] = {}
        self.join_book = Joins(self)  # joins at stations; where formations that asked for a place coupled, or why not

    # ------------------------------------------------------------------ registration
    def add(self, f: Any, where: str = "formations") -> None:
        """Register formation ``f`` (a :class:`railsim.scenario.FormationSpec`) with the state machine and the
        leader/follower maps: the scenario's at set-up, the junction planner's at run time."""
        leader = self.fleet.trip_ref(f.leader, f"{where}.leader")
        follower = self.fleet.trip_ref(f.follower, f"{where}.follower")
        # decoupling completes at this true gap: the engine default, or beyond a large target gap
        separation = max(self.settings.separation_gap_m, float(f.target_gap_m) + 100.0)
        form = Formation(
            id=f.id,
            leader_id=leader.train_id,
            follower_id=follower.train_id,
            target_gap_m=float(f.target_gap_m),
            separation_gap_m=separation,
            coupling_timeout_s=float(f.coupling_timeout_s),
        )
        self.manager.add(form)
        if trig(f.couple, "on_departure"):
            origin = follower.trip.origin.station_id
            planned = leader.trip.planned_departure_s.get(origin)
            if planned is None:
                raise ConfigError(
                    self.fleet.source,
                    f"{where}.couple",
                    f"the leader's trip does not stop at the follower's origin {origin!r}",
                )
            shift = planned - follower.trip.depart_s
            follower.trip.depart_s = planned
            for d in (follower.trip.planned_arrival_s, follower.trip.planned_departure_s):
                for key in d:
                    d[key] += shift
        if trig(f.couple, "at_station"):
            self.join_book.check_platform(f, leader, follower, where)
        self.of_follower[follower.train_id] = f
        self.of_leader.setdefault(leader.train_id, []).append(f)

    def note_on_run_infeasible(self, formation_id: str, detail: Mapping[str, float | None]) -> None:
        """A merge extension found that ``formation_id`` cannot couple on the run after its merge (the numbers
        why): the summary's ``formations_asked`` entry carries them as ``on_run``."""
        self.join_book.on_run_infeasible[formation_id] = dict(detail)

    def schedule_commands(self, formations: Any) -> None:
        """Timed couple/decouple triggers of the scenario's formations (``at_s``)."""
        for f in formations:
            if trig(f.couple, "at_s"):
                self.manager.request_couple(f.id, at_s=float(f.couple.at_s))
            if trig(f.decouple, "at_s"):
                self.manager.request_decouple(f.id, at_s=float(f.decouple.at_s))

    def wire(self, dispatcher: InsertsBehind, stops: KnowsStops) -> None:
        """The two collaborators built after this book (they ask it back): set once, by the engine."""
        set_once(self, "insert_behind", dispatcher.insert_behind)
        set_once(self, "current_stop", stops.current)

    def across_turnbacks(self, turnbacks: Any) -> None:
        """Check the order of the formations coupling across a turnback (the rotations port); note the formations
        that cannot couple on departure because their follower's unit comes straight out of a depot onto its origin
        platform (:meth:`depot_start_reasons`)."""
        turnbacks.check_formation_order(self.on_departure_pairs(), self.leader_id)
        self.not_coupling = self.depot_start_reasons(turnbacks)
        for fid, reason in self.not_coupling.items():
            log.warning("formation %s will not couple on departure: %s", fid, reason)
            self.manager.record(0.0, "couple_not_possible", fid, reason=reason)

    def why_not_coupled(self, end_s: float) -> dict[str, Any]:
        """The summary's entries on formations that did not couple where they asked, and why: per formation that
        asked at a station or after a switch (``formations_asked``, which may log ``not_reached`` events, so it is
        called before the events are read) and those that cannot couple on departure after a depot run
        (``formations_not_coupling``). Empty when no formation asked for either: the summary then has neither key."""
        out: dict[str, Any] = dict(self.join_book.where_asked(end_s))
        if self.not_coupling:
            out["formations_not_coupling"] = dict(sorted(self.not_coupling.items()))
        return out

    def depot_start_reasons(self, turnbacks: Any) -> dict[str, str]:
        """``{formation id: why}`` for each ``on_departure`` formation whose follower's first trip is reached by a
        depot-out run that ends on the very platform the trip departs from (no turnback there). That unit stands
        at the platform before its leader arrives, ahead of it: it cannot come out behind its leader, which is
        what coupling on departure means, so it runs its trip uncoupled. (A depot-out run that reaches the
        opposite platform turns back there and waits for its leader like any chained follower.) The reason is an
        event (``couple_not_possible``) and a line of the summary, never a silent drop."""
        reasons: dict[str, str] = {}
        for f in self.of_follower.values():
            follower = self.follower_of(f)
            if not trig(f.couple, "on_departure") or follower.train_id not in turnbacks.prev_of:
                continue
            before = self.fleet.trains[turnbacks.prev_of[follower.train_id]]
            if before.trip.kind == "depot_out" and follower.trip.stops[0].kind != "reversal":
                reasons[f.id] = (
                    f"the follower's unit comes from the depot by {before.train_id} straight onto its departure "
                    f"platform at {follower.trip.origin.station_id!r}, ahead of its leader "
                    f"{self.leader_of(f).train_id}; it runs its trip uncoupled (choose a depot from which it "
                    "reaches the opposite platform and turns back, or let another trip lead)"
                )
        return reasons

    def turnback_waits(self) -> tuple[Callable[[TrainRuntime], bool], Callable[[float, TrainRuntime], bool]]:
        """The two waits the stop book applies across a turnback: :meth:`waits_for_leader`, :meth:`holds_departure`."""
        return self.waits_for_leader, self.holds_departure

    def leader_id(self, train_id: str) -> str | None:
        """The trip ``train_id`` follows in a formation, or None."""
        f = self.of_follower.get(train_id)
        return None if f is None else self.leader_of(f).train_id

    def on_departure_pairs(self) -> list[tuple[str, TrainRuntime, TrainRuntime]]:
        """(scenario field, leader, follower) of every formation that couples on departure."""
        return [
            (f"formations.{f.id}", self.leader_of(f), self.follower_of(f))
            for f in self.of_follower.values()
            if trig(f.couple, "on_departure")
        ]

    def couples_on_departure(self, train_id: str) -> bool:
        f = self.of_follower.get(train_id)
        return f is not None and trig(f.couple, "on_departure")

    def waits_for_leader(self, tr: TrainRuntime) -> bool:
        """True while chained ``tr`` must stay at its reversal point: it couples on departure behind a leader that
        has yet to stand at ``tr``'s origin platform (it would otherwise come out in front of it). False once the
        leader stands there, or has left it (``tr`` then follows late), or has no stop there."""
        f = self.of_follower.get(tr.train_id)
        if f is None or not trig(f.couple, "on_departure") or not self.chained(tr.train_id):
            return False
        leader = self.leader_of(f)
        if leader.status in ("scheduled", "inserting"):
            return True
        if leader.status != "running":
            return False
        stop, _ = self.current_stop(leader)
        origin = tr.trip.origin.station_id
        if stop is None or not any(s.station_id == origin for s in leader.trip.stops[leader.next_stop :]):
            return False
        return not (stop.station_id == origin and leader.sumo_stopped)

    def joins(self, train_id: str, leader_id: str) -> bool:
        """True while chained ``train_id`` is on its way to couple on departure behind ``leader_id`` at its origin
        platform (it has not left that platform, and no attempt has failed): it runs into the platform its leader
        occupies on purpose, as a unit called on to attach (:mod:`railsim.engine.platforms`)."""
        f = self.of_follower.get(train_id)
        if f is None or not trig(f.couple, "on_departure") or not self.chained(train_id):
            return False
        if (
            self.leader_of(f).train_id != leader_id
            or self.follower_of(f).departed_s is not None
            or f.id in self._cut_off
        ):
            return False
        return f.id not in self._asked_after_turnback or self.manager.state(f.id) in COUPLED_STATES

    def holds_departure(self, t: float, tr: TrainRuntime) -> bool:
        """True while leader ``tr`` must stay at its platform after its dwell: for a chained follower coupling
        behind it on departure (:meth:`_holds_for_join`), or for its coupled follower's dwell at a station both
        serve when the formation departs together (:meth:`_holds_for_convoy`)."""
        stop, _ = self.current_stop(tr)
        return any(
            self._holds_for_join(t, f, stop)
            or self.join_book.holds(t, f, stop)
            or self._holds_for_convoy(t, tr, f, stop)
            for f in self.of_leader.get(tr.train_id, ())
        )

    def _holds_for_join(self, t: float, f: Any, stop: TripStop | None) -> bool:
        """At the origin of a chained follower that couples on departure: until the pair is coupled, the attempt
        failed, or one coupling timeout has passed since the leader's dwell ended (a pair leaves together; a
        follower that cannot come never keeps it for long)."""
        fol = self.follower_of(f)
        if not (trig(f.couple, "on_departure") and self.chained(fol.train_id)):
            return False
        if stop is None or stop.station_id != fol.trip.origin.station_id or fol.departed_s is not None:
            return False
        state = self.manager.state(f.id)
        if fol.status not in ("scheduled", "running") or state == "coupled":
            return False
        if (f.id in self._asked_after_turnback and state != "coupling") or f.id in self._cut_off:
            return False  # the attempt failed, or another train stands between them: the leader goes
        return t - self._held_since_s.setdefault(f.id, t) < float(f.coupling_timeout_s)

    def _holds_for_convoy(self, t: float, tr: TrainRuntime, f: Any, stop: TripStop | None) -> bool:
        """A formation that departs together (``depart_together``), coupled, at a station its follower serves
        too: until the follower's dwell there has ended (it has moved on to its next stop), so the pair's dwell is
        the longer of the two, as one coupled train's would be. Not for a follower that is not on its way in
        (farther than :data:`COUPLE_REACH_M` from where it halts) or is held for its route out (which may wait
        for the leader's route to be released), and at most one coupling timeout after the leader's own dwell
        ended."""
        if not f.depart_together or stop is None or self.manager.state(f.id) != "coupled":
            return False
        fol = self.follower_of(f)
        if fol.status != "running":
            return False
        fstop, offset = self.current_stop(fol)
        if fstop is None or fstop.station_id != stop.station_id or fstop.kind == "reversal":
            return False  # it does not stop here, or its dwell here is over
        if fol.held_for_route:
            return False  # its route out may wait for the leader's own to be released: no circular wait
        if not fol.sumo_stopped and fstop.mark_m - offset - fol.front_m > COUPLE_REACH_M:
            return False
        return t - self._convoy_held_since_s.setdefault((f.id, tr.next_stop), t) < float(f.coupling_timeout_s)

    def _couples_after_turnback(self, follower: TrainRuntime, leader: TrainRuntime, f: Any, a: Ahead | None) -> bool:
        """True once for an ``on_departure`` formation of a chained follower: both units ran their turnback, the
        leader stands at the follower's origin platform and the follower, on its way there, is within
        :data:`COUPLE_REACH_M` of its rear. Asked then, the follower halts at the target gap behind the leader (a
        coupled follower's mark); asked later, it could already stand registered at the platform further back,
        where a dwelling train does not move up. The coupled controller's closing speed is meant for these last
        metres, not for the run to the platform."""
        if not (
            trig(f.couple, "on_departure")
            and self.chained(follower.train_id)
            and f.id not in self._asked_after_turnback
            and leader.status == "running"
            and follower.status == "running"
            and not leader.reversing
            and not follower.reversing
            and leader.sumo_stopped
            and a is not None
            and a.train_id == leader.train_id
            and a.gap_m <= COUPLE_REACH_M
        ):
            return False
        stop, _ = self.current_stop(leader)
        return stop is not None and stop.station_id == follower.trip.origin.station_id

    def _join_cut_off(self, follower: TrainRuntime, leader: TrainRuntime, f: Any, a: Ahead) -> bool:
        """True once for an ``on_departure`` formation of a chained follower whose leader stands at the follower's
        origin platform with another train (``a``) between them — a through train let over the points before the
        unit came out of its turnback: it cannot reach its leader, so its leader does not wait for it
        (:meth:`holds_departure`; ``join_cut_off`` event) and it is not called on into the platform (:meth:`joins`).
        It follows on its own, late. Without this the leader waited its whole coupling timeout, the train
        between them with it (the Line 3 day with platform berths)."""
        if f.id in self._cut_off or f.id in self._asked_after_turnback or a.train_id == leader.train_id:
            return False
        if not (trig(f.couple, "on_departure") and self.chained(follower.train_id)):
            return False
        if follower.status != "running" or follower.departed_s is not None or leader.status != "running":
            return False
        first = follower.trip.stops[0]
        if first.kind == "reversal" and a.rear_m < first.window_end_m:
            return False  # a train before the unit's turnaround (on its arrival track) is not between them
        stop, _ = self.current_stop(leader)
        return leader.sumo_stopped and stop is not None and stop.station_id == follower.trip.origin.station_id

    # ------------------------------------------------------------------ queries
    def state(self, train_id: str) -> str:
        """Formation state of a follower (``free`` if it follows no one)."""
        f = self.of_follower.get(train_id)
        return self.manager.state(f.id) if f is not None else "free"

    def partners(self, a_id: str, b_id: str) -> bool:
        """True if the two trains are leader and follower of one formation (either way round)."""
        fa, fb = self.of_follower.get(a_id), self.of_follower.get(b_id)
        return (fa is not None and self.leader_of(fa).train_id == b_id) or (
            fb is not None and self.leader_of(fb).train_id == a_id
        )

    def leader_of(self, f: Any) -> TrainRuntime:
        return self.fleet.trains[self.fleet.trips_by_service[f.leader.service][f.leader.trip].trip_id]

    def follower_of(self, f: Any) -> TrainRuntime:
        return self.fleet.trip_ref(f.follower, "formations")

    def effective_target_m(self, tr: TrainRuntime, f: Any) -> float:
        """Target gap in force for a follower: its controller's policy value if it reported one."""
        return tr.vc_target_gap_m if tr.vc_target_gap_m is not None else float(f.target_gap_m)

    def tail_m(self, tr: TrainRuntime) -> float:
        """Length behind a formation leader's rear that belongs to its coupled formation (gap + follower), or 0."""
        tail = 0.0
        for f in self.of_leader.get(tr.train_id, ()):  # usually one follower
            if self.manager.state(f.id) not in COUPLED_STATES:
                continue
            fol = self.follower_of(f)
            if fol.status == "running":
                tail = max(tail, self.effective_target_m(fol, f) + fol.trip.vehicle.length_m + self.tail_m(fol))
        return tail

    def in_final_approach(self, tr: TrainRuntime, mark_m: float) -> bool:
        """Close enough to ``mark_m`` that station braking is (about to be) under way."""
        v = tr.plant.speed_mps
        plan_decel = 0.5 * tr.trip.vehicle.service_decel_mps2  # gentler than the ATO's: starts the hand-over early
        return mark_m - tr.front_m <= v * v / (2.0 * plan_decel) + self.settings.final_approach_margin_m

    def mark_offset_m(self, tr: TrainRuntime, stop: TripStop) -> float:
        """How far behind the platform mark a coupled follower halts (leader length + target gap), or 0."""
        f = self.of_follower.get(tr.train_id)
        if f is None:
            return 0.0
        if self.manager.state(f.id) not in ("coupling", "coupled", "decoupling"):
            return 0.0
        leader = self.leader_of(f)
        if leader.status in ("running", "inserting"):
            lstop = leader.trip.stops[leader.next_stop] if leader.next_stop < len(leader.trip.stops) else None
        elif leader.arrived_s is not None:
            # it stands at its destination (SUMO no longer holds it): a platoon keeps its places there
            lstop = leader.trip.stops[-1]
        else:
            return 0.0
        if lstop is None or lstop.station_id != stop.station_id:
            return 0.0
        # a chain (A <- B <- C) stands one behind the other: behind the leader's own halt position
        return self.mark_offset_m(leader, lstop) + leader.trip.vehicle.length_m + float(f.target_gap_m)

    # ------------------------------------------------------------------ events from the other ports
    def on_departed_station(self, tr: TrainRuntime, stop: TripStop) -> None:
        """A train left a station: decouple triggers of its formations, couple triggers of its own."""
        for f in self.of_leader.get(tr.train_id, ()):  # decouple when the leader departs X
            if self.manager.state(f.id) in COUPLED_STATES:
                if (
                    trig(f.decouple, "at_station") and f.decouple.station == stop.station_id
                ) or self._last_stop_before_switch(tr, stop, f):
                    self.manager.request_decouple(f.id)

    def _last_stop_before_switch(self, leader: TrainRuntime, stop: TripStop, f: Any) -> bool:
        if not trig(f.decouple, "before_switch"):
            return False
        sw_id = f.decouple.switch
        later_marks = [s.mark_m for s in leader.trip.stops if s.mark_m > stop.mark_m]
        for rs in leader.trip.route.switches:
            if rs.switch_id == sw_id and 0.0 <= rs.point_m - stop.mark_m <= self.settings.decouple_distance_m:
                # only the last stop before the switch: no other stop of the leader lies in between
                return not any(m < rs.point_m for m in later_marks)
        return False

    # ------------------------------------------------------------------ every step
    def bookkeeping(self, t: float, tr: TrainRuntime, a: Ahead | None) -> None:
        """See the module docstring (insert waiting followers, decouple before switches, feed the state machine)."""
        for f in self.of_leader.get(tr.train_id, ()):  # tr is a leader
            follower = self.follower_of(f)
            if (
                follower.status == "scheduled"
                and trig(f.couple, "on_departure")
                and not self.chained(follower.train_id)
            ):
                stop, _ = self.current_stop(tr)
                if stop is not None and tr.sumo_stopped and stop.station_id == follower.trip.origin.station_id:
                    if self.insert_behind(follower, tr, float(f.target_gap_m)):
                        self.manager.request_couple(f.id)
            if trig(f.decouple, "before_switch") and self.manager.state(f.id) in COUPLED_STATES:
                for rs in tr.trip.route.switches:
                    if (
                        rs.switch_id == f.decouple.switch
                        and rs.point_m - tr.front_m <= self.settings.decouple_distance_m
                        and tr.front_m < rs.point_m
                    ):
                        nxt, _ = self.current_stop(tr)
                        if nxt is None or nxt.mark_m > rs.point_m:  # no stop left before the switch
                            self.manager.request_decouple(f.id)
        f = self.of_follower.get(tr.train_id)
        if f is None:
            return
        if a is not None:
            self.extensions.follower_step(t, tr, f, a)
        leader = self.leader_of(f)
        if a is not None and self._join_cut_off(tr, leader, f, a):
            self._cut_off.add(f.id)
            self.manager.record(t, "join_cut_off", f.id, by=a.train_id, station=tr.trip.origin.station_id)
        if self._couples_after_turnback(tr, leader, f, a):
            self._asked_after_turnback.add(f.id)
            self.manager.request_couple(f.id)
        if a is not None and a.train_id == leader.train_id and trig(f.couple, "after_switch"):
            self._couple_after_merge(tr, leader, f, a)
        elif trig(f.couple, "after_switch"):
            if f.id not in self._merged:
                self.join_book.merge_out_of_order(t, tr, leader, f, a)
        if trig(f.couple, "at_station"):
            self.join_book.run_in(t, tr, leader, f, a)
        if a is not None and a.train_id == leader.train_id:
            # the state machine judges the error against the controller's effective target (gap policy: larger
            # than the standstill target at speed), expressed around the formation's own target
            gap_for_fsm = a.gap_m - (self.effective_target_m(tr, f) - float(f.target_gap_m))
            self.manager.observe(t, f.id, gap_for_fsm, tr.plant.speed_mps - leader.plant.speed_mps)
        elif self.manager.state(f.id) == "decoupling":
            # the leader is no longer ahead on our track (it took the other leg, or left the line): the units
            # are apart, which completes decoupling (no gap is reported: there is none to measure)
            self.manager.observe_apart(t, f.id)
        if self.manager.state(f.id) == "coupled" and tr.arrived_s is None:  # an arrived train is no longer coupled
            tr.coupled_s += self.dt_s
            if f.id not in self.join_book.coupled_where:
                self.join_book.note_coupled(f, leader)

    def _couple_after_merge(self, follower: TrainRuntime, leader: TrainRuntime, f: Any, a: Ahead) -> None:
        """``couple: {after_switch: X}``: ask once, when the follower's front is past switch ``X`` — or it has
        asked for ``X`` and stands with its leader directly ahead past it, standing too: a platform starting just
        past the merge holds a follower short of ``X`` behind its leader waiting there — and it is close enough to its leader
        (``Joins.close_enough``: within reach of its rear, or running in behind it at the station where it waits).
        Before that the follower keeps its own separation."""
        if f.id in self._merged:
            return
        sw = f.couple.switch
        held_short = sw in follower.locks and follower.plant.speed_mps < STANDING_MPS and leader.sumo_stopped
        if (
            held_short
            or any(rs.switch_id == sw and follower.front_m >= rs.point_m for rs in follower.trip.route.switches)
        ) and self.join_book.close_enough(follower, leader, f, a):
            self._merged.add(f.id)
            self.manager.request_couple(f.id)

    def on_off_line(self, t: float, tr: TrainRuntime) -> None:
        """``tr`` arrived or left the line: its formations' coupled time stops counting."""
        fs = list(self.of_leader.get(tr.train_id, ()))
        if tr.train_id in self.of_follower:
            fs.append(self.of_follower[tr.train_id])
        for f in fs:
            self.manager.stop_clock(t, f.id)
