"""Role arbitration (:func:`controllers.base.arbitrate`): the minimum, and the additive role of Paper D's arrival case.

Spec 003 A27: in the arrival case the collision-avoidance braking comes "on the basis of normal deceleration
braking", i.e. it is added to the service command rather than competing with it in the minimum. The sum is bounded
by the brake envelope (the emergency deceleration); without an additive command arbitration is exactly the minimum
it always was (the golden runs pin that on whole scenarios).
"""

from __future__ import annotations

import math

import pytest
from hypothesis import given, strategies as st

from controllers.base import Command, arbitrate

ACCEL = st.floats(-3.0, 2.0, allow_nan=False)


@given(st.dictionaries(st.sampled_from(["ato", "separation", "coupled", "ca"]), ACCEL, min_size=1))
def test_without_additive_commands_the_minimum_wins(accels: dict[str, float]) -> None:
    cmds = {r: Command(a) for r, a in accels.items()}
    role, cmd = arbitrate(cmds, 1.2)
    assert cmd is cmds[role] and cmd.accel_mps2 == min(accels.values())


@given(ACCEL, ACCEL, st.floats(-3.0, 1.0, allow_nan=False), st.floats(0.5, 2.0))
def test_additive_braking_adds_and_stays_in_the_envelope(ato: float, sep: float, ca: float, envelope: float) -> None:
    role, cmd = arbitrate({"ato": Command(ato), "separation": Command(sep), "ca": Command(ca, additive=True)}, envelope)
    base = min(ato, sep)
    expected = min(base, max(base + min(ca, 0.0), -envelope))
    assert cmd.accel_mps2 == pytest.approx(expected)
    assert cmd.accel_mps2 <= base + 1e-12  # never less braking than the other roles ask for
    assert cmd.accel_mps2 >= min(base, -envelope) - 1e-12  # never beyond the envelope (unless the base already is)
    if expected < base:  # something was added
        assert role == "ca" and cmd.info["base_mps2"] == base and cmd.accel_mps2 < base
    else:
        assert role in ("ato", "separation") and cmd.accel_mps2 == base


def test_closed_form_cases() -> None:
    svc = {"ato": Command(-0.3)}
    assert arbitrate({**svc, "ca": Command(-0.5, additive=True)}, 1.2)[1].accel_mps2 == pytest.approx(-0.8)
    assert arbitrate({**svc, "ca": Command(-1.5, additive=True)}, 1.2)[1].accel_mps2 == pytest.approx(-1.2)
    assert arbitrate({**svc, "ca": Command(0.4, additive=True)}, 1.2) == ("ato", svc["ato"])  # adds nothing
    emergency = arbitrate({**svc, "ca": Command(-0.5, emergency=True, additive=True)}, 1.2)[1]
    assert emergency.emergency and emergency.info["base_role"] == "ato"


def test_a_broken_increment_surfaces_as_nan_and_nothing_to_add_to_is_an_error() -> None:
    _, cmd = arbitrate({"ato": Command(-0.3), "ca": Command(math.nan, additive=True)}, 1.2)
    assert math.isnan(cmd.accel_mps2)  # the engine's non-finite check then brakes and logs it
    with pytest.raises(ValueError, match="additive"):
        arbitrate({"ca": Command(-0.5, additive=True)}, 1.2)
