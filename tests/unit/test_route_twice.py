"""A route over the same points, or through the same single-track section, twice asks for them each time.

A unit's turnback path can run out along the line to a place where it reverses and come back the same way: at
Jena's Winzerla the next trip's route runs 3.9 km on past the terminus to a reversal and back, through three
single-track sections and three sets of points twice. With one request per section and one lock per switch for
the whole trip, the unit, having released them on the way out, came back through them under no reservation: it
ran into a section held the other way (and stood there), and with the section asked for again it passed points
``1272033516`` a second time without their lock, into a tram that held them the other way (17 SUMO collision
reports). And points asked for while the track in front was clear are given up when a train comes onto the track
in front (at a junction) and waits for them: the next unit on that path held points ``1272033567`` far ahead of
a tram that joined in front of it and waited for them (deadlock at 2,431 s). But a section the route runs out
through into a stub right beyond it, reverses there and comes back through, with no passing place between, is held
once, from the way out until the rear has left it on the way back: at Jena's Lobeda-Ost a tram let into it between the two times
through stood in it, and its unit's next trip waited for the stub the first unit turned in (deadlock at 5,009.5 s).
Constructed without SUMO.
"""

from __future__ import annotations

from types import SimpleNamespace

import networkx as nx
import numpy as np

from railsim.engine.events import EventLayer, Interlocking
from railsim.engine.events.log import EventLog
from railsim.engine.events.tracks import TrackSections
from railsim.engine.extensions import ExtensionSet
from railsim.engine.locking import RouteLocks
from railsim.engine.settings import EngineSettings
from railsim.engine.single_track import RouteSection
from tests.unit.test_lock_requests import _no_join, _stop, _train
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


def test_points_held_beyond_a_train_that_came_in_front_are_given_up() -> None:
    # the unit asked for points 1,000 m ahead while its track was clear; a tram then came onto the track between
    # it and the points (at a junction) and waits for them: the unit gives them up and asks again behind it
    points = (SimpleNamespace(switch_id="p", leg="reverse", point_m=1500.0),)
    tr = _unit(500.0, points)
    front = _train("front", 1200.0, [_stop("A", 0.0, 30.0, origin=True), _stop("C", 6000.0, 1.0, destination=True)])
    front.trip.route.switches = [SimpleNamespace(switch_id="p", leg="normal", point_m=1500.0)]
    layer, locks = _locks(tr, front, switches=("p",))
    locks.bookkeeping(1.0, tr)
    layer.advance_to(1.5)
    assert locks.interlocking.is_locked_for("unit", "p", "reverse")
    locks.bookkeeping(2.0, front)  # front asks for the points the unit holds: it waits
    layer.advance_to(2.5)
    assert not locks.interlocking.is_locked_for("front", "p", "normal")
    ahead = SimpleNamespace(train_id="front", front_m=1000.0, rear_m=880.0)  # front, in the unit's frame
    locks.bookkeeping(3.0, tr, ahead)
    layer.advance_to(3.5)
    assert not locks.interlocking.is_locked_for("unit", "p", "reverse"), "held the points the train in front needs"
    assert locks.interlocking.is_locked_for("front", "p", "normal")
    assert "p" not in tr.locks  # asked for again once the train in front has gone


def _stub_graph() -> nx.DiGraph:
    """Single track ``a`` from points ``p`` on, then a stub ``b`` beyond a second set of points ``q`` (each with its
    bidi partner ``-a``, ``-b``): a unit goes out through ``a``, reverses in ``b`` and comes back through ``-a``; a
    tram goes out through ``a`` onto the double track ``c`` beyond ``q``."""
    g = nx.DiGraph()
    for e, bidi in (("in", None), ("a", "-a"), ("-a", "a"), ("b", "-b"), ("-b", "b"), ("c", None), ("out", None)):
        g.add_node(e, length_m=0.0, **({"bidi": bidi} if bidi else {}))
    g.add_edge("in", "a", switch="p")
    g.add_edge("a", "b", switch="q")
    g.add_edge("a", "c", switch="q")
    g.add_edge("-b", "-a", switch="q")
    g.add_edge("-a", "out", switch="p")
    return g


def _on_route(tr: SimpleNamespace, edges: list[str], starts: list[float], length_m: float) -> None:
    tr.trip.route.edges, tr.trip.route.edge_start_m, tr.trip.route.length_m = edges, starts, length_m


def test_a_section_the_unit_turns_beyond_is_its_own_until_it_has_come_back_through_it() -> None:
    # out through a (1,000-2,000 m), reversing in the stub b right beyond it, back through a (2,600-3,600 m): no
    # train may go into a in between, in either direction. A tram let into it the way the unit had gone out stood
    # in it and passed it to its unit's next trip, which waited for the stub the unit turned in (Jena, Lobeda-Ost)
    unit = _unit(900.0)
    _on_route(unit, ["in", "a", "b", "-b", "-a", "out"], [0.0, 1000.0, 2000.0, 2300.0, 2600.0, 3600.0], 5000.0)
    tram = _train("tram", 500.0, [_stop("A", 0.0, 30.0, origin=True), _stop("C", 6000.0, 1.0, destination=True)])
    tram.trip.vehicle.length_m = 27.0
    _on_route(tram, ["in", "a", "c"], [0.0, 1000.0, 2000.0], 6100.0)
    layer = EventLayer(t0_s=0.0, rng=np.random.default_rng(1))
    formations = SimpleNamespace(of_follower={}, of_leader={}, join_book=SimpleNamespace(route_waits=_no_join))
    fleet = SimpleNamespace(trains={"unit": unit, "tram": tram})
    locks = RouteLocks(fleet, Interlocking(layer), formations, EventLog(), EngineSettings(), ExtensionSet(), layer)  # type: ignore[arg-type]
    locks.set_up_shared_track(_stub_graph(), lambda train_id: None)
    assert [s.section_id for s in locks.sections["unit"]] == ["track:-a", "track:-b"], "a is one entry, out and back"
    locks.bookkeeping(1.0, unit)
    held = locks.section_requests["unit"]["track:-a"]
    assert held.granted and locks.section_requests["unit"]["track:-b"].granted
    unit.front_m = 2350.0  # in the stub, its rear well past a on the way out
    locks.bookkeeping(2.0, unit)
    assert "unit" not in held.released_by, "released on the way out"
    tram.front_m = 900.0
    locks.bookkeeping(3.0, tram)
    theirs = locks.section_requests["tram"]["track:-a"]
    assert not theirs.granted, "a tram went into the section the unit comes back through"
    unit.front_m = 3000.0  # back in a
    locks.bookkeeping(4.0, unit)
    assert locks.section_requests["unit"]["track:-a"] is held and locks.authority_end_m(unit) > 3600.0
    unit.front_m = 3700.0  # its rear is past a on the way back
    locks.bookkeeping(5.0, unit)
    assert "unit" in held.released_by and theirs.granted
