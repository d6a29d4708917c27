"""Depot runs in SUMO: a unit leaves a depot, runs its day and returns.

Here: the tests of it that start no process; the others are in ``tests/sumo/test_depot.py``.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from tests.helpers import DATA


def test_depot_entries_that_are_wrong_say_which_field(tmp_path: Path) -> None:
    from network.line import parse_description
    from railsim.errors import ConfigError

    base = yaml.safe_load((DATA / "lines" / "mini_y.yaml").read_text(encoding="utf-8"))
    cases = {
        "[{id: y, between: [a, c]}]": ("depots[0].between", "adjacent"),
        "[{id: b, between: [a, b]}]": ("depots[0].id", "not used by a station"),
        "[{id: y, km: 1.5}]": ("depots[0]", "platform"),  # inside B's platform
        "[{id: y, between: [a, b], km: 1.0}]": ("depots[0].km", "either between or km"),
        "[{id: y, line: nope, km: 1.0}]": ("depots[0].line", "expected one of"),
    }
    for text, (field, words) in cases.items():
        raw = {**base, "depots": yaml.safe_load(text)}
        with pytest.raises(ConfigError) as err:
            if "km: 1.5" in text:  # a break point inside a platform is the generator's check
                from network.generator import _Plan

                _Plan(parse_description(raw, "line.yaml"))
            else:
                parse_description(raw, "line.yaml")
        assert field in str(err.value) and words in str(err.value), (text, str(err.value))
