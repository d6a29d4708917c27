"""The track in front of a single-track section: how much of it a train may count on, and who comes into it.

Trains wait for a single-track section on the track before its protection point (between two sections: the passing
place of :mod:`railsim.engine.section_requests`, "Consecutive sections"). Three things decide whether that track
still holds a train when it gets there, and the rules here keep each of them in the count.

**Where the waiting ends.** A train waiting for the section stops the overlap before its protection point — or
before a flat crossing right before the section, if there is no room for the train between the two: that crossing
is asked for only once the section is the train's (:meth:`SectionRoom._wait_point_m`). The room between two
sections ends there too.

**Who comes in from a branch.** Points between two sections let trains in from a branch that never ran through the
first section; granted the first section alone, a train found the track in front of the next one filled by them and
stood in the first section, holding it against the opposing trains its own next section waited for. So a train
joining that track at points (from its branch, holding no section just before them) takes the points only while the
track from them to the section holds it beside the trains standing there and those on their way there through a
section they hold (:meth:`SectionRoom._joins_full_room`); else it stands on its branch until the section is its
own. A flat crossing right before such points is asked for only when the points may be taken
(:meth:`SectionRoom._points_taken_beyond`: nor while another train holds or has asked for them — it goes first and
may come to stand in the crossing's exit). Only points where another track joins the train's route count here
(:meth:`SectionRoom.note_joins`): at facing points the other train goes away from it.

**Who leaves by another way.** A train that runs over that track and leaves it by a branch at the very points
that protect the next section (:meth:`SectionRoom.note_passes`) cannot pass a train standing there waiting for
the section: it takes room there as the trains bound through the section do, from a branch too. Left out, an
opposing tram was granted the section behind it and stood in the section, waiting for the platform the leaving
tram stood at. A train counts in that room from the moment it has asked for the points onto the track, not only
once they are set for it (they may take seconds to throw, and the room was counted for it when it asked), and a
train taking points onto the track must fit beyond the points of that kind right after them too, if it could not
wait between the two.

**Too short one way.** A track that cannot hold a train clear of the section behind it even alone (its platform
there keeps its rear inside ``clearance_m``) is a passing place for it all the same while every train of the other
way, running from the next section into that one, waits there clear of the next section
(:meth:`SectionRoom._other_way_clear`): each of them is granted its section alone only while the track holds it,
and lets it go there, so no two opposing trains each hold the section the other waits for.

**Who stands in front.** A train holding a section cannot pass the trains in front of it that go through it the
same way, however many stand between it and the section (:meth:`SectionRoom._trains_in_front`): each of them is let
through as it asks (:meth:`railsim.engine.events.tracks.TrackSections.let_through`).

Every rule here comes from Potsdam's Platz der Einheit (all its tram lines every 720 s and every 1,200 s): two
short sections on either side of Platz der Einheit/West, branches from Platz der Einheit/Nord, Dortustraße and the
Bildungsforum joining the track between them, and a flat crossing right before each section.
"""

from __future__ import annotations

from bisect import bisect_right
from collections.abc import Iterator, Sequence
from typing import TYPE_CHECKING, Any

from railsim.engine.events.interlocking import Interlocking
from railsim.engine.events.tracks import OWN_DIRECTION
from railsim.engine.section_walk import SectionWalker
from railsim.engine.single_track import RouteSection
from railsim.engine.stop_timing import separation_margin_m
from railsim.engine.train import TrainRuntime

if TYPE_CHECKING:
    from railsim.engine.fleet import Fleet


def joining_switches(graph: Any, edges: Sequence[str]) -> frozenset[str]:
    """The switches on a route of ``edges`` where another track joins it: trailing points, the edge after the
    point having more than one way in (``graph``: the net's topology, a switch id on each connection through
    points)."""
    return frozenset(
        str(graph.edges[a, b]["switch"])
        for a, b in zip(edges, edges[1:])
        if graph.has_edge(a, b) and graph.edges[a, b].get("switch") and graph.in_degree(b) > 1
    )


