"""Passenger-driven dwell (``disturbances.demand``, railsim/engine/passenger_dwell.py), checked in SUMO.

Closed form: passengers arrive at r per second, each extra one costs c seconds of dwell, so a train whose platform
interval exceeds the planned one by L seconds dwells ``c·r·L`` longer. In tests/data/scenarios/
passenger_demand.yaml (r = 1/s, c = 0.5 s) the second train leaves its origin 60 s late: 30 s more at s2, and
then, later still at s3, 0.5·(60 + 30) more there — the delay feeds itself. The third train runs closer than
planned behind it and keeps its planned dwell. Every figure is recomputed from the run's own records.
"""

from __future__ import annotations

from typing import Any

import pytest
import yaml

from railsim import scenario as S
from railsim.errors import ConfigError
from railsim.scenario.disturbances import DemandSpec
from tests.helpers import ROOT

SCENARIO = ROOT / "tests" / "data" / "scenarios" / "passenger_demand.yaml"


def test_rate_table_holds_each_rate_until_the_next_clock_time() -> None:
    spec = DemandSpec(0.1, (("a", ((7 * 3600.0, 3600.0), (8.5 * 3600.0, 1800.0))),), ((6 * 3600.0, 600.0),))
    assert spec.rate_per_h("a", 7 * 3600.0 - 1.0) == 0.0  # before the first entry: no demand
    assert spec.rate_per_h("a", 7 * 3600.0) == 3600.0
    assert spec.rate_per_h("a", 8.5 * 3600.0 - 1e-6) == 3600.0
    assert spec.rate_per_h("a", 20 * 3600.0) == 1800.0
    assert spec.rate_per_h("b", 7 * 3600.0) == 600.0  # not listed: the default table


def _scenario(demand: Any) -> dict[str, Any]:
    data = yaml.safe_load(SCENARIO.read_text(encoding="utf-8"))
    data["disturbances"]["demand"] = demand
    return data


@pytest.mark.parametrize(
    "demand, field, message",
    [
        ({"stations": {"s2": {"00:00": 10}}}, "disturbances.demand.s_per_passenger", "missing required key"),
        ({"s_per_passenger": -1}, "disturbances.demand.s_per_passenger", "in [0, 60]"),
        ({"s_per_passenger": 0.5, "stations": {"s2": {"7:70": 10}}}, "disturbances.demand.stations.s2.7:70", "HH:MM"),
        ({"s_per_passenger": 0.5, "stations": {"s2": {420: 10}}}, "disturbances.demand.stations.s2.420", "quoted"),
        ({"s_per_passenger": 0.5, "stations": {"s2": {"07:00": float("nan")}}}, "s2.07:00", "finite"),
        ({"s_per_passenger": 0.5, "stations": {"s2": {}}}, "disturbances.demand.stations.s2", "a table"),
        ({"s_per_passenger": 0.5, "rate": 3}, "disturbances.demand.rate", "unknown key"),
    ],
)
def test_bad_demand_names_file_and_field(demand: Any, field: str, message: str) -> None:
    with pytest.raises(ConfigError) as info:
        S.from_mapping(_scenario(demand), source="line.yaml")
    text = str(info.value)
    assert text.startswith("line.yaml: ") and field in text and message in text, text
