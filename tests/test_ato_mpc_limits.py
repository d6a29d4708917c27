"""Every Paper B controller respects the same actuator envelope (issue #19): 0 force and 0 force-rate (60 kN/s)
violations over scenarios A, B (compressed), C-constant and C-harmonic in the numpy runner."""

from __future__ import annotations

import pytest

from controllers.ato_mpc.reference import Limit
from controllers.ato_mpc.sim import run, scenario_a, scenario_b, scenario_c


def _b_short():
    sc = scenario_b(dwell_s=3.0, line_speed_mps=25.0)
    return type(sc)(
        **{
            **sc.__dict__,
            "stops_m": (800.0, 1500.0, 2100.0),
            "limits": (Limit(300.0, 500.0, 12.0), Limit(1700.0, 1850.0, 10.0)),
        }
    )


SCEN = {
    "A": lambda: scenario_a(1500.0),
    "B": _b_short,
    "C-constant": lambda: scenario_c("constant", 1500.0),
    "C-harmonic": lambda: scenario_c("harmonic", 1500.0),
}


@pytest.mark.parametrize("scenario", list(SCEN))
@pytest.mark.parametrize("controller", ["sempc", "mpc", "afsmc", "pid"])
def test_zero_force_and_rate_violations(controller: str, scenario: str) -> None:
    m = run(SCEN[scenario](), controller).metrics
    assert m["rate_violations"] == 0 and m["force_violations"] == 0, m["max_force_rate_n_per_s"]


def test_afsmc_without_the_limiter_breaks_the_rate_limit() -> None:
    """The check can fail: the old force-box-only AFSMC violates the 60 kN/s limit on the same scenario."""
    m = run(SCEN["A"](), "afsmc", law_overrides={"rate_limited": False}).metrics
    assert m["rate_violations"] > 0
