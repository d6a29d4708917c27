"""Turnbacks and rotations in SUMO: a unit reverses and runs its next trip.

Two small nets built with netconvert:

* a single-track line whose terminal platforms are on ``bidi`` track: the unit reverses where it stands;
* a double-track line ending in a turnback track beyond the platform: the unit runs into it, SUMO reverses it,
  it runs back to the departure platform.

Every run below is checked by the engine's own desync check (railsim's chainage against SUMO's edge and lane
position every step; a disagreement exits 3), so exit 0 is itself the statement "position and direction agree
with SUMO after the reversal". The tests then check what a planner would: the reversal happened on the bidi
edge, the minimum turnback was respected, ``auto`` chains like the equivalent explicit list, and a late incoming
unit delays its next trip by exactly what it lacks of its turnback minimum.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from tests.helpers import DATA, read_csv, read_summary, run_railsim
from tests.sumo.test_external_net import _COMMON, _edge, _netconvert, _stops, _write
from tests.sumo.test_single_track import build_single_line

STEP_S = float(_COMMON["simulation"]["step_s"])  # type: ignore[index]


def build_tail_track(folder: Path) -> tuple[Path, Path]:
    """Double track Aston–Bury (3 km) and a 300 m bidi turnback track beyond Bury's platforms."""
    nodes = '<node id="A" x="0" y="0"/>\n<node id="B" x="3000" y="0"/>\n<node id="X" x="3300" y="0"/>'
    edges = [
        _edge("u1", "A", "B", spread="right"),
        _edge("d1", "B", "A", spread="right"),
        _edge("T", "B", "X"),
        _edge("-T", "X", "B"),
    ]
    cons = '<connection from="u1" to="T"/>\n<connection from="-T" to="d1"/>\n<connection from="T" to="-T"/>'
    net = _netconvert(folder, "tail", nodes, "\n".join(edges), cons)
    stops = _stops(
        folder,
        "tail",
        [
            ("a_out", "u1_0", 100, 400, "Aston"),
            ("b_in", "u1_0", 2600, 2900, "Bury"),
            ("b_out", "d1_0", 100, 400, "Bury"),
            ("a_in", "d1_0", 2600, 2900, "Aston"),
        ],
    )
    return net, stops


def _service(sid: str, a: str, b: str, times: list[float]) -> dict:
    return {"id": sid, "from": a, "to": b, "vehicle": "cq6", "departures": {"times": times}, "dwell_s": 30}


def _invoke(folder: Path, net: Path, stops: Path, services: list[dict], rotations: object) -> tuple[Path, object]:
    """``railsim run`` the services with ``rotations`` in a child process: (output folder, process result)."""
    folder.mkdir(parents=True, exist_ok=True)
    raw = {
        "name": folder.name,
        "world": {"net": str(net), "additional": [str(stops)]},
        **_COMMON,
        "services": services,
        "rotations": rotations,
    }
    raw["simulation"] = {**raw["simulation"], "duration_s": 2500}  # type: ignore[dict-item]
    scn = _write(folder, "scenario.yaml", yaml.safe_dump(raw, sort_keys=False))
    out = folder / "out"
    return out, run_railsim(["run", str(scn), "--out", str(out), "--no-progress"], timeout=300)


def _run(folder: Path, net: Path, stops: Path, services: list[dict], rotations: object) -> Path:
    out, res = _invoke(folder, net, stops, services, rotations)
    assert res.returncode == 0, res.stderr + res.stdout  # type: ignore[attr-defined]
    return out


def _events(out: Path, kind: str) -> list[dict]:
    return [r for r in read_csv(out / "events.csv") if r["kind"] == kind]


SHUTTLE = [_service("out", "Aston", "Bury", [0, 900]), _service("back", "Bury", "Aston", [400, 1300])]


def test_a_unit_reverses_on_a_bidi_platform_and_runs_the_day(tmp_path: Path) -> None:
    net, stops = build_single_line(tmp_path)
    out = _run(tmp_path, net, stops, SHUTTLE, {"units": "auto", "turnback_min_s": 60})
    fleet = read_summary(out)["fleet"]
    assert fleet["units_used"] == 1 and fleet["trips_per_unit"] == {"unit01": 4}
    reversed_ = _events(out, "reversed")
    # the unit is flipped onto the bidi partner of the edge it arrived on, at each of the three turnbacks
    assert [r["subject"] for r in reversed_] == ["back.000", "out.001", "back.001"]
    assert [yaml.safe_load(r["detail"])["edge"] for r in reversed_] == ["-MB", "AM", "-MB"]
    trips = {r["trip_id"]: r for r in read_csv(out / "trips.csv")}
    assert all(r["arrival_s"] != "" for r in trips.values())
    for row in fleet["turnbacks"]:
        assert row["achieved_s"] >= row["min_s"]
        # nobody was late: each next trip leaves on time (within one step of its scheduled departure)
        assert abs(row["departed_s"] - row["scheduled_departure_s"]) <= STEP_S + 1e-9
    assert read_summary(out)["collisions"] == 0


