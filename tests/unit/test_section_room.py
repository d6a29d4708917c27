"""The room between two single-track sections, and who may stand in it, constructed without SUMO.

A train asks for a single-track section alone only while the track between it and the next section holds the
train beside every other train that stands there or will stand there waiting for that next section the same
way. Each case below is one a simpler count missed, from Jena's and Potsdam's tram peaks:

* a train already standing between the sections (its first section released, the next not yet granted: a tram
  dwelling at a platform there, or one that came in from a branch);
* a unit reversing inside the first section, which leaves it towards the next one (Jena-Ost);
* the room filling while the request waits (asked for alone at 900 s, granted at 1,301 s: the request widens to
  both sections before it is granted);
* a train in front waiting for a section the train behind it holds the same way is let through (it came in from a
  branch between the two sections: Potsdam, Platz der Einheit);
* the trains further in front, standing between the train behind and the section it holds (the one directly in
  front not asking yet, at its platform), are let through too, and so is a group whose other section the train
  behind holds, however the requests of the other direction and the trains turning beyond rank there (Potsdam,
  Platz der Einheit, every 720 s);
* the room ends before a flat crossing right before the next section, which a train waiting there may not ask for
  yet (Potsdam, crossing ``1137879547`` before the section beyond Platz der Einheit/West, every 720 s);
* the room ends at a platform in it that the waiting train cannot draw clear of (it stays there after its dwell:
  Potsdam, Platz der Einheit/West, 53 m before the overlap, every 720 s);
* a track that cannot hold the train clear of the first section even alone (its platform there leaves the rear
  inside ``clearance_m``) is a passing place all the same while every train of the other way waits there clear of
  the next section: the opposing trains let that section go there (Jena, Löbstedt towards Lobeda);
* a train from a branch joining the room takes the points onto it only while the room holds it beside the trains
  bound to wait there, a train granted the first section among them, and a train with those points set for it
  counts as in the room (Potsdam, merge ``30566579``, every 720 s);
* a train that has asked for those points counts from then on, set or not; a train leaving the room by a branch
  at the next section's protection points counts as the trains bound through the section do (it cannot pass them);
  and a train takes points onto the room only if it fits beyond the points right after them too, when it could not
  wait between the two (Potsdam, Platz der Einheit/West, every 700 s and every 720 s);
* no flat crossing inside a section is asked for before the section is granted (Potsdam, crossing ``4073068946``);
* a train whose front has stopped a few centimetres inside a crossing asks for it at once, though the section
  beyond it is not its own yet (Potsdam, Platz der Einheit/West, 0.12 m into crossing ``1137879547``).
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

from railsim.engine.events.log import EventLog
from railsim.engine.events.tracks import TrackSections
from railsim.engine.locking import RouteLocks
from railsim.engine.single_track import RouteSection
from tests.unit.test_lock_requests import _stop, _train
from tests.unit.test_single_track_order import _locks, _runner

S1, S2, CROSSING = "track:s1", "track:s2", "crossing:c"
GAP_M = 100.0  # S1 ends at 2,000 m, S2 starts at 2,100 m: 70 m of room, one 27 m tram (27 m + 50 m margin each)


def _with_margin(tr: Any) -> Any:
    """A tram keeping the separation controller's 50 m behind the train in front."""
    tr.controllers = {"separation": SimpleNamespace(params=SimpleNamespace(margin_m=50.0))}
    return tr


def _sections(locks: RouteLocks, *trains: Any, reversing: tuple[str, ...] = ()) -> None:
    """S1 at 1,000-2,000 m and S2 at 2,100-3,100 m, the same way for every train; a train in ``reversing`` turns
    inside S1 (its own direction there) and then runs through S2 like the others."""
    locks.tracks = TrackSections(EventLog(), [S1, S2])
    for k, t in enumerate(trains):
        d1 = 7 + k if t.train_id in reversing else 0
        locks.sections[t.train_id] = [
            RouteSection(S1, d1, 1000.0, 2000.0, 1000.0),
            RouteSection(S2, 0, 2000.0 + GAP_M, 3000.0 + GAP_M, 2000.0 + GAP_M),
        ]
        locks.section_requests[t.train_id] = {}


