"""Single-track sections and flat crossings on the train side: when a train asks for them, how many at once, in
which order, and when it lets them go (the engine side of :mod:`railsim.engine.events.tracks`; the sections
themselves are found by :mod:`railsim.engine.single_track`).

**Single track and flat crossings** (:mod:`railsim.engine.single_track`, :mod:`railsim.engine.events.tracks`): a
section of bidi track that trains use in both directions is a resource held one direction at a time. A train
requests it ``lock_request_distance_m`` before its protection point (the switch in front of the section, if any) —
but with a station stop to make before that point, only when it is about to leave that stop
(:func:`~railsim.engine.stop_timing.stop_before`); until it is reserved the train's authority ends
``protection_margin_m`` before that point, and it does not ask for the switch in front of the section either (a
train waiting for a section must not hold or stand on the switch the oncoming train needs to leave). A train
starting inside a section reserves it before it is inserted (the dispatcher holds the departure until then). It
releases the section when its rear is ``clearance_m`` past the section's end. A flat crossing (two routes crossing
inside one SUMO node) is the same kind of resource with one movement at a time.

**Consecutive sections.** Points, a siding or a short piece of double track split a single-track line into
several sections, and the track between two of them may hold no train, or fewer than are coming. A train
entering single track therefore reserves every section up to the next place where it can wait for an opposing
train — all of them at once or none (:meth:`SectionRequests._request_run`, :meth:`TrackSections.request_all`). The
track between two sections is such a passing place for a train only if it holds the train clear of both (rear
``clearance_m`` past the first, front the overlap before the second's protection point) beside the trains of the
same direction already bound to wait there — or, too short for that even alone, where every train of the other
direction waits there clear of the next section (:meth:`~railsim.engine.section_room.SectionRoom._other_way_clear`).
Granted one section alone, two opposing groups each held one section and waited at the short piece between for
the other's (Jena-Ost: three trams leaving the terminus and two coming in, a 78 m one-way piece between the two sections with room for one tram). So a single-track section
is entered only when it is reserved to the next passing place.

**Room between sections.** The trains that take that room (:meth:`SectionRequests._waiting_between`) are every
train bound through the next section the same way and not granted it that stands between the two sections now
(a tram dwelling at a platform there, its first section released and the next not yet asked for; a tram come
in from a branch joining there), or holds or waits for the first section on its way there — in any direction:
a unit reversing inside the first section leaves it towards the next. Counting only the trains of the same
direction holding or waiting for the first section, the room looked empty twice: at Jena-Ost a tram was granted
the first section alone behind the unit that had turned inside it and took the one place between, and at
Potsdam's Platz der Einheit a tram was granted the short section there alone while two trams waited for the
long one beyond its platform. Both times the trams holding the two sections each waited for the other's. The
room can fill while a request waits, too: a request for the first section alone, not yet granted, widens to
the whole run as soon as the room no longer holds its train (:meth:`SectionRequests._widen`,
:meth:`TrackSections.extend`; the Jena-Ost tram had asked 400 s before it was granted). And where a train in
front (come in from a branch) waits for a section the train behind it holds the same way, it is let through
at once (:meth:`SectionRequests._let_ahead_through`): the train behind cannot pass it, and the opposing train
served first would wait for the one behind. The room itself ends where the first train waiting there stands,
a train on a branch with its points set onto it counts as in it, and a train from a branch takes those points
only while the room holds it: :mod:`railsim.engine.section_room`.

**A section twice on one route** (a turnback path out through single track to a reversal and back) is asked
for each time through (:meth:`SectionRequests.pass_m`): the request of the way out, released behind the train,
gives way to a new one for the way back. With one request per trip, the unit came back into a section another
tram held the other way (Jena, Winzerla). But where the train reverses in a stub right beyond the section, with no
passing place between, the two times through are one entry in the train's own direction
(:func:`~railsim.engine.single_track.kept_through_reversal`, at set-up), as the stub is: asked for with the stub,
it is held alone from the way out until the rear has left it on the way back, and the sections after it on the way
back join that run unless the track beyond it is a passing place (:meth:`SectionRequests._run_from` counts the
room from where the train leaves it). Released behind the train, it went to a tram of the way out, which stood at
the platform in it and passed it to its unit's next trip; that trip waited for the stub the first unit was turning
in, and the unit for the section (Jena, Lobeda-Ost).

**Order on single track.** Trains of one direction leave a place in an order the queue cannot see, so the requests
keep to it: a train does not ask for a section beyond the train in front of it before that train has
(:meth:`SectionRequests._behind_first`; for a section it holds alone, turning in it or behind it, only a train in
front bound into it there, which nobody else asks for the same way), asks for no less than the trains of its
direction already waiting for the section (:meth:`SectionRequests._others_run_on`), and when it asks for a run
through several sections, the trains of its direction holding the first one alone ask for the rest at that moment
(:meth:`SectionRequests._bring_forward`). Each closed a circular wait on Jena's peak: a tram granted less than the
tram behind it left first and waited between the sections behind an opposing tram that waited for the one behind. A train whose trip ends beyond its last
section (a terminus: its unit turns there or leaves service) lets the trains leaving that terminus go first
(``yields``, :class:`~railsim.engine.events.tracks.TrackSections`), and is let in only while the terminus has room
for it (:mod:`railsim.engine.terminus_room`: its platform, or the whole turning loop or turnback track its unit
turns on, beside the units standing there).

**A crossing is entered only with its exit clear** (:meth:`SectionRequests._crossing_exit_blocked`): it is asked
for only when the train fits beyond it in front of the train ahead (where that one will stand: at the end of its
authority, if that comes first), as a road vehicle keeps out of a box junction it cannot leave.

**A crossing right before a section** with no room for the train between the two is asked for only once that
section is the train's (:meth:`SectionRequests._crossing_waits_for_next`): a tram at a platform ending at the crossing
held it while waiting for the single track behind it, whose opposing tram waited for the crossing (Potsdam). **A
crossing inside a section** is asked for only once the section is the train's
(:meth:`SectionRequests._crossing_inside_pending`), as points there are. And a train whose front has stopped
inside a crossing it has not asked for (a few centimetres past a platform ending there) asks for it at once
(:meth:`SectionRequests._nose_in_crossing`): it occupies it, whatever it waits for beyond.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from typing import Any

from railsim.engine.coupling import COUPLED_STATES, FormationBook
from railsim.engine.events.log import EventLog
from railsim.engine.events.tracks import OWN_DIRECTION, SectionRequest, TrackSections
from railsim.engine.fleet import Fleet
from railsim.engine.section_walk import SectionWalk, ShortEntries
from railsim.engine.settings import EngineSettings
from railsim.engine.single_track import (
    REVERSING,
    RouteSection,
    contested,
    kept_through_reversal,
    route_crossings,
    route_sections,
    section_map,
)
from railsim.engine.stop_timing import separation_margin_m, stop_before
from railsim.engine.terminus_room import TerminusRoom
from railsim.engine.train import TrainRuntime
from railsim.engine.wiring import set_once

SAME_PLACE_M = 1.0  # two routes' chainages of one point, each summed over its own edges, agree to this (_ahead_through)


class SectionRequests(TerminusRoom):
    """The single-track part of :class:`~railsim.engine.locking.RouteLocks` (its base class): the sections and
    crossings each train contests, its requests for them and their release. It reads the fleet, the formations and
    the settings its subclass holds."""

    fleet: Fleet
    formations: FormationBook
    settings: EngineSettings
    events: EventLog
    tracks: TrackSections | None
    sections: dict[str, list[RouteSection]]  # train id -> contested sections on its route
    section_requests: dict[str, dict[str, SectionRequest]]  # train id -> section id -> request
    clock: Any  # the event layer's time (now_s)
    continues: Callable[[str], bool]  # does the unit of this trip run a next trip? (rotations)
    successor: Callable[[str], str | None]  # the trip the unit of this trip runs next (rotations), or None

    def _authority_end_of(self, tr: TrainRuntime) -> float:
        """Where a train's movement authority ends (RouteLocks': its AuthorityEnds)."""
        raise NotImplementedError

    def set_up_shared_track(self, graph: Any, successor: Callable[[str], str | None]) -> None:
        """Find the single-track sections the scenario's trains use in both directions and the flat crossings they
        cross on different movements (see the module docstring); ``successor(train_id)``: the trip the unit of that
        trip runs next (the rotations) or None; a unit running on keeps its sections on arrival (:meth:`hand_over`)."""
        set_once(self, "continues", lambda train_id: successor(train_id) is not None)
        self.successor = successor
        smap = section_map(graph)
        if not smap and not graph.graph.get("crossings"):
            return
        per_train = {
            tid: sorted(
                route_sections(tr.trip.route, smap) + route_crossings(tr.trip.route, graph), key=lambda x: x.start_m
            )
            for tid, tr in self.fleet.trains.items()
        }
        shared = contested(per_train)
        if not shared:
            return
        self.tracks = TrackSections(self.events, sorted(shared), room_beyond=self._room_beyond)
        self.note_joins(graph)
        clear_m = self.settings.protection_margin_m + self.settings.clearance_m
        for k, (tid, sections) in enumerate(per_train.items()):
            # a train reversing in a section gets a direction nobody else has: it holds the section alone, and so
            # the section it is shut in behind while it turns in a stub (module docstring, "A section twice on one
            # route")
            length_m = self.fleet.trains[tid].trip.vehicle.length_m
            kept = kept_through_reversal(
                [x for x in sections if x.section_id in shared], OWN_DIRECTION + k, length_m, clear_m
            )
            mine = [
                dataclasses.replace(x, direction=OWN_DIRECTION + k) if x.direction == REVERSING else x for x in kept
            ]
            if mine:
                self.sections[tid] = mine
                self.section_requests[tid] = {}
        self.note_passes()

    def wanted_by_others(self, tr: TrainRuntime) -> bool:
        """True if another train waits for a single-track section ``tr`` holds (a unit waiting in a turnback
        track moves on to its departure platform rather than keep the next unit out)."""
        if self.tracks is None:
            return False
        for sid, req in self.section_requests.get(tr.train_id, {}).items():
            if req.granted and any(h != tr.train_id for h in self.tracks.queued(sid)):
                return True
        return False

    # ------------------------------------------------------------------ single track
    def _sections_bookkeeping(self, t: float, tr: TrainRuntime, ahead: Any = None) -> None:
        """Request the sections ahead (in the order trains reach them: never past the train in front, ``ahead``,
        unless it has asked for that section the same way or leads this train coupled) and release those behind."""
        assert self.tracks is not None
        reqs = self.section_requests[tr.train_id]
        self.tracks.set_in_front(t, tr.train_id, None if ahead is None else ahead.train_id)
        rear = tr.front_m - tr.trip.vehicle.length_m
        sections = self.sections[tr.train_id]
        walked = len(sections) >= self.section_walk_min  # those that can act (railsim.engine.section_walk)
        walk = self._current_walk(tr) if walked else None
        short = None if walked else self._short_list(tr)
        if short is not None:
            todo: Sequence[RouteSection] = short.visit
        else:
            todo = sections if walk is None else self._sections_to_visit(tr, walk)
        for sec in todo:
            req = reqs.get(sec.section_id)
            if req is not None and self._stale(tr, req, sec):
                req = None  # left behind on an earlier time through the section: this time asks anew
            elif req is not None and self.pass_m(tr, req) != sec.start_m:
                continue  # the request is for another time through: this one is done, or waits for it to end
            if req is None:
                if self._nose_in_crossing(tr, sec):
                    self._request_run(t, tr, [sec])
                elif (
                    sec.end_m > tr.front_m
                    and sec.guard_m - tr.front_m <= self.settings.lock_request_distance_m
                    and not stop_before(t, tr, sec.guard_m - self.settings.protection_margin_m, sec.guard_m)
                    and not self._crossing_waits_for_next(tr, sec)
                    and not self._crossing_exit_blocked(tr, sec, ahead)
                    and not self._crossing_inside_pending(tr, sec)
                ):
                    run = self._run_from(tr, sec)
                    if not any(self._behind_first(tr, s, ahead) for s in run):
                        self._request_run(t, tr, run)
            elif tr.train_id not in req.released_by and rear > sec.end_m + self.settings.clearance_m:
                self.tracks.release(t, tr.train_id, req)
            else:
                self._widen(t, tr, sec, req)
        self._let_ahead_through(t, tr, ahead, walk, short)
        if walked:
            self._settle_sections(tr, walk)

    def pass_m(self, tr: TrainRuntime, req: SectionRequest) -> float:
        """Where on ``tr``'s route the time through ``req``'s section begins that ``req`` is for: a route that runs
        through a section twice (a turnback path out to a reversal and back) asks for it each time; a request made
        without one (a section handed over at a turnback) is for the first time through."""
        if req.pass_m is not None:
            return req.pass_m
        return next(s.start_m for s in self.sections[tr.train_id] if s.section_id == req.section_id)

    def _stale(self, tr: TrainRuntime, req: SectionRequest, sec: RouteSection) -> bool:
        """True if ``req`` is ``tr``'s request for an earlier time through ``sec``'s section, released since."""
        return tr.train_id in req.released_by and self.pass_m(tr, req) < sec.start_m

    def _let_ahead_through(
        self, t: float, tr: TrainRuntime, ahead: Any, walk: SectionWalk | None = None, short: ShortEntries | None = None
    ) -> None:
        """A train in front of ``tr`` (``ahead``, in ``tr``'s frame, or one in front of it in turn:
        :meth:`_trains_in_front`) waits for a section ``tr`` holds the same way and has not passed yet: it is
        granted the section at once (:meth:`TrackSections.let_through`), for ``tr`` cannot pass through before it.
        A tram coming in from a branch between two sections stood in front of the tram granted both and waited for
        the second behind an opposing request, which waited for the tram behind (Potsdam, Platz der Einheit); the
        second time a tram from the same branch, not yet asking (it had its platform to serve first), stood between
        the two."""
        assert self.tracks is not None
        if ahead is None:
            return
        for sec in self._sections_held(tr, walk, short):
            mine = self.section_requests[tr.train_id].get(sec.section_id)
            if (
                mine is None
                or not mine.granted
                or tr.train_id in mine.released_by
                or not sec.section_id.startswith("track:")
                or sec.end_m <= tr.front_m
            ):
                continue
            for front_id in self._trains_in_front(ahead.train_id, sec):
                other = self.section_requests.get(front_id, {}).get(sec.section_id)
                if (
                    other is not None
                    and not other.granted
                    and front_id not in other.released_by
                    and other.direction == mine.direction
                ):
                    self.tracks.let_through(t, other, mine.holder_ids)

    def _behind_first(self, tr: TrainRuntime, sec: RouteSection, ahead: Any) -> bool:
        """True if the train in front (``ahead``, in this train's frame) stands between this train and the
        protection point of ``sec`` and has not asked for ``sec`` in the same direction: it must ask first. Else
        the train behind, asking for two sections at once while the one in front had asked for the first only
        (it could wait between them), was granted the second; the one in front then waited for it behind an
        opposing train that waited for the train behind (Jena, ``track:-47054577``). A section this train holds
        alone (:meth:`_held_alone`: it turns in it or beyond it) nobody asks for the same way: the train in front
        comes first there only where it runs through it too, until it has asked for its own time through it there
        (:meth:`_ahead_through`). A train in front that does not run through the section at all
        (:meth:`_runs_through`) never comes first."""
        if ahead is None or sec.guard_m <= ahead.rear_m or not self._runs_through(ahead.train_id, sec):
            return False
        theirs = self.section_requests.get(ahead.train_id, {}).get(sec.section_id)
        if self._held_alone(sec) and ahead.train_id in self.fleet.trains:
            there = self._ahead_through(ahead, sec)
            if there is None or (
                theirs is not None
                and ahead.train_id not in theirs.released_by
                and self.pass_m(self.fleet.trains[ahead.train_id], theirs) == there.start_m
            ):
                return False
        elif theirs is not None and theirs.direction == sec.direction and ahead.train_id not in theirs.released_by:
            return False
        f = self.formations.of_follower.get(tr.train_id)
        if f is not None and self.formations.manager.state(f.id) in COUPLED_STATES:
            return self.formations.leader_of(f).train_id != ahead.train_id
        return True

    def _runs_through(self, train_id: str, sec: RouteSection) -> bool:
        """True if ``train_id``'s route runs through ``sec``'s section the way ``sec`` runs or reversing inside it
        (a direction of its own), or through it at all where ``sec`` is held alone (:meth:`_ahead_through` decides
        there). A train in front that leaves by another way at the section's protection points never asks for it:
        a tram behind one leaving Platz der Einheit/West for Dortustraße waited for it to ask, for good (all lines
        every 780 s: stalled)."""
        return any(
            s.section_id == sec.section_id
            and (s.direction == sec.direction or self._held_alone(s) or self._held_alone(sec))
            for s in self.sections.get(train_id, ())
        )

    @staticmethod
    def _held_alone(sec: RouteSection) -> bool:
        """True for a single-track section in a direction of the train's own (it reverses inside it, or beyond it
        with no passing place between: :func:`~railsim.engine.single_track.kept_through_reversal`)."""
        return sec.direction >= OWN_DIRECTION and sec.section_id.startswith("track:")

    def _ahead_through(self, ahead: Any, sec: RouteSection) -> RouteSection | None:
        """The entry on the route of the train in front (``ahead``, in the follower's frame) for ``sec``'s section
        where the follower's route enters it (the two routes run on together up to there), or None: it leaves the
        follower's way before, or comes back to the section another way."""
        other = self.fleet.trains[ahead.train_id]
        offset_m = ahead.front_m - other.front_m  # the follower's chainage of a point on the route in front
        return next(
            (
                s
                for s in self.sections.get(ahead.train_id, ())
                if s.section_id == sec.section_id and abs(s.start_m + offset_m - sec.start_m) < SAME_PLACE_M
            ),
            None,
        )

    def _crossing_waits_for_next(self, tr: TrainRuntime, sec: RouteSection) -> bool:
        """True for a flat crossing with no room for the train between it and the next section on its route (up to
        that section's protection point) while that section is not granted (module docstring)."""
        nxt = next((x for x in self.sections[tr.train_id] if x.start_m > sec.start_m), None)
        if not sec.section_id.startswith("crossing:") or nxt is None:
            return False
        req = self.section_requests[tr.train_id].get(nxt.section_id)
        pending = req is None or not req.granted or self._stale(tr, req, nxt)
        return self._room_m(sec.end_m, nxt.guard_m) < tr.trip.vehicle.length_m and pending

    def _nose_in_crossing(self, tr: TrainRuntime, sec: RouteSection) -> bool:
        """True for a flat crossing the train's front has entered without asking for it (a halt a few centimetres
        past a platform that ends at the crossing: the ATO stops within its tolerance of the mark): the train
        occupies the crossing, so it asks for it at once, whatever waits beyond. A tram 0.12 m past Potsdam's Platz
        der Einheit/West stood in crossing ``1137879547`` for minutes while trams of the other movement went
        through it (railsim's crossing check: three collisions)."""
        return sec.section_id.startswith("crossing:") and sec.start_m < tr.front_m < sec.end_m

    def _crossing_inside_pending(self, tr: TrainRuntime, sec: RouteSection) -> bool:
        """True for a flat crossing beyond the protection point of a single-track section the train has not been
        granted (a crossing inside the section): as with points there (:meth:`_section_guard_pending`), it is
        the train's only once the section is. A tram waiting for the section held a crossing inside it, and a
        tram coming from the branch over that crossing waited in front of the tram holding the section (Potsdam,
        crossing ``4073068946``)."""
        if not sec.section_id.startswith("crossing:"):
            return False
        reqs = self.section_requests[tr.train_id]
        for s in self.sections[tr.train_id]:
            if s.section_id.startswith("track:") and s.guard_m <= sec.guard_m and s.end_m > sec.guard_m:
                req = reqs.get(s.section_id)
                if req is None or not req.granted or tr.train_id in req.released_by:
                    return True
        return False

    def _crossing_exit_blocked(self, tr: TrainRuntime, sec: RouteSection, ahead: Any) -> bool:
        """True for a flat crossing whose exit is not clear: the train in front (``ahead``, in this train's frame)
        leaves no room for this train beyond the crossing (its rear ``clearance_m`` past the end, its front its
        separation margin behind the rear of the one in front). A tram that went in behind a tram waiting for the
        next crossing stood in this one, and the opposing tram waiting for it stood in that next crossing behind a
        tram waiting for this one (Jena, crossings ``1684176152`` and ``1684176122``). The train in front counts
        where it will stand: at the end of its movement authority (the overlap before a section or points not yet
        its own) if that comes first — a tram went into crossing ``259782418`` behind trams still rolling up to the
        Ernst-Abbe-Platz stub they waited for, and the unit turning in the stub waited for the trams leaving
        through that crossing. Nor is the exit clear while points the train would pass before it is clear of the
        crossing (at its separation margin) are locked for or asked for by another train
        (:meth:`_points_taken_beyond`)."""
        if not sec.section_id.startswith("crossing:"):
            return False
        if self._points_taken_beyond(tr, sec):
            return True
        if ahead is None:
            return False
        room_m = self._ahead_rear_m(ahead) - separation_margin_m(tr) - (sec.end_m + self.settings.clearance_m)
        return room_m < tr.trip.vehicle.length_m

    def _ahead_rear_m(self, ahead: Any) -> float:
        """Where the rear of the train in front (``ahead``, in the follower's frame) will stand: where it is, or
        further back at the end of its movement authority less its length, if that comes first."""
        rear_m = float(ahead.rear_m)
        other = self.fleet.trains.get(ahead.train_id)
        if other is not None:
            end_m = self._authority_end_of(other) + (ahead.front_m - other.front_m)
            rear_m = min(rear_m, end_m - (ahead.front_m - ahead.rear_m))
        return rear_m

    def admit(self, t: float, tr: TrainRuntime, depart_m: float) -> str | None:
        """Before insertion at ``depart_m``: reserve the sections the train starts in; a reason to wait, or None."""
        if self.tracks is None or tr.train_id not in self.sections:
            return None
        reqs = self.section_requests[tr.train_id]
        for sec in self.sections[tr.train_id]:
            if sec.start_m - self.settings.protection_margin_m <= depart_m < sec.end_m:
                if sec.section_id not in reqs:
                    self._request_run(t, tr, self._run_from(tr, sec))
                self._widen(t, tr, sec, reqs[sec.section_id])
                req = reqs[sec.section_id]
                if not req.granted:
                    others = ", ".join(self.tracks.waiting_ahead(req)) or "another train"
                    return f"single-track section {sec.section_id} is reserved for {others}"
        return None

    def _request_run(self, t: float, tr: TrainRuntime, run: list[RouteSection]) -> None:
        """Request the sections ``run`` (one section and every single-track section after it up to the next
        passing place for this train, :meth:`_run_from`) in one group (module docstring, "Consecutive sections")."""
        assert self.tracks is not None
        reqs = self.section_requests[tr.train_id]
        wanted = [(sec.section_id, sec.direction) for sec in run]
        last = run[-1]
        ends = self._ends_at_terminus(tr, last)
        for sec, req in zip(run, self.tracks.request_all(t, (tr.train_id,), wanted, yields=ends)):
            req.pass_m = sec.start_m
            reqs[sec.section_id] = req
        self._bring_forward(t, tr, run)

    def _widen(self, t: float, tr: TrainRuntime, sec: RouteSection, req: SectionRequest) -> None:
        """A request for ``sec`` alone, not yet granted, becomes a request for the run through the next sections
        once the room between them no longer holds the train (:meth:`_run_from`; module docstring, "Room between
        sections"): the room counted when it asked may have filled since. Granted ``sec`` alone later, a tram
        went into the Jena-Ost single track behind the unit that had turned there and took the one place between
        the two sections (``3_jena-ost_lobeda-ost_2.001``, asked at 900 s, granted at 1,301 s: deadlock)."""
        assert self.tracks is not None
        if req.granted or req.group or tr.train_id in req.released_by or not sec.section_id.startswith("track:"):
            return
        run = self._run_from(tr, sec)
        if len(run) == 1:
            return
        wanted = [(s.section_id, s.direction) for s in run[1:]]
        reqs = self.section_requests[tr.train_id]
        for s, new in zip(run[1:], self.tracks.extend(t, req, wanted, yields=self._ends_at_terminus(tr, run[-1]))):
            new.pass_m = s.start_m
            reqs[s.section_id] = new
        self._bring_forward(t, tr, run)

    def _ends_at_terminus(self, tr: TrainRuntime, last: RouteSection) -> bool:
        """True if ``last`` is the train's last single-track section and a terminus lies beyond it: the train's
        unit turns there and comes back through ``last`` first (:meth:`_turns_back_through`), or (the unit leaves
        service) another unit bound for the same station through the same section in the same direction does.
        Either way it stands at the terminus, which only the trains leaving make room in. A section a train
        passes far from where its unit turns (a stub it leaves at the start of its trip, double track after it)
        is no terminus approach: a tram leaving Ernst-Abbe-Platz for Lobeda-Ost, 8 km of double track away, let
        the trams coming in go first."""
        mine = self.sections[tr.train_id]
        if not last.section_id.startswith("track:") or any(
            s.end_m > last.end_m and s.section_id.startswith("track:") for s in mine
        ):
            return False
        if self.continues(tr.train_id):
            return self._turns_back_through(tr.train_id, last)
        station = tr.trip.stops[-1].station_id
        for oid, theirs in self.sections.items():
            other = self.fleet.trains[oid]
            if oid == tr.train_id or other.trip.stops[-1].station_id != station or not self.continues(oid):
                continue
            track = [s for s in theirs if s.section_id.startswith("track:")]
            if track and track[-1].section_id == last.section_id and track[-1].direction == last.direction:
                return self._turns_back_through(oid, track[-1])
        return False

    def _turns_back_through(self, train_id: str, last: RouteSection) -> bool:
        """True if the next trip of ``train_id``'s unit enters single track first through ``last`` the other way
        (beyond it, or reversing inside it): the unit is shut in beyond it until it leaves again. A unit that
        leaves through ``last`` the same way (a terminus platform on a loop inside the section: Jena's Winzerla)
        is not shut in: nothing comes back against the trains behind it."""
        succ_id = self.successor(train_id)
        track = [s for s in self.sections.get(succ_id or "", ()) if s.section_id.startswith("track:")]
        return bool(track) and track[0].section_id == last.section_id and track[0].direction != last.direction

    def _bring_forward(self, t: float, tr: TrainRuntime, run: list[RouteSection]) -> None:
        """Trains of ``tr``'s direction that hold or wait for the first section of ``run`` alone, and run on
        through the next ones, ask for those now: they would leave before ``tr`` and, asking later, wait between
        the sections behind an opposing train that waits for ``tr`` (Jena-Ost)."""
        assert self.tracks is not None
        first = run[0]
        for other in self.tracks.requests(first.section_id):
            if other.direction != first.direction or other.group or tr.train_id in other.holder_ids:
                continue
            for oid in other.holder_ids:
                theirs = self.section_requests.get(oid)
                if theirs is None or oid in other.released_by:
                    continue
                for sec in run[1:]:
                    mine = [s for s in self.sections[oid] if s.section_id == sec.section_id]
                    if sec.section_id in theirs or not mine or mine[0].direction != sec.direction:
                        break
                    theirs[sec.section_id] = self.tracks.request(t, (oid,), sec.section_id, sec.direction)
                    theirs[sec.section_id].pass_m = mine[0].start_m

    def _run_from(self, tr: TrainRuntime, first: RouteSection) -> list[RouteSection]:
        """``first`` and the single-track sections that follow it on the route with no passing place between:
        the next one is added while the track between the two cannot hold this train clear of both
        (:meth:`_passing_room_m`), counted from the end of the section the train leaves last (a section kept through
        the reversal in a stub beyond it, :func:`~railsim.engine.single_track.kept_through_reversal`, ends after the
        stub, which belongs to its run). Sections already requested end the run; flat crossings are requested alone (a
        train never stands inside one waiting)."""
        run = [first]
        if not first.section_id.startswith("track:"):
            return run
        reqs = self.section_requests[tr.train_id]
        track = [s for s in self.sections[tr.train_id] if s.section_id.startswith("track:")]
        # the room is counted from the section the train leaves last: ``first``, or one kept round it while it turns
        reach = max((s for s in track if s.start_m <= first.start_m and s.end_m >= first.end_m), key=lambda s: s.end_m)
        for nxt in (s for s in track if s.start_m > first.start_m):
            done = nxt.section_id in reqs and not self._stale(tr, reqs[nxt.section_id], nxt)
            if done or any(s.section_id == nxt.section_id for s in run):
                break
            if nxt.end_m > reach.end_m:  # (one inside a section kept through the reversal belongs to its run)
                fits = self._passing_room_m(tr, reach, nxt) >= tr.trip.vehicle.length_m
                if (fits or self._other_way_clear(tr, reach, nxt)) and not self._others_run_on(reach, nxt):
                    break
                reach = nxt
            run.append(nxt)
        return run

    def _others_run_on(self, sec: RouteSection, nxt: RouteSection) -> bool:
        """True if a train of the same direction already waits for ``sec`` together with ``nxt``: a train asks
        for no less than those before it. Asking for ``sec`` alone, it was granted it first, left ahead of them
        and waited between the sections for ``nxt``, which they were then granted behind it (Jena-Ost)."""
        assert self.tracks is not None
        for req in self.tracks.waiting(sec.section_id):
            if req.direction == sec.direction and any(r.section_id == nxt.section_id for r in req.group):
                return True
        return False

    def _passing_room_m(self, tr: TrainRuntime, sec: RouteSection, nxt: RouteSection) -> float:
        """Room left for ``tr`` to wait between ``sec`` and ``nxt`` with its rear clear of ``sec``: from
        ``clearance_m`` past the end of ``sec`` to where its authority ends before ``nxt`` (the overlap before its
        protection point), less the room of every other train that stands there or will stand there before it,
        waiting for ``nxt`` the way ``tr`` runs through it (:meth:`_waiting_between`), each its length and its
        separation margin. Its authority ends before a crossing right before ``nxt`` if it may not ask for that
        crossing yet (:meth:`_wait_point_m`)."""
        room_m = self._stand_room_m(tr, sec.end_m, nxt)
        gap_m = nxt.guard_m - sec.end_m
        for other in self._waiting_between(tr, sec, nxt, gap_m):
            room_m -= other.trip.vehicle.length_m + separation_margin_m(other)
        return room_m

    def _waiting_between(
        self, tr: TrainRuntime, sec: RouteSection, nxt: RouteSection, gap_m: float
    ) -> list[TrainRuntime]:
        """The trains other than ``tr`` that stand, or will stand, between ``sec`` and ``nxt`` waiting for ``nxt``
        in ``tr``'s direction through it (module docstring, "Room between sections"): not granted ``nxt`` and
        bound through it that way, and either standing within ``gap_m`` before its protection point now, or
        holding or waiting for ``sec`` (in any direction: a unit reversing inside ``sec`` leaves it towards
        ``nxt``) on the way there."""
        assert self.tracks is not None
        through_sec = set(self.tracks.holders(sec.section_id)) | set(self.tracks.queued(sec.section_id))
        out = []
        for other, theirs, there in self._bound_short_of(tr, nxt, through_sec):  # past nxt: never waits between
            other_id = other.train_id
            reqs = self.section_requests.get(other_id, {})
            on = reqs.get(nxt.section_id)
            if other.on_line and (there.guard_m - other.front_m <= gap_m or self._joining(other, there.guard_m, gap_m)):
                out.append(other)  # standing between the sections, or coming in from a branch joining there
                continue
            if other_id not in through_sec:
                continue
            before = next((s for s in theirs if s.section_id == sec.section_id), None)
            mine = reqs.get(sec.section_id)
            if before is None or before.start_m >= there.start_m or mine is None or other_id in mine.released_by:
                continue
            if on is not None and on in mine.group:
                continue  # it asked for sec and nxt together: it runs on through both
            out.append(other)
        return out

    def _section_guard_pending(self, tr: TrainRuntime, point_m: float) -> bool:
        """True if a section or crossing not yet reserved for the train has its protection point at or before
        this switch point: the train's authority ends before it, so the switch is not the train's yet. A train
        waiting at the near end of a section held the points at its far end, which the train in the section
        needed to leave it (Jena, points ``1831585450``; before, only a switch exactly at the protection point
        was held back). Nor are points that let the train in from a branch onto the track before a section while
        that track has no room for it (:meth:`~railsim.engine.section_room.SectionRoom._joins_full_room`)."""
        reqs = self.section_requests.get(tr.train_id, {})
        for sec in self.sections.get(tr.train_id, ()):
            if sec.guard_m <= point_m + 1e-6 and sec.end_m > tr.front_m:
                req = reqs.get(sec.section_id)
                if req is None or not req.granted or self._stale(tr, req, sec):
                    return True
        return self.tracks is not None and self._joins_full_room(tr, point_m)
