"""Platform berths (railsim/engine/platforms.py): a train does not run into a platform another train occupies.

tests/data/scenarios/platform_berth.yaml: a 400 m platform, two 6-car units 90 s apart, both dwelling 200 s at
s2. The second arrives while the first stands there. Before the rule it closed up to its 50 m separation margin
behind the first unit's rear — inside the platform's stopping window — halted, and SUMO served its stop 141 m
short of the mark. Now it waits the overlap before the platform, then runs in to its mark.

The Line 3 day's stall with berths on, on the mini line: a unit turned in the pocket beyond C comes out to couple
on departure behind a through train standing at C's long (300 m) platform, and another through train arrives
behind them. Held at the berth limit, the unit stood 200 m behind its leader's rear, beyond the 150 m from which
the coupling is asked; its leader waited its whole coupling timeout (300 s) for it, and the through train behind
waited longer than that (on the day: the stall, exit 3). A unit joining the train at its platform is called on.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from tests.helpers import DATA, ROOT, read_csv, read_summary, run_railsim
from tests.sumo.test_external_net import _write
from tests.sumo.test_turnback import POCKET_PAIR, _run_pocket_day

SCENARIO = ROOT / "tests" / "data" / "scenarios" / "platform_berth.yaml"
PLATFORM_M = 400.0
OVERLAP_M = 20.0
TRAIN_M_AT_MOST = 130.0  # the cq3_6car is shorter than this


def test_follower_waits_before_an_occupied_platform_and_stops_at_its_mark(tmp_path: Path) -> None:
    res = run_railsim(["run", str(SCENARIO), "--out", str(tmp_path), "--no-progress"])
    assert res.returncode == 0, res.stderr
    s = read_summary(tmp_path)
    assert s["collisions"] == 0 and s["n_arrived"] == 2 and s["n_stops_served"] == s["n_stops_scheduled"]
    stops = {(r["trip_id"], r["station"]): r for r in read_csv(tmp_path / "stops.csv")}
    assert abs(float(stops[("a.001", "s2")]["stopping_error_m"])) < 0.01  # served at its mark, not short
    events = read_csv(tmp_path / "events.csv")
    waits = [e for e in events if e["kind"] == "platform_occupied"]
    assert len(waits) == 1 and waits[0]["subject"] == "a.001" and '"by":"a.000"' in waits[0]["detail"]
    a_left_s = next(float(e["t_s"]) for e in events if e["kind"] == "stop_departed" and e["subject"] == "a.000")
    assert float(stops[("a.001", "s2")]["arrival_s"]) > a_left_s  # it came in only once the platform was clear
    # while the first unit stood at s2, the second stayed behind the platform's start (less the overlap): its gap
    # to the first unit's rear was at least the free platform length plus the overlap (~300 m, not 50 m)
    trace = read_csv(tmp_path / "trace.csv")
    gaps = [float(r["gap_m"]) for r in trace if r["train"] == "a.001" and r["gap_m"] and float(r["t_s"]) < a_left_s]
    assert gaps and min(gaps) > PLATFORM_M + OVERLAP_M - TRAIN_M_AT_MOST - 10.0


def test_platform_berths_false_turns_the_rule_off(tmp_path: Path) -> None:
    """The same scenario with ``interlocking: {platform_berths: false}``: the follower closes up inside the
    platform behind the standing unit and SUMO serves its stop short (the behaviour the rule exists for)."""
    data = yaml.safe_load(SCENARIO.read_text(encoding="utf-8"))
    data["interlocking"] = {"platform_berths": False}
    scn = _write(tmp_path, "off.yaml", yaml.safe_dump(data, sort_keys=False))
    res = run_railsim(["run", str(scn), "--out", str(tmp_path / "out"), "--no-progress"])
    assert res.returncode == 0, res.stderr
    stops = {(r["trip_id"], r["station"]): r for r in read_csv(tmp_path / "out" / "stops.csv")}
    assert float(stops[("a.001", "s2")]["stopping_error_m"]) < -100.0  # served more than 100 m short
    assert not any(e["kind"] == "platform_occupied" for e in read_csv(tmp_path / "out" / "events.csv"))


def _long_platform_pocket_line(folder: Path) -> Path:
    """``mini_y`` with a pocket beyond C on its low side and a 300 m platform at C."""
    text = (DATA / "lines" / "mini_y.yaml").read_text(encoding="utf-8")
    text = text.replace("{id: c, name: C, km: 3.3}", "{id: c, name: C, km: 3.3, pocket: low, platform_length_m: 300}")
    assert "platform_length_m: 300}" in text
    return _write(folder, "mini_long_c.yaml", text)


def _joining_run(folder: Path, through_s: float) -> tuple[dict, list[dict], dict]:
    """The pocket unit short_up.000 couples on departure from C behind up.000 (leaves A at 200 s); the through
    train up.001 leaves A at ``through_s``. Asserts exit 0 (no stall, no deadlock), no collision or switch
    violation, every trip arrived and every stop served; (summary, events, stops by (trip, station))."""
    raw = yaml.safe_load((DATA / "scenarios" / "mini_line.yaml").read_text(encoding="utf-8"))
    raw["world"] = {"line": str(_long_platform_pocket_line(folder))}
    raw["simulation"]["duration_s"] = 1500
    raw["services"] = [
        {"id": "short_down", "from": "e", "to": "c", "vehicle": "cq6", "departures": {"times": [0]}, "dwell_s": 20},
        {"id": "short_up", "from": "c", "to": "e", "vehicle": "cq6", "departures": {"times": [400]}, "dwell_s": 20},
        {
            "id": "up",
            "from": "a",
            "to": "e",
            "vehicle": "cq6",
            "departures": {"times": [200, through_s]},
            "dwell_s": 20,
        },
    ]
    raw["formations"] = [POCKET_PAIR]
    out = _run_pocket_day(folder, raw)
    s = read_summary(out)
    assert s["n_arrived"] == 4 and s["n_stops_served"] == s["n_stops_scheduled"]
    stops = {(r["trip_id"], r["station"]): r for r in read_csv(out / "stops.csv")}
    return s, read_csv(out / "events.csv"), stops


def test_a_unit_joining_its_leader_at_an_occupied_platform_is_called_on(tmp_path: Path) -> None:
    """The through train runs 150 s behind the leader (as on the Line 3 day): the pocket unit comes out first, is called on into the
    occupied platform, couples, and the pair leaves; the through train waits outside, then stops at its mark."""
    _, events, stops = _joining_run(tmp_path, 350.0)
    assert [e["subject"] for e in events if e["kind"] == "coupled"] == ["pair"]
    assert not any(e["kind"] == "platform_occupied" and e["subject"] == "short_up.000" for e in events)
    leader_at_c = stops[("up.000", "c")]
    # the pair left together, well before the leader's coupling timeout (300 s)
    assert float(leader_at_c["departure_s"]) - float(leader_at_c["arrival_s"]) < 150.0
    assert abs(float(stops[("up.001", "c")]["stopping_error_m"])) < 0.01
    assert float(stops[("up.001", "c")]["arrival_s"]) > float(leader_at_c["departure_s"])
    assert not any(e["kind"] == "emergency_brake_on" for e in events)


def test_a_through_train_between_a_leader_and_its_joining_unit_does_not_stall_them(tmp_path: Path) -> None:
    """The through train runs 75 s behind the leader and is over the pocket's exit points before the unit comes
    out: the join is cut off (``join_cut_off``), the leader leaves after its dwell instead of waiting its coupling
    timeout, the through train then the unit follow, each stopping at its mark (the day's stall at Liugongli)."""
    _, events, stops = _joining_run(tmp_path, 275.0)
    (cut,) = [e for e in events if e["kind"] == "join_cut_off"]
    assert cut["subject"] == "pair" and '"by":"up.001"' in cut["detail"]
    assert not any(e["kind"] in ("coupled", "departure_held_for_follower", "emergency_brake_on") for e in events)
    leader_at_c = stops[("up.000", "c")]
    assert float(leader_at_c["departure_s"]) - float(leader_at_c["arrival_s"]) <= 20.0 + 1.0  # its dwell
    for trip in ("up.000", "up.001"):
        assert abs(float(stops[(trip, "c")]["stopping_error_m"])) < 0.01
    assert float(stops[("up.001", "c")]["arrival_s"]) > float(leader_at_c["departure_s"])
