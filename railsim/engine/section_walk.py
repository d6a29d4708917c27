"""The walk over a train's single-track sections and crossings: which of them the section bookkeeping visits in a
step.

Each step :meth:`~railsim.engine.section_requests.SectionRequests._sections_bookkeeping` goes over the contested
sections on a train's route in route order (request a run ahead, release behind the rear, widen a waiting
request), and :meth:`~railsim.engine.section_requests.SectionRequests._let_ahead_through` over them again for a
train in front waiting for a section this one holds. Most entries can do nothing in a given step, and what decides
that is mostly the train's own requests, which change only when :meth:`TrackSections.version
<railsim.engine.events.tracks.TrackSections.version>` of the train moves on (a request made, granted, widened,
handed over or released). So after each step the walk sorts the entries (:meth:`SectionWalker._settle_sections`),
for the train's requests as they stand:

- **done**: the request for the section is for another time through it (a later one; or an earlier one still to be
  released), or the train has released the request for this time through: the bookkeeping passes them by;
- **free**: no request for this time through (none, or a released one for an earlier time): the bookkeeping asks
  for them only once their protection point is within the request distance and the section's end ahead of the
  front, or the front is inside the crossing;
- **open**: the rest (asked for, not released): visited every step.

While the version stays the same, a step visits the entries that are not done, less the free ones at either end
that cannot act where the front now is: a prefix whose ends all lie behind the front, and a suffix whose protection
points all lie beyond the request distance and whose starts are not behind the front. Both ends are found from
running maxima and minima, from where they were the step before. A request the bookkeeping makes in the step (a run
through the sections ahead, a widening) does nothing more for the entries it covers in that step — they are part
of a group, for a later stretch — so the walk can leave them out: it settles afresh after the step. When the version
moved on since the last settling, the step visits every entry. Likewise ``_let_ahead_through`` looks only at the
sections the train holds (granted, not released), a set that changes only with the version. A train with fewer
than ``section_walk_min`` entries (:data:`SECTION_WALK_MIN`) has no walk: going over a short list whole costs less
than keeping the walk (a train with one section, as on most lines, visits it every step).

**Short lists.** A train with fewer entries than ``section_walk_min`` has no walk, but its entries are sorted
too, at the start of a step whose version differs from the last sorting's (:meth:`SectionWalker._short_list`):
the step visits those not done *for good* — done are the entries whose request is for a later time through the
section, or for this time and released; both stay done whatever the step does (the record of which time a
request is for only moves on, a release is not undone). An entry whose request is for an earlier time not yet
released is still visited: the step may release that request and ask anew for this time. ``_let_ahead_through``
looks at the entries held as sorted while the version stays that of the sorting (else at every entry). On most
lines a train has one section: once it has released it, its step does nothing here.

The walk decides exactly as the walk over every entry (``walk_every_section``, the reference
``tests/unit/test_authority_memo.py`` holds it to).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

from railsim.engine.events.tracks import SectionRequest, TrackSections
from railsim.engine.settings import INF, EngineSettings
from railsim.engine.single_track import RouteSection
from railsim.engine.train import TrainRuntime

SECTION_WALK_MIN = 4  # entries on a route from which a walk pays (fewer: every entry is visited every step)


class SectionWalk:
    """One train's entries sorted for its requests at ``version`` (module docstring): ``visit`` the entries that are
    not done, in route order; among them, the first ``free_prefix`` are free, and so is every one from
    ``free_from``; the running maximum of their ends (``max_end_m``), and the running minima from the end of their
    protection points and starts; ``held`` the entries whose sections the train holds; ``lo`` and ``hi`` the
    window visited in the last step; ``reach_m`` the request distance."""

    __slots__ = (
        "free_from",
        "free_prefix",
        "held",
        "hi",
        "lo",
        "max_end_m",
        "min_guard_m",
        "min_start_m",
        "reach_m",
        "sections",
        "version",
        "visit",
    )

    def __init__(self, sections: list[RouteSection], version: int, reach_m: float) -> None:
        self.sections = sections
        self.version = version
        self.reach_m = reach_m  # the request distance
        self.visit: tuple[RouteSection, ...] = ()
        self.held: tuple[RouteSection, ...] = ()
        self.free_prefix = 0
        self.free_from = 0
        self.max_end_m: list[float] = []
        self.min_guard_m: list[float] = []
        self.min_start_m: list[float] = []
        self.lo = 0
        self.hi = 0


class ShortEntries(NamedTuple):
    """The entries of a train with fewer than ``section_walk_min`` sorted for its requests at ``version`` (module
    docstring, "Short lists"): ``visit`` those that are not done for good in route order, ``held`` those whose
    sections the train holds."""

    version: int
    sections: list[RouteSection]  # the train's entries it was sorted from (by identity)
    visit: tuple[RouteSection, ...]
    held: tuple[RouteSection, ...]


class SectionWalker:
    """The section walks of every train (module docstring): a base class of
    :class:`~railsim.engine.section_requests.SectionRequests`, which provides the requests and their reading."""

    settings: EngineSettings
    tracks: TrackSections | None
    sections: dict[str, list[RouteSection]]
    section_requests: dict[str, dict[str, SectionRequest]]
    _section_walks: dict[str, SectionWalk]
    walk_every_section: bool  # True: every entry is visited every step (the reference)
    section_walk_min: int  # a train with fewer entries visits every one every step (cheaper than the walk)
    _short_entries: dict[str, ShortEntries]  # train id -> its short list sorted (module docstring, "Short lists")

    def pass_m(self, tr: TrainRuntime, req: SectionRequest) -> float:
        raise NotImplementedError  # SectionRequests'

    def _stale(self, tr: TrainRuntime, req: SectionRequest, sec: RouteSection) -> bool:
        raise NotImplementedError  # SectionRequests'

    def _current_walk(self, tr: TrainRuntime) -> SectionWalk | None:
        """The train's walk if it still holds for its requests, else None (every entry is visited)."""
        walk = self._section_walks.get(tr.train_id)
        if walk is None:
            return None
        if (
            self.tracks is None
            or walk.version != self.tracks.versions.get(tr.train_id, 0)
            or walk.sections is not self.sections[tr.train_id]
            or self.walk_every_section
        ):
            return None
        return walk

    def _sections_to_visit(self, tr: TrainRuntime, walk: SectionWalk | None) -> Sequence[RouteSection]:
        """The entries the bookkeeping visits this step, in route order (module docstring); ``walk``: the train's
        :meth:`_current_walk`."""
        if walk is None:
            return self.sections[tr.train_id]
        front_m = tr.front_m
        max_end_m = walk.max_end_m
        lo = walk.lo  # the free prefix behind the front: every end at or behind it
        while lo < walk.free_prefix and max_end_m[lo] <= front_m:
            lo += 1
        while lo > 0 and not max_end_m[lo - 1] <= front_m:
            lo -= 1
        # the free suffix out of reach ahead: every protection point beyond the request distance, no start behind
        min_guard_m, min_start_m, reach_m = walk.min_guard_m, walk.min_start_m, walk.reach_m
        n = len(min_guard_m)
        hi = walk.hi
        while hi < n and not (min_guard_m[hi] - front_m > reach_m and min_start_m[hi] >= front_m):
            hi += 1
        while hi > walk.free_from and min_guard_m[hi - 1] - front_m > reach_m and min_start_m[hi - 1] >= front_m:
            hi -= 1
        walk.lo, walk.hi = lo, hi
        return walk.visit[lo:hi] if lo < hi else ()

    def _sections_held(
        self, tr: TrainRuntime, walk: SectionWalk | None, short: ShortEntries | None = None
    ) -> Sequence[RouteSection]:
        """The entries ``_let_ahead_through`` looks at: those whose sections the train holds, while its walk
        (``walk``) or its short list (``short``), as the step began, still holds; else every entry."""
        if self.tracks is None:
            return self.sections[tr.train_id]
        if short is not None:
            if short.version != self.tracks.versions.get(tr.train_id, 0):
                return self.sections[tr.train_id]
            return short.held
        if walk is None or walk.version != self.tracks.versions.get(tr.train_id, 0):
            return self.sections[tr.train_id]
        return walk.held

    def _short_list(self, tr: TrainRuntime) -> ShortEntries | None:
        """The train's short list (fewer entries than ``section_walk_min``) sorted for its requests as they stand
        (module docstring, "Short lists"), or None: every entry is visited (``walk_every_section``)."""
        if self.tracks is None or self.walk_every_section:
            return None
        tid = tr.train_id
        version = self.tracks.versions.get(tid, 0)
        sections = self.sections[tid]
        short = self._short_entries.get(tid)
        if short is not None and short.version == version and short.sections is sections:
            return short
        reqs = self.section_requests[tid]
        visit: list[RouteSection] = []
        held: list[RouteSection] = []
        for sec in sections:
            req = reqs.get(sec.section_id)
            if req is not None and req.granted and tid not in req.released_by and sec.section_id.startswith("track:"):
                held.append(sec)
            if req is not None and not self._stale(tr, req, sec):
                pass_m = self.pass_m(tr, req)
                if pass_m > sec.start_m or (pass_m == sec.start_m and tid in req.released_by):
                    continue  # done for good: a later time through, or this one released
            visit.append(sec)
        short = self._short_entries[tid] = ShortEntries(version, sections, tuple(visit), tuple(held))
        return short

    def _settle_sections(self, tr: TrainRuntime, walk: SectionWalk | None) -> None:
        """After the step: sort the entries afresh if the train's requests changed since ``walk`` (the train's
        :meth:`_current_walk` as the step began) was sorted (module docstring)."""
        if self.tracks is None or self.walk_every_section:
            return
        if walk is not None and walk.version == self.tracks.versions.get(tr.train_id, 0):
            return
        if len(self.sections[tr.train_id]) < self.section_walk_min:
            return  # a short list is cheaper to go over whole
        tid = tr.train_id
        sections = self.sections[tid]
        reqs = self.section_requests[tid]
        walk = SectionWalk(sections, self.tracks.version(tid), self.settings.lock_request_distance_m)
        visit: list[RouteSection] = []
        free: list[bool] = []
        held: list[RouteSection] = []
        for sec in sections:
            req = reqs.get(sec.section_id)
            if req is not None and req.granted and tid not in req.released_by and sec.section_id.startswith("track:"):
                held.append(sec)
            if req is not None and self._stale(tr, req, sec):
                req = None
            elif req is not None and (self.pass_m(tr, req) != sec.start_m or tid in req.released_by):
                continue  # done
            visit.append(sec)
            free.append(req is None)
        n = len(visit)
        walk.visit, walk.held = tuple(visit), tuple(held)
        walk.free_prefix = next((k for k in range(n) if not free[k]), n)
        walk.free_from = next((k + 1 for k in range(n - 1, -1, -1) if not free[k]), 0)
        top_m = -INF
        for sec in visit:
            top_m = max(top_m, sec.end_m)
            walk.max_end_m.append(top_m)
        guard_m, start_m = INF, INF
        min_guard_m, min_start_m = [INF] * n, [INF] * n
        for k in range(n - 1, -1, -1):
            guard_m, start_m = min(guard_m, visit[k].guard_m), min(start_m, visit[k].start_m)
            min_guard_m[k], min_start_m[k] = guard_m, start_m
        walk.min_guard_m, walk.min_start_m = min_guard_m, min_start_m
        walk.lo, walk.hi = 0, max(n, walk.free_from)
        self._section_walks[tid] = walk
