"""When a train asks for a switch or a section (RouteLocks.bookkeeping), constructed without SUMO.

Two rules found by the Line 3 service day, each with the case that broke it:

* a section or flat crossing beyond a station stop is requested only when the train is about to leave that stop
  (a unit waiting out its turnback at a terminal held the Bijin crossing for minutes while the Jurenba trains that
  cross there stalled);
* a switch beyond a station stop likewise (a branch train dwelling short of the merge held the points for two
  minutes and the main-line train at the merge waited for it), unless the stop lies within the authority margin
  of the points (without the lock the train could not reach its stopping point, and would never dwell there);
* a coupled follower never asks for a switch on its leader's leg before its leader does (granted first, it held
  the points its own leader needed and neither could move: the depot-switch deadlock).
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import networkx as nx
import numpy as np

from railsim.engine.coupling import COUPLED_STATES
from railsim.engine.events import EventLayer, Interlocking, Switch
from railsim.engine.events.log import EventLog
from railsim.engine.events.tracks import TrackSections
from railsim.engine.extensions import ExtensionSet
from railsim.engine.locking import RouteLocks
from railsim.engine.settings import EngineSettings
from railsim.engine.single_track import RouteSection
from railsim.engine.stop_timing import SECTION_REQUEST_LEAD_S, stop_before
from railsim.engine.trips import TripStop

CROSSING = "crossing:n1"
GUARD_M = 1000.0  # the crossing's protection point on the route


def _stop(name: str, mark_m: float, dwell_s: float, origin: bool = False, destination: bool = False) -> TripStop:
    return TripStop(
        name, name, mark_m, mark_m - 120.0, mark_m + 1.0, dwell_s, is_origin=origin, is_destination=destination
    )


def _train(tid: str, front_m: float, stops: list[TripStop], depart_s: float = 0.0, switches: Any = ()) -> Any:
    trip = SimpleNamespace(
        stops=tuple(stops),
        depart_s=depart_s,
        departure_delay_s=0.0,
        vehicle=SimpleNamespace(length_m=120.0),
        route=SimpleNamespace(switches=list(switches)),
        start_offset_m=0.0,
        depart_chainage_m=stops[0].mark_m,  # as Trip's: the origin's mark plus the start offset
        destination=stops[-1],
    )
    return SimpleNamespace(
        train_id=tid,
        trip=trip,
        view=SimpleNamespace(length_m=stops[-1].mark_m + 100.0),
        front_m=front_m,
        next_stop=1,
        sumo_stopped=False,
        dwell_started_s=None,
        locks={},
        released=set(),
        violations=set(),
        reversing=False,
        start_front_m=stops[0].mark_m,
        status="running",
        on_line=True,
        controllers={},
    )


def _no_join(tr: Any, point_m: float) -> bool:
    """No leader here waits at a station for a follower to join it (railsim.engine.joins.Joins.route_waits)."""
    return False


def _crossing_locks(*trains: Any) -> RouteLocks:
    formations = SimpleNamespace(of_follower={}, of_leader={}, join_book=SimpleNamespace(route_waits=_no_join))
    locks = RouteLocks(
        SimpleNamespace(trains={t.train_id: t for t in trains}),
        SimpleNamespace(),
        formations,
        EventLog(),
        EngineSettings(),
        ExtensionSet(),
        SimpleNamespace(now_s=0.0),
    )
    locks.tracks = TrackSections(EventLog(), [CROSSING])
    for t in trains:
        locks.sections[t.train_id] = [RouteSection(CROSSING, 0, GUARD_M + 50.0, GUARD_M + 60.0, GUARD_M)]
        locks.section_requests[t.train_id] = {}
    return locks


def test_a_train_dwelling_before_a_crossing_asks_for_it_only_when_about_to_leave() -> None:
    # origin at 0 m (dwell 30 s, planned departure 300 s: a unit waiting out its turnback), station B at 600 m
    stops = [_stop("A", 0.0, 30.0, origin=True), _stop("B", 600.0, 40.0), _stop("C", 3000.0, 1.0, destination=True)]
    tr = _train("t1", 0.0, stops, depart_s=300.0)
    tr.next_stop = 0
    tr.sumo_stopped, tr.dwell_started_s = True, 10.0
    locks = _crossing_locks(tr)
    for t in (10.0, 100.0, 300.0 - SECTION_REQUEST_LEAD_S - 1.0):
        locks.bookkeeping(t, tr)
        assert locks.section_requests["t1"] == {}, f"asked for the crossing at {t} s, standing at its origin"
    # about to leave the origin, but B (before the crossing) is still to come: not yet
    assert stop_before(300.0 - SECTION_REQUEST_LEAD_S, tr, GUARD_M)
    # on its way to B, within the request distance: still not
    tr.next_stop, tr.sumo_stopped, tr.dwell_started_s, tr.front_m = 1, False, None, 400.0
    locks.bookkeeping(330.0, tr)
    assert locks.section_requests["t1"] == {}
    # dwelling at B: asks SECTION_REQUEST_LEAD_S before its dwell is over, and is granted (nobody else wants it)
    tr.front_m, tr.sumo_stopped, tr.dwell_started_s = 600.0, True, 400.0
    locks.bookkeeping(400.0 + 40.0 - SECTION_REQUEST_LEAD_S - 0.5, tr)
    assert locks.section_requests["t1"] == {}
    locks.bookkeeping(400.0 + 40.0 - SECTION_REQUEST_LEAD_S, tr)
    assert locks.section_requests["t1"][CROSSING].granted
    assert locks.authority_end_m(tr) > GUARD_M  # the authority now reaches past the crossing


def test_a_train_without_a_stop_before_the_crossing_asks_at_the_request_distance() -> None:
    stops = [_stop("A", 0.0, 30.0, origin=True), _stop("C", 3000.0, 1.0, destination=True)]
    tr = _train("t1", GUARD_M - EngineSettings().lock_request_distance_m - 1.0, stops)
    locks = _crossing_locks(tr)
    locks.bookkeeping(50.0, tr)
    assert locks.section_requests["t1"] == {}
    assert locks.authority_end_m(tr) < GUARD_M  # no reservation: the authority ends before the crossing
    tr.front_m += 2.0
    locks.bookkeeping(51.0, tr)
    assert locks.section_requests["t1"][CROSSING].granted


def test_a_dwelling_train_does_not_keep_a_crossing_from_a_train_that_needs_it() -> None:
    stops_a = [_stop("A", 0.0, 30.0, origin=True), _stop("C", 3000.0, 1.0, destination=True)]
    dweller = _train("dweller", 0.0, stops_a, depart_s=600.0)
    dweller.next_stop, dweller.sumo_stopped, dweller.dwell_started_s = 0, True, 0.0
    crosser = _train("crosser", GUARD_M - 500.0, stops_a)
    locks = _crossing_locks(dweller, crosser)
    locks.sections["crosser"] = [RouteSection(CROSSING, 1, GUARD_M + 50.0, GUARD_M + 60.0, GUARD_M)]
    locks.bookkeeping(20.0, dweller)
    locks.bookkeeping(20.0, crosser)
    assert locks.section_requests["crosser"][CROSSING].granted
    assert locks.waiting_for(crosser) == []


# ---------------------------------------------------------------- a coupled follower and its leader's switch
def _switch_locks(leader: Any, follower: Any) -> tuple[EventLayer, Interlocking, RouteLocks]:
    layer = EventLayer(t0_s=0.0, rng=np.random.default_rng(1))
    il = Interlocking(layer)
    il.add_switch(Switch("sw", throw_time_s=0.0))
    formation = SimpleNamespace(id="f1")
    state = next(iter(sorted(COUPLED_STATES)))
    formations = SimpleNamespace(
        join_book=SimpleNamespace(route_waits=_no_join),
        of_follower={follower.train_id: formation},
        of_leader={leader.train_id: [formation]},
        leader_of=lambda f: leader,
        follower_of=lambda f: follower,
        manager=SimpleNamespace(state=lambda fid: state),
    )
    fleet = SimpleNamespace(trains={leader.train_id: leader, follower.train_id: follower})
    return layer, il, RouteLocks(fleet, il, formations, EventLog(), EngineSettings(), ExtensionSet(), layer)  # type: ignore[arg-type]


def test_a_coupled_follower_never_asks_for_its_leaders_switch_before_the_leader() -> None:
    stops = [_stop("A", 0.0, 30.0, origin=True), _stop("C", 5000.0, 1.0, destination=True)]
    switch = SimpleNamespace(switch_id="sw", leg="normal", point_m=2000.0)
    leader = _train("lead", 800.0, stops, switches=[switch])
    follower = _train("fol", 2000.0 - 1400.0, stops, switches=[switch])  # within the request distance
    layer, il, locks = _switch_locks(leader, follower)
    # the leader's front is further from the switch than the request distance: it has not asked yet
    leader.front_m = 2000.0 - EngineSettings().lock_request_distance_m - 10.0
    locks.bookkeeping(0.0, follower)
    assert "sw" not in follower.locks, "the follower asked for the switch ahead of its own leader"
    # the leader asks and takes the follower into its request: one lock for the formation
    leader.front_m += 20.0
    locks.bookkeeping(1.0, leader)
    layer.advance_to(2.0)
    assert follower.locks["sw"] is leader.locks["sw"]
    assert il.is_locked_for("fol", "sw", "normal") and il.is_locked_for("lead", "sw", "normal")


# ---------------------------------------------------------------- merges: where a train on the other leg appears
def test_before_a_merge_not_locked_for_it_a_train_stops_its_separation_margin_short() -> None:
    """At trailing points (another track joins ours) a train passing on the other leg appears on our track with its
    rear at the point: the authority ends the separation margin (50 m) before such a point, not only the overlap
    (20 m), so the train appearing there is never inside our margin (the Line 3 day's emergency brakes at the
    Bijin down merge). Facing points keep the overlap, and so does a train without a separation role."""
    g = nx.DiGraph()
    g.add_edge("main", "trunk", switch="merge_sw", leg="normal")
    g.add_edge("branch", "trunk", switch="merge_sw", leg="reverse")
    g.add_edge("trunk", "fork", switch=None)
    g.add_edge("fork", "left", switch="facing_sw", leg="normal")
    g.add_edge("fork", "right", switch="facing_sw", leg="reverse")
    stops = [_stop("A", 0.0, 30.0, origin=True), _stop("C", 6000.0, 1.0, destination=True)]
    switches = [
        SimpleNamespace(switch_id="merge_sw", leg="normal", point_m=2000.0),
        SimpleNamespace(switch_id="facing_sw", leg="normal", point_m=4000.0),
    ]
    sep = SimpleNamespace(params=SimpleNamespace(margin_m=50.0))
    guarded = _train("guarded", 500.0, stops, switches=switches)
    plain = _train("plain", 500.0, stops, switches=switches)
    for tr, controllers in ((guarded, {"separation": sep}), (plain, {})):
        tr.trip.route.edges = ["main", "trunk", "fork", "left"]
        tr.controllers = controllers
    layer = EventLayer(t0_s=0.0, rng=np.random.default_rng(1))
    il = Interlocking(layer)
    for sid in ("merge_sw", "facing_sw"):
        il.add_switch(Switch(sid, throw_time_s=0.0))
    formations = SimpleNamespace(of_follower={}, of_leader={}, join_book=SimpleNamespace(route_waits=_no_join))
    fleet = SimpleNamespace(trains={"guarded": guarded, "plain": plain})
    locks = RouteLocks(fleet, il, formations, EventLog(), EngineSettings(), ExtensionSet(), layer)  # type: ignore[arg-type]
    locks.protect_merges(g)
    overlap_m = EngineSettings().protection_margin_m
    assert locks.authority_end_m(guarded) == 2000.0 - 50.0
    assert locks.authority_end_m(plain) == 2000.0 - overlap_m
    # the merge locked for both: the next limit is the facing point, where the overlap is enough
    for tr in (guarded, plain):
        il.request((tr.train_id,), "merge_sw", "normal", 0.0)
    layer.advance_to(1.0)
    assert il.is_locked_for("guarded", "merge_sw", "normal") or il.is_locked_for("plain", "merge_sw", "normal")
    first = "guarded" if il.is_locked_for("guarded", "merge_sw", "normal") else "plain"
    assert locks.authority_end_m(fleet.trains[first]) == 4000.0 - overlap_m


# ---------------------------------------------------------------- a switch beyond a station stop
def _one_switch_locks(tr: Any) -> tuple[EventLayer, RouteLocks]:
    layer = EventLayer(t0_s=0.0, rng=np.random.default_rng(1))
    il = Interlocking(layer)
    il.add_switch(Switch("sw", throw_time_s=0.0))
    formations = SimpleNamespace(of_follower={}, of_leader={}, join_book=SimpleNamespace(route_waits=_no_join))
    fleet = SimpleNamespace(trains={tr.train_id: tr})
    return layer, RouteLocks(fleet, il, formations, EventLog(), EngineSettings(), ExtensionSet(), layer)  # type: ignore[arg-type]


def test_a_switch_beyond_a_station_stop_is_asked_for_only_when_about_to_leave_it() -> None:
    stops = [_stop("A", 0.0, 30.0, origin=True), _stop("B", 600.0, 40.0), _stop("C", 3000.0, 1.0, destination=True)]
    switch = SimpleNamespace(switch_id="sw", leg="reverse", point_m=GUARD_M)
    tr = _train("t1", 400.0, stops, switches=[switch])  # within the request distance, B still to come
    layer, locks = _one_switch_locks(tr)
    locks.bookkeeping(10.0, tr)
    assert "sw" not in tr.locks
    tr.front_m, tr.sumo_stopped, tr.dwell_started_s = 600.0, True, 100.0  # dwelling at B, due at 140 s
    locks.bookkeeping(140.0 - SECTION_REQUEST_LEAD_S - 0.5, tr)
    assert "sw" not in tr.locks
    locks.bookkeeping(140.0 - SECTION_REQUEST_LEAD_S, tr)
    layer.advance_to(140.0)
    assert locks.interlocking.is_locked_for("t1", "sw", "reverse")


def test_a_stop_within_the_overlap_of_the_points_does_not_hold_back_the_request() -> None:
    overlap_m = EngineSettings().protection_margin_m
    stops = [
        _stop("A", 0.0, 30.0, origin=True),
        _stop("B", GUARD_M - overlap_m / 2.0, 40.0),  # its stopping point lies beyond where the authority would end
        _stop("C", 3000.0, 1.0, destination=True),
    ]
    switch = SimpleNamespace(switch_id="sw", leg="reverse", point_m=GUARD_M)
    tr = _train("t1", 400.0, stops, switches=[switch])
    layer, locks = _one_switch_locks(tr)
    locks.bookkeeping(10.0, tr)
    layer.advance_to(11.0)
    assert locks.interlocking.is_locked_for("t1", "sw", "reverse")
    assert locks.authority_end_m(tr) > stops[1].mark_m  # it can reach its stopping point at B


# ---------------------------------------------------------------- leaving a platform: the route must let it clear
def test_a_train_stays_at_the_platform_until_its_route_lets_it_draw_clear() -> None:
    """Dwell over at B, points 100 m beyond B's stopping point not yet locked: its authority would end the overlap
    before them, with its rear still on the platform, so it stays (a train following it would halt short of its
    own stopping point on that platform). Locked: it goes. A destination, or points beyond its length + margin,
    never hold it."""
    stops = [_stop("A", 0.0, 30.0, origin=True), _stop("B", 600.0, 40.0), _stop("C", 3000.0, 1.0, destination=True)]
    switch = SimpleNamespace(switch_id="sw", leg="reverse", point_m=700.0)
    tr = _train("t1", 600.0, stops, switches=[switch])
    tr.sumo_stopped, tr.dwell_started_s = True, 100.0
    layer, locks = _one_switch_locks(tr)
    assert not locks.clears_platform(tr, stops[1])
    locks.bookkeeping(140.0 - SECTION_REQUEST_LEAD_S, tr)  # about to leave: it asks, and is granted
    layer.advance_to(140.0)
    assert locks.clears_platform(tr, stops[1])
    assert locks.clears_platform(tr, stops[2])  # at its destination it goes nowhere
    far = _train("t2", 600.0, stops, switches=[SimpleNamespace(switch_id="sw", leg="reverse", point_m=900.0)])
    _, far_locks = _one_switch_locks(far)
    # 900 − overlap 20 ≥ 600 + 120 (length) + 20 (no separation role: the overlap): the route lets it clear
    assert far_locks.clears_platform(far, stops[1])


# ---------------------------------------------------------------- a route over the same points twice
def test_points_passed_while_still_waiting_are_asked_for_anew_on_the_next_time_over_them() -> None:
    """A train that passed points while its request still waited (a ``switch_violation``: another train held
    them) and comes over the same points again later on its route asks anew there: its waiting request is
    withdrawn first (the interlocking allows one request per train and switch; asking again on top of it raised)."""
    stops = [_stop("A", 0.0, 30.0, origin=True), _stop("C", 6000.0, 1.0, destination=True)]
    out = SimpleNamespace(switch_id="sw", leg="normal", point_m=1000.0)
    back = SimpleNamespace(switch_id="sw", leg="reverse", point_m=3000.0)
    tr = _train("t1", 500.0, stops, switches=[out, back])
    holder = _train("holder", 0.0, stops)
    layer = EventLayer(t0_s=0.0, rng=np.random.default_rng(1))
    il = Interlocking(layer)
    il.add_switch(Switch("sw", throw_time_s=0.0))
    formations = SimpleNamespace(of_follower={}, of_leader={}, join_book=SimpleNamespace(route_waits=_no_join))
    fleet = SimpleNamespace(trains={tr.train_id: tr, holder.train_id: holder})
    log = EventLog()
    locks = RouteLocks(fleet, il, formations, log, EngineSettings(), ExtensionSet(), layer)  # type: ignore[arg-type]
    held = il.request(("holder",), "sw", "reverse")
    layer.advance_to(1.0)
    assert held.state.name == "GRANTED"
    locks.bookkeeping(1.0, tr)  # within the request distance of the first time over the points: it waits
    first = tr.locks["sw"]
    assert first.state.name == "WAITING"
    for t, front_m in ((2.0, 1010.0), (3.0, 1200.0), (4.0, 2800.0)):  # over them unlocked, clear, towards the next
        tr.front_m = front_m
        layer.advance_to(t)
        locks.bookkeeping(t, tr)
    assert "sw" in tr.violations
    assert first.state.name == "CANCELLED" and tr.locks["sw"] is not first  # withdrawn, and asked anew
    assert tr.locks["sw"].state.name == "WAITING" and tr.locks["sw"].leg == "reverse"
