"""The authority end remembered per train (:mod:`railsim.engine.authority`) is exactly the one worked out afresh,
every step: the working-out as it was before it was remembered is kept here word for word
(:func:`authority_end_reference_m`) and two copies of one random world run side by side, one asking it, the other
the route locks' remembered ``authority_end_m``.

The worlds are those of the walk's test (``test_lock_walk.World``: routes over the same points twice, a coupled
follower whose locks its leader asks for, stops within the overlap of points and a stop served only with them, a
planner taking locks away and adding them, fronts stepping back and jumping) with what the authority reads
besides: single-track sections and a flat crossing contested both ways (a train that comes on the line inside a
section it does not hold; a protection point just beyond a stop's mark), a train facing each train coming and going
(``facing_m``), merges whose margin the extension's answer changes, and ATO margins. After every step the two
copies must agree on every train's authority end (the movement follows it, so a wrong answer also moves the train),
on the event log (``stop_needs_resource`` among it) and on every question asked of the extensions.

The same two copies hold the section walk (:mod:`railsim.engine.section_walk`) to the walk over every section
(``walk_every_section``, in the reference copy): every train's section requests (holders, direction, times,
releases, which time through) must agree after every step, besides the event log.

Breaking what makes the memo work out the answer again, or what brings a section into the walk, is caught
(:func:`test_a_memo_that_misses_a_change_is_caught`): lock grants and releases unseen, section requests and
grants unseen, the front intervals ignored, a stop's window end not bounding them; the sections ahead out of
reach too early, the sections held never looked at for a train in front, the sections just behind left out.
"""

from __future__ import annotations

import types
from bisect import bisect_right
from collections.abc import Callable
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from railsim.engine.events.tracks import TrackSections
from railsim.engine.locking import RouteLocks
from railsim.engine.single_track import RouteSection
from railsim.engine.stop_timing import STOP_OVERRUN_ALLOWANCE_M, stop_aim_m
from tests.unit.test_lock_walk import World

SEEDS, STEPS = 8, 1200
ATO = SimpleNamespace(params=SimpleNamespace(authority_margin_m=3.0, stop_tolerance_m=0.5))


def authority_end_reference_m(self: RouteLocks, tr: Any) -> float:
    """The authority end worked out afresh at every call: ``RouteLocks.authority_end_m`` before it was remembered,
    word for word."""
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
            if sec.end_m <= tr.front_m or (req is not None and req.granted):
                continue
            if sec.guard_m > tr.front_m - 1e-6:
                end = min(
                    end, _reach_stop_reference(self, tr, sec.guard_m - self.settings.protection_margin_m, sec.guard_m)
                )
            else:  # inside a section it does not hold (a unit turning back in it): it may not move
                end = min(end, tr.front_m)
            break
    facing_m = self.facing_m.get(tr.train_id)
    if facing_m is not None:  # never into track a train facing it stands or runs on
        end = min(end, _reach_stop_reference(self, tr, facing_m - self.settings.protection_margin_m, facing_m))
    switches = tr.trip.route.switches
    behind_m = tr.front_m - 1e-6
    index = self._route_index(switches)
    first = bisect_right(index.points_m, behind_m) if index.walkable else 0  # those before lie behind
    for i in range(first, len(switches)):
        rs = switches[i]
        if rs.point_m <= behind_m:
            continue
        if rs.switch_id in tr.released and self._lock_pass_m(tr, rs.switch_id) >= rs.point_m:
            continue
        if not self.interlocking.is_locked_for(tr.train_id, rs.switch_id, rs.leg):
            return min(
                end, _reach_stop_reference(self, tr, rs.point_m - self._margin_m(tr.train_id, rs.switch_id), rs.point_m)
            )
    return end


