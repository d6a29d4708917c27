"""The compiled step (railsim/engine/line_step_kernel.py) decides what the roles one by one decide, bit for bit.

``ControlStage.control_all`` hands a line train, and a coupled follower on the CACC, to the compiled step
``line_step_kernel.step`` and every other train to its roles one by one (``ControlStage._role_commands``, then
``controllers.base.arbitrate`` and the plant). On random states (those of ``tests/unit/test_line_kernels.py``: every
ATO phase, restrictions, stops, authorities, formation tails) with and without a known rear of a train ahead at
random distances and ages, at three step lengths and the three step methods: with no coupled role
(``NO_COUPLED``) the step must give the command, emergency flag and winning role that ``Ato.decide`` and
``Separation.decide`` arbitrated by ``arbitrate`` give, and the plant result of ``dynamics.step_values`` on the true
plant state; with a coupled role likewise, a CACC (``Cacc.decide``) on a random leader state between the two, its
inputs in one array kept over two decisions, and the CACC's memory (its leader's reconstructed command) carried over
them as the engine does.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest

from controllers.ato import Ato
from controllers.base import Command, PredecessorState, arbitrate
from controllers.cacc import make_cacc
from controllers.separation import Separation, SeparationParams
from railsim.engine import line_step_kernel
from railsim.physics import dynamics, plant_kernel
from railsim.physics.vehicle import VehicleParams
from tests.unit.test_line_kernels import PARAMS, VEHICLES, _random_state, line_ahead_args

# every test at three step lengths and the three step methods
pytestmark = [pytest.mark.parametrize("dt", [0.1, 0.5, 1.0]), pytest.mark.parametrize("method", dynamics.STEP_METHODS)]


@dataclass(frozen=True)
class _Case:
    """One random train: its vehicle, line ATO and separation, what it knows of itself and its true plant state."""

    veh: VehicleParams
    ato: Ato
    sep: Separation
    state: tuple[Any, ...]  # _random_state's (x, v, applied, grade, line speed, limits, stop, authority)
    tail_m: float
    plant: dynamics.PlantState

    def roles_one_by_one(
        self, dt: float, method: str, known: tuple[float, float] | None, vc_cmd: Command | None = None
    ) -> tuple[str, Command, tuple[Any, ...]]:
        """The winning role and command as ``ControlStage._role_commands`` and ``arbitrate`` find them (the ATO,
        the coupled role's ``vc_cmd`` if any, the separation against ``known``), and the plant's step on it."""
        veh, (x, v, applied, grade, line, limits, stop, authority) = self.veh, self.state
        accel, emergency, _ = self.ato.decide(
            veh, dt, x, v, applied, veh.length_m, grade, line, limits, stop, authority, self.tail_m
        )
        commands = {"ato": Command(accel, emergency=emergency)}
        if vc_cmd is not None:
            commands["coupled"] = vc_cmd
        if known is not None:
            commands["separation"] = self.sep.decide(veh, dt, x, v, applied, grade, *known)
        role, cmd = arbitrate(commands, veh.emergency_decel_mps2)
        return role, cmd, dynamics.step_values(veh, self.plant, cmd.accel_mps2, dt, grade, cmd.emergency, method)

    def step(self, dt: float, method: str, known: tuple[float, float] | None, coupled: np.ndarray) -> tuple[Any, ...]:
        """The compiled step on the same values, as ``ControlStage._line_args`` hands them."""
        veh, (x, v, _, grade, line, limits, stop, authority) = self.veh, self.state
        return line_step_kernel.step(
            self.ato.packed(veh, dt),
            self.sep.packed(veh, dt),
            plant_kernel.pack(veh, dt),
            plant_kernel.method_index(method),
            dt,
            x,
            v,
            self.plant.speed_mps,
            self.plant.applied_accel_mps2,
            self.plant.target_accel_mps2,
            veh.length_m,
            grade,
            line,
            *line_ahead_args(limits, stop, authority, self.tail_m),
            known is not None,
            *(known if known is not None else (0.0, 0.0)),
            coupled,
        )


def _cases(seed: int) -> Iterator[tuple[np.random.Generator, _Case]]:
    """1500 random trains, each with the generator that drew it (a test draws the rest of its case from it)."""
    rng = np.random.default_rng(seed)
    for k in range(1500):
        veh = VEHICLES[k % len(VEHICLES)]
        ato = Ato(PARAMS[(k // 3) % len(PARAMS)], veh)
        sep = Separation(SeparationParams(margin_m=float(rng.choice([20.0, 50.0]))), veh)
        state = _random_state(rng, veh)
        tail_m = float(rng.choice([0.0, 0.0, rng.uniform(0.0, 150.0)]))
        plant = dynamics.PlantState(state[1], state[2], float(rng.uniform(-1.2, 1.2)))
        yield rng, _Case(veh, ato, sep, state, tail_m, plant)


def _known_rear(rng: np.random.Generator, x: float, farthest_m: float) -> tuple[float, float]:
    """The known rear of a train ahead (up to ``farthest_m`` on) and the age of that knowledge."""
    return x + float(rng.uniform(-5.0, farthest_m)), float(rng.choice([0.0, rng.uniform(0.0, 3.0)]))


def _assert_same(got: tuple[Any, ...], role: str, cmd: Command, ref: tuple[Any, ...]) -> None:
    g_accel, g_emergency, g_role, ok, v_next, a_k, u_k, energy, mask, _ = got
    assert ok
    assert (float(g_accel).hex(), bool(g_emergency)) == (float(cmd.accel_mps2).hex(), cmd.emergency)
    assert line_step_kernel.ROLES[g_role] == role
    assert (v_next, a_k, u_k, energy, mask) == (ref[0], ref[1], ref[2], ref[5], ref[6])


def test_line_train_step_is_the_separate_calls(dt: float, method: str) -> None:
    roles: set[str] = set()
    emergencies = 0
    for rng, case in _cases(31):
        known = _known_rear(rng, case.state[0], 900.0) if rng.random() < 0.7 else None
        role, cmd, ref = case.roles_one_by_one(dt, method, known)
        got = case.step(dt, method, known, line_step_kernel.NO_COUPLED)
        _assert_same(got, role, cmd, ref)
        assert math.isnan(got[9])  # no coupled role, no CACC target gap
        roles.add(role)
        emergencies += cmd.emergency
    assert roles == {"ato", "separation"} and emergencies > 0  # both winners and emergencies were compared


def test_coupled_follower_step_is_the_separate_calls(dt: float, method: str) -> None:
    roles: set[str] = set()
    emergencies = 0
    for rng, case in _cases(47):
        veh, x = case.veh, case.state[0]
        params = {"gap_policy": str(rng.choice(["safe", "constant"])), "ff_lag_compensation": bool(rng.random() < 0.8)}
        ctl, shadow = make_cacc(params, veh), make_cacc(params, veh)  # the engine's and the reference's controller
        coupled = line_step_kernel.coupled_inputs(ctl.packed(veh, dt))  # kept over both decisions, as the engine does
        known = _known_rear(rng, x, 300.0) if rng.random() < 0.3 else None  # a train between follower and leader
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
            vc_cmd = shadow.decide(veh, dt, x, case.state[1], case.state[2], case.state[3], lead, target_gap, tracking)
            role, cmd, ref = case.roles_one_by_one(dt, method, known, vc_cmd)
            line_step_kernel.set_lead(coupled, lead, ctl.feed_forward_mps2(lead, veh), target_gap, tracking)
            got = case.step(dt, method, known, coupled)
            _assert_same(got, role, cmd, ref)
            assert got[9] == vc_cmd.info["target_gap_m"]
            roles.add(role)
            emergencies += cmd.emergency
    assert roles == {"ato", "coupled", "separation"} and emergencies > 0
