"""Platform berths (railsim/engine/platforms.py): a train does not run into a platform another train occupies.

Here: the tests of it that start no process; the others are in ``tests/sumo/test_platform_berth.py``.
"""

from __future__ import annotations

import pytest
import yaml

from tests.sumo.test_platform_berth import SCENARIO


def test_platform_berths_is_a_yes_or_no_knob_on_by_default() -> None:
    from railsim import scenario as S
    from railsim.engine.settings import EngineSettings
    from railsim.errors import ConfigError

    data = yaml.safe_load(SCENARIO.read_text(encoding="utf-8"))
    spec = S.from_mapping(data, source="b.yaml").interlocking
    assert spec.platform_berths is None and EngineSettings().with_interlocking(spec).platform_berths is True
    data["interlocking"] = {"platform_berths": False}
    off = S.from_mapping(data, source="b.yaml").interlocking
    assert EngineSettings().with_interlocking(off).platform_berths is False
    data["interlocking"] = {"platform_berths": "yes"}
    with pytest.raises(ConfigError) as info:
        S.from_mapping(data, source="b.yaml")
    assert "b.yaml: interlocking.platform_berths: expected true or false" in str(info.value)
