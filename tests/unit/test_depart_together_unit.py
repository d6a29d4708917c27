"""A formation that departs together (``formations[].depart_together: true``) leaves every station both units
serve as one: the leader waits for its coupled follower's dwell there, at most one coupling timeout.

Here: the tests of it that start no process; the others are in ``tests/sumo/test_depart_together.py``.
"""

from __future__ import annotations

import pytest
import yaml

from railsim import scenario as S
from railsim.errors import ConfigError
from tests.sumo.test_depart_together import DATA


def test_depart_together_is_true_or_false_and_listed_only_when_set() -> None:
    data = yaml.safe_load((DATA / "scenarios" / "mini_line.yaml").read_text(encoding="utf-8"))
    data["world"] = {"line": str(DATA / "lines" / "mini_y.yaml")}
    assert S.from_mapping(data, source="m.yaml").formations[0].depart_together is False
    data["formations"][0]["depart_together"] = True
    assert S.from_mapping(data, source="m.yaml").formations[0].depart_together is True
    data["formations"][0]["depart_together"] = "yes"
    with pytest.raises(ConfigError) as info:
        S.from_mapping(data, source="m.yaml")
    assert "m.yaml: formations[0].depart_together: expected true or false" in str(info.value)
