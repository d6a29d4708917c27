"""The route locks' walk over a train's switches visits only those that can matter, and decides exactly as the
walk over every switch (``RouteLocks.walk_every_switch``, the reference).

Two copies of one randomly built world step side by side, one walking every switch of every route each step,
the other only the switches its cursor, its tracked switches and the request distance give. After every
train's bookkeeping the two must agree on everything the walk decides: each train's locks (request, holders,
leg, state), released switches, violations and lock records, the event log (requests, grants, throws,
releases, ``lock_given_up``, ``switch_violation``), the order in which the extension hooks and the join book
were asked, and every train's authority end. The worlds hold what makes the walk hard: routes over the same
points twice (out to a reversal and back), a coupled follower whose leader's request gives it locks beyond its
own request distance, a unit that sets no route beyond its reversal point until it leaves, trains that come on
the line past switches, points that take time to throw (requests wait), an extension that manages or defers
some switches, locks added and taken away from outside the walk (as the junction planner does), a train in
front that comes and goes, fronts that step back a little and jump ahead, and a release of every lock at the
end of a trip.

A walk that leaves out a switch it should visit is caught: :func:`test_a_walk_that_leaves_out_a_switch_is_caught`
breaks the walk five ways and expects a difference each time.
"""

from __future__ import annotations

import copy
import dataclasses
import zlib
from collections.abc import Callable
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from railsim.engine.coupling import COUPLED_STATES
from railsim.engine.events import EventLayer, Interlocking, Switch
from railsim.engine.events.log import EventLog
from railsim.engine.locking import RouteLocks
from railsim.engine.settings import EngineSettings
from railsim.engine.trips import TripStop

POOL = tuple(f"p{k}" for k in range(12))  # the switches of the net
LENGTH_M = 120.0
COUPLED = COUPLED_STATES[-1]
# trains that sometimes run past their authority (passing points without their lock: switch_violation); routes
# over the same points twice keep theirs (a request still waiting when the train passes is the engine's own case)
RECKLESS = ("a", "lead", "fol")
SEEDS, STEPS = 12, 1200  # worlds, and seconds each runs


def _route(rng: np.random.Generator, start_m: float, n_out: int, back: bool = True) -> list[SimpleNamespace]:
    """Switches out along the line and, for some routes (``back``), back over the same points after a reversal."""
    out: list[SimpleNamespace] = []
    point_m = start_m
    for sid in rng.choice(POOL, size=n_out, replace=False):
        point_m += float(rng.uniform(150.0, 1800.0))
        out.append(SimpleNamespace(switch_id=str(sid), leg=str(rng.choice(["normal", "reverse"])), point_m=point_m))
    if back and rng.random() < 0.6:  # a turnback path: back over some of the same points
        again = [rs.switch_id for rs in reversed(out)][: int(rng.integers(2, n_out))]
        for sid in again:
            point_m += float(rng.uniform(150.0, 1800.0))
            leg = str(rng.choice(["normal", "reverse"]))
            out.append(SimpleNamespace(switch_id=sid, leg=leg, point_m=point_m))
    return out


def _stops(
    rng: np.random.Generator, first_m: float, end_m: float, first_kind: str, switches: list[SimpleNamespace]
) -> tuple[TripStop, ...]:
    """An origin, four stops, a destination; one stop ends within the overlap of a switch (the authority is carried
    to its mark, ``_reach_stop``), and one so close to another that it is served only with the points."""
    stops = [TripStop("o", "o", first_m, first_m - LENGTH_M, first_m + 1.0, 20.0, kind=first_kind, is_origin=True)]
    marks = [(float(x), float(x) - 100.0) for x in rng.uniform(first_m + 300.0, end_m - 200.0, size=4)]
    beyond = [rs.point_m for rs in switches if first_m + 300.0 < rs.point_m < end_m - 200.0]
    if len(beyond) >= 2:
        near, tight = rng.choice(beyond, size=2, replace=False)
        marks[0] = (float(near) - 10.0, float(near) - 110.0)
        marks[1] = (float(tight) - 0.5, float(tight) - 1.0)
    for k, (mark_m, start_m) in enumerate(sorted(marks)):
        dwell_s = float(rng.uniform(5.0, 40.0))
        stops.append(TripStop(f"s{k}", f"s{k}", mark_m, start_m, mark_m + 1.0, dwell_s))
    stops.append(TripStop("d", "d", end_m, end_m - 100.0, end_m + 1.0, 1.0, is_destination=True))
    return tuple(stops)


