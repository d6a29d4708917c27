"""Where a train's movement authority ends, worked out again only when something it depends on has changed.

The control stage asks every step, for every train, where its authority ends
(:meth:`AuthorityEnds.authority_end_m`): before the first switch on its route not locked for it, before the first
single-track section or flat crossing not reserved for it, the overlap short of a train facing it, at the end of its
route — each carried on to a station stop within the overlap (:meth:`AuthorityEnds._reach_stop`). Worked out afresh,
that is a walk over the train's sections and its route's switches ahead and a look at its next stops, every step.
Most steps nothing it depends on has changed, so the answer is **remembered** per train (:class:`AuthorityMemo`)
together with everything it was worked out from, and given again while all of that is the same:

- the train's trip stops, route switches and contested sections (the objects: a turnback replaces them), its next
  stop, whether SUMO holds it at a stop, its ATO (its margins), and where the train facing it begins;
- the **versions** of the train's lock and section states: :meth:`~railsim.engine.events.interlocking.Interlocking.version`
  moves on whenever a lock the train is one of the holders of is granted, released or freed, and
  :meth:`~railsim.engine.events.tracks.TrackSections.version` whenever a section request of the train is made,
  granted, widened, handed over or released; the route locks move :attr:`AuthorityEnds._lock_state` on whenever
  they change which switches the train is done with (``released``) or which time over the points its lock is for;
- and where its front is. The answer depends on the front only through comparisons with fixed points (a switch
  point ahead or behind it, a section's end and protection point, a stop's window end), so each working-out also
  records the **interval** of front positions over which every one of those comparisons comes out the same; the
  answer holds while the front stays inside it. The comparisons with switch points and protection points are made
  on ``front_m - 1e-6`` (as the walk makes them), the others on the front itself, so the memo keeps an interval for
  each and compares exactly as the working-out does. A train standing inside a section it does not hold has its
  authority at its front: that answer holds only while the front stays exactly where it is.

One input is asked anew each time: whether an extension manages the switch the authority ends before, when that
switch is a merge for the train (the margin before it depends on it, and the junction planner changes it), as the
full working-out asks it; a changed answer moves the end before that same switch.

The answer is exactly the one worked out afresh, every step (``tests/unit/test_authority_memo.py`` holds it to the
former working-out over random worlds, step by step); ``remember_authority = False`` works it out every time.
"""

from __future__ import annotations

import logging
from bisect import bisect_right
from math import inf, nextafter
from typing import Any

from mypy_extensions import trait

from railsim.engine.events.interlocking import Interlocking
from railsim.engine.events.log import EventLog
from railsim.engine.events.tracks import SectionRequest, TrackSections
from railsim.engine.lock_walk import RouteSwitches
from railsim.engine.settings import EngineSettings
from railsim.engine.single_track import RouteSection
from railsim.engine.stop_timing import STOP_OVERRUN_ALLOWANCE_M, stop_aim_m
from railsim.engine.train import TrainRuntime

log = logging.getLogger("railsim.engine.locking")  # the route locks speak under one name

BEHIND_TOLERANCE_M = 1e-6  # a point this close ahead of the front counts as behind it (the walk's comparison)


class AuthorityMemo:
    """One train's remembered authority end and what it was worked out from (module docstring): the objects and
    values it read, the versions of its lock and section states, the front interval ``[lo_m, hi_m)`` and the
    interval ``[lo_behind_m, hi_behind_m)`` of ``front_m - 1e-6`` over which it holds, and the merge switch the
    authority ends before, if any (its point, the margin used before it, and the end the rest of the route gave)."""

    __slots__ = (
        "ato",
        "before_merge_m",
        "end_m",
        "facing_m",
        "hi_behind_m",
        "hi_m",
        "lo_behind_m",
        "lo_m",
        "lock_state",
        "locks_version",
        "merge_id",
        "merge_margin_m",
        "merge_point_m",
        "next_stop",
        "sections",
        "sections_version",
        "stopped",
        "stops",
        "switches",
    )

    def __init__(self) -> None:
        self.lo_m = -inf
        self.hi_m = inf
        self.lo_behind_m = -inf
        self.hi_behind_m = inf
        self.merge_id: str | None = None
        self.merge_margin_m = 0.0
        self.merge_point_m = inf
        self.before_merge_m = inf  # the end before the merge switch is counted
        self.end_m = inf
        self.stops: Any = None
        self.switches: Any = None
        self.sections: Any = None
        self.ato: Any = None
        self.facing_m: float | None = None
        self.next_stop = -1
        self.stopped = False
        self.locks_version = -1
        self.sections_version = -1
        self.lock_state = -1