def _reach_stop_reference(self: RouteLocks, tr: Any, end_m: float, point_m: float) -> float:
    """``RouteLocks._reach_stop`` before the authority end was remembered, word for word."""
    k = tr.next_stop
    stops = tr.trip.stops
    if tr.sumo_stopped and k + 1 < len(stops) and stops[k + 1].kind == "station":
        k += 1
    if k >= len(stops):
        return end_m
    stop = stops[k]
    if stop.kind != "station" or stop.mark_m >= point_m or tr.front_m > stop.window_end_m:
        return end_m
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
    return max(end_m, aim_m + margin_m)


class SectionWorld(World):
    """A world of the walk's test with sections, a crossing, facing trains, merges and ATO margins
    (``reference``: its route locks work the authority end out afresh at every call)."""

    def __init__(
        self, seed: int, reference: bool, patch: Callable[[RouteLocks], None] | None = None, short: bool = False
    ) -> None:
        """``short``: the remembering copy keeps the engine's ``section_walk_min``, so every train's one to three
        sections are a short list (``SectionWalker._short_list``) rather than a walk."""
        super().__init__(seed, every=False)
        rng = np.random.default_rng(seed + 1000)
        self.draws = np.random.default_rng(seed + 2000)  # the facing trains; the same draws in both copies
        self.stop_lag = np.random.default_rng(seed + 3000)  # a passed stop is seen late, as SUMO reports it
        locks = self.locks
        locks.tracks = TrackSections(self.log, ["track:A", "track:B", "crossing:X"], room_beyond=locks._room_beyond)
        locks.continues = lambda _tid: False
        for tid, tr in sorted(self.trains.items()):
            if tid == "fol":
                continue  # below: the leader's
            stops = tr.trip.stops
            route_end_m = stops[-1].mark_m
            low_m = stops[0].mark_m + 200.0
            first_m = float(rng.uniform(low_m, max(low_m + 1.0, 0.4 * route_end_m)))
            if tid == "rev":  # it comes on the line inside the section
                first_m = tr.front_m - 200.0
            a_end_m = first_m + float(rng.uniform(300.0, 900.0))
            guard_m = first_m - float(rng.uniform(0.0, 60.0))
            if rng.random() < 0.5:  # the protection point just beyond a stop's mark
                mark_m = float(stops[int(rng.integers(1, len(stops) - 1))].mark_m)
                guard_m = mark_m + float(rng.uniform(0.5, 15.0))
                first_m, a_end_m = guard_m, guard_m + float(rng.uniform(300.0, 900.0))
            b_start_m = a_end_m + float(rng.uniform(50.0, 400.0))
            b_end_m = b_start_m + float(rng.uniform(200.0, 700.0))
            x_m = float(rng.uniform(b_end_m + 100.0, route_end_m - 50.0)) if b_end_m + 150.0 < route_end_m else None
            mine = [RouteSection("track:A", int(rng.integers(0, 2)), first_m, a_end_m, guard_m)]
            if rng.random() < 0.7:
                mine.append(RouteSection("track:B", int(rng.integers(0, 2)), b_start_m, b_end_m, b_start_m - 10.0))
            if x_m is not None and rng.random() < 0.7:
                mine.append(RouteSection("crossing:X", int(rng.integers(0, 2)), x_m, x_m + 20.0, x_m))
            locks.sections[tid] = mine
            locks.section_requests[tid] = {}
            if tid == "lead":
                locks.sections["fol"] = list(mine)
                locks.section_requests["fol"] = {}
        for tid in ("a", "b", "lead", "fol"):
            self.trains[tid].controllers = {"ato": ATO}
        for tid, merges in (("ext", ("p1", "p2", "p3")), ("a", ("p4", "p5", "p6"))):
            locks.merges_of[tid] = frozenset(merges)
            locks.merge_margin_m[tid] = 50.0
        hooks = self.hooks

        def manages_lock(train_id: str, switch_id: str) -> bool:  # the planner takes switches on and off
            hooks.asked.append(("manages", train_id, switch_id))
            return train_id == "ext" and switch_id in ("p1", "p2") and int(hooks.t) // 90 % 2 == 0

        hooks.manages_lock = manages_lock  # type: ignore[method-assign]
        if reference:
            locks.authority_end_m = types.MethodType(authority_end_reference_m, locks)  # type: ignore[method-assign]
            locks.walk_every_section = True
        elif not short:
            locks.section_walk_min = 0  # the worlds' routes have one to three sections: walk them all the same
        if patch is not None:
            patch(locks)

    def step(self, t: float) -> None:
        """Trains facing each train come and go, then the walk's world steps."""
        for tid, tr in sorted(self.trains.items()):
            if self.draws.random() < 0.03:
                if self.draws.random() < 0.5:
                    self.locks.facing_m.pop(tid, None)
                else:
                    self.locks.facing_m[tid] = tr.front_m + float(self.draws.uniform(25.0, 1500.0))
        super().step(t)

    def state(self) -> dict[str, Any]:
        """The walk's world's state and every train's section requests."""
        out = super().state()
        for tid, reqs in sorted(self.locks.section_requests.items()):
            out["sections:" + tid] = sorted(
                (sid, r.holder_ids, r.direction, r.requested_s, r.granted_s, sorted(r.released_by), r.pass_m)
                for sid, r in reqs.items()
            )
        return out


