"""A flat crossing is asked for only with its exit clear: room for the train beyond it in front of the train
ahead, constructed without SUMO. On Jena's tram peak a tram that went in behind a tram waiting for the next
crossing stood in this one, and the opposing tram waited in that next crossing for this one (a deadlock at
1,642.5 s).
"""

from __future__ import annotations

from types import SimpleNamespace

from railsim.engine.single_track import RouteSection
from tests.unit.test_lock_requests import _crossing_locks
from tests.unit.test_terminus_room import TRAM_M, _tram


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
