"""Depot runs in SUMO: a unit leaves a depot, runs its day and returns.

The world is the small ``mini_y`` line (A–E, branch to G) with depot leads added to its line description
(``network.generator``: a bidi lead joined to both tracks by one switch each). Every run is checked by the
engine's own desync check every step (railsim's chainage against SUMO's edge and lane position; a
disagreement exits 3), so exit 0 already says "position and direction agree with SUMO" through the depot
runs and their reversals. The tests then check the day a planner would read off the outputs.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from tests.helpers import DATA, read_csv, read_summary, run_railsim


def _line(folder: Path, depots: str) -> Path:
    """``mini_y`` with ``depots`` (a YAML list) added."""
    text = (DATA / "lines" / "mini_y.yaml").read_text(encoding="utf-8")
    text = text.replace("branches:\n", f"depots: {depots}\nbranches:\n", 1)
    path = folder / "mini_depot.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def _service(sid: str, a: str, b: str, at_s: float) -> dict[str, Any]:
    return {"id": sid, "from": a, "to": b, "vehicle": "cq6", "departures": {"times": [at_s]}, "dwell_s": 20}


def _invoke(folder: Path, depots: str, services: list[dict[str, Any]], rotations: dict[str, Any]) -> Any:
    """``railsim run`` in a child process: (output folder, process result)."""
    folder.mkdir(parents=True, exist_ok=True)
    raw = yaml.safe_load((DATA / "scenarios" / "mini_line.yaml").read_text(encoding="utf-8"))
    raw["world"] = {"line": str(_line(folder, depots))}
    raw["services"] = services
    raw["formations"] = []
    raw["simulation"]["duration_s"] = 3600
    raw["rotations"] = rotations
    scn = folder / "scenario.yaml"
    scn.write_text(yaml.safe_dump(raw, sort_keys=False), encoding="utf-8")
    out = folder / "out"
    res = run_railsim(["run", str(scn), "--out", str(out), "--no-progress"], timeout=300)
    return out, res


def _events(out: Path, kind: str) -> list[dict[str, str]]:
    return [r for r in read_csv(out / "events.csv") if r["kind"] == kind]


def _detail(row: dict[str, str]) -> dict[str, Any]:
    return dict(yaml.safe_load(row["detail"]))


ONE_DEPOT = "[{id: yard, name: Yard, between: [b, c]}]"
TWO_DEPOTS = "[{id: west, between: [a, b]}, {id: east, between: [d, e]}]"


def test_a_unit_runs_depot_out_trip_turnback_trip_depot_in(tmp_path: Path) -> None:
    services = [_service("up", "c", "e", 300), _service("down", "e", "c", 900)]
    out, res = _invoke(tmp_path, ONE_DEPOT, services, {"units": "auto", "turnback_min_s": 120, "depots": "auto"})
    assert res.returncode == 0, res.stderr[-2000:]
    s = read_summary(out)
    assert s["collisions"] == 0 and s["sumo_collisions"] == 0 and s["switch_violations"] == 0
    assert s["n_trains"] == 2 and s["n_arrived"] == 2  # the service trips; depot runs are counted apart
    fleet = s["fleet"]
    assert fleet["trips_per_unit"] == {"unit01": 4} and fleet["depot_runs"] == 2 and fleet["depot_runs_arrived"] == 2
    assert fleet["units_per_depot"] == {"start_of_day": {"yard": 1}, "end_of_day": {"yard": 1}}
    assert [r["from_trip"] for r in fleet["turnbacks"]] == ["up.000"]  # the one turnback between service trips
    trips = {r["trip_id"]: r for r in read_csv(out / "trips.csv")}
    run_out, run_in = trips["unit01.depot_out"], trips["unit01.depot_in"]
    assert (run_out["service"], run_out["origin"], run_out["destination"]) == ("depot_out", "yard", "c")
    assert (run_in["service"], run_in["origin"], run_in["destination"]) == ("depot_in", "c", "yard")
    # the day in order: out of the depot, the first trip, the turnback at E, the second trip, into the depot
    arrived = [(float(r["t_s"]), r["subject"]) for r in _events(out, "train_arrived")]
    assert [tid for _, tid in sorted(arrived)] == ["unit01.depot_out", "up.000", "down.000", "unit01.depot_in"]
    # it reaches C's up platform in the direction of its first trip: no turnback there, it arrives at least the
    # depot slack (60 s, planned) before the departure (16 s of it went on the lead switch's throw) and the trip
    # leaves on time; at the end of the day it runs on from C's down platform at once (it does not hold the
    # through platform for a turnback minimum)
    assert float(run_out["planned_arrival_s"]) == pytest.approx(300.0 - 60.0)
    assert float(run_out["arrival_s"]) < float(trips["up.000"]["departure_s"]) - 30.0
    assert abs(float(trips["up.000"]["departure_s"]) - 300.0) <= 0.5 + 1e-9
    assert 0.0 < float(run_in["departure_s"]) - float(trips["down.000"]["arrival_s"]) <= 2.0
    # it ran empty: no stop between the depot and C
    stops = [r for r in read_csv(out / "stops.csv") if r["trip_id"].startswith("unit01.depot")]
    assert {r["station"] for r in stops} == {"c", "yard"}
    # leaving the lead set the up track's depot switch reverse; entering it, the down track's; through trains none
    granted = {(r["subject"], _detail(r)["leg"], tuple(_detail(r)["holders"])) for r in _events(out, "lock_granted")}
    assert ("yard_up", "reverse", ("unit01.depot_out",)) in granted
    assert ("yard_down", "reverse", ("unit01.depot_in",)) in granted
    # the lead is a single-track section: each run reserved it before it used it
    reserved = [(r["subject"], _detail(r)["trains"]) for r in _events(out, "section_reserved")]
    assert ("track:-yard_lead", ["unit01.depot_out"]) in reserved and (
        "track:-yard_lead",
        ["unit01.depot_in"],
    ) in reserved
    # the unit's km include both depot runs (about 1 km each: the lead and the stretch to C)
    assert 1.5 < fleet["empty_km_per_unit"]["unit01"] < 3.0
    assert fleet["km_per_unit"]["unit01"] > fleet["empty_km_per_unit"]["unit01"] + 2 * 2.5


@pytest.mark.parametrize(
    ("rotations_depots", "expected"), [("auto", "west"), ({"by_unit": {"unit01": "east"}}, "east")]
)
def test_the_nearest_depot_or_the_named_one_and_reversals_at_the_terminus(
    tmp_path: Path, rotations_depots: object, expected: str
) -> None:
    services = [_service("up", "a", "e", 1000), _service("down", "e", "a", 1700)]
    rotations = {"units": "auto", "turnback_min_s": 120, "depots": rotations_depots}
    out, res = _invoke(tmp_path, TWO_DEPOTS, services, rotations)
    assert res.returncode == 0, res.stderr[-2000:]
    s = read_summary(out)
    assert s["collisions"] == 0 and s["sumo_collisions"] == 0 and s["switch_violations"] == 0
    fleet = s["fleet"]
    assert fleet["units_per_depot"] == {"start_of_day": {expected: 1}, "end_of_day": {expected: 1}}
    assert fleet["late_first_departures"] == 0
    trips = {r["trip_id"]: r for r in read_csv(out / "trips.csv")}
    assert all(r["arrival_s"] != "" for r in trips.values())
    # both depots join the line beyond A's up platform: out on the down track to A, reverse on the turnback track
    # beyond A, board on the up platform; at the end of the day A -> the same turnback -> up the line to the depot
    reversed_ = {r["subject"]: _detail(r)["edge"] for r in _events(out, "reversed")}
    assert reversed_["up.000"] == "-main_tb_lo" and reversed_["unit01.depot_in"] == "-main_tb_lo"
    # West joins at km 0.75, East at km 5.6: twice that, the leads and the turnbacks at A
    empty_km = fleet["empty_km_per_unit"]["unit01"]
    assert 1.5 < empty_km < 4.0 if expected == "west" else 11.2 < empty_km < 14.0
    # the train graph places the depot runs between A and the depot (km 0.75 or 5.6), in their directions
    from railsim.report.plots.line_data import load_line_run

    paths = load_line_run(out).paths
    run_out, run_in = paths["unit01.depot_out"], paths["unit01.depot_in"]
    assert (run_out.direction, run_in.direction) == ("down", "up")
    depot_km = 0.75 if expected == "west" else 5.6
    assert run_out.km[0] == pytest.approx(depot_km) and run_in.km[-1] == pytest.approx(depot_km)
    assert abs(run_out.km[-1]) < 0.12  # at A's platform (its centre is km 0, the stopping mark 109 m from it)


@pytest.mark.parametrize(
    ("depots", "field", "words"),
    [
        ("nowhere", "rotations.depots.depot", "nowhere"),
        ({"depot": "auto", "by_unit": {"unit01": "depot9"}}, "rotations.depots.by_unit.unit01", "depot9"),
        ({"by_unit": {"unit77": "yard"}}, "rotations.depots.by_unit.unit77", "a unit of the rotations"),
        ({"depot": 5}, "rotations.depots.depot", "'auto' or a depot id"),
    ],
)
def test_bad_depot_names_exit_2_naming_the_field(tmp_path: Path, depots: object, field: str, words: str) -> None:
    services = [_service("up", "c", "e", 300)]
    out, res = _invoke(tmp_path, ONE_DEPOT, services, {"units": "auto", "depots": depots})
    assert res.returncode == 2, res.stderr[-2000:]
    last = res.stderr.strip().splitlines()[-1]
    assert field in last and words in last and "Traceback" not in res.stderr
