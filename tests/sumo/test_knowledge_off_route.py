"""A train ahead whose last report has it off our track still separates us (railsim/engine/knowledge.py).

Found by the operating fuzz (:mod:`tests.fuzz_runs`, variants 33 and 35): during a t2g outage the ground's last
report of the train directly ahead placed it on track the follower's route does not use — still on the branch short
of the merge, or short of the station where the follower's route begins. The frame change found no part of it on our
track, the separation role got no predecessor and dropped out, and the follower ran on its ATO alone into the train
ahead (951 and 3 collision events). Now such a train is known standing where its route joins ours (nothing of it on
our track can be behind that point): the follower holds or brakes until a report places it.

Both cases are built on the mini line and run in SUMO; each fails on the code before the fix.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from tests.helpers import mini_line, read_csv, read_summary, run_mapping


def _two_services(services: list[dict[str, Any]], outage_s: tuple[float, float]) -> dict[str, Any]:
    d = mini_line()
    d.pop("formations")
    d["services"] = services
    d["faults"]["comm"]["t2g"]["outages"] = [{"start_s": outage_s[0], "end_s": outage_s[1]}]
    return d


def test_follower_starting_behind_a_train_last_heard_before_its_route_begins(tmp_path: Path) -> None:
    """br_up starts at b behind main_up, whose last report (before the outage at 50 s) has it short of b."""
    d = _two_services(
        [
            {"id": "main_up", "from": "a", "to": "e", "vehicle": "cq6", "departures": {"times": [0]}, "dwell_s": 5},
            {"id": "br_up", "from": "b", "to": "g", "vehicle": "cq6", "departures": {"times": [120]}, "dwell_s": 20},
        ],
        (50.0, 350.0),
    )
    d["simulation"].update({"step_s": 2.0, "step_method": "ballistic"})
    d["outputs"]["trace_stride_s"] = 2.0
    d["vehicles"]["cq6"]["length_m"] = 200.0
    proc, out = run_mapping(tmp_path, d)
    assert proc.returncode == 0, proc.stderr[-2000:]
    s = read_summary(out)
    assert s["collisions"] == 0 and s["n_arrived"] == s["n_trains"] == 2
    follower = [r for r in read_csv(out / "trace.csv") if r["train"] == "br_up.000"]
    in_outage = [r for r in follower if 150.0 <= float(r["t_s"]) <= 240.0 and r["gap_m"]]
    assert in_outage and all(r["role"] == "separation" for r in in_outage)  # held on what the ground knows
    assert all(float(r["speed_mps"]) == 0.0 for r in in_outage)


def test_train_behind_a_merge_while_the_merged_train_was_last_heard_on_the_branch(tmp_path: Path) -> None:
    """main_down, held at d, follows branch trains that merged ahead of it while the ground heard nothing."""
    d = _two_services(
        [
            {"id": "main_down", "from": "e", "to": "a", "vehicle": "cq6", "departures": {"times": [30]}, "dwell_s": 5},
            {
                "id": "br_down",
                "from": "g",
                "to": "a",
                "vehicle": "cq6",
                "departures": {"times": [0, 30, 60, 90]},
                "dwell_s": 20,
            },
        ],
        (300.0, 600.0),
    )
    d["disturbances"] = {"incidents": [{"trip": "main_down.000", "station": "d", "hold_s": 200}]}
    proc, out = run_mapping(tmp_path, d)
    assert proc.returncode == 0, proc.stderr[-2000:]
    s = read_summary(out)
    assert s["collisions"] == 0 and s["n_arrived"] == s["n_trains"] == 5
