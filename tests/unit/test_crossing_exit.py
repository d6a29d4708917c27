"""A flat crossing is asked for only with its exit clear: room for the train beyond it in front of the train
ahead, constructed without SUMO. On Jena's tram peak a tram that went in behind a tram waiting for the next
crossing stood in this one, and the opposing tram waited in that next crossing for this one (a deadlock at
1,642.5 s). Nor while points right beyond it are another train's: at Potsdam's Platz der Einheit a tram from the
Dortustraße branch held merge ``30566579`` right beyond crossing ``1137879547``, went in front of the tram granted
the crossing and stopped at its platform, and that tram stood in the crossing (every 720 s and every 1,200 s).
"""

from __future__ import annotations

from types import SimpleNamespace

from railsim.engine.events.log import EventLog
from railsim.engine.events.tracks import TrackSections
from railsim.engine.single_track import RouteSection
from tests.unit.test_lock_requests import _crossing_locks, _stop, _train
from tests.unit.test_single_track_order import _locks
from tests.unit.test_terminus_room import TRAM_M, _tram


def test_a_crossing_is_not_asked_for_while_the_points_right_beyond_it_are_another_trains() -> None:
    merge = SimpleNamespace(switch_id="merge", leg="reverse", point_m=1520.5)  # 0.5 m past the crossing's end
    stops = [_stop("A", 0.0, 30.0, origin=True), _stop("Z", 3000.0, 1.0, destination=True)]
    tr = _train("t", 1400.0, stops, switches=[merge])
    tr.trip.vehicle.length_m = TRAM_M
    layer, locks = _locks(tr, switches=("merge",))
    locks.tracks = TrackSections(EventLog(), ["crossing:c"])
    locks.sections["t"] = [RouteSection("crossing:c", 0, 1500.0, 1520.0, 1500.0)]
    locks.section_requests["t"] = {}
    locks.joins_of["t"] = frozenset({"merge"})  # another track joins the route there
    locks.interlocking.request(("branch",), "merge", "normal")  # a train from the other leg holds the merge
    layer.advance_to(1.0)
    locks.bookkeeping(1.0, tr)
    assert locks.section_requests["t"] == {}, "asked for a crossing while another train held the points beyond it"
    locks.interlocking.release("branch", "merge")
    layer.advance_to(2.0)
    locks.bookkeeping(2.0, tr)
    assert locks.section_requests["t"]["crossing:c"].granted


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


def test_the_exit_counts_where_the_train_ahead_will_stand_not_where_it_is() -> None:
    # the train ahead is just clear of the exit but still rolling towards a single-track section it does not hold:
    # it will stand the overlap before that section's protection point, and its rear then blocks the exit (Jena:
    # a tram went into crossing 259782418 behind trams running up to the Ernst-Abbe-Platz stub, which they waited
    # for; the tram turning in the stub waited for the trams leaving through that crossing)
    tr = _tram("t", 900.0, 3000.0)
    ahead_tr = _tram("ahead", 0.0, 3000.0)
    locks = _crossing_locks(tr, ahead_tr)
    crossing = locks.sections["t"][0]
    exit_m = crossing.end_m + locks.settings.clearance_m
    guard_m = exit_m + 60.0  # its authority ends 20 m before: its rear will stand 13 m past the exit
    locks.sections["ahead"] = [RouteSection("track:s", 0, guard_m, guard_m + 500.0, guard_m)]
    ahead_tr.front_m = exit_m + 1.0 + 2 * TRAM_M
    ahead = SimpleNamespace(train_id="ahead", front_m=ahead_tr.front_m, rear_m=ahead_tr.front_m - TRAM_M)
    locks.bookkeeping(1.0, tr, ahead)
    assert locks.section_requests["t"] == {}, "asked for a crossing behind a train bound to stop in its exit"
    locks.sections["ahead"] = []  # nothing stops it before it is well clear: the crossing is asked for
    locks.bookkeeping(2.0, tr, ahead)
    assert locks.section_requests["t"][crossing.section_id].granted