class SectionRoom(SectionWalker):
    """The room before a section (module docstring): a base class of
    :class:`~railsim.engine.section_requests.SectionRequests`, which holds the fleet and the interlocking."""

    fleet: Fleet  # the fleet (trains by id)
    interlocking: Interlocking
    joins_of: dict[str, frozenset[str]]  # train id -> points where another track joins its route (note_joins)
    passes_by: dict[str, list[RouteSection]]  # train id -> sections whose protection points it leaves by (note_passes)
    other_way_clear: dict[tuple[str, int, str, int], bool]  # (_other_way_clear)

    def note_joins(self, graph: Any) -> None:
        """Find on every train's route the points where another track joins it (trailing points: the edge after
        the point has more than one way in): only there do trains from a branch come in front of it."""
        for tid, tr in self.fleet.trains.items():
            joins = joining_switches(graph, tr.trip.route.edges)
            if joins:
                self.joins_of[tid] = joins

    def note_passes(self) -> None:
        """Find on every train's route the single-track sections whose protection points it passes on another leg:
        it runs over the track where trains wait for the section, and leaves it by another way right there. Each
        is kept as a section of no length at that point in the train's chainage (``start_m = end_m = guard_m``).
        Standing on that track behind a train waiting for the section, it cannot leave, so it takes room there as
        the trains bound through the section do (:meth:`_bound_short_of`)."""
        # the edge each protection point lies on (its end, at points) -> (section, direction) -> (how far past the
        # edge's start the point lies, the edges routes run on into the section)
        into: dict[str, dict[tuple[str, int], tuple[float, set[str]]]] = {}
        for tid, secs in self.sections.items():
            edges, starts = self._route_edges(tid)
            for sec in secs:
                i = max(bisect_right(starts, sec.guard_m - 1e-3) - 1, 0)
                if sec.section_id.startswith("track:") and sec.direction < OWN_DIRECTION and i + 1 < len(edges):
                    _, nexts = into.setdefault(edges[i], {}).setdefault(
                        (sec.section_id, sec.direction), (sec.guard_m - starts[i], set())
                    )
                    nexts.add(edges[i + 1])
        if not into:
            return
        for tid in self.fleet.trains:
            edges, starts = self._route_edges(tid)
            passes = [
                RouteSection(sid, direction, starts[i] + at_m, starts[i] + at_m, starts[i] + at_m)
                for i in range(len(edges) - 1)
                for (sid, direction), (at_m, nexts) in into.get(edges[i], {}).items()
                if edges[i + 1] not in nexts
            ]
            if passes:
                self.passes_by[tid] = sorted(passes, key=lambda x: x.guard_m)

    def _route_edges(self, train_id: str) -> tuple[Sequence[str], Sequence[float]]:
        """The edges of ``train_id``'s route and where each starts (route chainage [m])."""
        route = self.fleet.trains[train_id].trip.route
        return route.edges, route.edge_start_m

    def _room_rules_apply(self, train_id: str) -> bool:
        """True if the room before single-track sections concerns ``train_id``: it runs through such a section or
        leaves by another way at one's protection points (:meth:`note_passes`)."""
        return train_id in self.sections or train_id in self.passes_by

    def _joins_at(self, tr: TrainRuntime, point_m: float) -> bool:
        """True if the points at ``point_m`` on ``tr``'s route are points where another track joins it."""
        joins = self.joins_of.get(tr.train_id, frozenset())
        return any(rs.switch_id in joins and abs(rs.point_m - point_m) < 1e-6 for rs in tr.trip.route.switches)

    def _room_m(self, end_m: float, guard_m: float) -> float:
        """Room for a train to stand between what ends at ``end_m`` and a resource protected at ``guard_m``: its
        rear ``clearance_m`` past the first, its front the overlap before the second."""
        return (guard_m - self.settings.protection_margin_m) - (end_m + self.settings.clearance_m)

    def _wait_point_m(self, tr: TrainRuntime, after_m: float, nxt: RouteSection) -> float:
        """Where ``tr``, waiting for ``nxt`` beyond ``after_m``, stops short (its protection point): that of
        ``nxt``, or of the flat crossing right before it with no room for the train between, which it asks for only
        once ``nxt`` is its own — back over every such crossing after ``after_m``. Counting the room up to
        ``nxt``'s own protection point, a tram was granted the section before Platz der Einheit/West alone while
        the room before crossing ``1137879547`` held only the tram already waiting there: it stood in the section,
        and the tram beyond waited for an opposing tram stuck behind it (every 720 s: deadlock at 1,116 s)."""
        mine = self.sections.get(tr.train_id, [])
        point_m = nxt.guard_m
        if nxt not in mine:
            return point_m  # one it leaves by another way at its protection points (note_passes)
        k = mine.index(nxt)
        while k > 0 and mine[k - 1].start_m >= after_m and mine[k - 1].section_id.startswith("crossing:"):
            if self._room_m(mine[k - 1].end_m, point_m) >= tr.trip.vehicle.length_m:
                break
            k -= 1
            point_m = mine[k].guard_m
        return point_m

    def _stand_room_m(self, tr: TrainRuntime, after_m: float, nxt: RouteSection) -> float:
        """Room for ``tr`` between ``after_m`` (its rear ``clearance_m`` past it) and where the first train waiting
        for ``nxt`` stands: the overlap before the point it waits at (:meth:`_wait_point_m`), or the stopping mark
        of a platform on the way from which the authority there would not let it draw clear (its length plus its
        separation margin, at least the overlap): it stays at that platform after its dwell
        (:meth:`~railsim.engine.locking.RouteLocks.clears_platform`). Counting the room up to the overlap, two trams
        were granted the section before Platz der Einheit/West, where the first stayed at its platform 53 m short of
        that, and the second stood in the section (every 720 s)."""
        front_m = self._wait_point_m(tr, after_m, nxt) - self.settings.protection_margin_m
        draw_m = tr.trip.vehicle.length_m + max(self.settings.protection_margin_m, separation_margin_m(tr))
        for stop in tr.trip.stops:
            if after_m < stop.mark_m <= front_m and stop.kind == "station" and front_m < stop.mark_m + draw_m:
                front_m = stop.mark_m
                break
        return front_m - (after_m + self.settings.clearance_m)

    def _other_way_clear(self, tr: TrainRuntime, sec: RouteSection, nxt: RouteSection) -> bool:
        """True if the track between ``sec`` and ``nxt`` cannot hold ``tr`` clear of ``sec`` even alone, while
        every train running the other way from ``nxt``'s section straight into ``sec``'s can wait there clear of
        ``nxt``'s (:meth:`_other_way_fits`). A train granted ``sec`` alone then waits there holding it, but no
        opposing train holding ``nxt`` waits for it there: each is granted ``nxt`` alone only while that track
        holds it, and lets it go there. The track is a passing place for ``tr`` all the same
        (:meth:`~railsim.engine.section_requests.SectionRequests._run_from`). A tram standing at Jena's Löbstedt
        towards Lobeda has its rear 6 m past the end of the single track from Zwätzen, 4 m short of
        ``clearance_m``; asking for both sections, the unit turning at Zwätzen Schleife held the one beyond
        Löbstedt from its arrival to its departure 343 s later, and the opposing tram waited 248 s for it."""
        if sec.direction >= OWN_DIRECTION or nxt.direction >= OWN_DIRECTION:
            return False
        if self._stand_room_m(tr, sec.end_m, nxt) >= tr.trip.vehicle.length_m:
            return False  # it fits there alone: the room beside the other trains of its way decides
        key = (sec.section_id, sec.direction, nxt.section_id, nxt.direction)
        clear = self.other_way_clear.get(key)
        if clear is None:
            clear = self.other_way_clear[key] = self._other_way_fits(sec, nxt)
        return clear

    def _other_way_fits(self, sec: RouteSection, nxt: RouteSection) -> bool:
        """True if some train runs the other way through ``nxt``'s section, and each such train runs on from it
        into ``sec``'s with no other single-track section between (it ends nowhere between the two, nor leaves that
        track by another section) and, alone on the track between the two, stands clear of ``nxt``'s (its rear
        ``clearance_m`` past it) where it waits for ``sec``'s (:meth:`_stand_room_m`). Only then does every train
        of the other way standing there count in the room its followers ask for ``nxt``'s section alone against
        (:meth:`~railsim.engine.section_requests.SectionRequests._waiting_between`): a train whose trip ended on a
        short loop track stood in the section behind it, behind a train waiting on the loop for the section the
        train across, not clear of it, held (``tests/sumo/test_single_track.py``)."""
        found = False
        for other_id, theirs in self.sections.items():
            track = [s for s in theirs if s.section_id.startswith("track:")]
            for k, came in enumerate(track):
                if came.section_id != nxt.section_id or came.direction == nxt.direction:
                    continue
                then = track[k + 1] if k + 1 < len(track) else None
                if then is None or then.section_id != sec.section_id or then.direction == sec.direction:
                    return False  # it ends between the two, leaves that track for another section, or turns
                if came.direction >= OWN_DIRECTION or then.direction >= OWN_DIRECTION:
                    return False  # it reverses there: it holds both alone
                other = self.fleet.trains[other_id]
                if self._stand_room_m(other, came.end_m, then) < other.trip.vehicle.length_m:
                    return False
                found = True
        return found

    def _trains_in_front(self, ahead_id: str, sec: RouteSection) -> Iterator[str]:
        """``ahead_id`` (the train in front) and the trains in front of it in turn (``TrackSections.in_front``, as
        the train side last saw them), as long as each is bound through ``sec``'s section the way ``sec`` runs and
        short of its end: the train behind them all passes through only after each of them. A tram from the
        Bildungsforum, not asking yet (its platform to serve first), stood between the tram granted both sections
        and one from the same branch waiting for the second (every 720 s: deadlock at 1,580 s)."""
        assert self.tracks is not None
        seen = set()
        front_id: str | None = ahead_id
        while front_id is not None and front_id not in seen:
            if not self._bound_through(front_id, sec):
                return
            yield front_id
            seen.add(front_id)
            front_id = self.tracks.in_front.get(front_id)

    def _bound_through(self, train_id: str, sec: RouteSection) -> bool:
        """True if ``train_id`` runs through ``sec``'s section the way ``sec`` runs and is short of its end."""
        tr = self.fleet.trains.get(train_id)
        return tr is not None and any(
            s.section_id == sec.section_id and s.direction == sec.direction and s.end_m > tr.front_m
            for s in self.sections.get(train_id, ())
        )

    def _points_taken_beyond(self, tr: TrainRuntime, sec: RouteSection) -> bool:
        """True if points on ``tr``'s route from the start of the crossing ``sec`` to where its front stands once
        its rear is clear of it (plus its separation margin) are locked for, or asked for by, another train, or may
        not be taken yet (:meth:`_joins_full_room`). A tram from Platz der Einheit/Nord was granted crossing
        ``1137879547`` while a tram from Dortustraße held merge ``30566579`` right beyond it: that tram went in
        front of it and stopped at the platform, and the tram stood in the crossing, which the tram waiting for it
        held the next section for (every 720 s and every 1,200 s)."""
        reach_m = sec.end_m + self.settings.clearance_m + tr.trip.vehicle.length_m + separation_margin_m(tr)
        joins = self.joins_of.get(tr.train_id, frozenset())
        for rs in tr.trip.route.switches:
            if rs.switch_id not in joins or not sec.start_m <= rs.point_m <= reach_m:
                continue
            holder = self.interlocking.holder(rs.switch_id)
            if holder is not None and tr.train_id not in holder:
                return True
            if any(tr.train_id not in q.holder_ids for q in self.interlocking.queue(rs.switch_id)):
                return True
            if self._joins_full_room(tr, rs.point_m):
                return True
        return False

    def _joins_full_room(self, tr: TrainRuntime, point_m: float) -> bool:
        """True if the points at ``point_m`` let ``tr`` in from a branch (it holds no single-track section ending
        at or before them) onto the track before its next section, not yet its own, and that track, from the points
        to where a train waiting for the section stops, cannot hold it beside the trains bound to wait there
        (:meth:`_bound_for_room`). A tram from Dortustraße took merge ``30566579`` in front of a tram that had been
        granted the section beyond Brandenburger Straße alone, which then stood in it (every 720 s).

        The section is the train's next one, or one it leaves by another way at its protection points
        (:meth:`note_passes`), whichever comes first after the points; and so must it beyond the points of that kind
        right after these, too close for the train to wait between (:meth:`_joins_from`): a tram from Platz der
        Einheit/Nord took points ``1137879547`` on the room from them, 18.5 m before merge ``30566579``, for which the
        room was too short, and stood on them, shutting in the tram that needed them (every 700 s)."""
        if not self._joins_at(tr, point_m):
            return False
        mine = self.sections.get(tr.train_id, [])
        reqs = self.section_requests.get(tr.train_id, {})
        nxt = next((s for s in mine if s.section_id.startswith("track:") and s.guard_m > point_m), None)
        req = reqs.get(nxt.section_id) if nxt is not None else None
        if nxt is not None and req is not None and req.granted and not self._stale(tr, req, nxt):
            nxt = None
        passed = next((s for s in self.passes_by.get(tr.train_id, ()) if s.guard_m > point_m), None)
        targets = [s for s in (nxt, passed) if s is not None]
        if not targets:
            return False
        for s in mine:
            held = reqs.get(s.section_id)
            if (
                s.section_id.startswith("track:")
                and s.end_m <= point_m
                and held is not None
                and held.granted
                and tr.train_id not in held.released_by
            ):
                return False  # it comes through a section into this track: its room was counted when it asked
        return any(self._full_for(tr, p_m, target) for target in targets for p_m in self._joins_from(tr, point_m))

    def _joins_from(self, tr: TrainRuntime, point_m: float) -> list[float]:
        """``point_m`` and the points after it where another track joins ``tr``'s route, as long as each lies too
        close behind the one before for the train to wait between them: its front the overlap before the later
        one, its rear ``clearance_m`` past the earlier one."""
        joins = self.joins_of.get(tr.train_id, frozenset())
        later = sorted({rs.point_m for rs in tr.trip.route.switches if rs.switch_id in joins and rs.point_m > point_m})
        need_m = tr.trip.vehicle.length_m + self.settings.protection_margin_m + self.settings.clearance_m
        out = [point_m]
        for p_m in later:
            if p_m - out[-1] >= need_m:
                break
            out.append(p_m)
        return out

    def _full_for(self, tr: TrainRuntime, point_m: float, nxt: RouteSection) -> bool:
        """True if the track from ``point_m`` to where trains waiting for ``nxt`` stop cannot hold ``tr`` beside
        the trains bound to wait there (:meth:`_bound_for_room`)."""
        gap_m = nxt.guard_m - point_m
        room_m = self._stand_room_m(tr, point_m, nxt)
        for other in self._bound_for_room(tr, nxt, gap_m):
            room_m -= other.trip.vehicle.length_m + separation_margin_m(other)
        return room_m < tr.trip.vehicle.length_m

    def _bound_short_of(
        self, tr: TrainRuntime, nxt: RouteSection, also: frozenset[str] | set[str]
    ) -> Iterator[tuple[TrainRuntime, list[RouteSection], RouteSection]]:
        """The trains other than ``tr``, on the line or named in ``also``, whose routes run through ``nxt``'s section
        the way ``tr`` does, whose fronts are not past its protection point and that are neither granted it nor run
        on through it: each with its route's sections and its pass of ``nxt``'s."""
        for other_id in [*self.sections, *(k for k in self.passes_by if k not in self.sections)]:
            other = self.fleet.trains[other_id]
            if other_id == tr.train_id or not (other.on_line or other_id in also):
                continue
            theirs = self.sections.get(other_id, [])
            there = next((s for s in theirs if s.section_id == nxt.section_id and s.direction == nxt.direction), None)
            if there is None:  # or it leaves by another way at nxt's protection points, still before them
                there = next(
                    (
                        s
                        for s in self.passes_by.get(other_id, ())
                        if s.section_id == nxt.section_id
                        and s.direction == nxt.direction
                        and s.guard_m >= other.front_m
                    ),
                    None,
                )
            if there is None or other.front_m > there.guard_m:
                continue
            on = self.section_requests.get(other_id, {}).get(nxt.section_id)
            if on is not None and (on.granted or other_id in on.released_by):
                continue  # it runs on through nxt
            yield other, theirs, there

    def _bound_for_room(self, tr: TrainRuntime, nxt: RouteSection, gap_m: float) -> list[TrainRuntime]:
        """The trains other than ``tr`` bound through ``nxt``'s section the way ``tr`` runs through it, not granted
        it, that stand within ``gap_m`` before its protection point with every points up to it set for them (in the
        track before it, not waiting at a branch's points), have the points set onto that track from a branch
        (:meth:`_joining`), or hold a section ending so close before that track that they cannot wait between the
        two. Within ``gap_m`` up to the overlap more: the legs of a junction differ by a few metres (a tram 0.1 m past
        merge ``30566579`` on its way to Platz der Einheit/West was 137.5 m short of the point in its route, 2.4 m more
        than the tram joining there behind it was; left out, the tram joining filled the track)."""
        assert self.tracks is not None
        out = []
        near_m = gap_m + self.settings.protection_margin_m
        for other, theirs, there in self._bound_short_of(tr, nxt, frozenset()):
            other_id = other.train_id
            reqs = self.section_requests.get(other_id, {})
            standing = there.guard_m - other.front_m <= near_m and self._points_set(other, there.guard_m)
            if standing or self._joining(other, there.guard_m, gap_m):
                out.append(other)
                continue
            reach_m = gap_m + other.trip.vehicle.length_m + self.settings.clearance_m + separation_margin_m(other)
            for s in theirs:
                held = reqs.get(s.section_id)
                if (
                    s.section_id.startswith("track:")
                    and there.guard_m - reach_m <= s.end_m <= there.guard_m
                    and held is not None
                    and held.granted
                    and other_id not in held.released_by
                ):
                    out.append(other)
                    break
        return out

    def _joining(self, tr: TrainRuntime, guard_m: float, gap_m: float) -> bool:
        """True if ``tr`` has the points from its branch onto the track within ``gap_m`` before ``guard_m`` (a
        section's protection point) set or asked for: points there lie ahead of it, and every points up to
        ``guard_m`` are locked for it or asked for by it. It comes into that track before any train the points are
        not set for. A tram from Dortustraße, standing 15 m short of merge ``30566579`` with the points set for it,
        was left out of the room between the two sections around Platz der Einheit/West, and the tram granted the
        first of them alone stood in it (every 720 s). Points asked for count as set: it took them on the room it
        found when it asked (:meth:`_joins_full_room`), and while they were thrown (6 s) two trams were granted the
        section before that track on a room that left it out; the three filled it, the last stood in the section
        (all lines every 720 s: deadlock at 4,222 s)."""
        reach_m = gap_m + self.settings.protection_margin_m  # the legs of a junction differ by a few metres
        points = self.joins_of.get(tr.train_id, frozenset())
        joins = any(
            rs.switch_id in points and tr.front_m < rs.point_m < guard_m and guard_m - rs.point_m <= reach_m
            for rs in tr.trip.route.switches
        )
        return joins and self._points_set(tr, guard_m, asked=True)

    def _points_set(self, tr: TrainRuntime, until_m: float, asked: bool = False) -> bool:
        """True if every points on ``tr``'s route between its front and ``until_m`` are locked for it (``asked``: or
        asked for by it, being thrown or queued)."""
        for rs in tr.trip.route.switches:
            if tr.front_m < rs.point_m < until_m:
                req = tr.locks.get(rs.switch_id)
                if req is None or rs.switch_id in tr.released or not (asked or self.interlocking.is_granted(req)):
                    return False
        return True
