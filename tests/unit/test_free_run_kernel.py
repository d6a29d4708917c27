"""The compiled free run and plant step give the same bits as their interpreted forms.

* :func:`railsim.physics.plant_kernel.step` (the plant, written once) against its interpreted form on random
  states (speeds from standstill to over the top speed, commands beyond both envelopes, gradients, emergency,
  every step method, three vehicles including one without actuator lag): all seven outputs equal, mask included.
* :func:`railsim.engine.free_run_kernel.free_run` (through ``trips.free_run``) against its interpreted form
  (``tests.helpers.interpreted``), whole trips (``tests/sumo/test_free_run_kernel_sumo.py``): every distinct trip of the mini line at step
  lengths 0.1/0.5/1.0 s and the three step methods, at full performance and slowed (the running-time factors of
  :mod:`railsim.engine.primary_delays`), and the Line 3 peak's trips at 0.5 s. Planned arrival and departure
  dictionaries must be equal (same floats, same keys in the same order). (With the ballistic and forward step
  methods at 0.5–1 s, the line ATO — whose stop predictor is Euler's — may never halt inside a window on the
  mini line: both loops then run the 6 h limit and agree on that too.)
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from railsim.physics import dynamics, plant_kernel
from railsim.physics.vehicle import VehicleParams, preset
from tests.helpers import interpreted

VEHICLES = [
    preset("cq3_6car"),
    VehicleParams("stiff", 60.0, 1.0e5, jerk_limit_mps3=math.inf, actuator_time_constant_s=0.0),
    VehicleParams("slow", 200.0, 4.0e5, max_speed_mps=12.0, traction_max_power_w=8e5, jerk_limit_mps3=0.4),
]


def test_mask_bits_are_dynamics_flag_order() -> None:
    bits = [plant_kernel._B_TRACTION, plant_kernel._B_POWER, plant_kernel._B_OVERSPEED, plant_kernel._B_BRAKE]
    bits += [plant_kernel._B_JERK, plant_kernel._B_OVERRIDE, plant_kernel._B_HOLD]
    assert bits == [dynamics._BIT[name] for name in dynamics._FLAG_ORDER]


@pytest.mark.parametrize("method", dynamics.STEP_METHODS)
def test_compiled_plant_step_is_its_interpreted_form(method: str) -> None:
    """The plant step is written once (:func:`plant_kernel.step`); compiled, it gives the bits of its interpreted
    form on random states, and :func:`dynamics.step_values` hands over and returns the same values."""
    reference = interpreted(plant_kernel)
    rng = np.random.default_rng(7)
    n_checked, masks = 0, set()
    for k in range(6000):
        veh = VEHICLES[k % len(VEHICLES)]
        dt = (0.1, 0.5, 1.0)[(k // 3) % 3]
        v = float(rng.choice([0.0, rng.uniform(0.0, 1e-3), rng.uniform(0.0, 1.3 * veh.max_speed_mps)]))
        state = dynamics.PlantState(v, float(rng.uniform(-1.5, 1.5)), float(rng.uniform(-1.5, 1.5)))
        u = float(rng.uniform(-3.0, 3.0))
        grad = float(rng.choice([0.0, rng.uniform(-40.0, 40.0)]))
        emergency = bool(rng.random() < 0.15)
        args = (
            plant_kernel.pack(veh, dt),
            state.speed_mps,
            state.applied_accel_mps2,
            state.target_accel_mps2,
            u,
            dt,
            grad,
            emergency,
            plant_kernel.method_index(method),
        )
        compiled = plant_kernel.step(*args)
        assert compiled == reference.step(*args), (veh.name, dt, state, u, grad, emergency)
        assert dynamics.step_values(veh, state, u, dt, grad, emergency, method) == compiled
        n_checked += 1
        masks.add(compiled[6])
    assert n_checked == 6000 and len(masks) >= 8  # many saturation combinations were met
