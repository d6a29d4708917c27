"""Waits that end by themselves do not stall a run; circular ones still do (railsim/engine/watchdog.py).

Found by fuzzing the mini line: a 550 s t2g outage held a train behind the last position it heard of the train
ahead and the watchdog stopped the run at 300 s "for no reason"; a branch train waited 300 s for a flat crossing
held by a train standing out such an outage, and stalled the same way. Constructed without SUMO (as
tests/test_watchdog_berths.py): plain train objects, a stub route-lock port with ``blockers``.
"""

from __future__ import annotations

from types import SimpleNamespace

from railsim.engine.occupancy import Ahead
from railsim.engine.watchdog import OCCUPANCY_WAIT_M
from tests.test_watchdog_berths import TIMEOUT_S, STEP_S, _run, _train, _watch


def _ahead(follower: str, leader: str, gap_m: float = 180.0) -> dict:
    return {follower: Ahead(leader, 1000.0, 1000.0 - 120.0, gap_m, 0.0), leader: None}


def test_standing_behind_a_train_while_the_radio_is_out_is_not_a_stall() -> None:
    watch, events, _ = _watch()
    out_until_s = 2 * TIMEOUT_S
    watch.radio_out = lambda t, a, b: t < out_until_s and {a, b} == {"F", "L"}
    leader, follower = _train("L", 1000.0), _train("F", 700.0)
    leader.plant.speed_mps = 5.0  # it moved on, far ahead; F heard nothing since the outage began
    far = _ahead("F", "L", gap_m=OCCUPANCY_WAIT_M + 200.0)
    _run(watch, [leader, follower], 0.0, out_until_s - STEP_S, far)
    assert watch.failure is None and events.entries("stalled") == []
    # the outage over, a train still standing there stands for no reason: the clock runs from then
    _run(watch, [leader, follower], out_until_s, out_until_s + TIMEOUT_S + 2 * STEP_S, far)
    stalled = {e.subject: e.detail for e in events.entries("stalled")}
    assert set(stalled) == {"F"} and TIMEOUT_S <= stalled["F"]["standing_s"] < TIMEOUT_S + 2 * STEP_S + 1e-9


class _Locks:
    """A route-lock port that only says who blocks whom (``blockers``), and finds no deadlock."""

    def __init__(self, waits: dict[str, dict[str, tuple[str, ...]]]) -> None:
        self.waits = waits

    def blockers(self, tr: SimpleNamespace) -> dict[str, tuple[str, ...]]:
        return self.waits.get(tr.train_id, {})

    def waiting_for(self, tr: SimpleNamespace) -> list[str]:
        return list(self.waits.get(tr.train_id, {}))


def test_waiting_for_a_lock_held_by_a_busy_train_is_not_a_stall_and_the_wait_passes_along_a_chain() -> None:
    locks = _Locks({"A": {"crossing": ("B",)}, "B": {"sw1": ("C",)}})
    watch, events, _ = _watch(locks)
    a, b, c = _train("A", 100.0), _train("B", 2000.0), _train("C", 4000.0)
    c.sumo_stopped = True  # C dwells (a reason of its own); B waits for C's switch, A for B's crossing
    _run(watch, [a, b, c], 0.0, 2 * TIMEOUT_S)
    assert watch.failure is None and events.entries("stalled") == []
    c.sumo_stopped, c.held_for_route = True, True  # C's dwell is over and its route is not set: no reason now
    _run(watch, [a, b, c], 2 * TIMEOUT_S + STEP_S, 4 * TIMEOUT_S)
    assert {e.subject for e in events.entries("stalled")} == {"A", "B", "C"}
    assert {e.subject: e.detail["waiting_for"] for e in events.entries("stalled")}["A"] == "crossing"


def test_a_circular_lock_wait_is_never_a_legitimate_one() -> None:
    """A and B wait for each other's locks and nobody else is busy: both clocks run (the deadlock search, here
    stubbed out, would name them sooner)."""
    watch, events, _ = _watch(_Locks({"A": {"sw1": ("B",)}, "B": {"sw2": ("A",)}}))
    _run(watch, [_train("A", 100.0), _train("B", 2000.0)], 0.0, TIMEOUT_S + 2 * STEP_S)
    assert {e.subject for e in events.entries("stalled")} == {"A", "B"}


def test_standing_close_behind_a_train_that_stands_for_a_reason_is_not_a_stall() -> None:
    """A follower stood 300 s behind its leader, held for it at a platform too short for both (the fuzz case):
    the leader stands for a reason, so does the train behind it; once the leader stands for none, both clocks run."""
    watch, events, _ = _watch()
    leader, follower = _train("L", 1000.0), _train("F", 840.0)
    leader.sumo_stopped = True  # it dwells (held for its follower: SUMO still holds it)
    _run(watch, [leader, follower], 0.0, 2 * TIMEOUT_S, _ahead("F", "L"))
    assert watch.failure is None and events.entries("stalled") == []
    leader.held_for_route = True  # its dwell is over and its route is not set: no reason now
    _run(watch, [leader, follower], 2 * TIMEOUT_S + STEP_S, 4 * TIMEOUT_S, _ahead("F", "L"))
    assert {e.subject for e in events.entries("stalled")} == {"L", "F"}