def _tram(tid: str, front_m: float) -> Any:
    return _with_margin(_runner(tid, front_m))


def test_a_train_standing_between_the_sections_takes_the_room() -> None:
    standing, second = _tram("standing", 2080.0), _tram("second", 500.0)  # standing: rear 43 m past S1's end
    _, locks = _locks(standing, second)
    _sections(locks, standing, second)
    assert locks.tracks is not None
    req = locks.tracks.request(0.0, ("standing",), S1, 0)
    locks.tracks.release(1.0, "standing", req)  # it has left S1 and waits at a platform before S2
    locks.section_requests["standing"][S1] = req
    locks.bookkeeping(2.0, second)
    assert set(locks.section_requests["second"]) == {S1, S2}, "granted S1 alone behind a tram standing between"


def test_a_unit_reversing_in_the_first_section_takes_the_room() -> None:
    unit, second = _tram("unit", 1500.0), _tram("second", 500.0)
    _, locks = _locks(unit, second)
    _sections(locks, unit, second, reversing=("unit",))
    assert locks.tracks is not None
    held = locks.tracks.request(0.0, ("unit",), S1, 7)  # the unit turning in S1 holds it with a direction of its own
    locks.section_requests["unit"][S1] = held
    locks.bookkeeping(1.0, second)
    assert set(locks.section_requests["second"]) == {S1, S2}, "a unit leaving S1 for S2 was not counted"


def test_a_request_for_the_first_section_alone_widens_when_the_room_fills() -> None:
    first, later = _tram("first", 500.0), _tram("later", 300.0)
    later.on_line = False  # not on the line yet
    _, locks = _locks(first, later)
    _sections(locks, first, later)
    assert locks.tracks is not None
    blocker = locks.tracks.request(0.0, ("blocker",), S1, 1)  # S1 is held the other way
    locks.bookkeeping(1.0, first)
    assert set(locks.section_requests["first"]) == {S1}  # the room is empty: S1 alone
    later.on_line, later.front_m = True, 2080.0  # a tram comes in between the sections (a branch joins there)
    assert locks.tracks.request(2.0, ("oncoming",), S2, 1).granted  # and S2 is held the other way
    locks.bookkeeping(3.0, first)
    assert set(locks.section_requests["first"]) == {S1, S2}, "the request for S1 alone did not widen"
    s1 = locks.section_requests["first"][S1]
    assert s1.group and s1.requested_s == 1.0  # one group, keeping its turn
    locks.tracks.release(4.0, "blocker", blocker)
    assert not s1.granted, "granted S1 alone with no room left before S2, which the oncoming tram holds"
    back = locks.tracks.request(5.0, ("oncoming",), S1, 1)  # the oncoming tram, past S2, asks for S1
    assert back.granted  # the group waits for S2, which the oncoming tram holds: it does not go first


def test_a_train_in_front_waiting_for_a_section_the_train_behind_holds_is_let_through() -> None:
    front, behind = _tram("front", 2080.0), _tram("behind", 1900.0)
    _, locks = _locks(front, behind)
    _sections(locks, front, behind)
    assert locks.tracks is not None
    mine = locks.tracks.request(0.0, ("behind",), S2, 0)  # behind was granted S2 (with S1)
    locks.section_requests["behind"][S2] = mine
    oncoming = locks.tracks.request(1.0, ("oncoming",), S2, 1)  # an opposing request, before the one in front
    theirs = locks.tracks.request(2.0, ("front",), S2, 0)  # front came in from a branch and asks after it
    locks.section_requests["front"][S2] = theirs
    assert mine.granted and not theirs.granted and not oncoming.granted
    ahead = SimpleNamespace(train_id="front", front_m=2080.0, rear_m=2053.0)
    locks.bookkeeping(3.0, behind, ahead)
    assert theirs.granted, "the train in front waited for a section the train behind it holds"
    assert not oncoming.granted


