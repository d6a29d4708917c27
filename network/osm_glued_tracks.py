"""Two one-way tracks drawn on one line of nodes: kept two tracks.

OpenStreetMap maps each track of a double-track line as a way of its own; on a metro, each way usually carries
``railway:preferred_direction=forward`` (or ``backward``): trains use it one way. Sometimes mappers glue both tracks
to the same nodes for a stretch — through a station, along a tunnel drawn on one line — so the two ways run over the
same nodes in opposite directions. netconvert then builds, between each pair of those nodes, one edge per direction
with the same geometry, and SUMO takes such a pair for a single bidirectional track (``bidi``): railsim's
single-track rules let one train at a time through what is double track (São Paulo's Line 1 at São Bento: every
northbound train waited for the southbound one; delays grew by ~100 s a train).

:func:`separate` finds these stretches before netconvert reads the extract and gives one of the two ways its own
copy of the shared nodes, so each track is built on its own nodes and netconvert sees two one-way tracks. A copy
has a new id above every node id in the file and lies :data:`TRACK_SPACING_M` to the right of its way's direction of
travel: netconvert merges OSM nodes at the very same position into one. The rule needs both ways to say so: a *glued pair* is two rail ways,
each with an explicit ``railway:preferred_direction`` of ``forward`` or ``backward``, that travel the same segment
(two consecutive nodes) in opposite directions. A way without a preferred direction, or with ``both``, is left as
mapped (a tram's single-track stretch or gauntlet is single track). Which way gets the copies: the one with the
larger id. A shared node that a third rail way also uses (a real junction) is not copied: the two tracks still meet
there, on distinct edges.

The extract is read once (ways and their tags only); only when a glued pair is found is it parsed whole and written
again, to a file netconvert reads instead of the user's (which is never changed).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

from network.xmlscan import open_xml

TRACK_SPACING_M = 4.0  # a copy lies this far to the right of its way's travel (a metro's track centres)
_M_PER_DEG_LAT = 111_320.0  # metres per degree of latitude (and of longitude on the equator)
RAIL_TAGS = ("subway", "light_rail", "tram", "rail", "monorail", "narrow_gauge")  # ``railway=`` values of tracks
_DIRECTIONS = ("forward", "backward")


@dataclass
class Separation:
    """What :func:`separate` did: the file netconvert should read, the glued pairs found (way ids, smaller first),
    and how many node copies were made."""

    source: Path
    pairs: list[tuple[str, str]] = field(default_factory=list)
    copies: int = 0


def _id_key(way_id: str) -> tuple[int, int | str]:
    """Ways ordered by numeric id where they have one (OSM's), else by text."""
    try:
        return (0, int(way_id))
    except ValueError:
        return (1, way_id)


def _rail_ways(osm_file: Path) -> tuple[dict[str, list[str]], dict[str, int], int]:
    """``{way id: its nodes in the direction of travel}`` for every one-way rail way, how many rail ways use each
    node, and the largest numeric node id in the file."""
    ways: dict[str, list[str]] = {}
    users: dict[str, int] = defaultdict(int)
    max_node = 0
    with open_xml(osm_file) as fh:
        for _, elem in ET.iterparse(fh, events=("end",)):
            if elem.tag == "node":
                try:
                    max_node = max(max_node, int(elem.get("id", "0")))
                except ValueError:
                    pass
                elem.clear()
            elif elem.tag == "way":
                tags = {t.get("k"): t.get("v") for t in elem.iter("tag")}
                if tags.get("railway") in RAIL_TAGS:
                    refs = [nd.get("ref", "") for nd in elem.iter("nd")]
                    for ref in set(refs):
                        users[ref] += 1
                    direction = tags.get("railway:preferred_direction")
                    if direction in _DIRECTIONS:
                        ways[elem.get("id", "")] = refs if direction == "forward" else refs[::-1]
                elem.clear()
            elif elem.tag == "relation":
                elem.clear()
    return ways, users, max_node


def glued_pairs(ways: dict[str, list[str]]) -> dict[tuple[str, str], set[str]]:
    """``{(way, other way): shared nodes}`` of every glued pair (module docstring), the way with the smaller id
    first; ``ways`` gives each one-way rail way's nodes in the direction of travel."""
    by_segment: dict[tuple[str, str], list[str]] = defaultdict(list)
    for wid, refs in ways.items():
        for a, b in zip(refs, refs[1:]):
            by_segment[(a, b)].append(wid)
    pairs: dict[tuple[str, str], set[str]] = defaultdict(set)
    for (a, b), wids in by_segment.items():
        for other in by_segment.get((b, a), ()):
            for wid in wids:
                if wid != other:
                    key = (wid, other) if _id_key(wid) < _id_key(other) else (other, wid)
                    pairs[key].update((a, b))
    return dict(pairs)


def separate(osm_file: Path, work: Path) -> Separation:
    """The extract netconvert should read: ``osm_file`` itself when it has no glued pair, else a copy written into
    ``work`` with the glued ways' shared nodes copied (module docstring)."""
    ways, users, max_node = _rail_ways(osm_file)
    pairs = glued_pairs(ways)
    if not pairs:
        return Separation(osm_file)
    moved: dict[str, set[str]] = defaultdict(set)  # way -> nodes it gets copies of
    for (_, later), shared in pairs.items():
        moved[later].update(n for n in shared if users[n] <= 2)
    with open_xml(osm_file) as fh:
        tree = ET.parse(fh)
    root = tree.getroot()
    position = {n.get("id", ""): (float(n.get("lat", "nan")), float(n.get("lon", "nan"))) for n in root.iter("node")}
    copies: dict[tuple[str, str], tuple[str, float, float]] = {}  # (way, node) -> the copy: id, lat, lon
    next_id = max_node
    for wid in sorted(moved, key=_id_key):
        refs = ways[wid]
        for i, node in enumerate(refs):
            if node in moved[wid] and (wid, node) not in copies and node in position:
                next_id += 1
                before, after = refs[max(i - 1, 0)], refs[min(i + 1, len(refs) - 1)]
                lat, lon = _beside(position[node], position.get(before), position.get(after))
                copies[(wid, node)] = (str(next_id), lat, lon)
    _rewrite(root, copies)
    out = work / "railsim-separated.osm"
    tree.write(out, encoding="utf-8", xml_declaration=True)
    return Separation(out, sorted(pairs, key=lambda p: (_id_key(p[0]), _id_key(p[1]))), len(copies))


def _beside(
    here: tuple[float, float], before: tuple[float, float] | None, after: tuple[float, float] | None
) -> tuple[float, float]:
    """``here`` moved :data:`TRACK_SPACING_M` to the right of the direction of travel from ``before`` to ``after``
    (lat/lon in degrees; a local flat-earth step, exact enough over metres)."""
    lat, lon = here
    a, b = before or here, after or here
    north_m = (b[0] - a[0]) * _M_PER_DEG_LAT
    east_m = (b[1] - a[1]) * _M_PER_DEG_LAT * math.cos(math.radians(lat))
    norm = math.hypot(north_m, east_m)
    if norm == 0.0:
        return lat + TRACK_SPACING_M / _M_PER_DEG_LAT, lon  # no direction known: beside it to the north
    right_north, right_east = -east_m / norm, north_m / norm
    return (
        lat + TRACK_SPACING_M * right_north / _M_PER_DEG_LAT,
        lon + TRACK_SPACING_M * right_east / (_M_PER_DEG_LAT * math.cos(math.radians(lat))),
    )


def _rewrite(root: ET.Element, copies: dict[tuple[str, str], tuple[str, float, float]]) -> None:
    """Point the moved ways at their copies and add the copies after the last node (OSM's order: nodes, ways,
    relations)."""
    last_node = max((i for i, elem in enumerate(root) if elem.tag == "node"), default=-1)
    for elem in root.iter("way"):
        wid = elem.get("id", "")
        for nd in elem.iter("nd"):
            copy = copies.get((wid, nd.get("ref", "")))
            if copy is not None:
                nd.set("ref", copy[0])
    for k, (new, lat, lon) in enumerate(sorted(copies.values(), key=lambda c: int(c[0])), start=1):
        attrs = {"id": new, "lat": f"{lat:.9f}", "lon": f"{lon:.9f}", "version": "1"}
        root.insert(last_node + k, ET.Element("node", attrs))
