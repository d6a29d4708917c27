"""The departure rules asked of the trains near the spot give the answer of asking every train on the line.

:class:`railsim.engine.insertion_reach.NearTrains` hands the dispatcher only the trains that could hold a
departure; the full scan over ``fleet.active()`` (the rules' old loop, written out here as the oracle) must give
the same blocker string, for the same first train in scenario order, on random fleets over merging, diverging
and twice-passing routes, with trains whose tails lie before their route begins, switch locks held far ahead,
starts in motion, and the index kept across questions while trains are put on, moved and withdrawn.
"""

from __future__ import annotations

import random
from collections import Counter
from types import SimpleNamespace

from network.topology import RouteInfo, RouteSwitch
from railsim.engine.events.log import EventLog
from railsim.engine.fleet import ON_LINE, Fleet
from railsim.engine.insertion import Dispatcher
from railsim.engine.routeview import RouteView
from railsim.engine.settings import EngineSettings
from railsim.engine.train import TrainRuntime
from railsim.physics import dynamics
from railsim.physics.vehicle import preset

EDGE_M = {"a0": 300.0, "a1": 250.0, "a2": 400.0, "a3": 200.0, "a4": 350.0, "a5": 300.0, "a6": 300.0, "a7": 300.0}
EDGE_M |= {"b0": 280.0, "b1": 150.0, "c4": 220.0, "c5": 300.0, "c6": 300.0, "loop": 350.0, "d0": 90.0}
ROUTES = {  # merging at a2 (b), diverging after a3 (c), passing a2 and a3 twice (loop), starting mid-line (d)
    "main": ("a0", "a1", "a2", "a3", "a4", "a5", "a6", "a7"),
    "merge": ("b0", "b1", "a2", "a3", "a4"),
    "diverge": ("a0", "a1", "a2", "a3", "c4", "c5", "c6"),
    "twice": ("a1", "a2", "a3", "loop", "a2", "a3", "a4"),
    "mid": ("a3", "a4", "a5", "a6"),
    "short": ("d0", "a2", "a3"),
}
KINDS = ("ahead is less than", "track occupied by", "could not stop", "holds the route through here")
VEHICLES = (preset("cq3_6car"), preset("hst_203m"), preset("paper002_point_mass"))


def _route(rid: str, rng: random.Random) -> RouteInfo:
    starts, m = [], 0.0
    for e in ROUTES[rid]:
        starts.append(m)
        m += EDGE_M[e] + rng.choice((0.0, 4.5, 17.0))  # the junction lane after an edge differs route by route
    switches = tuple(RouteSwitch(f"sw{k}", s + 5.0, "normal") for k, s in enumerate(starts[1:]) if k % 2 == 0)
    return RouteInfo(rid, ROUTES[rid], tuple(starts), m, (), (), (), switches)


def _fleet(rng: random.Random, n: int) -> tuple[Dispatcher, list[TrainRuntime]]:
    views = {rid: RouteView(_route(rid, rng)) for rid in ROUTES}
    fleet = Fleet("<test>")
    trains = []
    for k in range(n):
        view = views[rng.choice(list(ROUTES))]
        vehicle = rng.choice(VEHICLES)
        trip = SimpleNamespace(trip_id=f"t{k:02d}", vehicle=vehicle, route=view.route)
        tr = TrainRuntime(trip=trip, view=view, controllers={})  # type: ignore[arg-type]
        _place(tr, rng)
        fleet.trains[tr.train_id] = tr
        if tr.status in ON_LINE:  # on the line: the fleet lists it (as Fleet.start does for a real run)
            fleet.start(tr, tr.status)
        trains.append(tr)
    partners = {(a.train_id, b.train_id) for a in trains for b in trains if rng.random() < 0.05}
    dispatcher = Dispatcher(
        fleet,
        SimpleNamespace(now_s=0.0),  # type: ignore[arg-type]
        EventLog(),
        EngineSettings(),
        SimpleNamespace(partners=lambda a, b: (a, b) in partners),  # type: ignore[arg-type]
        lambda tr: None,
        lambda tr: None,
        lambda tid: False,
        (),
        None,  # type: ignore[arg-type]
    )
    return dispatcher, trains


