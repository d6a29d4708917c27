"""Paper D monorail units: safety distance, braking policies, hysteresis, state machine, plant delays, CA role."""

from __future__ import annotations

import numpy as np
import pytest

from controllers.base import Observation, OwnState, create
from controllers.monorail import collision_avoidance  # noqa: F401  (registers)
from controllers.monorail.braking_modes import (
    BrakingPolicy,
    adbm_distance_m,
    average_emergency_decel_mps2,
    max_safe_speed_mps,
    rdbm_distance_m,
    required_gap_m,
    safety_distance_m,
)
from controllers.monorail.collision_avoidance import sensor_extras
from controllers.monorail.coupling import incidence, laplacian
from controllers.monorail.states import StateParams, VcInputs, VcMemory, VcState, ca_hysteresis, transition
from railsim.physics.monorail import (
    MonorailParams,
    PlantState,
    load_mass_kg,
    plant_step,
    step_response_mps2,
    vehicle_params_for,
)


def test_safety_distance_hand_values() -> None:
    v = 25 / 3.6  # 6.9444 m/s; 6.9444·1 + 48.2253/3 = 23.0196; + 5 = 28.0196
    assert safety_distance_m() == pytest.approx(6.944444 + 16.075103 + 5.0, abs=1e-5)
    assert safety_distance_m(10.0, 0.5, 2.0, 5.0) == pytest.approx(5.0 + 25.0 + 5.0)
    assert average_emergency_decel_mps2(v, 23.0196, 1.0) == pytest.approx(1.5, abs=1e-3)
    assert adbm_distance_m(10.0, 2.0, 0.5, 5.0) == pytest.approx(35.0)
    assert rdbm_distance_m(10.0, 2.0, 8.0, 1.6, 0.5, 5.0) == pytest.approx(30.0 - 20.0 + 5.0)
    assert rdbm_distance_m(0.0, 2.0, 8.0, 1.6, 0.5, 5.0) == pytest.approx(5.0)  # never below the margin
    assert required_gap_m(BrakingPolicy(), 20.0, 0.0, 1.0) == 28.0  # the paper's fixed trigger


@pytest.mark.parametrize("mode", ["adbm", "rdbm"])
def test_max_safe_speed_inverts_required_gap(mode: str) -> None:
    pol = BrakingPolicy(mode=mode, t_eq_s=0.7, margin_m=3.0)
    for gap, v_l in [(20.0, 0.0), (35.0, 5.0), (60.0, 12.0)]:
        v = max_safe_speed_mps(pol, gap, v_l, 1.2)
        assert required_gap_m(pol, v, v_l, 1.2) == pytest.approx(gap, abs=1e-9)


def test_ca_hysteresis_trigger_release_and_latch() -> None:
    trig, rel = 28.0, 28.5
    assert not ca_hysteresis(False, 0.0, 0.0, 28.01, trig, rel, 0.1, False, 5.0)
    assert ca_hysteresis(False, 0.0, 0.0, 28.0, trig, rel, 0.1, False, 5.0)  # on at ≤ trigger
    assert ca_hysteresis(True, 0.0, 1.0, 28.4, trig, rel, 0.1, False, 5.0)  # inside the band: stays on
    assert ca_hysteresis(True, 0.0, 0.05, 29.0, trig, rel, 0.1, False, 5.0)  # minimum on-time
    assert not ca_hysteresis(True, 0.0, 1.0, 28.6, trig, rel, 0.1, False, 5.0)  # released above release
    assert ca_hysteresis(True, 0.0, 9.0, 99.0, trig, rel, 0.1, True, 0.5)  # latched: on while moving
    assert ca_hysteresis(True, 0.0, 9.0, 10.0, trig, rel, 0.1, True, 0.0)  # standing, obstacle still close
    assert not ca_hysteresis(True, 0.0, 9.0, 99.0, trig, rel, 0.1, True, 0.0)  # standing, cleared


def _run_states(seq: list[VcInputs], p: StateParams, start: VcState) -> list[VcState]:
    mem, out = VcMemory(start), []
    for inp in seq:
        mem, _ = transition(mem, inp, p)
        out.append(mem.state)
    return out


