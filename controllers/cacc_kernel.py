"""The CACC law, written once and compiled with numba: gap tracking under the relative-braking-distance cap.

:class:`controllers.cacc.Cacc` explains the law (the tracking law in cascade form, the ``safe`` gap policy, the
worst-case extrapolated predecessor and the barrier on the relative braking distance); this module is where it is
*written*, once. ``Cacc.command`` reconstructs the predecessor's command (it keeps that piece of state between
steps), packs the gains and the vehicle once per (vehicle, step length) and calls :func:`cacc` — one compiled call
instead of some forty float operations and eight calls of compiled force and braking functions in the interpreter.

The interpreted form of :func:`cacc` (the dispatcher's ``py_func``, or ``NUMBA_DISABLE_JIT=1``) is the readable
reference and gives the same bits as the compiled one, as for the line laws (:mod:`controllers.line_kernels`): IEEE
operations and ``√`` only, fastmath off, ``min``/``max`` as :func:`~controllers.line_kernels._mn`/``_mx`` (the first
argument on ties). The forces are :mod:`railsim.physics.forces`'s and the relative braking distance is
:func:`controllers.line_kernels.relative_braking_distance_m`: no second definition of either.
``tests/unit/test_cacc_kernel.py`` holds the compiled form to the interpreted one over random states and the law to
its closed-form pieces.

Inputs: :data:`CACC_FIELDS` packed by :func:`pack`; the own state (position, speed, applied acceleration, gradient);
the predecessor as reported (rear, speed, applied acceleration, emergency deceleration, message age); the
feed-forward acceleration ``a_p_applied`` the caller chose (plan entry, reconstructed command or reported value);
the target gap; and whether the gap is tracked (``False`` while stopping behind a standing leader: only the safety
cap acts). Output: ``(applied accel, emergency, phase index into PHASES, gap, gap error, barrier h, target gap)``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from controllers.line_kernels import _mn, _mx, net_braking_mps2, relative_braking_distance_m
from railsim.physics import forces

PHASES = ("track", "safety", "emergency")
_TRACK, _SAFETY, _EMERGENCY = range(3)
CACC_FIELDS = (
    # the vehicle
    "mass_kg",
    "rotating_mass_factor",
    "davis_a_n",
    "davis_b_n_per_mps",
    "davis_c_n_per_mps2",
    "traction_max_force_n",
    "traction_max_power_w",
    "service_decel_mps2",
    "emergency_decel_mps2",
    "actuator_time_constant_s",
    # the gains and safety parameters (controllers.cacc.CaccParams)
    "k_gap_per_s2",
    "k_speed_per_s",
    "k_ff",
    "approach_speed_mps",
    "approach_decel_mps2",
    "safety_margin_m",
    "reaction_time_s",
    "barrier_rate_per_s",
    "gap_buffer_m",
    "safe_policy",  # 1.0: gap_policy "safe", 0.0: "constant"
    "dt_s",
)
(
    _M,
    _ROT,
    _DA,
    _DB,
    _DC,
    _F0,
    _P,
    _SERVICE,
    _EMERG,
    _TAU,
    _K_GAP,
    _K_SPEED,
    _K_FF,
    _APPROACH_V,
    _APPROACH_D,
    _MARGIN,
    _REACTION,
    _GAMMA,
    _BUFFER,
    _SAFE,
    _DT,
) = range(len(CACC_FIELDS))


def pack(vehicle: object, params: object, dt_s: float) -> np.ndarray:
    """The law's float inputs (:data:`CACC_FIELDS`) for one vehicle, one set of gains and one step length."""
    values = []
    for name in CACC_FIELDS:
        if name == "safe_policy":
            values.append(1.0 if params.gap_policy == "safe" else 0.0)  # type: ignore[attr-defined]
        elif name == "dt_s":
            values.append(float(dt_s))
        else:
            values.append(float(getattr(vehicle, name) if hasattr(vehicle, name) else getattr(params, name)))
    return np.array(values, dtype=np.float64)


