"""The plant step, written once and compiled with numba: one train's step (:func:`step`), a fleet's (:func:`step_fleet`).

The model — the order of operations, the envelopes, the flags — is described in :mod:`railsim.physics.dynamics`,
whose :func:`~railsim.physics.dynamics.step`, :func:`~railsim.physics.dynamics.step_values` and
:func:`~railsim.physics.dynamics.step_many` check their inputs and call the functions here. The engine's compiled
loops (``railsim.engine.free_run_kernel``, ``railsim.engine.line_step_kernel``) call :func:`step` inside their own
code, where a step costs a few nanoseconds. The forces it applies — running resistance, gradient, the traction
envelope — are the laws of :mod:`railsim.physics.forces`, called here, not written again.

**Written once.** The interpreted form of :func:`step` (the module loaded with the JIT off,
``tests.helpers.interpreted``, or ``NUMBA_DISABLE_JIT=1``) is the readable reference, and it gives the same bits as
the compiled one: IEEE operations only, fastmath off, and the lag gain ``1 − e^{−dt/τ}`` computed once per
``(τ, dt)`` in Python (:func:`lag_gain`) and handed over packed. Inputs are not validated here: the callers check
what they hand over (:func:`railsim.physics.dynamics.step_values` raises its clear errors first).

The vehicle comes packed by :func:`pack` (:data:`PLANT_FIELDS`, then the lag gain); the step method as an index
into :data:`STEP_METHODS`.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numba import njit

from railsim.physics import forces
from railsim.physics.vehicle import VehicleParams

STEP_METHODS = ("euler", "ballistic", "forward")
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
# The saturation mask's bits, in the order of railsim.physics.dynamics._FLAG_ORDER (checked in the tests)
_B_TRACTION, _B_POWER, _B_OVERSPEED = 1, 2, 4
_B_BRAKE, _B_JERK, _B_OVERRIDE, _B_HOLD = 8, 16, 32, 64


@lru_cache(maxsize=256)
def lag_gain(tau_s: float, dt_s: float) -> float:
    """``1 − exp(−dt/τ)`` (computed as −expm1 for accuracy when dt ≪ τ); 1.0 for τ = 0."""
    if not tau_s >= 0.0:
        raise ValueError(f"actuator_time_constant_s must be >= 0, got {tau_s!r}")
    if tau_s == 0.0:
        return 1.0
    return -math.expm1(-dt_s / tau_s)


def pack(vehicle: VehicleParams, dt_s: float) -> np.ndarray:
    """The vehicle's plant parameters and the lag gain for ``dt_s``, as the kernel reads them."""
    gain = lag_gain(vehicle.actuator_time_constant_s, dt_s)
    return np.array([float(getattr(vehicle, f)) for f in PLANT_FIELDS] + [gain], dtype=np.float64)


def method_index(step_method: str) -> int:
    """The kernel's code for a step method (its index in :data:`STEP_METHODS`)."""
    return STEP_METHODS.index(step_method)


@njit(cache=True, inline="always")
def _clip(x: float, lower: float, upper: float, upper_bit: int) -> tuple[float, int]:
    """``x`` within ``[lower, upper]``, and the mask bit of the bound that clipped it (``upper_bit`` or the brake's;
    0 when neither did)."""
    if x > upper:
        return upper, upper_bit
    if x < lower:
        return lower, _B_BRAKE
    return x, 0


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
    """One step of one train (:mod:`railsim.physics.dynamics`, steps 1–6): ``(v_next, applied a_k, target u_k,
    net acceleration, advance, traction energy, saturation mask)``."""
    mass, rot, davis_a, davis_b, davis_c = p[0], p[1], p[2], p[3], p[4]
    max_speed, f0, power, service, emergency_decel, jerk, gain = p[5], p[6], p[7], p[8], p[9], p[10], p[11]
    m_eff = mass * rot
    mask = 0

    # 1. Envelope at the current speed (the traction envelope of railsim.physics.forces, cut at the design speed).
    if v >= max_speed:
        upper, upper_bit = 0.0, _B_OVERSPEED
    else:
        force_n, power_limited = forces.traction_force_n(f0, power, v)
        upper, upper_bit = force_n / m_eff, (_B_POWER if power_limited else _B_TRACTION)
    lower = -emergency_decel if emergency else -service
    u_env, bits = _clip(u_cmd_mps2, lower, upper, upper_bit)
    mask |= bits

    # 2. Jerk limit on the target (bypassed by emergency); the envelope has the last word.
    u = u_env
    if not emergency:
        du = jerk * dt_s
        if u > target_prev + du:
            u = target_prev + du
        elif u < target_prev - du:
            u = target_prev - du
        u, bits = _clip(u, lower, upper, upper_bit)
        if bits:
            mask |= bits | _B_OVERRIDE
        if u != u_env:
            mask |= _B_JERK

    # 3. First-order actuator lag (exact ZOH), then the physical envelope on the applied force.
    if gain == 1.0:
        a = u
    else:
        a, bits = _clip(applied_prev + (u - applied_prev) * gain, lower, upper, upper_bit)
        mask |= bits

    # 4.–5. Resistance (railsim.physics.forces) and speed; no rolling backwards, holding brake.
    a_net = a - forces.resistance_n(mass, davis_a, davis_b, davis_c, v, gradient_permille) / m_eff
    v_raw = v + a_net * dt_s
    if v_raw < 0.0 or (v == 0.0 and a <= 0.0 and v_raw > 0.0):
        v_next = 0.0
        mask |= _B_HOLD
    else:
        v_next = v_raw

    # 6. Position advance and energy.
    if method == 0:  # euler
        advance = v_next * dt_s
    elif method == 1:  # ballistic: SUMO's MSVehicle::getDeltaPos, (v + 0.5·ACCEL2SPEED(SPEED2ACCEL(Δv)))·dt
        advance = (v + 0.5 * ((v_next - v) / dt_s * dt_s)) * dt_s
    else:  # forward
        advance = v * dt_s
    energy = a * m_eff * (v + v_next) * 0.5 * dt_s if a > 0.0 else 0.0
    return v_next, a, u, (v_next - v) / dt_s, advance, energy, mask


@njit(cache=True)
def step_fleet(
    p: np.ndarray,
    v: np.ndarray,
    applied_prev: np.ndarray,
    target_prev: np.ndarray,
    u_cmd_mps2: np.ndarray,
    dt_s: float,
    gradient_permille: np.ndarray,
    emergency: np.ndarray,
    method: int,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`step` for every train ``i`` (row ``i`` of ``p``): a ``(6, n)`` array of the six float outputs (rows in
    :func:`step`'s order) and the ``n`` saturation masks."""
    n = v.shape[0]
    out = np.empty((6, n))
    mask = np.empty(n, dtype=np.int64)
    for i in range(n):
        v_next, a, u, net, advance, energy, m = step(
            p[i], v[i], applied_prev[i], target_prev[i], u_cmd_mps2[i], dt_s, gradient_permille[i], emergency[i], method
        )
        out[0, i], out[1, i], out[2, i], out[3, i], out[4, i], out[5, i] = v_next, a, u, net, advance, energy
        mask[i] = m
    return out, mask
