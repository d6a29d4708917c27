"""The walk over a route's switches: which of them the route locks' bookkeeping visits in a step.

Each step :meth:`railsim.engine.locking.RouteLocks.bookkeeping` goes over the switches of a train's route in route
order (``RouteLocks._visit_switch``: ask anew, give up, request, note the first switch waited for, detect a pass
without the lock, release). Most of them can do nothing in a given step: a switch far ahead is not asked
for yet, and a switch behind is done with. So the walk visits only those that can, and decides exactly as the
walk over all of them (``walk_every_switch``, the reference its test holds it to). Per train it keeps a
**cursor** (:class:`SwitchWalk`), forward only: every switch behind it is *dormant*
(:meth:`SwitchWalker._dormant`: its lock is for a later time over these points, or this time is done; or for an
earlier time not yet released; or, never asked for, the point lies behind where the train came on the line)
or **tracked**. Tracked are the switches whose points the train holds or waits for, wherever they lie (a
follower's lock, asked for by its leader, may lie beyond its own request distance), and those behind the
cursor that still can do something (points passed without being asked for are asked for again every step, as
the full walk does). A step visits the tracked switches and those from the cursor to the request distance
ahead; when a release frees points the route passes again, the next time over them joins the same walk (it
asks anew at once). Dormancy lasts: the record of which time over a switch its lock is for only moves on, and
the train's ``released`` loses a switch only when a later time asks anew. What can end it from outside the walk
is looked for at the start of each step: locks added by a leader or an extension (the train's lock ids against
those after its last walk), a release made elsewhere, a new route or a new place the train came on the line (the
walk begins afresh and visits every switch once). A step with nothing tracked, nothing within the request
distance and no lock added returns at once: most steps of most trains. Where the train came on the line (the
start limit, :func:`start_limit_of`) is remembered with what it is worked out from (the trip's stops and vehicle,
both immutable, by identity; its start offset; the train's start front: :meth:`SwitchWalk.remember_start_inputs`).

**One switch in reach.** Most other steps visit one switch: the one at the cursor, ahead of the front, the only
one within the request distance, and tracked if the train holds or waits for it (a train coming in to the
platform before the points, which it asks for only when about to leave: :func:`~railsim.engine.stop_timing.
stop_before`). :meth:`SwitchWalker._single_switch` finds it without :meth:`SwitchWalker._walk_candidates`; and if
the visit changed none of the train's locks and released nothing, settling would leave the walk as it stands (the
cursor stays — the point lies beyond the front and the switch is not dormant: what that depends on did not change
— and the switch stays tracked or not as it was), so :meth:`SwitchWalker._still_settled` skips it.

**Approaching points held.** The other common step: the train holds (or waits for) the points at the cursor, its
front short of them, and nothing else lies within the request distance. The walk would visit those points alone
and do nothing — the request is made, the front has not passed the point (no pass without the lock, no release),
and the cursor stays — unless the train gives them up to the train in front. So
:meth:`SwitchWalker._approaching_held` checks exactly that and the step returns.

:class:`SwitchWalker` is the part of :class:`railsim.engine.locking.RouteLocks` that keeps the walks (a base
class of it, as :class:`~railsim.engine.section_requests.SectionRequests` is): the route locks visit the switches
it names and it moves the walk on after them.
"""

from __future__ import annotations

from bisect import bisect_right
from typing import Any

from mypy_extensions import trait

from railsim.engine.settings import INF, EngineSettings
from railsim.engine.train import TrainRuntime

WINDOW_SLACK_M = 1.0  # the walk's window reaches this far past the request distance (rounding never cuts it)