def test_a_unit_turns_back_via_a_turnback_track_beyond_the_platform(tmp_path: Path) -> None:
    net, stops = build_tail_track(tmp_path)
    services = [_service("out", "Aston", "Bury", [0]), _service("back", "Bury", "Aston", [600])]
    out = _run(tmp_path, net, stops, services, {"units": "auto", "turnback_min_s": 120})
    (rev,) = _events(out, "reversed")
    assert yaml.safe_load(rev["detail"])["edge"] == "-T"  # it reversed on the turnback track, not at the platform
    (halt,) = _events(out, "reversal_halt")
    (arrived,) = [r for r in _events(out, "train_arrived") if r["subject"] == "out.000"]
    assert float(halt["t_s"]) > float(arrived["t_s"]) + 10.0  # it ran from the platform into the track first
    fleet = read_summary(out)["fleet"]
    assert fleet["units_used"] == 1
    (row,) = fleet["turnbacks"]
    assert row["achieved_s"] >= row["min_s"] and abs(row["departed_s"] - 600.0) <= STEP_S + 1e-9


def test_auto_chains_like_the_explicit_list(tmp_path: Path) -> None:
    net, stops = build_single_line(tmp_path)
    auto = _run(tmp_path / "auto", net, stops, SHUTTLE, {"units": "auto", "turnback_min_s": 60})
    listed = {"unit01": ["out.000", "back.000", "out.001", "back.001"]}
    explicit = _run(tmp_path / "explicit", net, stops, SHUTTLE, {"units": listed, "turnback_min_s": 60})
    a, e = read_summary(auto)["fleet"], read_summary(explicit)["fleet"]
    assert a["trips_per_unit"] == e["trips_per_unit"] == {"unit01": 4}
    assert [(r["from_trip"], r["to_trip"]) for r in a["turnbacks"]] == [
        (r["from_trip"], r["to_trip"]) for r in e["turnbacks"]
    ]
    assert (auto / "trips.csv").read_text() == (explicit / "trips.csv").read_text()


def test_auto_starts_a_new_unit_when_the_turnback_minimum_does_not_fit(tmp_path: Path) -> None:
    net, stops = build_tail_track(tmp_path)
    services = [_service("out", "Aston", "Bury", [0]), _service("back", "Bury", "Aston", [200])]
    out = _run(tmp_path, net, stops, services, {"units": "auto", "turnback_min_s": 120})
    fleet = read_summary(out)["fleet"]  # arrives ~150 s, +120 s > 200 s: a second unit takes "back"
    assert fleet["units_used"] == 2 and fleet["turnbacks"] == []


def test_a_late_incoming_unit_delays_its_next_trip_by_what_it_lacks(tmp_path: Path) -> None:
    net, stops = build_tail_track(tmp_path)
    services = [_service("out", "Aston", "Bury", [0]), _service("back", "Bury", "Aston", [200])]
    rot = {"units": {"u1": ["out.000", "back.000"]}, "turnback_min_s": 120}
    out = _run(tmp_path, net, stops, services, rot)
    trips = {r["trip_id"]: r for r in read_csv(out / "trips.csv")}
    arrival_s = float(trips["out.000"]["arrival_s"])
    departure_s = float(trips["back.000"]["departure_s"])
    expected_s = arrival_s + 120.0  # the knock-on: arrival + minimum turnback, not the timetable's 200 s
    assert expected_s > 200.0 + 30.0
    assert expected_s - 1e-9 <= departure_s <= expected_s + 2 * STEP_S
    (row,) = read_summary(out)["fleet"]["turnbacks"]
    assert abs(row["knock_on_s"] - (expected_s - 200.0)) < 1e-6
    assert read_summary(out)["fleet"]["late_starts_from_incoming_unit"] == 1


