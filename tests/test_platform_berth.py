"""Platform berths (railsim/engine/platforms.py): a train does not run into a platform another train occupies.

tests/data/scenarios/platform_berth.yaml: a 400 m platform, two 6-car units 90 s apart, both dwelling 200 s at
s2. The second arrives while the first stands there. Before the rule it closed up to its 50 m separation margin
behind the first unit's rear — inside the platform's stopping window — halted, and SUMO served its stop 141 m
short of the mark. Now it waits the overlap before the platform, then runs in to its mark.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.helpers import ROOT, read_csv, read_summary, run_railsim


SCENARIO = ROOT / "tests" / "data" / "scenarios" / "platform_berth.yaml"
PLATFORM_M = 400.0
OVERLAP_M = 20.0
TRAIN_M_AT_MOST = 130.0  # the cq3_6car is shorter than this


@pytest.mark.sumo
def test_follower_waits_before_an_occupied_platform_and_stops_at_its_mark(tmp_path: Path) -> None:
    res = run_railsim(["run", str(SCENARIO), "--out", str(tmp_path), "--no-progress"])
    assert res.returncode == 0, res.stderr
    s = read_summary(tmp_path)
    assert s["collisions"] == 0 and s["n_arrived"] == 2 and s["n_stops_served"] == s["n_stops_scheduled"]
    stops = {(r["trip_id"], r["station"]): r for r in read_csv(tmp_path / "stops.csv")}
    assert abs(float(stops[("a.001", "s2")]["stopping_error_m"])) < 0.01  # served at its mark, not short
    events = read_csv(tmp_path / "events.csv")
    waits = [e for e in events if e["kind"] == "platform_occupied"]
    assert len(waits) == 1 and waits[0]["subject"] == "a.001" and '"by":"a.000"' in waits[0]["detail"]
    a_left_s = next(float(e["t_s"]) for e in events if e["kind"] == "stop_departed" and e["subject"] == "a.000")
    assert float(stops[("a.001", "s2")]["arrival_s"]) > a_left_s  # it came in only once the platform was clear
    # while the first unit stood at s2, the second stayed behind the platform's start (less the overlap): its gap
    # to the first unit's rear was at least the free platform length plus the overlap (~300 m, not 50 m)
    trace = read_csv(tmp_path / "trace.csv")
    gaps = [float(r["gap_m"]) for r in trace if r["train"] == "a.001" and r["gap_m"] and float(r["t_s"]) < a_left_s]
    assert gaps and min(gaps) > PLATFORM_M + OVERLAP_M - TRAIN_M_AT_MOST - 10.0


def test_platform_berths_is_a_yes_or_no_knob() -> None:
    import yaml

    from railsim import scenario as S
    from railsim.errors import ConfigError

    data = yaml.safe_load(SCENARIO.read_text(encoding="utf-8"))
    assert S.from_mapping(data, source="b.yaml").interlocking.platform_berths is True
    data["interlocking"] = {"platform_berths": "yes"}
    with pytest.raises(ConfigError) as info:
        S.from_mapping(data, source="b.yaml")
    assert "b.yaml: interlocking.platform_berths: expected true or false" in str(info.value)
