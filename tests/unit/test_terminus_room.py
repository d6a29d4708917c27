"""Room at a terminus beyond single track, constructed without SUMO (each case from Jena's tram peak).

A train whose trip ends at a terminus beyond a single-track section (turning there or leaving service) is
granted the section only while the terminus has room for it beside the units standing there and the trains
already let in (four trams granted the Zwätzen Schleife approach together filled the loop; the last stood in
the section behind a unit waiting to leave through it).
"""

from __future__ import annotations

from typing import Any

from railsim.engine.events.log import EventLog
from railsim.engine.events.tracks import TrackSections
from railsim.engine.settings import EngineSettings
from railsim.engine.single_track import RouteSection
from tests.unit.test_lock_requests import _stop, _train
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
    locks.successor = {"a": "a2", "b": "b2"}.get  # their units turn where they stand and come back through S1
    locks.tracks = TrackSections(EventLog(), [S1], room_beyond=locks._room_beyond)
    for tr in arriving:
        locks.sections[tr.train_id] = [RouteSection(S1, 0, 1000.0, 2000.0, 1000.0)]
        locks.section_requests[tr.train_id] = {}
    for tid in ("a2", "b2"):  # (not on the line yet)
        locks.fleet.trains[tid] = _tram(tid, 0.0, 5000.0)
        locks.sections[tid] = [RouteSection(S1, 1, 0.0, 1000.0, 0.0)]
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


def test_trains_whose_units_turn_round_a_loop_are_let_in_as_far_as_the_loop_holds_them() -> None:
    # the approach S1 runs 1,000-2,000 m; each tram's platform ends just past it (room for one tram there), but
    # its unit runs on round a loop and enters S1 again, the other way, where its next trip waits: the loop's
    # track (less the overlap before that entry and the clearance after the exit) holds two trams, not one
    settings = EngineSettings()
    clearance_m, overlap_m = settings.clearance_m, settings.protection_margin_m
    dest_m = 2000.0 + clearance_m + TRAM_M + 1.0 - 1.0
    arriving = [_tram(tid, 900.0 - 100.0 * k, dest_m) for k, tid in enumerate(("a", "b", "c"))]
    last_edge_m = 2010.0  # each arriving route's last edge (the arrival track) starts here
    loop_m = 2 * TRAM_M + 5.0 + overlap_m + clearance_m  # from S1's end round to its entry the other way
    _, locks = _locks(*arriving)
    locks.fleet.active = lambda: [t for t in arriving if t.status in ("inserting", "running")]  # type: ignore[method-assign]
    locks.continues = lambda train_id: True
    locks.successor = lambda train_id: f"{train_id}2"
    locks.tracks = TrackSections(EventLog(), [S1], room_beyond=locks._room_beyond)
    back_m = loop_m - (last_edge_m - 2000.0)  # where the next trip's route (from the arrival track) meets S1
    for tr in arriving:
        locks.fleet.trains[f"{tr.train_id}2"] = _tram(f"{tr.train_id}2", 0.0, 5000.0)  # (not on the line yet)
        tr.view.edge_start_m = (0.0, last_edge_m)
        locks.sections[tr.train_id] = [RouteSection(S1, 0, 1000.0, 2000.0, 1000.0)]
        locks.section_requests[tr.train_id] = {}
        locks.sections[f"{tr.train_id}2"] = [RouteSection(S1, 1, back_m, back_m + 1000.0, back_m)]
    for tr in arriving:
        locks.bookkeeping(1.0, tr)
    granted = [tr.train_id for tr in arriving if locks.section_requests[tr.train_id][S1].granted]
    assert granted == ["a", "b"], f"granted {granted}: the loop holds two trams (its platform alone one)"


def test_a_section_far_from_where_the_unit_turns_is_no_terminus_approach() -> None:
    # "leaving" passes S1 at the start of its trip (a stub it leaves) and turns 8 km on, where its next trip first
    # enters another section: it does not yield on S1. "coming" ends beyond S1 and its unit comes back through it.
    leaving, coming = _tram("leaving", 50.0, 9000.0), _tram("coming", 900.0, 2040.0)
    _, locks = _locks(leaving, coming)
    for tid, first in (("leaving2", "track:far"), ("coming2", S1)):
        locks.fleet.trains[tid] = _tram(tid, 0.0, 5000.0)
        locks.sections[tid] = [RouteSection(first, 1, 0.0, 500.0, 0.0)]
    locks.continues = lambda train_id: True
    locks.successor = lambda train_id: f"{train_id}2"
    locks.tracks = TrackSections(EventLog(), [S1, "track:far"], room_beyond=locks._room_beyond)
    locks.sections["leaving"] = [RouteSection(S1, 1, 0.0, 1000.0, 0.0)]
    locks.sections["coming"] = [RouteSection(S1, 0, 1000.0, 2000.0, 1000.0)]
    for tr in (leaving, coming):
        locks.section_requests[tr.train_id] = {}
        locks.bookkeeping(1.0, tr)
    assert not locks.section_requests["leaving"][S1].yields, "a train leaving a stub yielded to the trains coming in"
    assert locks.section_requests["coming"][S1].yields


def test_a_unit_that_leaves_its_terminus_through_the_section_the_same_way_is_no_terminus_approach() -> None:
    # Jena's Winzerla: the terminus platform lies on a loop inside the last single-track section, and the unit's
    # next trip leaves through that section in the same direction. Counted as a terminus approach, the room beyond
    # the section was negative (the platform lies inside it), the tram never got in and the peak stalled.
    coming = _tram("coming", 900.0, 1500.0)
    _, locks = _locks(coming)
    locks.fleet.trains["coming2"] = _tram("coming2", 0.0, 5000.0)
    locks.sections["coming2"] = [RouteSection(S1, 0, 0.0, 500.0, 0.0)]
    locks.continues = lambda train_id: True
    locks.successor = lambda train_id: f"{train_id}2"
    locks.tracks = TrackSections(EventLog(), [S1], room_beyond=locks._room_beyond)
    locks.sections["coming"] = [RouteSection(S1, 0, 1000.0, 2000.0, 1000.0)]
    locks.section_requests["coming"] = {}
    locks.bookkeeping(1.0, coming)
    assert not locks.section_requests["coming"][S1].yields, "a unit leaving through the section the same way yielded"
    assert locks.section_requests["coming"][S1].granted