def _place(tr: TrainRuntime, rng: random.Random) -> None:
    """A random state: on the line or not, anywhere on its route (a tail before its start now and then), a
    random speed, switch locks now and then (some released)."""
    tr.status = rng.choice(("scheduled", "inserting", "running", "running", "running", "arrived"))
    tr.front_m = rng.uniform(-0.02, 1.02) * tr.view.length_m if rng.random() < 0.9 else rng.uniform(0.0, 60.0)
    tr.edge_i = tr.view.edge_at(tr.front_m)
    tr.plant = dynamics.PlantState(speed_mps=rng.choice((0.0, 0.0, rng.uniform(0.0, 40.0))))
    tr.locks, tr.released = {}, set()
    if rng.random() < 0.3:
        held = [rs.switch_id for rs in tr.trip.route.switches if rng.random() < 0.6]
        tr.locks = {sid: object() for sid in held}
        tr.released = {sid for sid in held if rng.random() < 0.3}


# ---------------------------------------------------------------------- the oracle: the old loops over every train
def full_blocker(d: Dispatcher, tr: TrainRuntime, depart_m: float) -> str | None:
    for other in d.fleet.active():
        if other is tr:
            continue
        reason = d.blocker_of(tr, depart_m, other)
        if reason is not None:
            return reason
    return None


def full_collision_course(
    d: Dispatcher, tr: TrainRuntime, depart_m: float, v_mps: float, approaching_only: bool
) -> str | None:
    own_stop_m = dynamics.least_stop_distance_m(tr.trip.vehicle, v_mps, tr.view.gradient_at(depart_m))
    for other in d.fleet.active():
        if other is tr:
            continue
        reason = d.collision_course_with(tr, depart_m, own_stop_m, other, approaching_only)
        if reason is not None:
            return reason
    return None


def full_guard(d: Dispatcher, tr: TrainRuntime) -> str | None:
    """The train :meth:`Dispatcher.guard_pending` would withdraw ``tr`` for (the old loop), or None."""
    length_m = tr.trip.vehicle.length_m
    for other in d.fleet.active():
        if other is tr or other.status != "running":
            continue
        mapped = other.view.map_body(tr.view, tr.front_m, length_m)
        if mapped is None or mapped[1] < other.front_m:
            continue
        if d._cannot_stop_behind(other, mapped[1] - other.front_m):
            return other.train_id
    return None


def _ask(d: Dispatcher, tr: TrainRuntime, rng: random.Random, tally: Counter[str]) -> None:
    """One random question of each kind, indexed and full, compared exactly."""
    length_m = tr.trip.vehicle.length_m
    depart_m = rng.choice((rng.uniform(0.0, tr.view.length_m), rng.uniform(0.0, length_m), tr.view.length_m))
    got, want = d.blocker(tr, depart_m), full_blocker(d, tr, depart_m)
    assert got == want, (tr.train_id, depart_m, got, want)
    v_mps = rng.choice((0.0, 8.0, 16.7, 30.0, 60.0))
    only = rng.random() < 0.3
    got_c, want_c = d.collision_course(tr, depart_m, v_mps, only), full_collision_course(d, tr, depart_m, v_mps, only)
    assert got_c == want_c, (tr.train_id, depart_m, v_mps, only, got_c, want_c)
    guard_for = full_guard(d, tr)
    if guard_for is not None:
        assert any(o.train_id == guard_for for o in d.near.near(tr, tr.front_m, length_m, 0.0)), guard_for
    for key, answer in (("blocker", want), ("collision", want_c), ("guard", guard_for)):
        tally[key + (" held" if answer is not None else " free")] += 1
    for kind in KINDS:
        tally[kind] += want is not None and kind in want
    tally["asked"] += 1
    tally["candidates"] += len(d.near.near(tr, depart_m, length_m, d.settings.insertion_margin_m))
    tally["on line"] += len(d.fleet.active())


