"""Passenger-driven dwell (``disturbances.demand``, railsim/engine/passenger_dwell.py), checked in SUMO.

Here: the tests of it that run SUMO or a railsim child process; the others are in ``tests/unit/test_passenger_dwell.py``.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from tests.helpers import read_csv, read_summary, run_railsim
from tests.unit.test_passenger_dwell import SCENARIO, _scenario

DT_S = 0.5


C_S_PER_PAX = 0.5


RATE_PER_S = 1.0


def test_a_late_train_dwells_longer_by_the_passengers_it_finds(tmp_path: Path) -> None:
    res = run_railsim(["run", str(SCENARIO), "--out", str(tmp_path), "--no-progress"])
    assert res.returncode == 0, res.stderr
    delays = {(r["trip_id"], r["station"]): r for r in read_csv(tmp_path / "delays.csv")}
    events = read_csv(tmp_path / "events.csv")
    ext = {
        (e["subject"], json.loads(e["detail"])["station"]): json.loads(e["detail"])["extra_s"]
        for e in events
        if e["kind"] == "dwell_extended_demand"
    }
    assert set(ext) == {("a.001", "s2"), ("a.001", "s3")}  # the first train has no interval, the third is early

    def f(trip: str, station: str, key: str) -> float:
        return float(delays[(trip, station)][key])

    registered = {
        (e["subject"], json.loads(e["detail"])["station"]): float(e["t_s"])
        for e in events
        if e["kind"] == "stop_registered"
    }
    total = 0.0
    for station in ("s2", "s3"):
        actual = f("a.001", station, "arrival_s") - f("a.000", station, "departure_s")
        planned = f("a.001", station, "planned_arrival_s") - f("a.000", station, "planned_departure_s")
        expected = C_S_PER_PAX * RATE_PER_S * (actual - planned)
        assert expected > 25.0
        assert ext[("a.001", station)] == pytest.approx(expected, abs=1e-9)
        assert f("a.001", station, "dwell_demand_s") == pytest.approx(expected, abs=1e-9)
        # served: SUMO's 30 s dwell, then held for the extra boarding (to the next step)
        dwell = f("a.001", station, "departure_s") - registered[("a.001", station)]
        assert 30.0 + expected - 1e-9 <= dwell <= 30.0 + expected + DT_S
        total += expected
    # the delay feeds itself: the lateness at s3 includes s2's extension, and so does its extension
    assert ext[("a.001", "s3")] == pytest.approx(C_S_PER_PAX * (60.0 + ext[("a.001", "s2")]), abs=DT_S)
    # accounting: the extensions are the train's own (primary) delay; nothing is left as knock-on
    assert f("a.001", "s4", "primary_s") == pytest.approx(60.0 + total, abs=1e-9)
    assert abs(f("a.001", "s4", "secondary_s")) <= 2 * DT_S
    for station in ("s2", "s3"):  # closer than planned behind the late train: the planned dwell, not less
        assert f("a.002", station, "dwell_demand_s") == 0.0
        assert f("a.002", station, "departure_s") - registered[("a.002", station)] == pytest.approx(30.0, abs=DT_S)
    s = read_summary(tmp_path)
    assert s["disturbances"]["injected_demand_s"] == pytest.approx(total, abs=1e-9)
    assert s["disturbances"]["extra_passengers"] == pytest.approx(total / C_S_PER_PAX, abs=1e-9)
    res = run_railsim(["report", str(tmp_path)])
    assert res.returncode == 0, res.stderr
    line = f"| passenger demand: extra dwell [s] / extra passengers | {total:.0f} / {total / C_S_PER_PAX:.0f} |"
    assert line in (tmp_path / "report.md").read_text(encoding="utf-8")


def test_unknown_demand_station_is_exit_2(tmp_path: Path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(_scenario({"s_per_passenger": 0.5, "stations": {"s9": {"00:00": 5}}})))
    res = run_railsim(["run", str(path), "--out", str(tmp_path / "o"), "--no-progress"])
    assert res.returncode == 2 and "disturbances.demand.stations.s9" in res.stderr and "Traceback" not in res.stderr
