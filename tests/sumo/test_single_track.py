"""Single track is one direction at a time: opposing trains on nets built here with netconvert.

* **no passing loop** — one bidi line A–B with a station at each end: both trains are due at the same time; the
  second is held at its platform (``departure_held`` naming the section) until the first has left the section,
  then runs; both arrive, 0 collisions (ours and SUMO's).
* **passing loop** — the two trains enter the single track from opposite ends at the same moment; they cross at
  the loop: each single-track section is reserved in one direction at a time, and a train waiting for a section
  stops before the loop's switch, not on it.

Section sets are checked without SUMO too (:mod:`railsim.engine.single_track`).
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from tests.helpers import read_csv, read_summary, run_railsim
from tests.sumo.test_external_net import _COMMON, _edge, _netconvert, _service, _stops, _write, build_passing_loop


def build_single_line(folder: Path) -> tuple[Path, Path]:
    """A 4 km single-track line (bidi edges, two pieces joined at a plain node) with stations at both ends."""
    nodes = '<node id="A" x="0" y="0"/>\n<node id="M" x="2000" y="0"/>\n<node id="B" x="4000" y="0"/>'
    edges = [_edge("AM", "A", "M"), _edge("-AM", "M", "A"), _edge("MB", "M", "B"), _edge("-MB", "B", "M")]
    net = _netconvert(folder, "single", nodes, "\n".join(edges))
    stops = _stops(
        folder,
        "single",
        [
            ("a_out", "AM_0", 100, 400, "Aston"),
            ("b_in", "MB_0", 1600, 1900, "Bury"),
            ("b_out", "-MB_0", 100, 400, "Bury"),
            ("a_in", "-AM_0", 1600, 1900, "Aston"),
        ],
    )
    return net, stops


def _scenario(folder: Path, name: str, net: Path, stops: Path, services: list[dict], extra: dict | None = None) -> Path:
    raw = {"name": name, "world": {"net": str(net), "additional": [str(stops)]}, **_COMMON, "services": services}
    return _write(folder, f"{name}.yaml", yaml.safe_dump({**raw, **(extra or {})}, sort_keys=False))


def _run(
    folder: Path,
    name: str,
    net: Path,
    stops: Path,
    services: list[dict],
    exit_code: int = 0,
    extra: dict | None = None,
) -> tuple[Path, dict, str]:
    """``railsim run`` the services in a child process; assert the exit code; (output folder, summary, stderr)."""
    out = folder / "out"
    scn = _scenario(folder, name, net, stops, services, extra)
    res = run_railsim(["run", str(scn), "--out", str(out), "--no-progress"], timeout=300)
    assert res.returncode == exit_code, res.stderr + res.stdout
    return out, read_summary(out), res.stderr


def test_sections_of_a_line_and_a_loop(tmp_path: Path) -> None:
    from network.external import load_net
    from railsim.engine.single_track import contested, route_sections, section_map

    line = load_net(*build_single_line(tmp_path)[:1], [build_single_line(tmp_path)[1]])
    smap = section_map(line.graph)
    assert {smap[e][0] for e in ("AM", "-AM", "MB", "-MB")} == {"track:-AM"}  # one section: M is a plain node
    assert smap["AM"][1] == smap["MB"][1] != smap["-AM"][1]
    east, west = line.route_between("aston", "bury"), line.route_between("bury", "aston")
    (e,) = route_sections(east, smap)
    (w,) = route_sections(west, smap)
    assert (e.start_m, e.end_m) == (0.0, pytest.approx(east.length_m)) and e.direction != w.direction
    assert contested({"e": [e], "w": [w]}) == {"track:-AM"} and contested({"e": [e], "e2": [e]}) == set()
    loop = load_net(*build_passing_loop(tmp_path)[:1], [build_passing_loop(tmp_path)[1]])
    lmap = section_map(loop.graph)
    assert len({lmap[x][0] for x in lmap}) == 4  # portal track, two loop tracks, bravo track: switches end them
    r = loop.route_between("portal", "bravo")
    secs = route_sections(r, lmap)
    assert [s.section_id for s in secs] == ["track:-AW", "track:-L1", "track:-EB"]
    w_point = next(s.point_m for s in r.switches if s.switch_id == "W")
    assert secs[1].guard_m == w_point < secs[1].start_m  # the loop track is protected at the switch in front


def test_no_passing_loop_second_train_waits_at_the_entry(tmp_path: Path) -> None:
    net, stops = build_single_line(tmp_path)
    services = [_service("east", "aston", "bury", 0), _service("west", "bury", "aston", 0)]
    out, s, stderr = _run(tmp_path, "single_line", net, stops, services)
    assert s["n_arrived"] == s["n_trains"] == 2 and s["collisions"] == 0 and s["sumo_collisions"] == 0
    events = read_csv(out / "events.csv")
    held = [e for e in events if e["kind"] == "departure_held"]
    assert len(held) == 1 and held[0]["subject"] == "west.000" and "track:-AM" in held[0]["detail"]
    trips = {r["service"]: r for r in read_csv(out / "trips.csv")}
    released = [float(e["t_s"]) for e in events if e["kind"] == "section_released"]
    # the west train left only after the east train had released the whole section
    assert float(trips["west"]["departure_s"]) >= released[0] > float(trips["east"]["departure_s"])


def test_opposing_trains_cross_at_the_passing_loop(tmp_path: Path) -> None:
    net, stops = build_passing_loop(tmp_path)
    services = [_service("east", "portal", "bravo", 0), _service("west", "bravo_w", "Portal", 0, via=["Mid"])]
    out, s, stderr = _run(tmp_path, "loop", net, stops, services)
    assert s["n_arrived"] == s["n_trains"] == 2 and s["collisions"] == 0 and s["sumo_collisions"] == 0
    assert s["switch_violations"] == 0
    events = read_csv(out / "events.csv")
    reserved = [(e["subject"], e["detail"]) for e in events if e["kind"] == "section_reserved"]
    assert any("east.000" in d for sid, d in reserved if sid == "track:-EB")
    assert any("west.000" in d for sid, d in reserved if sid == "track:-AW")
    # never both directions at once: replay the reservations and releases of every section
    holders: dict[str, set[str]] = {}
    for e in events:
        if e["kind"] in ("section_reserved", "section_released"):
            train = yaml.safe_load(e["detail"])["trains"][0]
            bucket = holders.setdefault(e["subject"], set())
            if e["kind"] == "section_reserved":
                assert not bucket, f"{e['subject']} reserved for {train} while {bucket} held it"
                bucket.add(train)
            else:
                bucket.discard(train)


def build_diamond(folder: Path) -> tuple[Path, Path]:
    """Two lines crossing flat at node X (no connection between them: a diamond crossing, not a junction)."""
    nodes = (
        '<node id="W" x="0" y="0"/>\n<node id="X" x="2000" y="0"/>\n<node id="E" x="4000" y="0"/>\n'
        '<node id="S" x="2000" y="-2000"/>\n<node id="N" x="2000" y="2000"/>'
    )
    edges = [_edge("WX", "W", "X"), _edge("XE", "X", "E"), _edge("SX", "S", "X"), _edge("XN", "X", "N")]
    only = '<connection from="WX" to="XE"/>\n<connection from="SX" to="XN"/>'
    net = _netconvert(folder, "diamond", nodes, "\n".join(edges), connections=only)
    stops = _stops(
        folder,
        "diamond",
        [
            ("w", "WX_0", 100, 400, "West"),
            ("e", "XE_0", 1600, 1900, "East"),
            ("s", "SX_0", 100, 400, "South"),
            ("n", "XN_0", 1600, 1900, "North"),
        ],
    )
    return net, stops


def test_routes_crossing_inside_one_node_take_turns(tmp_path: Path) -> None:
    from network.external import load_net

    net, stops = build_diamond(tmp_path)
    bundle = load_net(net, [stops])
    assert bundle.switches == {}  # no connection between the lines: only the crossing protects them
    assert set(bundle.graph.graph["crossings"]["X"]) == {("WX", "XE"), ("SX", "XN")}
    services = [_service("we", "west", "east", 0), _service("sn", "south", "north", 0)]
    out, s, stderr = _run(tmp_path, "diamond", net, stops, services)
    assert s["n_arrived"] == s["n_trains"] == 2 and s["collisions"] == 0 and s["sumo_collisions"] == 0
    events = read_csv(out / "events.csv")
    reserved = [yaml.safe_load(e["detail"])["trains"][0] for e in events if e["kind"] == "section_reserved"]
    assert sorted(reserved) == ["sn.000", "we.000"]  # each took the crossing once, one after the other
    kinds = [(e["kind"], e["subject"]) for e in events if e["subject"] == "crossing:X"]
    first_release = kinds.index(("section_released", "crossing:X"))
    assert [k for k, _ in kinds[:first_release]].count("section_reserved") == 1


def build_merge(folder: Path) -> tuple[Path, Path]:
    """Two lines merging at switch J onto one track (a Y): the flank case."""
    nodes = (
        '<node id="A" x="0" y="0"/>\n<node id="B" x="0" y="600"/>\n<node id="J" x="2000" y="0"/>\n'
        '<node id="Z" x="5000" y="0"/>'
    )
    branch = "0,600 1200,600 2000,0"
    edges = [_edge("AJ", "A", "J"), _edge("BJ", "B", "J", 16.0, shape=branch), _edge("JZ", "J", "Z")]
    net = _netconvert(folder, "merge", nodes, "\n".join(edges))
    stops = _stops(
        folder,
        "merge",
        [("a", "AJ_0", 100, 400, "Ash"), ("b", "BJ_0", 100, 400, "Birch"), ("z", "JZ_0", 2600, 2900, "Zed")],
    )
    return net, stops


@pytest.mark.parametrize("overlap_m", [None, 80.0])
def test_flank_a_train_on_the_other_leg_stops_before_the_fouling_point(tmp_path: Path, overlap_m: float | None) -> None:
    """Both trains reach the merge at about the same time: the one without the lock stands at least the overlap
    (``interlocking.overlap_m``, default 20 m) before the switch point (it never fouls the route set for the
    other), then follows; 0 collisions."""
    net, stops = build_merge(tmp_path)
    services = [_service("main", "ash", "zed", 0), _service("branch", "birch", "zed", 0)]
    extra = None if overlap_m is None else {"interlocking": {"overlap_m": overlap_m}}
    out, s, stderr = _run(tmp_path, "merge", net, stops, services, extra=extra)
    assert s["n_arrived"] == s["n_trains"] == 2 and s["collisions"] == 0 and s["sumo_collisions"] == 0
    assert s["switch_violations"] == 0
    events = read_csv(out / "events.csv")
    grants = [e for e in events if e["kind"] == "lock_granted"]
    assert len(grants) == 2
    second = yaml.safe_load(grants[1]["detail"])["holders"][0]
    assert yaml.safe_load(grants[1]["detail"])["waited_s"] > 10.0  # it really had to wait for the other
    t_grant = float(grants[1]["t_s"])
    from network.external import load_net

    bundle = load_net(net, [stops])
    origin = "ash" if second.startswith("main") else "birch"
    route = bundle.route_between(origin, "zed")
    (sw,) = route.switches
    trace = [r for r in read_csv(out / "trace.csv") if r["train"] == second and float(r["t_s"]) <= t_grant]
    front_before_grant = max(float(r["chainage_m"]) for r in trace)
    overlap = 20.0 if overlap_m is None else overlap_m  # EngineSettings.protection_margin_m by default
    assert front_before_grant <= sw.point_m - overlap + 0.5


@pytest.mark.parametrize("overlap_m", [None, 80.0])
def test_a_train_waiting_for_the_points_stands_the_overlap_before_them(tmp_path: Path, overlap_m: float | None) -> None:
    """A slow train (15 km/h) holds the merge for minutes; the branch train comes up and stands where its authority
    ends: before a merge, ``max(overlap_m, separation margin)`` before the switch point (default overlap 20 m, the
    scenarios' separation margin 50 m: locking.py's "Merges"), minus the ATO's 5 m authority margin."""
    net, stops = build_merge(tmp_path)
    services = [
        {**_service("main", "ash", "zed", 0), "vehicle": "slow"},
        _service("branch", "birch", "zed", 120),
    ]
    extra: dict = {"vehicles": {"cq6": {"preset": "cq3_6car"}, "slow": {"preset": "cq3_6car", "max_speed_kmh": 15}}}
    if overlap_m is not None:
        extra["interlocking"] = {"overlap_m": overlap_m}
    out, s, stderr = _run(tmp_path, "slowmerge", net, stops, services, extra=extra)
    assert s["n_arrived"] == 2 and s["collisions"] == 0 and s["sumo_collisions"] == 0 and s["switch_violations"] == 0
    from network.external import load_net

    (sw,) = load_net(net, [stops]).route_between("birch", "zed").switches
    standing = [
        float(r["chainage_m"])
        for r in read_csv(out / "trace.csv")
        if r["train"] == "branch.000" and float(r["speed_mps"]) == 0.0 and 1000.0 < float(r["chainage_m"]) < sw.point_m
    ]
    assert len(standing) > 30  # it stood for more than half a minute
    margin = max(20.0 if overlap_m is None else overlap_m, 50.0)
    assert sw.point_m - margin - 5.5 <= min(standing) <= max(standing) <= sw.point_m - margin - 4.5


