"""A follower that couples on departure is put on behind its standing leader — never faster than the leader.

Found by fuzzing the mini line (real SUMO): ``br_up`` with ``start: {offset_m: 500, speed_kmh: 60}`` and a formation
that couples it on departure behind ``main_up.001``. The dispatcher puts a follower on at its target gap behind its
leader's rear (the start offset does not apply), but it kept the start speed: 16.7 m/s, 30 m behind a standing
train — 739 collisions (SUMO's and ours), the follower 79.5 m into its leader. Now the speed is limited to the
leader's (a ``start_speed_limited`` event).
"""

from __future__ import annotations

from pathlib import Path

from tests.helpers import mini_line, read_csv, read_summary, run_mapping


def test_a_follower_started_in_motion_behind_a_standing_leader_starts_at_its_speed(tmp_path: Path) -> None:
    data = mini_line()
    follower = next(s for s in data["services"] if s["id"] == "br_up")
    follower["start"] = {"offset_m": 500, "speed_kmh": 60}
    res, out = run_mapping(tmp_path, data, "start")
    assert res.returncode == 0, res.stderr
    s = read_summary(out)
    assert s["collisions"] == 0 and s["min_gap_m"] > 0.0 and s["n_arrived"] == s["n_trains"]
    limited = [e for e in read_csv(out / "events.csv") if e["kind"] == "start_speed_limited"]
    assert len(limited) == 1 and limited[0]["subject"] == "br_up.000"
    assert '"speed_mps":0.0' in limited[0]["detail"] and '"leader":"main_up.001"' in limited[0]["detail"]
    first = next(r for r in read_csv(out / "trace.csv") if r["train"] == "br_up.000")
    assert float(first["speed_mps"]) < 1.0  # it started from a standstill behind its leader


def test_a_follower_is_not_put_on_in_front_of_a_train_that_could_not_stop_for_it(tmp_path: Path) -> None:
    """Found by fuzzing: with platform berths off, ``main_up.002`` runs into B behind the standing leader
    ``main_up.001``; the follower put on 5 m behind the leader stood in its way, and it ran into it (138
    collisions). Now the follower waits while a train approaching from behind could not stop for it, and gets on
    once it could (here 4 s later)."""
    data = mini_line()
    data["simulation"].update(step_s=0.5, step_method="forward", seed=846)
    for svc in data["services"]:
        svc["dwell_s"] = 20 if svc["id"] == "br_up" else 60
        svc["departures"] = {
            "times": {"main_up": [0, 60, 120], "br_up": [30], "main_down": [30, 150]}.get(svc["id"], [60])
        }
    data["formations"][0].update(target_gap_m=5, depart_together=True)
    data["interlocking"] = {"platform_berths": False}
    res, out = run_mapping(tmp_path, data, "behind")
    s = read_summary(out)
    assert s["collisions"] == 0 and s["sumo_collisions"] == 0
    held = [e for e in read_csv(out / "events.csv") if e["kind"] == "departure_held" and e["subject"] == "br_up.000"]
    assert held and "approaching train main_up.002 could not stop" in held[0]["detail"]
    assert res.returncode == 0, res.stderr
    assert s["n_arrived"] == s["n_trains"] == 7
