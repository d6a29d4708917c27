"""Shipped worlds and the builder: stations, chainage, junctions, routes, cache, topology output."""

from __future__ import annotations

import json
import os
import subprocess
import tempfile
from pathlib import Path

import networkx as nx
import pytest
import yaml
from hypothesis import HealthCheck, given, settings, strategies as st

import network
from network.topology import make_route
from network.worlds import WORLD_DIR

REPO = Path(__file__).resolve().parents[2]
DATASET_MAIN_KM = 53.98  # Yudong -> Jiangbei Airport T2, sum of official sections (dataset S2)


@pytest.fixture(scope="module", autouse=True)
def _cache(tmp_path_factory: pytest.TempPathFactory):
    old = os.environ.get("RAILSIM_CACHE")
    os.environ["RAILSIM_CACHE"] = str(tmp_path_factory.mktemp("railsim-cache"))
    yield
    if old is None:
        del os.environ["RAILSIM_CACHE"]
    else:
        os.environ["RAILSIM_CACHE"] = old


@pytest.fixture(scope="module")
def cq() -> network.NetworkBundle:
    return network.build("chongqing_line3")


def _centre(stop: network.RouteStop) -> float:
    return 0.5 * (stop.start_m + stop.end_m)


def _package_yaml() -> dict:
    return yaml.safe_load((WORLD_DIR / "chongqing_line3.yaml").read_text(encoding="utf-8"))


# ------------------------------------------------------------------------------------------- Chongqing
def test_line3_has_45_stations_with_a_stop_per_direction(cq: network.NetworkBundle) -> None:
    assert len(cq.stations) == 45
    stop_ids = set()
    for station in cq.stations.values():
        assert sorted(p.direction for p in station.platforms) == ["down", "up"]
        for p in station.platforms:
            assert p.end_pos_m - p.start_pos_m == pytest.approx(220.0)
            stop_ids.add(p.stop_id)
    assert len(stop_ids) == 90
    # the stops file holds exactly those trainStops, each on the lane of its edge, and one per depot lead edge
    text = cq.stops_file.read_text(encoding="utf-8")
    assert text.count("<trainStop ") == 90 + 2 * len(cq.graph.graph["depots"])


def test_line3_main_stations_match_dataset_chainage_in_both_directions(cq: network.NetworkBundle) -> None:
    data = _package_yaml()
    km = {s["id"]: s["km"] for s in data["stations"]}
    assert len(km) == 39
    up = cq.routes["yudong->jiangbei-airport-t2"]
    origin = _centre(up.stop("yudong"))
    assert [s.station_id for s in up.stops] == list(km)
    for s in up.stops:
        assert _centre(s) - origin == pytest.approx(km[s.station_id] * 1000.0, abs=1.0), s.station_id
    down = cq.routes["jiangbei-airport-t2->yudong"]
    end = _centre(down.stop("jiangbei-airport-t2"))
    for s in down.stops:
        assert _centre(s) - end == pytest.approx((km["jiangbei-airport-t2"] - km[s.station_id]) * 1000.0, abs=1.0)
    distance_km = (_centre(up.stop("jiangbei-airport-t2")) - origin) / 1000.0
    assert abs(distance_km - DATASET_MAIN_KM) / DATASET_MAIN_KM < 0.01


def test_line3_branch_stations_at_bijin_plus_km_from_bijin(cq: network.NetworkBundle) -> None:
    km_from_bijin = {
        "shuangfengqiao": 2.037,
        "konggang-square": 2.969,
        "gaobaohu": 4.985,
        "guanyue-road": 6.647,
        "lianhua": 8.308,
        "jurenba": 9.970,
    }  # dataset branch_konggang
    bijin_km = 52.668
    for rid in ("yudong->jurenba", "jurenba->yudong"):
        route = cq.routes[rid]
        bijin = _centre(route.stop("bijin"))
        sign = 1 if rid.startswith("yudong") else -1
        for sid, d_km in km_from_bijin.items():
            assert sign * (_centre(route.stop(sid)) - bijin) == pytest.approx(d_km * 1000.0, abs=1.0)
        yudong = _centre(route.stop("yudong"))
        assert sign * (_centre(route.stop("jurenba")) - yudong) == pytest.approx((bijin_km + 9.970) * 1000.0, abs=1.0)
    assert {s.station_id for s in cq.routes["yudong->jurenba"].stops} >= set(km_from_bijin)
    assert "jiangbei-airport-t2" not in {s.station_id for s in cq.routes["yudong->jurenba"].stops}