def test_a_bad_overlap_is_refused_naming_the_field(tmp_path: Path) -> None:
    net, stops = build_merge(tmp_path)
    services = [_service("main", "ash", "zed", 0)]
    scn = _scenario(tmp_path, "bad", net, stops, services, {"interlocking": {"overlap_m": -5}})
    res = run_railsim(["validate", str(scn)], timeout=120)
    assert res.returncode == 2 and "Traceback" not in res.stderr
    (line,) = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert "bad.yaml" in line and "interlocking.overlap_m" in line


def build_no_passing_place(folder: Path) -> tuple[Path, Path]:
    """Single track A–M–B where M is a switch to a spur (so A–M and M–B are two sections) but no passing loop."""
    nodes = (
        '<node id="A" x="0" y="0"/>\n<node id="M" x="2500" y="0"/>\n<node id="B" x="5000" y="0"/>\n'
        '<node id="C" x="4000" y="800"/>'
    )
    edges = [
        _edge("AM", "A", "M"),
        _edge("-AM", "M", "A"),
        _edge("MB", "M", "B"),
        _edge("-MB", "B", "M"),
        _edge("MC", "M", "C", 16.0, shape="2500,0 3000,200 4000,800"),
        _edge("-MC", "C", "M", 16.0, shape="4000,800 3000,200 2500,0"),
    ]
    net = _netconvert(folder, "spur", nodes, "\n".join(edges))
    stops = _stops(
        folder,
        "spur",
        [
            ("a_out", "AM_0", 100, 400, "Aston"),
            ("a_in", "-AM_0", 2000, 2300, "Aston"),
            ("b_in", "MB_0", 2100, 2400, "Bury"),
            ("b_out", "-MB_0", 100, 400, "Bury"),
        ],
    )
    return net, stops


