"""Engine integration: real SUMO runs (each in a child process) of a small Y-shaped line.

What is pinned here: a line with up/down trains, a virtually coupled pair that decouples before the
switch and a merging train runs with 0 collisions, every stop served within ±0.5 m of the mark, the decoupled
units each take the switch lock for their own leg; the same seed gives byte-identical trips.csv; late and lost
messages make the follower act on stale data and the recorder shows it; SUMO's positions match the numpy plant.
"""

from __future__ import annotations

import copy
import json
from pathlib import Path

import yaml

from tests.helpers import DATA, read_csv, read_summary, run_python, run_railsim

MINI = DATA / "scenarios" / "mini_line.yaml"


def _variant(tmp_path: Path, name: str, **changes: object) -> Path:
    """Copy of mini_line.yaml with top-level sections replaced (and an absolute line path)."""
    raw = yaml.safe_load(MINI.read_text())
    raw = copy.deepcopy(raw)
    raw["world"] = {"line": str((MINI.parent / raw["world"]["line"]).resolve())}
    for key, value in changes.items():
        raw[key] = value
    raw["name"] = name
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


def test_mini_line_is_safe_and_serves_every_stop(mini_run: Path) -> None:
    s = read_summary(mini_run)
    assert s["collisions"] == 0 and s["sumo_collisions"] == 0
    assert s["switch_violations"] == 0
    assert s["n_arrived"] == s["n_trains"] == 7
    assert s["n_stops_missed"] == 0
    assert s["n_stops_served"] == s["n_stops_scheduled"]
    assert s["max_stopping_error_m"] <= 0.5
    assert s["min_gap_m"] > 0


def test_stop_rows_are_consistent(mini_run: Path) -> None:
    stops = read_csv(mini_run / "stops.csv")
    assert stops, "no stop rows"
    for row in stops:
        assert row["missed"] == "False"
        err = abs(float(row["stopping_error_m"]))
        assert err <= 0.5, row
        if row["departure_s"]:
            assert float(row["departure_s"]) >= float(row["arrival_s"])
            assert float(row["dwell_s"]) >= 20.0 - 1e-6  # the scenario's dwell, kept by SUMO


def test_pair_couples_then_decouples_and_takes_own_switch_lock(mini_run: Path) -> None:
    forms = read_csv(mini_run / "formations.csv")
    assert len(forms) == 1
    f = forms[0]
    assert int(f["couple_successes"]) == 1 and f["final_state"] == "free"
    # holds its target gap while coupled (median error; the gap opens while both units accelerate from a
    # station, the follower starting 0.5-1 s later, and closes again at cruise)
    assert float(f["gap_error_p50_m"]) <= 3.0
    assert float(f["min_gap_m"]) >= 30.0 - 0.1  # never closer than the standstill target
    events = read_csv(mini_run / "events.csv")
    leader, follower = f["leader"], f["follower"]
    grants = [
        (float(e["t_s"]), json.loads(e["detail"]))
        for e in events
        if e["kind"] == "lock_granted" and e["subject"] == "c_up"
    ]
    lead_grant = [g for g in grants if g[1]["holders"] == [leader]]
    fol_grant = [g for g in grants if g[1]["holders"] == [follower]]
    assert len(lead_grant) == 1 and len(fol_grant) == 1, grants  # decoupled: each unit locks its own leg
    assert lead_grant[0][1]["leg"] != fol_grant[0][1]["leg"]
    released = [
        float(e["t_s"])
        for e in events
        if e["kind"] == "lock_released"
        and e["subject"] == "c_up"
        and json.loads(e["detail"])["request"] == lead_grant[0][1]["request"]
    ]
    # the follower's lock comes after the leader's tail cleared and the switch was thrown (15 s)
    assert released and fol_grant[0][0] >= released[0] + 15.0 - 1e-6
    trips = {r["trip_id"]: r for r in read_csv(mini_run / "trips.csv")}
    assert trips[leader]["destination"] == "e" and trips[leader]["status"] == "arrived"
    assert trips[follower]["destination"] == "g" and trips[follower]["status"] == "arrived"
    assert float(trips[follower]["time_coupled_s"]) > 60.0