class RouteSwitches:
    """One route's switches, looked up for the walk (:meth:`SwitchWalker._walk_candidates`): their points and ids,
    the first point of each switch (a lock's time over its points, without a record), the index of each time
    over a switch, and the next time over the same points."""

    __slots__ = ("first_i", "first_m", "ids", "index_at", "next_same", "points_m", "switches", "walkable")

    def __init__(self, switches: Any) -> None:
        self.switches = switches
        self.ids: tuple[str, ...] = tuple(rs.switch_id for rs in switches)
        self.points_m: tuple[float, ...] = tuple(rs.point_m for rs in switches)
        self.first_m: dict[str, float] = {}
        self.first_i: dict[str, int] = {}
        self.index_at: dict[tuple[str, float], int] = {}
        next_same = [-1] * len(self.ids)
        last: dict[str, int] = {}
        for i, (sid, point_m) in enumerate(zip(self.ids, self.points_m)):
            self.first_m.setdefault(sid, point_m)
            self.first_i.setdefault(sid, i)
            self.index_at.setdefault((sid, point_m), i)
            if sid in last:
                next_same[last[sid]] = i
            last[sid] = i
        self.next_same: tuple[int, ...] = tuple(next_same)
        # the window is found by bisection, and a time over the points by its point: chainage order, no point twice
        self.walkable = len(self.index_at) == len(self.ids) and all(
            a <= b for a, b in zip(self.points_m, self.points_m[1:])
        )


class SwitchWalk:
    """Where one train's walk over its route's switches stands (:meth:`SwitchWalker._settle_walk`): every switch
    before ``cursor`` not in ``tracked`` is dormant (:meth:`SwitchWalker._dormant`), and ``tracked`` holds every
    switch whose points the train holds or waits for."""

    __slots__ = (
        "cursor",
        "index",
        "lock_ids",
        "n_released",
        "next_m",
        "start_front_m",
        "start_limit_m",
        "start_offset_m",
        "stops",
        "tracked",
        "vehicle",
    )

    def __init__(self, index: RouteSwitches, start_limit_m: float) -> None:
        self.index = index
        self.start_limit_m = start_limit_m  # switches before it (not asked for) are not the train's business
        # what start_limit_m was worked out from (remember_start_inputs): the trip's stops and vehicle (by
        # identity: both immutable), its start offset and the train's start front; None: nothing remembered
        self.stops: Any = None
        self.vehicle: Any = None
        self.start_offset_m = 0.0
        self.start_front_m = 0.0
        self.cursor = 0
        self.next_m = -INF  # the point of the switch at the cursor
        self.tracked: list[int] = []
        self.lock_ids: set[str] = set()  # the train's locks after the last walk
        self.n_released = -1  # len(tr.released) after the last walk: a release made elsewhere begins it afresh

    def remember_start_inputs(self, trip: Any, start_front_m: float) -> None:
        """Note what :attr:`start_limit_m` was worked out from (:func:`start_limit_of` of ``trip`` and
        ``start_front_m``). It reads nothing but the stops (a tuple of frozen stops), the vehicle's length (a
        frozen vehicle), the start offset and the start front: while all four are these (the stops and the vehicle
        the same objects), it is :attr:`start_limit_m` for certain (``RouteLocks.bookkeeping`` compares them)."""
        self.stops, self.vehicle = trip.stops, trip.vehicle
        self.start_offset_m, self.start_front_m = trip.start_offset_m, start_front_m


def start_limit_of(trip: Any, start_front_m: float) -> float:
    """Where the switches that are ``trip``'s business begin: the rear of the train where it came on the line
    (its origin's departure point; a unit whose next trip comes on the line before its origin platform, starting
    with its turnback: where its front was then). Points before it, never asked for, are not its business."""
    start_m = trip.depart_chainage_m if trip.stops[0].kind == "station" else start_front_m
    return start_m - trip.vehicle.length_m


