"""The mutator of :mod:`tests.fuzz_osm` (pure: no netconvert, no SUMO): mutant ``k`` is the same bytes every
time, the hostile families the campaign promises all occur, and the structure checks it led to refuse a
hand-made broken input naming the element."""

from __future__ import annotations

import gzip
import hashlib
import zlib
from pathlib import Path

import pytest

from network.netcheck import check_net_structure
from network.osm_check import check_osm_content
from railsim.errors import ConfigError
from tests import fuzz_osm

OSM = (
    b'<?xml version="1.0"?>\n<osm version="0.6">'
    b'<node id="1" lat="50.9" lon="11.59"><tag k="name" v="A"/><tag k="railway" v="tram_stop"/></node>'
    b'<node id="2" lat="50.91" lon="11.59"/><way id="10"><nd ref="1"/><nd ref="2"/><tag k="railway" v="tram"/></way>'
    b'<relation id="20"><member type="way" ref="10" role=""/><tag k="route" v="tram"/></relation></osm>\n'
)
NET = (
    b'<?xml version="1.0"?>\n<net version="1.20">'
    b'<edge id="e" from="a" to="b"><lane id="e_0" index="0" allow="rail" speed="20" length="100" shape="0,0 100,0"/>'
    b'</edge><edge id="f" from="b" to="a"><lane id="f_0" index="0" allow="rail" speed="20" length="100"/></edge>'
    b'<junction id="a" type="dead_end"/><junction id="b" type="priority"/>'
    b'<connection from="e" to="f" fromLane="0" toLane="0" dir="t"/></net>\n'
)
STOPS = b'<additional><trainStop id="s" lane="e_0" startPos="10" endPos="90" name="S"/></additional>\n'


def _xml(m: fuzz_osm.Mutant) -> bytes:
    """The mutant's first file as plain XML (gzip undone when the stream is intact)."""
    name, data = next(iter(m.files.items()))
    try:
        return gzip.decompress(data) if name.endswith(".gz") else data
    except (OSError, EOFError, zlib.error):
        return data


def test_mutant_k_is_the_same_bytes_every_time() -> None:
    for k in range(60):
        assert fuzz_osm.mutant(k, 3, OSM, (NET, STOPS)) == fuzz_osm.mutant(k, 3, OSM, (NET, STOPS))
    digests = {hashlib.sha256(_xml(fuzz_osm.mutant(k, 0, OSM, (NET, STOPS)))).hexdigest() for k in range(60)}
    assert len(digests) > 30  # and they differ from one another


def test_the_committed_base_gives_the_same_first_mutant_everywhere() -> None:
    base = gzip.decompress(fuzz_osm.OSM_BASE.read_bytes())
    m = fuzz_osm.osm_mutant(4, 0, base)  # a tree mutation, serialised by ElementTree, gzip-compressed
    assert m.ops == ("relation 377683 self", "duplicate node 1272033412")
    assert hashlib.sha256(_xml(m)).hexdigest()[:16] == "285a7fc5554424e1"


def test_every_hostile_family_occurs() -> None:
    labels = " | ".join(op for k in range(400) for op in fuzz_osm.mutant(k, 0, OSM, (NET, STOPS)).ops)
    for family in (
        "nodes missing", "nodes one", "duplicate node", "lat=", "no railway tags", "relation 20 self",
        "relation 20 empty", "maxspeed=", "gauge=", "name=", "billion laughs", "truncated", "gzip broken",
        "header only", "-> <html>", "without lanes", "lane length=", "junction", "connection via missing",
        "no rail vClass", "stop lane", "empty",
    ):  # fmt: skip
        assert family in labels, family


@pytest.mark.parametrize(
    ("old", "new", "field"),
    [
        (b'lat="50.91"', b'lat="nan"', "node[id=2].lat"),
        (b'lon="11.59"/>', b'lon="-181"/>', "node[id=2].lon"),
        (b'<tag k="railway" v="tram"/>', b'<tag k="maxspeed" v="inf"/>', "way[id=10].maxspeed"),
        (b"<osm ", b"<html ", "root element"),
        (b'lat="50.91"', b'lat="50.91', "line 2, column"),
        (b"<way ", b'<node id="1" lat="50.9" lon="11.6"/><way ', "node[id=1]"),
        (b'<node id="2"', b'<node id="n2" lat="0" lon="0"/><node id="n2"', "node[id=n2]"),
    ],
)
def test_the_extract_check_names_the_element(old: bytes, new: bytes, field: str, tmp_path: Path) -> None:
    good = tmp_path / "ok.osm"
    good.write_bytes(OSM)
    check_osm_content(good)
    path = tmp_path / "city.osm"
    path.write_bytes(OSM.replace(old, new).replace(b"</osm>", b"</html>" if new == b"<html " else b"</osm>"))
    with pytest.raises(ConfigError) as err:
        check_osm_content(path)
    assert f"{path}: {field}" in str(err.value)


