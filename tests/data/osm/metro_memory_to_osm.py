"""Rebuild an OpenStreetMap extract (OSM XML, gzipped) from a metro-memory.com ``source.json``.

The game https://github.com/benjamintd/metro-memory.com keeps, for each city, the OSM data it read from the
OpenStreetMap API (``src/app/(game)/<city>/data/source.json``, written by its ``download-osm-raw-data.ts``):

``lines``
    one entry per line (``lineId``, e.g. ``DresdenTram3``); its ``relations`` are the OSM relations behind the line
    (the ``route_master`` and, read recursively, each child ``route`` relation: one per direction and variant).
    Each relation lists its member stop nodes (``stationsNodeIds``: members whose role starts with ``stop``) and its
    member ways (``routesWayIds``: members with an empty role; platforms are left out), both in member order.
    The ``route_master`` itself has neither. ``extraStationNodeIds``/``extraRouteWayIds`` are ids the game's
    authors added by hand for their map.
``ways``
    each way's id and node ids, in order.
``nodes``
    each node's id, latitude, longitude and (for stops) name.

Beside it, ``lines.json`` maps each ``lineId`` to the line's public ``name`` (``"3"``), which becomes the ``ref``.

What this writes is what ``netconvert`` needs to build the track, the stops and the lines (``railsim network
import``): each route relation with members as an OSM relation ``type=route``, ``route=<mode>``, ``ref``, its stop
nodes first (role ``stop``) and then its ways (empty role), each in the source's order; each member way as an
OSM way with its nodes and the railway tag of the mode (``railway=tram`` for a tram); each node of those ways;
each stop node tagged ``name``, ``public_transport=stop_position``, the mode's stop tag (``railway=tram_stop``
for a tram, ``railway=stop`` otherwise) and ``<mode>=yes``. Ids, coordinates, names and member order are the
source's. Nothing is invented: the source holds no other tags (no ``oneway``, no speeds, no platforms), and
the extra ids are left out (only what the OSM relations hold is used). ``--line`` keeps a subset of the lines,
which keeps the extract small.

**Gaps in a route are closed** (:func:`close_gaps`), the one change to the relations: where two consecutive
member ways of a route share no node, an OSM edit split a way and added the new piece to some of the routes
that use it but not to this one (in Dresden's data the pieces of the tracks past Hauptbahnhof Nord are members of
lines 7 and 9 only, so lines 3 and 11 jump 146 m). netconvert then cannot follow the route, and railsim finds no
path through the line's stations. The shortest chain of the source's other member ways (ways of any line's
route) joining the two is inserted between them, when one of at most :data:`MAX_GAP_WAYS` ways exists; the
script reports each gap it closed and each it could not.

Run (the Dresden extract in this folder)::

    git -C METRO_MEMORY show 83767b5b:'src/app/(game)/dresden/data/source.json' > source.json
    git -C METRO_MEMORY show 83767b5b:'src/app/(game)/dresden/data/lines.json' > lines.json
    python tests/data/osm/metro_memory_to_osm.py source.json lines.json --mode tram \\
        --line DresdenTram3 --line DresdenTram9 ... --out tests/data/osm/dresden_tram_2025.osm.gz

The output is byte-for-byte reproducible (elements sorted by id inside each kind, gzip without a timestamp).
"""

from __future__ import annotations

import argparse
import gzip
import json
import sys
import xml.etree.ElementTree as ET
from collections import defaultdict, deque
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

MAX_GAP_WAYS = 4  # a longer chain is no split piece but a different path: the gap is left as it is
RAILWAY_TAG = {"tram": "tram", "subway": "subway", "light_rail": "light_rail", "train": "rail"}  # route= -> railway=


@dataclass(frozen=True)
class Route:
    """One OSM route relation of a line: its stop nodes and ways in member order."""

    relation_id: int
    ref: str
    stop_node_ids: tuple[int, ...]
    way_ids: tuple[int, ...]


def read_routes(source: dict[str, Any], refs: dict[str, str], keep: set[str] | None) -> list[Route]:
    """The route relations of the kept lines (all when ``keep`` is None) that have members.

    A relation without stops or ways (the ``route_master``) is skipped: its routes are listed on their own.
    A ``lineId`` missing from ``refs`` is an error (the ref is what the line is called after import)."""
    routes: list[Route] = []
    for line in source["lines"]:
        line_id = str(line["lineId"])
        if keep is not None and line_id not in keep:
            continue
        if line_id not in refs:
            raise SystemExit(f"metro_memory_to_osm: error: lines.json: {line_id}: expected a name, got none")
        for relation in line["relations"]:
            stops = tuple(int(n) for n in relation["stationsNodeIds"])
            ways = tuple(int(w) for w in relation["routesWayIds"])
            if stops and ways:
                routes.append(Route(int(relation["relationId"]), refs[line_id], stops, ways))
    return routes


def close_gaps(route: Route, way_nodes: dict[int, list[int]]) -> tuple[Route, list[str]]:
    """``route`` with every gap between consecutive member ways closed by the shortest chain of source ways
    (fewest ways, breadth first over ways that share a node), and one line per gap saying what was done."""
    ways_at: dict[int, list[int]] = defaultdict(list)
    for wid in sorted(way_nodes):
        for nid in way_nodes[wid]:
            ways_at[nid].append(wid)
    members = list(route.way_ids)
    out: list[int] = [members[0]]
    notes: list[str] = []
    for prev, nxt in zip(members, members[1:]):
        if set(way_nodes[prev]) & set(way_nodes[nxt]):
            out.append(nxt)
            continue
        chain = _shortest_chain(prev, nxt, way_nodes, ways_at)
        if chain is None:
            notes.append(f"route {route.relation_id}: ways {prev} and {nxt} do not meet; left as they are")
        else:
            notes.append(f"route {route.relation_id}: ways {prev} and {nxt} do not meet; inserted {chain}")
            out.extend(chain)
        out.append(nxt)
    return replace(route, way_ids=tuple(out)), notes


