"""Paper D's follower state machine drives in-operation decoupling in the engine (spec §3.2.4).

From the decelerated-tracking scenario (both followers couple at 5 m behind a 10 km/h lead): at t = 30 s the lead
accelerates to 50 km/h while the followers' cars are capped at 25 km/h, so the spacing opens. Once it exceeds
d_max (= max(2·d_c, d_c + 20 m) = 25 m) plus the 1 m band while opening, the state machine declares *passive*
decoupling and the engine sends the formation a decouple request; every state change is in events.csv.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from tests.helpers import ROOT, read_csv, run_railsim


def test_spacing_opening_past_d_max_triggers_passive_decoupling(tmp_path: Path) -> None:
    raw = yaml.safe_load((ROOT / "scenarios" / "paper003_track_decel.yaml").read_text())
    raw["vehicles"]["mc_slow"] = {"preset": "cq3_mc_empty", "max_speed_kmh": 25}
    for svc in raw["services"]:
        if svc["id"] != "L":
            svc["vehicle"] = "mc_slow"
    raw["controllers"]["lead"]["params"]["segments"] = [{"at_s": 30, "to_kmh": 50, "accel_mps2": 1.0}]
    raw["simulation"]["duration_s"] = 70
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    res = run_railsim(["run", str(path), "--out", str(tmp_path / "o"), "--no-progress"])
    assert res.returncode == 0, res.stderr[-2000:]
    ev = [
        (float(e["t_s"]), e["kind"], e["subject"], json.loads(e["detail"]))
        for e in read_csv(tmp_path / "o" / "events.csv")
    ]
    coupled = [t for t, k, sub, d in ev if k == "vc_state" and sub == "F1.000" and d["state"] == "coupled"]
    passive = [(t, d) for t, k, sub, d in ev if k == "passive_decoupling" and sub == "L_F1"]
    assert coupled and coupled[0] < 30.0
    assert passive and passive[0][0] > 30.0 and passive[0][1]["gap_m"] > 26.0
    requested = [t for t, k, sub, _ in ev if k == "decouple_requested" and sub == "L_F1"]
    assert requested and requested[0] == passive[0][0]
    assert not any(k == "collision" for _, k, _, _ in ev)


def test_monorail_drive_plant_applies_dead_time_and_lag_in_sumo(tmp_path: Path) -> None:
    """``plant: monorail``: a command reaches the drive after the 0.1 s dead time, then a 0.3 s first-order lag."""
    import math

    raw = yaml.safe_load((ROOT / "scenarios" / "paper003_track_decel.yaml").read_text())
    raw["simulation"]["step_method"] = "euler"
    raw["vehicles"]["mc"]["plant"] = "monorail"
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    res = run_railsim(["run", str(path), "--out", str(tmp_path / "o"), "--no-progress"])
    assert res.returncode == 0, res.stderr[-2000:]
    rows = {float(r["t_s"]): r for r in read_csv(tmp_path / "o" / "trace.csv") if r["train"] == "F1.000"}
    cmd0 = float(rows[0.1]["command_mps2"])  # the first command, issued at t = 0.1 s
    assert float(rows[0.1]["applied_accel_mps2"]) == 0.0 and float(rows[0.2]["applied_accel_mps2"]) == 0.0
    assert float(rows[0.3]["applied_accel_mps2"]) == pytest.approx(cmd0 * (1 - math.exp(-0.1 / 0.3)), abs=2e-6)
    forms = read_csv(tmp_path / "o" / "formations.csv")
    assert all(int(f["couple_successes"]) == 1 for f in forms)
    assert "collision" not in {e["kind"] for e in read_csv(tmp_path / "o" / "events.csv")}
