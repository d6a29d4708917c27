"""The stops an OSM import writes, completed: both tracks of a station, off edges too short, long enough, named.

netconvert's ``--ptstop-output`` writes a stop where OSM maps a stop position, which is often not what a train can
serve. Before the stops are written (:mod:`network.osm_import`), each is completed, and each change is counted in
the import's summary:

* **the other track of a double-track station** (:func:`twin_stops`): a station OSM maps with a stop position on one
  track only gets a copy on the opposite track within :data:`TWIN_RADIUS_M`, unless that track has a platform of the
  station within :data:`STATION_TRACK_M` along it (staggered stops);
* **off an edge shorter than a platform** (:func:`move_off_short_edges`): the stop moves to the end of the single
  edge before it, :data:`END_CLEARANCE_M` short of its end;
* **long enough** (:func:`ensure_length`): a stop shorter than :data:`MIN_STOP_M` (netconvert writes some tram stops
  0 m long) — or than the import's ``platform_m`` (OSM maps a stop position, not the platform's length: trams
  coupled in pairs need longer platforms than one unit) — is widened around its centre within its lane;
* **named** (:func:`name_unnamed_stops`): a stop written without a name takes the name of the nearest named stop of
  its class, or named OSM stop, platform or station node (:func:`osm_named_stops`), within
  :data:`UNNAMED_RADIUS_M`; else it is called ``stop <id>``.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from network.geo import distance_m, net_to_lonlat
from network.xmlscan import open_xml

RAIL_CLASSES = ("subway", "rail_urban", "tram", "rail", "rail_electric", "rail_fast")  # stop-class preference
TWIN_RADIUS_M = 25.0  # the other track of a double-track station lies within this of a stop
STATION_TRACK_M = 150.0  # a station's platforms on one track lie within this of each other along the track
END_CLEARANCE_M = 3.0  # a moved stop ends this far before the end of its edge
MIN_STOP_M = {"tram": 30.0, "other": 60.0}  # shortest platform written (a zero-length stop cannot be served)
UNNAMED_RADIUS_M = 100.0  # an OSM stop without a name takes the name of a named stop or platform within this
_STOP_TAGS = {
    "railway": {"stop", "tram_stop", "halt", "station", "platform"},
    "public_transport": {"stop_position", "platform", "station"},
}


def lane_class(permissions: set[str]) -> str | None:
    """The rail class a stop's lane belongs to: the first of :data:`RAIL_CLASSES` it allows."""
    return next((vc for vc in RAIL_CLASSES if vc in permissions), None)


@dataclass(frozen=True)
class Stop:
    elem: ET.Element
    vclass: str
    name: str


def ensure_length(st: Stop, lane_length_m: float, platform_m: float | None = None) -> int:
    """Widen a stop shorter than ``platform_m`` (default :data:`MIN_STOP_M` of its class) around its centre,
    within its lane; 1 if it was widened."""
    want = min(platform_m or MIN_STOP_M["tram" if st.vclass == "tram" else "other"], lane_length_m)
    start = float(st.elem.get("startPos", 0.0))
    end = float(st.elem.get("endPos", lane_length_m))
    if end - start >= want - 1e-6:
        return 0
    centre = min(max(0.5 * (start + end), 0.5 * want), lane_length_m - 0.5 * want)
    st.elem.set("startPos", f"{centre - 0.5 * want:.2f}")
    st.elem.set("endPos", f"{centre + 0.5 * want:.2f}")
    return 1


