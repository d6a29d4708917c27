"""The converter behind ``tests/data/osm/dresden_tram_2025.osm.gz`` (``tests/data/osm/metro_memory_to_osm.py``):
a metro-memory.com ``source.json`` becomes OSM XML whose route relations netconvert can follow — members in the
source's order, the tags of the mode, and a gap an OSM way split left in a route closed with the split piece."""

from __future__ import annotations

import gzip
import json
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

from tests.data.osm.metro_memory_to_osm import build_osm, close_gaps, main, read_routes


def _source() -> dict[str, Any]:
    """Line A runs over ways 1 and 3; way 2 (the piece between them, split off in OSM) belongs to line B only."""
    nodes = [{"nodeId": n, "lat": 51.0, "lon": 13.7 + n * 0.001} for n in range(1, 6)]
    nodes[0]["name"] = "West"
    nodes[4]["name"] = "East"
    return {
        "lines": [
            {
                "lineId": "CityA",
                "relations": [
                    {"relationId": 900, "stationsNodeIds": [], "routesWayIds": []},  # the route_master
                    {"relationId": 901, "stationsNodeIds": [1, 5], "routesWayIds": [1, 3]},
                ],
                "extraStationNodeIds": [],
                "extraRouteWayIds": [],
            },
            {
                "lineId": "CityB",
                "relations": [{"relationId": 902, "stationsNodeIds": [1, 5], "routesWayIds": [1, 2, 3]}],
                "extraStationNodeIds": [],
                "extraRouteWayIds": [],
            },
        ],
        "ways": [
            {"wayId": 1, "nodeIds": [1, 2]},
            {"wayId": 2, "nodeIds": [2, 3, 4]},
            {"wayId": 3, "nodeIds": [4, 5]},
        ],
        "nodes": nodes,
    }


def test_a_gap_in_a_route_is_closed_with_the_split_piece_and_the_rest_is_kept() -> None:
    source = _source()
    (route,) = read_routes(source, {"CityA": "A", "CityB": "B"}, keep={"CityA"})
    assert route.relation_id == 901 and route.ref == "A" and route.way_ids == (1, 3)
    way_nodes = {w["wayId"]: w["nodeIds"] for w in source["ways"]}
    closed, notes = close_gaps(route, way_nodes)
    assert closed.way_ids == (1, 2, 3) and closed.stop_node_ids == (1, 5)
    assert notes == ["route 901: ways 1 and 3 do not meet; inserted [2]"]
    osm = build_osm(source, [closed], "tram")
    rel = osm.find("relation")
    assert rel is not None
    members = [(m.get("type"), m.get("ref"), m.get("role")) for m in rel.findall("member")]
    assert members == [
        ("node", "1", "stop"),
        ("node", "5", "stop"),
        ("way", "1", ""),
        ("way", "2", ""),
        ("way", "3", ""),
    ]
    assert {t.get("k"): t.get("v") for t in rel.findall("tag")} == {"type": "route", "route": "tram", "ref": "A"}
    stop = next(n for n in osm.findall("node") if n.get("id") == "1")
    assert {t.get("k"): t.get("v") for t in stop.findall("tag")} == {
        "name": "West",
        "public_transport": "stop_position",
        "railway": "tram_stop",
        "tram": "yes",
    }
    assert [t.get("v") for w in osm.findall("way") for t in w.findall("tag")] == ["tram", "tram", "tram"]


def test_the_written_file_is_reproducible(tmp_path: Path) -> None:
    src, lines = tmp_path / "source.json", tmp_path / "lines.json"
    src.write_text(json.dumps(_source()), encoding="utf-8")
    lines.write_text(json.dumps({"CityA": {"name": "A"}, "CityB": {"name": "B"}}), encoding="utf-8")
    outs = [tmp_path / "a.osm.gz", tmp_path / "b.osm.gz"]
    for out in outs:
        assert main([str(src), str(lines), "--mode", "tram", "--out", str(out)]) == 0
    assert outs[0].read_bytes() == outs[1].read_bytes()
    root = ET.fromstring(gzip.decompress(outs[0].read_bytes()))
    assert sorted(r.get("id") for r in root.findall("relation")) == ["901", "902"]  # not the empty route_master