def test_state_machine_coupling_decoupling_and_ca() -> None:
    p = StateParams(target_gap_m=5.0, hold_s=1.0)
    ok = [VcInputs(0.1 * k, 5.2, 0.0, 8.0, ca_trigger_m=3.0, ca_release_m=3.5) for k in range(12)]
    states = _run_states(ok, p, VcState.COUPLING)
    assert states[9] is VcState.COUPLING and states[10] is VcState.COUPLED  # held exactly 1 s
    # passive: gap > d_max + band (= 26 m) and opening; active: gap < d_min − band (= 4 m) and closing
    assert _run_states([VcInputs(0, 26.5, -0.5, 8.0, ca_trigger_m=0.0)], p, VcState.COUPLED)[0] is VcState.DECOUPLING
    assert _run_states([VcInputs(0, 26.5, +0.5, 8.0, ca_trigger_m=0.0)], p, VcState.COUPLED)[0] is VcState.COUPLED
    assert _run_states([VcInputs(0, 3.9, 0.5, 8.0, ca_trigger_m=0.0)], p, VcState.COUPLED)[0] is VcState.DECOUPLING
    assert _run_states([VcInputs(0, 4.5, 0.5, 8.0, ca_trigger_m=0.0)], p, VcState.COUPLED)[0] is VcState.COUPLED
    # CA pre-empts, releases to independent (re-coupling needs a command); latched ends stopped
    seq = [
        VcInputs(0.0, 27.0, 1.0, 8.0, ca_release_m=28.5),
        VcInputs(0.5, 28.2, -1.0, 6.0, ca_release_m=28.5),
        VcInputs(1.0, 29.0, -1.0, 5.0, ca_release_m=28.5),
    ]
    assert _run_states(seq, p, VcState.COUPLED) == [VcState.CA_ACTIVE, VcState.CA_ACTIVE, VcState.INDEPENDENT]
    seq = [
        VcInputs(0.0, 27.0, 1.0, 8.0, ca_latch_to_standstill=True),
        VcInputs(1.0, 40.0, -1.0, 3.0),
        VcInputs(2.0, 40.0, 0.0, 0.0),
    ]
    assert _run_states(seq, p, VcState.INDEPENDENT) == [VcState.CA_ACTIVE, VcState.CA_ACTIVE, VcState.STOPPED]


def test_delayed_command_takes_effect_exactly_after_delay() -> None:
    mp = MonorailParams(
        traction_delay_s=0.3, traction_response_s=0.0, traction_efficiency=0.9, brake_delay_s=0.5, brake_response_s=0.0
    )
    m = load_mass_kg("empty")
    s = PlantState(v_mps=5.0)
    accel = []
    for k in range(6):
        s = plant_step(s, 0.5 if k == 0 else s.active_command_mps2 if k < 3 else 0.5, 0.1, mp, m)
        accel.append(s.a_mps2)
    assert accel[:3] == [0.0, 0.0, 0.0] and accel[3] == pytest.approx(0.45)  # arrives at t = 0.3 s exactly
    s2 = s
    for k in range(6):  # braking: 5 steps of dead time
        s2 = plant_step(s2, -1.0, 0.1, mp, m)
        assert s2.a_mps2 == pytest.approx(0.45 if k < 5 else -1.0)


def test_form_b_closed_form_matches_discrete_plant() -> None:
    mp = MonorailParams(traction_delay_s=0.2, traction_response_s=0.3)
    m = load_mass_kg("empty")
    s, a = PlantState(v_mps=1.0), []
    for _ in range(30):
        s = plant_step(s, 0.8, 0.1, mp, m)
        a.append(s.a_mps2)
    # the plant updates at step boundaries: step k+1 sees the lag output at t = (k+1)·dt with the dead time
    ref = step_response_mps2(0.1 * np.arange(1, 31), 0.8, mp)
    assert np.allclose(a, ref, atol=1e-12)
    # cut-off decays to zero, re-traction rises again
    assert step_response_mps2(5.0, 0.0, mp, a0_mps2=0.72) == pytest.approx(0.0, abs=1e-6)


def test_load_cases_and_force_limited_braking() -> None:
    assert [load_mass_kg(x) for x in ("empty", "full", "overloaded")] == pytest.approx([27000, 39660, 44100])
    mp = MonorailParams()
    assert mp.emergency_decel_mps2(44100) == pytest.approx(1.5 * 27000 / 44100)
    assert MonorailParams(braking_model="load_compensated").emergency_decel_mps2(44100) == 1.5
    with pytest.raises(ValueError, match="load"):
        load_mass_kg("heavy")


def test_graph_matrices() -> None:
    a = np.array([[0, 1, 0], [1, 0, 1], [0, 1, 0]], float)
    b = incidence([(0, 1), (1, 2)], 3)
    assert np.allclose(laplacian(a), b.T @ b)


def _obs(v: float, extras: dict, t: float = 0.0) -> Observation:
    veh = vehicle_params_for("empty")
    return Observation(t, 0.1, OwnState("F1", 0.0, v, 0.0, 0.0), veh, 1e4, predecessor=None, extras=extras)


