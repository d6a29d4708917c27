"""Line descriptions: validation messages a user sees, and the CLI's one-line errors (exit code 2)."""

from __future__ import annotations

import copy
import os
from pathlib import Path
from typing import Any

import pytest
import yaml

from network.line import parse_description
from railsim.errors import ConfigError

GOOD: dict[str, Any] = {
    "name": "mini",
    "line_speed_kmh": 80,
    "platform_length_m": 150,
    "stations": [
        {"id": "a", "km": 0.0, "turnback": True},
        {"id": "b", "km": 1.5},
        {"id": "c", "km": 3.0},
        {"id": "d", "km": 4.2, "turnback": True},
    ],
    "branches": [
        {
            "id": "spur",
            "joins": "main",
            "at_km": 3.4,
            "side": "up",
            "switches": {
                "up": {"id": "j_up", "throw_time_s": 8, "diverging_speed_kmh": 30},
                "down": {"id": "j_down", "throw_time_s": 8, "diverging_speed_kmh": 30},
            },
            "stations": [{"id": "e", "km": 5.0}],
        },
    ],
}


def _bad(mutate) -> dict[str, Any]:
    d = copy.deepcopy(GOOD)
    mutate(d)
    return d


# (name, mutation, field, message)
BAD_CASES = [
    (
        "missing_station_id",
        lambda d: d["stations"][3].pop("id"),
        "stations[3].id",
        "expected an id of letters, digits, '_' or '-', got nothing (required key is missing)",
    ),
    (
        "decreasing_chainage",
        lambda d: d["stations"][2].update(km=1.2),
        "stations[2].km",
        "expected a chainage greater than stations[1].km (1.5), got 1.2",
    ),
    (
        "unknown_branch_target",
        lambda d: d["branches"][0].update(joins="mian"),
        "branches[0].joins",
        "expected one of main, got 'mian'",
    ),
    (
        "negative_length",
        lambda d: d["stations"][1].update(platform_length_m=-150),
        "stations[1].platform_length_m",
        "expected a number > 0, got -150",
    ),
    (
        "unknown_key",
        lambda d: d["stations"][0].update(colour="red"),
        "stations[0].colour",
        "expected one of id, name, km, platform_length_m, turnback, pocket, basis, name_zh, got unknown key 'colour'",
    ),
    ("wrong_type", lambda d: d.update(line_speed_kmh="fast"), "line_speed_kmh", "expected a number > 0, got 'fast'"),
    (
        "bool_is_not_a_number",
        lambda d: d["stations"][0].update(km=True),
        "stations[0].km",
        "expected a number, got True",
    ),
    (
        "overlapping_platforms",
        lambda d: d["stations"][1].update(km=0.1),
        "stations[1].km",
        "expected platforms not to overlap: b starts 50.0 m before the end of a's platform, got km 0.1",
    ),
    (
        "duplicate_station",
        lambda d: d["branches"][0]["stations"][0].update(id="b"),
        "branches[0].stations[0].id",
        "expected a unique station id, got 'b' (already used at stations[1])",
    ),
    (
        "junction_outside_line",
        lambda d: d["branches"][0].update(at_km=9.0),
        "branches[0].at_km",
        "expected a chainage inside line 'main' (-0.224 < km < 4.424), got 9.0",
    ),
    (
        "missing_switch",
        lambda d: d["branches"][0]["switches"].pop("down"),
        "branches[0].switches.down",
        "expected a switch mapping, got nothing (required key is missing)",
    ),
    (
        "bad_side",
        lambda d: d["branches"][0].update(side="left"),
        "branches[0].side",
        "expected one of up, down, got 'left'",
    ),
]


@pytest.mark.parametrize("name,mutate,field,message", BAD_CASES, ids=[c[0] for c in BAD_CASES])
def test_bad_description_names_field_and_expectation(name, mutate, field, message) -> None:
    with pytest.raises(ConfigError) as info:
        parse_description(_bad(mutate), "bad.yaml")
    assert info.value.field == field
    assert info.value.message == message
    assert str(info.value) == f"bad.yaml: {field}: {message}"


def test_good_description_parses() -> None:
    d = parse_description(GOOD, "good.yaml")
    assert [s.id for s in d.stations] == ["a", "b", "c", "d"]
    assert d.from_km == pytest.approx(-0.275)  # first platform start (75 m) + default overrun 200 m
    assert d.branches[0].from_km == 3.4 and d.branches[0].to_km == pytest.approx(5.275)
    assert d.branches[0].end_name == "e" and d.end_name == "d"


def test_speed_limit_boundary_inside_platform_is_rejected(tmp_path: Path) -> None:
    import network

    os.environ["RAILSIM_CACHE"] = str(tmp_path / "cache")
    desc = _bad(lambda d: d.update(speed_limits=[{"from_km": 1.45, "to_km": 2.0, "speed_kmh": 40}]))
    path = tmp_path / "limit.yaml"
    path.write_text(yaml.safe_dump(desc))
    with pytest.raises(ConfigError) as info:
        network.build(path)
    assert str(info.value) == (
        f"{path}: speed_limits[0].from_km: expected an edge break outside the platform "
        "of b (km 1.5 +/- 75 m), got km 1.45"
    )
