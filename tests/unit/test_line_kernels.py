"""The line laws of :mod:`controllers.line_kernels`: written once, compiled, and their interpreted form is the same.

Each law is defined once (a numba function); its interpreted form — the same module loaded with the JIT off
(:func:`tests.helpers.interpreted`) — is the readable reference, and the compiled form must give the same bits on
every branch (the engine's golden outputs depend on it): ATO holding, cruising, restrictions under and ahead of the
train, stop points (screens, exact sums, the solver), the end of authority and its emergency; separation following,
braking inside the curve, emergency, the final halt; the braking curves on their own. Whole runs are flown
closed-loop through the plant and must do what the laws promise (stop on the mark, halt short of rear − margin).
The braking curves' closed forms (stopping distance, the plant's recursion, the curve's inverse) are tested in
``tests/unit/test_controllers_line.py``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers import braking, line_kernels
from controllers.ato import NO_STOP, Ato, AtoParams, limits_array_cached
from controllers.base import SpeedLimit
from controllers.separation import Separation, SeparationParams
from railsim.physics import dynamics
from railsim.physics.vehicle import VehicleParams
from tests.helpers import interpreted

INTERPRETED = interpreted(line_kernels)

VEHICLES = [
    VehicleParams("metro", 118.0, 2.3e5, davis_a_n=2000.0, davis_b_n_per_mps=60.0, davis_c_n_per_mps2=8.0),
    VehicleParams("stiff", 60.0, 1.0e5, jerk_limit_mps3=math.inf, actuator_time_constant_s=0.0),
    VehicleParams("slow", 200.0, 4.0e5, max_speed_mps=12.0, traction_max_power_w=8e5, jerk_limit_mps3=0.4),
]
PARAMS = [AtoParams(), AtoParams(speed_margin_mps=0.0, max_accel_mps2=0.8, planning_decel_fraction=1.0)]


def _bits(values: tuple) -> tuple:
    return tuple(float(x).hex() if isinstance(x, float) else x for x in values)


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


def line_ahead_args(
    limits: tuple[SpeedLimit, ...], stop: tuple[float, float, float, bool] | None, authority: float | None, tail: float
) -> tuple:
    """The ATO kernel's last inputs, what the train knows of the line ahead, as the engine hands them: the
    restrictions, the next stop (``has_stop`` and its four values), the end of authority, the formation's tail."""
    return (
        limits_array_cached(limits),
        stop is not None,
        *(stop if stop is not None else NO_STOP),
        authority is not None,
        authority if authority is not None else 0.0,
        tail,
    )