def test_a_train_further_in_front_waiting_for_a_section_the_train_behind_holds_is_let_through() -> None:
    front, middle, behind = _tram("front", 2080.0), _tram("middle", 2000.0), _tram("behind", 1920.0)
    _, locks = _locks(front, middle, behind)
    _sections(locks, front, middle, behind)
    assert locks.tracks is not None
    mine = locks.tracks.request(0.0, ("behind",), S2, 0)  # behind was granted S2 (with S1)
    locks.section_requests["behind"][S2] = mine
    oncoming = locks.tracks.request(1.0, ("oncoming",), S2, 1)
    theirs = locks.tracks.request(2.0, ("front",), S2, 0)  # front came in from a branch and asks after it
    locks.section_requests["front"][S2] = theirs
    locks.tracks.set_in_front(2.5, "middle", "front")  # middle (no request yet: at its platform) stands behind front
    ahead = SimpleNamespace(train_id="middle", front_m=2000.0, rear_m=1973.0)
    locks.bookkeeping(3.0, behind, ahead)
    assert theirs.granted, "a train two in front waited for a section the train behind them holds"
    assert not oncoming.granted


def test_a_group_whose_other_section_the_train_behind_holds_is_let_through() -> None:
    room = {"ok": False}
    tracks = TrackSections(EventLog(), [S1, S2], room_beyond=lambda req: room["ok"])
    first = tracks.request_all(0.0, ("first",), [(S1, 1), (S2, 1)], yields=True)  # turning beyond: no room yet
    second = tracks.request_all(1.0, ("second",), [(S1, 1), (S2, 1)], yields=True)
    behind = tracks.request_all(2.0, ("behind",), [(S1, 1), (S2, 1)])  # runs on: granted both
    oncoming = tracks.request_all(3.0, ("oncoming",), [(S2, 0), (S1, 0)])  # waits for behind
    room["ok"] = True
    tracks.set_in_front(4.0, "behind", "second")  # second stands in front of behind, first in front of second
    assert all(r.granted for r in behind) and not any(r.granted for r in first + second + oncoming)
    assert tracks.let_through(5.0, second[0], ("behind",)), "the other section, held by the train behind, stopped it"
    assert tracks.let_through(5.0, first[0], ("behind",)), "the oncoming group, yielded to at S2, stopped it"
    assert all(r.granted for r in first + second) and not any(r.granted for r in oncoming)


def test_the_room_ends_before_a_crossing_asked_for_only_with_the_next_section() -> None:
    tr = _tram("t", 500.0)
    _, locks = _locks(tr)
    locks.tracks = TrackSections(EventLog(), [S1, CROSSING, S2])
    locks.sections["t"] = [
        RouteSection(S1, 0, 1000.0, 2000.0, 1000.0),
        RouteSection(CROSSING, 0, 2050.0, 2100.0, 2050.0),  # right before S2: asked for only once S2 is granted
        RouteSection(S2, 0, 2100.0, 3100.0, 2100.0),  # 70 m of room before S2, 20 m before the crossing
    ]
    locks.section_requests["t"] = {}
    locks.tracks.request(0.0, ("oncoming",), S2, 1)
    locks.bookkeeping(1.0, tr)
    assert set(locks.section_requests["t"]) == {S1, S2}, "asked for S1 alone with no room before the crossing"
    assert not locks.section_requests["t"][S1].granted


def test_the_room_ends_at_a_platform_the_waiting_train_cannot_draw_clear_of() -> None:
    # S1 ends at 2,000 m, S2's protection point at 2,150 m; a platform at 2,100 m: a tram waiting there for S2 can
    # draw only 30 m clear of it (27 m + its 50 m margin needed), so it stays there, 30 m short of the overlap
    stops = [_stop("A", 0.0, 30.0, origin=True), _stop("B", 2100.0, 20.0), _stop("C", 6000.0, 1.0, destination=True)]
    standing, second = _with_margin(_train("standing", 2100.0, stops)), _with_margin(_train("second", 500.0, stops))
    for t in (standing, second):
        t.trip.vehicle.length_m = 27.0
    _, locks = _locks(standing, second)
    locks.tracks = TrackSections(EventLog(), [S1, S2])
    for t in (standing, second):
        locks.sections[t.train_id] = [
            RouteSection(S1, 0, 1000.0, 2000.0, 1000.0),
            RouteSection(S2, 0, 2150.0, 3150.0, 2150.0),
        ]
        locks.section_requests[t.train_id] = {}
    locks.bookkeeping(1.0, second)
    assert set(locks.section_requests["second"]) == {S1, S2}, "counted the room up to the overlap past the platform"


