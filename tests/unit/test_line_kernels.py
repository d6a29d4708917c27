"""The compiled line laws (:mod:`controllers.line_kernels`) give the same bits as their Python references.

:meth:`Ato.decide` and :meth:`Separation.decide` run the numba transcriptions; ``decide_reference`` is each law
as written. They must agree exactly — the engine's golden outputs depend on it — on every branch. ATO: holding,
cruising, restrictions under and ahead of the train, stop points (screens, exact sums, the solver), the end of
authority and its emergency. Separation: following, braking inside the curve, emergency, the final halt. Random
states are drawn around those branches, and whole runs are flown closed-loop with each.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers.ato import Ato, AtoParams
from controllers.base import Command, SpeedLimit
from controllers.separation import Separation, SeparationParams
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
        ato.use_position_update(("euler", "ballistic", "forward")[(k // 6) % 3])  # the lead's branches too
        x, v, applied, grade, line, limits, stop, authority = _random_state(rng, veh)
        tail = float(rng.choice([0.0, 0.0, rng.uniform(0.0, 150.0)]))  # a formation's length behind the train
        args = (veh, dt, x, v, applied, veh.length_m, grade, line, limits, stop, authority, tail)
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


SEPARATIONS = [SeparationParams(), SeparationParams(margin_m=0.0, reaction_time_s=0.0, barrier_rate_per_s=3.0)]


def _command_bits(cmd: Command) -> tuple:
    info = {k: (v.hex() if isinstance(v, float) else v) for k, v in cmd.info.items()}
    return (cmd.accel_mps2.hex(), cmd.emergency, cmd.fallback, cmd.additive, sorted(info.items()))


@pytest.mark.parametrize("dt", [0.1, 0.5, 1.0])
def test_separation_kernel_matches_reference_on_random_states(dt: float) -> None:
    rng = np.random.default_rng(21)
    phases: set[str] = set()
    for k in range(4000):
        veh = VEHICLES[k % len(VEHICLES)]
        if math.isinf(veh.jerk_limit_mps3):
            continue  # the reference's emergency ramp divides by the jerk limit: a finite one is required
        sep = Separation(SEPARATIONS[(k // 3) % len(SEPARATIONS)], veh)
        x = float(rng.uniform(0.0, 3000.0))
        v = float(rng.choice([0.0, rng.uniform(0.0, 0.6), rng.uniform(0.0, veh.max_speed_mps)]))
        a0 = float(rng.uniform(-veh.emergency_decel_mps2, 1.2))
        grade = float(rng.choice([0.0, rng.uniform(-35.0, 35.0)]))
        rear = x + float(rng.choice([rng.uniform(40.0, 60.0), rng.uniform(0.0, 300.0), rng.uniform(0.0, 3000.0)]))
        age = float(rng.choice([0.0, rng.uniform(0.0, 3.0)]))
        args = (veh, dt, x, v, a0, grade, rear, age)
        fast, ref = sep.decide(*args), sep.decide_reference(*args)
        assert _command_bits(fast) == _command_bits(ref), args
        phases.add(ref.info["phase"])
    assert phases == {"follow", "brake", "emergency", "halt"}


def test_a_follower_closes_up_the_same_way() -> None:
    """Closed loop: a follower runs up behind a train standing 1.5 km ahead; every command is the same."""
    veh = VEHICLES[0]
    sep = Separation(SeparationParams(), veh)
    runs = []
    for law in (sep.decide, sep.decide_reference):
        x, state, trace = 0.0, dynamics.PlantState(speed_mps=15.0), []
        for _ in range(1200):
            cmd = law(veh, 0.5, x, state.speed_mps, state.applied_accel_mps2, 0.0, 1500.0, 0.2)
            res = dynamics.step(veh, state, cmd.accel_mps2, 0.5, 0.0, cmd.emergency)
            state, x = res.state, x + res.advance_m
            trace.append(_command_bits(cmd))
        runs.append((trace, x))
    assert runs[0] == runs[1]
    assert 1500.0 - 50.0 - 5.0 < runs[0][1] <= 1500.0 - 50.0  # it halts just short of rear − margin