@njit(cache=True)
def cacc(
    p: np.ndarray,
    x: float,
    speed_mps: float,
    a0: float,
    grade: float,
    pred_rear_m: float,
    pred_speed_mps: float,
    pred_accel_mps2: float,
    pred_emergency_decel_mps2: float,
    pred_age_s: float,
    a_p_applied: float,
    target_gap_m: float,
    tracking: bool,
) -> tuple[float, bool, int, float, float, float, float]:
    """One CACC decision on packed inputs (module docstring): ``(accel, emergency, phase, gap, error, h, target)``."""
    mass, rot = p[_M], p[_ROT]
    m_eff = mass * rot
    v = _mx(speed_mps, 0.0)
    traction = forces.traction_limit_mps2(mass, rot, p[_F0], p[_P], v)
    tau = p[_TAU]
    dt = p[_DT]
    age_s = _mx(pred_age_s, 0.0)
    v_p = _mx(pred_speed_mps, 0.0)
    rho_p = forces.resistance_n(mass, p[_DA], p[_DB], p[_DC], v_p, grade) / m_eff  # own Davis as proxy
    # ---- relative-braking-distance quantities (shared by the gap policy and the safety cap)
    b_f = _mx(net_braking_mps2(p[_EMERG], mass, rot, p[_DA], p[_DB], p[_DC], grade, True, 0.0), 0.05)
    b_p = _mx(pred_emergency_decel_mps2 + rho_p, 0.05)
    v_pw = _mx(v_p - b_p * age_s, 0.0)
    rear_w = pred_rear_m + (v_p * v_p - v_pw * v_pw) / (2.0 * b_p)
    delay_s = tau + p[_REACTION] + dt  # a command holds for a whole step (zero-order hold)
    target_m = target_gap_m
    if p[_SAFE] != 0.0:
        # steady cruise at v: the applied acceleration is the resistance feed-forward, which keeps acting through
        # the braking delay (the barrier below uses the same a0)
        a_cruise = forces.resistance_n(mass, p[_DA], p[_DB], p[_DC], v, grade) / m_eff
        steady_m = relative_braking_distance_m(v, v, b_f, b_p, delay_s, a_cruise, p[_MARGIN]) + v * age_s
        target_m = _mx(target_m, steady_m + p[_BUFFER])
    gap_m = pred_rear_m + v_p * age_s - x
    error_m = gap_m - target_m
    v_close = p[_K_GAP] / p[_K_SPEED] * error_m
    if error_m > 0.0:
        v_close = _mn(_mn(v_close, p[_APPROACH_V]), math.sqrt(2.0 * p[_APPROACH_D] * error_m))
    track_net = p[_K_SPEED] * (v_p + v_close - v) + p[_K_FF] * (a_p_applied - rho_p)
    if not tracking:
        track_net = math.inf  # stopping behind a standing leader: the ATO stops us, we only guard safety
    rbd_m = relative_braking_distance_m(v, v_pw, b_f, b_p, delay_s, a0, p[_MARGIN])
    h = rear_w - x - rbd_m
    a_p_net = _mx(pred_accel_mps2 - rho_p, -b_p) if v_pw > 0.0 else 0.0
    slope_s = delay_s + _mx(v + a0 * delay_s, 0.0) / b_f
    # γ·dt ≤ 0.5: a sampled barrier with γ·dt near 1 rings (limit cycle) against the lagged plant
    gamma = _mn(p[_GAMMA], 0.5 / dt)
    numer = (v_p - v) + v_pw / b_p * a_p_net + gamma * h
    if slope_s > 0.0:
        cap_net = numer / slope_s
    else:
        cap_net = math.inf if numer >= 0.0 else -math.inf
    service_net = net_braking_mps2(p[_SERVICE], mass, rot, p[_DA], p[_DB], p[_DC], grade, True, v)
    if cap_net < -service_net and v > 0.0:
        return -p[_EMERG], True, _EMERGENCY, gap_m, error_m, h, target_m
    net = track_net
    phase = _TRACK
    if cap_net < track_net:
        net = cap_net
        phase = _SAFETY
    if math.isinf(net):
        return traction, False, phase, gap_m, error_m, h, target_m
    applied = net + forces.resistance_n(mass, p[_DA], p[_DB], p[_DC], v, grade) / m_eff
    return _mn(_mx(applied, -p[_SERVICE]), traction), False, phase, gap_m, error_m, h, target_m
