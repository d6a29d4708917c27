"""The forces on a train, written once and compiled with numba: running resistance, gradient, traction envelope.

Three laws every model of a train needs (:mod:`railsim.physics.vehicle` states them with their units):

* gradient resistance ``m·g·i/1000`` [N] for a gradient of ``i`` per mille, uphill positive
  (:func:`gradient_force_n`);
* running resistance plus gradient, ``R(v) = A + B·|v| + C·v² + m·g·i/1000`` [N], where a standing train feels no
  Davis term (static friction is not modelled) (:func:`resistance_n`);
* the traction envelope ``F_max(v) = min(F0, P/max(v, ε))`` [N]: constant force, then constant power
  (:func:`traction_force_n`, which also says which branch bounds it; :func:`traction_limit_mps2` divides by the
  effective mass).

**Written once.** These functions are the only definitions. The compiled laws call them inside their own code —
the plant step (:mod:`railsim.physics.plant_kernel`), the line ATO and separation
(:mod:`controllers.line_kernels`) — and the Python-facing API calls their interpreted form (the dispatcher's
``py_func``: the same text run by CPython, which costs less than a call into compiled code for one value):
:meth:`VehicleParams.resistance_n <railsim.physics.vehicle.VehicleParams.resistance_n>` and
:func:`railsim.physics.dynamics.traction_limit_mps2`. Both forms give the same bits (IEEE operations only,
fastmath off; ``tests/unit/test_forces.py``). Each is compiled for its one signature of floats when the module is
imported (from numba's disk cache after the first run), so a Python caller may pass ints or numpy scalars: they
are converted to floats, as the arithmetic would convert them anyway.
"""

from __future__ import annotations

from numba import njit

from railsim.physics.units import G_MPS2

# Floor on the speed in P/v: keeps the power branch finite at standstill (F0 caps the force there anyway).
SPEED_EPS_MPS = 1e-6


@njit("float64(float64, float64)", cache=True)
def gradient_force_n(mass_kg: float, gradient_permille: float) -> float:
    """Gradient resistance ``m·g·i/1000`` [N] (uphill positive: it holds the train back)."""
    return mass_kg * G_MPS2 * gradient_permille / 1000.0


@njit("float64(float64, float64, float64, float64, float64, float64)", cache=True)
def resistance_n(
    mass_kg: float,
    davis_a_n: float,
    davis_b_n_per_mps: float,
    davis_c_n_per_mps2: float,
    speed_mps: float,
    gradient_permille: float,
) -> float:
    """Davis running resistance at ``|speed_mps|`` plus :func:`gradient_force_n` [N]; no Davis term standing."""
    v = abs(speed_mps)
    davis = 0.0 if v == 0.0 else davis_a_n + davis_b_n_per_mps * v + davis_c_n_per_mps2 * v * v
    return davis + gradient_force_n(mass_kg, gradient_permille)


@njit("Tuple((float64, boolean))(float64, float64, float64)", cache=True)
def traction_force_n(max_force_n: float, max_power_w: float, speed_mps: float) -> tuple[float, bool]:
    """The largest tractive force ``min(F0, P/max(v, ε))`` [N], and whether the power branch bounds it."""
    power_force_n = max_power_w / (speed_mps if speed_mps > SPEED_EPS_MPS else SPEED_EPS_MPS)
    if max_force_n <= power_force_n:
        return max_force_n, False
    return power_force_n, True


@njit("float64(float64, float64, float64, float64, float64)", cache=True)
def traction_limit_mps2(
    mass_kg: float, rotating_mass_factor: float, max_force_n: float, max_power_w: float, speed_mps: float
) -> float:
    """Largest applied traction acceleration ``F_max(v)/m_eff`` [m/s²] (:func:`traction_force_n`; the traction
    cut at the design speed is not included: the plant applies it on top)."""
    force_n, _ = traction_force_n(max_force_n, max_power_w, speed_mps)
    return force_n / (mass_kg * rotating_mass_factor)
