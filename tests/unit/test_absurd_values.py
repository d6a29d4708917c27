"""Values a scenario or a sweep may not hold because no railway has them, refused naming file and field."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from railsim import scenario
from railsim.errors import ConfigError
from tests.helpers import DATA


def _load(tmp_path: Path, edit) -> None:
    data = yaml.safe_load((DATA / "scenarios" / "disturbed_line.yaml").read_text(encoding="utf-8"))
    edit(data)
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    scenario.load(path)


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (lambda d: d.update(interlocking={"overlap_m": 1e6}), "interlocking.overlap_m"),
        (lambda d: d["disturbances"].update(running_time={"low": 1e-9, "high": 1.0}), "disturbances.running_time.low"),
    ],
)
def test_absurd_values_are_refused(tmp_path: Path, edit, field: str) -> None:
    with pytest.raises(ConfigError) as err:
        _load(tmp_path, edit)
    assert err.value.field == field, str(err.value)


def test_turnback_minimum_at_an_unknown_station_is_refused_by_the_world_check(tmp_path: Path) -> None:
    data = yaml.safe_load((DATA / "scenarios" / "disturbed_line.yaml").read_text(encoding="utf-8"))
    data["rotations"] = {"units": "auto", "turnback_min_by_station": {"nowhere": 300}}
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    scn = scenario.load(path)
    with pytest.raises(ConfigError) as err:
        scenario.check_against_world(scn, ["s1", "s2", "s3", "s4"], [])
    assert err.value.field == "rotations.turnback_min_by_station.nowhere"