def test_a_train_from_a_branch_takes_the_points_onto_a_full_room_only_with_the_next_section() -> None:
    merge = SimpleNamespace(switch_id="merge", leg="reverse", point_m=2010.0)  # the branch joins 10 m past S1's end
    stops = [_stop("A", 0.0, 30.0, origin=True), _stop("C", 6000.0, 1.0, destination=True)]
    branch = _with_margin(_train("branch", 1900.0, stops, switches=[merge]))
    branch.trip.vehicle.length_m = 27.0
    through = _tram("through", 1500.0)  # granted S1 alone: it comes into the room between S1 and S2
    layer, locks = _locks(branch, through, switches=("merge",))
    _sections(locks, through)
    assert locks.tracks is not None
    locks.sections["branch"] = [RouteSection(S2, 0, 2000.0 + GAP_M, 3000.0 + GAP_M, 2000.0 + GAP_M)]
    locks.section_requests["branch"] = {}
    locks.joins_of["branch"] = frozenset({"merge"})  # the branch joins the track between S1 and S2 there
    locks.section_requests["through"][S1] = locks.tracks.request(0.0, ("through",), S1, 0)
    locks.tracks.request(0.0, ("oncoming",), S2, 1)  # S2 is held the other way
    layer.advance_to(1.0)
    locks.bookkeeping(1.0, branch)
    assert "merge" not in branch.locks, "took the points onto a room the train granted S1 needs"
    assert not locks.section_requests["branch"][S2].granted  # it waits on its branch for S2
    through.front_m = 3500.0  # gone on through S2
    layer.advance_to(2.0)
    locks.bookkeeping(2.0, branch)
    assert "merge" in branch.locks


def _branch_onto_room(front_m: float) -> tuple[Any, Any, Any, RouteLocks]:
    """A branch tram at ``front_m`` whose points ``j0`` (10 m past S1's end) bring it onto the room before S2, and a
    tram ``second`` at 500 m bound through S1 and S2: ``(branch, second, layer, locks)``."""
    branch, second = _branch("branch", front_m, 2010.0), _tram("second", 500.0)
    layer, locks = _locks(branch, second, switches=("j0",))
    _sections(locks, second)
    locks.sections["branch"] = [RouteSection(S2, 0, 2000.0 + GAP_M, 3000.0 + GAP_M, 2000.0 + GAP_M)]
    locks.section_requests["branch"] = {}
    locks.joins_of["branch"] = frozenset({"j0"})
    return branch, second, layer, locks


def test_a_train_with_the_points_set_onto_the_room_from_a_branch_takes_the_room() -> None:
    branch, second, layer, locks = _branch_onto_room(1900.0)  # 110 m short of the points
    branch.locks["j0"] = locks.interlocking.request(("branch",), "j0", "reverse")
    layer.advance_to(1.0)
    locks.bookkeeping(1.0, second)
    assert set(locks.section_requests["second"]) == {S1, S2}, "left out a train with the points set onto the room"


def test_no_crossing_inside_a_section_is_asked_for_before_the_section() -> None:
    tr = _tram("t", 600.0)
    _, locks = _locks(tr)
    locks.tracks = TrackSections(EventLog(), [S1, CROSSING])
    locks.sections["t"] = [
        RouteSection(S1, 0, 1000.0, 2000.0, 1000.0),
        RouteSection(CROSSING, 0, 1500.0, 1510.0, 1500.0),
    ]
    locks.section_requests["t"] = {}
    oncoming = locks.tracks.request(0.0, ("oncoming",), S1, 1)
    locks.bookkeeping(1.0, tr)
    assert S1 in locks.section_requests["t"] and not locks.section_requests["t"][S1].granted
    assert CROSSING not in locks.section_requests["t"], "asked for a crossing inside a section it waits for"
    locks.tracks.release(2.0, "oncoming", oncoming)
    locks.bookkeeping(3.0, tr)
    assert locks.section_requests["t"][CROSSING].granted


