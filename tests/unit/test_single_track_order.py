"""Who goes first on single track and at points, constructed without SUMO (each case from Jena's tram peak).

* A request never waits for a request of the other direction that itself waits for a section this train holds
  (a group waiting outside kept a tram between two sections from the section it needed: deadlock).
* A train bound to turn beyond the section (a terminus loop) yields to the other direction, the trains leaving
  that terminus (arriving trams filled the Zwätzen Schleife loop while the units there waited to leave).
* A train asks for no less than the trains of its direction already waiting for the section (asking for the
  first of two sections alone, a tram left Jena-Ost ahead of trams waiting for both and blocked them).
* A train does not ask for a section beyond the train in front before that train has (the tram behind was granted
  both sections near Zwätzen, the one in front waited for it behind an opposing tram) — unless the train in front
  does not run through that section at all (it leaves before it, and never asks).
* A train granted the first of two sections alone asks for the second as soon as a train behind it asks for
  both (granted later, it waited between the sections behind an opposing tram that waited for the one behind).
* A train that comes to stand in front of a train of its direction (a unit turned there) takes that train's place
  against the other direction, and a request of the other direction does not go first against it while it waits for
  a section that train holds (the one behind leaves it only after it): a tram granted the approach behind a unit
  turned at Lobeda-West held the section an opposing tram waited for, and the unit waited behind that tram.
* Nor does it where the train holding that section stands in a line of trains, each right behind the next, behind
  this train: it leaves the section only after this train has moved on (Potsdam, Platz der Einheit/West).
* A section a train holds alone (it turns in it, or beyond it) waits for the train in front only where that train
  runs through it there too, until it has asked for its own time through it: nobody asks for it the same way, so
  a unit bound out through single track to its reversal waited forever behind a tram in front (Jena, Lobeda-West).
* No points beyond the protection point of a section not yet reserved are asked for (a tram waiting at the
  near end of a section held the points at its far end, which the tram in the section needed).
* Routes are set in order within one step too: a train that has just asked for busy points asks for none beyond
  them (granted points beyond a busy merge, a tram held them while a tram from the other leg went in front of it).
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np

from railsim.engine.events import EventLayer, Interlocking, Switch
from railsim.engine.events.log import EventLog
from railsim.engine.events.tracks import OWN_DIRECTION, TrackSections
from railsim.engine.extensions import ExtensionSet
from railsim.engine.locking import RouteLocks
from railsim.engine.settings import EngineSettings
from railsim.engine.single_track import RouteSection
from tests.unit.test_lock_requests import _no_join, _stop, _train

S1, S2 = "track:s1", "track:s2"


# ---------------------------------------------------------------- the section queue (TrackSections)
def test_a_request_never_waits_for_a_group_that_waits_for_this_train() -> None:
    tracks = TrackSections(EventLog(), [S1, S2])
    east = tracks.request(0.0, ("east",), S1, 0)  # east holds S1, will need S2 from the piece between
    west = tracks.request(0.0, ("west",), S2, 1)  # west holds S2, then needs S1
    assert east.granted and west.granted
    group = tracks.request_all(10.0, ("east2",), [(S2, 1), (S1, 1)])  # a group outside waits for both (held)
    assert not any(r.granted for r in group)
    west_on = tracks.request(20.0, ("west",), S1, 1)  # later than the group, same direction: no conflict
    east_on = tracks.request(20.0, ("east",), S2, 0)  # the group waits for S1, which east holds
    tracks.release(30.0, "west", west)
    assert east_on.granted, "east waited for a group that waited for east's own section"
    assert not west_on.granted  # east still holds S1
    tracks.release(40.0, "east", east)
    assert west_on.granted


def test_a_train_that_comes_to_stand_in_front_takes_the_place_of_the_train_behind() -> None:
    tracks = TrackSections(EventLog(), [S1, S2])
    opposing = tracks.request(0.0, ("opposing",), S2, 0)  # holds S2 for now
    behind = tracks.request(10.0, ("behind",), S1, 1)  # asked first; S1 is free: granted at once
    west = tracks.request_all(20.0, ("west",), [(S2, 0), (S1, 0)])  # waits for S2 (held) and S1 (held by behind)
    front = tracks.request_all(30.0, ("front",), [(S1, 1), (S2, 1)])  # a unit turned in front of "behind"
    assert behind.granted and not any(r.granted for r in west) and not any(r.granted for r in front)
    tracks.set_in_front(35.0, "behind", "front")  # the train side sees it there: "behind" cannot pass it
    tracks.release(40.0, "opposing", opposing)
    assert all(r.granted for r in front), "the train in front waited behind an opposing group that waited for it"
    assert not any(r.granted for r in west)


def test_the_train_in_front_counts_as_asking_when_the_train_behind_it_did() -> None:
    tracks = TrackSections(EventLog(), [S1, S2])
    tracks.request(0.0, ("blocker",), S2, 1)  # holds S2 the way "front" will go
    tracks.request(10.0, ("behind",), S1, 1)  # granted
    west = tracks.request(20.0, ("west",), S2, 0)  # waits for the blocker; it waits for nothing "behind" holds
    front = tracks.request_all(30.0, ("front",), [(S1, 1), (S2, 1)])
    assert not west.granted and not any(r.granted for r in front)  # west asked before "front"
    tracks.set_in_front(35.0, "behind", "front")  # "front" takes the place of "behind", which asked at 10 s
    assert all(r.granted for r in front) and not west.granted


def test_an_opposing_request_waiting_for_the_train_behind_never_goes_before_the_train_in_front() -> None:
    tracks = TrackSections(EventLog(), [S1, S2])
    unit = tracks.request(0.0, ("unit",), S1, 1)
    tracks.request(0.0, ("blocker",), S2, 1)
    west = tracks.request_all(20.0, ("west",), [(S2, 0), (S1, 0)])  # asked before anything below
    tracks.hand_over(50.0, unit, "behind", 1)  # the unit's next trip holds S1 from 50 s on
    front = tracks.request_all(60.0, ("front",), [(S1, 1), (S2, 1)])
    assert not any(r.granted for r in front)
    tracks.set_in_front(65.0, "behind", "front")  # west waits for S1, which "behind" leaves only after "front"
    assert all(r.granted for r in front) and not any(r.granted for r in west)


def test_without_a_train_in_front_the_earlier_request_of_the_other_direction_goes_first() -> None:
    tracks = TrackSections(EventLog(), [S1, S2])
    opposing = tracks.request(0.0, ("opposing",), S2, 0)
    tracks.request(10.0, ("behind",), S1, 1)
    west = tracks.request_all(20.0, ("west",), [(S2, 0), (S1, 0)])
    front = tracks.request_all(30.0, ("front",), [(S1, 1), (S2, 1)])
    tracks.set_in_front(35.0, "behind", None)  # nobody stands in front of it: first come, first served
    tracks.release(40.0, "opposing", opposing)
    assert not any(r.granted for r in front)  # west asked first and does not wait for "front"
    assert not any(r.granted for r in west)  # it waits for S1, which "behind" holds


def test_a_train_seen_in_front_of_an_earlier_waiting_request_is_served_at_once() -> None:
    tracks = TrackSections(EventLog(), [S1])
    holder = tracks.request(0.0, ("holder",), S1, 1)
    opposing = tracks.request(5.0, ("opposing",), S1, 0)  # waits for the holder
    front = tracks.request(10.0, ("front",), S1, 1)  # same way as the holder, but after the opposing request
    assert holder.granted and not opposing.granted and not front.granted
    tracks.set_in_front(12.0, "holder", "front")  # the holder stands behind it: it must go through first
    assert front.granted and not opposing.granted
    assert tracks.in_front == {"holder": "front"}


def test_an_opposing_group_waiting_for_a_train_in_line_behind_this_one_does_not_go_first() -> None:
    # "holder" holds S2 the way to S1 and stands in a line behind "middle" (which leaves by a branch) and "head",
    # which waits for S1. An opposing group for S1 and S2 asked earlier, but it waits for S2, which "holder" leaves
    # only after "head" has moved on: "head" goes first. Served first come, first served, the group held S1's turn
    # and "head" waited for it (Potsdam, Platz der Einheit/West, all lines every 680 s: deadlock at 3,244.5 s)
    tracks = TrackSections(EventLog(), [S1, S2])
    holder = tracks.request(0.0, ("holder",), S2, 0)
    blocker = tracks.request(0.0, ("blocker",), S1, 1)  # S1 is busy for now
    group = tracks.request_all(10.0, ("east",), [(S1, 1), (S2, 1)])  # waits for S1 and for S2 (held by "holder")
    head = tracks.request(20.0, ("head",), S1, 0)
    tracks.set_in_front(25.0, "holder", "middle")
    tracks.set_in_front(25.0, "middle", "head")
    tracks.release(30.0, "blocker", blocker)
    assert head.granted, "the group waiting for the train in line behind it went first"
    assert holder.granted and not any(r.granted for r in group)


def test_a_line_that_does_not_reach_the_waiting_train_leaves_the_earlier_request_first() -> None:
    tracks = TrackSections(EventLog(), [S1, S2])
    tracks.request(0.0, ("holder",), S2, 0)
    blocker = tracks.request(0.0, ("blocker",), S1, 1)
    group = tracks.request_all(10.0, ("east",), [(S1, 1), (S2, 1)])
    head = tracks.request(20.0, ("head",), S1, 0)
    tracks.set_in_front(25.0, "holder", "middle")
    tracks.set_in_front(25.0, "middle", "holder")  # a ring that never reaches "head" (and ends)
    tracks.release(30.0, "blocker", blocker)
    assert not head.granted and not any(r.granted for r in group)  # the group asked first; it waits for S2


def test_a_train_bound_to_turn_beyond_the_section_lets_the_trains_leaving_go_first() -> None:
    tracks = TrackSections(EventLog(), [S1])
    leaving = tracks.request(0.0, ("leaving.000",), S1, 0)
    arriving = tracks.request_all(5.0, ("arriving",), [(S1, 1)], yields=True)[0]
    next_out = tracks.request(50.0, ("leaving.001",), S1, 0)  # later, but it makes room at the terminus
    assert leaving.granted and next_out.granted and not arriving.granted
    tracks.release(60.0, "leaving.000", leaving)
    tracks.release(90.0, "leaving.001", next_out)
    assert arriving.granted
    plain = TrackSections(EventLog(), [S1])  # without yielding: first come, first served
    held = plain.request(0.0, ("leaving.000",), S1, 0)
    plain.request(5.0, ("arriving",), S1, 1)
    assert held.granted and not plain.request(50.0, ("leaving.001",), S1, 0).granted


# ---------------------------------------------------------------- requests (RouteLocks)
def _locks(*trains: Any, switches: tuple[str, ...] = ()) -> tuple[EventLayer, RouteLocks]:
    layer = EventLayer(t0_s=0.0, rng=np.random.default_rng(1))
    il = Interlocking(layer)
    for sid in switches:
        il.add_switch(Switch(sid, throw_time_s=0.0))
    formations = SimpleNamespace(of_follower={}, of_leader={}, join_book=SimpleNamespace(route_waits=_no_join))
    fleet = SimpleNamespace(trains={t.train_id: t for t in trains})
    locks = RouteLocks(fleet, il, formations, EventLog(), EngineSettings(), ExtensionSet(), layer)  # type: ignore[arg-type]
    locks.continues = lambda train_id: False
    return layer, locks


def _two_sections(locks: RouteLocks, *trains: Any, gap_m: float) -> None:
    """S1 at 1,000-2,000 m and S2 ``gap_m`` after it, the same way for every train."""
    locks.tracks = TrackSections(EventLog(), [S1, S2])
    for t in trains:
        locks.sections[t.train_id] = [
            RouteSection(S1, 0, 1000.0, 2000.0, 1000.0),
            RouteSection(S2, 0, 2000.0 + gap_m, 3000.0 + gap_m, 2000.0 + gap_m),
        ]
        locks.section_requests[t.train_id] = {}


def _runner(tid: str, front_m: float) -> Any:
    stops = [_stop("A", 0.0, 30.0, origin=True), _stop("C", 6000.0, 1.0, destination=True)]
    tr = _train(tid, front_m, stops)
    tr.trip.vehicle.length_m = 27.0
    return tr


def test_a_train_asks_for_no_less_than_the_trains_of_its_direction_waiting_before_it() -> None:
    # the piece between S1 and S2 holds one 27 m tram; a asks while nobody else waits there, but a train of its
    # direction already waits for S1 together with S2: a must not ask for less (it would leave ahead of it)
    a, b = _runner("a", 500.0), _runner("b", 400.0)
    _, locks = _locks(a, b)
    _two_sections(locks, a, b, gap_m=100.0)
    assert locks.tracks is not None
    blocker = locks.tracks.request(0.0, ("blocker",), S1, 1)
    locks.tracks.request_all(0.5, ("waiting",), [(S1, 0), (S2, 0)])  # a train waiting for both, not granted
    locks.bookkeeping(1.0, a)
    assert set(locks.section_requests["a"]) == {S1, S2}, "asked for S1 alone past a train waiting for both"
    locks.tracks.release(2.0, "blocker", blocker)
    assert locks.section_requests["a"][S2].granted


def test_a_train_does_not_ask_for_a_section_beyond_the_train_in_front_before_it() -> None:
    front, behind = _runner("front", 800.0), _runner("behind", 500.0)
    _, locks = _locks(front, behind)
    _two_sections(locks, front, behind, gap_m=40.0)  # no room between: S1 and S2 go together
    ahead = SimpleNamespace(train_id="front", rear_m=773.0)
    locks.bookkeeping(1.0, behind, ahead)
    assert locks.section_requests["behind"] == {}, "the train behind asked before the train in front"
    locks.bookkeeping(1.0, front)
    locks.bookkeeping(2.0, behind, ahead)
    assert set(locks.section_requests["behind"]) == {S1, S2}


def test_a_train_in_front_that_does_not_run_through_the_section_never_comes_first() -> None:
    # the train in front leaves by another way at S1's protection points: it never asks for S1, so the train behind
    # must not wait for it to (a tram behind one leaving Platz der Einheit/West for Dortustraße waited for good)
    front, behind = _runner("front", 800.0), _runner("behind", 500.0)
    _, locks = _locks(front, behind)
    _two_sections(locks, behind, gap_m=40.0)
    ahead = SimpleNamespace(train_id="front", rear_m=773.0)
    locks.bookkeeping(1.0, behind, ahead)
    assert set(locks.section_requests["behind"]) == {S1, S2}, "waited for a train in front that never asks"


def test_a_train_in_front_reversing_inside_the_section_still_comes_first() -> None:
    # the train in front runs into S1 and reverses there (a direction of its own): it does run through S1, so the
    # train behind waits until it has gone in; asking first, it could be granted S1 while the train in front
    # still waited for it
    front, behind = _runner("front", 800.0), _runner("behind", 500.0)
    _, locks = _locks(front, behind)
    _two_sections(locks, behind, gap_m=40.0)
    locks.sections["front"] = [RouteSection(S1, OWN_DIRECTION + 1, 1000.0, 2000.0, 1000.0)]
    locks.section_requests["front"] = {}
    ahead = SimpleNamespace(train_id="front", rear_m=773.0)
    locks.bookkeeping(1.0, behind, ahead)
    assert locks.section_requests["behind"] == {}, "asked before the train in front reversing in the section"


def test_a_section_held_alone_waits_for_the_train_in_front_only_where_it_runs_through_it() -> None:
    front, unit = _runner("front", 800.0), _runner("unit", 500.0)
    _, locks = _locks(front, unit)
    locks.tracks = TrackSections(EventLog(), [S1])
    locks.sections["unit"] = [RouteSection(S1, 7, 1000.0, 2000.0, 1000.0)]  # the unit's own: it turns in S1
    locks.sections["front"], locks.section_requests["front"], locks.section_requests["unit"] = [], {}, {}
    ahead = SimpleNamespace(train_id="front", rear_m=773.0, front_m=800.0)
    locks.bookkeeping(1.0, unit, ahead)
    assert S1 in locks.section_requests["unit"], "waited for a train in front that leaves its way before S1"
    turning = _runner("turning", 800.0)  # turns in S1 too, in a direction of its own
    _, locks = _locks(turning, unit)
    locks.tracks = TrackSections(EventLog(), [S1])
    locks.sections["unit"] = [RouteSection(S1, 7, 1000.0, 2000.0, 1000.0)]
    locks.sections["turning"] = [RouteSection(S1, 8, 1000.0, 2000.0, 1000.0)]
    locks.section_requests["turning"], locks.section_requests["unit"] = {}, {}
    ahead = SimpleNamespace(train_id="turning", rear_m=773.0, front_m=800.0)
    locks.bookkeeping(1.0, unit, ahead)
    assert locks.section_requests["unit"] == {}, "asked before the train in front bound into S1 there"
    locks.bookkeeping(1.0, turning)
    locks.bookkeeping(2.0, unit, ahead)
    assert S1 in locks.section_requests["unit"], "the train in front asked for its own time through S1"
    assert locks.section_requests["turning"][S1].granted and not locks.section_requests["unit"][S1].granted


def test_no_points_beyond_busy_points_are_asked_for_in_the_same_step() -> None:
    switches = [
        SimpleNamespace(switch_id="merge", leg="normal", point_m=1000.0),
        SimpleNamespace(switch_id="beyond", leg="normal", point_m=1300.0),
    ]
    stops = [_stop("A", 0.0, 30.0, origin=True), _stop("C", 6000.0, 1.0, destination=True)]
    tr = _train("t", 600.0, stops, switches=switches)
    layer, locks = _locks(tr, switches=("merge", "beyond"))
    locks.interlocking.request(("other",), "merge", "reverse")  # another train holds the merge
    layer.advance_to(1.0)
    locks.bookkeeping(1.0, tr)
    assert "merge" in tr.locks and "beyond" not in tr.locks, "asked for the points beyond busy points"
    locks.interlocking.release("other", "merge")
    layer.advance_to(2.0)
    locks.bookkeeping(2.0, tr)
    assert "beyond" in tr.locks


def test_a_train_granted_the_first_section_alone_asks_for_the_next_when_one_behind_asks_for_both() -> None:
    a, b = _runner("a", 500.0), _runner("b", 400.0)
    _, locks = _locks(a, b)
    _two_sections(locks, a, b, gap_m=70.0)  # 40 m of room between the sections: one 27 m tram
    assert locks.tracks is not None
    blocker = locks.tracks.request(0.0, ("blocker",), S2, 1)  # S2 is held the other way
    locks.bookkeeping(1.0, a)
    assert set(locks.section_requests["a"]) == {S1} and locks.section_requests["a"][S1].granted  # a waits between
    locks.bookkeeping(2.0, b)  # no room left between for b: it asks for both
    assert set(locks.section_requests["b"]) == {S1, S2}
    assert S2 in locks.section_requests["a"], "a, leaving first, did not ask for S2 when b asked for it"
    oncoming = locks.tracks.request(3.0, ("oncoming",), S2, 1)
    locks.tracks.release(4.0, "blocker", blocker)
    assert locks.section_requests["a"][S2].granted and locks.section_requests["b"][S2].granted
    assert not oncoming.granted


def test_no_points_beyond_the_protection_point_of_a_section_not_reserved() -> None:
    far = SimpleNamespace(switch_id="far", leg="normal", point_m=1500.0)  # inside the section's span, past its guard
    stops = [_stop("A", 0.0, 30.0, origin=True), _stop("C", 6000.0, 1.0, destination=True)]
    tr = _train("t", 600.0, stops, switches=[far])
    layer, locks = _locks(tr, switches=("far",))
    locks.tracks = TrackSections(EventLog(), [S1])
    locks.sections["t"] = [RouteSection(S1, 0, 1000.0, 2000.0, 1000.0)]
    locks.section_requests["t"] = {}
    oncoming = locks.tracks.request(0.0, ("oncoming",), S1, 1)  # holds the section the other way
    locks.bookkeeping(1.0, tr)
    assert not locks.section_requests["t"][S1].granted
    assert "far" not in tr.locks, "asked for points beyond a section it waits for"
    locks.tracks.release(2.0, "oncoming", oncoming)
    locks.bookkeeping(3.0, tr)
    assert "far" in tr.locks
