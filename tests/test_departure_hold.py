"""A departure that would put a train in front of one approaching too fast to stop waits (engine dispatcher).

Found by the Line 3 headway study: at a 75 s headway a branch unit was inserted at Liugongli right in front of an
Airport train approaching at 17 m/s, which could not stop. Now the insertion waits until every train behind on
shared track could stop short of the new train's rear (service braking + 1 s + 50 m), and ``departure_held`` is
logged once.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.helpers import ROOT, read_csv, read_summary, run_railsim

pytestmark = pytest.mark.sumo

SCENARIO = ROOT / "tests" / "data" / "scenarios" / "departure_hold.yaml"


def test_departure_waits_for_the_approaching_train(tmp_path: Path) -> None:
    res = run_railsim(["run", str(SCENARIO), "--out", str(tmp_path), "--no-progress"])
    assert res.returncode == 0, res.stderr
    s = read_summary(tmp_path)
    assert s["collisions"] == 0 and s["sumo_collisions"] == 0 and s["n_arrived"] == 2
    events = read_csv(tmp_path / "events.csv")
    held = [e for e in events if e["kind"] == "departure_held"]
    assert len(held) == 1 and held[0]["subject"] == "b.000" and "a.000" in held[0]["detail"]
    departed = {e["subject"]: float(e["t_s"]) for e in events if e["kind"] == "train_departed"}
    assert departed["b.000"] > float(held[0]["t_s"]) >= 260.0
    # B left only once A's front was past s2 (km 5, ~5000 m along A's route): nobody was behind B any more
    trace = read_csv(tmp_path / "trace.csv")
    a_at = sorted((float(r["t_s"]), float(r["chainage_m"])) for r in trace if r["train"] == "a.000")
    a_front_at_b_departure = next(x for t, x in a_at if t >= departed["b.000"] - 1e-9)
    assert a_front_at_b_departure > 5000.0
    assert s["min_gap_m"] is not None and s["min_gap_m"] > 0.0