def test_a_train_stopped_with_its_front_in_a_crossing_asks_for_it_at_once() -> None:
    tr = _tram("t", 1500.12)  # halted 0.12 m past a platform that ends where the crossing begins
    _, locks = _locks(tr)
    locks.tracks = TrackSections(EventLog(), [S1, CROSSING])
    locks.sections["t"] = [
        RouteSection(CROSSING, 0, 1500.0, 1510.0, 1500.0),
        RouteSection(S1, 0, 1510.0, 2500.0, 1510.0),  # no room between: the crossing waits for S1 otherwise
    ]
    locks.section_requests["t"] = {}
    locks.tracks.request(0.0, ("oncoming",), S1, 1)
    locks.bookkeeping(1.0, tr)
    assert CROSSING in locks.section_requests["t"], "a train standing in a crossing did not ask for it"
    assert locks.section_requests["t"][CROSSING].granted
    other = locks.tracks.request(2.0, ("across",), CROSSING, 1)  # a tram of the other movement waits for it
    assert not other.granted


def _passing(up_platform_m: float | None) -> tuple[RouteLocks, Any]:
    """S1 ends at 2,000 m and S2's protection point is 66 m on (36 m to the overlap: room for a 27 m tram), with a
    platform 33 m past S1's end: the down tram waiting there stays at it (it cannot draw its 27 m and 50 m margin
    clear), its rear 6 m past S1, 4 m short of ``clearance_m``. An up tram runs S2 then S1 the other way, with
    room between them clear of S2 (or a platform at ``up_platform_m`` that leaves it short of that too)."""
    down_stops = [_stop("A", 0.0, 30.0, origin=True), _stop("B", 2033.0, 20.0), _stop("C", 6000.0, 1.0, True, True)]
    up_stops = [_stop("D", 0.0, 30.0, origin=True), _stop("E", 6000.0, 1.0, destination=True)]
    if up_platform_m is not None:
        up_stops.insert(1, _stop("F", up_platform_m, 20.0))
    down, up = _with_margin(_train("down", 500.0, down_stops)), _with_margin(_train("up", 100.0, up_stops))
    for t in (down, up):
        t.trip.vehicle.length_m = 27.0
    _, locks = _locks(down, up)
    locks.tracks = TrackSections(EventLog(), [S1, S2])
    locks.sections["down"] = [RouteSection(S1, 0, 1000.0, 2000.0, 1000.0), RouteSection(S2, 0, 2066.0, 2400.0, 2066.0)]
    locks.sections["up"] = [RouteSection(S2, 1, 1000.0, 1334.0, 1000.0), RouteSection(S1, 1, 1400.0, 2400.0, 1400.0)]
    for t in (down, up):
        locks.section_requests[t.train_id] = {}
    return locks, down


def test_a_track_the_other_way_waits_clear_on_is_a_passing_place_though_this_way_stands_short() -> None:
    locks, down = _passing(None)
    assert locks._stand_room_m(down, 2000.0, locks.sections["down"][1]) < 27.0  # it stands 4 m short of clear
    locks.bookkeeping(1.0, down)
    assert set(locks.section_requests["down"]) == {S1}, "asked for both sections, though every up tram lets S2 go there"
    locks.sections.pop("up")  # nobody runs the other way from S2 into S1: the rule has nothing to rest on
    locks.other_way_clear.clear()
    locks.section_requests["down"] = {}
    locks.tracks = TrackSections(EventLog(), [S1, S2])
    locks.bookkeeping(2.0, down)
    assert set(locks.section_requests["down"]) == {S1, S2}


def test_a_track_neither_way_waits_clear_on_is_no_passing_place() -> None:
    locks, down = _passing(1370.0)  # the up tram stays at a platform 36 m past S2, its rear 1 m short of clear
    locks.bookkeeping(1.0, down)
    assert set(locks.section_requests["down"]) == {S1, S2}, "asked for S1 alone where both ways would stand in it"