def test_the_trains_near_a_departure_give_the_full_scans_answer() -> None:
    rng = random.Random(20261129)
    tally: Counter[str] = Counter()
    for _ in range(120):
        d, trains = _fleet(rng, rng.choice((6, 15, 30)))
        for _ in range(12):
            _ask(d, rng.choice(trains), rng, tally)
    # every rule was met, both ways: the comparison is not between two Nones
    for key in ("blocker held", "blocker free", "collision held", "collision free", "guard held", "guard free"):
        assert tally[key] >= 20, (key, tally)
    for kind in KINDS:
        assert tally[kind] >= 5, (kind, tally)
    assert tally["candidates"] < 0.7 * tally["on line"], tally  # and the index does leave trains out


def test_the_index_follows_the_line_between_questions() -> None:
    """Kept across questions: trains put on (one by one, as a timetable at t = 0), moved, given locks, withdrawn."""
    rng = random.Random(7)
    tally: Counter[str] = Counter()
    for _ in range(40):
        d, trains = _fleet(rng, 25)
        for _ in range(10):
            change = rng.random()
            tr = rng.choice(trains)
            if change < 0.4:  # put on by the dispatcher (as insert does), then asked again at once
                d.fleet.start(tr, "inserting")
                tr.front_m = rng.uniform(0.0, tr.view.length_m)
                tr.plant = dynamics.PlantState(speed_mps=rng.uniform(0.0, 20.0))
                d.near.inserted(tr)
            elif change < 0.6:  # a step: every train on the line moved on
                for t in d.fleet.active():
                    t.front_m += t.plant.speed_mps * 0.5
            elif change < 0.7:
                tr.locks = {rs.switch_id: object() for rs in tr.trip.route.switches}
            elif change < 0.8:
                tr.status = "scheduled"  # withdrawn
            else:
                tr.plant = dynamics.PlantState(speed_mps=rng.uniform(0.0, 40.0))
            for _ in range(3):
                _ask(d, rng.choice(trains), rng, tally)
    assert tally["blocker held"] >= 20 and tally["blocker free"] >= 20, tally


def _twin_fleets(
    seed: int, n: int
) -> tuple[tuple[Dispatcher, list[TrainRuntime]], tuple[Dispatcher, list[TrainRuntime]]]:
    """Two identical fleets (the same draws), each with a dispatcher that can withdraw and hold trains."""
    twins = []
    for _ in range(2):
        d, trains = _fleet(random.Random(seed), n)
        d.layer = SimpleNamespace(now_s=0.0, at=lambda *a: None)  # type: ignore[assignment]
        d.bridge = SimpleNamespace(remove=lambda sumo_id: None)  # type: ignore[assignment]
        twins.append((d, trains))
    return twins[0], twins[1]


def test_guard_pending_and_the_watchdogs_questions_after_it_give_the_full_scans_answers() -> None:
    """The loop's order: guard_pending withdraws trains a running train could not stop for, then the watchdog asks
    blocker_at_front of every train still waiting (answered from guard_pending's look at the line)."""
    checked = withdrawn = held = 0
    for seed in range(150):
        (d, trains), (old, old_trains) = _twin_fleets(seed, 20)
        pending = [tr for tr in trains if tr.status == "inserting"]
        for tr in pending:
            tr.plant = dynamics.PlantState(speed_mps=0.0)
        old_pending = [old.fleet.trains[tr.train_id] for tr in pending]
        for tr in old_pending:
            tr.plant = dynamics.PlantState(speed_mps=0.0)
        d.guard_pending(pending)
        for tr in old_pending:  # the old loop, withdrawing as it goes
            for other in old.fleet.active():
                if other is tr or other.status != "running":
                    continue
                mapped = other.view.map_body(tr.view, tr.front_m, tr.trip.vehicle.length_m)
                if mapped is None or mapped[1] < other.front_m:
                    continue
                if old._cannot_stop_behind(other, mapped[1] - other.front_m):
                    tr.status = "scheduled"
                    break
        assert [t.status for t in trains] == [t.status for t in old_trains], seed
        withdrawn += sum(t.status == "scheduled" for t in pending)
        for tr, old_tr in zip(pending, old_pending):
            if tr.status != "inserting":
                continue
            got, want = d.blocker_at_front(tr), full_blocker(old, old_tr, old_tr.front_m)
            assert got == want, (seed, tr.train_id, got, want)
            checked += 1
            held += want is not None
    assert withdrawn >= 10 and checked >= 100 and 10 <= held < checked, (withdrawn, checked, held)