def _bijin(switches: tuple) -> list:
    """The Bijin switch of a route (the pocket switches at Jiugongli and Liugongli lie on every route too)."""
    return [s for s in switches if s.switch_id.startswith("bijin")]


def test_line3_turns_units_beyond_its_termini_and_in_two_pockets(cq: network.NetworkBundle) -> None:
    rev = cq.graph.graph["reversals"]
    assert set(rev) == {"main_tb_lo", "main_tb_hi", "konggang_tb_hi", "jiugongli_pk", "liugongli_pk"}
    for track, (partner, via) in rev.items():
        assert cq.graph.nodes[track]["bidi"] == partner and cq.graph.nodes[partner]["bidi"] == track
        assert cq.graph.nodes[track]["length_m"] == pytest.approx(180.0 - 0.1)  # TURNBACK_TRACK_M minus a lane
        assert len(via) == 1  # the turnaround's one internal lane
    # a pocket is entered from the arriving track and left onto the departing one through locked points
    sw_in, sw_out = cq.switches["jiugongli_pk_in"], cq.switches["jiugongli_pk_out"]
    assert (sw_in.kind, sw_in.reverse_edge, sw_out.kind, sw_out.reverse_edge) == (
        "diverge",
        "jiugongli_pk",
        "merge",
        "-jiugongli_pk",
    )
    assert sw_in.trunk_edge == cq.stations["jiugongli"].platform("down").edge
    assert sw_out.trunk_edge == cq.stations["jiugongli"].platform("up").edge


def test_bijin_is_a_junction_whose_legs_lead_to_t2_and_jurenba(cq: network.NetworkBundle) -> None:
    g = cq.graph
    up, down = cq.switches["bijin_up"], cq.switches["bijin_down"]
    assert (up.kind, down.kind) == ("diverge", "merge")
    assert up.throw_time_s == 15.0 and up.diverging_speed_mps == pytest.approx(30 / 3.6)
    # the up switch lies after Bijin's up platform: the platform edge leads to the trunk edge
    bijin_up_edge = cq.stations["bijin"].platform("up").edge
    assert bijin_up_edge == up.trunk_edge or up.trunk_edge in nx.descendants(g, bijin_up_edge)
    reach_normal = nx.descendants(g, up.normal_edge) | {up.normal_edge}
    reach_reverse = nx.descendants(g, up.reverse_edge) | {up.reverse_edge}
    assert cq.stations["jiangbei-airport-t2"].platform("up").edge in reach_normal
    assert cq.stations["jurenba"].platform("up").edge in reach_reverse
    assert cq.stations["jurenba"].platform("up").edge not in reach_normal
    # down: both legs come from the termini and merge before Bijin's down platform
    assert cq.stations["bijin"].platform("down").edge in nx.descendants(g, down.trunk_edge) | {down.trunk_edge}
    assert down.normal_edge in nx.descendants(g, cq.stations["jiangbei-airport-t2"].platform("down").edge)
    assert down.reverse_edge in nx.descendants(g, cq.stations["jurenba"].platform("down").edge)
    # routes record the switch and leg, with the diverging speed on the reverse leg
    (sw,) = _bijin(cq.routes["yudong->jurenba"].switches)
    assert (sw.switch_id, sw.leg) == ("bijin_up", "reverse")
    r = cq.routes["yudong->jurenba"]
    assert r.speed_at(sw.point_m + 10.0) == pytest.approx(30 / 3.6)
    assert sw.point_m > r.stop("bijin").end_m
    (sw_t2,) = _bijin(cq.routes["yudong->jiangbei-airport-t2"].switches)
    assert (sw_t2.switch_id, sw_t2.leg) == ("bijin_up", "normal")
    (sw_dn,) = _bijin(cq.routes["jurenba->yudong"].switches)
    assert sw_dn.switch_id == "bijin_down" and sw_dn.point_m < cq.routes["jurenba->yudong"].stop("bijin").start_m


def test_line3_turnbacks_and_level_profile(cq: network.NetworkBundle) -> None:
    turnbacks = {s.id for s in cq.stations.values() if s.turnback}
    assert {"yudong", "jiugongli", "sigongli", "longtousi", "bijin", "jiangbei-airport-t2", "jurenba"} <= turnbacks
    assert cq.stations["bijin"].crossover_speed_mps == pytest.approx(30 / 3.6)
    for r in cq.routes.values():
        assert r.gradients == ((0.0, r.length_m, 0.0),)
        assert max(v for _, _, v in r.speed_limits) == pytest.approx(70 / 3.6)


