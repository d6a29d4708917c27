"""The compiled free run and plant step give the same bits as the interpreted ones (issue 20).

* :func:`railsim.physics.plant_kernel.step` (the plant, written once) against its interpreted form on random
  states (speeds from standstill to over the top speed, commands beyond both envelopes, gradients, emergency,
  every step method, three vehicles including one without actuator lag): all seven outputs equal, mask included.
* :func:`railsim.engine.free_run_kernel.free_run` (through ``trips._free_run_compiled``) against
  :func:`railsim.engine.trips.free_run_reference`, whole trips: every distinct trip of the mini line at step
  lengths 0.1/0.5/1.0 s and the three step methods, at full performance and slowed (the running-time factors of
  :mod:`railsim.engine.primary_delays`), and the Line 3 peak's trips at 0.5 s. Planned arrival and departure
  dictionaries must be equal (same floats, same keys in the same order). (With the ballistic and forward step
  methods at 0.5–1 s, the line ATO — whose stop predictor is Euler's — may never halt inside a window on the
  mini line: both loops then run the 6 h limit and agree on that too.)
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from railsim.physics import dynamics, plant_kernel
from railsim.physics.vehicle import VehicleParams, preset
from tests.helpers import DATA, ROOT, interpreted, run_python

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


CHILD = r"""
import dataclasses, json, sys, tempfile
from pathlib import Path
from controllers.ato import Ato
from railsim.engine import trips as T
from railsim.engine.fleet import ato_factory
from railsim.engine.loop import Simulation
from railsim.engine.primary_delays import scaled_vehicle
from railsim.scenario.loading import load

scn = load(SCENARIO)
with tempfile.TemporaryDirectory() as out:
    sim = Simulation(scn, Path(out), progress=False)
seen, rows = set(), []
for tr in sim.trains.values():
    trip = tr.trip
    key = (trip.route.id, trip.stops, trip.start_offset_m, trip.start_speed_mps)
    if key in seen:
        continue
    seen.add(key)
    for factor in FACTORS:
        run = trip if factor == 1.0 else dataclasses.replace(trip, vehicle=scaled_vehicle(trip.vehicle, factor))
        for dt in STEPS:
            for method in METHODS:
                ato = ato_factory(sim.scenario, dict(trip.roles), trip.vehicle, method)()
                assert type(ato) is Ato
                fast = T._free_run_compiled(run, ato, dt, method, 6 * 3600.0)
                slow = T.free_run_reference(run, ato, dt, method, 6 * 3600.0)
                rows.append([method, list(fast[0].items()), list(fast[1].items()), list(slow[0].items()), list(slow[1].items())])
print(json.dumps(rows))
"""


@pytest.mark.parametrize(
    ("scenario", "steps", "methods", "factors"),
    [
        (DATA / "scenarios" / "mini_line.yaml", (0.1, 0.5, 1.0), dynamics.STEP_METHODS, (1.0, 0.9, 0.95)),
        (ROOT / "scenarios" / "chongqing_line3_peak.yaml", (0.5,), ("euler",), (1.0, 0.97)),
    ],
)
def test_compiled_free_run_is_the_reference_bit_for_bit(scenario, steps, methods, factors, tmp_path_factory) -> None:
    code = CHILD.replace("SCENARIO", repr(str(scenario))).replace("FACTORS", repr(factors))
    code = code.replace("STEPS", repr(steps)).replace("METHODS", repr(tuple(methods)))
    res = run_python(code, cache_dir=tmp_path_factory.mktemp("cache"))
    assert res.returncode == 0, res.stderr[-3000:]
    rows = json.loads(res.stdout.strip().splitlines()[-1])
    assert len(rows) >= len(steps) * len(methods) * len(factors) * 2  # at least two distinct trips
    for method, fast_arr, fast_dep, slow_arr, slow_dep in rows:
        assert fast_arr == slow_arr and fast_dep == slow_dep  # same floats (JSON keeps 17 digits), same order
        if method == "euler":  # whole runs compared (the line ATO's stop predictor is Euler's: with the other
            assert len(slow_arr) >= 3  # methods at 0.5-1 s it may never halt in a window, 6 h both ways)
