"""The compiled line step (railsim/engine/line_step_kernel.py) decides what the roles one by one decide, bit for bit.

``ControlStage.control_all`` hands a line train (a coupled follower on the CACC: ``coupled_step``) to the compiled line step and every other train to its roles one by
one (``ControlStage._role_commands``, then ``controllers.base.arbitrate`` and the plant). On random states (those of
``tests/unit/test_line_kernels.py``: every ATO phase, restrictions, stops, authorities, formation tails) with and
without a known rear of a train ahead at random distances and ages, at three step lengths and the three step
methods: ``line_step`` must give the command, emergency flag and winning role that ``Ato.decide`` and
``Separation.decide`` arbitrated by ``arbitrate`` give, and the plant result of ``dynamics.step_values`` on the
true plant state. ``coupled_step`` likewise, with a CACC (``Cacc.decide``) on a random leader state between the
two, the CACC's memory (its leader's reconstructed command) carried over two decisions as the engine does.
"""

from __future__ import annotations

import numpy as np
import pytest

from typing import Any

from controllers.ato import Ato, limits_array_cached
from controllers.base import Command, PredecessorState, arbitrate
from controllers.cacc import make_cacc
from controllers.separation import Separation, SeparationParams
from railsim.engine import line_step_kernel
from railsim.physics import dynamics, plant_kernel
from tests.unit.test_line_kernels import PARAMS, VEHICLES, _random_state