# ------------------------------------------------------------------------------------------- y_junction
def test_y_junction_names_its_entries_and_switches() -> None:
    y = network.build("y_junction")
    assert set(y.switches) == {"sw1", "sw2", "sw1_down", "sw2_down"}
    assert (y.switches["sw1"].kind, y.switches["sw2"].kind) == ("merge", "merge")
    assert set(y.routes) == {f"entry{i}->platform" for i in (1, 2, 3)} | {f"platform->entry{i}" for i in (1, 2, 3)}
    first_edges = {y.routes[f"entry{i}->platform"].edges[0] for i in (1, 2, 3)}
    assert len(first_edges) == 3  # three distinct entry tracks
    # spec 004 Table 3 scenario 1 distances along each route: start of the approach is 2 km upstream
    s1, s2, s3, s4, s5 = 400.0, 200.0, 160.0, 200.0, 200.0
    expect = {
        "entry1": (("sw2", s1, "reverse"),),
        "entry2": (("sw1", s2, "normal"), ("sw2", s2 + s4, "normal")),
        "entry3": (("sw1", s3, "reverse"), ("sw2", s3 + s4, "normal")),
    }
    for entry, sws in expect.items():
        r = y.routes[f"{entry}->platform"]
        assert [(s.switch_id, s.leg) for s in r.switches] == [(a, leg) for a, _, leg in sws]
        for s, (_, dist, _) in zip(r.switches, sws):
            assert s.point_m == pytest.approx(2000.0 + dist, abs=0.5)
        (f,) = r.points
        assert f.point_id == "F" and f.point_m - r.switches[-1].point_m == pytest.approx(s5, abs=0.5)
        # an origin station at the far end of each entry track, the platform beyond F
        assert r.stops[0].station_id == entry and r.stops[0].end_m < 2000.0
        assert r.stops[-1].station_id == "platform" and r.stops[-1].start_m > f.point_m
    # legs swap with the parameter
    swapped = network.build("y_junction", sw1_branch_leg="normal", S3=300)
    r = swapped.routes["entry3->platform"]
    assert r.switches[0].leg == "normal" and r.switches[0].point_m == pytest.approx(2300.0, abs=0.5)
    assert swapped.cache_key != y.cache_key


# ------------------------------------------------------------------------------------------- routes & API
def test_route_between_services(cq: network.NetworkBundle) -> None:
    r = cq.route_between("sigongli", "jurenba")
    assert r.edges[0] == cq.stations["sigongli"].platform("up").edge
    assert r.edges[-1] == cq.stations["jurenba"].platform("up").edge
    assert r.stops[0].station_id == "sigongli" and r.stops[-1].station_id == "jurenba"
    d = cq.route_between("jurenba", "liugongli")
    assert d.edges[0] == cq.stations["jurenba"].platform("down").edge and d.stops[-1].station_id == "liugongli"
    # chainage along a service route agrees with the through route (shifted by the origin)
    full = cq.routes["yudong->jurenba"]
    shift = full.chainage(r.edges[0], 0.0)
    for s in r.stops:
        assert s.end_m + shift == pytest.approx(full.stop(s.station_id).end_m, abs=1e-6)
    with pytest.raises(KeyError, match="unknown station 'atlantis'"):
        cq.route_between("yudong", "atlantis")
    with pytest.raises(ValueError, match="no route from 'jiangbei-airport-t2' to 'jurenba'"):
        cq.route_between("jiangbei-airport-t2", "jurenba")
    with pytest.raises(ValueError):
        cq.route_between("yudong", "yudong")
    with pytest.raises(KeyError, match="is not on route"):
        r.chainage("main_up_0", 1.0)


@pytest.mark.parametrize("world", network.shipped_worlds())
def test_route_tables_cover_the_route(world: str) -> None:
    b = network.build(world)
    for r in b.routes.values():
        assert len(r.edges) == len(r.edge_start_m) and r.edge_start_m[0] == 0.0
        assert all(a < z for a, z in zip(r.edge_start_m, r.edge_start_m[1:]))
        for table in (r.speed_limits, r.gradients):
            assert table[0][0] == 0.0 and table[-1][1] == pytest.approx(r.length_m)
            assert all(abs(a[1] - z[0]) < 1e-6 for a, z in zip(table, table[1:]))
        assert all(v > 0 for _, _, v in r.speed_limits)
        for s in r.stops:  # every platform lies wholly on its edge
            length = b.graph.nodes[s.edge]["length_m"]
            assert 0.0 <= s.start_pos_m < s.end_pos_m <= length
            assert s.start_m == pytest.approx(r.chainage(s.edge, s.start_pos_m))