def twin_stops(net: Any, stops: dict[str, Stop]) -> int:
    """Add the missing platform of a double-track station: for each stop, a rail edge of its class running the
    opposite way within :data:`TWIN_RADIUS_M` of the stop's centre (not its own bidi partner, which already
    carries it) and holding no stop of the same station — the nearest, one a platform fits on first — gets a copy
    of the stop (id ``<stop>_twin``, same name and length, centred on the point nearest the original), unless
    that track already has another platform of the station on an edge within :data:`STATION_TRACK_M` before or
    after it along the track (:func:`_edges_along`; the stop's own edge does not count, a turning loop joins the
    two tracks of a terminus). Tram stops are often
    staggered, each direction's platform on the far side of a junction from the other, so the opposite
    platform lies on the next edge of the track, not beside the stop; a copy there would make every train stop
    twice at the station, the second time a few metres on. Returns how many were added."""
    from sumolib.geomhelper import polygonOffsetAndDistanceToPoint, positionAtShapeOffset

    def heading(shape: Sequence[Any], offset: float) -> float:
        a = positionAtShapeOffset(shape, max(0.0, offset - 5.0))
        b = positionAtShapeOffset(shape, offset + 5.0)
        return math.atan2(b[1] - a[1], b[0] - a[0])

    edges_by_class: dict[str, list[Any]] = defaultdict(list)
    for e in net.getEdges(withInternal=False):
        for vc in {lane_class(set(ln.getPermissions())) for ln in e.getLanes()} - {None}:
            edges_by_class[str(vc)].append(e)
    station_edges: dict[tuple[str, str], set[str]] = defaultdict(set)
    for st in stops.values():
        station_edges[(st.vclass, st.name)].add(net.getLane(st.elem.get("lane", "")).getEdge().getID())
    added: dict[str, Stop] = {}
    for sid, st in stops.items():
        lane = net.getLane(st.elem.get("lane", ""))
        start, end = float(st.elem.get("startPos", 0.0)), float(st.elem.get("endPos", lane.getLength()))
        centre = positionAtShapeOffset(lane.getShape(), 0.5 * (start + end))
        h = heading(lane.getShape(), 0.5 * (start + end))
        own = lane.getEdge()
        want = _min_stop_m(st.vclass)
        others = station_edges[(st.vclass, st.name)] - {own.getID()}  # where the station's other platforms are
        candidates: list[tuple[bool, float, Any, float]] = []  # (too short, distance, lane, offset)
        for e in edges_by_class[st.vclass]:
            if e is own or e is own.getBidi() or e.getID() in station_edges[(st.vclass, st.name)]:
                continue
            other = next((ln for ln in e.getLanes() if lane_class(set(ln.getPermissions())) == st.vclass), None)
            if other is None:
                continue
            offset, dist = polygonOffsetAndDistanceToPoint(centre, other.getShape())
            if dist > TWIN_RADIUS_M:
                continue
            turn = abs((heading(other.getShape(), offset) - h + math.pi) % (2 * math.pi) - math.pi)
            if turn < math.radians(135):
                continue
            candidates.append((other.getLength() < want, dist, other, offset))
        if not candidates:
            continue
        _short, _dist, other, offset = min(candidates, key=lambda c: (c[0], c[1]))  # a lane a platform fits on first
        if not others.isdisjoint(_edges_along(other.getEdge(), STATION_TRACK_M)):
            continue  # that track has the station's platform already, on an edge before or after this one
        length = min(max(end - start, want), other.getLength())
        a = min(max(offset - 0.5 * length, 0.0), other.getLength() - length)
        elem = ET.Element(st.elem.tag, dict(st.elem.attrib))
        elem.set("id", f"{sid}_twin")
        elem.set("lane", other.getID())
        elem.set("startPos", f"{a:.2f}")
        elem.set("endPos", f"{a + length:.2f}")
        added[f"{sid}_twin"] = Stop(elem, st.vclass, st.name)
        station_edges[(st.vclass, st.name)].add(other.getEdge().getID())
    stops.update(added)
    return len(added)


def _edges_along(edge: Any, reach_m: float) -> set[str]:
    """The ids of ``edge`` and of the edges every train on it runs over within ``reach_m`` before or after it:
    forwards while the track does not diverge (one outgoing edge), backwards while no other track joins it (one
    incoming edge); an edge's own bidi partner, the same track the other way, is never taken."""
    found = {edge.getID()}
    for forward in (True, False):
        current, dist_m = edge, 0.0
        while dist_m < reach_m:
            nexts = [
                e for e in (current.getOutgoing() if forward else current.getIncoming()) if e is not current.getBidi()
            ]
            if len(nexts) != 1 or nexts[0].getID() in found:
                break
            current = nexts[0]
            found.add(current.getID())
            dist_m += current.getLength()
    return found


