"""Engine features the paper experiments need, in a real SUMO run (child process) on the straight corridor:
trains that start in motion at given offsets, a leader on a speed-versus-time profile, chained formations
(train 2 follows 1, train 3 follows 2), actuator noise and ballistic steps. Plus the profile's closed form.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.helpers import DATA, read_csv, read_summary, run_railsim

SCENARIO = DATA / "scenarios" / "corridor_platoon.yaml"


@pytest.fixture(scope="module")
def corridor(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("corridor")
    res = run_railsim(["run", str(SCENARIO), "--out", str(out), "--no-progress"])
    assert res.returncode == 0, res.stderr[-2000:]
    return out


def test_trains_start_in_motion_where_the_scenario_puts_them(corridor: Path) -> None:
    trace = read_csv(corridor / "trace.csv")
    first = {}
    for row in trace:
        first.setdefault(row["train"], row)
    # the first sample is the state at insertion: the configured offsets and speeds
    x = {k: float(v["chainage_m"]) for k, v in first.items()}
    assert x["t1.000"] - x["t2.000"] == pytest.approx(500.0, abs=1e-6)
    assert x["t2.000"] - x["t3.000"] == pytest.approx(1500.0, abs=1e-6)
    for train, kmh in (("t1.000", 220), ("t2.000", 200), ("t3.000", 180)):
        assert float(first[train]["speed_mps"]) == pytest.approx(kmh / 3.6, abs=1e-6)
    # nobody brakes at the start: before the first radio message the followers use the formation handshake
    for train in ("t2.000", "t3.000"):
        assert float(first[train]["command_mps2"]) > -0.5, first[train]


def test_leader_follows_its_profile_and_the_chain_couples_safely(corridor: Path) -> None:
    s = read_summary(corridor)
    assert s["collisions"] == 0 and s["sumo_collisions"] == 0
    lead = {float(r["t_s"]): float(r["speed_mps"]) for r in read_csv(corridor / "trace.csv") if r["train"] == "t1.000"}
    assert lead[250.0] == pytest.approx(220 / 3.6, abs=0.15)  # holds 220 km/h (noise 0.01 m/s² on the command)
    assert lead[420.0] == pytest.approx(180 / 3.6, abs=0.15)  # decelerated at 0.2 m/s² from t = 300 s
    assert lead[700.0] == pytest.approx(220 / 3.6, abs=0.15)  # back up from t = 455 s
    forms = {r["formation"]: r for r in read_csv(corridor / "formations.csv")}
    assert forms["f12"]["final_state"] == "coupled" and forms["f23"]["final_state"] == "coupled"
    assert int(forms["f23"]["couple_successes"]) == 1  # closed a 1.3 km gap from behind
    assert float(forms["f12"]["gap_error_p50_m"]) <= 2.0


def test_a_train_starting_beyond_the_first_edge_is_placed_where_the_scenario_says(tmp_path: Path) -> None:
    """Regression: SUMO inserts on a route's first edge; a start further along must use a trimmed route.

    Two units start in motion 1.3 and 1.5 km beyond Jiugongli (past Qilong and several SUMO edges), 110 m apart.
    Misplaced, SUMO's own collision check disagreed with our ground truth; placed right, neither sees a collision,
    the first trace sample is exactly the start chainage, and both stop at Bagongli (the stop behind them skipped).
    """
    import yaml

    raw = {
        "name": "far_start",
        "world": "chongqing_line3",
        "simulation": {"step_s": 0.5, "duration_s": 600, "seed": 1},
        "vehicles": {"cq6": {"preset": "cq3_6car"}},
        "controllers": {"ato": {"type": "ato"}, "sep": {"type": "separation", "params": {"margin_m": 20}}},
        "roles": {"ato": "ato", "separation": "sep"},
        "services": [
            {
                "id": "a",
                "from": "jiugongli",
                "to": "bagongli",
                "vehicle": "cq6",
                "departures": {"times": [0]},
                "start": {"offset_m": 1500, "speed_kmh": 30},
            },
            {
                "id": "b",
                "from": "jiugongli",
                "to": "bagongli",
                "vehicle": "cq6",
                "departures": {"times": [0]},
                "start": {"offset_m": 1300, "speed_kmh": 30},
            },
        ],
    }
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    res = run_railsim(["run", str(path), "--out", str(tmp_path / "o"), "--no-progress"])
    assert res.returncode == 0, res.stderr[-2000:]
    s = read_summary(tmp_path / "o")
    assert s["collisions"] == 0 and s["sumo_collisions"] == 0
    assert s["n_arrived"] == 2 and s["n_stops_scheduled"] == 2 and s["n_stops_missed"] == 0
    first = {}
    for r in read_csv(tmp_path / "o" / "trace.csv"):
        first.setdefault(r["train"], float(r["chainage_m"]))
    assert first["a.000"] - first["b.000"] == pytest.approx(200.0, abs=1e-6)