def test_same_seed_gives_byte_identical_trips(tmp_path: Path) -> None:
    faults = {
        "comm": {
            "t2t": {"delay_s": {"dist": "lognormal", "mean": 0.3, "sd": 0.1}, "loss_prob": 0.05},
            "t2g": {"delay_s": {"dist": "uniform", "low": 0.1, "high": 0.6}, "loss_prob": 0.05},
        },
        "sensor_noise": {"position_sd_m": 0.05, "speed_sd_mps": 0.01},
    }
    path = _variant(tmp_path, "noisy", faults=faults)
    outs = []
    for k in range(2):
        out = tmp_path / f"run{k}"
        res = run_railsim(["run", str(path), "--out", str(out), "--seed", "11", "--no-progress"])
        assert res.returncode == 0, res.stderr
        outs.append(out)
    assert (outs[0] / "trips.csv").read_bytes() == (outs[1] / "trips.csv").read_bytes()
    assert (outs[0] / "stops.csv").read_bytes() == (outs[1] / "stops.csv").read_bytes()
    assert (outs[0] / "events.csv").read_bytes() == (outs[1] / "events.csv").read_bytes()


def test_late_and_lost_messages_leave_the_follower_on_stale_data(tmp_path: Path) -> None:
    # t2t messages arrive 1.5 s late, and the follower hears nothing for 20 s while coupled on the run
    faults = {
        "comm": {
            "t2t": {
                "delay_s": {"dist": "constant", "value": 1.5},
                "loss_prob": 0.0,
                "outages": [{"start_s": 250.0, "end_s": 270.0}],
            },
            "t2g": {"delay_s": {"dist": "constant", "value": 0.3}, "loss_prob": 0.0},
        }
    }
    path = _variant(tmp_path, "stale", faults=faults)
    out = tmp_path / "out"
    res = run_railsim(["run", str(path), "--out", str(out), "--no-progress"])
    assert res.returncode == 0, res.stderr
    s = read_summary(out)
    assert s["collisions"] == 0
    follower = read_csv(out / "formations.csv")[0]["follower"]
    trips = {r["trip_id"]: r for r in read_csv(out / "trips.csv")}
    assert float(trips[follower]["max_message_age_s"]) >= 1.5  # it acted on 1.5 s-old states
    events = read_csv(out / "events.csv")
    degraded = [float(e["t_s"]) for e in events if e["kind"] == "vc_degraded" and e["subject"] == follower]
    restored = [float(e["t_s"]) for e in events if e["kind"] == "vc_restored" and e["subject"] == follower]
    assert degraded and 250.0 < degraded[0] < 270.0  # fell back to separation on ground data in the outage
    assert restored and restored[0] > degraded[0]
    assert s["comm"]["t2t"]["lost_outage"] > 0


def test_sumo_positions_match_the_numpy_plant() -> None:
    """Euler and ballistic: SUMO's odometer equals the plant's own position integration to 1e-6 m."""
    code = r"""
import json, numpy as np, network
from railsim.physics import dynamics
from railsim.physics.vehicle import preset
from railsim.engine.sumo import SumoBridge, SumoConfig, VTypeSpec
veh = preset("cq3_6car")
b = network.build("straight_corridor")
route = next(iter(b.routes.values()))
out = {}
for method in ("euler", "ballistic"):
    cfg = SumoConfig(net_file=b.net_file, additional_files=[b.stops_file], step_s=0.5, step_method=method,
                     vtypes=[VTypeSpec("t", veh.length_m, 100.0)])
    with SumoBridge(cfg) as br:
        br.add_route("r", route.edges)
        br.add_train("x", "r", "t", 200.0)
        br.step()
        st = dynamics.PlantState(speed_mps=0.0)
        x = 0.0; err = 0.0
        for k in range(600):
            u = 0.8 if k < 200 else (0.0 if k < 350 else -0.9)
            res = dynamics.step(veh, st, u, 0.5, 0.0, False, method)
            st = res.state; x += res.advance_m
            br.set_speeds(["x"], [st.speed_mps]); br.step()
            odo = float(br.read(["x"]).odometer_m[0])
            err = max(err, abs(odo - x))
        out[method] = {"err": err, "x": x}
print(json.dumps(out))
"""
    res = run_python(code)
    assert res.returncode == 0, res.stderr
    import json

    data = json.loads(res.stdout.strip().splitlines()[-1])
    for method in ("euler", "ballistic"):
        assert data[method]["x"] > 1000.0
        assert data[method]["err"] <= 1e-6, (method, data[method])


def test_run_rejects_a_broken_scenario_with_exit_2(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    raw = yaml.safe_load(MINI.read_text())
    raw["world"] = {"line": str((MINI.parent / raw["world"]["line"]).resolve())}
    raw["simulation"]["step_s"] = -1
    bad.write_text(yaml.safe_dump(raw, sort_keys=False))
    res = run_railsim(["run", str(bad), "--out", str(tmp_path / "o")])
    assert res.returncode == 2
    assert "Traceback" not in res.stderr
    assert "simulation.step_s" in res.stderr