def _min_stop_m(vclass: str) -> float:
    return MIN_STOP_M["tram" if vclass == "tram" else "other"]


def move_off_short_edges(net: Any, stops: dict[str, Stop]) -> int:
    """A stop on an edge shorter than a platform (:data:`MIN_STOP_M`; OSM stop positions often sit on a stub
    between two junctions) cannot hold a train: when its edge has one incoming edge of the class (not its own
    bidi partner) long enough, the stop moves to the end of that edge — the train halts a few metres earlier
    than the OSM node. Returns how many moved."""
    moved = 0
    for st in stops.values():
        lane = net.getLane(st.elem.get("lane", ""))
        want = _min_stop_m(st.vclass)
        if lane.getLength() >= want:
            continue
        edge = lane.getEdge()
        before = [e for e in edge.getIncoming() if e is not edge.getBidi()]
        if len(before) != 1:
            continue
        prev = next((ln for ln in before[0].getLanes() if lane_class(set(ln.getPermissions())) == st.vclass), None)
        if prev is None or prev.getLength() < want:
            continue
        end = max(want, prev.getLength() - END_CLEARANCE_M)  # the halt mark a little short of the junction
        st.elem.set("lane", prev.getID())
        st.elem.set("startPos", f"{end - want:.2f}")
        st.elem.set("endPos", f"{end:.2f}")
        moved += 1
    return moved


def osm_named_stops(osm_file: Path) -> list[tuple[float, float, str]]:
    """``(lon, lat, name)`` of every named OSM node tagged as a stop, platform or station (:data:`_STOP_TAGS`)."""
    out: list[tuple[float, float, str]] = []
    with open_xml(osm_file) as fh:
        for _, elem in ET.iterparse(fh, events=("end",)):
            if elem.tag == "node":
                tags = {t.get("k", ""): t.get("v", "") for t in elem.iter("tag")}
                if tags.get("name") and any(tags.get(k) in v for k, v in _STOP_TAGS.items()):
                    out.append((float(elem.get("lon", "nan")), float(elem.get("lat", "nan")), tags["name"]))
                elem.clear()
            elif elem.tag in ("way", "relation"):
                elem.clear()
    return out


def _stop_xy(net: Any, st: Stop) -> tuple[float, float]:
    from sumolib.geomhelper import positionAtShapeOffset

    lane = net.getLane(st.elem.get("lane", ""))
    mid = 0.5 * (float(st.elem.get("startPos", 0.0)) + float(st.elem.get("endPos", lane.getLength())))
    x, y = positionAtShapeOffset(lane.getShape(), mid)[:2]
    return float(x), float(y)


def name_unnamed_stops(net: Any, loc: Any, stops: dict[str, Stop], osm_named: list[tuple[float, float, str]]) -> int:
    """Name every stop netconvert wrote without a name (module docstring); the number named from a neighbour.
    Distances in metres on the net's plane, or between lon/lat when the net is geo-referenced (OSM's nodes)."""

    def where(st: Stop) -> tuple[float, float]:
        x, y = _stop_xy(net, st)
        return net_to_lonlat(loc, x, y) if loc is not None else (x, y)

    def dist(a: tuple[float, float], b: tuple[float, float]) -> float:
        return distance_m(a[0], a[1], b[0], b[1]) if loc is not None else math.hypot(a[0] - b[0], a[1] - b[1])

    unnamed = [sid for sid, st in stops.items() if not st.elem.get("name")]
    candidates: list[tuple[tuple[float, float], str, str | None]] = [
        (where(st), st.name, st.vclass) for st in stops.values() if st.elem.get("name")
    ]
    if loc is not None:
        candidates += [((lon, lat), nm, None) for lon, lat, nm in osm_named]
    named = 0
    for sid in unnamed:
        st = stops[sid]
        here = where(st)
        near = [(dist(here, pos), nm) for pos, nm, vc in candidates if vc in (None, st.vclass)]
        d_m, nm = min(near, default=(math.inf, ""))
        if d_m <= UNNAMED_RADIUS_M:
            named += 1
        else:
            nm = f"stop {sid}"
        st.elem.set("name", nm)
        stops[sid] = Stop(st.elem, st.vclass, nm)
    return named
