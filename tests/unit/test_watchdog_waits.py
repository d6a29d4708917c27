"""Waits that end by themselves do not stall a run; circular ones still do (railsim/engine/watchdog.py).

Found by fuzzing the mini line: a 550 s t2g outage held a train behind the last position it heard of the train
ahead and the watchdog stopped the run at 300 s "for no reason"; a branch train waited 300 s for a flat crossing
held by a train standing out such an outage, and stalled the same way. Constructed without SUMO (as
tests/unit/test_watchdog_berths.py): plain train objects, a stub route-lock port with ``blockers``.
"""

from __future__ import annotations

from types import SimpleNamespace

from railsim.engine.occupancy import Ahead
from railsim.engine.watchdog import OCCUPANCY_WAIT_M
from tests.unit.test_watchdog_berths import STEP_S, TIMEOUT_S, _run, _train, _watch


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


def _reference_fixed_point(waits: dict[str, set[str]], busy: set[str]) -> set[str]:
    """The rule as written: add any waiting train that waits for a busy or already found one, until none is added."""
    found: set[str] = set()
    grown = True
    while grown:
        grown = False
        for train_id, others in waits.items():
            if train_id not in found and not others.isdisjoint(busy | found):
                found.add(train_id)
                grown = True
    return found


def test_waits_along_long_chains_and_random_graphs_match_the_rule_as_written() -> None:
    """The watchdog grows the waits from the busy trains along reversed edges (linear); the answer is the rule's
    least fixed point — a chain listed back to front (one train per pass for the rule as written), cycles with and
    without a busy train in reach, and random wait graphs."""
    import random

    n = 300
    chain = {f"w{i}": {f"w{i - 1}" if i else "B"} for i in reversed(range(n))}  # w0 waits for B, w1 for w0, ...
    chain |= {"c1": {"c2"}, "c2": {"c1"}, "c3": {"c1", "w5"}}  # a closed cycle; c3 also waits for a chain train
    graphs = [(chain, {"B"})]
    rng = random.Random(3)
    for _ in range(200):
        ids = [f"t{i}" for i in range(rng.randrange(1, 30))]
        busy = {i for i in ids if rng.random() < 0.2}
        waits = {i: {rng.choice(ids) for _ in range(rng.randrange(0, 3))} - {i} for i in ids if i not in busy}
        graphs.append((waits, busy))
    for waits, busy in graphs:
        watch, _, _ = _watch(_Locks({w: {f"sw_{o}": (o,) for o in others} for w, others in waits.items()}))
        got = watch._waiting_for_busy([_train(w, 0.0) for w in waits], set(busy), {})  # type: ignore[list-item]
        assert got == _reference_fixed_point(waits, busy)
    watch, _, _ = _watch(_Locks({w: {f"sw_{o}": (o,) for o in others} for w, others in chain.items()}))
    got = watch._waiting_for_busy([_train(w, 0.0) for w in chain], {"B"}, {})  # type: ignore[list-item]
    assert {f"w{i}" for i in range(n)} | {"c3"} == got and not {"c1", "c2"} & got