def test_two_sections_without_a_passing_place_are_reserved_together(tmp_path: Path) -> None:
    """Both trains start at once towards opposite sections with no place to pass between them (a spur's points
    split the line): each used to be granted its own first section and wait for the other's — a deadlock. Now a
    train reserves both sections in one instant or neither: the first to ask runs through, the other waits at
    its platform, both arrive."""
    net, stops = build_no_passing_place(tmp_path)
    services = [_service("east", "a_out", "b_in", 0), _service("west", "b_out", "a_in", 0)]
    out, s, stderr = _run(tmp_path, "spur", net, stops, services)
    assert s["n_arrived"] == s["n_trains"] == 2 and s["collisions"] == 0 and s["sumo_collisions"] == 0
    events = read_csv(out / "events.csv")
    assert not [e for e in events if e["kind"] == "deadlock"]
    reserved: dict[str, dict[str, float]] = {}
    for e in events:
        if e["kind"] == "section_reserved":
            for train in yaml.safe_load(e["detail"])["trains"]:
                reserved.setdefault(train, {}).setdefault(e["subject"], float(e["t_s"]))
    for train in ("east.000", "west.000"):
        assert sorted(reserved[train]) == ["track:-AM", "track:-MB"]
        assert reserved[train]["track:-AM"] == reserved[train]["track:-MB"]  # in one instant
    held = [e for e in events if e["kind"] == "departure_held"]
    assert len(held) == 1 and "single-track section" in held[0]["detail"]


