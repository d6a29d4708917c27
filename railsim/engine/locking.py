"""Route locking on the train side: when a train asks the interlocking for a switch, how far its movement
authority reaches, and when it releases (the engine side of :mod:`railsim.engine.events.interlocking`).

Every switch on a train's route is requested ``lock_request_distance_m`` before its point; until the lock is
granted the train's movement authority ends ``protection_margin_m`` before the switch point (the **overlap**: a
scenario sets it with ``interlocking.overlap_m``; the authority also reaches that far beyond the destination
platform's end); the lock is released when the train's rear is ``clearance_m`` past the point. A coupled follower on the same leg rides on
its leader's request (one lock for the formation). With a station stop to make before the switch, it is requested
only when the train is about to leave that stop (:func:`stop_before`), as a route is set from the starting signal:
a branch train dwelling short of a merge held the points for two minutes and the main-line train at the merge
waited for it — unless the stop lies within the authority margin of the points (the train could not reach its
stopping point without the lock). And a train whose route beyond its stop is not set far enough to draw clear of
the platform (its length plus its separation margin) stays at the platform after its dwell
(:meth:`RouteLocks.clears_platform`, the stop book's ``route_set``): a Jurenba unit that left Bijin and stood
short of the crossing with its rear on the platform held the next up train 113 m short of its stopping point,
and SUMO registered that train's stop there. Passing a switch without its lock is a ``switch_violation``
event. A route over the same points twice (a turnback path out along the line to a reversal and back) locks
them each time (:meth:`RouteLocks._lock_pass_m`): released behind the train on the way out, they are asked for
again on the way back, and the authority ends before them until they are. With one lock per trip, a unit turning
3.9 km beyond Jena's Winzerla came back over points ``1272033516`` under no lock, into a tram that held them.
An extension may take over the requests for some trains and switches (its ``manages_lock`` hook: the
junction planner requests in its planned order), or hold a train's request back for a while (``defers_lock``: a
merge is kept for a formation's follower, :mod:`railsim.engine.extensions.merge_order`).

**Stops within the overlap.** A platform may end closer to the points (or a single-track section, a crossing)
than the overlap: OSM nets put stops a few metres before the points. The authority before a resource not yet
granted then reaches the train's stopping mark (plus the margin its ATO keeps before an authority end), never
less (:meth:`RouteLocks._reach_stop`): the train halts at its mark, SUMO registers the stop, and the resource is
requested from there. Ending the authority the overlap short, a train with a platform 22 m before the points
halted 2 m short of its mark, outside a short platform's window: SUMO never registered the stop and the run
stalled. The overlap left beyond such a stop is the distance from the mark to the point. The carried authority
never lets the ATO aim closer than :data:`~railsim.engine.stop_timing.STOP_OVERRUN_ALLOWANCE_M` to the point
(the ATO's worst measured overrun of its stop point, rounded up): a tram handed to its ATO at speed close before
Potsdam's Platz der Einheit/West ran 1.12 m past its mark, 1 m before the platform end, into flat crossing
``1137879547`` while another tram held it. The aim then lies before the mark, inside the stop's window
(:func:`~railsim.engine.stop_timing.stop_aim_m`). A stop whose window has no such aim is served only with the
resource: the train asks for it on its way in (the stop's window ends within the overlap, and
:func:`~railsim.engine.stop_timing.stop_before` does not hold the request back), halts the allowance short of
the point while it waits, and the run records ``stop_needs_resource``.

**Merges.** At a merge (two tracks joining, SUMO's trailing points) a train on the other leg appears on our
track the moment it passes the point: its rear is at the point. So before a merge not locked for it a train's
authority ends ``max(overlap, its separation margin)`` before the point (:meth:`RouteLocks.protect_merges`), so
that the train appearing there is never inside the follower's own moving-block margin: with the overlap alone
(20 m < the 50 m margin) every such appearance was an emergency brake (29 on the Line 3 day, all at Bijin's down
merge). A merge is found on the route itself (the edge after the point has another way in), so it covers a
depot lead or a pocket joining the running track as well as a junction. Facing points keep the overlap: nobody
can appear ahead of us from the other leg there (and the Bijin up platform ends closer than 50 m to them). Nor
does a merge an extension manages (the junction planner orders the trains through it and plans their spacing).

**The walk.** Each step :meth:`RouteLocks.bookkeeping` visits only the switches of a train's route that can do
something now, and decides exactly as a walk over all of them (:mod:`railsim.engine.lock_walk`); likewise the
single-track sections (:mod:`railsim.engine.section_walk`). The authority end is worked out again only when
something it depends on has changed (:mod:`railsim.engine.authority`).

**Single track and flat crossings** are requested and released by :class:`~railsim.engine.section_requests.SectionRequests`
(its module docstring: consecutive sections, order on single track, a crossing right before a section).
"""

