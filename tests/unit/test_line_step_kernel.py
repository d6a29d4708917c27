"""The compiled line step (railsim/engine/line_step_kernel.py) decides what the roles one by one decide, bit for bit.

``ControlStage.control`` hands a line train to the compiled line step and every other train to its roles one by
one (``ControlStage._role_commands``, then ``controllers.base.arbitrate`` and the plant). On random states (those of
``tests/unit/test_line_kernels.py``: every ATO phase, restrictions, stops, authorities, formation tails) with and
without a known rear of a train ahead at random distances and ages, at three step lengths and the three step
methods: ``line_step`` must give the command, emergency flag and winning role that ``Ato.decide`` and
``Separation.decide`` arbitrated by ``arbitrate`` give, and the plant result of ``dynamics.step_values`` on the
true plant state.
"""

from __future__ import annotations

import numpy as np
import pytest

from controllers.ato import Ato, limits_array_cached
from controllers.base import Command, arbitrate
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
        g_accel, g_emergency, g_role, ok, v_next, a_k, u_k, energy, mask = got
        assert ok
        assert (float(g_accel).hex(), bool(g_emergency)) == (float(accel).hex(), emergency)
        assert ("separation" if g_role == line_step_kernel.ROLE_SEPARATION else "ato") == role
        assert (v_next, a_k, u_k, energy, mask) == (ref[0], ref[1], ref[2], ref[5], ref[6])
        roles.add(role)
        emergencies += emergency
    assert roles == {"ato", "separation"} and emergencies > 0  # both winners and emergencies were compared
