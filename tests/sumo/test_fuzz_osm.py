"""Hostile OpenStreetMap extracts and user nets (:mod:`tests.fuzz_osm`): a fixed sample of the campaign, and each
defect the campaign found as its own minimal input, through the CLI (``network import``, ``network show``).

Every outcome keeps the product rule: exit 0, or exit 2 with one line ``railsim: error: FILE: FIELD: ...`` naming
the file and the element — never a traceback, exit 4, a hang, or a world that imports and is broken.
"""

from __future__ import annotations

import gzip
from pathlib import Path

import pytest

from tests import fuzz_osm

SAMPLE = range(40, 56)  # 8 OSM extracts, 8 nets; a few seconds each
OSM_HEAD = '<?xml version="1.0" encoding="UTF-8"?>\n<osm version="0.6">\n'
TRACK = (
    '<node id="1" lat="50.9000" lon="11.5900"/>\n<node id="2" lat="50.9010" lon="11.5900"/>\n'
    '<node id="3" lat="50.9020" lon="11.5900"/>\n'
    '<way id="10"><nd ref="1"/><nd ref="2"/><nd ref="3"/><tag k="railway" v="tram"/>{way_tags}</way>\n'
)


@pytest.fixture(scope="module")
def work(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fuzz_osm")


@pytest.fixture(scope="module")
def cache(work: Path) -> Path:
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("RAILSIM_CACHE", str(work / "cache"))
        yield work / "cache"


@pytest.fixture(scope="module")
def bases(work: Path, cache: Path) -> tuple[bytes, tuple[bytes, bytes]]:
    return fuzz_osm.bases(work)


def _osm(folder: Path, body: str, name: str = "city.osm") -> Path:
    path = folder / name
    path.write_text(body, encoding="utf-8")
    return path


def _refusal(argv: list[str], inputs: list[Path]) -> str:
    """The one error line of a command that must refuse cleanly, naming one of ``inputs``."""
    verdict, detail = fuzz_osm.judge(fuzz_osm._cli(argv, fuzz_osm.TIMEOUT_S), inputs)
    assert verdict == "refused", detail
    return detail


def _import(osm: Path, out: Path) -> str:
    return _refusal(["network", "import", str(osm), "--out", str(out)], [osm])


@pytest.mark.parametrize("k", SAMPLE)
def test_a_sample_of_the_campaign_keeps_the_rule(
    k: int, bases: tuple[bytes, tuple[bytes, bytes]], tmp_path: Path
) -> None:
    m = fuzz_osm.mutant(k, 0, *bases)
    verdict, detail = fuzz_osm.check(m, tmp_path)
    assert verdict in ("ok", "refused"), f"mutant {k} ({'; '.join(m.ops)}): {detail}"


def test_the_minimal_extract_imports(tmp_path: Path, cache: Path) -> None:
    """The base of the regressions below is a valid extract: each refusal is the mutation's."""
    osm = _osm(tmp_path, OSM_HEAD + TRACK.format(way_tags="") + "</osm>\n")
    verdict, detail = fuzz_osm.judge(
        fuzz_osm._cli(["network", "import", str(osm), "--out", str(tmp_path / "w")], 60), []
    )
    assert verdict == "ok", detail


def test_an_html_root_is_not_an_extract(tmp_path: Path, cache: Path) -> None:
    # was: imported (netconvert reads any root element)
    osm = _osm(tmp_path, "<html>\n" + TRACK.format(way_tags="") + "</html>\n")
    assert "root element: expected an OpenStreetMap file (an <osm> root), got <html>" in _import(osm, tmp_path / "w")


@pytest.mark.parametrize("value", ["nan", "inf", "91", ""])
def test_a_node_latitude_must_be_a_latitude(value: str, tmp_path: Path, cache: Path) -> None:
    # was: nan imported as it is; an empty one refused by netconvert without saying which node's
    body = OSM_HEAD + TRACK.format(way_tags="").replace('lat="50.9010"', f'lat="{value}"') + "</osm>\n"
    line = _import(_osm(tmp_path, body), tmp_path / "w")
    assert "node[id=2].lat: expected a latitude in -90..90 degrees" in line


@pytest.mark.parametrize("value", ["inf", "0", "-50", "1e308"])
def test_a_maxspeed_out_of_range_names_the_way(value: str, tmp_path: Path, cache: Path) -> None:
    # was: the net got a track of speed inf (or the type's speed, silently) and imported
    body = OSM_HEAD + TRACK.format(way_tags=f'<tag k="maxspeed" v="{value}"/>') + "</osm>\n"
    assert "way[id=10].maxspeed: expected a speed above 0" in _import(_osm(tmp_path, body), tmp_path / "w")


def test_a_maxspeed_netconvert_does_not_read_keeps_the_track_speed(tmp_path: Path, cache: Path) -> None:
    body = OSM_HEAD + TRACK.format(way_tags='<tag k="maxspeed" v="fast"/>') + "</osm>\n"
    res = fuzz_osm._cli(["network", "import", str(_osm(tmp_path, body)), "--out", str(tmp_path / "w")], 60)
    assert fuzz_osm.judge(res, [])[0] == "ok"


def test_entity_declarations_are_refused_before_netconvert(tmp_path: Path, cache: Path) -> None:
    # was: netconvert's "no declaration found for element 'osm'", naming no place
    body = fuzz_osm.BILLION_LAUGHS + '<osm version="0.6">&lol9;' + TRACK.format(way_tags="") + "</osm>\n"
    assert ": line 3: expected an OpenStreetMap file without entity declarations" in _import(
        _osm(tmp_path, body), tmp_path / "w"
    )


def test_broken_xml_and_gzip_name_the_place(tmp_path: Path, cache: Path) -> None:
    # was: "netconvert refused it: Error: whitespace expected", naming no place
    cut = _osm(tmp_path, (OSM_HEAD + TRACK.format(way_tags=""))[:-40])
    assert ": line 6, column " in _import(cut, tmp_path / "w")
    packed = gzip.compress((OSM_HEAD + TRACK.format(way_tags="") + "</osm>\n").encode(), mtime=0)
    broken = tmp_path / "city.osm.gz"
    broken.write_bytes(packed[:-12] + b"\x00" * 12)
    assert "got a broken gzip stream" in _import(broken, tmp_path / "w2")


# ---- user nets: the base world's net with one element broken -------------------------------------------------------


def _net_refusal(bases: tuple[bytes, tuple[bytes, bytes]], folder: Path, old: bytes, new: bytes) -> str:
    net_bytes, stops_bytes = bases[1]
    assert old in net_bytes
    net, stops = folder / "w.net.xml", folder / "w.stops.add.xml"
    net.write_bytes(net_bytes.replace(old, new, 1))
    stops.write_bytes(stops_bytes)
    return _refusal(["network", "show", str(net), "-a", str(stops)], [net])


def test_a_missing_junction_names_the_edge(bases: tuple[bytes, tuple[bytes, bytes]], tmp_path: Path) -> None:
    # was: exit 4 (TypeError in the switch search: sumolib made a node without lanes)
    line = _net_refusal(bases, tmp_path, b'<junction id="main_n5"', b'<junction id="renamed"')
    assert ".from: expected a junction of the network, got 'main_n5'" in line or ".to: expected a junction" in line


def test_a_connection_via_a_missing_lane_names_the_connection(
    bases: tuple[bytes, tuple[bytes, bytes]], tmp_path: Path
) -> None:
    # was: exit 4 (KeyError when the route through the junction was measured)
    line = _net_refusal(bases, tmp_path, b'via=":main_n7_0_0"', b'via=":main_n7_9_0"')
    assert "connection[from=-main_tb_hi,to=main_down_6].via: expected a lane of the network, got ':main_n7_9_0'" in line


@pytest.mark.parametrize(
    ("old", "new", "expected"),
    [
        (b'speed="19.444444"', b'speed="0"', ".speed: expected a speed > 0 m/s, got '0'"),  # was: accepted
        (
            b'4" length="1449.900000"',
            b'4" length="nan"',
            "_0].length: expected a length > 0 m, got 'nan'",
        ),  # was: stops blamed
        (b'toLane="0"', b'toLane="3"', ".toLane: expected a lane index below 1"),  # was: "list index out of range"
    ],
)
def test_a_broken_lane_or_connection_names_it(
    old: bytes, new: bytes, expected: str, bases: tuple[bytes, tuple[bytes, bytes]], tmp_path: Path
) -> None:
    assert expected in _net_refusal(bases, tmp_path, old, new)


def test_a_node_misplaced_by_degrees_imports_and_shows(tmp_path: Path, cache: Path) -> None:
    # was: a hang in `network show` (the wrong-line search indexed every cell of a 5,000 km edge's bounding box)
    body = (
        OSM_HEAD
        + '<node id="1" lat="50.9000" lon="11.5900"/><node id="2" lat="5.9000" lon="11.5900"/>\n'
        + '<node id="3" lat="50.9000" lon="11.59006"/><node id="4" lat="5.9000" lon="11.59006"/>\n'
        + '<way id="10"><nd ref="1"/><nd ref="2"/><tag k="railway" v="tram"/></way>\n'
        + '<way id="11"><nd ref="3"/><nd ref="4"/><tag k="railway" v="tram"/></way>\n</osm>\n'
    )
    verdict, detail = fuzz_osm.check(fuzz_osm.Mutant(0, "osm", ("misplaced",), {"city.osm": body.encode()}), tmp_path)
    assert verdict == "ok", detail
