"""A double-track line whose two tracks are both ``bidi`` (as OSM data and ``netconvert --railway.topology.repair``
make it): each direction keeps its own track, a platform can be pinned, opposing trains never meet head-on.

The net is built here with netconvert: two parallel 4 km tracks 4.5 m apart (``N`` north, ``S`` south), each with
an edge for either direction, and a platform on each track at both stations (Aston in the west, Bury in the
east). The stop file lists the north track first, so a router that only minimises metres (all four ways are the
same length) sends both directions along the north track: the line is run as one single track (opposing
trains take turns at the entry, ``departure_held``) and the south track stays empty. With right-hand running
eastbound trains keep the south track and westbound trains the north one; a service naming a stop id (or
``{station, platform}``) is pinned to that platform.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from tests.helpers import read_csv, read_summary, run_railsim
from tests.sumo.test_external_net import _COMMON, _edge, _netconvert, _service, _write


def build_double_bidi(folder: Path) -> tuple[Path, Path]:
    """Two parallel bidi tracks Aston–Bury with a platform on each track (and for each direction) at both ends."""
    nodes = (
        '<node id="A1" x="0" y="4.5"/>\n<node id="B1" x="4000" y="4.5"/>\n'
        '<node id="A2" x="0" y="0"/>\n<node id="B2" x="4000" y="0"/>'
    )
    edges = [_edge("N", "A1", "B1"), _edge("-N", "B1", "A1"), _edge("S", "A2", "B2"), _edge("-S", "B2", "A2")]
    net = _netconvert(folder, "double_bidi", nodes, "\n".join(edges))
    rows = [  # north track first: the order a metres-only router breaks its ties by
        ("a_n", "N_0", 100, 400, "Aston"),
        ("a_n_w", "-N_0", 3600, 3900, "Aston"),
        ("b_n", "N_0", 3600, 3900, "Bury"),
        ("b_n_w", "-N_0", 100, 400, "Bury"),
        ("a_s", "S_0", 100, 400, "Aston"),
        ("a_s_w", "-S_0", 3600, 3900, "Aston"),
        ("b_s", "S_0", 3600, 3900, "Bury"),
        ("b_s_w", "-S_0", 100, 400, "Bury"),
    ]
    body = "\n".join(
        f'  <trainStop id="{s}" lane="{lane}" startPos="{a}" endPos="{b}" name="{n}"/>' for s, lane, a, b, n in rows
    )
    stops = _write(folder, "double_bidi.stops.add.xml", f"<additional>\n{body}\n</additional>")
    return net, stops


def test_each_direction_keeps_its_own_track(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from network.external import load_net

    monkeypatch.setenv("RAILSIM_CACHE", str(tmp_path / "cache"))
    net, stops = build_double_bidi(tmp_path)
    right = load_net(net, [stops])
    assert right.graph.graph["running_side"] == "right"
    assert {n for n, a in right.graph.nodes(data=True) if a["wrong_line"]} == {"N", "-S"}
    assert right.route_between("aston", "bury").edges == ("S",)
    assert right.route_between("bury", "aston").edges == ("-N",)
    pinned = right.route_between("aston", "bury", platforms={"aston": "a_n"})
    assert pinned.edges == ("N",) and pinned.stops[0].stop_id == "a_n"
    left = load_net(net, [stops], running_side="left")
    assert left.route_between("aston", "bury").edges == ("N",)
    assert left.route_between("bury", "aston").edges == ("-S",)
    with pytest.raises(KeyError, match="no platform 'b_n'"):
        right.route_between("aston", "bury", platforms={"aston": "b_n"})


def _routes_given_to_sumo(out: Path) -> dict[str, str]:
    """trip id -> the edges of the route SUMO got (the run folder's copy of the trains)."""
    import xml.etree.ElementTree as ET

    found: dict[str, str] = {}
    for path in out.glob("*.rou.xml"):
        for veh in ET.parse(path).getroot().iter("vehicle"):
            route = veh.find("route")
            if route is not None:
                found[veh.get("id", "")] = route.get("edges", "")
    return found


def _run(folder: Path, services: list[dict]) -> tuple[Path, dict, list[dict[str, str]], dict[str, str]]:
    net, stops = build_double_bidi(folder)
    raw = {"name": "double_bidi", "world": {"net": str(net), "additional": [str(stops)]}, **_COMMON}
    raw["services"] = services
    raw["simulation"] = {**_COMMON["simulation"], "duration_s": 1800}
    scn = _write(folder, "double_bidi.yaml", yaml.safe_dump(raw, sort_keys=False))
    out = folder / "out"
    res = run_railsim(["run", str(scn), "--out", str(out), "--no-progress"], cache_dir=folder / "c", timeout=600)
    assert res.returncode == 0, res.stderr + res.stdout
    s = read_summary(out)
    assert s["n_arrived"] == s["n_trains"] and s["collisions"] == 0 and s["sumo_collisions"] == 0
    return out, s, read_csv(out / "events.csv"), _routes_given_to_sumo(out)


def test_opposing_trains_run_on_their_own_tracks(tmp_path: Path) -> None:
    services = [
        {**_service("east", "aston", "bury", 0), "departures": {"times": [0, 240]}},
        {**_service("west", "Bury", "Aston", 0), "departures": {"times": [0, 240]}},
    ]
    out, s, events, routes = _run(tmp_path, services)
    assert s["n_trains"] == 4
    assert [e for e in events if e["kind"] in ("departure_held", "section_reserved")] == []
    trips = {r["trip_id"]: r for r in read_csv(out / "trips.csv")}
    for trip_id in ("east.000", "west.000", "east.001", "west.001"):
        assert float(trips[trip_id]["departure_s"]) == pytest.approx(float(trip_id[-1]) * 240, abs=2.0), trip_id
    assert routes["east.000"] == routes["east.001"] == "S"
    assert routes["west.000"] == routes["west.001"] == "-N"


def test_a_pinned_platform_holds_against_the_running_side(tmp_path: Path) -> None:
    services = [
        {**_service("east", "aston", "bury", 0), "departures": {"times": [0, 240]}},
        {**_service("west", "Bury", "Aston", 0), "departures": {"times": [0, 240]}},
        _service("pinned", {"station": "Aston", "platform": "a_n"}, "bury", 480),
        _service("by_stop", "Bury", "a_s_w", 480),  # a stop id pins the platform: the south track, westbound
    ]
    _, s, events, routes = _run(tmp_path, services)
    assert s["n_trains"] == 6
    assert routes["pinned.000"] == "N" and routes["by_stop.000"] == "-S"
    # the pinned trains run against the others, so both tracks are single-track sections: interlocked, and east
    # and west never need the same one
    reserved = [(e["subject"], e["detail"]) for e in events if e["kind"] == "section_reserved"]
    east = {sec for sec, d in reserved if "east." in d}
    west = {sec for sec, d in reserved if "west." in d}
    assert east and west and not east & west, reserved