@pytest.mark.parametrize(
    ("old", "new", "field"),
    [
        (b'<junction id="b" type="priority"/>', b"", "edge[id=e].to"),
        (b'toLane="0"', b'toLane="0" via=":x_0_0"', "connection[from=e,to=f].via"),
        (b'to="f" fromLane', b'to="g" fromLane', "connection[from=e,to=g].to"),
        (b'speed="20" length="100"/>', b'speed="0" length="100"/>', "lane[id=f_0].speed"),
        (b'length="100" shape', b'length="-5" shape', "lane[id=e_0].length"),
        (b'<lane id="f_0" index="0" allow="rail" speed="20" length="100"/>', b"", "edge[id=f]"),
    ],
)
def test_the_net_check_names_the_element(old: bytes, new: bytes, field: str, tmp_path: Path) -> None:
    good = tmp_path / "ok.net.xml"
    good.write_bytes(NET)
    check_net_structure(good)
    path = tmp_path / "w.net.xml"
    path.write_bytes(NET.replace(old, new))
    with pytest.raises(ConfigError) as err:
        check_net_structure(path)
    assert f"{path}: {field}" in str(err.value)


def test_the_wrong_line_search_is_linear_in_track_length() -> None:
    """Two bidi tracks 4 m apart on a 1,000 km diagonal (an extract with one node misplaced by degrees makes such
    an edge): the spatial index took every 25 m cell of each segment's bounding box (1.6 billion here: a hang in
    ``network show`` after the import); it takes the cells along the segment."""
    from network.running_side import wrong_line_edges

    d_m = 1_000_000.0 / 2**0.5
    up = [(0.0, 0.0), (d_m, d_m)]
    shapes = {"a": up, "-a": up[::-1], "b": [(x + 2.83, y - 2.83) for x, y in up]}
    shapes["-b"] = shapes["b"][::-1]
    bidi = {"a": "-a", "-a": "a", "b": "-b", "-b": "b"}
    assert wrong_line_edges(shapes, bidi, "right") == {"a", "-b"}


def test_a_node_given_twice_at_one_position_is_one_node(tmp_path: Path) -> None:
    """An extract merged with itself repeats its nodes unchanged: nothing to refuse."""
    path = tmp_path / "twice.osm"
    node = b'<node id="2" lat="50.91" lon="11.59"/>'
    path.write_bytes(OSM.replace(node, node + node))
    check_osm_content(path)


def test_the_first_node_given_at_two_positions_is_named_with_both_lines(tmp_path: Path) -> None:
    """Many nodes, two ids moved: the one named is where a reader going down the file first meets a conflict (the
    earliest second mention), with both its lines."""
    nodes = [f'<node id="{i}" lat="50.{i:04d}" lon="11.5"/>' for i in range(100, 400)]
    nodes.insert(250, '<node id="390" lat="51.0" lon="11.5"/>')  # 390 moved, before its own line: conflict at 390's
    nodes.insert(200, '<node id="150" lat="50.0150" lon="11.5"/>')  # 150 again, same place: fine
    nodes.insert(280, '<node id="120" lat="50.0120" lon="11.6"/>')  # 120 moved: met before 390's second mention
    text = '<?xml version="1.0"?>\n<osm version="0.6">\n' + "\n".join(nodes) + "\n</osm>\n"
    path = tmp_path / "merged.osm"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ConfigError) as err:
        check_osm_content(path)
    lines = {i: [n for n, line in enumerate(text.splitlines(), 1) if f'id="{i}"' in line] for i in (120, 390)}
    assert max(lines[120]) < max(lines[390])
    assert f"{path}: node[id=120]: " in str(err.value)
    assert f"lines {lines[120][0]} and {lines[120][1]}" in str(err.value)
