"""The stall watchdog knows platform berths (railsim/engine/watchdog.py, railsim/engine/platforms.py).

A train standing at the limit of a platform the train ahead occupies waits for that train, as behind a platform
entry signal at danger. Constructed on the event layer without SUMO (as tests/unit/test_locking_deadlock.py): the
berth port's ``waiting`` map says who stands at a berth limit for whose platform, the trains are plain objects
with the fields the watchdog reads. Three cases:

* the occupant dwells (a reason that ends by itself): the follower's wait is legitimate, no stall however long;
* the occupant stands for no reason: the follower's clock runs from then, and its ``stalled`` event names the
  platform and the occupant;
* the occupant waits for a switch the follower holds: a circular wait through the berth, found as a ``deadlock``
  with the resource ``platform:S`` — the berth is an edge of the wait-for graph.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from railsim.engine.events import EventLayer, Interlocking, Switch
from railsim.engine.events.log import EventLog
from railsim.engine.extensions import ExtensionSet
from railsim.engine.locking import RouteLocks
from railsim.engine.occupancy import Ahead
from railsim.engine.settings import EngineSettings
from railsim.engine.watchdog import DEADLOCK_CONFIRM_S, OCCUPANCY_WAIT_M, StallWatch
from tests.helpers import standing_train

TIMEOUT_S = 300.0
STEP_S = 1.0


def _train(tid: str, front_m: float) -> SimpleNamespace:
    """A standing train on the line, with the fields the watchdog and the route-lock port read."""
    return standing_train(tid, front_m, locks={}, released=set())


def _watch(locks: object = None) -> tuple[StallWatch, EventLog, SimpleNamespace]:
    events = EventLog()
    berths = SimpleNamespace(waiting={})
    settings = EngineSettings(stall_timeout_s=TIMEOUT_S)
    return StallWatch(events, settings, locks if locks is not None else SimpleNamespace(), berths), events, berths


def _run(watch: StallWatch, trains: list[SimpleNamespace], t0_s: float, t1_s: float, ahead: dict | None = None) -> None:
    t = t0_s
    while t <= t1_s and watch.failure is None:
        watch.check(t, trains, ahead)  # type: ignore[arg-type]
        t += STEP_S


def test_waiting_behind_a_dwelling_occupant_is_not_a_stall() -> None:
    watch, events, berths = _watch()
    occupant, follower = _train("O", 1000.0), _train("F", 700.0)
    occupant.sumo_stopped = True  # it dwells at the platform (a long dwell: the wait is legitimate)
    berths.waiting["F"] = ("s2", "O")
    _run(watch, [occupant, follower], 0.0, 2 * TIMEOUT_S)
    assert watch.failure is None and events.entries("stalled") == []
    # the same follower, standing there without the berth wait, stalls (the check itself can fail)
    berths.waiting.clear()
    _run(watch, [occupant, follower], 2 * TIMEOUT_S + STEP_S, 4 * TIMEOUT_S)
    assert watch.failure is not None and [e.subject for e in events.entries("stalled")] == ["F"]


def test_waiting_behind_an_occupant_that_stands_for_no_reason_runs_the_clock_and_names_it() -> None:
    watch, events, berths = _watch()
    occupant, follower = _train("O", 1000.0), _train("F", 700.0)
    occupant.sumo_stopped = True
    berths.waiting["F"] = ("s2", "O")
    _run(watch, [occupant, follower], 0.0, 200.0)  # dwelling: no clock for either
    occupant.sumo_stopped, occupant.held_for_route = True, True  # its dwell is over, its route is not set
    _run(watch, [occupant, follower], 201.0, 201.0 + TIMEOUT_S + 2 * STEP_S)
    stalled = {e.subject: e.detail for e in events.entries("stalled")}
    assert set(stalled) == {"O", "F"}
    assert stalled["F"]["waiting_for"] == "platform:s2(O)"
    assert stalled["F"]["standing_s"] >= TIMEOUT_S and stalled["F"]["standing_s"] < TIMEOUT_S + 2 * STEP_S + 1e-9


def test_a_circular_wait_through_a_platform_berth_is_a_deadlock() -> None:
    layer = EventLayer(t0_s=0.0, rng=np.random.default_rng(1))
    il = Interlocking(layer)
    il.add_switch(Switch("p1", throw_time_s=0.0))
    locks = RouteLocks(
        SimpleNamespace(trains={}),
        il,
        SimpleNamespace(),
        SimpleNamespace(),
        EngineSettings(),
        ExtensionSet(),
        SimpleNamespace(now_s=0.0),
    )
    watch, events, berths = _watch(locks)
    # F stands at the berth limit of s2 behind O, holding the points p1 it has passed over; O, at the platform,
    # has finished its dwell and waits for p1 to leave (held for its route): neither can move
    occupant, follower = _train("O", 1000.0), _train("F", 400.0)
    train_m = 120.0
    ahead = {"F": Ahead("O", 1000.0, 1000.0 - train_m, 600.0 - train_m, 0.0), "O": None}
    assert ahead["F"].gap_m > OCCUPANCY_WAIT_M  # F stands too far back for the occupancy rule ("ahead:O")
    follower.locks["p1"] = il.request(("F",), "p1", "normal")
    layer.advance_to(0.0)
    occupant.locks["p1"] = il.request(("O",), "p1", "reverse")
    layer.advance_to(1.0)
    occupant.sumo_stopped, occupant.held_for_route = True, True
    berths.waiting["F"] = ("s2", "O")
    _run(watch, [occupant, follower], 1.0, 1.0 + DEADLOCK_CONFIRM_S + 2 * STEP_S, ahead)
    (dl,) = events.entries("deadlock")
    assert sorted(dl.detail["trains"]) == ["F", "O"] and dl.detail["resources"] == ["p1", "platform:s2"]
    assert watch.failure is not None and "deadlock" in watch.failure
    # without the berth edge the same standstill is no cycle (the occupancy rule does not reach F)
    watch2, events2, _ = _watch(locks)
    _run(watch2, [occupant, follower], 1.0, 1.0 + DEADLOCK_CONFIRM_S + 2 * STEP_S, ahead)
    assert events2.entries("deadlock") == []
