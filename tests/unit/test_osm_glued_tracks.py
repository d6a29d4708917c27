"""Two one-way tracks drawn on one line of nodes are kept two tracks (:mod:`network.osm_glued_tracks`).

The rule on the ways (which pairs are glued), and the rewritten extract: the later way gets copies of the shared
nodes beside them, a node a third rail way uses stays shared, and an extract without a glued pair is
read as it is.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from network.osm_glued_tracks import TRACK_SPACING_M, glued_pairs, separate


def test_opposite_directions_over_one_segment_are_a_glued_pair() -> None:
    ways = {"10": ["1", "2", "3", "4"], "20": ["9", "4", "3", "2", "8"], "30": ["5", "6"]}
    assert glued_pairs(ways) == {("10", "20"): {"2", "3", "4"}}


def test_the_same_direction_or_one_shared_node_is_not_a_glued_pair() -> None:
    assert glued_pairs({"10": ["1", "2", "3"], "20": ["1", "2", "3"]}) == {}  # same direction
    assert glued_pairs({"10": ["1", "2", "3"], "20": ["4", "2", "5"]}) == {}  # they cross at one node


def _osm(ways: str) -> str:
    nodes = "".join(f'<node id="{i}" lat="50.{i}" lon="11.{i}"/>' for i in range(1, 10))
    return f'<?xml version="1.0"?>\n<osm version="0.6">{nodes}{ways}</osm>\n'


def _way(wid: int, refs: list[int], direction: str | None, railway: str = "subway") -> str:
    nds = "".join(f'<nd ref="{r}"/>' for r in refs)
    tag = f'<tag k="railway:preferred_direction" v="{direction}"/>' if direction else ""
    return f'<way id="{wid}">{nds}<tag k="railway" v="{railway}"/>{tag}</way>'


def test_the_later_way_gets_copies_except_where_a_third_track_meets(tmp_path: Path) -> None:
    osm = tmp_path / "city.osm"
    # 10 runs 1..5 forward; 20 runs 5..1 forward over the same nodes; 30 (a siding) leaves node 3
    osm.write_text(
        _osm(_way(10, [1, 2, 3, 4, 5], "forward") + _way(20, [5, 4, 3, 2, 1], "forward") + _way(30, [3, 9], None)),
        encoding="utf-8",
    )
    sep = separate(osm, tmp_path)
    assert sep.source != osm and sep.pairs == [("10", "20")] and sep.copies == 4
    root = ET.parse(sep.source).getroot()
    ways = {w.get("id"): [nd.get("ref") for nd in w.iter("nd")] for w in root.iter("way")}
    assert ways["10"] == ["1", "2", "3", "4", "5"] and ways["30"] == ["3", "9"]
    assert ways["20"] == ["10", "11", "3", "12", "13"]  # copies numbered above node 9 in travel order; 3 kept
    pos = {n.get("id"): (float(n.get("lat", "")), float(n.get("lon", ""))) for n in root.iter("node")}
    for copy, node in (("10", "5"), ("11", "4"), ("12", "2"), ("13", "1")):
        (lat, lon), (lat0, lon0) = pos[copy], pos[node]
        north_m = (lat - lat0) * 111_320.0
        east_m = (lon - lon0) * 111_320.0 * math.cos(math.radians(lat0))
        assert math.hypot(north_m, east_m) == pytest.approx(TRACK_SPACING_M, abs=0.01)
        # way 20 travels south-west (from node 5 to node 1): its right is north-west
        assert north_m > 0 and east_m < 0
    assert "<node" in osm.read_text(encoding="utf-8")  # the user's file is left as it was
    assert [w.get("id") for w in ET.parse(osm).getroot().iter("way")] == ["10", "20", "30"]


def test_ways_without_an_explicit_direction_stay_as_mapped(tmp_path: Path) -> None:
    """A tram's single-track stretch or gauntlet may be drawn as two ways on one line of nodes: without
    ``forward``/``backward`` on both, nothing is copied and netconvert reads the user's file."""
    osm = tmp_path / "tram.osm"
    osm.write_text(_osm(_way(10, [1, 2, 3], "forward", "tram") + _way(20, [3, 2, 1], None, "tram")), encoding="utf-8")
    assert separate(osm, tmp_path).source == osm
    both = tmp_path / "both.osm"
    both.write_text(_osm(_way(10, [1, 2, 3], "forward") + _way(20, [3, 2, 1], "both")), encoding="utf-8")
    assert separate(both, tmp_path).source == both


def test_backward_reads_the_way_against_its_nodes(tmp_path: Path) -> None:
    """Two ways drawn the same way round, one of them ``backward``: trains use them in opposite directions."""
    osm = tmp_path / "city.osm"
    osm.write_text(_osm(_way(10, [1, 2, 3], "forward") + _way(20, [1, 2, 3], "backward")), encoding="utf-8")
    assert separate(osm, tmp_path).pairs == [("10", "20")]
