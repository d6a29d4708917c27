"""``railsim network import`` adds the opposite platform of a station OSM maps on one track only, and only there.

Tram stops are often staggered: each direction's stop position lies on the far side of a junction from the other,
so netconvert puts the two on different edges of their tracks. The import must not take the first for a
one-track station and copy it onto the other track beside it: every train of that direction would then stop
twice at the station, the second time a few metres after the first (Dresden's Hülßestraße: the second stop
41 m on, overrun by 0.9 m and missed by every tram; Jena's line 5 stopped twice at Sparkassen-Arena). A station with a stop on one track only still gets its copy.
The net is built by netconvert from a small OSM file written here: two one-way tram tracks 4.4 m apart, both
split halfway by a railway crossing them."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from tests.helpers import ok_stdout, run_railsim

LAT_EAST_M = 1.0 / 111_320.0  # degrees of latitude per metre
LON_M = 1.0 / (111_320.0 * 0.6293)  # degrees of longitude per metre at 51° N


def _osm(path: Path) -> None:
    """Eastbound track y=0 and westbound track y=4.4 m from x=0 to 1,000 m; a railway crosses both at x=500 m
    (a flat crossing of another class, no connection to it: each tram track is split there and runs on).
    "Staggered" has its eastbound stop at x=470 m and its westbound stop at x=540 m (other edges of each track);
    "One Side" has a stop on the eastbound track only, at x=200 m."""
    nodes: dict[int, tuple[float, float]] = {}
    tags: dict[int, dict[str, str]] = {}

    def node(nid: int, x_m: float, y_m: float, stop: str | None = None) -> int:
        nodes[nid] = (51.0 + y_m * LAT_EAST_M, 13.7 + x_m * LON_M)
        if stop:
            tags[nid] = {"name": stop, "public_transport": "stop_position", "railway": "tram_stop", "tram": "yes"}
        return nid

    east = [node(1, 0, 0), node(2, 200, 0, "One Side"), node(3, 470, 0, "Staggered"), node(4, 500, 0), node(5, 1000, 0)]
    west = [node(11, 1000, 4.4), node(12, 540, 4.4, "Staggered"), node(13, 500, 4.4), node(14, 0, 4.4)]
    crossing = [node(21, 500, -300), node(4, 500, 0), node(13, 500, 4.4), node(22, 500, 300)]  # a railway across
    osm = ET.Element("osm", version="0.6")
    for nid, (lat, lon) in sorted(nodes.items()):
        elem = ET.SubElement(osm, "node", id=str(nid), lat=f"{lat:.7f}", lon=f"{lon:.7f}", version="1")
        for key, value in tags.get(nid, {}).items():
            ET.SubElement(elem, "tag", k=key, v=value)
    for wid, way in ((101, east), (102, west), (103, crossing)):
        elem = ET.SubElement(osm, "way", id=str(wid), version="1")
        for nid in way:
            ET.SubElement(elem, "nd", ref=str(nid))
        ET.SubElement(elem, "tag", k="railway", v="rail" if wid == 103 else "tram")
    ET.ElementTree(osm).write(path, encoding="utf-8", xml_declaration=True)


def test_a_staggered_station_gets_no_second_platform_on_either_track(tmp_path: Path) -> None:
    osm = tmp_path / "staggered.osm"
    _osm(osm)
    world = tmp_path / "w"
    ok_stdout(run_railsim(["network", "import", str(osm), "--out", str(world)], cache_dir=tmp_path / "cache"))
    stops = ET.parse(world / "staggered.stops.tram.add.xml").getroot()
    by_name: dict[str, list[tuple[str, str]]] = {}
    for stop in stops:
        by_name.setdefault(stop.get("name", ""), []).append((stop.get("id", ""), stop.get("lane", "")))
    staggered = sorted(by_name["Staggered"])
    assert [sid for sid, _ in staggered] == ["12", "3"], staggered  # the two OSM stops, no copy of either
    one_side = sorted(by_name["One Side"])
    assert [sid for sid, _ in one_side] == ["2", "2_twin"], one_side  # the one-track station keeps its copy
    assert one_side[1][1].startswith("102"), one_side  # on the westbound track
