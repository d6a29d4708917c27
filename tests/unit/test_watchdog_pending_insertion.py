"""A train handed to SUMO that SUMO never puts on stalls the run with a report, never silently.

Found on Jena's tram network: a tram handed to SUMO at its terminus stayed in SUMO's insertion queue for the
rest of the run while railsim counted it as on the line (it held its single-track section); it had no trace row
and no stall report. :meth:`railsim.engine.watchdog.StallWatch.pending` times such a wait while the train's spot is
free of our trains and fails the run after ``stall_timeout_s``."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

from railsim.engine.events.log import EventLog
from railsim.engine.settings import EngineSettings
from railsim.engine.watchdog import StallWatch


def _train(train_id: str) -> Any:
    view = SimpleNamespace(edges=["e0", "e1"], edge_at=lambda m: 0 if m < 100.0 else 1)
    return SimpleNamespace(train_id=train_id, front_m=29.0, view=view)


def _watch() -> tuple[StallWatch, EventLog]:
    events = EventLog()
    return StallWatch(events, EngineSettings(stall_timeout_s=300.0), locks=None), events


def test_a_train_sumo_never_puts_on_while_its_spot_is_free_stalls_the_run_with_an_event() -> None:
    watch, events = _watch()
    tr = _train("5_ernst-abbe-platz_lobeda-ost.000")
    for k in range(601):
        watch.pending(300.0 + 0.5 * k, [tr], lambda _tr: None)
        if k < 600:
            assert watch.failure is None, k
    assert watch.failure is not None and "never put on" in watch.failure
    stalled = events.entries("stalled")
    assert len(stalled) == 1 and stalled[0].subject == tr.train_id
    assert stalled[0].detail["waiting_for"] == "insertion by SUMO"


def test_a_wait_for_a_train_on_the_spot_is_not_a_stall_and_the_clock_restarts_once_it_leaves() -> None:
    watch, _ = _watch()
    tr = _train("follower.000")
    for k in range(2000):  # 1,000 s behind a leader dwelling on the spot
        watch.pending(0.5 * k, [tr], lambda _tr: "track occupied by leader.000")
    assert watch.failure is None
    for k in range(500):  # the spot is free: 250 s < 300 s
        watch.pending(1000.0 + 0.5 * k, [tr], lambda _tr: None)
    assert watch.failure is None
    watch.pending(1250.0, [], lambda _tr: None)  # put on: forgotten
    assert not watch.pending_since