def test_rotations_that_do_not_chain_or_cannot_turn_are_refused(tmp_path: Path) -> None:
    net, stops = build_tail_track(tmp_path)
    services = [_service("out", "Aston", "Bury", [0, 900]), _service("back", "Bury", "Aston", [600])]
    # out.001 starts at Aston, but out.000 leaves its unit at Bury
    _, res = _invoke(tmp_path / "a", net, stops, services, {"units": {"u1": ["out.000", "out.001"]}})
    assert res.returncode == 2  # type: ignore[attr-defined]
    assert "rotations.units.u1[1]" in res.stderr and "ends 'out.000' at 'bury'" in res.stderr  # type: ignore[attr-defined]
    # back.000 -> out.001 chains on paper, but Aston has no turnaround: the world cannot turn the unit there
    no_turn = {"units": {"u1": ["out.000", "back.000", "out.001"]}}
    _, res = _invoke(tmp_path / "b", net, stops, services, no_turn)
    assert res.returncode == 2  # type: ignore[attr-defined]
    assert "rotations.units.u1[2]" in res.stderr and "no turnaround" in res.stderr  # type: ignore[attr-defined]


def _mini_with_pocket(folder: Path) -> Path:
    """``mini_y`` with a pocket track beyond C on its low side (so trains from E can turn at C)."""
    text = (DATA / "lines" / "mini_y.yaml").read_text(encoding="utf-8")
    text = text.replace("{id: c, name: C, km: 3.3}", "{id: c, name: C, km: 3.3, pocket: low}")
    assert "pocket: low" in text
    return _write(folder, "mini_pocket.yaml", text)


# the pocket unit's next trip (short_up.000) couples on departure from C behind the through train up.000
POCKET_PAIR = {
    "id": "pair",
    "leader": {"service": "up", "trip": 0},
    "follower": {"service": "short_up", "trip": 0},
    "target_gap_m": 30,
    "couple": {"on_departure": True},
}


