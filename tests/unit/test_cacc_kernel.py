"""The CACC law in one compiled call (:mod:`controllers.cacc_kernel`) gives the bits the interpreted law gave.

The oracle is the law as it was written in :meth:`controllers.cacc.Cacc.command` before it moved into the kernel
(kept below, word for word apart from its inputs' names, on the public braking and force functions). Random states
cover every branch: the ``safe`` and ``constant`` gap policies, gaps far above and below the target, stale and fresh
messages, a standing and a braking predecessor, stopping behind a standing leader (``vc_tracking`` False), a plan,
the lag reconstruction and the reported acceleration as feed-forward, gradients up and down. The compiled kernel is
also held to its own interpreted form (``py_func``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from controllers import cacc_kernel
from controllers.base import Command, Observation, OwnState, PredecessorState
from controllers.braking import net_braking_mps2, relative_braking_distance_m, traction_limit_mps2
from controllers.cacc import Cacc, CaccParams, make_cacc
from railsim.physics.vehicle import preset

VEHICLES = (preset("cq3_6car"), preset("cq3_6car").with_overrides(davis_a_n=4000.0, actuator_time_constant_s=0.3))


def _former_law(p: CaccParams, obs: Observation, a_p_applied: float) -> Command:
    """The law as :meth:`Cacc.command` computed it in the interpreter (after the feed-forward was chosen)."""
    veh = obs.vehicle
    own = obs.own
    v = max(own.speed_mps, 0.0)
    traction = traction_limit_mps2(veh, v)
    pred = obs.predecessor
    assert pred is not None and obs.target_gap_m is not None
    grade = own.gradient_permille
    m_eff = veh.effective_mass_kg
    tau = veh.actuator_time_constant_s
    age_s = max(pred.age_s, 0.0)
    v_p = max(pred.speed_mps, 0.0)
    rho_p = veh.resistance_n(v_p, grade) / m_eff
    b_f = max(net_braking_mps2(veh, veh.emergency_decel_mps2, grade, davis_speed_mps=0.0), 0.05)
    b_p = max(pred.emergency_decel_mps2 + rho_p, 0.05)
    v_pw = max(v_p - b_p * age_s, 0.0)
    rear_w = pred.rear_position_m + (v_p * v_p - v_pw * v_pw) / (2.0 * b_p)
    a0 = own.accel_mps2
    delay_s = tau + p.reaction_time_s + obs.dt_s
    target_m = float(obs.target_gap_m)
    if p.gap_policy == "safe":
        a_cruise = veh.resistance_n(v, grade) / m_eff
        steady_m = relative_braking_distance_m(v, v, b_f, b_p, delay_s, a_cruise, p.safety_margin_m) + v * age_s
        target_m = max(target_m, steady_m + p.gap_buffer_m)
    gap_m = pred.rear_position_m + v_p * age_s - own.position_m
    error_m = gap_m - target_m
    v_close = p.k_gap_per_s2 / p.k_speed_per_s * error_m
    if error_m > 0.0:
        v_close = min(v_close, p.approach_speed_mps, math.sqrt(2.0 * p.approach_decel_mps2 * error_m))
    track_net = p.k_speed_per_s * (v_p + v_close - v) + p.k_ff * (a_p_applied - rho_p)
    if obs.extras.get("vc_tracking") is False:
        track_net = math.inf
    rbd_m = relative_braking_distance_m(v, v_pw, b_f, b_p, delay_s, a0, p.safety_margin_m)
    h = rear_w - own.position_m - rbd_m
    a_p_net = max(pred.accel_mps2 - rho_p, -b_p) if v_pw > 0.0 else 0.0
    slope_s = delay_s + max(v + a0 * delay_s, 0.0) / b_f
    gamma = min(p.barrier_rate_per_s, 0.5 / obs.dt_s)
    numer = (v_p - v) + v_pw / b_p * a_p_net + gamma * h
    cap_net = numer / slope_s if slope_s > 0.0 else (math.inf if numer >= 0.0 else -math.inf)
    info: dict[str, Any] = {
        "phase": "track",
        "gap_m": gap_m,
        "gap_error_m": error_m,
        "rbd_margin_m": h,
        "target_gap_m": target_m,
    }
    service_net = net_braking_mps2(veh, veh.service_decel_mps2, grade, davis_speed_mps=v)
    if cap_net < -service_net and v > 0.0:
        info["phase"] = "emergency"
        return Command(-veh.emergency_decel_mps2, emergency=True, info=info)
    net = track_net
    if cap_net < track_net:
        net = cap_net
        info["phase"] = "safety"
    if math.isinf(net):
        return Command(traction, info=info)
    applied = veh.net_to_applied(net, v, grade)
    return Command(min(max(applied, -veh.service_decel_mps2), traction), info=info)


def _random_obs(rng: np.random.Generator) -> tuple[Observation, dict[str, Any]]:
    veh = VEHICLES[int(rng.integers(len(VEHICLES)))]
    v = float(rng.choice([0.0, rng.uniform(0.0, 2.0), rng.uniform(0.0, 25.0)]))
    v_p = float(rng.choice([0.0, rng.uniform(0.0, 25.0), v + rng.normal(0.0, 1.0)]))
    gap = float(rng.choice([rng.uniform(-2.0, 40.0), rng.uniform(20.0, 600.0)]))
    age = float(rng.choice([0.0, rng.uniform(0.0, 3.0)]))
    grade = float(rng.choice([0.0, rng.uniform(-35.0, 35.0)]))
    own = OwnState("f", 5000.0, v, float(rng.uniform(-1.3, 1.0)), veh.length_m, grade)
    plan = tuple(rng.uniform(-1.0, 1.0, 6).tolist()) if rng.random() < 0.2 else ()
    pred = PredecessorState(
        "l",
        5000.0 + gap + veh.length_m,
        v_p,
        float(rng.uniform(-1.5, 1.0)),
        veh.length_m,
        stamp_s=100.0 - age,
        age_s=age,
        service_decel_mps2=1.0,
        emergency_decel_mps2=float(rng.uniform(1.0, 1.4)),
        planned_accel_mps2=plan,
        plan_dt_s=0.5 if plan else 0.0,
    )
    extras = {"vc_tracking": False} if rng.random() < 0.15 else {}
    params = {
        "gap_policy": "safe" if rng.random() < 0.7 else "constant",
        "ff_lag_compensation": bool(rng.random() < 0.8),
        "reaction_time_s": float(rng.choice([0.0, 0.3])),
        "barrier_rate_per_s": float(rng.choice([1.0, 0.3])),
    }
    dt = float(rng.choice([0.1, 0.5, 1.0]))
    obs = Observation(
        t_s=100.0,
        dt_s=dt,
        own=own,
        vehicle=veh,
        route_length_m=1e5,
        predecessor=pred,
        formation_state="coupled",
        target_gap_m=float(rng.choice([20.0, 30.0, 80.0])),
        extras=extras,
    )
    return obs, params


def _feed_forward(ctl: Cacc, obs: Observation) -> float:
    """The feed-forward the controller chooses (a copy of its state is used: the choice has a side effect)."""
    pred = obs.predecessor
    assert pred is not None
    if pred.planned_accel_mps2 and pred.plan_dt_s > 0.0:
        index = min(int(max(pred.age_s, 0.0) / pred.plan_dt_s + 1e-9), len(pred.planned_accel_mps2) - 1)
        return pred.planned_accel_mps2[index]
    if ctl.params.ff_lag_compensation:
        shadow = Cacc(ctl.params, ctl.vehicle)
        shadow._last, shadow._command_estimate_mps2 = ctl._last, ctl._command_estimate_mps2
        return shadow._predecessor_command(pred, obs.vehicle.actuator_time_constant_s)
    return pred.accel_mps2


def test_the_compiled_law_gives_the_former_interpreted_bits_over_random_states() -> None:
    rng = np.random.default_rng(20261129)
    phases: set[str] = set()
    for _ in range(3000):
        obs, params = _random_obs(rng)
        ctl = make_cacc(params, obs.vehicle)
        ctl.command(obs)  # a first message: the lag reconstruction has a history for the second
        ahead = obs.predecessor
        assert ahead is not None
        later = PredecessorState(**{**ahead.__dict__, "stamp_s": ahead.stamp_s + obs.dt_s, "accel_mps2": -0.4})
        obs2 = Observation(**{**obs.__dict__, "predecessor": later})
        want = _former_law(ctl.params, obs2, _feed_forward(ctl, obs2))
        got = ctl.command(obs2)
        assert (got.accel_mps2, got.emergency, got.info) == (want.accel_mps2, want.emergency, want.info)
        phases.add(str(got.info["phase"]))
    assert phases == {"track", "safety", "emergency"}  # every branch was reached


def test_the_kernel_is_its_interpreted_form() -> None:
    rng = np.random.default_rng(7)
    for _ in range(500):
        obs, params = _random_obs(rng)
        pred = obs.predecessor
        assert pred is not None and obs.target_gap_m is not None
        packed = cacc_kernel.pack(obs.vehicle, CaccParams(**params), obs.dt_s)
        args = (
            packed,
            obs.own.position_m,
            obs.own.speed_mps,
            obs.own.accel_mps2,
            obs.own.gradient_permille,
            pred.rear_position_m,
            pred.speed_mps,
            pred.accel_mps2,
            pred.emergency_decel_mps2,
            pred.age_s,
            float(rng.uniform(-1.0, 1.0)),
            obs.target_gap_m,
            bool(rng.random() < 0.8),
        )
        assert cacc_kernel.cacc(*args) == cacc_kernel.cacc.py_func(*args)


@pytest.mark.parametrize("field", ["k_gap_per_s2", "safety_margin_m", "emergency_decel_mps2", "dt_s"])
def test_a_packed_input_out_of_place_changes_the_answer(field: str) -> None:
    """The oracle test above sees the packing: a field read from the wrong slot gives other bits."""
    veh = VEHICLES[0]
    params = CaccParams()
    packed = cacc_kernel.pack(veh, params, 0.5)
    k = cacc_kernel.CACC_FIELDS.index(field)
    wrong = packed.copy()
    wrong[k] *= 1.5
    args = (5000.0, 15.0, 0.1, 3.0, 5035.0, 14.0, -0.6, 1.2, 0.4, -0.5, 30.0, True)  # a gap 5-10 m over target
    assert cacc_kernel.cacc(packed, *args) != cacc_kernel.cacc(wrong, *args)