def test_no_train_is_inserted_between_a_train_and_the_switch_it_holds(tmp_path: Path) -> None:
    """The train behind already holds the switch ahead: a departure in between would wait for that lock in front
    of its holder for ever. The dispatcher holds it (reason names the holder) until the holder has passed."""
    nodes = (
        '<node id="A" x="0" y="0"/>\n<node id="J" x="1800" y="0"/>\n<node id="Z" x="5000" y="0"/>\n'
        '<node id="C" x="4000" y="900"/>'
    )
    edges = [_edge("AJ", "A", "J"), _edge("JZ", "J", "Z"), _edge("JC", "J", "C", 16.0, shape="1800,0 4000,900")]
    net = _netconvert(tmp_path, "hold", nodes, "\n".join(edges))
    stops = _stops(
        tmp_path,
        "hold",
        [("p1", "AJ_0", 100, 400, "First"), ("p2", "AJ_0", 1000, 1300, "Second"), ("z", "JZ_0", 2600, 2900, "Zed")],
    )
    services = [_service("first", "p1", "z", 0, skip=["second"]), _service("second", "p2", "z", 20)]
    out, s, stderr = _run(tmp_path, "hold", net, stops, services)
    assert s["n_arrived"] == s["n_trains"] == 2 and s["collisions"] == 0 and s["sumo_collisions"] == 0
    events = read_csv(out / "events.csv")
    held = [e for e in events if e["kind"] == "departure_held" and e["subject"] == "second.000"]
    assert held and "first.000 holds the route through here (switch J" in held[0]["detail"]
    trips = {r["service"]: r for r in read_csv(out / "trips.csv")}
    t_dep = float(trips["second"]["departure_s"])
    first_at = [
        float(r["chainage_m"])
        for r in read_csv(out / "trace.csv")
        if r["train"] == "first.000" and abs(float(r["t_s"]) - t_dep) < 1.0
    ]
    assert first_at and min(first_at) > 1300.0  # it departed only once the holder had passed its platform