def _run_pocket_day(tmp_path: Path, raw: dict) -> Path:
    """Run ``raw`` with unit u1 = short_down.000 then short_up.000 (turning in C's pocket); assert exit 0 and no
    collision or switch violation; the output folder."""
    raw["rotations"] = {"units": {"u1": ["short_down.000", "short_up.000"]}, "turnback_min_s": 120}
    scn = _write(tmp_path, "pocket.yaml", yaml.safe_dump(raw, sort_keys=False))
    out = tmp_path / "out"
    res = run_railsim(["run", str(scn), "--out", str(out), "--no-progress"], timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    s = read_summary(out)
    assert s["collisions"] == 0 and s["sumo_collisions"] == 0 and s["switch_violations"] == 0
    return out


def test_a_short_turn_in_a_pocket_track_between_through_trains(tmp_path: Path) -> None:
    line = _mini_with_pocket(tmp_path)
    raw = yaml.safe_load((DATA / "scenarios" / "mini_line.yaml").read_text(encoding="utf-8"))
    raw["world"] = {"line": str(line)}
    raw["services"] = [
        {"id": "short_down", "from": "e", "to": "c", "vehicle": "cq6", "departures": {"times": [0]}, "dwell_s": 20},
        {"id": "short_up", "from": "c", "to": "e", "vehicle": "cq6", "departures": {"times": [420]}, "dwell_s": 20},
        # through trains pass C on both tracks while the unit turns
        {"id": "up", "from": "a", "to": "e", "vehicle": "cq6", "departures": {"times": [120, 300]}, "dwell_s": 20},
        {"id": "down", "from": "e", "to": "a", "vehicle": "cq6", "departures": {"times": [150]}, "dwell_s": 20},
    ]
    raw["formations"] = []
    out = _run_pocket_day(tmp_path, raw)
    (rev,) = _events(out, "reversed")
    assert yaml.safe_load(rev["detail"])["edge"] == "-c_pk"
    # the unit took both pocket switches on their reverse leg; the through trains passed them on the normal leg
    legs = {
        (r["subject"], yaml.safe_load(r["detail"])["leg"], tuple(yaml.safe_load(r["detail"])["holders"]))
        for r in _events(out, "lock_granted")
        if r["subject"] in ("c_pk_in", "c_pk_out")
    }
    assert ("c_pk_in", "reverse", ("short_up.000",)) in legs and ("c_pk_out", "reverse", ("short_up.000",)) in legs
    assert any(leg == "normal" for _, leg, _ in legs)
    # the exit route is set only when the unit leaves the pocket, not while it waits there
    (granted_out,) = [
        r for r in _events(out, "lock_requested") if r["subject"] == "c_pk_out" and "short_up" in r["detail"]
    ]
    assert float(granted_out["t_s"]) >= float(rev["t_s"])
    trips = {r["trip_id"]: r for r in read_csv(out / "trips.csv")}
    assert all(r["arrival_s"] != "" for r in trips.values())
    # on time, or a little late when the through train ahead still holds the junction beyond C (lock queue)
    assert 420.0 - 1e-9 <= float(trips["short_up.000"]["departure_s"]) <= 420.0 + 30.0


def test_a_unit_with_nothing_to_run_within_its_layover_leaves_service(tmp_path: Path) -> None:
    net, stops = build_tail_track(tmp_path)
    services = [_service("out", "Aston", "Bury", [0]), _service("back", "Bury", "Aston", [1500])]
    short = {"units": "auto", "turnback_min_s": 60, "max_layover_s": 600}  # ready ~210 s, next departure 1500 s
    long = {**short, "max_layover_s": 3600}
    assert read_summary(_run(tmp_path / "short", net, stops, services, short))["fleet"]["units_used"] == 2
    out = _run(tmp_path / "long", net, stops, services, long)
    assert read_summary(out)["fleet"]["units_used"] == 1
    (row,) = read_summary(out)["fleet"]["turnbacks"]
    assert row["departed_s"] >= 1500.0  # it waited in the turnback track for its departure


# ---------------------------------------------------------------------- a coupled pair across a turnback
def _pair_services(back_s: float) -> list[dict]:
    return [
        _service("outA", "Aston", "Bury", [0]),
        _service("outB", "Aston", "Bury", [0]),
        _service("backA", "Bury", "Aston", [back_s]),
        _service("backB", "Bury", "Aston", [back_s]),
    ]


def _pair_run(folder: Path, net: Path, stops: Path, back_leader: str, back_s: float) -> tuple[Path, object]:
    """outA+outB coupled Aston → Bury; each unit turns back; the back pair couples again with ``back_leader``
    leading (the other back trip follows)."""
    back_follower = "backB" if back_leader == "backA" else "backA"

    def pair(fid: str, lead: str, fol: str) -> dict:
        return {
            "id": fid,
            "leader": {"service": lead, "trip": 0},
            "follower": {"service": fol, "trip": 0},
            "target_gap_m": 30,
            "couple": {"on_departure": True},
        }

    folder.mkdir(parents=True, exist_ok=True)
    raw = {
        "name": folder.name,
        "world": {"net": str(net), "additional": [str(stops)]},
        **_COMMON,
        "services": _pair_services(back_s),
        "rotations": {
            "units": {"u1": ["outA.000", "backA.000"], "u2": ["outB.000", "backB.000"]},
            "turnback_min_s": 60,
        },
        "formations": [pair("there", "outA", "outB"), pair("back", back_leader, back_follower)],
    }
    raw["simulation"] = {**raw["simulation"], "duration_s": 2500}  # type: ignore[dict-item]
    scn = _write(folder, "scenario.yaml", yaml.safe_dump(raw, sort_keys=False))
    out = folder / "out"
    return out, run_railsim(["run", str(scn), "--out", str(out), "--no-progress"], timeout=300)


def _check_pair_back(out: Path, leader: str, follower: str) -> None:
    summary = read_summary(out)
    assert summary["collisions"] == 0 and summary["fleet"]["turnback_min_respected"]
    coupled = [r["subject"] for r in _events(out, "coupled")]
    assert coupled == ["there", "back"]  # coupled on the way there, and again after the turnback
    trips = {r["trip_id"]: r for r in read_csv(out / "trips.csv")}
    lead, fol = trips[f"{leader}.000"], trips[f"{follower}.000"]
    assert lead["arrival_s"] != "" and fol["arrival_s"] != ""
    # they leave together, the follower right behind its leader (it waited for the leader's departure) ...
    assert 0.0 <= float(fol["departure_s"]) - float(lead["departure_s"]) <= 10.0
    # ... and run coupled to the end: the follower arrives within a few seconds of its leader
    assert 0.0 < float(fol["arrival_s"]) - float(lead["arrival_s"]) <= 15.0
    # a unit carries its state across the turnback: its energy and coupled time are its trips' sums
    fleet = summary["fleet"]
    by_unit: dict[str, list[dict]] = {}
    for row in fleet["turnbacks"]:  # each unit ran two trips: the one it arrived with and the one after
        by_unit.setdefault(row["unit"], []).extend([trips[row["from_trip"]], trips[row["to_trip"]]])
    assert len(by_unit) == 2 and all(len(rows) == 2 for rows in by_unit.values())
    for uid, rows in by_unit.items():
        assert abs(fleet["energy_kwh_per_unit"][uid] - sum(float(r["energy_kwh"]) for r in rows)) < 2e-3
        assert abs(fleet["coupled_s_per_unit"][uid] - sum(float(r["time_coupled_s"]) for r in rows)) < 2e-3
    assert sum(fleet["coupled_s_per_unit"].values()) > 0.0 and all(v > 0 for v in fleet["energy_kwh_per_unit"].values())


def test_a_coupled_pair_cannot_reverse_in_place_on_one_bidi_track(tmp_path: Path) -> None:
    """Measured: when two units reverse one behind the other on one bidi platform track, SUMO 1.28 keeps them on
    the lane in their old order and reports them colliding (1595 reports in this case, railsim's own gap 30 m)
    until they leave the edge. The engine refuses the formation before the run, naming it."""
    net, stops = build_single_line(tmp_path)
    _, bad = _pair_run(tmp_path, net, stops, "backB", 900.0)
    assert bad.returncode == 2, bad.stderr + bad.stdout  # type: ignore[attr-defined]
    assert "formations.back" in bad.stderr and "one behind the other on one bidi track" in bad.stderr  # type: ignore[attr-defined]


def test_a_coupled_pair_turns_back_through_a_turnback_track_first_in_first_out(tmp_path: Path) -> None:
    net, stops = build_tail_track(tmp_path)
    out, res = _pair_run(tmp_path / "ok", net, stops, "backA", 900.0)
    assert res.returncode == 0, res.stderr + res.stdout  # type: ignore[attr-defined]
    _check_pair_back(out, "backA", "backB")
    # the unit of outB comes round second: naming it the leader is refused before the run, with the fix
    _, bad = _pair_run(tmp_path / "bad", net, stops, "backB", 900.0)
    assert bad.returncode == 2  # type: ignore[attr-defined]
    assert "formations.back" in bad.stderr and "make 'backA.000' the leader" in bad.stderr  # type: ignore[attr-defined]


def test_a_unit_turned_in_a_pocket_couples_behind_a_through_train(tmp_path: Path) -> None:
    """The day's Jurenba case on the mini line: a unit turns in the pocket beyond C and leaves coupled behind a
    through train. It waits in the pocket until the through train stands at C (coming out earlier would put it in
    front), comes out behind it, and the through train stays at C after its dwell until the two are coupled."""
    line = _mini_with_pocket(tmp_path)
    raw = yaml.safe_load((DATA / "scenarios" / "mini_line.yaml").read_text(encoding="utf-8"))
    raw["world"] = {"line": str(line)}
    raw["services"] = [
        {"id": "short_down", "from": "e", "to": "c", "vehicle": "cq6", "departures": {"times": [0]}, "dwell_s": 20},
        {"id": "short_up", "from": "c", "to": "e", "vehicle": "cq6", "departures": {"times": [400]}, "dwell_s": 20},
        {"id": "up", "from": "a", "to": "e", "vehicle": "cq6", "departures": {"times": [200]}, "dwell_s": 20},
    ]
    raw["formations"] = [POCKET_PAIR]
    out = _run_pocket_day(tmp_path, raw)
    assert [r["subject"] for r in _events(out, "coupled")] == ["pair"]
    stops = {(r["trip_id"], r["station"]): r for r in read_csv(out / "stops.csv")}
    leader_at_c = stops[("up.000", "c")]
    # the unit left the pocket only once the through train stood at C
    (rev,) = _events(out, "reversed")
    assert float(rev["t_s"]) >= float(leader_at_c["arrival_s"])
    # the through train waited for it after its dwell (logged), and the two left C together
    (held,) = _events(out, "departure_held_for_follower")
    assert held["subject"] == "up.000"
    assert float(leader_at_c["departure_s"]) - float(leader_at_c["arrival_s"]) > 20.0 + STEP_S
    trips = {r["trip_id"]: r for r in read_csv(out / "trips.csv")}
    gap_s = float(trips["short_up.000"]["departure_s"]) - float(leader_at_c["departure_s"])
    assert 0.0 <= gap_s <= 10.0
    # coupled to E: it arrives right behind its leader
    assert 0.0 < float(trips["short_up.000"]["arrival_s"]) - float(trips["up.000"]["arrival_s"]) <= 15.0


def test_a_train_behind_a_unit_at_its_turnback_does_not_brake_for_a_ghost(tmp_path: Path) -> None:
    """At a handover the unit's next trip is a new train to the ground; before its first report arrives the ground
    places it where it came on the line (its platform), not where its unit was first inserted. Found in the
    service day: every handover with a train approaching behind gave that train a one-step emergency brake (374 in
    the day) because the ground placed the new trip at its unit's first insertion point."""
    net, stops = build_tail_track(tmp_path)
    services = [_service("out", "Aston", "Bury", [0, 150]), _service("back", "Bury", "Aston", [900])]
    out = _run(tmp_path, net, stops, services, {"units": {"u1": ["out.000", "back.000"]}, "turnback_min_s": 120})
    (handover,) = _events(out, "unit_turnback")
    arrived = {r["trip_id"]: r for r in read_csv(out / "trips.csv")}
    # out.001 was on its way behind when out.000's unit turned (the dangerous moment) ...
    assert float(arrived["out.001"]["arrival_s"]) > float(handover["t_s"]) + 30.0
    # ... and never had to brake for it
    assert _events(out, "emergency_brake_on") == []
    assert read_summary(out)["collisions"] == 0


def _late_first_unit(folder: Path, rotations: object) -> Path:
    """out.000 (planned first to reach Bury) leaves Aston 200 s late, so out.001's unit arrives first."""
    folder.mkdir(parents=True, exist_ok=True)
    net, stops = build_tail_track(folder)
    services = [_service("out", "Aston", "Bury", [0, 60]), _service("back", "Bury", "Aston", [400, 700])]
    raw = {
        "name": folder.name,
        "world": {"net": str(net), "additional": [str(stops)]},
        **_COMMON,
        "services": services,
        "rotations": rotations,
        "disturbances": {"departure": [{"services": ["out"], "until_s": 10, "dist": "constant", "value_s": 200}]},
    }
    raw["simulation"] = {**raw["simulation"], "duration_s": 2500}  # type: ignore[dict-item]
    scn = _write(folder, "scenario.yaml", yaml.safe_dump(raw, sort_keys=False))
    out = folder / "out"
    res = run_railsim(["run", str(scn), "--out", str(out), "--no-progress"], timeout=300)
    assert res.returncode == 0, res.stderr + res.stdout
    return out


def test_a_unit_that_arrives_first_takes_the_first_departure(tmp_path: Path) -> None:
    """First in, first out by the actual arrivals (``units: auto``): the unit planned for back.000 arrives after
    the one planned for back.001, so the two swap the rest of their days and both trips leave on time. With the
    same chaining written out explicitly the units keep their trips, and back.000 waits for its late unit."""
    auto = _late_first_unit(tmp_path / "auto", {"units": "auto", "turnback_min_s": 60})
    listed = {"units": {"u1": ["out.000", "back.000"], "u2": ["out.001", "back.001"]}, "turnback_min_s": 60}
    fixed = _late_first_unit(tmp_path / "explicit", listed)
    trips = {r["trip_id"]: r for r in read_csv(auto / "trips.csv")}
    assert float(trips["out.001"]["arrival_s"]) < float(trips["out.000"]["arrival_s"])  # the case: out of order
    (swap,) = _events(auto, "unit_swapped")
    assert swap["subject"] == "out.001" and yaml.safe_load(swap["detail"])["takes"] == "back.000"
    fleet = read_summary(auto)["fleet"]
    assert fleet["units_swapped"] == 1 and fleet["late_starts_from_incoming_unit"] == 0
    assert {(r["from_trip"], r["to_trip"]) for r in fleet["turnbacks"]} == {
        ("out.001", "back.000"),
        ("out.000", "back.001"),
    }
    for row in fleet["turnbacks"]:  # both leave on time, each after its own unit's minimum turnback
        assert row["achieved_s"] >= row["min_s"] - 1e-6
        assert abs(row["departed_s"] - row["scheduled_departure_s"]) <= STEP_S + 1e-9
    late = {r["trip_id"]: r for r in read_csv(fixed / "trips.csv")}
    assert float(late["back.000"]["departure_s"]) > float(trips["back.000"]["departure_s"]) + 60.0
    assert not _events(fixed, "unit_swapped")
    assert read_summary(auto)["collisions"] == 0 and read_summary(fixed)["collisions"] == 0