def test_ca_works_without_communication_and_latches_for_obstacles() -> None:
    ca = create("monorail_ca", {}, vehicle_params_for("empty"))
    assert ca.command(_obs(7.0, {})).accel_mps2 > 0.0  # nothing sensed: no restriction
    cmd = ca.command(_obs(7.0, sensor_extras(27.0, 7.0, "obstacle")))  # predecessor None: comm down
    assert cmd.emergency and cmd.accel_mps2 == pytest.approx(-1.5)
    cmd = ca.command(_obs(5.0, sensor_extras(60.0, 5.0, "obstacle"), t=1.0))  # far again, still moving: latched
    assert cmd.emergency and cmd.accel_mps2 < 0.0
    debounced = {"trigger_dwell_s": 0.3, "trigger_band_m": 2.5, "rearm_s": 1.0, "release_margin_m": 0.5}
    ca2 = create("monorail_ca", {"law": "mpc", **debounced}, vehicle_params_for("empty"))
    c = ca2.command(_obs(8.0, sensor_extras(27.0, 3.0, "vehicle")))
    assert c.info["ca"] == "idle"  # shallow (1 m < band), not braking: debounced for trigger_dwell_s (0.3 s)
    for t in (0.1, 0.2, 0.3):
        c = ca2.command(_obs(8.0, sensor_extras(27.0, 3.0, "vehicle"), t=t))
    assert c.info["ca"] == "active" and c.accel_mps2 < 0.0 and not c.fallback
    c = ca2.command(_obs(5.0, sensor_extras(29.0, -1.0, "vehicle"), t=0.5))  # > 28 + release margin 0.5
    assert c.info["ca"] == "idle" and c.info.get("event") == "ca_off"


def test_bad_parameters_are_value_errors() -> None:
    with pytest.raises(ValueError, match="threshold_mode|mode"):
        create("monorail_ca", {"threshold_mode": "abs"}, vehicle_params_for("empty"))
    with pytest.raises(ValueError, match="k_x_per_s2"):
        create("monorail_apf", {"k_x_per_s2": -1}, vehicle_params_for("empty"))
    with pytest.raises(ValueError, match="unknown|bogus"):
        create("monorail_apf", {"bogus": 1.0}, vehicle_params_for("empty"))


# --- CA trigger debounce and the additive braking of Eq. (A27) ------------------------------------------


def test_ca_should_fire_debounce_rules() -> None:
    from controllers.monorail.states import ca_should_fire

    trig = 28.0
    assert not ca_should_fire(28.01, trig, 5.0, None, -1e9, 0.3, 0.5, 1.0)  # above the trigger: never
    assert ca_should_fire(27.4, trig, 5.0, 5.0, -1e9, 0.3, 0.5, 1.0)  # deeper than the band: at once
    assert ca_should_fire(27.9, trig, 5.0, 5.0, -1e9, 0.3, 0.5, 1.0, urgent_object=True)  # obstacle: at once
    assert not ca_should_fire(27.9, trig, 5.1, 5.0, -1e9, 0.3, 0.5, 1.0)  # shallow, 0.1 s < dwell
    assert ca_should_fire(27.9, trig, 5.3, 5.0, -1e9, 0.3, 0.5, 1.0)  # shallow for the whole dwell
    assert not ca_should_fire(27.9, trig, 5.3, 5.0, 4.5, 0.3, 0.5, 1.0)  # released 0.8 s ago: not re-armed
    assert not ca_should_fire(27.9, trig, 5.3, 5.0, -1e9, 0.3, 0.5, 1.0, braking_suffices=True)
    assert ca_should_fire(27.0, trig, 5.0, 5.0, -1e9, 0.3, 0.5, 1.0, braking_suffices=True)  # deep beats it
    assert ca_should_fire(27.99, trig, 0.0, 0.0, -1e9, 0.0, 0.0, 0.0)  # all zero: the paper's bare trigger


def test_braking_suffices_closed_form() -> None:
    from controllers.monorail.states import braking_suffices

    # v_c = 2 m/s, braking 0.5 m/s²: the closing ends after v_c²/(2a) = 4 m
    assert braking_suffices(9.01, 2.0, -0.5, 5.0) and not braking_suffices(8.99, 2.0, -0.5, 5.0)
    assert not braking_suffices(100.0, 0.1, 0.0, 5.0)  # closing without braking never suffices
    assert braking_suffices(6.0, -1.0, 0.3, 5.0) and not braking_suffices(4.0, -1.0, 0.3, 5.0)  # opening gap


def _additive_ca(**over: float | str | bool) -> object:
    return create("monorail_ca", {"additive": True, "law": "mpc", **over}, vehicle_params_for("empty"))


