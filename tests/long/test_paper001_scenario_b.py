"""Paper B's controllers on scenario B (compressed: three sections, two restrictions, dwell), the longest closed
loops of the Paper B checks (up to ~8 s of CPU each): the actuator envelope for every controller, and SEMPC's limits,
stops and sections. The same checks on the short scenarios A and C are in ``tests/unit/test_ato_mpc_limits.py`` and
``tests/unit/test_ato_mpc_closed_loop.py``.
"""

from __future__ import annotations

import pytest

import controllers.ato_mpc  # noqa: F401  (registers sempc, mpc, afsmc, pid_ato)
from controllers.ato_mpc.sim import run
from tests.unit.test_ato_mpc_closed_loop import _limits_hold
from tests.unit.test_ato_mpc_limits import CONTROLLERS, SCEN, check_envelope


@pytest.mark.parametrize("controller", CONTROLLERS)
def test_zero_force_and_rate_violations_on_scenario_b(controller: str) -> None:
    check_envelope("B", controller)


def test_sempc_multi_section_limits_and_stops() -> None:
    r = run(SCEN["B"](), "sempc")
    _limits_hold(r)
    assert len(r.stop_errors_m) == 3 and max(r.stop_errors_m) <= 0.3
    assert r.metrics["speed_limit_violations"] == 0
    assert [s["section"] for s in r.metrics["sections"]] == [1, 2, 3]