def _differ(
    seed: int, patch: Callable[[RouteLocks], None] | None = None, short: bool = False
) -> tuple[str | None, SectionWorld]:
    """Run the two copies side by side: the first difference (step and what) or None, and the remembering one."""
    ref = SectionWorld(seed, reference=True)
    fast = SectionWorld(seed, reference=False, patch=patch, short=short)
    for k in range(STEPS):
        t = float(k)
        ref.step(t)
        fast.step(t)
        a, b = ref.state(), fast.state()
        if a != b:
            what = next(key for key in a if a[key] != b[key])
            return f"seed {seed}, t = {t} s: {what} differs", fast
    assert ref.log.rows() == fast.log.rows()
    return None, fast


@pytest.mark.parametrize("seed", range(SEEDS))
def test_the_remembered_authority_is_the_one_worked_out_afresh(seed: int) -> None:
    calls = {"worked": 0, "asked": 0, "visited": 0, "entries": 0}
    difference, fast = _differ(seed, patch=lambda locks: _count(locks, calls))
    assert difference is None, difference
    assert fast.log.count("section_reserved") > 3 and fast.log.count("lock_granted") > 10  # the world does things
    assert calls["worked"] < calls["asked"] / 3, calls  # most calls are answered from the memo
    assert calls["visited"] < calls["entries"] / 2, calls  # the section walk leaves most entries out


def _count(locks: RouteLocks, calls: dict[str, int]) -> None:
    """Count the calls and the workings-out, and the section entries visited of all there are."""
    ask, work = locks.authority_end_m, locks._work_out

    def asked(tr: Any) -> float:
        calls["asked"] += 1
        return ask(tr)

    def worked(tr: Any, memo: Any) -> float:
        calls["worked"] += 1
        return work(tr, memo)

    locks.authority_end_m = asked  # type: ignore[method-assign]
    locks._work_out = worked  # type: ignore[method-assign]
    visit = locks._sections_to_visit

    def visited(tr: Any, walk: Any) -> Any:
        out = visit(tr, walk)
        calls["visited"] += len(out)
        calls["entries"] += len(locks.sections[tr.train_id])
        return out

    locks._sections_to_visit = visited  # type: ignore[method-assign]


