"""A flat crossing is asked for only with its exit clear: room for the train beyond it in front of the train
ahead, constructed without SUMO. On Jena's tram peak a tram that went in behind a tram waiting for the next
crossing stood in this one, and the opposing tram waited in that next crossing for this one (a deadlock at
1,642.5 s).
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

from tests.unit.test_lock_requests import _crossing_locks, _stop, _train


TRAM_M = 27.0


def _tram(tid: str, front_m: float, destination_m: float) -> Any:
    stops = [_stop("A", 0.0, 30.0, origin=True), _stop("Z", destination_m, 1.0, destination=True)]
    tr = _train(tid, front_m, stops)
    tr.trip.vehicle.length_m = TRAM_M
    return tr


def test_a_crossing_is_asked_for_only_with_room_beyond_it_in_front_of_the_train_ahead() -> None:
    tr = _tram("t", 900.0, 3000.0)
    locks = _crossing_locks(tr)
    crossing = locks.sections["t"][0]
    exit_m = crossing.end_m + locks.settings.clearance_m
    blocked = SimpleNamespace(train_id="ahead", front_m=exit_m + 20.0 + TRAM_M, rear_m=exit_m + 20.0)
    locks.bookkeeping(1.0, tr, blocked)
    assert locks.section_requests["t"] == {}, "asked for a crossing it could not leave"
    clear = SimpleNamespace(train_id="ahead", front_m=exit_m + 40.0 + TRAM_M, rear_m=exit_m + 40.0)
    locks.bookkeeping(2.0, tr, clear)
    assert locks.section_requests["t"][crossing.section_id].granted
