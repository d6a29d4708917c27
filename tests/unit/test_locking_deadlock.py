"""Circular waits on switch locks are found (RouteLocks.deadlock): the wait-for graph of lock holders and FIFO
queues, constructed on purpose on the event layer without SUMO."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from railsim.engine.events import EventLayer, Interlocking, Switch
from railsim.engine.extensions import ExtensionSet
from railsim.engine.locking import RouteLocks
from railsim.engine.settings import EngineSettings


def _train(tid: str) -> SimpleNamespace:
    return SimpleNamespace(train_id=tid, locks={}, released=set())


def _locks(interlocking: Interlocking) -> RouteLocks:
    return RouteLocks(
        SimpleNamespace(trains={}),
        interlocking,
        SimpleNamespace(),
        SimpleNamespace(),
        EngineSettings(),
        ExtensionSet(),
        SimpleNamespace(now_s=0.0),
    )


def _setup() -> tuple[EventLayer, Interlocking, RouteLocks]:
    layer = EventLayer(t0_s=0.0, rng=np.random.default_rng(1))
    il = Interlocking(layer)
    for sid in ("s1", "s2"):
        il.add_switch(Switch(sid, throw_time_s=0.0))
    return layer, il, _locks(il)


def test_two_trains_each_holding_what_the_other_needs_is_a_deadlock() -> None:
    layer, il, locks = _setup()
    a, b = _train("A"), _train("B")
    a.locks["s1"] = il.request(("A",), "s1", "normal")
    b.locks["s2"] = il.request(("B",), "s2", "normal")
    layer.advance_to(0.0)
    a.locks["s2"] = il.request(("A",), "s2", "normal")
    b.locks["s1"] = il.request(("B",), "s1", "normal")
    layer.advance_to(1.0)
    assert locks.held_by(a) == ["s1"] and locks.waiting_for(a) == ["s2"]
    assert locks.blockers(a) == {"s2": ("B",)}
    found = locks.deadlock([a, b])
    assert found is not None
    trains, switches = found
    assert sorted(trains) == ["A", "B"] and switches == ["s1", "s2"]


def test_waiting_in_a_queue_without_a_cycle_is_not_a_deadlock() -> None:
    layer, il, locks = _setup()
    a, b, c = _train("A"), _train("B"), _train("C")
    a.locks["s1"] = il.request(("A",), "s1", "normal")
    layer.advance_to(0.0)
    b.locks["s1"] = il.request(("B",), "s1", "normal")
    c.locks["s1"] = il.request(("C",), "s1", "normal")
    layer.advance_to(1.0)
    assert locks.blockers(c) == {"s1": ("A", "B")}  # the holder and the request queued ahead
    assert locks.deadlock([a, b, c]) is None
    il.release("A", "s1")
    a.released.add("s1")
    layer.advance_to(2.0)
    assert locks.held_by(b) == ["s1"] and locks.deadlock([a, b, c]) is None
