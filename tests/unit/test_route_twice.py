"""A route over the same points, or through the same single-track section, twice asks for them each time.

A unit's turnback path can run out along the line to a place where it reverses and come back the same way: at
Jena's Winzerla the next trip's route runs 3.9 km on past the terminus to a reversal and back, through three
single-track sections and three sets of points twice. With one request per section and one lock per switch for
the whole trip, the unit, having released them on the way out, came back through them under no reservation: it
ran into a section held the other way (and stood there), and with the section asked for again it passed points
``1272033516`` a second time without their lock, into a tram that held them the other way (17 SUMO collision
reports). Constructed without SUMO.
"""

from __future__ import annotations

from types import SimpleNamespace

from railsim.engine.events.log import EventLog
from railsim.engine.events.tracks import TrackSections
from railsim.engine.single_track import RouteSection
from tests.unit.test_lock_requests import _stop, _train
from tests.unit.test_single_track_order import _locks

S1 = "track:s1"


def _unit(front_m: float, switches: tuple = ()) -> SimpleNamespace:
    stops = [_stop("A", 0.0, 30.0, origin=True), _stop("C", 6000.0, 1.0, destination=True)]
    tr = _train("unit", front_m, stops, switches=list(switches))
    tr.trip.vehicle.length_m = 27.0
    return tr


def test_points_passed_twice_are_locked_each_time() -> None:
    twice = (
        SimpleNamespace(switch_id="p", leg="reverse", point_m=1000.0),  # out
        SimpleNamespace(switch_id="p", leg="reverse", point_m=3000.0),  # and back over the same points
    )
    tr = _unit(900.0, twice)
    layer, locks = _locks(tr, switches=("p",))
    locks.bookkeeping(1.0, tr)
    layer.advance_to(1.5)
    assert locks.interlocking.is_locked_for("unit", "p", "reverse")
    tr.front_m = 1100.0  # its rear is past the points: released
    locks.bookkeeping(2.0, tr)
    assert not locks.interlocking.is_locked_for("unit", "p", "reverse")
    locks.interlocking.request(("other",), "p", "normal")  # another train takes them
    layer.advance_to(3.0)
    tr.front_m = 2500.0
    locks.bookkeeping(4.0, tr)
    assert locks.authority_end_m(tr) < 3000.0, "the unit may run over the points a second time without their lock"
    locks.interlocking.release("other", "p")
    layer.advance_to(10.0)
    locks.bookkeeping(10.0, tr)
    layer.advance_to(10.5)
    assert locks.interlocking.is_locked_for("unit", "p", "reverse"), "the points were not asked for again"
    assert locks.authority_end_m(tr) > 3000.0


def test_a_section_passed_twice_is_asked_for_each_time() -> None:
    tr = _unit(900.0)
    _, locks = _locks(tr)
    locks.tracks = TrackSections(EventLog(), [S1])
    locks.sections["unit"] = [
        RouteSection(S1, 0, 1000.0, 2000.0, 1000.0),  # out through the section
        RouteSection(S1, 1, 3700.0, 4700.0, 3700.0),  # and back through it the other way after a reversal
    ]
    locks.section_requests["unit"] = {}
    locks.bookkeeping(1.0, tr)
    first = locks.section_requests["unit"][S1]
    assert first.granted and first.direction == 0
    tr.front_m = 2100.0  # its rear is past the section: released
    locks.bookkeeping(2.0, tr)
    assert "unit" in first.released_by
    oncoming = locks.tracks.request(3.0, ("oncoming",), S1, 0)  # a train enters it against the unit's way back
    assert oncoming.granted
    tr.front_m = 2600.0
    locks.bookkeeping(4.0, tr)
    again = locks.section_requests["unit"][S1]
    assert again is not first and again.direction == 1, "the section was not asked for again"
    assert not again.granted
    assert locks.authority_end_m(tr) < 3700.0, "the unit may run back into the section held the other way"
    locks.tracks.release(5.0, "oncoming", oncoming)
    assert again.granted
    tr.front_m = 4800.0
    locks.bookkeeping(6.0, tr)
    assert "unit" in again.released_by