def build_short_loop(folder: Path) -> tuple[Path, Path]:
    """Single track A–M1 and M2–B (bidi) joined by a loop of one-way tracks: eastbound L1 (curved, ~190 m, with a
    platform) and westbound L2 (straight, 100 m: shorter than a train plus the overlap, so a westbound train
    waiting at M1 still stands with its rear in the M2–B section)."""
    nodes = (
        '<node id="A" x="0" y="0"/>\n<node id="M1" x="3000" y="0"/>\n<node id="M2" x="3100" y="0"/>\n'
        '<node id="B" x="5100" y="0"/>'
    )
    edges = [
        _edge("AM", "A", "M1"),
        _edge("-AM", "M1", "A"),
        _edge("L1", "M1", "M2", 16.0, spread="right", shape="3000,0 3030,-70 3070,-70 3100,0"),
        _edge("L2", "M2", "M1", 16.0, spread="right"),
        _edge("MB", "M2", "B"),
        _edge("-MB", "B", "M2"),
    ]
    net = _netconvert(folder, "shortloop", nodes, "\n".join(edges))
    stops = _stops(
        folder,
        "shortloop",
        [
            ("x_out", "AM_0", 100, 400, "West"),
            ("z_out", "AM_0", 1000, 1300, "Mid"),
            ("loop", "L1_0", 60, -1, "Loop"),
            ("b_in", "MB_0", 1600, 1900, "East"),
            ("b_out", "-MB_0", 100, 400, "East"),
            ("a_in", "-AM_0", 2600, 2900, "West"),
        ],
    )
    return net, stops


@pytest.mark.parametrize("berths", [True, False])
def test_a_passing_loop_too_short_for_the_train_is_no_passing_place(tmp_path: Path, berths: bool) -> None:
    """Three trains on a line whose loop track L2 (westbound) is shorter than a train plus the overlap. ``west``
    used to be granted M2–B alone, stand on the short loop track with its rear still in M2–B waiting for A–M1,
    which ``ex`` held while standing right behind ``zed``, who waited on the loop for M2–B: a circular wait only
    the occupancy of the track closed (found as a deadlock, with or without platform berths). Now ``west`` reserves
    M2–B and A–M1 together (L2 cannot hold it), and all three arrive."""
    net, stops = build_short_loop(tmp_path)
    services = [
        _service("zed", "z_out", "b_in", 0),
        _service("ex", "x_out", "loop", 0),
        _service("west", "b_out", "a_in", 0),
    ]
    extra = None if berths else {"interlocking": {"platform_berths": False}}
    out, s, stderr = _run(tmp_path, "occ", net, stops, services, extra=extra)
    assert s["n_arrived"] == s["n_trains"] == 3 and s["collisions"] == 0 and s["sumo_collisions"] == 0
    events = read_csv(out / "events.csv")
    assert not [e for e in events if e["kind"] == "deadlock"]
    grouped = [
        e
        for e in events
        if e["kind"] == "section_requested" and e["subject"] == "track:-AM" and "west.000" in e["detail"]
    ]
    assert len(grouped) == 1 and "track:-MB" in yaml.safe_load(grouped[0]["detail"])["with"]