@trait  # a part of RouteLocks (railsim.engine.locking), compiled as a mypyc trait (railsim/native.py)
class AuthorityEnds:
    """The authority ends of every train (module docstring): a base class of
    :class:`~railsim.engine.locking.RouteLocks`, which provides the state they are worked out from."""

    settings: EngineSettings
    interlocking: Interlocking
    tracks: TrackSections | None
    events: EventLog
    clock: Any
    sections: dict[str, list[RouteSection]]
    section_requests: dict[str, dict[str, SectionRequest]]
    merges_of: dict[str, frozenset[str]]
    facing_m: dict[str, float]
    _route_end: dict[str, tuple[Any, float]]
    _short_of_resource: set[tuple[str, str, float]]
    _memos: dict[str, AuthorityMemo]  # train id -> its remembered authority end
    _lock_state: dict[str, int]  # train id -> version of its released switches and lock records
    remember_authority: bool  # False: worked out afresh at every call

    def _route_index(self, switches: Any) -> RouteSwitches:
        raise NotImplementedError  # the walk's

    def _lock_pass_m(self, tr: TrainRuntime, switch_id: str) -> float:
        raise NotImplementedError  # RouteLocks'

    def _margin_m(self, train_id: str, switch_id: str) -> float:
        raise NotImplementedError  # RouteLocks'

    def _lock_state_changed(self, train_id: str) -> None:
        """The route locks changed which switches ``train_id`` is done with, or which time over points its lock
        is for: its remembered authority end is worked out again."""
        self._lock_state[train_id] = self._lock_state.get(train_id, 0) + 1

    def authority_end_m(self, tr: TrainRuntime) -> float:
        """Route chainage where the train's movement authority ends: before the first switch not locked for it,
        or the protection point of the first single-track section not reserved for it; a train standing inside a
        section it does not hold (a unit turning back in it, whose arrival direction another train still holds) may
        not move at all (its authority ends at its front), and no authority reaches closer than the overlap to a
        train on its track facing it (``facing_m``: ground truth, as a track circuit shows the track occupied; a
        unit turned back in a terminus stub is on the partner edges, never "ahead" of a train coming in). At the
        end of its trip the authority reaches the route's end, and at least the overlap beyond the destination
        platform (a platform ending within the overlap of the route's end would otherwise cut the train's stopping
        window short). Remembered while nothing it depends on changes (module docstring)."""
        tid = tr.train_id
        memo = self._memos.get(tid)
        front_m = tr.front_m
        behind_m = front_m - BEHIND_TOLERANCE_M
        if (
            memo is not None
            and self.remember_authority
            and memo.lo_m <= front_m < memo.hi_m
            and memo.lo_behind_m <= behind_m < memo.hi_behind_m
            and memo.stops is tr.trip.stops
            and memo.switches is tr.trip.route.switches
            and memo.next_stop == tr.next_stop
            and memo.stopped == tr.sumo_stopped
            and memo.facing_m == self.facing_m.get(tid)
            and (not memo.switches or memo.locks_version == self.interlocking.versions.get(tid, 0))
            and memo.lock_state == self._lock_state.get(tid, 0)
            and memo.sections is self.sections.get(tid)
            and (self.tracks is None or memo.sections_version == self.tracks.versions.get(tid, 0))
            and memo.ato is tr.controllers.get("ato")
        ):
            if memo.merge_id is not None:  # asked anew, as the full working-out does (module docstring)
                margin_m = self._margin_m(tid, memo.merge_id)
                if margin_m != memo.merge_margin_m:  # the same switch, another margin before it
                    memo.merge_margin_m = margin_m
                    point_m = memo.merge_point_m
                    memo.end_m = min(memo.before_merge_m, self._reach_stop(tr, point_m - margin_m, point_m, memo))
            return memo.end_m
        memo = AuthorityMemo()
        memo.stops = tr.trip.stops
        memo.switches = tr.trip.route.switches
        memo.next_stop = tr.next_stop
        memo.stopped = tr.sumo_stopped
        memo.facing_m = self.facing_m.get(tid)
        memo.locks_version = self.interlocking.version(tid) if memo.switches else -1  # no switches: no say
        memo.lock_state = self._lock_state.get(tid, 0)
        memo.sections = self.sections.get(tid)
        memo.sections_version = -1 if self.tracks is None else self.tracks.version(tid)
        memo.ato = tr.controllers.get("ato")
        memo.end_m = self._work_out(tr, memo)
        self._memos[tid] = memo
        return memo.end_m

    def _work_out(self, tr: TrainRuntime, memo: AuthorityMemo) -> float:
        """The authority end afresh (:meth:`authority_end_m`), narrowing ``memo``'s front intervals to those over
        which every comparison with the front made here comes out the same."""
        front_m = tr.front_m
        behind_m = front_m - BEHIND_TOLERANCE_M
        stops = tr.trip.stops  # (a turnback may replace them: the end is remembered per stops tuple)
        known = self._route_end.get(tr.train_id)
        if known is not None and known[0] is stops:
            end = known[1]
        else:
            end = max(tr.view.length_m - 1.0, stops[-1].window_end_m + self.settings.protection_margin_m)
            self._route_end[tr.train_id] = (stops, end)
        if tr.train_id in self.sections:
            reqs = self.section_requests[tr.train_id]
            for sec in self.sections[tr.train_id]:
                req = reqs.get(sec.section_id)
                if req is not None and req.granted:
                    continue
                if sec.end_m <= front_m:
                    memo.lo_m = max(memo.lo_m, sec.end_m)
                    continue
                memo.hi_m = min(memo.hi_m, sec.end_m)
                if sec.guard_m > behind_m:
                    memo.hi_behind_m = min(memo.hi_behind_m, sec.guard_m)
                    guard_end_m = sec.guard_m - self.settings.protection_margin_m
                    end = min(end, self._reach_stop(tr, guard_end_m, sec.guard_m, memo))
                else:  # inside a section it does not hold (a unit turning back in it): it may not move
                    memo.lo_m = max(memo.lo_m, front_m)  # the answer is the front: it holds only right there
                    memo.hi_m = min(memo.hi_m, nextafter(front_m, inf))
                    end = min(end, front_m)
                break
        facing_m = self.facing_m.get(tr.train_id)
        if facing_m is not None:  # never into track a train facing it stands or runs on
            end = min(end, self._reach_stop(tr, facing_m - self.settings.protection_margin_m, facing_m, memo))
        switches = tr.trip.route.switches
        index = self._route_index(switches)
        first = 0
        if index.walkable:  # those before the first point ahead lie behind
            first = bisect_right(index.points_m, behind_m)
            if first > 0:
                memo.lo_behind_m = max(memo.lo_behind_m, index.points_m[first - 1])
        for i in range(first, len(switches)):
            rs = switches[i]
            if rs.point_m <= behind_m:
                memo.lo_behind_m = max(memo.lo_behind_m, rs.point_m)
                continue
            if rs.switch_id in tr.released and self._lock_pass_m(tr, rs.switch_id) >= rs.point_m:
                continue
            if not self.interlocking.is_locked_for(tr.train_id, rs.switch_id, rs.leg):
                memo.hi_behind_m = min(memo.hi_behind_m, rs.point_m)
                margin_m = self._margin_m(tr.train_id, rs.switch_id)
                if rs.switch_id in self.merges_of.get(tr.train_id, ()):
                    memo.merge_id, memo.merge_margin_m, memo.merge_point_m = rs.switch_id, margin_m, rs.point_m
                    memo.before_merge_m = end
                return min(end, self._reach_stop(tr, rs.point_m - margin_m, rs.point_m, memo))
        return end

    def _reach_stop(self, tr: TrainRuntime, end_m: float, point_m: float, memo: AuthorityMemo | None = None) -> float:
        """The authority end ``end_m`` before a resource at ``point_m``, carried on to the train's next station
        stop when that stop's mark lies before the point but within the overlap (plus the margin the ATO keeps
        before its authority end): the train stops at its mark, not short of it (module docstring of
        :mod:`railsim.engine.locking`, "Stops within the overlap"). A train standing at its next stop runs to the
        stop after it: that one's mark is carried to, so the train can leave a platform for a next one within the
        overlap (two platforms of a station one behind the other before a merge: the resource is asked for only at
        the second). The ATO's aim stays :data:`STOP_OVERRUN_ALLOWANCE_M` before the point (:func:`stop_aim_m`); a
        stop with no such aim in its window waits for the resource there (``stop_needs_resource``, once per train,
        stop and point). ``memo``: narrowed to the fronts over which the stop's window end compares the same."""
        k = tr.next_stop
        stops = tr.trip.stops
        if tr.sumo_stopped and k + 1 < len(stops) and stops[k + 1].kind == "station":
            k += 1
        if k >= len(stops):
            return end_m
        stop = stops[k]
        if stop.kind != "station" or stop.mark_m >= point_m:
            return end_m
        past_m = nextafter(stop.window_end_m, inf)  # the first front past the window's end
        if tr.front_m > stop.window_end_m:
            if memo is not None:
                memo.lo_m = max(memo.lo_m, past_m)
            return end_m
        if memo is not None:
            memo.hi_m = min(memo.hi_m, past_m)
        params = getattr(tr.controllers.get("ato"), "params", None)
        margin_m = float(getattr(params, "authority_margin_m", 0.0))
        aim_m = stop_aim_m(tr, stop, point_m)
        if aim_m is None:  # served only with the resource: the train halts short of it and waits for it
            aim_m = point_m - STOP_OVERRUN_ALLOWANCE_M
            key = (tr.train_id, stop.station_id, point_m)
            if key not in self._short_of_resource:
                self._short_of_resource.add(key)
                self.events.record(
                    self.clock.now_s, "stop_needs_resource", tr.train_id, station=stop.station_id, point_m=point_m
                )
                log.info(
                    "%s serves %s only with the resource %.1f m past the window's start: it halts short and waits",
                    tr.train_id,
                    stop.station_id,
                    point_m - stop.window_start_m,
                )
        return max(end_m, aim_m + margin_m)