def test_additive_ca_decides_a_bounded_braking_increment() -> None:
    """A27 in the controller: the increment is marked additive, brakes (Δ ≤ 0) and never takes the total
    (service + Δ) beyond the emergency deceleration; idle it adds nothing."""
    veh = vehicle_params_for("empty")
    ca = _additive_ca()
    idle = ca.command(_obs(11.0, sensor_extras(40.0, 1.5, "vehicle", -0.15)))
    assert idle.additive and idle.accel_mps2 == 0.0 and not idle.emergency
    for service in (-0.15, -0.9, -1.4, -1.6):  # the last one is already beyond the envelope on its own
        ca = _additive_ca()
        cmd = ca.command(_obs(11.0, sensor_extras(27.0, 3.0, "vehicle", service)))
        assert cmd.info["ca"] == "active" and cmd.additive
        assert cmd.accel_mps2 <= 0.0
        assert service + cmd.accel_mps2 >= min(service, -veh.emergency_decel_mps2) - 1e-9
    bang = _additive_ca(law="bang_bang").command(_obs(11.0, sensor_extras(27.0, 3.0, "vehicle", -0.15)))
    assert -0.15 + bang.accel_mps2 == pytest.approx(-veh.emergency_decel_mps2) and bang.emergency


def test_additive_ca_increment_is_priced_by_r_u() -> None:
    """The calibration knob of the arrival case: a dearer increment (r_u) brakes less at the same reading."""
    reading = sensor_extras(26.0, 2.0, "vehicle", -0.15)
    cheap = _additive_ca(r_u=0.5).command(_obs(11.0, reading)).accel_mps2
    dear = _additive_ca(r_u=75.0).command(_obs(11.0, reading)).accel_mps2
    assert cheap < dear < 0.0


def test_additive_ca_without_a_service_reading_is_an_ordinary_command() -> None:
    cmd = _additive_ca().command(_obs(11.0, sensor_extras(27.0, 3.0, "vehicle")))
    assert not cmd.additive and cmd.accel_mps2 < 0.0


def test_post_release_previous_command_keeps_the_service_braking_of_the_trigger() -> None:
    """A11 (arrival): after the release the vehicle keeps the deceleration it had when CA fired, until a couple
    command or ``ca_hold_clear``; ``hold_speed`` caps at cruise instead."""
    ca = _additive_ca(post_release="previous_command")
    assert ca.command(_obs(8.0, sensor_extras(27.0, 1.0, "vehicle", -0.15), t=0.0)).info.get("event") == "ca_on"
    off = ca.command(_obs(6.0, sensor_extras(29.0, -0.5, "vehicle", -0.15), t=1.0))
    assert off.info.get("event") == "ca_off" and off.accel_mps2 == pytest.approx(-0.15) and not off.additive
    later = ca.command(_obs(5.0, sensor_extras(60.0, -0.5, "vehicle", 0.4), t=2.0))  # service asks for traction
    assert later.accel_mps2 == pytest.approx(-0.15) and later.info["ca"] == "previous_command"
    cleared = ca.command(_obs(5.0, {**sensor_extras(60.0, -0.5, "vehicle", 0.4), "ca_hold_clear": True}, t=3.0))
    assert cleared.accel_mps2 == 0.0 and cleared.additive  # idle again: adds nothing
    hold = create("monorail_ca", {"post_release": "hold_speed"}, vehicle_params_for("empty"))
    hold.command(_obs(8.0, sensor_extras(27.0, 1.0, "vehicle", -0.15), t=0.0))
    assert hold.command(_obs(6.0, sensor_extras(29.0, -0.5, "vehicle", -0.15), t=1.0)).accel_mps2 == 0.0


def test_ca_hysteresis_constructed_sequence() -> None:
    """The coupling scenarios' debounced trigger and release hysteresis on a constructed gap sequence (fixed 28 m
    trigger for clarity; closing at 2 m/s without own braking, so the own braking never 'suffices')."""
    params = {"trigger_dwell_s": 0.3, "trigger_band_m": 0.5, "rearm_s": 1.0, "release_margin_m": 0.5}
    ca = create("monorail_ca", {"law": "bang_bang", **params}, vehicle_params_for("empty"))

    def state(t: float, gap: float) -> str:
        return ca.command(_obs(10.0, sensor_extras(gap, 2.0, "vehicle"), t=t)).info["ca"]

    assert [state(t, 27.8) for t in (0.0, 0.1, 0.2)] == ["idle"] * 3  # shallow, shorter than the dwell
    assert state(0.3, 28.2) == "idle"  # back above: the dwell restarts
    assert [state(t, 27.8) for t in (0.4, 0.5, 0.6)] == ["idle"] * 3
    assert state(0.7, 27.8) == "active"  # shallow for the whole 0.3 s dwell
    assert state(0.8, 28.3) == "active"  # above the trigger but not above trigger + 0.5 m release margin
    assert state(0.9, 28.6) == "idle"  # released
    assert [state(t, 27.8) for t in (1.0, 1.1, 1.2, 1.3, 1.4)] == ["idle"] * 5  # shallow within the 1 s re-arm
    assert state(1.5, 27.4) == "active"  # deeper than the 0.5 m band: at once, re-arm or not