from __future__ import annotations

import logging
from bisect import insort
from collections.abc import Callable
from typing import Any, Protocol

import networkx as nx

from railsim.engine.authority import AuthorityEnds, AuthorityMemo
from railsim.engine.coupling import COUPLED_STATES, FormationBook
from railsim.engine.events.interlocking import Interlocking, RequestState
from railsim.engine.events.log import EventLog
from railsim.engine.events.tracks import SectionRequest, TrackSections
from railsim.engine.extensions.base import ExtensionSet
from railsim.engine.fleet import Fleet
from railsim.engine.lock_walk import WINDOW_SLACK_M, RouteSwitches, SwitchWalk, SwitchWalker, start_limit_of
from railsim.engine.section_requests import SectionRequests
from railsim.engine.section_room import joining_switches
from railsim.engine.section_walk import SECTION_WALK_MIN, SectionWalk, ShortEntries
from railsim.engine.settings import INF, EngineSettings
from railsim.engine.single_track import (
    RouteSection,
)
from railsim.engine.stop_timing import separation_margin_m, stop_before
from railsim.engine.train import TrainRuntime
from railsim.engine.trips import TripStop
from railsim.engine.wiring import unwired

log = logging.getLogger(__name__)


class Clock(Protocol):
    """The event layer's time."""

    @property
    def now_s(self) -> float:
        """Now [s]."""


