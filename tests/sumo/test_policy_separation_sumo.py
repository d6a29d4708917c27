"""ADBM vs RDBM as the line's separation policy (Paper D §3.9), closed forms and a SUMO run on Line 3.

Here: the tests of it that run SUMO or a railsim child process; the others are in ``tests/unit/test_policy_separation.py``.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from tests.helpers import read_summary, run_railsim


def test_rdbm_runs_closer_than_adbm_on_line3(tmp_path: Path) -> None:
    running = {}
    for mode in ("adbm", "rdbm"):
        raw = {
            "name": f"sep_{mode}",
            "world": "chongqing_line3",
            "simulation": {"step_s": 0.5, "duration_s": 900, "seed": 2},
            "vehicles": {"cq6": {"preset": "cq3_6car"}},
            "controllers": {
                "ato": {"type": "ato"},
                "sep": {"type": "policy_separation", "params": {"mode": mode, "margin_m": 10}},
            },
            "roles": {"ato": "ato", "separation": "sep"},
            # the follower, 20 s behind, reaches each platform while the leader stops there: the platform berth
            # (railsim.engine.platforms) would hold both modes at the same limit; this compares the separations
            "interlocking": {"platform_berths": False},
            "services": [
                {
                    "id": "x",
                    "from": "jiugongli",
                    "to": "bagongli",
                    "vehicle": "cq6",
                    "departures": {"times": [0, 20]},
                    "dwell_s": 20,
                }
            ],
        }
        path = tmp_path / f"{mode}.yaml"
        path.write_text(yaml.safe_dump(raw, sort_keys=False))
        res = run_railsim(["run", str(path), "--out", str(tmp_path / mode), "--no-progress"])
        assert res.returncode == 0, res.stderr[-2000:]
        s = read_summary(tmp_path / mode)
        assert s["collisions"] == 0 and s["n_arrived"] == 2 and s["n_stops_missed"] == 0
        running[mode] = s["mean_running_time_s"]["x"]
    assert running["rdbm"] < running["adbm"]  # the follower is held back less (runs closer) under RDBM
