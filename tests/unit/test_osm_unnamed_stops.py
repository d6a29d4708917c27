"""``railsim network import`` names the stops OSM maps without a name (a bare stop position in a route relation
whose name sits on the platform node beside it): after the nearest named stop or OSM platform within
``UNNAMED_RADIUS_M``, else ``stop <id>`` — never the bare stop id, which a scenario would read as a pinned
platform (Jena's extract has six such stops)."""

from __future__ import annotations

import gzip
import xml.etree.ElementTree as ET
from pathlib import Path

from network.osm_stops import UNNAMED_RADIUS_M, Stop, name_unnamed_stops, osm_named_stops


class _Lane:
    def __init__(self, y_m: float) -> None:
        self.y_m = y_m

    def getLength(self) -> float:  # noqa: N802 - sumolib's name
        return 100.0

    def getShape(self) -> list[tuple[float, float]]:  # noqa: N802 - sumolib's name
        return [(0.0, self.y_m), (100.0, self.y_m)]


class _Net:
    """Parallel straight lanes ``L<y>`` 100 m long at height y (metres), as sumolib's net answers for them."""

    def getLane(self, lane_id: str) -> _Lane:  # noqa: N802 - sumolib's name
        return _Lane(float(lane_id[1:]))


def _stop(sid: str, lane: str, name: str | None, vclass: str = "tram") -> Stop:
    attrs = {"id": sid, "lane": lane, "startPos": "35", "endPos": "65"}
    if name:
        attrs["name"] = name
    return Stop(ET.Element("trainStop", attrs), vclass, name or sid)


def test_an_unnamed_stop_takes_the_nearest_named_stop_of_its_class_else_stop_id() -> None:
    stops = {
        "1": _stop("1", "L0", "Felsenkeller"),
        "2": _stop("2", "L30", None),  # the other track of Felsenkeller, 30 m away
        "3": _stop("3", "L20", "Depot", vclass="rail"),  # nearer, but another class
        "9": _stop("9", f"L{UNNAMED_RADIUS_M + 400:g}", None),  # nothing named near
    }
    named = name_unnamed_stops(_Net(), None, stops, [])
    assert named == 1
    assert stops["2"].name == "Felsenkeller" and stops["2"].elem.get("name") == "Felsenkeller"
    assert stops["9"].name == "stop 9" and stops["9"].name != "9"
    assert stops["1"].name == "Felsenkeller"


def test_named_stop_and_platform_nodes_are_read_from_the_osm_file(tmp_path: Path) -> None:
    osm = tmp_path / "x.osm.gz"
    with gzip.open(osm, "wt", encoding="utf-8") as fh:
        fh.write(
            '<osm version="0.6">'
            '<node id="1" lat="50.92" lon="11.58"><tag k="name" v="Felsenkeller"/>'
            '<tag k="public_transport" v="platform"/><tag k="railway" v="tram_stop"/></node>'
            '<node id="2" lat="50.93" lon="11.59"><tag k="public_transport" v="stop_position"/></node>'
            '<node id="3" lat="50.94" lon="11.60"><tag k="name" v="Bakery"/><tag k="shop" v="bakery"/></node>'
            '<node id="4" lat="50.95" lon="11.61"/>'
            '<way id="5"><nd ref="1"/><nd ref="4"/><tag k="railway" v="tram"/><tag k="name" v="Street"/></way>'
            "</osm>"
        )
    assert osm_named_stops(osm) == [(11.58, 50.92, "Felsenkeller")]
