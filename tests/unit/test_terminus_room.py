"""Room beyond single track and flat crossings, constructed without SUMO (each case from Jena's tram peak).

* A train whose trip ends at a terminus beyond a single-track section (turning there or leaving service) is
  granted the section only while the terminus has room for it beside the units standing there and the trains
  already let in (four trams granted the Zwätzen Schleife approach together filled the loop; the last stood in
  the section behind a unit waiting to leave through it).
* A flat crossing is asked for only with its exit clear: room for the train beyond it in front of the train
  ahead (a tram that went in behind a tram waiting for the next crossing stood in this one, and the opposing
  tram waited in that next crossing for this one).
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

from railsim.engine.events.log import EventLog
from railsim.engine.events.tracks import TrackSections
from railsim.engine.settings import EngineSettings
from railsim.engine.single_track import RouteSection
from tests.unit.test_lock_requests import _crossing_locks, _stop, _train
from tests.unit.test_single_track_order import _locks

S1 = "track:approach"
TRAM_M = 27.0


def _tram(tid: str, front_m: float, destination_m: float) -> Any:
    stops = [_stop("A", 0.0, 30.0, origin=True), _stop("Z", destination_m, 1.0, destination=True)]
    tr = _train(tid, front_m, stops)
    tr.trip.vehicle.length_m = TRAM_M
    return tr


def test_trains_turning_beyond_a_section_are_let_in_only_as_far_as_the_terminus_holds_them() -> None:
    # the approach S1 runs 1,000-2,000 m; the terminus platform ends where two trams fit past its clearance
    clearance_m = EngineSettings().clearance_m
    dest_m = 2000.0 + clearance_m + 2 * TRAM_M + 2.0 - 1.0  # the stop window ends 1 m past the mark
    arriving = [_tram(tid, 900.0 - 100.0 * k, dest_m) for k, tid in enumerate(("a", "b", "c"))]
    standing = _tram("standing", 60.0, 5000.0)  # a turned unit at the terminus, S1 ahead of it the other way
    _, locks = _locks(*arriving, standing)
    on_line = [*arriving, standing]
    locks.fleet.active = lambda: [t for t in on_line if t.status in ("inserting", "running")]  # type: ignore[method-assign]
    locks.continues = lambda train_id: train_id not in ("standing", "c")  # c leaves service at the terminus
    locks.tracks = TrackSections(EventLog(), [S1], room_beyond=locks._room_beyond)
    for tr in arriving:
        locks.sections[tr.train_id] = [RouteSection(S1, 0, 1000.0, 2000.0, 1000.0)]
        locks.section_requests[tr.train_id] = {}
    locks.sections["standing"] = [RouteSection(S1, 1, 100.0, 1100.0, 100.0)]
    locks.section_requests["standing"] = {}
    for tr in arriving:
        locks.bookkeeping(1.0, tr)
    granted = [tr.train_id for tr in arriving if locks.section_requests[tr.train_id][S1].granted]
    assert granted == ["a"], f"granted {granted}: the terminus holds the standing unit and one tram more"
    # the standing unit leaves through the section once a is in: a's rear clears S1, and standing goes
    a = arriving[0]
    a.front_m = 2000.0 + clearance_m + TRAM_M + 1.0
    locks.bookkeeping(2.0, a)
    locks.bookkeeping(2.0, standing)
    out = locks.section_requests["standing"][S1]
    assert out.granted, "the unit leaving the terminus waited behind the trams coming in"
    assert not locks.section_requests["b"][S1].granted  # the section is the leaving unit's
    standing.front_m = 1200.0
    locks.bookkeeping(3.0, standing)  # it leaves S1: b is let in, c waits (a and b fill the terminus)
    assert locks.section_requests["b"][S1].granted
    assert not locks.section_requests["c"][S1].granted, "a train ending its trip at the full terminus was let in"
    a.status = "arrived"  # a leaves service at the terminus: there is room for c
    b = arriving[1]
    b.front_m = 2000.0 + clearance_m + TRAM_M + 1.0
    locks.bookkeeping(4.0, b)
    assert locks.section_requests["c"][S1].granted


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
