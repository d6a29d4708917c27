"""The compiled ATO law (:mod:`controllers.ato_kernel`) gives the same bits as the Python reference.

:meth:`Ato.decide` runs the numba transcription; :meth:`Ato.decide_reference` is the law as written. They must
agree exactly — the engine's golden outputs depend on it — on every branch: holding, cruising, restrictions
under and ahead of the train, stop points (screens, exact sums, the solver), the end of authority and its
emergency. Random states are drawn around those branches, and whole stops are flown closed-loop with each.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers.ato import Ato, AtoParams
from controllers.base import SpeedLimit
from railsim.physics import dynamics
from railsim.physics.vehicle import VehicleParams

VEHICLES = [
    VehicleParams("metro", 118.0, 2.3e5, davis_a_n=2000.0, davis_b_n_per_mps=60.0, davis_c_n_per_mps2=8.0),
    VehicleParams("stiff", 60.0, 1.0e5, jerk_limit_mps3=math.inf, actuator_time_constant_s=0.0),
    VehicleParams("slow", 200.0, 4.0e5, max_speed_mps=12.0, traction_max_power_w=8e5, jerk_limit_mps3=0.4),
]
PARAMS = [AtoParams(), AtoParams(speed_margin_mps=0.0, max_accel_mps2=0.8, planning_decel_fraction=1.0)]


def _bits(out: tuple[float, bool, str]) -> tuple[str, bool, str]:
    return (float(out[0]).hex(), bool(out[1]), out[2])


def _random_state(rng: np.random.Generator, veh: VehicleParams) -> tuple:
    x = float(rng.uniform(0.0, 3000.0))
    v = float(rng.choice([0.0, 1e-4, rng.uniform(0.0, 1.2), rng.uniform(0.0, veh.max_speed_mps * 1.05)]))
    applied = float(rng.uniform(-veh.emergency_decel_mps2, 1.2))
    grade = float(rng.choice([0.0, rng.uniform(-35.0, 35.0)]))
    line = float(rng.choice([veh.max_speed_mps, rng.uniform(8.0, 25.0)]))
    limits = []
    for _ in range(int(rng.integers(0, 4))):
        start = x + float(rng.uniform(-400.0, 1500.0))
        limits.append(SpeedLimit(start, start + float(rng.uniform(10.0, 800.0)), float(rng.uniform(3.0, 20.0))))
    limits.sort(key=lambda lim: lim.start_m)
    stop = None
    if rng.random() < 0.8:
        mark = x + float(rng.choice([rng.uniform(-3.0, 3.0), rng.uniform(0.0, 60.0), rng.uniform(0.0, 1500.0)]))
        start = mark - float(rng.uniform(0.0, 120.0))
        stop = (mark, start, mark + float(rng.uniform(0.0, 5.0)), bool(rng.random() < 0.1))
    authority = None
    if rng.random() < 0.6:
        authority = x + float(rng.choice([rng.uniform(-5.0, 30.0), rng.uniform(0.0, 400.0), rng.uniform(0.0, 3000.0)]))
    return x, v, applied, grade, line, tuple(limits), stop, authority


@pytest.mark.parametrize("dt", [0.1, 0.5, 1.0])
def test_kernel_matches_reference_on_random_states(dt: float) -> None:
    rng = np.random.default_rng(20)
    phases: set[str] = set()
    for k in range(4000):
        veh = VEHICLES[k % len(VEHICLES)]
        ato = Ato(PARAMS[(k // 3) % len(PARAMS)], veh)
        x, v, applied, grade, line, limits, stop, authority = _random_state(rng, veh)
        args = (veh, dt, x, v, applied, veh.length_m, grade, line, limits, stop, authority)
        fast, ref = ato.decide(*args), ato.decide_reference(*args)
        assert _bits(fast) == _bits(ref), args
        phases.add(ref[2])
    # every branch was compared ("brake" cannot arise: a braking sub-law below cruise also names its phase)
    assert phases == {"hold", "cruise", "restriction", "stop", "emergency"}


@pytest.mark.parametrize("veh", VEHICLES, ids=lambda v: v.name)
def test_whole_stops_fly_the_same_bits(veh: VehicleParams) -> None:
    """Closed loop through the plant: run to a stop 2 km on, behind an end of authority and a restriction, with
    each law; every command along the way is the same (so the solver's branches are compared where they
    matter: the approach and the final metres)."""
    ato = Ato(AtoParams(), veh)
    limits = (SpeedLimit(600.0, 900.0, 9.0),)
    runs = []
    for law in (ato.decide, ato.decide_reference):
        x, state, trace = 0.0, dynamics.PlantState(speed_mps=0.0), []
        for _ in range(2000):
            accel, emergency, phase = law(
                veh,
                0.5,
                x,
                state.speed_mps,
                state.applied_accel_mps2,
                veh.length_m,
                2.0,
                20.0,
                limits,
                (2000.0, 1990.0, 2002.0, False),
                2060.0,
            )
            res = dynamics.step(veh, state, accel, 0.5, 2.0, emergency)
            state, x = res.state, x + res.advance_m
            trace.append((accel.hex(), phase))
        runs.append((trace, x))
    assert runs[0] == runs[1]
    assert abs(runs[0][1] - 2000.0) < 0.5  # and it is a real stop on the mark
