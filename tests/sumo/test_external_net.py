"""Bring your own SUMO net: three networks railsim did not generate, built here with netconvert.

* **ring**: a one-way loop line (four curved edges, four stations, no switches); a service wraps around the
  point where the loop closes.
* **passing loop**: single track (``bidi`` edges) with a crossing loop and **rail signals** at both loop ends
  (stripped in railsim's copy); two stations share one edge; opposing trains cross at the loop station.
* **junction**: a double-track main line with a single-track ``bidi`` branch (a diverge on the up track, a
  merge on the down track); the pair decouples before the diverge and the follower takes the branch.

Each runs an ATO service and a virtually coupled pair end to end in SUMO through the engine (a child process,
``railsim run``): 0 collisions (ours and SUMO's), every stop served, no switch violation. Topology, the rail-
signal choice, ``railsim network show`` and every documented error (exit code 2, file and field named) are
checked too.
"""

from __future__ import annotations

import math
import subprocess
from pathlib import Path

import pytest
import yaml

from network.generator import netconvert_binary as netconvert
from tests.helpers import read_csv, read_summary, run_railsim


def _write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(text.strip() + "\n", encoding="utf-8")
    return path


def _netconvert(folder: Path, name: str, nodes: str, edges: str, connections: str = "") -> Path:
    """Build ``name.net.xml`` from plain XML; ``connections`` (``<connection .../>`` lines) restricts the links."""
    nod = _write(folder, f"{name}.nod.xml", f"<nodes>\n{nodes}\n</nodes>")
    edg = _write(folder, f"{name}.edg.xml", f"<edges>\n{edges}\n</edges>")
    net = folder / f"{name}.net.xml"
    extra = []
    if connections:
        extra = ["-x", str(_write(folder, f"{name}.con.xml", f"<connections>\n{connections}\n</connections>"))]
    proc = subprocess.run(
        [str(netconvert()), "-n", str(nod), "-e", str(edg), *extra, "-o", str(net)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    return net


def _edge(
    eid: str, a: str, b: str, speed: float = 22.0, spread: str = "center", shape: str = "", allow: str = "rail_urban"
) -> str:
    shp = f' shape="{shape}"' if shape else ""
    return (
        f'<edge id="{eid}" from="{a}" to="{b}" numLanes="1" speed="{speed}" allow="{allow}" '
        f'spreadType="{spread}"{shp}/>'
    )


def _stops(folder: Path, name: str, stops: list[tuple[str, str, float, float, str]]) -> Path:
    body = "\n".join(
        f'  <trainStop id="{s}" lane="{lane}" startPos="{a}" endPos="{b}" name="{n}"/>' for s, lane, a, b, n in stops
    )
    return _write(folder, f"{name}.stops.add.xml", f"<additional>\n{body}\n</additional>")


def build_ring(folder: Path) -> tuple[Path, Path]:
    r = 800.0
    nodes = "\n".join(
        f'<node id="R{k}" x="{r * math.cos(k * math.pi / 2):.3f}" y="{r * math.sin(k * math.pi / 2):.3f}"/>'
        for k in range(4)
    )
    edges = []
    for k in range(4):  # counter-clockwise quarter arcs, shape points every 5 degrees
        pts = " ".join(
            f"{r * math.cos(math.radians(90 * k + d)):.3f},{r * math.sin(math.radians(90 * k + d)):.3f}"
            for d in range(0, 91, 5)
        )
        edges.append(_edge(f"q{k}", f"R{k}", f"R{(k + 1) % 4}", spread="right", shape=pts))
    net = _netconvert(folder, "ring", nodes, "\n".join(edges))
    stops = _stops(folder, "ring", [(f"s{k}", f"q{k}_0", 500.0, 800.0, f"Ring {k}") for k in range(4)])
    return net, stops


def build_passing_loop(folder: Path) -> tuple[Path, Path]:
    nodes = """<node id="A" x="0" y="0"/>
<node id="W" x="3000" y="0" type="rail_signal"/>
<node id="E" x="4200" y="0" type="rail_signal"/>
<node id="B" x="6200" y="0"/>"""
    loop = "3000,0 3200,-40 4000,-40 4200,0"
    edges = [
        _edge("AW", "A", "W"),
        _edge("-AW", "W", "A"),
        _edge("L1", "W", "E"),
        _edge("-L1", "E", "W"),
        _edge("L2", "W", "E", 16.0, shape=loop),
        _edge("-L2", "E", "W", 16.0, shape=" ".join(reversed(loop.split()))),
        _edge("EB", "E", "B"),
        _edge("-EB", "B", "E"),
    ]
    net = _netconvert(folder, "passing", nodes, "\n".join(edges))
    stops = _stops(
        folder,
        "passing",
        [
            ("portal_e", "AW_0", 100, 400, "Portal"),
            ("alpha_e", "AW_0", 1000, 1300, "Alpha"),
            ("alpha_w", "-AW_0", 1700, 2000, "Alpha"),
            ("portal_w", "-AW_0", 2600, 2900, "Portal"),
            ("mid_1", "L1_0", 400, 700, "Mid"),
            ("mid_2", "-L2_0", 400, 700, "Mid"),
            ("bravo_e", "EB_0", 1600, 1900, "Bravo"),
            ("bravo_w", "-EB_0", 100, 400, "Bravo"),
        ],
    )
    return net, stops


def build_junction(folder: Path) -> tuple[Path, Path]:
    nodes = """<node id="X" x="0" y="0"/>
<node id="J" x="6000" y="0"/>
<node id="Y" x="8500" y="0"/>
<node id="Z" x="8300" y="900"/>"""
    branch = "6000,0 6600,150 8300,900"
    edges = [
        _edge("U1", "X", "J", spread="right"),
        _edge("D1", "J", "X", spread="right"),
        _edge("U2", "J", "Y", spread="right"),
        _edge("D2", "Y", "J", spread="right"),
        _edge("Z1", "J", "Z", 16.0, shape=branch),
        _edge("-Z1", "Z", "J", 16.0, shape=" ".join(reversed(branch.split()))),
    ]
    net = _netconvert(folder, "junction", nodes, "\n".join(edges))
    stops = _stops(
        folder,
        "junction",
        [
            ("x1_up", "U1_0", 200, 500, "X1"),
            ("x2_up", "U1_0", 1500, 1800, "X2"),
            ("y1_up", "U2_0", 1900, 2200, "Y1"),
            ("zed_in", "Z1_0", 2000, 2300, "Zed"),
            ("zed_out", "-Z1_0", 100, 400, "Zed"),
            ("x2_down", "D1_0", 4200, 4500, "X2"),
            ("x1_down", "D1_0", 5500, 5800, "X1"),
        ],
    )
    return net, stops


@pytest.fixture(scope="module")
def cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("extcache")


@pytest.fixture(scope="module")
def nets(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, Path]]:
    folder = tmp_path_factory.mktemp("extnets")
    return {"ring": build_ring(folder), "passing": build_passing_loop(folder), "junction": build_junction(folder)}


@pytest.fixture()
def use_cache(cache: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("RAILSIM_CACHE", str(cache))
    return cache


# ---- topology -------------------------------------------------------------------------------------------------


def test_passing_loop_topology_and_stripped_signals(nets: dict, use_cache: Path) -> None:
    from network.external import load_net

    net, stops = nets["passing"]
    b = load_net(net, [stops])
    assert b.n_rail_signals == 2 and b.signals == "strip"
    assert b.net_file != net and b.net_file.is_relative_to(use_cache)  # railsim's copy, in the cache
    assert "rail_signal" not in b.net_file.read_text() and "rail_signal" in net.read_text()
    # stations grouped by name, with both platforms; two stations share edge AW
    assert set(b.stations) == {"portal", "alpha", "mid", "bravo"}
    assert {p.stop_id for p in b.stations["alpha"].platforms} == {"alpha_e", "alpha_w"}
    assert {p.direction for p in b.stations["mid"].platforms} == {"E", "W"}
    assert [s[1] for s in b.graph.nodes["AW"]["stops"]] == ["portal_e", "alpha_e"]
    # one switch per turnout: both directions of travel over the bidi points share one lock
    assert set(b.switches) == {"W", "E"}
    w = b.switches["W"]
    assert (w.kind, w.trunk_edge, w.normal_edge, w.reverse_edge) == ("diverge", "AW", "L1", "L2")
    assert w.diverging_speed_mps == pytest.approx(16.0) and w.normal_speed_mps > 16.0
    assert b.graph.edges["-L2", "-AW"]["switch"] == "W" and b.graph.edges["-L2", "-AW"]["leg"] == "reverse"
    assert not b.graph.has_edge("AW", "-AW")  # no reversal
    # a route chooses the platforms with a path: westbound through Mid takes the loop's other track
    east = b.route_between("portal", "bravo")
    assert east.edges == ("AW", "L1", "EB") and [s.stop_id for s in east.stops] == [
        "portal_e",
        "alpha_e",
        "mid_1",
        "bravo_e",
    ]
    west = b.route_between("bravo", "portal", via=("mid",))
    assert west.edges == ("-EB", "-L2", "-AW")
    assert [(s.switch_id, s.leg) for s in west.switches] == [("E", "reverse"), ("W", "reverse")]
    # chainage = lane lengths plus the internal junction lanes (SUMO's odometer)
    g = b.graph
    expect = sum(g.nodes[e]["length_m"] for e in east.edges) + sum(
        v[1] for a, c in zip(east.edges, east.edges[1:]) for v in g.edges[a, c]["via"]
    )
    assert east.length_m == pytest.approx(expect)
    assert east.stop("bravo").end_m == pytest.approx(east.edge_start_m[2] + 1900.0)
    with pytest.raises(ValueError, match="do not reverse"):
        b.route_between("alpha", "portal", via=("bravo",))
    # the stripped copy is made once per input hash
    mtime = b.net_file.stat().st_mtime_ns
    assert load_net(net, [stops]).net_file.stat().st_mtime_ns == mtime
    kept = load_net(net, [stops], signals="keep")
    assert kept.net_file == net and kept.signals == "keep"


def test_junction_with_bidi_branch_topology(nets: dict, use_cache: Path) -> None:
    from network.external import load_net

    b = load_net(*nets["junction"][:1], [nets["junction"][1]])
    assert b.graph.nodes["Z1"]["bidi"] == "-Z1" and b.graph.nodes["U1"]["bidi"] is None
    assert set(b.switches) == {"J/U1", "J/D1"}
    up, down = b.switches["J/U1"], b.switches["J/D1"]
    assert (up.kind, up.normal_edge, up.reverse_edge) == ("diverge", "U2", "Z1")
    assert (down.kind, down.normal_edge, down.reverse_edge) == ("merge", "D2", "-Z1")
    r = b.route_between("x2", "zed")
    assert r.edges == ("U1", "Z1") and r.switches[0].switch_id == "J/U1" and r.switches[0].leg == "reverse"
    assert [s.station_id for s in b.route_between("zed", "x1").stops] == ["zed", "x2", "x1"]
    with pytest.raises(ValueError, match="reversal"):
        b.route_between("y1", "x1")  # the Y1 platform is on the up track only


def test_ring_routes_wrap_around_the_loop(nets: dict, use_cache: Path) -> None:
    from network.external import load_net

    b = load_net(nets["ring"][0], [nets["ring"][1]])
    assert b.switches == {}
    assert b.station_aliases["s2"] == "ring-2" and b.station_aliases["Ring 2"] == "ring-2"
    r = b.route_between("ring-3", "ring-1")
    assert r.edges == ("q3", "q0", "q1")
    quarter = 2 * math.pi * 800.0 / 4
    assert r.length_m == pytest.approx(3 * quarter, rel=0.02)  # three quarter arcs (netconvert's own lengths)
    assert len(b.routes) == 12  # every ordered station pair on a loop


# ---- end to end in SUMO ---------------------------------------------------------------------------------------

_COMMON = {
    "simulation": {"step_s": 0.5, "duration_s": 1500, "seed": 5},
    "vehicles": {"cq6": {"preset": "cq3_6car"}},
    "controllers": {
        "ato": {"type": "ato"},
        "sep": {"type": "separation", "params": {"margin_m": 50}},
        "vc": {"type": "cacc"},
    },
    "roles": {"ato": "ato", "separation": "sep", "coupled": "vc"},
    "faults": {
        "comm": {
            "t2t": {"delay_s": {"dist": "constant", "value": 0.2}},
            "t2g": {"delay_s": {"dist": "constant", "value": 0.3}},
        }
    },
}


def _service(sid: str, a: str, b: str, t: float, **extra: object) -> dict:
    return {"id": sid, "from": a, "to": b, "vehicle": "cq6", "departures": {"times": [t]}, "dwell_s": 30, **extra}


def _pair(decouple: dict | None = None) -> list[dict]:
    f = {
        "id": "pair",
        "leader": {"service": "lead", "trip": 0},
        "follower": {"service": "follow", "trip": 0},
        "target_gap_m": 30,
        "couple": {"on_departure": True},
    }
    if decouple:
        f["decouple"] = decouple
    return [f]


SCENARIOS = {
    # stations named by id, by name and by stop id
    "ring": (
        [
            _service("lead", "ring-0", "ring-3", 0),
            _service("follow", "s1", "Ring 3", 0),
            _service("ato", "ring-2", "ring-1", 0),
        ],
        _pair(),
    ),
    "passing": (
        [
            _service("lead", "portal", "bravo", 0),
            _service("follow", "alpha_e", "Bravo", 0),
            _service("ato", "bravo_w", "Portal", 100, via=["Mid"]),
        ],
        _pair(),
    ),
    "junction": (
        [_service("lead", "x1", "y1", 30), _service("follow", "X2", "zed", 30), _service("ato", "zed", "x1", 0)],
        _pair({"before_switch": "J/U1"}),
    ),
}


def _scenario(folder: Path, name: str, net: Path, stops: Path) -> Path:
    services, formations = SCENARIOS[name]
    raw = {
        "name": f"ext_{name}",
        "world": {"net": str(net), "additional": [str(stops)]},
        **_COMMON,
        "services": services,
        "formations": formations,
    }
    return _write(folder, f"{name}.yaml", yaml.safe_dump(raw, sort_keys=False))


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_ato_and_coupled_pair_run_end_to_end(name: str, nets: dict, cache: Path, tmp_path: Path) -> None:
    scn = _scenario(tmp_path, name, *nets[name])
    out = tmp_path / "out"
    res = run_railsim(["run", str(scn), "--out", str(out), "--no-progress"], cache_dir=cache, timeout=300)
    assert res.returncode == 0, res.stderr + res.stdout
    s = read_summary(out)
    assert s["collisions"] == 0 and s["sumo_collisions"] == 0
    assert s["switch_violations"] == 0
    assert s["n_arrived"] == s["n_trains"] == 3
    assert s["n_stops_missed"] == 0 and s["n_stops_served"] == s["n_stops_scheduled"] > 0
    assert s["max_stopping_error_m"] <= 0.5  # route chainage agrees with SUMO's odometer
    forms = read_csv(out / "formations.csv")
    assert forms[0]["couple_successes"] == "1" and float(forms[0]["time_coupled_s"]) > 60.0
    assert float(forms[0]["min_gap_m"]) >= 30.0 - 0.1
    stops = read_csv(out / "stops.csv")
    assert stops and all(r["missed"] == "False" for r in stops)
    if name == "junction":  # decoupled before the diverge: each unit took its own leg of J/U1
        grants = [e for e in read_csv(out / "events.csv") if e["kind"] == "lock_granted" and e["subject"] == "J/U1"]
        assert len(grants) == 2 and grants[0]["detail"] != grants[1]["detail"]
    if name == "passing":  # opposing trains crossed at Mid: both stood there at the same time
        mid = {r["service"]: (float(r["arrival_s"]), float(r["departure_s"])) for r in stops if r["station"] == "mid"}
        assert set(mid) == {"lead", "follow", "ato"}
        assert max(mid["lead"][0], mid["ato"][0]) < min(mid["lead"][1], mid["ato"][1])


# ---- CLI and errors -------------------------------------------------------------------------------------------


def test_network_show_prints_stations_switches_and_route_lengths(nets: dict, cache: Path) -> None:
    net, stops = nets["passing"]
    res = run_railsim(["network", "show", str(net), "-a", str(stops)], cache_dir=cache)
    assert res.returncode == 0, res.stderr
    out = res.stdout
    assert "stations (4):" in out and "mid_2 on -L2" in out
    assert "switches (2):" in out and "rail signals: 2 (strip)" in out
    line = next(ln for ln in out.splitlines() if ln.strip().startswith("portal->bravo"))
    from network.external import load_net

    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("RAILSIM_CACHE", str(cache))
        route = load_net(net, [stops]).route_between("portal", "bravo")
    distance_km = (route.stop("bravo").end_m - route.stop("portal").end_m) / 1000  # first stop to last stop
    assert f"{distance_km:8.3f} km" in line and distance_km < route.length_m / 1000


def _error(args: list[str], cache: Path) -> str:
    res = run_railsim(args, cache_dir=cache)
    assert res.returncode == 2, res.stdout + res.stderr
    assert "Traceback" not in res.stderr
    return res.stderr.strip()


def _load_error(net: Path, *adds: Path) -> str:
    from network.external import load_net
    from railsim.errors import ConfigError

    with pytest.raises(ConfigError) as info:
        load_net(net, adds, where=("<command line>", "--"))
    return str(info.value)


def _scenario_error(path: Path) -> str:
    from railsim import scenario
    from railsim.engine import loop as engine
    from railsim.errors import ConfigError

    with pytest.raises(ConfigError) as info:
        engine.Simulation(scenario.load(path), None)  # the world and the trips are checked before SUMO starts
    return str(info.value)


def test_errors_name_the_file_and_field(nets: dict, use_cache: Path, tmp_path: Path) -> None:
    net, stops = nets["passing"]
    road = _netconvert(
        tmp_path,
        "road",
        '<node id="a" x="0" y="0"/><node id="b" x="500" y="0"/>',
        _edge("r", "a", "b", allow="passenger bus"),
    )
    assert _load_error(road).startswith(f"{road}: no rail edges (vClass rail_urban/subway/")
    garbage = _write(tmp_path, "garbage.net.xml", "this is not xml <")
    assert _load_error(garbage).startswith(f"{garbage}: not a SUMO network")
    future = tmp_path / "future.net.xml"
    future.write_text(net.read_text().replace('<net version="', '<net version="99.', 1))
    msg = _load_error(future)
    assert msg.startswith(f"{future}: net.version: network version 99.") and "newer than this SUMO" in msg
    off = _write(
        tmp_path,
        "off.add.xml",
        '<additional><trainStop id="x" lane="AW_0" startPos="10" endPos="50"/>'
        '<trainStop id="bad" lane="nope_0" startPos="1" endPos="9"/></additional>',
    )
    assert _load_error(net, off).startswith(f"{off}: trainStop[id=bad].lane: expected a lane of the network")
    mixed = _netconvert(
        tmp_path,
        "mixed",
        '<node id="a" x="0" y="0"/><node id="b" x="900" y="0"/>',
        _edge("t", "a", "b") + "\n" + _edge("r", "a", "b", allow="passenger", spread="right"),
    )
    road_stop = _write(
        tmp_path, "road.add.xml", '<additional><trainStop id="st" lane="r_0" startPos="10" endPos="300"/></additional>'
    )
    msg = _load_error(mixed, road_stop)
    assert msg.startswith(f"{road_stop}: trainStop[id=st].lane:") and "not on any rail edge" in msg
    # scenario-level: unsupported vClass, a vClass the net does not allow, an unknown station, an unreachable
    # service (the Y1 platform is on the up track only: going back to X1 needs a reversal)
    base = yaml.safe_load(_scenario(tmp_path, "passing", net, stops).read_text())
    for vclass, expect in (("bus", "world.vclass: expected one of"), ("tram", "world.vclass: no lane of")):
        path = _write(
            tmp_path, f"v_{vclass}.yaml", yaml.safe_dump({**base, "world": {**base["world"], "vclass": vclass}})
        )
        assert _scenario_error(path).startswith(f"{path}: {expect}")
    path = _write(
        tmp_path,
        "ghost.yaml",
        yaml.safe_dump({**base, "services": base["services"] + [_service("ghost", "nowhere", "alpha", 0)]}),
    )
    assert _scenario_error(path).startswith(f"{path}: services[3].from: expected a station id")
    jbase = yaml.safe_load(_scenario(tmp_path, "junction", *nets["junction"]).read_text())
    path = _write(
        tmp_path,
        "unreachable.yaml",
        yaml.safe_dump({**jbase, "services": jbase["services"] + [_service("back", "y1", "x1", 0)]}),
    )
    msg = _scenario_error(path)
    assert msg.startswith(f"{path}: services[back]: no route") and "reversal" in msg
    # and the CLI turns them into one line and exit code 2
    assert _error(["network", "show", str(future)], use_cache).startswith(f"railsim: error: {future}: net.version")
    assert _error(["run", str(path), "--out", str(tmp_path / "o")], use_cache).startswith(
        f"railsim: error: {path}: services[back]: no route"
    )


def test_unregulated_node_crossings_come_from_the_geometry(tmp_path: Path) -> None:
    """A node without a foe matrix (``type="unregulated"``: netgenerate's spider centre) used to crash the loader
    (sumolib's ``areFoes`` KeyError). Its crossings now come from the movements' paths through the node: on a
    four-arm double-track cross the straight movement B1→B3 crosses the perpendicular ones (B2→B4, B4→B2), not the
    opposite movement on its own bidi track (B3→B1, single track, protected as such)."""
    import sumo

    from network.external import load_net

    net = tmp_path / "cross.net.xml"
    proc = subprocess.run(
        [str(Path(sumo.SUMO_HOME) / "bin" / "netgenerate"), "--spider", "--spider.arm-number", "4",
         "--spider.circle-number", "1", "--spider.space-radius", "600", "--bidi-probability", "1",
         "--default.allow", "rail", "--default.junctions.type", "rail_signal", "--no-turnarounds", "true",
         "-o", str(net)],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert 'type="unregulated"' in net.read_text(encoding="utf-8")
    crossings = load_net(net).graph.graph["crossings"]["A1"]
    assert set(crossings[("B1A1", "A1B3")]) == {("B2A1", "A1B4"), ("B4A1", "A1B2")}
    assert ("B3A1", "A1B1") not in crossings[("B1A1", "A1B3")]
