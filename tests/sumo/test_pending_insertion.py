"""A train handed to SUMO but not yet put on is withdrawn when a train approaching from behind could not stop for it.

SUMO fills a spot it was given only once the spot is free — possibly minutes later, when the line has changed.
Found by the operating fuzz (:mod:`tests.fuzz_runs`, variant 275, mini line): a follower handed over 5 m behind its
standing leader at b (coupling on departure, platform berths off) waited 330 s in SUMO's queue and appeared 12 m in
front of a train approaching at 24 km/h — emergency brake, then a collision. ``Dispatcher.guard_pending`` now checks
every standing train in SUMO's queue each step with the rule of a standing departure (the approaching train must
be able to stop with its service brake, after a reaction time, with the insertion margin to spare); one that fails
it is withdrawn (``train_withdrawn``) and its departure held and retried from its origin.
"""

from __future__ import annotations

from pathlib import Path

from tests.helpers import mini_line, read_csv, read_summary, run_mapping


def _variant_275() -> dict:
    d = mini_line()
    d["simulation"].update({"step_s": 0.1, "seed": 570, "step_method": "ballistic", "duration_s": 2400})
    d["vehicles"]["cq6"]["max_speed_kmh"] = 120
    d["controllers"]["ato"]["params"] = {"speed_margin_mps": 0.0, "authority_margin_m": 20.0}
    d["services"] = [
        {"id": "main_up", "from": "a", "to": "e", "vehicle": "cq6", "departures": {"times": [30, 90, 150, 210]},
         "dwell_s": 300},
        {"id": "br_up", "from": "b", "to": "g", "vehicle": "cq6", "departures": {"times": [120]}, "dwell_s": 60},
        {"id": "main_down", "from": "e", "to": "a", "vehicle": "cq6", "departures": {"times": [30, 150]},
         "dwell_s": 20},
        {"id": "br_down", "from": "g", "to": "a", "vehicle": "cq6", "departures": {"times": [60]}, "dwell_s": 60},
    ]  # fmt: skip
    d["formations"][0]["target_gap_m"] = 5
    d["disturbances"] = {"incidents": [{"trip": "main_up.000", "station": "c", "hold_s": 30}]}
    d["interlocking"] = {"platform_berths": False}
    return d


def test_a_queued_follower_is_withdrawn_rather_than_put_on_in_front_of_an_approaching_train(tmp_path: Path) -> None:
    proc, out = run_mapping(tmp_path, _variant_275())
    assert proc.returncode == 0, proc.stderr[-2000:]
    s = read_summary(out)
    assert s["collisions"] == 0 and s["sumo_collisions"] == 0 and s["n_never_inserted"] == 0
    events = read_csv(out / "events.csv")
    withdrawn = [e for e in events if e["kind"] == "train_withdrawn"]
    assert [e["subject"] for e in withdrawn] == ["br_up.000"]
    # put on later, once the line behind it was clear: inserted again after the withdrawal, and it ran
    inserted = [float(e["t_s"]) for e in events if e["kind"] == "train_inserted" and e["subject"] == "br_up.000"]
    assert len(inserted) == 2 and inserted[1] > float(withdrawn[0]["t_s"])
    assert any(e["kind"] == "stop_registered" and e["subject"] == "br_up.000" for e in events)
    # the train it was withdrawn for never had to brake in emergency for a train appearing in front of it
    approaching = withdrawn[0]["detail"]
    assert "main_up.003" in approaching
    assert not [e for e in events if e["kind"] == "emergency_brake_on" and e["subject"] == "main_up.003"]
