"""The plant step compiled with numba, bit for bit: :func:`railsim.physics.dynamics.step_values` on packed inputs.

Why: a loop that steps one train thousands of times — a trip's free run (the plan, and every primarily delayed
trip's running-time loss, :mod:`railsim.engine.free_run_kernel`) — pays the interpreter for every float
operation of every step. Called from other compiled code the step costs a few nanoseconds.

**Bit for bit**, as :mod:`controllers.line_kernels`: the same operands in the same order, IEEE operations only
(the lag gain ``1 − e^{−dt/τ}`` is the caller's, from :func:`dynamics._lag_gain`). Inputs are not validated here:
callers check what they hand over (a non-finite command falls back to the interpreted step, which raises its
clear error). ``tests/unit/test_free_run_kernel.py`` compares it with :func:`dynamics.step_values` on random states.

The vehicle comes packed by :func:`pack` (:data:`PLANT_FIELDS`, then the lag gain); the step method as an index
into :data:`dynamics.STEP_METHODS`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from railsim.physics import dynamics
from railsim.physics.units import G_MPS2
from railsim.physics.vehicle import VehicleParams

PLANT_FIELDS = (
    "mass_kg",
    "rotating_mass_factor",
    "davis_a_n",
    "davis_b_n_per_mps",
    "davis_c_n_per_mps2",
    "max_speed_mps",
    "traction_max_force_n",
    "traction_max_power_w",
    "service_decel_mps2",
    "emergency_decel_mps2",
    "jerk_limit_mps3",
)
_SPEED_EPS_MPS = dynamics.SPEED_EPS_MPS
_G = G_MPS2
_B_TRACTION, _B_POWER, _B_OVERSPEED = 1, 2, 4  # dynamics._FLAG_ORDER's bits (checked in the test)
_B_BRAKE, _B_JERK, _B_OVERRIDE, _B_HOLD = 8, 16, 32, 64


def pack(vehicle: VehicleParams, dt_s: float) -> np.ndarray:
    """The vehicle's plant parameters and the lag gain for ``dt_s``, as the kernel reads them."""
    gain = dynamics._lag_gain(vehicle.actuator_time_constant_s, dt_s)
    return np.array([float(getattr(vehicle, f)) for f in PLANT_FIELDS] + [gain], dtype=np.float64)


def method_index(step_method: str) -> int:
    """The kernel's code for a step method (its index in :data:`dynamics.STEP_METHODS`)."""
    return dynamics.STEP_METHODS.index(step_method)


@njit(cache=True)
def step(
    p: np.ndarray,
    v: float,
    applied_prev: float,
    target_prev: float,
    u_cmd_mps2: float,
    dt_s: float,
    gradient_permille: float,
    emergency: bool,
    method: int,
) -> tuple[float, float, float, float, float, float, int]:
    """:func:`dynamics.step_values`: ``(v_next, applied a_k, target u_k, net acceleration, advance, traction
    energy, saturation mask)``."""
    mass, rot, davis_a, davis_b, davis_c = p[0], p[1], p[2], p[3], p[4]
    max_speed, f0, power, service, emergency_decel, jerk, gain = p[5], p[6], p[7], p[8], p[9], p[10], p[11]
    m_eff = mass * rot
    mask = 0
    upper_bit = 0
    if v >= max_speed:
        upper, upper_bit = 0.0, _B_OVERSPEED
    else:
        power_force_n = power / (v if v > _SPEED_EPS_MPS else _SPEED_EPS_MPS)
        if f0 <= power_force_n:
            upper, upper_bit = f0 / m_eff, _B_TRACTION
        else:
            upper, upper_bit = power_force_n / m_eff, _B_POWER
    lower = -emergency_decel if emergency else -service

    u_env = u_cmd_mps2
    if u_env > upper:
        u_env = upper
        mask |= upper_bit
    elif u_env < lower:
        u_env = lower
        mask |= _B_BRAKE

    u = u_env
    if not emergency:
        du = jerk * dt_s
        if u > target_prev + du:
            u = target_prev + du
        elif u < target_prev - du:
            u = target_prev - du
        if u > upper:
            u = upper
            mask |= upper_bit | _B_OVERRIDE
        elif u < lower:
            u = lower
            mask |= _B_BRAKE | _B_OVERRIDE
        if u != u_env:
            mask |= _B_JERK

    if gain == 1.0:
        a = u
    else:
        a = applied_prev + (u - applied_prev) * gain
        if a > upper:
            a = upper
            mask |= upper_bit
        elif a < lower:
            a = lower
            mask |= _B_BRAKE

    speed = abs(v)
    davis = 0.0 if speed == 0.0 else davis_a + davis_b * speed + davis_c * speed * speed
    resistance_n = davis + mass * _G * gradient_permille / 1000.0
    a_net = a - resistance_n / m_eff
    v_raw = v + a_net * dt_s
    if v_raw < 0.0 or (v == 0.0 and a <= 0.0 and v_raw > 0.0):
        v_next = 0.0
        mask |= _B_HOLD
    else:
        v_next = v_raw

    if method == 0:  # euler
        advance = v_next * dt_s
    elif method == 1:  # ballistic
        advance = (v + 0.5 * ((v_next - v) / dt_s * dt_s)) * dt_s
    else:  # forward
        advance = v * dt_s
    energy = a * m_eff * (v + v_next) * 0.5 * dt_s if a > 0.0 else 0.0
    return v_next, a, u, (v_next - v) / dt_s, advance, energy, mask