class RouteLocks(SectionRequests, SwitchWalker, AuthorityEnds):
    """Requests, authority and releases of switch locks for every train."""

    def __init__(
        self,
        fleet: Fleet,
        interlocking: Interlocking,
        formations: FormationBook,
        events: EventLog,
        settings: EngineSettings,
        extensions: ExtensionSet,
        clock: Clock,
    ) -> None:
        self.fleet = fleet
        self.interlocking = interlocking
        self.formations = formations
        self.events = events
        self.settings = settings
        self.extensions = extensions  # manages_lock: switch requests an extension makes itself (the junction planner)
        self.tracks: TrackSections | None = None
        self.clock = clock  # the event layer's time (single-track releases are stamped with it)
        self.sections: dict[str, list[RouteSection]] = {}  # train id -> contested sections on its route
        self.section_requests: dict[str, dict[str, SectionRequest]] = {}  # train id -> section id -> request
        # does the unit of this trip run a next trip? (rotations: ``Turnbacks.next_of``; set_up_shared_track)
        self.continues: Callable[[str], bool] = unwired("RouteLocks", "continues")
        self.successor: Callable[[str], str | None] = lambda _train_id: None  # no rotations until set up
        self._parked: dict[str, list[SectionRequest]] = {}  # arrived trip -> sections kept for its unit's next trip
        # train id -> switch id -> where on its route the points its lock is for lie (a route over them twice)
        self._lock_pass: dict[str, dict[str, float]] = {}
        self.merges_of: dict[str, frozenset[str]] = {}  # train id -> switches that are merges on its route
        self.joins_of: dict[str, frozenset[str]] = {}  # train id -> points where another track joins its route
        self.passes_by: dict[str, list[RouteSection]] = {}  # train id -> sections whose protection points it leaves by
        # (section, direction, next section, direction) -> every train the other way waits clear of the next (SectionRoom)
        self.other_way_clear: dict[tuple[str, int, str, int], bool] = {}
        self.merge_margin_m: dict[str, float] = {}  # train id -> authority margin before a merge not locked for it
        self._indexes: dict[int, RouteSwitches] = {}  # id(route's switches) -> their look-ups (the walk)
        self._walks: dict[str, SwitchWalk] = {}  # train id -> where its walk over its route's switches stands
        self.walk_every_switch = False  # True: bookkeeping visits every switch of the route every step (the reference)
        self._route_end: dict[str, tuple[Any, float]] = {}  # train id -> (its trip's stops, authority at the end)
        # train id -> where the nearest train facing it on its track ahead begins (the loop sets it every step)
        self.facing_m: dict[str, float] = {}
        # (train id, station id, point) of each stop reported as served only with the resource beyond (_reach_stop)
        self._short_of_resource: set[tuple[str, str, float]] = set()
        self._memos: dict[str, AuthorityMemo] = {}  # train id -> its remembered authority end (authority.py)
        self._lock_state: dict[str, int] = {}  # train id -> version of its released switches and lock records
        self.remember_authority = True  # False: the authority end is worked out afresh at every call
        self._section_walks: dict[str, SectionWalk] = {}  # train id -> its walk over its sections (section_walk.py)
        self._short_entries: dict[str, ShortEntries] = {}  # train id -> its short list sorted (section_walk.py)
        self.walk_every_section = False  # True: the section bookkeeping visits every section every step
        self.section_walk_min = SECTION_WALK_MIN  # fewer sections on a route: it is gone over whole every step

    def protect_merges(self, graph: nx.DiGraph) -> None:
        """Find, on every train's route, the switches where another track joins the one the route continues on
        (the edge after the point has more than one way in: trailing points, a merge for this train), and the
        train's margin before them when they are not locked for it: the overlap, or its separation controller's
        ``margin_m`` if larger (module docstring, "Merges")."""
        overlap_m = self.settings.protection_margin_m
        for tid, tr in self.fleet.trains.items():
            margin_m = separation_margin_m(tr)
            if margin_m <= overlap_m:
                continue
            trailing = joining_switches(graph, tr.trip.route.edges)
            if trailing:
                self.merge_margin_m[tid] = margin_m
                self.merges_of[tid] = trailing

    def _margin_m(self, train_id: str, switch_id: str) -> float:
        """How far before a switch not locked for it the train's authority ends: the overlap, or its separation
        margin before a merge (module docstring, "Merges")."""
        if switch_id in self.merges_of.get(train_id, ()) and not self.extensions.manages_lock(train_id, switch_id):
            return self.merge_margin_m[train_id]
        return self.settings.protection_margin_m

    def _authority_end_of(self, tr: TrainRuntime) -> float:
        """The single-track part's view of :meth:`AuthorityEnds.authority_end_m`."""
        return self.authority_end_m(tr)

    def bookkeeping(self, t: float, tr: TrainRuntime, ahead: Any = None) -> None:
        """Request locks ahead, detect a pass without a lock, release behind the rear.

        Locks are requested in the order trains reach the switch: while another train (``ahead``, ground truth
        in this train's frame) stands between this train and a switch point, this train does not request that
        switch — granted first, it would hold the points the train in front needs, and neither could ever move (a
        unit waiting at a platform for its pocket track and a through train behind it; a follower that decouples
        before the points to take the other leg, its leader held up behind a third train). The one exception is a
        coupled follower taking the points on its leader's leg: it rides on its leader's request.

        Routes are set in order: while a train waits for a switch it asked for in an earlier step, or asked for in
        this step while another train holds it or is queued for it first, it asks for no switch beyond it. Else it
        could be granted the next points while a train coming from the other leg of the first takes that switch
        and passes in front of it: it then holds the points the train in front needs (Jena, points
        ``1854212868``: a deadlock at 1,163 s of the peak; points ``1684176122`` beyond the busy merge
        ``1684176151``, all asked for in one step at Stadtzentrum Löbdergraben). Points asked for while the track in
        front was clear are given up when a train comes onto the track in front (at a junction) and waits for them
        (:meth:`_gives_way`)."""
        if tr.train_id in self.sections:
            self._sections_bookkeeping(t, tr, ahead)
        elif self.tracks is not None and tr.train_id in self.passes_by:  # others may stand in line behind it
            self.tracks.set_in_front(t, tr.train_id, None if ahead is None else ahead.train_id)
        trip = tr.trip
        walk = self._walks.get(tr.train_id)
        if (  # the inputs SwitchWalk.remember_start_inputs noted (compared here: a call costs as much as it saves)
            walk is not None
            and walk.stops is trip.stops
            and walk.vehicle is trip.vehicle
            and walk.start_offset_m == trip.start_offset_m
            and walk.start_front_m == tr.start_front_m
        ):
            start_limit_m = walk.start_limit_m  # worked out from the same inputs
        else:
            start_limit_m = start_limit_of(trip, tr.start_front_m)
        switches = trip.route.switches
        order: Any
        if (
            walk is None
            or walk.index.switches is not switches
            or walk.start_limit_m != start_limit_m
            or walk.n_released != len(tr.released)
        ):
            walk = self._begin_walk(tr, switches, start_limit_m)
            if walk is not None:
                walk.remember_start_inputs(trip, tr.start_front_m)
            order = range(len(switches))  # begun afresh (or no walk): every switch
        elif (
            not walk.tracked
            and tr.front_m + self.settings.lock_request_distance_m + WINDOW_SLACK_M < walk.next_m
            and tr.locks.keys() == walk.lock_ids
        ):
            return  # no switch can matter this step (module docstring, "The walk")
        elif self._approaching_held(tr, walk, ahead):
            return  # only the points at the cursor, held or asked for, ahead of the front (lock_walk's docstring)
        else:
            single = self._single_switch(tr, walk)  # lock_walk's docstring, "One switch in reach"
            order = [single] if single >= 0 else self._walk_candidates(tr, walk)
        # a reversing unit sets no route beyond its reversal point before it leaves it (it may wait there long)
        request_until_m = tr.trip.stops[0].window_end_m if tr.reversing else INF
        behind = None if ahead is None else self.fleet.trains.get(ahead.train_id)
        waiting_m = INF  # the first switch on its route it waits for: no switch beyond it is requested yet
        k = 0
        while k < len(order):
            i = order[k]
            k += 1
            rs = switches[i]
            waiting_m = self._visit_switch(t, tr, rs, ahead, behind, start_limit_m, request_until_m, waiting_m)
            if walk is not None and type(order) is list:
                nxt = walk.index.next_same[i]
                if nxt >= 0 and self._lock_done(tr, rs) and nxt not in order[k:]:
                    insort(order, nxt, lo=k)  # released: the next time over the same points asks anew now
        if walk is not None and not (len(order) == 1 and self._still_settled(tr, walk, order[0])):
            self._settle_walk(tr, walk, order)

    def _visit_switch(
        self,
        t: float,
        tr: TrainRuntime,
        rs: Any,
        ahead: Any,
        behind: TrainRuntime | None,
        start_limit_m: float,
        request_until_m: float,
        waiting_m: float,
    ) -> float:
        """One switch of :meth:`bookkeeping`'s walk, in route order: ask anew on a later time over points done
        with, give points up to the train in front, request, note the first switch waited for, detect a pass
        without the lock, release behind the rear. Returns the updated ``waiting_m`` (the first switch waited
        for: nothing beyond it is requested). A switch this does nothing for is one :meth:`_walk_candidates`
        may leave out."""
        sid = rs.switch_id
        pass_m = self._lock_pass_m(tr, sid)
        if pass_m < rs.point_m and sid in tr.released:  # done with on an earlier time over it: ask anew
            tr.released.discard(sid)
            old = tr.locks.pop(sid, None)
            if old is not None and old.state in (RequestState.SCHEDULED, RequestState.WAITING):
                self.interlocking.cancel(old)  # passed while still waiting (a violation): one request per switch
            self._lock_pass.setdefault(tr.train_id, {})[sid] = rs.point_m
            self._lock_state_changed(tr.train_id)
        elif pass_m != rs.point_m or sid in tr.released:
            return waiting_m  # the lock is for another time over these points, or this one is done
        if behind is not None and sid in tr.locks and self._gives_way(tr, behind, ahead, rs):
            self.interlocking.cancel(tr.locks.pop(sid))
            self.events.record(t, "lock_given_up", tr.train_id, switch=sid, to=behind.train_id)
        if rs.point_m < start_limit_m:
            return waiting_m
        if (
            sid not in tr.locks
            and rs.point_m <= waiting_m
            and rs.point_m - tr.front_m <= self.settings.lock_request_distance_m
            and rs.point_m <= request_until_m
            and not stop_before(t, tr, rs.point_m - self._margin_m(tr.train_id, sid), rs.point_m)
            and not self.formations.join_book.route_waits(tr, rs.point_m)
            and not (behind is not None and rs.point_m > ahead.rear_m and not self._rides_with(tr, behind, rs))
            and not self.extensions.manages_lock(tr.train_id, sid)
            and not self.extensions.defers_lock(tr.train_id, sid)
            and not (self._room_rules_apply(tr.train_id) and self._section_guard_pending(tr, rs.point_m))
        ):
            holders = self._lock_group(tr, rs)
            if holders is not None:
                req = self.interlocking.request(holders, sid, rs.leg)
                for h in holders:
                    self.fleet.trains[h].locks[sid] = req
                self._lock_pass.setdefault(tr.train_id, {})[sid] = rs.point_m
                self._lock_state_changed(tr.train_id)
        held = tr.locks.get(sid)
        if (
            held is not None
            and held.state == RequestState.WAITING
            and (held.requested_s < t or self._switch_busy(sid, held))
            and rs.point_m < waiting_m
        ):
            waiting_m = rs.point_m
        if (
            sid in tr.locks
            and tr.front_m > rs.point_m
            and sid not in tr.violations
            and not self.interlocking.is_locked_for(tr.train_id, sid, rs.leg)
        ):
            tr.violations.add(sid)
            self.events.record(t, "switch_violation", tr.train_id, switch=sid, leg=rs.leg)
            log.error("%s passed switch %s without its lock", tr.train_id, sid)
        if sid in tr.locks and tr.front_m - tr.trip.vehicle.length_m > rs.point_m + self.settings.clearance_m:
            self.interlocking.release(tr.train_id, sid)
            tr.released.add(sid)
            self._lock_state_changed(tr.train_id)
        return waiting_m

    def _gives_way(self, tr: TrainRuntime, front: TrainRuntime, ahead: Any, rs: Any) -> bool:
        """True if ``tr`` holds (or waits for) the points ``rs`` alone, the train in front of it (``front``,
        ``ahead`` in ``tr``'s frame) stands between it and them and waits for them: ``tr`` gives them up and asks
        again once that train has gone (it asks for no points beyond a train in front). Asked for while the track
        in front was clear, they were held by a unit whose turnback path ran on along the line, and a tram that
        came onto the track in front of it at a junction waited for them (Jena, points ``1272033567``)."""
        req = tr.locks[rs.switch_id]
        if getattr(req, "holder_ids", ()) != (tr.train_id,) or rs.point_m <= ahead.rear_m:
            return False
        theirs = front.locks.get(rs.switch_id)
        if theirs is None or rs.switch_id in front.released:
            return False
        if theirs.state not in (RequestState.WAITING, RequestState.SCHEDULED):
            return False
        return not self._rides_with(tr, front, rs)

    def _lock_pass_m(self, tr: TrainRuntime, switch_id: str) -> float:
        """Where on ``tr``'s route lie the points its lock of ``switch_id`` is for: a route over the same points
        twice (a turnback path out to a reversal and back) locks them each time; without a record, the first."""
        known = self._lock_pass.get(tr.train_id, {}).get(switch_id)
        if known is not None:
            return known
        return self._route_index(tr.trip.route.switches).first_m.get(switch_id, INF)

    def _lock_done(self, tr: TrainRuntime, rs: Any) -> bool:
        """True if ``tr`` has released the lock of its time over the points at ``rs``."""
        return rs.switch_id in tr.released and self._lock_pass_m(tr, rs.switch_id) == rs.point_m

    def _switch_busy(self, switch_id: str, req: Any) -> bool:
        """True if another group holds ``switch_id`` or is queued for it ahead of ``req`` (a request made this
        step on a free switch is granted in the same instant; on a busy one it waits)."""
        holder = self.interlocking.holder(switch_id)
        if holder is not None and holder != req.holder_ids:
            return True
        queue = self.interlocking.queue(switch_id)
        return bool(queue) and queue[0] is not req

    def _rides_with(self, tr: TrainRuntime, leader: TrainRuntime, rs: Any) -> bool:
        """True if ``tr`` is coupled behind ``leader`` and takes switch ``rs`` on the leader's leg."""
        f = self.formations.of_follower.get(tr.train_id)
        if f is None or self.formations.leader_of(f) is not leader:
            return False
        if self.formations.manager.state(f.id) not in COUPLED_STATES:
            return False
        return any(s.switch_id == rs.switch_id and s.leg == rs.leg for s in leader.trip.route.switches)

    def _lock_group(self, tr: TrainRuntime, rs: Any) -> tuple[str, ...] | None:
        """Who requests: a coupled follower on the same leg rides on its leader's request."""
        f = self.formations.of_follower.get(tr.train_id)
        if f is not None and self.formations.manager.state(f.id) in COUPLED_STATES:
            leader = self.formations.leader_of(f)
            if rs.switch_id in leader.locks and rs.switch_id not in leader.released:
                req = leader.locks[rs.switch_id]
                if tr.train_id in getattr(req, "holder_ids", ()):
                    return None  # already in the leader's group
            elif leader.on_line and any(
                s.switch_id == rs.switch_id and s.leg == rs.leg and leader.front_m < s.point_m
                for s in leader.trip.route.switches
            ):
                return None  # the leader has yet to ask: the follower rides on its request, never ahead of it
        group = [tr.train_id]
        for f2 in self.formations.of_leader.get(tr.train_id, ()):  # include coupled followers on the same leg
            if self.formations.manager.state(f2.id) not in COUPLED_STATES:
                continue
            fol = self.formations.follower_of(f2)
            if fol.status not in ("inserting", "running") or rs.switch_id in fol.locks:
                continue
            if any(s.switch_id == rs.switch_id and s.leg == rs.leg for s in fol.trip.route.switches):
                group.append(fol.train_id)
        return tuple(group)

    def release_all(self, tr: TrainRuntime) -> None:
        """A train that arrived or left the line gives up every lock and section it still holds — except the
        sections a train that arrived still stands in while its unit runs a next trip (``continues``): those wait
        for :meth:`hand_over`. Released at once, the section went to a train waiting to enter it head-on, while
        the unit reversed and ran to its departure platform inside it (Jena, Ernst-Abbe-Platz: a frontal
        collision)."""
        if self.tracks is not None:
            rear_m = tr.front_m - tr.trip.vehicle.length_m
            ends = {(sec.section_id, sec.start_m): sec.end_m for sec in self.sections.get(tr.train_id, ())}
            for sid, req in self.section_requests.get(tr.train_id, {}).items():
                if tr.train_id in req.released_by:
                    continue
                end_m = ends.get((sid, self.pass_m(tr, req)), -INF)
                if tr.status == "arrived" and self.continues(tr.train_id) and rear_m <= end_m:
                    self._parked.setdefault(tr.train_id, []).append(req)
                    continue
                self.tracks.release(self.clock.now_s, tr.train_id, req)
        for sid in list(tr.locks):
            if sid not in tr.released:
                self.interlocking.release(tr.train_id, sid)
                tr.released.add(sid)
                self._lock_state_changed(tr.train_id)

    def hand_over(self, t: float, pred: TrainRuntime, succ: TrainRuntime | None) -> None:
        """``pred`` arrived and its unit starts ``succ`` where it stands (None: the unit leaves the line): the
        sections ``pred`` still stands in pass to ``succ`` if its route runs on in them (:meth:`release_all`),
        else they are released."""
        parked = self._parked.pop(pred.train_id, [])
        if self.tracks is None:
            return
        mine: dict[str, RouteSection] = {}  # the sections of succ's route, each its first time through
        for first in self.sections.get(succ.train_id, ()) if succ is not None else ():
            mine.setdefault(first.section_id, first)
        for req in parked:
            there = mine.get(req.section_id)
            reqs = self.section_requests[succ.train_id] if succ is not None and there is not None else {}
            new = None
            if succ is not None and there is not None and there.section_id not in reqs:
                new = self.tracks.hand_over(t, req, succ.train_id, there.direction)
            if new is None:
                self.tracks.release(t, pred.train_id, req)
            else:
                req.released_by.add(pred.train_id)
                reqs[req.section_id] = new

    # ------------------------------------------------------------------ who waits for whom
    def held_by(self, tr: TrainRuntime) -> list[str]:
        """Switches and sections ``tr`` (or its group) holds and has not released."""
        out = [sid for sid, req in tr.locks.items() if sid not in tr.released and self.interlocking.is_granted(req)]
        out += [
            sid
            for sid, req in self.section_requests.get(tr.train_id, {}).items()
            if req.granted and tr.train_id not in req.released_by
        ]
        return out

    def waiting_for(self, tr: TrainRuntime) -> list[str]:
        """Switches and sections ``tr`` has asked for and not been granted yet."""
        out = [sid for sid, req in tr.locks.items() if sid not in tr.released and not self.interlocking.is_granted(req)]
        out += [sid for sid, req in self.section_requests.get(tr.train_id, {}).items() if not req.granted]
        return out

    def blockers(self, tr: TrainRuntime) -> dict[str, tuple[str, ...]]:
        """For each switch ``tr`` waits for: the trains it waits behind (the lock holder and the requests queued
        ahead of its own, FIFO), excluding its own group."""
        out: dict[str, tuple[str, ...]] = {}
        for sid in self.waiting_for(tr):
            if sid not in tr.locks:
                continue  # a section: below
            own = tr.locks[sid]
            ahead: list[str] = list(self.interlocking.holder(sid) or ())
            for req in self.interlocking.queue(sid):
                if req is own:
                    break
                ahead.extend(req.holder_ids)
            out[sid] = tuple(dict.fromkeys(h for h in ahead if h not in own.holder_ids))
        if self.tracks is not None:
            for sec_id, sec_req in self.section_requests.get(tr.train_id, {}).items():
                if not sec_req.granted:
                    out[sec_id] = self.tracks.waiting_ahead(sec_req)
        return out

    def deadlock(
        self, trains: list[TrainRuntime], behind: dict[str, tuple[str, str]] | None = None
    ) -> tuple[list[str], list[str]] | None:
        """A circular wait among ``trains``: ``(train ids in the cycle, resources involved)``, or None.

        Train A waits for B when B holds (or is queued ahead for) a switch or section A asked for, or when A stands
        behind B (``behind``: standing train -> (the standing train it waits behind, the resource): ``ahead:B``
        for the train directly ahead, from the occupancy of the track, or ``platform:S`` for the train occupying
        the platform of station S that A waits to enter). A cycle in that graph can never resolve by itself: the
        interlocking serves each resource first-in-first-out, nobody releases a lock without moving past it, and
        a train cannot move through the train standing in front of it.
        """
        by_id = {tr.train_id: tr for tr in trains}
        waits: dict[str, dict[str, str]] = {}  # train -> {blocking train: resource}
        for tr in trains:
            for sid, others in self.blockers(tr).items():
                for other in others:
                    if other in by_id:
                        waits.setdefault(tr.train_id, {})[other] = sid
        for a, (b, resource) in (behind or {}).items():
            if a in by_id and b in by_id:
                waits.setdefault(a, {}).setdefault(b, resource)
        graph = nx.DiGraph()
        for a in sorted(waits):  # insertion order keeps the search deterministic
            for b in sorted(waits[a]):
                graph.add_edge(a, b, switch=waits[a][b])
        try:
            edges = nx.find_cycle(graph)
        except nx.NetworkXNoCycle:
            return None
        return [a for a, _ in edges], sorted({graph.edges[a, b]["switch"] for a, b in edges})

    def clears_platform(self, tr: TrainRuntime, stop: TripStop) -> bool:
        """True if the route set for the train standing at ``stop`` lets it draw clear of the platform: its
        authority reaches its own length plus its separation margin (at least the overlap) beyond the stopping
        point, or its next stop if that comes first. Until then it stays at the platform after its dwell, as
        behind a starting signal at danger (module docstring, "Routes from a station stop")."""
        if stop.is_destination or stop.kind != "station":
            return True
        f = self.formations.of_follower.get(tr.train_id)
        if f is not None and self.formations.manager.state(f.id) in COUPLED_STATES:
            return True  # a coupled follower goes with its leader
        margin_m = max(self.settings.protection_margin_m, separation_margin_m(tr))
        need_m = stop.mark_m + tr.trip.vehicle.length_m + margin_m
        if tr.next_stop + 1 < len(tr.trip.stops):
            need_m = min(need_m, tr.trip.stops[tr.next_stop + 1].window_start_m)
        return self.authority_end_m(tr) >= need_m - 1e-6
