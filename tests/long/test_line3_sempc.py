"""SEMPC as every train's ATO on Chongqing Line 3, in a real SUMO run (child process).

A smaller slice than scenarios/chongqing_line3_sempc.yaml (one Airport unit each way and the coupled Jurenba
unit) to keep the suite fast: every stop served by SEMPC within ±0.3 m, 0 collisions, no fallbacks, and
end-to-end Yudong → T2 within the 90–100 min band of the published ≈ 94 min.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from tests.helpers import ROOT, read_csv, read_summary, run_railsim


def test_sempc_drives_line3_to_every_stop(tmp_path: Path) -> None:
    raw = yaml.safe_load((ROOT / "scenarios" / "chongqing_line3_sempc.yaml").read_text())
    for svc in raw["services"]:
        if svc["id"].startswith("airport"):
            svc["departures"] = {"times": ["07:30"]}
    raw["world"] = "chongqing_line3"
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False, allow_unicode=True))
    res = run_railsim(["run", str(path), "--out", str(tmp_path / "out"), "--no-progress"], timeout=900)
    assert res.returncode == 0, res.stderr[-2000:]
    s = read_summary(tmp_path / "out")
    assert s["collisions"] == 0 and s["sumo_collisions"] == 0 and s["fallbacks"] == 0
    assert s["n_arrived"] == s["n_trains"] == 4
    assert s["n_stops_served"] == s["n_stops_scheduled"] and s["n_stops_missed"] == 0
    assert s["max_stopping_error_m"] <= 0.3
    trips = read_csv(tmp_path / "out" / "trips.csv")
    up = next(r for r in trips if r["service"] == "airport_up")
    assert 90.0 <= float(up["travel_time_s"]) / 60.0 <= 100.0
    roles = {r["role"] for r in read_csv(tmp_path / "out" / "trace.csv") if r["train"] == up["trip_id"]}
    assert "ato" in roles  # the SEMPC ATO drove it