def _train(tid: str, switches: list[SimpleNamespace], stops: tuple[TripStop, ...], front_m: float) -> Any:
    end_m = stops[-1].mark_m
    trip = SimpleNamespace(
        stops=stops,
        depart_s=0.0,
        departure_delay_s=0.0,
        vehicle=SimpleNamespace(length_m=LENGTH_M),
        route=SimpleNamespace(switches=tuple(switches)),
        start_offset_m=0.0,
        depart_chainage_m=stops[0].mark_m,  # as Trip's: the origin's mark plus the start offset
    )
    return SimpleNamespace(
        train_id=tid,
        trip=trip,
        view=SimpleNamespace(length_m=end_m + 50.0),
        front_m=front_m,
        next_stop=1,
        sumo_stopped=False,
        dwell_started_s=None,
        locks={},
        released=set(),
        violations=set(),
        reversing=False,
        start_front_m=front_m,
        status="running",
        on_line=True,
        controllers={},
    )


class _Hooks:
    """The extension hooks and the join book, answering from a hash of their arguments and the step, and logging
    every question (the two worlds must ask the same questions in the same order)."""

    def __init__(self, seed: int) -> None:
        self.seed = seed
        self.t = 0.0
        self.asked: list[tuple[Any, ...]] = []

    def _says(self, *key: Any, per: int = 1) -> bool:
        return zlib.crc32(repr((self.seed, int(self.t) // 40, *key)).encode()) % per == 0

    def manages_lock(self, train_id: str, switch_id: str) -> bool:
        self.asked.append(("manages", train_id, switch_id))
        return train_id == "ext" and switch_id in ("p1", "p2")

    def defers_lock(self, train_id: str, switch_id: str) -> bool:
        self.asked.append(("defers", train_id, switch_id))
        return train_id == "ext" and self._says(switch_id, per=3)

    def route_waits(self, tr: Any, point_m: float) -> bool:
        self.asked.append(("route_waits", tr.train_id, point_m))
        return tr.train_id == "lead" and self._says(point_m, per=4)


class _Formations:
    """One formation, ``lead`` and ``fol``, coupled or not as the world says."""

    def __init__(self, trains: dict[str, Any], hooks: _Hooks) -> None:
        self.trains = trains
        self.f = SimpleNamespace(id="F")
        self.of_follower = {"fol": self.f}
        self.of_leader = {"lead": [self.f]}
        self.join_book = SimpleNamespace(route_waits=hooks.route_waits)
        self.state = COUPLED
        self.manager = SimpleNamespace(state=lambda _fid: self.state)

    def leader_of(self, _f: Any) -> Any:
        return self.trains["lead"]

    def follower_of(self, _f: Any) -> Any:
        return self.trains["fol"]


class World:
    """One copy of the randomly built world (``every``: walk every switch, the reference)."""

    def __init__(
        self, seed: int, every: bool, patch: Callable[[RouteLocks], None] | None = None, move_start: bool = False
    ) -> None:
        rng = np.random.default_rng(seed)
        # move_start: now and then a train's start moves (a new start front, start offset, origin or vehicle)
        self.move_start = np.random.default_rng(seed + 2) if move_start else None
        self.rng = np.random.default_rng(seed + 1)  # the world's run; the same draws in both copies
        self.log = EventLog()
        self.layer = EventLayer(t0_s=0.0, rng=np.random.default_rng(1), log=self.log)
        il = Interlocking(self.layer)
        for sid in POOL:
            il.add_switch(Switch(sid, throw_time_s=float(rng.choice([0.0, 4.0, 12.0]))))
        trains: dict[str, Any] = {}
        for tid in ("a", "b", "ext"):
            sw = _route(rng, 0.0, int(rng.integers(4, 10)), back=tid not in RECKLESS)
            trains[tid] = _train(tid, sw, _stops(rng, 0.0, sw[-1].point_m + 800.0, "station", sw), 0.0)
        # a formation: the follower runs the leader's route 200 m behind, its locks asked for by the leader
        sw = _route(rng, 0.0, 8, back=False)
        lead_stops = _stops(rng, 0.0, sw[-1].point_m + 800.0, "station", sw)
        trains["lead"] = _train("lead", sw, lead_stops, 0.0)
        trains["fol"] = _train("fol", list(sw), lead_stops, -200.0)
        # a unit that reverses first (no route beyond its reversal point until it leaves it) and came on the line
        # past some switches of its route
        sw = _route(rng, 0.0, 9)
        come_on_m = sw[2].point_m + 300.0
        rev_stops = _stops(rng, come_on_m + 40.0, sw[-1].point_m + 800.0, "reversal", sw)
        trains["rev"] = _train("rev", sw, rev_stops, come_on_m)
        trains["rev"].reversing = True
        # a trip from a platform past its route's first switches, on the line before it (a unit's next trip
        # comes on the line before its origin platform): the points between are not its business
        sw = _route(rng, 0.0, 8)
        mid_stops = _stops(rng, sw[2].point_m + 300.0, sw[-1].point_m + 800.0, "station", sw)
        trains["mid"] = _train("mid", sw, mid_stops, sw[1].point_m - 200.0)
        self.trains = trains
        self.hooks = _Hooks(seed)
        self.formations = _Formations(trains, self.hooks)
        self.locks = RouteLocks(
            SimpleNamespace(trains=trains),  # type: ignore[arg-type]
            il,
            self.formations,  # type: ignore[arg-type]
            self.log,
            EngineSettings(),
            self.hooks,  # type: ignore[arg-type]
            self.layer,
        )
        self.locks.walk_every_switch = every
        if patch is not None:
            patch(self.locks)
        self.stop_lag: np.random.Generator | None = None  # None: a stop is seen passed at once
        self.visits = 0
        self.logged = 0  # log entries compared so far
        visit = self.locks._visit_switch

        def counted(*args: Any) -> float:
            self.visits += 1
            return visit(*args)

        self.locks._visit_switch = counted  # type: ignore[method-assign,assignment]

    def step(self, t: float) -> None:
        """Move the trains, change what the walk does not own, then each train's bookkeeping and authority."""
        rng, trains, il = self.rng, self.trains, self.locks.interlocking
        self.layer.advance_to(t)
        self.hooks.t = t
        self.formations.state = COUPLED if (t // 150) % 3 else "uncoupled"
        if self.move_start is not None and self.move_start.random() < 0.03:
            self._move_start(trains[str(self.move_start.choice(sorted(trains)))])
        order = sorted(trains)
        rng.shuffle(order)
        for tid in order:
            tr = trains[tid]
            if tr.status != "running":
                continue
            end = self.locks.authority_end_m(tr)
            step_m = float(rng.uniform(0.0, 25.0))
            if rng.random() < 0.05:
                step_m = -0.3  # SUMO's chainage may step back a little
            elif rng.random() < 0.01:
                step_m = 900.0  # a jump
            if tid not in RECKLESS or rng.random() < 0.5:
                step_m = min(step_m, max(0.0, end - tr.front_m))  # the authority is kept
            tr.front_m += step_m
            stops = tr.trip.stops
            while tr.next_stop < len(stops) - 1 and tr.front_m > stops[tr.next_stop].window_end_m:
                if self.stop_lag is not None and self.stop_lag.random() < 0.5:
                    break  # the stop is seen passed a step or more later
                tr.next_stop += 1
            tr.sumo_stopped = bool(rng.random() < 0.2)
            tr.dwell_started_s = t - float(rng.uniform(0.0, 40.0)) if tr.sumo_stopped else None
            if tr.reversing and tr.front_m > stops[0].window_end_m + 200.0:
                tr.reversing = False
        # a planner outside the walk takes a waiting request away, or asks for points for a train (points its route
        # passes once, as the junction planner's)
        if rng.random() < 0.08:
            tr = trains[str(rng.choice(sorted(trains)))]
            ids = [rs.switch_id for rs in tr.trip.route.switches]
            once = [rs for rs in tr.trip.route.switches if rs.point_m > tr.front_m and ids.count(rs.switch_id) == 1]
            if tr.status == "running" and once:
                rs = once[int(rng.integers(0, len(once)))]
                held = tr.locks.get(rs.switch_id)
                if held is not None and rs.switch_id not in tr.released and not il.is_granted(held):
                    il.cancel(held)
                    for h in held.holder_ids:
                        trains[h].locks.pop(rs.switch_id, None)
                elif held is None and all(tr.train_id not in q.holder_ids for q in il.queue(rs.switch_id)):
                    if tr.train_id not in (il.holder(rs.switch_id) or ()):
                        tr.locks[rs.switch_id] = il.request((tr.train_id,), rs.switch_id, rs.leg)
        for tid in order:
            tr = trains[tid]
            if tr.status != "running":
                continue
            ahead: SimpleNamespace | None = None
            if rng.random() < 0.3:  # a train in front, in this train's frame
                other = str(rng.choice([o for o in sorted(trains) if o != tid]))
                rear_m = tr.front_m + float(rng.uniform(0.0, 2500.0))
                ahead = SimpleNamespace(train_id=other, front_m=rear_m + LENGTH_M, rear_m=rear_m)
            self.locks.bookkeeping(t, tr, ahead)
            if tr.front_m > tr.trip.stops[-1].mark_m:
                tr.status = "arrived"
                self.locks.release_all(tr)

    def _move_start(self, tr: Any) -> None:
        """Move where the train's switches begin to be its business (``lock_walk.start_limit_of``'s inputs): its
        start front (a unit handed over elsewhere), its trip's start offset, its origin's mark (new stops) or its
        vehicle (a new length), a few hundred metres either way."""
        rng, trip = self.move_start, tr.trip
        assert rng is not None
        shift_m = float(rng.choice([-900.0, -300.0, 0.0, 300.0]))
        what = int(rng.integers(0, 4))
        if what == 0:
            tr.start_front_m += shift_m
        elif what == 1:
            trip.start_offset_m += shift_m
        elif what == 2:
            first = trip.stops[0]
            trip.stops = (dataclasses.replace(first, mark_m=first.mark_m + shift_m), *trip.stops[1:])
        else:
            trip.vehicle = SimpleNamespace(length_m=LENGTH_M + shift_m / 10.0)
        trip.depart_chainage_m = trip.stops[0].mark_m + trip.start_offset_m

    def state(self) -> dict[str, Any]:
        """Everything the walk decides since the last call (events, questions), and every train's locks and
        authority end."""
        entries = self.log.entries()
        out: dict[str, Any] = {"log": [(e.t_s, e.kind, e.subject, repr(e.detail)) for e in entries[self.logged :]]}
        self.logged = len(entries)
        out["asked"] = self.hooks.asked
        self.hooks.asked = []
        for tid, tr in sorted(self.trains.items()):
            out[tid] = (
                sorted((sid, r.seq, r.holder_ids, r.leg, str(r.state)) for sid, r in tr.locks.items()),
                sorted(tr.released),
                sorted(tr.violations),
                sorted(self.locks._lock_pass.get(tid, {}).items()),
                self.locks.authority_end_m(tr) if tr.status == "running" else None,
            )
        return out


def _differ(
    seed: int, patch: Callable[[RouteLocks], None] | None = None, move_start: bool = False
) -> tuple[str | None, World]:
    """Run the two copies side by side: the first difference (step and what) or None, and the reference."""
    every = World(seed, every=True, move_start=move_start)
    fast = World(seed, every=False, patch=patch, move_start=move_start)
    for k in range(STEPS):
        t = float(k)
        every.step(t)
        fast.step(t)
        a, b = every.state(), fast.state()
        if a != b:
            what = next(key for key in a if a[key] != b[key])
            return f"seed {seed}, t = {t} s: {what} differs", every
    assert every.log.rows() == fast.log.rows()
    assert fast.visits < every.visits / 3, "the walk visits nearly every switch"
    return None, every


@pytest.mark.parametrize("seed", range(SEEDS))
def test_the_walk_decides_as_the_walk_over_every_switch(seed: int) -> None:
    difference, every = _differ(seed)
    assert difference is None, difference
    assert every.log.count("lock_granted") > 10 and every.log.count("lock_released") > 10  # the world does things


def test_the_worlds_hold_the_hard_cases() -> None:
    """Over the seeds, the reference world asks again for points on a later time over them, gives points up to
    a train in front, passes points without their lock, and gives the follower locks through its leader."""
    seen: dict[str, int] = {"again": 0, "given_up": 0, "violation": 0, "group": 0, "short": 0}
    for seed in range(SEEDS):
        w = World(seed, every=True)
        for k in range(STEPS):
            w.step(float(k))
            for tid, tr in w.trains.items():
                record = w.locks._lock_pass.get(tid, {})
                firsts: dict[str, float] = {}
                for rs in tr.trip.route.switches:
                    firsts.setdefault(rs.switch_id, rs.point_m)
                seen["again"] += any(firsts[sid] < p for sid, p in record.items())
        seen["given_up"] += w.log.count("lock_given_up")
        seen["violation"] += w.log.count("switch_violation")
        seen["group"] += sum(1 for e in w.log.entries("lock_requested") if len(e.detail["holders"]) > 1)
        seen["short"] += w.log.count("stop_needs_resource")
    assert all(n > 0 for n in seen.values()), seen


def _skip_tracked(locks: RouteLocks) -> None:
    """Broken on purpose: the tracked switches (held, waited for, lagging) are left out."""
    walk_candidates = locks._walk_candidates

    def broken(tr: Any, walk: Any) -> list[int]:
        return [i for i in walk_candidates(tr, walk) if i >= walk.cursor]

    locks._walk_candidates = broken  # type: ignore[method-assign]


def _short_window(locks: RouteLocks) -> None:
    """Broken on purpose: the window stops 100 m short of the request distance."""
    walk_candidates = locks._walk_candidates

    def broken(tr: Any, walk: Any) -> list[int]:
        reach_m = tr.front_m + locks.settings.lock_request_distance_m - 100.0
        return [i for i in walk_candidates(tr, walk) if i in walk.tracked or walk.index.points_m[i] <= reach_m]

    locks._walk_candidates = broken  # type: ignore[method-assign]


def _no_next_time(locks: RouteLocks) -> None:
    """Broken on purpose: a release does not bring the next time over the same points into the walk."""
    locks._lock_done = lambda tr, rs: False  # type: ignore[method-assign]


def _outside_unseen(locks: RouteLocks) -> None:
    """Broken on purpose: locks added outside the walk (a leader's request, a planner's) are not looked for."""
    walk_candidates = locks._walk_candidates

    def broken(tr: Any, walk: Any) -> list[int]:
        walk.lock_ids = set(tr.locks)
        return walk_candidates(tr, walk)

    locks._walk_candidates = broken  # type: ignore[method-assign]


def _behind_start_asleep(locks: RouteLocks) -> None:
    """Broken on purpose: a switch behind where the train came on the line is dormant even while it holds it."""
    dormant = locks._dormant

    def broken(tr: Any, walk: Any, i: int) -> bool:
        return walk.index.points_m[i] < walk.start_limit_m or dormant(tr, walk, i)

    locks._dormant = broken  # type: ignore[method-assign]


def _held_given_up_unseen(locks: RouteLocks) -> None:
    """Broken on purpose: approaching points held, the train in front waiting for them is not looked at."""
    approaching = locks._approaching_held
    locks._approaching_held = lambda tr, walk, ahead: approaching(tr, walk, None)  # type: ignore[method-assign]


def _held_front_unseen(locks: RouteLocks) -> None:
    """Broken on purpose: approaching points held, where the front is is not looked at (it may have passed the
    point, or come within the request distance of the next points)."""
    approaching = locks._approaching_held

    def broken(tr: Any, walk: Any, ahead: Any) -> bool:
        return approaching(SimpleNamespace(**{**vars(tr), "front_m": -1e9}), walk, ahead)

    locks._approaching_held = broken  # type: ignore[method-assign]


def _single_too_eager(locks: RouteLocks) -> None:
    """Broken on purpose: the switch at the cursor is taken as the only one in reach whenever nothing else is
    tracked (the next points within the request distance, and where the front is, not looked at)."""
    single = locks._single_switch

    def broken(tr: Any, walk: Any) -> int:
        i = walk.cursor
        if i < len(walk.index.ids) and set(walk.tracked) <= {i} and tr.locks.keys() == walk.lock_ids:
            return i
        return single(tr, walk)

    locks._single_switch = broken  # type: ignore[method-assign]


@pytest.mark.parametrize(
    "patch",
    [
        _skip_tracked,
        _short_window,
        _no_next_time,
        _outside_unseen,
        _behind_start_asleep,
        _held_given_up_unseen,
        _held_front_unseen,
        _single_too_eager,
    ],
)
def test_a_walk_that_leaves_out_a_switch_is_caught(patch: Callable[[RouteLocks], None]) -> None:
    assert any(_differ(seed, patch)[0] is not None for seed in range(SEEDS)), f"{patch.__name__} went unnoticed"


@pytest.mark.parametrize("seed", range(SEEDS))
def test_the_walk_follows_a_moved_start(seed: int) -> None:
    """The start limit the walk remembers (``SwitchWalk.remember_start_inputs``) is worked out again whenever what it
    comes from moves: the walk still decides as the walk over every switch, which works it out every step."""
    difference, _ = _differ(seed, move_start=True)
    assert difference is None, difference


class _Same:
    """Equal to anything (a memo broken on purpose: it sees no change)."""

    def __eq__(self, _other: object) -> bool:
        return True

    __hash__ = None  # type: ignore[assignment]


def _start_kept(locks: RouteLocks) -> None:
    """Broken on purpose: the remembered start limit is kept whatever start offset or start front it is asked for."""
    bookkeeping = locks.bookkeeping

    def broken(t: float, tr: Any, ahead: Any = None) -> None:
        bookkeeping(t, tr, ahead)
        walk = locks._walks.get(tr.train_id)
        if walk is not None:
            walk.start_offset_m = walk.start_front_m = _Same()  # type: ignore[assignment]

    locks.bookkeeping = broken  # type: ignore[method-assign]


def test_a_start_limit_kept_when_its_inputs_moved_is_caught() -> None:
    assert any(_differ(seed, _start_kept, move_start=True)[0] is not None for seed in range(SEEDS))


def test_the_worlds_take_the_short_steps() -> None:
    """The steps that return approaching points held (``_approaching_held``), that visit the one switch in reach
    without looking for candidates (``_single_switch``) and that leave the walk settled (``_still_settled``) are
    all taken, and often."""
    taken = {"approaching": 0, "single": 0, "settled": 0}

    def counted(what: str, answer: Callable[..., Any], taken_if: Callable[[Any], bool]) -> Callable[..., Any]:
        def ask(*args: Any) -> Any:
            out = answer(*args)
            taken[what] += taken_if(out)
            return out

        return ask

    for seed in range(3):
        world = World(seed, every=False)
        locks = world.locks
        locks._approaching_held = counted("approaching", locks._approaching_held, bool)  # type: ignore[method-assign]
        locks._single_switch = counted("single", locks._single_switch, lambda i: i >= 0)  # type: ignore[method-assign]
        locks._still_settled = counted("settled", locks._still_settled, bool)  # type: ignore[method-assign]
        for k in range(STEPS):
            world.step(float(k))
    assert min(taken.values()) > 100, taken


_WALK_FIELDS = ("cursor", "tracked", "next_m", "n_released", "lock_ids")


def _settling_skipped_wrongly(seed: int, still_settled: Callable[..., bool] | None = None) -> tuple[int, int]:
    """Run one world; wherever the walk is left unsettled (``_still_settled``, or ``still_settled`` in its place)
    settle a copy of it the long way (``_settle_walk``, the former code) and compare: (steps where the two walks
    differ, steps left unsettled)."""
    world = World(seed, every=False)
    locks = world.locks
    settled = still_settled or locks._still_settled
    wrong = skipped = 0

    def checked(tr: Any, walk: Any, i: int) -> bool:
        nonlocal wrong, skipped
        out = settled(tr, walk, i)
        if out:
            skipped += 1
            long_way = copy.copy(walk)
            locks._settle_walk(tr, long_way, [i])
            wrong += any(getattr(walk, k) != getattr(long_way, k) for k in _WALK_FIELDS)
        return bool(out)

    locks._still_settled = checked  # type: ignore[method-assign]
    for k in range(STEPS):
        world.step(float(k))
    return wrong, skipped


def test_a_walk_left_unsettled_is_what_settling_gives() -> None:
    """A step that visited one switch and leaves the walk unsettled leaves it exactly as settling it would."""
    results = [_settling_skipped_wrongly(seed) for seed in range(SEEDS)]
    assert sum(w for w, _ in results) == 0
    assert sum(n for _, n in results) > 300, "hardly any walk left unsettled: test too weak"


def test_a_walk_left_unsettled_after_a_change_is_caught() -> None:
    """Broken on purpose: the walk is left unsettled whatever the visit changed (a lock requested or given up)."""
    results = [_settling_skipped_wrongly(seed, lambda tr, walk, i: i == walk.cursor) for seed in range(SEEDS)]
    assert sum(w for w, _ in results) > 0