@pytest.mark.parametrize("dt", [0.1, 0.5, 1.0])
def test_compiled_ato_is_its_interpreted_form_on_random_states(dt: float) -> None:
    rng = np.random.default_rng(20)
    phases: set[str] = set()
    for k in range(4000):
        veh = VEHICLES[k % len(VEHICLES)]
        ato = Ato(PARAMS[(k // 3) % len(PARAMS)], veh)
        ato.use_position_update(("euler", "ballistic", "forward")[(k // 6) % 3])  # the lead's branches too
        x, v, applied, grade, line, limits, stop, authority = _random_state(rng, veh)
        tail = float(rng.choice([0.0, 0.0, rng.uniform(0.0, 150.0)]))  # a formation's length behind the train
        args = (
            ato.packed(veh, dt),
            x,
            v,
            applied,
            veh.length_m,
            grade,
            line,
            *line_ahead_args(limits, stop, authority, tail),
        )
        compiled, reference = line_kernels.ato(*args), INTERPRETED.ato(*args)
        assert _bits(compiled) == _bits(reference), args
        phases.add(line_kernels.ATO_PHASES[reference[2]])
    # every branch was compared ("brake" cannot arise: a braking sub-law below cruise also names its phase)
    assert phases == {"hold", "cruise", "restriction", "stop", "emergency"}


@pytest.mark.parametrize("veh", VEHICLES, ids=lambda v: v.name)
def test_whole_stops_land_on_the_mark_the_same_in_both_forms(veh: VehicleParams) -> None:
    """Closed loop through the plant: run to a stop 2 km on, behind an end of authority and a restriction. The
    train stands on the mark, never exceeds the restriction by more than its margin's worth, never brakes in
    emergency; and the interpreted law flies the same run, command for command (so the solver's branches are
    compared where they matter: the approach and the final metres)."""
    ato = Ato(AtoParams(), veh)
    limits = (SpeedLimit(600.0, 900.0, 9.0),)
    runs = []
    for law in (line_kernels.ato, INTERPRETED.ato):
        x, state, trace = 0.0, dynamics.PlantState(speed_mps=0.0), []
        for _ in range(2000):
            accel, emergency, phase = law(
                ato.packed(veh, 0.5),
                x,
                state.speed_mps,
                state.applied_accel_mps2,
                veh.length_m,
                2.0,
                20.0,
                limits_array_cached(limits),
                True,
                2000.0,
                1990.0,
                2002.0,
                False,
                True,
                2060.0,
                0.0,
            )
            assert not emergency
            res = dynamics.step(veh, state, accel, 0.5, 2.0, emergency)
            state, x = res.state, x + res.advance_m
            if 600.0 <= x < 900.0 + veh.length_m:
                assert state.speed_mps <= 9.0 + 0.05, (x, state.speed_mps)  # the restriction, rear rule
            trace.append((accel.hex(), phase))
        runs.append((trace, x))
    assert runs[0] == runs[1]
    assert abs(runs[0][1] - 2000.0) < 0.5  # a real stop on the mark
    assert runs[0][0][-1][1] == line_kernels.ATO_PHASES.index("hold")


SEPARATIONS = [SeparationParams(), SeparationParams(margin_m=0.0, reaction_time_s=0.0, barrier_rate_per_s=3.0)]


@pytest.mark.parametrize("dt", [0.1, 0.5, 1.0])
def test_compiled_separation_is_its_interpreted_form_on_random_states(dt: float) -> None:
    rng = np.random.default_rng(21)
    phases: set[str] = set()
    for k in range(4000):
        veh = VEHICLES[k % len(VEHICLES)]
        if math.isinf(veh.jerk_limit_mps3):
            continue  # the emergency ramp divides by the jerk limit: a finite one is required
        sep = Separation(SEPARATIONS[(k // 3) % len(SEPARATIONS)], veh)
        x = float(rng.uniform(0.0, 3000.0))
        v = float(rng.choice([0.0, rng.uniform(0.0, 0.6), rng.uniform(0.0, veh.max_speed_mps)]))
        a0 = float(rng.uniform(-veh.emergency_decel_mps2, 1.2))
        grade = float(rng.choice([0.0, rng.uniform(-35.0, 35.0)]))
        rear = x + float(rng.choice([rng.uniform(40.0, 60.0), rng.uniform(0.0, 300.0), rng.uniform(0.0, 3000.0)]))
        age = float(rng.choice([0.0, rng.uniform(0.0, 3.0)]))
        args = (sep.packed(veh, dt), x, v, a0, grade, rear, age)
        compiled, reference = line_kernels.separation(*args), INTERPRETED.separation(*args)
        assert _bits(compiled) == _bits(reference), args
        phases.add(line_kernels.SEPARATION_PHASES[reference[2]])
    assert phases == {"follow", "brake", "emergency", "halt"}


def test_a_follower_closes_up_and_halts_short_of_rear_minus_margin() -> None:
    """Closed loop: a follower runs up behind a train standing 1.5 km ahead (its rear known 0.2 s late). It never
    passes rear − margin, never brakes in emergency, ends standing within a few metres of that point, and the
    interpreted law flies the same run, command for command."""
    veh = VEHICLES[0]
    sep = Separation(SeparationParams(), veh)
    runs = []
    for law in (line_kernels.separation, INTERPRETED.separation):
        x, state, trace = 0.0, dynamics.PlantState(speed_mps=15.0), []
        for _ in range(1200):
            out = law(sep.packed(veh, 0.5), x, state.speed_mps, state.applied_accel_mps2, 0.0, 1500.0, 0.2)
            assert not out[1]
            res = dynamics.step(veh, state, out[0], 0.5, 0.0, out[1])
            state, x = res.state, x + res.advance_m
            assert x <= 1500.0 - 50.0
            trace.append(_bits(out))
        runs.append((trace, x, state.speed_mps))
    assert runs[0] == runs[1]
    assert 1500.0 - 50.0 - 5.0 < runs[0][1] <= 1500.0 - 50.0 and runs[0][2] == 0.0


@pytest.mark.parametrize("dt", [0.1, 0.5, 1.0])
def test_compiled_braking_curves_are_their_interpreted_form(dt: float) -> None:
    """The braking curves on their own, over the whole input range the laws feed them (standing, creeping,
    coasting, braking hard, steep gradients, no lag), with the net braking they plan with and the coupled
    follower's relative braking distance: the same bits compiled and interpreted."""
    rng = np.random.default_rng(22)
    for _ in range(3000):
        v = float(rng.choice([0.0, rng.uniform(0.0, 1.0), rng.uniform(0.0, 30.0)]))
        a0 = float(rng.uniform(-1.5, 1.2))
        b = float(rng.choice([1e-5, rng.uniform(0.01, 1.5)]))
        delay = float(rng.uniform(0.0, 4.0))
        target = float(rng.choice([0.0, rng.uniform(0.0, 20.0)]))
        d = float(rng.choice([rng.uniform(-5.0, 30.0), rng.uniform(0.0, 3000.0)]))
        tau = float(rng.choice([0.0, rng.uniform(0.1, 1.0)]))
        jerk = float(rng.choice([math.inf, rng.uniform(0.3, 2.0)]))
        r = math.exp(-dt / tau) if tau > 0.0 else 0.0
        veh = VEHICLES[int(rng.integers(len(VEHICLES)))]
        grade = float(rng.choice([0.0, rng.uniform(-35.0, 35.0)]))
        resistance = (
            veh.mass_kg,
            veh.rotating_mass_factor,
            veh.davis_a_n,
            veh.davis_b_n_per_mps,
            veh.davis_c_n_per_mps2,
        )
        v_lead, b_lead, margin = (
            float(rng.uniform(-1.0, 30.0)),
            float(rng.uniform(0.05, 2.0)),
            float(rng.uniform(0, 50)),
        )
        calls = [
            ("net_braking_mps2", (b, *resistance, grade, bool(rng.random() < 0.5), v)),
            ("relative_braking_distance_m", (v, v_lead, b, b_lead, delay, a0, margin)),
            ("build_up_delay_s", (a0, b, tau, jerk, delay)),
            ("stopping_distance_m", (v, b, delay, a0, target)),
            ("allowed_speed_mps", (d, b, delay, a0, target)),
            ("required_decel_mps2", (v, d, delay, a0, target)),
            ("discrete_stop_distance_m", (v, a0, b, dt, r)),
            ("discrete_stop_distance_bound_m", (v, a0, b, dt, r)),
            ("required_decel_surely_below", (v, a0, d, dt, r, b)),
            ("discrete_required_decel_mps2", (v, a0, d, dt, tau, r, 1.2)),
        ]
        for name, args in calls:
            compiled, reference = getattr(line_kernels, name)(*args), getattr(INTERPRETED, name)(*args)
            assert _bits((compiled,)) == _bits((reference,)), (name, args)


def test_net_braking_is_the_brake_plus_gradient_and_davis_where_asked() -> None:
    """Closed form: the applied brake plus the gradient resistance (and Davis at the given speed) over the
    effective mass; a downhill reduces it, and the Davis term only ever adds."""
    veh = VEHICLES[0]
    m_eff = veh.effective_mass_kg
    for grade in (-30.0, 0.0, 12.0):
        plain = braking.net_braking_mps2(veh, 1.0, grade)
        assert plain == pytest.approx(1.0 + veh.mass_kg * 9.81 * grade / 1000.0 / m_eff, rel=1e-12)
        with_davis = braking.net_braking_mps2(veh, 1.0, grade, davis_speed_mps=15.0)
        assert with_davis == pytest.approx(1.0 + veh.resistance_n(15.0, grade) / m_eff, rel=1e-15)
        assert with_davis > plain
    assert braking.net_braking_mps2(veh, 1.0, -30.0) < 1.0 < braking.net_braking_mps2(veh, 1.0, 12.0)
    # at a standstill (a crawl, 1e-9 m/s) only Davis's constant term acts
    crawl = braking.net_braking_mps2(veh, 1.0, 0.0, davis_speed_mps=0.0)
    assert crawl == pytest.approx(1.0 + veh.davis_a_n / m_eff, rel=1e-9)
