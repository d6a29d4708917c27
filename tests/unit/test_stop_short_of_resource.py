"""An authority carried on to a stop before a resource the train does not hold (RouteLocks._reach_stop) keeps the
ATO's aim the overrun allowance before the resource's point, constructed without SUMO: a platform ending at a
flat crossing another movement holds (Potsdam, Platz der Einheit/West, crossing ``1137879547``)."""

from __future__ import annotations

from typing import Any

from controllers.ato import AtoParams
from railsim.engine.single_track import RouteSection
from railsim.engine.stop_timing import STOP_OVERRUN_ALLOWANCE_M, stop_before
from railsim.engine.trips import TripStop
from tests.unit.test_lock_requests import CROSSING, _crossing_locks, _stop, _train

POINT_M = 1000.0  # the crossing begins where the platform ends
ATO = AtoParams()  # authority margin 5 m, stopping tolerance 0.5 m


def _at_crossing(window_start_m: float, mark_m: float = POINT_M - 1.0) -> Any:
    """A tram on its way to a platform ending at the crossing (window ``[window_start_m, POINT_M]``)."""
    pee = TripStop("P", "P", mark_m, window_start_m, POINT_M, 20.0)
    stops = [_stop("A", 0.0, 30.0, origin=True), pee, _stop("Z", 3000.0, 1.0, destination=True)]
    tr = _train("t", 900.0, stops)
    tr.controllers = {"ato": type("Ato", (), {"params": ATO})()}
    return tr


def _locks(tr: Any) -> Any:
    locks = _crossing_locks(tr)
    locks.sections["t"] = [RouteSection(CROSSING, 0, POINT_M, POINT_M + 10.0, POINT_M)]
    return locks


def _aim_m(locks: Any, tr: Any) -> float:
    """Where the ATO aims to halt: its mark or the authority end less its margin, whichever comes first."""
    return min(tr.trip.stops[1].mark_m, locks.authority_end_m(tr) - ATO.authority_margin_m)


def test_the_aim_stays_the_overrun_allowance_before_a_crossing_the_train_does_not_hold() -> None:
    # a platform longer than the tram: the mark 1 m before the crossing; carried to it, the ATO's 1.12 m overrun
    # (Potsdam) put the front into the crossing
    tr = _at_crossing(window_start_m=POINT_M - 60.0)
    locks = _locks(tr)
    assert _aim_m(locks, tr) == POINT_M - STOP_OVERRUN_ALLOWANCE_M
    assert _aim_m(locks, tr) + 1.12 < POINT_M
    assert locks.events.count("stop_needs_resource") == 0


def test_a_short_platforms_window_is_still_served() -> None:
    # a platform shorter than the tram: the window is its last 2 m; the aim lies the ATO's tolerance inside it
    tr = _at_crossing(window_start_m=POINT_M - 2.0)
    locks = _locks(tr)
    aim_m = _aim_m(locks, tr)
    assert aim_m >= tr.trip.stops[1].window_start_m + ATO.stop_tolerance_m
    assert aim_m <= POINT_M - STOP_OVERRUN_ALLOWANCE_M


def test_a_stop_served_only_with_the_crossing_waits_for_it_and_says_so() -> None:
    # a window of 1 m before the crossing: no aim in it keeps the allowance; the tram halts short of it, asks for
    # the crossing on its way in (the stop does not hold the request back) and the run says why it waits
    tr = _at_crossing(window_start_m=POINT_M - 1.0, mark_m=POINT_M - 0.5)
    locks = _locks(tr)
    assert _aim_m(locks, tr) == POINT_M - STOP_OVERRUN_ALLOWANCE_M
    assert locks.events.count("stop_needs_resource") == 1
    beyond_m = POINT_M + 0.5  # a point whose overlap ends past the window (an overlap of less than 2 m)
    assert not stop_before(0.0, tr, beyond_m, beyond_m)
    assert stop_before(0.0, tr, beyond_m)  # without the resource's point the stop would hold the request back
    locks.bookkeeping(1.0, tr)
    assert locks.section_requests["t"][CROSSING].granted
    assert locks.authority_end_m(tr) > POINT_M + 10.0  # granted: the authority reaches past the crossing
