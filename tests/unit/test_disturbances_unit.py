"""Primary delays (``disturbances:``), their injection, and the primary/secondary split of ``delays.csv``.

Here: the tests of it that start no process; the others are in ``tests/sumo/test_disturbances.py``.
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
import pytest

from railsim import scenario as S
from railsim.errors import ConfigError
from railsim.scenario.disturbances import DelayDist
from tests.sumo.test_disturbances import _with


def test_draws_follow_their_distributions() -> None:
    rng = np.random.default_rng(1)
    n = 20_000
    exp = np.array([DelayDist("exponential", mean_s=20.0).draw(rng) for _ in range(n)])
    assert abs(exp.mean() - 20.0) < 0.6 and exp.min() >= 0.0
    logn = np.array([DelayDist("lognormal", mean_s=10.0, sd_s=5.0).draw(rng) for _ in range(n)])
    assert abs(logn.mean() - 10.0) < 0.2 and abs(logn.std() - 5.0) < 0.3
    emp = np.array([DelayDist("empirical", values_s=(0.0, 30.0), weights=(3.0, 1.0)).draw(rng) for _ in range(n)])
    assert set(np.unique(emp)) == {0.0, 30.0} and abs((emp == 30.0).mean() - 0.25) < 0.015


@pytest.mark.parametrize(
    ("section", "field", "message"),
    [
        ({"intensity": -1}, "disturbances.intensity", "expected a number in [0, 100]"),
        ({"intensity": float("nan")}, "disturbances.intensity", "finite"),
        ({"dwell": [{"dist": "gamma", "mean_s": 3}]}, "disturbances.dwell[0].dist", "expected one of"),
        ({"dwell": [{"dist": "lognormal", "mean_s": 3}]}, "disturbances.dwell[0].sd_s", "missing required key"),
        ({"dwell": [{"dist": "exponential", "mean_s": float("inf")}]}, "disturbances.dwell[0].mean_s", "finite"),
        ({"dwell": [{"dist": "exponential", "mean_s": 3, "prob": 1.5}]}, "disturbances.dwell[0].prob", "in [0, 1]"),
        ({"dwell": [{"dist": "exponential", "mean_s": 3, "sd_s": 1}]}, "disturbances.dwell[0].sd_s", "not a param"),
        (
            {"dwell": [{"dist": "empirical", "values_s": [1, 2], "weights": [1]}]},
            "disturbances.dwell[0].weights",
            "a list of 2 weights",
        ),
        (
            {"departure": [{"dist": "constant", "value_s": 5, "services": ["b"]}]},
            "disturbances.departure[0].services[0]",
            "expected a service id",
        ),
        ({"running_time": {"low": 0.0}}, "disturbances.running_time.low", "in [0.5, 1]"),
        ({"running_time": {"low": 0.9, "high": 1.2}}, "disturbances.running_time.high", "in [0.9, 1]"),
        ({"incidents": [{"trip": "a.009", "station": "s2", "hold_s": 5}]}, "disturbances.incidents[0].trip", ""),
        ({"incidents": [{"hold_s": 5}]}, "disturbances.incidents[0].rate_per_h", "missing required key"),
        ({"dwell": [{"dist": "exponential", "mean_s": 3, "from_s": 50, "until_s": 10}]}, "until_s", ">= 50"),
    ],
)
def test_bad_values_name_file_and_field(section: Any, field: str, message: str) -> None:
    with pytest.raises(ConfigError) as info:
        S.from_mapping(_with(section), source="line.yaml")
    text = str(info.value)
    assert text.startswith("line.yaml: ") and field in text and message in text, text


def test_resolved_section_loads_back_unchanged() -> None:
    section = {
        "dwell": [{"dist": "empirical", "values_s": [0, 10], "stations": ["s2"], "until_s": 600}],
        "departure": [{"dist": "constant", "value_s": 5, "services": ["a"]}],
        "running_time": {"low": 0.9},
        "incidents": [{"trip": "a.001", "station": "s3", "hold_s": 60}, {"rate_per_h": 1, "hold_s": 30}],
    }
    scn = S.from_mapping(_with(section), source="line.yaml")
    again = S.from_mapping(copy.deepcopy(scn.raw), source="line.yaml")
    assert again.raw == scn.raw and again.disturbances == scn.disturbances
    assert scn.raw["disturbances"]["running_time"] == {"low": 0.9, "high": 1.0, "services": []}


def test_station_order_is_the_line_order_not_the_alphabet() -> None:
    import pandas as pd

    from railsim.analysis.punctuality import kpis
    from railsim.studies.robustness import station_order

    rows = [
        ("t1", st, t, t - 10.0 * k) for k, (st, t) in enumerate([("zeta", 100.0), ("alpha", 200.0), ("mid", 300.0)])
    ]
    rows += [("t2", "alpha", 260.0, 250.0)]
    frame = pd.DataFrame(
        [
            {
                "trip_id": tid,
                "station": st,
                "arrival_s": t,
                "arrival_delay_s": t - p,
                "primary_s": 0.0,
                "secondary_s": t - p,
                "missed": False,
            }
            for tid, st, t, p in rows
        ]
    )
    out = kpis(frame)
    assert out["station_order"] == "zeta,alpha,mid" and list(out["by_station"]) == ["zeta", "alpha", "mid"]
    flat = {f"robustness.by_station.{s}": v for s, v in sorted(out["by_station"].items())}
    assert station_order({**flat, "robustness.station_order": out["station_order"]}) == ["zeta", "alpha", "mid"]
