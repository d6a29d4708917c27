"""CACC gap policy: at standstill the configured gap, at speed the relative braking distance it must keep.

The ``safe`` policy tracks ``max(target, G(v) + buffer)`` with ``G(v) = S_f(v, a0=R(v)/m) − v²/(2·b_p) + margin + v·age``,
the steady-state gap at which the controller's own relative-braking-distance barrier is exactly zero. These
tests pin the closed form and show that at that gap, at equal speeds, the controller neither brakes for safety
nor tries to close in.
"""

from __future__ import annotations

import math

import pytest

from controllers.base import Observation, OwnState, PredecessorState
from controllers.braking import net_braking_mps2, stopping_distance_m
from controllers.cacc import make_cacc
from railsim.physics.vehicle import preset

VEH = preset("cq3_6car")
DT = 0.5


def _obs(v: float, gap_m: float, age_s: float, target: float = 30.0) -> Observation:
    cruise = VEH.resistance_n(v) / VEH.effective_mass_kg  # applied acceleration that holds speed v
    own = OwnState("f", 1000.0, v, cruise, VEH.length_m)
    pred = PredecessorState(
        "l",
        1000.0 + gap_m + VEH.length_m - v * age_s,
        v,
        cruise,
        VEH.length_m,
        stamp_s=100.0 - age_s,
        age_s=age_s,
        service_decel_mps2=VEH.service_decel_mps2,
        emergency_decel_mps2=VEH.emergency_decel_mps2,
    )
    return Observation(
        t_s=100.0,
        dt_s=DT,
        own=own,
        vehicle=VEH,
        route_length_m=1e5,
        predecessor=pred,
        formation_state="coupled",
        target_gap_m=target,
    )


def _steady_gap(v: float, age_s: float, margin: float = 10.0) -> float:
    b_f = net_braking_mps2(VEH, VEH.emergency_decel_mps2, 0.0, davis_speed_mps=0.0)
    b_p = VEH.emergency_decel_mps2 + VEH.resistance_n(v, 0.0) / VEH.effective_mass_kg
    delay = VEH.actuator_time_constant_s + DT
    a_cruise = VEH.resistance_n(v) / VEH.effective_mass_kg
    return stopping_distance_m(v, b_f, delay, a_cruise) - v * v / (2 * b_p) + margin + v * age_s


@pytest.mark.parametrize("v", [0.0, 5.0, 12.0, 19.4])
@pytest.mark.parametrize("age", [0.2, 0.7])
def test_safe_policy_target_is_max_of_configured_and_steady_safe_gap(v: float, age: float) -> None:
    ctl = make_cacc({}, VEH)
    cmd = ctl.command(_obs(v, 60.0, age))
    expected = max(30.0, _steady_gap(v, age) + 2.0)
    assert cmd.info["target_gap_m"] == pytest.approx(expected, rel=1e-9)
    if v == 0.0:
        assert cmd.info["target_gap_m"] == 30.0  # at standstill: the platform-sized configured gap


def test_constant_policy_keeps_the_configured_gap() -> None:
    ctl = make_cacc({"gap_policy": "constant"}, VEH)
    assert ctl.command(_obs(19.4, 60.0, 0.5)).info["target_gap_m"] == 30.0


def test_at_the_policy_gap_at_line_speed_there_is_no_safety_braking() -> None:
    v, age = 19.4, 0.5
    target = _steady_gap(v, age) + 2.0
    assert target > 30.0  # a 30 m gap is not safe at 70 km/h with these delays
    cmd = make_cacc({}, VEH).command(_obs(v, target, age))
    assert cmd.info["phase"] == "track" and not cmd.emergency
    assert cmd.info["rbd_margin_m"] == pytest.approx(2.0, abs=0.3)  # the buffer, kept above the barrier
    # both cruise: the command is the resistance feed-forward only (equal speeds, zero gap error)
    assert cmd.accel_mps2 == pytest.approx(VEH.resistance_n(v) / VEH.effective_mass_kg, abs=0.02)


def test_at_a_30m_gap_at_line_speed_the_safety_cap_brakes() -> None:
    cmd = make_cacc({"gap_policy": "constant"}, VEH).command(_obs(19.4, 30.0, 0.5))
    assert cmd.info["rbd_margin_m"] < 0.0
    assert cmd.accel_mps2 < 0.0 and math.isfinite(cmd.accel_mps2)


def test_bad_gap_policy_is_rejected() -> None:
    with pytest.raises(ValueError, match="gap_policy"):
        make_cacc({"gap_policy": "tight"}, VEH)