@trait  # a part of RouteLocks (railsim.engine.locking), compiled as a mypyc trait (railsim/native.py)
class SwitchWalker:
    """The walks of every train (module docstring); :class:`~railsim.engine.locking.RouteLocks` provides the
    settings, the record of which time over a switch each lock is for, and its reading (``_lock_pass_m``)."""

    settings: EngineSettings
    fleet: Any  # the fleet (its trains by id)
    _lock_pass: dict[str, dict[str, float]]  # train id -> switch id -> the point its lock is for
    _indexes: dict[int, RouteSwitches]  # id(route's switches) -> their look-ups
    _walks: dict[str, SwitchWalk]  # train id -> where its walk over its route's switches stands
    walk_every_switch: bool  # True: bookkeeping visits every switch of the route every step (the reference)

    def _lock_pass_m(self, tr: TrainRuntime, switch_id: str) -> float:
        raise NotImplementedError  # RouteLocks'

    def _gives_way(self, tr: TrainRuntime, front: TrainRuntime, ahead: Any, rs: Any) -> bool:
        raise NotImplementedError  # RouteLocks'

    def _route_index(self, switches: Any) -> RouteSwitches:
        """The look-ups of one route's switches (made once per route, shared by the trips on it)."""
        index = self._indexes.get(id(switches))
        if index is None or index.switches is not switches or len(index.ids) != len(switches):
            index = RouteSwitches(switches)
            self._indexes[id(switches)] = index
        return index

    def _begin_walk(self, tr: TrainRuntime, switches: Any, start_limit_m: float) -> SwitchWalk | None:
        """A fresh walk for ``tr`` over ``switches`` (the first step, a new route or start, or a release made
        outside the walk); its first step visits every switch. None: every step does (a route whose switches are
        not in chainage order, or pass the same points twice at one chainage; or :attr:`walk_every_switch`)."""
        index = self._route_index(switches)
        if self.walk_every_switch or not index.walkable:
            self._walks.pop(tr.train_id, None)
            return None
        walk = self._walks[tr.train_id] = SwitchWalk(index, start_limit_m)
        return walk

    def _walk_candidates(self, tr: TrainRuntime, walk: SwitchWalk) -> list[int]:
        """The switches (indices into the route's) :meth:`bookkeeping` visits this step, in route order: those
        tracked (held or waited for, or lagging behind the cursor), those from the cursor to the end of the request
        distance, and, if the train's locks changed outside its walk (a follower's, asked for by its leader, may
        lie beyond its own request distance), the one time over each of the points it holds or waits for. Every
        switch left out is one :meth:`_visit_switch` does nothing for (module docstring, "The walk")."""
        index = walk.index
        out = set(walk.tracked)
        reach_m = tr.front_m + self.settings.lock_request_distance_m + WINDOW_SLACK_M
        if reach_m >= walk.next_m:
            out.update(range(walk.cursor, bisect_right(index.points_m, reach_m)))
        if tr.locks.keys() != walk.lock_ids:
            record = self._lock_pass.get(tr.train_id, {})
            for sid in tr.locks.keys() - tr.released:
                known = record.get(sid)
                i = index.first_i.get(sid) if known is None else index.index_at.get((sid, known))
                if i is not None:
                    out.add(i)
        return sorted(out)

    def _settle_walk(self, tr: TrainRuntime, walk: SwitchWalk, visited: Any) -> None:
        """After the walk: move the cursor past the switches behind the front and those that can do nothing more,
        and track every switch that still can behind it, or whose points the train holds or waits for, or whose
        next time over them is still to ask anew."""
        index = walk.index
        points_m = index.points_m
        cursor = walk.cursor
        n = len(points_m)
        seen = set(walk.tracked)
        seen.update(visited)
        while cursor < n and (points_m[cursor] <= tr.front_m or self._dormant(tr, walk, cursor)):
            seen.add(cursor)
            cursor += 1
        locks, released = tr.locks, tr.released
        walk.tracked = [
            i
            for i in sorted(seen)
            if not self._dormant(tr, walk, i) and (i < cursor or index.ids[i] in locks or index.ids[i] in released)
        ]
        walk.cursor = cursor
        walk.next_m = points_m[cursor] if cursor < n else INF
        walk.n_released = len(released)
        if locks.keys() != walk.lock_ids:
            walk.lock_ids = set(locks)

    def _approaching_held(self, tr: TrainRuntime, walk: SwitchWalk, ahead: Any) -> bool:
        """True if the walk of this step would visit only the switch at the cursor and do nothing there, nor move
        the walk on (module docstring, "Approaching points held"): the train's locks are those of its last walk,
        the only switch tracked is the one at the cursor and no other lies within the request distance; the train
        holds or waits for those points on this time over them, has not released them, its front is short of the
        point (no pass without the lock, no release, the cursor stays) and it does not give them up to the train
        in front (``ahead``)."""
        i = walk.cursor
        tracked = walk.tracked
        if len(tracked) != 1 or tracked[0] != i or tr.locks.keys() != walk.lock_ids:
            return False
        index = walk.index
        points_m = index.points_m
        point_m = points_m[i]
        if not tr.front_m < point_m:
            return False
        reach_m = tr.front_m + self.settings.lock_request_distance_m + WINDOW_SLACK_M  # as _walk_candidates'
        if i + 1 < len(points_m) and points_m[i + 1] <= reach_m:
            return False
        sid = index.ids[i]
        if sid not in tr.locks or sid in tr.released or self._lock_pass_m(tr, sid) != point_m:
            return False
        if ahead is None:
            return True
        behind = self.fleet.trains.get(ahead.train_id)
        return behind is None or not self._gives_way(tr, behind, ahead, index.switches[i])

    def _single_switch(self, tr: TrainRuntime, walk: SwitchWalk) -> int:
        """The switch at the cursor if it is the only one :meth:`_walk_candidates` would give and its visit may
        leave the walk as it stands (module docstring, "One switch in reach"), else -1: the train's locks are those
        of its last walk, nothing is tracked but that switch, no other lies within the request distance, the
        front is short of its point, the train has not released it and any lock it holds on it is for this time
        over the points."""
        i = walk.cursor
        tracked = walk.tracked
        if len(tracked) > 1 or (tracked and tracked[0] != i) or tr.locks.keys() != walk.lock_ids:
            return -1
        points_m = walk.index.points_m
        if i >= len(points_m) or not tr.front_m < points_m[i]:
            return -1
        reach_m = tr.front_m + self.settings.lock_request_distance_m + WINDOW_SLACK_M  # as _walk_candidates'
        if (i + 1 < len(points_m) and points_m[i + 1] <= reach_m) or (not tracked and points_m[i] > reach_m):
            return -1
        sid = walk.index.ids[i]
        if sid in tr.released or self._lock_pass_m(tr, sid) != points_m[i]:
            return -1
        return i

    def _still_settled(self, tr: TrainRuntime, walk: SwitchWalk, i: int) -> bool:
        """True if, after a step that visited switch ``i`` alone (:meth:`_single_switch`), :meth:`_settle_walk`
        would leave the walk as it is: the visit changed none of the train's locks and released nothing (module
        docstring, "One switch in reach")."""
        return (
            i == walk.cursor
            and tr.locks.keys() == walk.lock_ids
            and len(tr.released) == walk.n_released
            and walk.index.ids[i] not in tr.released
            and tr.front_m < walk.next_m
        )

    def _dormant(self, tr: TrainRuntime, walk: SwitchWalk, i: int) -> bool:
        """True if :meth:`_visit_switch` does nothing for switch ``i`` until the walk itself changes that, or its
        train comes to hold or wait for the points (then :meth:`_walk_candidates` picks it up): the lock is for a
        later time over these points, or this time is done (for good: the record only moves on, and ``released``
        loses the points only when a later time asks anew); the lock is for an earlier time, not released (the
        walk adds this one when it releases that); or, not asked for, it lies behind where the train came on the
        line."""
        index = walk.index
        sid, point_m = index.ids[i], index.points_m[i]
        pass_m = self._lock_pass_m(tr, sid)
        if pass_m != point_m:
            return pass_m > point_m or sid not in tr.released
        return sid in tr.released or (sid not in tr.locks and point_m < walk.start_limit_m)
