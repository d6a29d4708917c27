"""The engine's positions follow the discrete model a scenario names, exactly (docs/architecture.md, "The step loop").

One train on the straight corridor driven by a speed profile (accelerate, cruise, brake), run through the
whole engine in SUMO for each step method; from the trace (the state at every step):

* ``euler``     x(k+1) = x(k) + v(k+1)·T            (SUMO's default update)
* ``ballistic`` x(k+1) = x(k) + (v(k) + v(k+1))/2·T  (Paper A's ZOH, Eq. 2)
* ``forward``   x(k+1) = x(k) + v(k)·T              (Paper C's explicit Euler: SUMO is handed v(k))
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from tests.helpers import read_csv, run_railsim

SCENARIO = {
    "name": "discretisation",
    "world": "straight_corridor",
    "simulation": {"step_s": 1.0, "duration_s": 120, "seed": 1},
    "vehicles": {"hst": {"preset": "hst_203m"}},
    "controllers": {
        "prof": {
            "type": "speed_profile",
            "params": {
                "initial_kmh": 100,
                "segments": [
                    {"at_s": 10, "to_kmh": 250, "accel_mps2": 0.9},
                    {"at_s": 80, "to_kmh": 150, "accel_mps2": 0.7},
                ],
            },
        },
        "sep": {"type": "separation"},
    },
    "roles": {"ato": "prof", "separation": "sep"},
    "services": [
        {
            "id": "x",
            "from": "s1",
            "to": "s3",
            "skip": ["s2"],
            "vehicle": "hst",
            "departures": {"times": [0]},
            "start": {"offset_m": 100, "speed_kmh": 100},
        }
    ],
    "faults": {"actuator_noise": {"accel_sd_mps2": 0.05}},
    "outputs": {"trace_stride_s": 1.0},
}


@pytest.mark.parametrize("method", ["euler", "ballistic", "forward"])
def test_positions_follow_the_named_discrete_model(tmp_path: Path, method: str) -> None:
    raw = {**SCENARIO, "simulation": {**SCENARIO["simulation"], "step_method": method}}
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(raw))
    res = run_railsim(["run", str(path), "--out", str(tmp_path / "out"), "--no-progress"])
    assert res.returncode == 0, res.stderr[-2000:]
    rows = read_csv(tmp_path / "out" / "trace.csv")
    x = [float(r["chainage_m"]) for r in rows]
    v = [float(r["speed_mps"]) for r in rows]
    assert len(x) > 100 and max(v) > 60.0  # it did accelerate
    worst = 0.0
    for k in range(len(x) - 1):
        if method == "euler":
            step = v[k + 1]
        elif method == "ballistic":
            step = 0.5 * (v[k] + v[k + 1])
        else:
            step = v[k]
        worst = max(worst, abs((x[k + 1] - x[k]) - step * 1.0))
    assert worst <= 1e-5, (method, worst)  # CSV keeps 6 decimals
