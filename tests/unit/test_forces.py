"""The forces on a train (:mod:`railsim.physics.forces`): their closed forms, and one definition in two forms.

Each force law is written once, as a numba function; the plant, the line laws and the Python API
(:meth:`VehicleParams.resistance_n`, :func:`railsim.physics.dynamics.traction_limit_mps2`) all call it. Checked
here: the laws against their closed forms (Davis plus gradient, constant force then constant power), the
compiled form against the interpreted one (the module loaded with the JIT off) bit for bit, and the Python API
against the law it calls, ints included.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from railsim.physics import dynamics, forces
from railsim.physics.units import G_MPS2
from railsim.physics.vehicle import VehicleParams
from tests.helpers import interpreted

INTERPRETED = interpreted(forces)
VEH = VehicleParams(
    "t", 100.0, 2.0e5, davis_a_n=2500.0, davis_b_n_per_mps=40.0, davis_c_n_per_mps2=6.0, traction_max_power_w=1.6e6
)


def test_resistance_is_davis_plus_gradient_and_none_of_davis_standing() -> None:
    for v in (0.5, 7.0, 22.0):
        davis = VEH.davis_a_n + VEH.davis_b_n_per_mps * v + VEH.davis_c_n_per_mps2 * v * v
        assert VEH.resistance_n(v, 12.0) == pytest.approx(davis + VEH.mass_kg * G_MPS2 * 12.0 / 1000.0, rel=1e-15)
        assert VEH.resistance_n(-v, 12.0) == VEH.resistance_n(v, 12.0)  # the speed's magnitude counts
    assert VEH.resistance_n(0.0, 0.0) == 0.0
    assert VEH.resistance_n(0.0, -20.0) == forces.gradient_force_n(VEH.mass_kg, -20.0) < 0.0  # downhill pushes


def test_traction_is_constant_force_then_constant_power() -> None:
    corner_mps = VEH.traction_max_power_w / VEH.traction_max_force_n
    m_eff = VEH.effective_mass_kg
    assert forces.traction_force_n(VEH.traction_max_force_n, VEH.traction_max_power_w, 0.0) == (
        VEH.traction_max_force_n,
        False,
    )
    assert dynamics.traction_limit_mps2(VEH, 0.5 * corner_mps) == VEH.traction_max_force_n / m_eff
    force_n, power_limited = forces.traction_force_n(VEH.traction_max_force_n, VEH.traction_max_power_w, 2 * corner_mps)
    assert power_limited and force_n == VEH.traction_max_power_w / (2 * corner_mps)
    # continuous at the corner speed, falling beyond it
    below = dynamics.traction_limit_mps2(VEH, corner_mps * (1 - 1e-9))
    above = dynamics.traction_limit_mps2(VEH, corner_mps * (1 + 1e-9))
    assert below == pytest.approx(above, rel=1e-8) and above < below


def test_python_api_calls_the_law_and_takes_ints() -> None:
    ints = VehicleParams("ints", 100, 200000, davis_a_n=2500, davis_b_n_per_mps=40, davis_c_n_per_mps2=6)
    assert ints.resistance_n(10, 5) == VEH.resistance_n(10.0, 5.0)
    assert dynamics.traction_limit_mps2(ints, 3) == forces.traction_limit_mps2(
        2e5, ints.rotating_mass_factor, ints.traction_max_force_n, ints.traction_max_power_w, 3.0
    )


def _bits(value: float | tuple[float, bool]) -> list[str]:
    return [float(x).hex() for x in (value if isinstance(value, tuple) else (value,))]


@pytest.mark.parametrize("seed", [0, 1])
def test_compiled_forces_are_their_interpreted_form(seed: int) -> None:
    """Standing, crawling, running, beyond the design speed, both signs of the gradient: the same bits."""
    rng = np.random.default_rng(seed)
    for _ in range(3000):
        mass = float(rng.uniform(1e4, 8e5))
        a, b, c = (float(x) for x in rng.uniform(0.0, [5e3, 100.0, 12.0]))
        v = float(rng.choice([0.0, 1e-7, rng.uniform(-1.0, 1.0), rng.uniform(0.0, 40.0)]))
        grade = float(rng.choice([0.0, rng.uniform(-40.0, 40.0)]))
        f0, power, rot = float(rng.uniform(5e4, 5e5)), float(rng.uniform(2e5, 1e7)), float(rng.uniform(1.0, 1.15))
        calls = [
            ("gradient_force_n", (mass, grade)),
            ("resistance_n", (mass, a, b, c, v, grade)),
            ("traction_force_n", (f0, power, v)),
            ("traction_limit_mps2", (mass, rot, f0, power, v)),
        ]
        for name, args in calls:
            compiled, reference = getattr(forces, name)(*args), getattr(INTERPRETED, name)(*args)
            assert _bits(compiled) == _bits(reference), (name, args)


def test_the_plant_steps_with_these_forces() -> None:
    """One plant step by hand from the laws: coasting (no command) on a grade, resistance and gradient only."""
    v, grade, dt = 15.0, 8.0, 0.5
    res = dynamics.step(
        VehicleParams("lagless", 100.0, 2e5, davis_a_n=2500.0, actuator_time_constant_s=0.0),
        dynamics.PlantState(v),
        0.0,
        dt,
        grade,
    )
    m_eff = 2e5 * 1.08
    expected = v - forces.resistance_n(2e5, 2500.0, 0.0, 0.0, v, grade) / m_eff * dt
    assert res.v_next_mps == expected and math.isfinite(expected)
