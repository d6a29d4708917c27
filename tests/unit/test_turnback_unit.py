"""Turnbacks and rotations in SUMO: a unit reverses and runs its next trip.

Here: the tests of it that start no process; the others are in ``tests/sumo/test_turnback.py``.
"""

from __future__ import annotations

import yaml

from tests.helpers import DATA


def test_rotation_sections_that_are_wrong_say_which_field() -> None:
    from railsim.errors import ConfigError
    from railsim.scenario import from_mapping

    base = yaml.safe_load((DATA / "scenarios" / "mini_line.yaml").read_text(encoding="utf-8"))
    base["formations"] = []
    base["world"] = {"line": str(DATA / "lines" / "mini_y.yaml")}
    cases = {
        "nonsense": ("rotations", "'auto' or a mapping"),
        "{units: auto, turnback_min_s: -5}": ("rotations.turnback_min_s", "number >= 0"),
        "{units: {u1: [main_up.000, main_up.000]}}": ("rotations.units.u1[1]", "already run by unit"),
        "{units: {u1: [main_up.001, main_up.000]}}": ("rotations.units.u1[1]", "departs before"),
        "{units: {u1: [no_such_trip]}}": ("rotations.units.u1[0]", "expected a trip id"),
        "{unit: auto}": ("rotations.unit", "did you mean 'units'"),
    }
    for text, (field, words) in cases.items():
        raw = {**base, "rotations": yaml.safe_load(text)}
        try:
            from_mapping(raw, "scn.yaml")
        except ConfigError as err:
            assert err.field == field and words in err.message, (text, err.field, err.message)
        else:
            raise AssertionError(f"{text} was accepted")
    ok = from_mapping({**base, "rotations": "auto"}, "scn.yaml")
    assert ok.rotations is not None and ok.rotations.units is None and ok.rotations.turnback_min_at("a") == 120.0
