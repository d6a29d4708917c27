"""The junction planner online in SUMO: Table 3 scenario 1 on the ``y_junction`` world.

Here: the tests of it that start no process; the others are in ``tests/sumo/test_junction_engine.py``.
"""

from __future__ import annotations

import pytest


def test_switch_interval_reading_closed_form() -> None:
    """The planner's t_ls = release + throw + sighting (railsim.engine.extensions.junction_coordinator.readings)."""
    from controllers.junction.model import JunctionParams
    from railsim.engine.extensions.junction_coordinator.readings import switch_interval_s
    from railsim.engine.extensions.junction_coordinator.tracking import PlannedTrain
    from railsim.engine.settings import EngineSettings

    members = [PlannedTrain("a", {"sw2": 90.0}, {"sw2": "reverse"}, {"sw2": 100.0}, 300.0)]
    p = JunctionParams()
    got = switch_interval_s(EngineSettings(clearance_m=10.0, protection_margin_m=20.0), members, p, 10.0, 20.0)
    release = (10.0 + 20.0 + 10.0) / 10.0
    sighting = (15.0**2 / (2 * 1.2) + 20.0) / 15.0
    assert got == pytest.approx(release + 10.0 + sighting)