def test_a_track_a_train_of_the_other_way_ends_on_is_no_passing_place_for_one_standing_short() -> None:
    locks, down = _passing(None)
    locks.sections["up"] = locks.sections["up"][:1]  # the up tram's trip ends between S2 and S1: it could stand in S2
    locks.bookkeeping(1.0, down)
    assert set(locks.section_requests["down"]) == {S1, S2}, "asked for S1 alone where an up tram may stay in S2"


def _branch(tid: str, front_m: float, *points_m: float) -> Any:
    """A tram on a branch whose points (``j0``, ``j1``, … at ``points_m``) bring it onto the track before S2."""
    switches = [SimpleNamespace(switch_id=f"j{k}", leg="reverse", point_m=p) for k, p in enumerate(points_m)]
    stops = [_stop("A", 0.0, 30.0, origin=True), _stop("C", 6000.0, 1.0, destination=True)]
    tr = _with_margin(_train(tid, front_m, stops, switches=switches))
    tr.trip.vehicle.length_m = 27.0
    return tr


def test_a_train_that_has_asked_for_the_points_onto_the_room_takes_it() -> None:
    # the points are being thrown for the branch tram (or it is queued for them): it comes onto the track between
    # S1 and S2 next, and a train asking for S1 now must count it. Counting only points already locked, two trams
    # were granted the section before Platz der Einheit/West while the points from the Bildungsforum were thrown
    # for a third: the three filled the track and the last stood in the section (Potsdam, every 720 s)
    branch, second, layer, locks = _branch_onto_room(1990.0)
    locks.interlocking.request(("other",), "j0", "normal")  # another train holds the points: the branch queues
    branch.locks["j0"] = locks.interlocking.request(("branch",), "j0", "reverse")
    layer.advance_to(1.0)
    assert not locks.interlocking.is_granted(branch.locks["j0"])
    locks.bookkeeping(1.0, second)
    assert set(locks.section_requests["second"]) == {S1, S2}, "left out a train that had asked for the points"


def test_a_train_leaving_by_another_way_at_the_protection_points_takes_the_room() -> None:
    # a tram between the sections that leaves at S2's protection points by a branch cannot pass a train waiting for
    # S2 in front of it: it stands on the track as those bound through S2 do. Left out, an opposing tram was granted
    # the section behind it and stood in it, waiting for the platform the leaving tram stood at (Potsdam, 720 s)
    leaving, second = _tram("leaving", 2080.0), _tram("second", 500.0)  # leaving: rear 43 m past S1's end
    _, locks = _locks(leaving, second)
    _sections(locks, second)
    locks.passes_by["leaving"] = [RouteSection(S2, 0, 2100.0, 2100.0, 2100.0)]
    locks.bookkeeping(1.0, second)
    assert set(locks.section_requests["second"]) == {S1, S2}, "granted S1 alone beside a tram leaving by a branch"
    leaving.front_m = 2140.0  # gone by its branch
    third = _tram("third", 400.0)
    locks.fleet.trains["third"] = third
    locks.sections["third"] = list(locks.sections["second"])
    locks.section_requests["third"] = {}
    locks.bookkeeping(2.0, third)
    s1, s2 = locks.sections["third"]
    assert "leaving" not in [t.train_id for t in locks._waiting_between(third, s1, s2, GAP_M)]