def test_the_worlds_hold_the_hard_cases() -> None:
    """Over the seeds, the reference world has a train standing in a section it does not hold (its authority at
    its front), an authority carried to a stop before a section's protection point, one ending before a train
    facing it, and one before a merge whose margin the extension changed."""
    seen = {"inside": 0, "stop_before_section": 0, "facing": 0, "merge_margin": 0}
    for seed in range(SEEDS // 2):
        w = SectionWorld(seed, reference=True)
        overlap_m = w.locks.settings.protection_margin_m
        for k in range(STEPS):
            w.step(float(k))
            for tid, tr in w.trains.items():
                if tr.status != "running":
                    continue
                end_m = w.locks.authority_end_m(tr)
                reqs = w.locks.section_requests.get(tid, {})
                for sec in w.locks.sections.get(tid, ()):
                    req = reqs.get(sec.section_id)
                    if sec.end_m <= tr.front_m or (req is not None and req.granted):
                        continue
                    seen["inside"] += sec.guard_m <= tr.front_m - 1e-6 and end_m == tr.front_m
                    seen["stop_before_section"] += sec.guard_m > tr.front_m and end_m > sec.guard_m - overlap_m
                    break
                facing_m = w.locks.facing_m.get(tid)
                seen["facing"] += facing_m is not None and end_m <= facing_m - overlap_m
                seen["merge_margin"] += end_m in {rs.point_m - 50.0 for rs in tr.trip.route.switches}
    assert all(n > 0 for n in seen.values()), seen


class _Frozen(dict[str, int]):
    """A version book that never moves on."""

    def __setitem__(self, key: str, value: int) -> None:
        pass


def _versions_frozen(locks: RouteLocks) -> None:
    """Broken on purpose: grants and releases of locks are not seen."""
    locks.interlocking.versions = _Frozen()


def _sections_frozen(locks: RouteLocks) -> None:
    """Broken on purpose: section requests and grants are not seen."""
    assert locks.tracks is not None
    locks.tracks.versions = _Frozen()


def _front_ignored(locks: RouteLocks) -> None:
    """Broken on purpose: the answer holds wherever the front is."""
    work = locks._work_out

    def broken(tr: Any, memo: Any) -> float:
        end_m = work(tr, memo)
        memo.lo_m, memo.hi_m, memo.lo_behind_m, memo.hi_behind_m = -np.inf, np.inf, -np.inf, np.inf
        return end_m

    locks._work_out = broken  # type: ignore[method-assign]


def _stop_window_ignored(locks: RouteLocks) -> None:
    """Broken on purpose: a stop's window end does not bound the front interval."""
    reach = locks._reach_stop
    locks._reach_stop = lambda tr, end_m, point_m, memo=None: reach(tr, end_m, point_m)  # type: ignore[method-assign]


def _short_reach(locks: RouteLocks) -> None:
    """Broken on purpose: the free sections ahead count as out of reach 200 m early."""
    settle = locks._settle_sections

    def broken(tr: Any, walk: Any) -> None:
        settle(tr, walk)
        mine = locks._section_walks.get(tr.train_id)
        if mine is not None:
            mine.reach_m = locks.settings.lock_request_distance_m - 200.0

    locks._settle_sections = broken  # type: ignore[method-assign]


def _in_front_unseen(locks: RouteLocks) -> None:
    """Broken on purpose: the sections never learn which train stands in front of which, so a train in front of a
    holder never takes the holder's place in their order (``TrackSections.set_in_front``), the other way a train in
    front is let through."""
    assert locks.tracks is not None
    locks.tracks.set_in_front = lambda t_s, train_id, front_id: None  # type: ignore[method-assign]


def _held_unseen(locks: RouteLocks) -> None:
    """Broken on purpose: a train in front is never let through a section this train holds."""
    held = locks._sections_held
    locks._sections_held = lambda tr, walk, short=None: () if walk is not None else held(tr, walk, short)  # type: ignore[method-assign]
    _in_front_unseen(locks)


def _rear_unseen(locks: RouteLocks) -> None:
    """Broken on purpose: a section whose end the front has just passed is not visited (its release waits)."""
    visit = locks._sections_to_visit
    locks._sections_to_visit = lambda tr, walk: [s for s in visit(tr, walk) if s.end_m > tr.front_m - 100.0]  # type: ignore[method-assign]


@pytest.mark.parametrize(
    "patch",
    [
        _versions_frozen,
        _sections_frozen,
        _front_ignored,
        _stop_window_ignored,
        _short_reach,
        _held_unseen,
        _rear_unseen,
    ],
)
def test_a_memo_that_misses_a_change_is_caught(patch: Callable[[RouteLocks], None]) -> None:
    assert any(_differ(seed, patch)[0] is not None for seed in range(SEEDS)), f"{patch.__name__} went unnoticed"


def _left_out_wrongly(locks: RouteLocks, calls: dict[str, int]) -> None:
    """Count the entries of the short lists visited and left out, and the entries left out that the former code
    (the loop over every entry) would have acted on in that step: at the step's end, one whose request is gone
    stale or is for this time through and not released (``calls["wrong"]``)."""
    short_list, bookkeeping = locks._short_list, locks._sections_bookkeeping
    left_out: dict[str, list[Any]] = {}

    def counted(tr: Any) -> Any:
        out = short_list(tr)
        calls["visited"] += len(out.visit)
        calls["entries"] += len(locks.sections[tr.train_id])
        left_out[tr.train_id] = [sec for sec in locks.sections[tr.train_id] if sec not in out.visit]
        return out

    def checked(t: float, tr: Any, ahead: Any = None) -> None:
        left_out[tr.train_id] = []
        bookkeeping(t, tr, ahead)
        reqs = locks.section_requests[tr.train_id]
        for sec in left_out[tr.train_id]:
            req = reqs.get(sec.section_id)
            acts = req is None or locks._stale(tr, req, sec)
            acts = acts or (locks.pass_m(tr, req) == sec.start_m and tr.train_id not in req.released_by)
            calls["wrong"] += acts

    locks._short_list = counted  # type: ignore[method-assign]
    locks._sections_bookkeeping = checked  # type: ignore[method-assign]


@pytest.mark.parametrize("seed", range(SEEDS))
def test_short_lists_decide_as_every_entry(seed: int) -> None:
    """Trains with fewer sections than ``section_walk_min`` go over their short lists sorted
    (``SectionWalker._short_list``): every decision as the copy that visits every entry, no entry left out that
    the step acts on, and entries left out."""
    calls = {"visited": 0, "entries": 0, "wrong": 0}
    difference, fast = _differ(seed, patch=lambda locks: _left_out_wrongly(locks, calls), short=True)
    assert difference is None, difference
    assert fast.log.count("section_reserved") > 3
    assert calls["wrong"] == 0, calls
    assert calls["entries"] - calls["visited"] > 300, calls


def _short_open_done(locks: RouteLocks) -> None:
    """Broken on purpose: an entry the train holds (granted, not released) is taken as done."""
    short_list = locks._short_list

    def broken(tr: Any) -> Any:
        out = short_list(tr)
        reqs = locks.section_requests[tr.train_id]

        def open_(sec: Any) -> bool:
            req = reqs.get(sec.section_id)
            return req is not None and req.granted and tr.train_id not in req.released_by

        return out._replace(visit=tuple(sec for sec in out.visit if not open_(sec)))

    locks._short_list = broken  # type: ignore[method-assign]


def _short_held_none(locks: RouteLocks) -> None:
    """Broken on purpose: a short list holds no entry (a train in front is never let through)."""
    short_list = locks._short_list
    locks._short_list = lambda tr: short_list(tr)._replace(held=())  # type: ignore[method-assign]
    _in_front_unseen(locks)


@pytest.mark.parametrize("patch", [_short_open_done, _short_held_none])
def test_a_short_list_that_leaves_out_an_entry_is_caught(patch: Callable[[RouteLocks], None]) -> None:
    assert any(_differ(seed, patch, short=True)[0] is not None for seed in range(SEEDS)), patch.__name__
