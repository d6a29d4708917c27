"""The stall watchdog's cheap path (:meth:`railsim.engine.watchdog.StallWatch.check`) keeps the clocks it kept.

A moving train is counted busy before anything else about it is read, and the standing clocks are touched only for
the busy trains (when any clock runs) and the trains that wait for no busy one. The check as it was before is kept
here word for word (:class:`ReferenceWatch`) and both run side by side over random runs: trains that move, dwell,
are held for a departure or for their route, stand behind a train ahead (within the occupancy wait or far from
it), wait at a berth, for a lock held by another, behind a radio outage; trains coming on and going off the line;
a deadlock search that sometimes finds one. After every step both must hold the same clocks (in the same order:
the reports and the deadlock search read them in order), the same failure and the same event log.

:func:`test_a_broken_fast_path_is_caught` breaks the fast path on purpose and checks the comparison catches it.
"""

from __future__ import annotations

from collections.abc import Callable
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from railsim.engine import watchdog
from railsim.engine.events.log import EventLog
from railsim.engine.occupancy import Ahead
from railsim.engine.settings import EngineSettings
from railsim.engine.watchdog import OCCUPANCY_WAIT_M, STANDSTILL_MPS, StallWatch
from tests.helpers import standing_train

SEEDS, STEPS = 6, 6000
TIMEOUT_S = 60.0
IDS = tuple(f"t{i}" for i in range(7))


class ReferenceWatch(StallWatch):
    """``StallWatch.check`` before the cheap path, word for word."""

    def check(self, t: float, active: list[Any], ahead: Any = None) -> None:
        ahead = ahead or {}
        busy: set[str] = set()  # moving, or standing for a reason of its own
        waiting: list[Any] = []
        for tr in active:
            held = tr.hold_until_s is not None and t < tr.hold_until_s  # a unit early for its next departure
            dwelling = (tr.sumo_stopped or tr.sumo_stopped_now) and not tr.held_for_route
            if tr.plant.speed_mps > STANDSTILL_MPS or dwelling or held or self._radio_wait(t, tr, ahead):
                busy.add(tr.train_id)
            else:
                waiting.append(tr)
        busy |= self._waiting_for_busy(waiting, busy, ahead)
        for tr in active:
            if tr.train_id in busy:
                self.standing_since.pop(tr.train_id, None)
            elif tr.train_id not in self.standing_since:
                self.standing_since[tr.train_id] = (t, tr)
        self._deadlock(t, ahead)
        self._report(t, self.settings.stall_timeout_s, "")


class World:
    """Seven trains whose states change now and then (so clocks run out), and the ports the watchdog asks."""

    def __init__(self, seed: int) -> None:
        self.rng = np.random.default_rng(seed)
        self.trains = {tid: standing_train(tid) for tid in IDS}
        self.blocked: dict[str, dict[str, tuple[str, ...]]] = {}
        self.radio_cut: set[tuple[str, str]] = set()
        self.ahead: dict[str, Ahead | None] = {}
        self.berth_waits: dict[str, tuple[str, str]] = {}
        self.active: list[Any] = list(self.trains.values())

    # the route-lock port
    def blockers(self, tr: Any) -> dict[str, tuple[str, ...]]:
        return self.blocked.get(tr.train_id, {})

    def waiting_for(self, tr: Any) -> list[str]:
        return sorted(self.blocked.get(tr.train_id, {}))

    def deadlock(self, standing: list[Any], behind: dict[str, tuple[str, str]]) -> Any:
        ids = [tr.train_id for tr in standing]
        if len(ids) >= 3 and behind:
            return ids, [resource for _, resource in behind.values()]
        return None

    def radio_out(self, t: float, a: str, b: str) -> bool:
        return (a, b) in self.radio_cut

    def step(self, t: float) -> None:
        rng = self.rng
        for tr in self.trains.values():
            if rng.random() < 0.08:
                tr.plant.speed_mps = float(rng.choice([0.0, 0.0, STANDSTILL_MPS, 2 * STANDSTILL_MPS, 12.0]))
            if rng.random() < 0.05:
                tr.sumo_stopped, tr.sumo_stopped_now = bool(rng.random() < 0.3), bool(rng.random() < 0.1)
                tr.held_for_route = bool(rng.random() < 0.3)
            if rng.random() < 0.03:
                tr.hold_until_s = None if rng.random() < 0.5 else t + float(rng.uniform(-5.0, 30.0))
            if rng.random() < 0.01:
                tr.arrived_s = None if tr.arrived_s is not None else t
            if rng.random() < 0.02:
                tr.on_line = not tr.on_line
        if rng.random() < 0.05:  # who stands behind whom, and how close
            self.ahead = {}
            for tid in IDS:
                other = IDS[int(rng.integers(len(IDS)))]
                gap_m = float(rng.choice([OCCUPANCY_WAIT_M - 1.0, OCCUPANCY_WAIT_M, OCCUPANCY_WAIT_M + 1.0, 900.0]))
                self.ahead[tid] = None if other == tid or rng.random() < 0.3 else Ahead(other, 0.0, 0.0, gap_m, 0.0)
        if rng.random() < 0.05:
            self.berth_waits.clear()
            for tid in rng.choice(IDS, size=int(rng.integers(3)), replace=False):
                self.berth_waits[str(tid)] = ("s", IDS[int(rng.integers(len(IDS)))])
        if rng.random() < 0.05:
            self.blocked = {
                str(tid): {"sw": (IDS[int(rng.integers(len(IDS)))],)}
                for tid in rng.choice(IDS, size=int(rng.integers(4)), replace=False)
            }
        if rng.random() < 0.05:
            self.radio_cut = {(IDS[int(rng.integers(7))], IDS[int(rng.integers(7))]) for _ in range(3)}
        if rng.random() < 0.03:  # trains come on and go off the line; the order of the active list changes
            self.active = [self.trains[str(tid)] for tid in rng.permutation(IDS) if rng.random() < 0.85]