@pytest.mark.parametrize("dt", [0.1, 0.5, 1.0])
@pytest.mark.parametrize("method", dynamics.STEP_METHODS)
def test_line_step_is_the_separate_calls(dt: float, method: str) -> None:
    rng = np.random.default_rng(31)
    roles: set[str] = set()
    emergencies = 0
    for k in range(1500):
        veh = VEHICLES[k % len(VEHICLES)]
        ato = Ato(PARAMS[(k // 3) % len(PARAMS)], veh)
        sep = Separation(SeparationParams(margin_m=float(rng.choice([20.0, 50.0]))), veh)
        x, v, applied, grade, line, limits, stop, authority = _random_state(rng, veh)
        tail = float(rng.choice([0.0, 0.0, rng.uniform(0.0, 150.0)]))
        plant = dynamics.PlantState(v, applied, float(rng.uniform(-1.2, 1.2)))
        known = None
        if rng.random() < 0.7:
            known = (x + float(rng.uniform(-5.0, 900.0)), float(rng.choice([0.0, rng.uniform(0.0, 3.0)])))
        # the roles one by one, as ControlStage._role_commands asks them, and the general arbitration
        a_accel, a_emergency, _ = ato.decide(
            veh, dt, x, v, applied, veh.length_m, grade, line, limits, stop, authority, tail
        )
        commands = {"ato": Command(a_accel, emergency=a_emergency)}
        if known is not None:
            commands["separation"] = sep.decide(veh, dt, x, v, applied, grade, *known)
        role, cmd = arbitrate(commands, veh.emergency_decel_mps2)
        accel, emergency = cmd.accel_mps2, cmd.emergency
        ref = dynamics.step_values(veh, plant, accel, dt, grade, emergency, method)
        got = line_step_kernel.line_step(
            *_line_args(ato, sep, veh, dt, method, x, v, plant, grade, line, limits, stop, authority, tail, known)
        )
        g_accel, g_emergency, g_role, ok, v_next, a_k, u_k, energy, mask = got
        assert ok
        assert (float(g_accel).hex(), bool(g_emergency)) == (float(accel).hex(), emergency)
        assert line_step_kernel.ROLES[g_role] == role
        assert (v_next, a_k, u_k, energy, mask) == (ref[0], ref[1], ref[2], ref[5], ref[6])
        roles.add(role)
        emergencies += emergency
    assert roles == {"ato", "separation"} and emergencies > 0  # both winners and emergencies were compared


def _line_args(
    ato: Ato,
    sep: Separation,
    veh: Any,
    dt: float,
    method: str,
    x: float,
    v: float,
    plant: dynamics.PlantState,
    grade: float,
    line: float,
    limits: Any,
    stop: Any,
    authority: float | None,
    tail: float,
    known: tuple[float, float] | None,
) -> tuple[Any, ...]:
    return (
        ato.packed(veh, dt),
        sep.packed(veh, dt),
        plant_kernel.pack(veh, dt),
        plant_kernel.method_index(method),
        dt,
        x,
        v,
        plant.speed_mps,
        plant.applied_accel_mps2,
        plant.target_accel_mps2,
        veh.length_m,
        grade,
        line,
        limits_array_cached(limits),
        stop is not None,
        *(stop if stop is not None else (0.0, 0.0, 0.0, False)),
        authority is not None,
        authority if authority is not None else 0.0,
        tail,
        known is not None,
        *(known if known is not None else (0.0, 0.0)),
    )


@pytest.mark.parametrize("dt", [0.1, 0.5, 1.0])
@pytest.mark.parametrize("method", dynamics.STEP_METHODS)
def test_coupled_step_is_the_separate_calls(dt: float, method: str) -> None:
    rng = np.random.default_rng(47)
    roles: set[str] = set()
    emergencies = 0
    for k in range(1500):
        veh = VEHICLES[k % len(VEHICLES)]
        ato = Ato(PARAMS[(k // 3) % len(PARAMS)], veh)
        sep = Separation(SeparationParams(margin_m=float(rng.choice([20.0, 50.0]))), veh)
        params = {"gap_policy": str(rng.choice(["safe", "constant"])), "ff_lag_compensation": bool(rng.random() < 0.8)}
        ctl, shadow = make_cacc(params, veh), make_cacc(params, veh)  # the engine's and the reference's controller
        x, v, applied, grade, line, limits, stop, authority = _random_state(rng, veh)
        tail = float(rng.choice([0.0, 0.0, rng.uniform(0.0, 150.0)]))
        plant = dynamics.PlantState(v, applied, float(rng.uniform(-1.2, 1.2)))
        known = None
        if rng.random() < 0.3:  # a train between the follower and its leader
            known = (x + float(rng.uniform(-5.0, 300.0)), float(rng.choice([0.0, rng.uniform(0.0, 3.0)])))
        gap = float(rng.choice([rng.uniform(-3.0, 60.0), rng.uniform(20.0, 800.0)]))
        target_gap = float(rng.choice([20.0, 40.0]))
        tracking = bool(rng.random() < 0.85)
        for step in range(2):  # the second decision reconstructs the leader's command from two messages
            age = float(rng.choice([0.0, rng.uniform(0.0, 2.0)]))
            lead = PredecessorState(
                "L",
                x + gap + veh.length_m,
                float(rng.uniform(0.0, 22.0)),
                float(rng.uniform(-1.3, 1.0)),
                veh.length_m,
                stamp_s=10.0 + step * dt - age,
                age_s=age,
                emergency_decel_mps2=float(rng.uniform(1.0, 1.4)),
            )
            a_accel, a_emergency, _ = ato.decide(
                veh, dt, x, v, applied, veh.length_m, grade, line, limits, stop, authority, tail
            )
            commands = {"ato": Command(a_accel, emergency=a_emergency)}
            vc_cmd = shadow.decide(veh, dt, x, v, applied, grade, lead, target_gap, tracking)
            commands["coupled"] = vc_cmd
            if known is not None:
                commands["separation"] = sep.decide(veh, dt, x, v, applied, grade, *known)
            role, cmd = arbitrate(commands, veh.emergency_decel_mps2)
            ref = dynamics.step_values(veh, plant, cmd.accel_mps2, dt, grade, cmd.emergency, method)
            got = line_step_kernel.coupled_step(
                *_line_args(ato, sep, veh, dt, method, x, v, plant, grade, line, limits, stop, authority, tail, known),
                ctl.packed(veh, dt),
                lead.rear_position_m,
                lead.speed_mps,
                lead.accel_mps2,
                lead.emergency_decel_mps2,
                lead.age_s,
                ctl.feed_forward_mps2(lead, veh),
                target_gap,
                tracking,
            )
            g_accel, g_emergency, g_role, ok, v_next, a_k, u_k, energy, mask, g_target = got
            assert ok
            assert (float(g_accel).hex(), bool(g_emergency)) == (float(cmd.accel_mps2).hex(), cmd.emergency)
            assert line_step_kernel.ROLES[g_role] == role
            assert (v_next, a_k, u_k, energy, mask) == (ref[0], ref[1], ref[2], ref[5], ref[6])
            assert g_target == vc_cmd.info["target_gap_m"]
            roles.add(role)
            emergencies += cmd.emergency
    assert roles == {"ato", "coupled", "separation"} and emergencies > 0