def test_gradients_and_speed_limits_by_chainage(tmp_path: Path) -> None:
    desc = {
        "name": "hilly",
        "line_speed_kmh": 90,
        "platform_length_m": 100,
        "overrun_m": 100,
        "stations": [{"id": "a", "km": 0.0}, {"id": "b", "km": 3.0}],
        "gradients": [
            {"from_km": 1.0, "to_km": 1.5, "permille": 20.0},
            {"from_km": 1.5, "to_km": 2.0, "permille": -5.0},
        ],
        "speed_limits": [{"from_km": 0.5, "to_km": 0.8, "speed_kmh": 36, "direction": "up"}],
    }
    path = tmp_path / "hilly.yaml"
    path.write_text(yaml.safe_dump(desc))
    b = network.build(path)
    up, down = b.routes["a->b"], b.routes["b->a"]
    o = _centre(up.stop("a"))  # route chainage of km 0 on the up route
    assert up.gradients[1] == pytest.approx((o + 1000.0, o + 1500.0, 20.0), abs=1e-6)
    assert up.gradients[2] == pytest.approx((o + 1500.0, o + 2000.0, -5.0), abs=1e-6)
    e = _centre(down.stop("b"))  # route chainage of km 3 on the down route
    assert down.gradients[1] == pytest.approx((e + 1000.0, e + 1500.0, 5.0), abs=1e-6)
    assert down.gradients[2] == pytest.approx((e + 1500.0, e + 2000.0, -20.0), abs=1e-6)
    assert up.speed_at(o + 650.0) == pytest.approx(10.0)
    assert up.speed_at(o + 450.0) == pytest.approx(25.0)
    assert all(v == pytest.approx(25.0) for _, _, v in down.speed_limits)  # the limit is up-only


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    gaps_m=st.lists(st.floats(300.0, 5000.0), min_size=1, max_size=6),
    platforms_m=st.lists(st.floats(40.0, 280.0), min_size=7, max_size=7),
)
def test_any_valid_line_puts_stops_at_design_chainage(gaps_m: list[float], platforms_m: list[float]) -> None:
    kms, km = [], 0.0
    for g in [0.0] + gaps_m:
        km += g / 1000.0
        kms.append(km)
    stations = [
        {"id": f"s{i}", "km": round(k, 4), "platform_length_m": round(p, 2)}
        for i, (k, p) in enumerate(zip(kms, platforms_m))
    ]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "prop.yaml"
        path.write_text(yaml.safe_dump({"name": "prop", "line_speed_kmh": 80, "stations": stations}))
        b = network.build(path)
    up = b.routes[f"s0->s{len(stations) - 1}"]
    o = _centre(up.stop("s0"))
    for s, spec in zip(up.stops, stations):
        assert _centre(s) - o == pytest.approx(spec["km"] * 1000.0, abs=1e-3)
        assert s.end_m - s.start_m == pytest.approx(spec["platform_length_m"], abs=1e-3)
    # the graph recomputes the same route
    assert make_route(b.graph, up.id, up.edges) == up


# ------------------------------------------------------------------------------------------- cache & CLI
def test_cache_hit_returns_identical_bundle_without_netconvert(tmp_path: Path) -> None:
    os.environ["RAILSIM_CACHE"] = str(tmp_path / "fresh")
    first = network.build("chongqing_line3")
    assert first.net_file.parent.parent == tmp_path / "fresh" / "networks"
    mtime = first.net_file.stat().st_mtime_ns
    second = network.build("chongqing_line3")
    assert second.net_file == first.net_file and second.net_file.stat().st_mtime_ns == mtime
    assert second.routes == first.routes and second.stations == first.stations
    assert second.switches == first.switches
    other = network.build("straight_corridor", length_km=20.0, stations=4)
    assert other.cache_key != network.build("straight_corridor").cache_key
    assert len(other.stations) == 4
    assert other.routes["s1->s4"].stop("s4").start_m - other.routes["s1->s4"].stop("s1").start_m == pytest.approx(
        20000.0, abs=1e-6
    )