def _two_joins(first_m: float) -> tuple[Any, Any, Any, Any]:
    """A branch tram at 2,050 m whose points ``j0`` (at ``first_m``) and ``j1`` (2,180 m) bring it onto the track
    before S2 (protection point 2,300 m), where a tram waits for S2: from ``j1`` there is no room for it (13 m)."""
    branch, standing = _branch("branch", 2050.0, first_m, 2180.0), _tram("standing", 2280.0)
    layer, locks = _locks(branch, standing, switches=("j0", "j1"))
    locks.tracks = TrackSections(EventLog(), [S1, S2])
    for t in (branch, standing):
        locks.sections[t.train_id] = [RouteSection(S2, 0, 2300.0, 3300.0, 2300.0)]
        locks.section_requests[t.train_id] = {}
    locks.joins_of["branch"] = frozenset({"j0", "j1"})
    assert locks.tracks.request(0.0, ("oncoming",), S2, 1).granted  # the standing tram waits for S2
    assert not locks._full_for(branch, first_m, locks.sections["branch"][0])
    assert locks._full_for(branch, 2180.0, locks.sections["branch"][0])
    layer.advance_to(1.0)
    locks.bookkeeping(1.0, branch)
    return branch, standing, layer, locks


def test_a_train_takes_points_onto_the_room_only_if_it_fits_beyond_the_points_right_after_them() -> None:
    # 20 m between the two points: it cannot wait between them. Taking the first on the room beyond them, it would
    # stand on them (on Potsdam's points 1137879547, 18.5 m before merge 30566579, shutting in the tram that needed
    # them: every 700 s)
    branch, standing, layer, locks = _two_joins(2160.0)
    assert "j0" not in branch.locks, "took the first points with no room beyond the second, 20 m after them"
    standing.front_m = 3400.0  # gone through S2
    layer.advance_to(2.0)
    locks.bookkeeping(2.0, branch)
    assert "j0" in branch.locks


def test_a_train_takes_points_it_can_wait_beyond_whatever_the_room_beyond_later_points() -> None:
    branch, _, _, _ = _two_joins(2100.0)  # 80 m between the two: it waits between them, clear of the first
    assert "j0" in branch.locks, "held back 80 m before the points whose room it waits for"


def test_the_trains_leaving_at_a_sections_protection_points_are_found_from_the_routes() -> None:
    # S2 starts at the end of edge b (2,100 m); "through" runs b -> s2 into it, "leaving" b -> branch: it passes S2's
    # protection points on another leg, at 2,300 m of its own route (its b starts 200 m later than through's)
    through, leaving, far = _tram("through", 500.0), _tram("leaving", 500.0), _tram("far", 500.0)
    through.trip.route.edges, through.trip.route.edge_start_m = ["a", "b", "s2"], [0.0, 1500.0, 2100.0]
    leaving.trip.route.edges, leaving.trip.route.edge_start_m = ["x", "b", "branch"], [0.0, 1700.0, 2300.0]
    far.trip.route.edges, far.trip.route.edge_start_m = ["x", "y"], [0.0, 1000.0]  # never near S2
    _, locks = _locks(through, leaving, far)
    locks.sections["through"] = [RouteSection(S2, 0, 2100.0, 3100.0, 2100.0)]
    locks.note_passes()
    assert locks.passes_by == {"leaving": [RouteSection(S2, 0, 2300.0, 2300.0, 2300.0)]}


def test_a_train_on_the_track_a_few_metres_beyond_the_gap_in_its_own_route_counts_as_standing_there() -> None:
    # the legs of a junction differ by a few metres: a tram 0.1 m past the merge onto the track before S2 was
    # 2.4 m further from S2's protection point in its own route than the gap from the points a branch tram checks
    # the room from; left out, the branch tram took the points and filled the track (Potsdam, every 700 s)
    coming, branch = _tram("coming", 0.0), _branch("branch", 2050.0, 2165.0)
    _, locks = _locks(coming, branch, switches=("j0",))
    locks.tracks = TrackSections(EventLog(), [S2])
    for t in (coming, branch):
        locks.sections[t.train_id] = [RouteSection(S2, 0, 2300.0, 3300.0, 2300.0)]
        locks.section_requests[t.train_id] = {}
    gap_m = 2300.0 - 2165.0
    coming.front_m = 2300.0 - gap_m - 2.4
    assert [t.train_id for t in locks._bound_for_room(branch, locks.sections["branch"][0], gap_m)] == ["coming"]
    coming.front_m = 2300.0 - gap_m - locks.settings.protection_margin_m - 1.0  # further back: still on its way
    assert locks._bound_for_room(branch, locks.sections["branch"][0], gap_m) == []