def _shortest_chain(
    start: int, goal: int, way_nodes: dict[int, list[int]], ways_at: dict[int, list[int]]
) -> list[int] | None:
    """The fewest ways (at most :data:`MAX_GAP_WAYS`) leading from way ``start`` to way ``goal``, both excluded."""
    parent: dict[int, int | None] = {start: None}
    queue = deque([(start, 0)])
    while queue:
        wid, depth = queue.popleft()
        if depth > MAX_GAP_WAYS:
            break
        for nid in way_nodes[wid]:
            for nb in ways_at[nid]:
                if nb in parent:
                    continue
                parent[nb] = wid
                if nb == goal:
                    chain: list[int] = []
                    step = parent[nb]
                    while step is not None and step != start:
                        chain.append(step)
                        step = parent[step]
                    return chain[::-1] if len(chain) <= MAX_GAP_WAYS else None
                queue.append((nb, depth + 1))
    return None


def build_osm(source: dict[str, Any], routes: list[Route], mode: str) -> ET.Element:
    """The ``<osm>`` element holding the routes, their ways and those ways' nodes (see the module docstring)."""
    way_nodes = {int(w["wayId"]): [int(n) for n in w["nodeIds"]] for w in source["ways"]}
    node_data = {int(n["nodeId"]): n for n in source["nodes"]}
    way_ids = sorted({w for r in routes for w in r.way_ids})
    missing_ways = [w for w in way_ids if w not in way_nodes]
    if missing_ways:
        raise SystemExit(
            f"metro_memory_to_osm: error: source: ways: expected every member way, missing {missing_ways[:5]}"
        )
    stop_ids = {n for r in routes for n in r.stop_node_ids}
    node_ids = sorted({n for w in way_ids for n in way_nodes[w]} | stop_ids)
    missing_nodes = [n for n in node_ids if n not in node_data]
    if missing_nodes:
        raise SystemExit(f"metro_memory_to_osm: error: source: nodes: expected every node, missing {missing_nodes[:5]}")

    osm = ET.Element("osm", version="0.6", generator="metro_memory_to_osm.py")
    for nid in node_ids:
        data = node_data[nid]
        node = ET.SubElement(osm, "node", id=str(nid), lat=str(data["lat"]), lon=str(data["lon"]), version="1")
        if nid in stop_ids:
            tags = {
                "public_transport": "stop_position",
                "railway": "tram_stop" if mode == "tram" else "stop",
                mode: "yes",
            }
            if data.get("name"):
                tags = {"name": str(data["name"]), **tags}
            for key, value in tags.items():
                ET.SubElement(node, "tag", k=key, v=value)
    for wid in way_ids:
        way = ET.SubElement(osm, "way", id=str(wid), version="1")
        for nid in way_nodes[wid]:
            ET.SubElement(way, "nd", ref=str(nid))
        ET.SubElement(way, "tag", k="railway", v=RAILWAY_TAG[mode])
    for route in sorted(routes, key=lambda r: r.relation_id):
        rel = ET.SubElement(osm, "relation", id=str(route.relation_id), version="1")
        for nid in route.stop_node_ids:
            ET.SubElement(rel, "member", type="node", ref=str(nid), role="stop")
        for wid in route.way_ids:
            ET.SubElement(rel, "member", type="way", ref=str(wid), role="")
        for key, value in (("type", "route"), ("route", mode), ("ref", route.ref)):
            ET.SubElement(rel, "tag", k=key, v=value)
    return osm


def write_gzip(osm: ET.Element, out: Path) -> None:
    """Write ``osm`` as indented OSM XML, gzipped without a file name or time stamp (reproducible bytes)."""
    ET.indent(osm, space=" ")
    text = ET.tostring(osm, encoding="unicode", xml_declaration=False)
    data = ('<?xml version="1.0" encoding="UTF-8"?>\n' + text + "\n").encode("utf-8")
    with out.open("wb") as raw, gzip.GzipFile(filename="", mode="wb", fileobj=raw, mtime=0, compresslevel=9) as gz:
        gz.write(data)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    parser.add_argument("source", type=Path, help="metro-memory source.json (lines, ways, nodes)")
    parser.add_argument("lines", type=Path, help="metro-memory lines.json (lineId -> name, the ref)")
    parser.add_argument("--mode", required=True, choices=sorted(RAILWAY_TAG), help="route= of every line")
    parser.add_argument("--line", action="append", default=None, help="keep this lineId (repeat; default all)")
    parser.add_argument("--out", type=Path, required=True, help="the .osm.gz to write")
    args = parser.parse_args(argv)
    source = json.loads(args.source.read_text(encoding="utf-8"))
    refs = {key: str(value["name"]) for key, value in json.loads(args.lines.read_text(encoding="utf-8")).items()}
    keep = set(args.line) if args.line else None
    way_nodes = {int(w["wayId"]): [int(n) for n in w["nodeIds"]] for w in source["ways"]}
    routes: list[Route] = []
    for route in read_routes(source, refs, keep):
        closed, notes = close_gaps(route, way_nodes)
        routes.append(closed)
        for note in notes:
            print(note, file=sys.stderr)
    write_gzip(build_osm(source, routes, args.mode), args.out)
    n_ways = len({w for r in routes for w in r.way_ids})
    print(f"{args.out}: {len(routes)} route relations, {n_ways} ways", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