def _watch(cls: type[StallWatch], world: World) -> StallWatch:
    settings = EngineSettings(stall_timeout_s=TIMEOUT_S)
    return cls(EventLog(), settings, world, SimpleNamespace(waiting=world.berth_waits), world.radio_out)


def _state(w: StallWatch) -> tuple[Any, ...]:
    return [(k, s) for k, (s, _) in w.standing_since.items()], w.failure, w.events.rows()


def _first_difference(seed: int, steps: int = STEPS) -> str | None:
    """Run both checks side by side over one random world; the first step where they differ, or None."""
    world = World(seed)
    new, ref = _watch(StallWatch, world), _watch(ReferenceWatch, world)
    for k in range(steps):
        t = float(k)
        world.step(t)
        ahead = world.ahead if k % 7 else None
        new.check(t, world.active, ahead)
        ref.check(t, world.active, ahead)
        if _state(new) != _state(ref):
            return f"step {k}: {_state(new)} != {_state(ref)}"
        if ref.failure is not None:  # a run ends at its first failure: a new one starts
            new, ref = _watch(StallWatch, world), _watch(ReferenceWatch, world)
    return None


@pytest.mark.parametrize("seed", range(SEEDS))
def test_the_cheap_path_keeps_the_clocks_it_kept(seed: int) -> None:
    assert _first_difference(seed) is None


def test_the_worlds_stall_and_deadlock() -> None:
    """The random runs reach stalls and deadlocks, and clocks that start and stop (the comparison has teeth)."""
    world = World(0)
    ref = _watch(ReferenceWatch, world)
    kinds: list[str] = []
    for k in range(STEPS):
        world.step(float(k))
        ref.check(float(k), world.active, world.ahead)
        if ref.failure is not None:
            kinds.append(ref.failure.split(":")[0])
            ref = _watch(ReferenceWatch, world)
    assert kinds.count("stalled") >= 2 and kinds.count("deadlock") >= 2, kinds


def _no_clock_for_radio_waits(self: StallWatch, t: float, tr: Any, ahead: Any) -> bool:
    return False


def _busy_trains_keep_clocks(self: StallWatch, t: float, active: list[Any], ahead: Any = None) -> None:
    ahead = ahead or {}
    waiting = [tr for tr in active if tr.plant.speed_mps <= STANDSTILL_MPS]
    busy = {tr.train_id for tr in active if tr.plant.speed_mps > STANDSTILL_MPS}
    busy |= self._waiting_for_busy(waiting, busy, ahead)
    for tr in waiting:
        if tr.train_id not in busy and tr.train_id not in self.standing_since:
            self.standing_since[tr.train_id] = (t, tr)
    self._deadlock(t, ahead)
    self._report(t, self.settings.stall_timeout_s, "")


@pytest.mark.parametrize(
    "name, broken", [("_radio_wait", _no_clock_for_radio_waits), ("check", _busy_trains_keep_clocks)]
)
def test_a_broken_fast_path_is_caught(monkeypatch: pytest.MonkeyPatch, name: str, broken: Callable[..., Any]) -> None:
    monkeypatch.setattr(ReferenceWatch, name, getattr(ReferenceWatch, name))  # the reference keeps its own
    monkeypatch.setattr(watchdog.StallWatch, name, broken)
    assert any(_first_difference(seed) is not None for seed in range(SEEDS))
