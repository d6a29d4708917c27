"""Trains facing each other on one track, constructed without SUMO (railsim.engine.occupancy, safety, locking).

On ``bidi`` track one physical track is two SUMO edges, one per direction; a train running the other way, or a
unit turned back in a terminus stub, is on the partner edge and never "ahead" by edge. A unit turning back inside
a single-track section ran off under no reservation and met a tram coming in head-on (Jena, Ernst-Abbe-Platz:
13 SUMO ``frontal`` reports, none of railsim's own). Here:

* the occupancy finds the train facing another on its track, in that train's frame;
* the safety check counts two facing bodies that overlap as a collision (and two apart as none);
* a train standing inside a section it does not hold has no movement authority, and no authority reaches into
  track a facing train stands on.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import networkx as nx
import numpy as np

from railsim.engine.events import EventLayer
from railsim.engine.events.log import EventLog
from railsim.engine.events.tracks import TrackSections
from railsim.engine.occupancy import Body, Occupancy
from railsim.engine.routeview import RouteView
from railsim.engine.safety import SafetyMonitor
from railsim.engine.settings import EngineSettings
from railsim.engine.single_track import RouteSection
from tests.unit.test_lock_requests import _stop, _train
from tests.unit.test_single_track_order import _locks

EDGE_M = 2000.0


def _graph() -> nx.DiGraph:
    """Aston –AM– M –MB– Bury, every edge with its bidi partner (one track, 4 km)."""
    g = nx.DiGraph()
    for e, partner in (("AM", "-AM"), ("MB", "-MB")):
        g.add_node(e, length_m=EDGE_M, bidi=partner)
        g.add_node(partner, length_m=EDGE_M, bidi=e)
    return g


def _view(rid: str, edges: tuple[str, ...]) -> RouteView:
    starts = tuple(EDGE_M * k for k in range(len(edges)))
    route = SimpleNamespace(
        id=rid, edges=edges, edge_start_m=starts, speed_limits=(), gradients=(), length_m=EDGE_M * len(edges)
    )
    return RouteView(route)


EAST, WEST = _view("east", ("AM", "MB")), _view("west", ("-MB", "-AM"))


def _occupancy(*bodies: tuple[str, RouteView, float]) -> Occupancy:
    occ = Occupancy()
    occ.set_bidi(_graph())
    occ.update([Body(tid, view, front_m, 27.0) for tid, view, front_m in bodies])
    return occ


def test_the_train_facing_another_on_its_track_is_found_in_its_frame() -> None:
    # west's front 1,100 m into -MB: its body covers 900-927 m of MB, 2,900-2,927 m in east's frame
    occ = _occupancy(("east", EAST, 2500.0), ("west", WEST, 1100.0), ("behind", EAST, 2000.0))
    hit = occ.facing("east", 2500.0, 1000.0)
    assert hit is not None and hit.train_id == "west"
    assert abs(hit.near_m - 2900.0) < 1e-9 and abs(hit.far_m - 2927.0) < 1e-9
    assert occ.facing("east", 2500.0, 300.0) is None  # beyond the look-ahead
    assert occ.ahead("east") is None  # by edge it is nobody's leader: only facing() sees it
    back = occ.facing("west", 1100.0, 2000.0)  # from west: east's front is 1,500 m into -MB
    assert back is not None and back.train_id == "east" and abs(back.near_m - 1500.0) < 1e-9
    assert occ.facing("behind", 2000.0, 400.0) is None  # a train of its own direction is not facing it


def _monitor(*ids: str) -> tuple[SafetyMonitor, list[Any], EventLog]:
    layer = EventLayer(t0_s=0.0, rng=np.random.default_rng(1))
    events = EventLog()
    trains = {
        tid: SimpleNamespace(train_id=tid, front_m=0.0, trip=SimpleNamespace(vehicle=SimpleNamespace(length_m=27.0)))
        for tid in ids
    }
    return SafetyMonitor(trains, layer, events, EngineSettings()), list(trains.values()), events  # type: ignore[arg-type]


def test_two_trains_meeting_head_on_are_a_collision() -> None:
    monitor, active, events = _monitor("east", "west")
    east, west = active
    east.front_m, west.front_m = 2890.0, 1100.0  # 10 m apart, facing: no collision yet
    occ = _occupancy(("east", EAST, east.front_m), ("west", WEST, west.front_m))
    monitor.head_on_checks(1.0, active, occ.facing_own_bodies)
    assert monitor.collisions == []
    east.front_m = 2905.0  # 5 m into the body of the train facing it
    occ = _occupancy(("east", EAST, east.front_m), ("west", WEST, west.front_m))
    monitor.head_on_checks(2.0, active, occ.facing_own_bodies)
    monitor.head_on_checks(2.5, active, occ.facing_own_bodies)  # once per pair
    assert len(monitor.collisions) == 1 and monitor.collisions[0]["head_on"] is True
    assert len(events.rows("collision")) == 1


def _inside_train(front_m: float) -> Any:
    stops = [_stop("A", 0.0, 30.0, origin=True), _stop("C", 6000.0, 1.0, destination=True)]
    tr = _train("unit", front_m, stops)
    tr.trip.vehicle.length_m = 27.0
    return tr


def test_a_train_inside_a_section_it_does_not_hold_has_no_authority() -> None:
    tr = _inside_train(1500.0)
    _, locks = _locks(tr)
    locks.tracks = TrackSections(EventLog(), ["track:s"])
    locks.sections["unit"] = [RouteSection("track:s", 5, 1000.0, 2000.0, 1000.0)]  # inside it, turned back
    locks.section_requests["unit"] = {}
    holder = locks.tracks.request(0.0, ("coming_in",), "track:s", 0)  # the train still coming in holds it
    locks.bookkeeping(1.0, tr)
    assert not locks.section_requests["unit"]["track:s"].granted
    assert locks.authority_end_m(tr) == 1500.0, "a unit inside a section it does not hold may move"
    locks.tracks.release(2.0, "coming_in", holder)
    assert locks.section_requests["unit"]["track:s"].granted
    assert locks.authority_end_m(tr) > 5000.0


def test_no_authority_reaches_into_track_a_facing_train_stands_on() -> None:
    tr = _inside_train(500.0)
    _, locks = _locks(tr)
    assert locks.authority_end_m(tr) > 5000.0
    locks.facing_m = {"unit": 900.0}  # a unit turned back stands 400 m ahead, facing it
    assert locks.authority_end_m(tr) == 900.0 - EngineSettings().protection_margin_m