def test_cli_build_writes_files_and_show_prints_summary(tmp_path: Path) -> None:
    env = dict(os.environ, RAILSIM_CACHE=str(tmp_path / "cache"))
    railsim = str(REPO / ".venv" / "bin" / "railsim")
    out = tmp_path / "out"
    proc = subprocess.run(
        [railsim, "network", "build", "chongqing_line3", "--out", str(out)],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    for suffix in (".net.xml", ".stops.add.xml", ".topology.json"):
        assert (out / f"chongqing_line3{suffix}").is_file()
    topo = json.loads((out / "chongqing_line3.topology.json").read_text(encoding="utf-8"))
    pockets = {f"{s}_pk_{d}" for s in ("jiugongli", "liugongli") for d in ("in", "out")}
    depots = {f"{d}_{t}" for d in ("daojiao", "tongjiayuanzi-depot", "huancheng-north-road") for t in ("up", "down")}
    assert len(topo["stations"]) == 45 and set(topo["switches"]) == {"bijin_up", "bijin_down"} | pockets | depots
    assert topo["stations"]["bijin"]["km"] == 52.668
    legs = {s["switch_id"]: s["leg"] for s in topo["routes"]["yudong->jurenba"]["switches"]}
    assert legs["bijin_up"] == "reverse" and legs["jiugongli_pk_out"] == legs["liugongli_pk_out"] == "normal"
    assert legs["daojiao_up"] == legs["tongjiayuanzi-depot_up"] == legs["huancheng-north-road_up"] == "normal"
    proc = subprocess.run(
        [railsim, "network", "show", "y_junction"], capture_output=True, text=True, env=env, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    for word in ("sw1", "sw2", "entry1->platform", "entry3->platform", "platform->entry2"):
        assert word in proc.stdout


def test_single_track_builds_bidi_edges_with_exact_chainage(tmp_path: Path) -> None:
    desc = {
        "name": "single",
        "track": "single",
        "line_speed_kmh": 60,
        "platform_length_m": 120,
        "stations": [{"id": "a", "km": 0.0}, {"id": "b", "km": 1.234}, {"id": "c", "km": 2.5}],
    }
    path = tmp_path / "single.yaml"
    path.write_text(yaml.safe_dump(desc))
    b = network.build(path)
    assert 'bidi="' in b.net_file.read_text(encoding="utf-8")  # SUMO paired the two directions
    up, down = b.routes["a->c"], b.routes["c->a"]
    assert _centre(up.stop("b")) - _centre(up.stop("a")) == pytest.approx(1234.0, abs=1e-3)
    assert _centre(down.stop("b")) - _centre(down.stop("c")) == pytest.approx(2500.0 - 1234.0, abs=1e-3)
    assert up.length_m == pytest.approx(down.length_m)


def test_line3_depot_leads_join_both_tracks_between_their_stations(cq: network.NetworkBundle) -> None:
    """The data pack's three depots (locations sourced, connections estimated): each lead is a bidi pair whose
    track out of the depot feeds both running tracks and whose track in is fed by both, at the km of the middle
    of the gap between its two stations, through that depot's two switches on their reverse leg."""
    g = cq.graph
    between = {
        "daojiao": ("yuhulu", "xuetangwan"),
        "tongjiayuanzi-depot": ("longtousi", "tongjiayuanzi"),
        "huancheng-north-road": ("gaobaohu", "guanyue-road"),
    }
    assert set(g.graph["depots"]) == set(between)
    for did, (a, b) in between.items():
        d = g.graph["depots"][did]
        assert cq.stations[a].km < d["km"] < cq.stations[b].km and d["line"] == cq.stations[a].line
        start, end = d["start_edge"], d["end_edge"]
        assert g.nodes[start]["bidi"] == end and g.nodes[end]["bidi"] == start
        assert g.nodes[start]["station"] == g.nodes[end]["station"] == did
        onto = {g.nodes[e]["direction"]: g.edges[start, e] for e in g.successors(start)}
        into = {g.nodes[e]["direction"]: g.edges[e, end] for e in g.predecessors(end)}
        for direction in ("up", "down"):
            assert (onto[direction]["switch"], onto[direction]["leg"]) == (f"{did}_{direction}", "reverse")
            assert (into[direction]["switch"], into[direction]["leg"]) == (f"{did}_{direction}", "reverse")
        assert "estimated" in d["basis"] and "sourced" in d["basis"]
    # no through route enters a depot lead
    assert not any(
        e in (v["start_edge"], v["end_edge"])
        for r in cq.routes.values()
        for e in r.edges
        for v in g.graph["depots"].values()
    )
