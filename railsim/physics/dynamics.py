"""The longitudinal train model (the *plant*): from a commanded acceleration to the next speed and position.

SUMO moves controlled trains (speedMode 32) by exactly the speed we set and enforces no physics at all
(docs/architecture.md), so every physical limit of a train lives here. Controllers command the **applied** specific
force ``u`` [m/s²] — traction (>0) or braking (<0) force divided by the effective mass — and running resistance
and gradient act on top of it, as in the papers' models ``dv/dt = u − ω(v)`` (spec 000 eq. (1), spec 002 eq. (1)).
The plant reads the same :class:`~railsim.physics.vehicle.VehicleParams` as the controllers' prediction models (one
definition of the physics; the resistance is :meth:`VehicleParams.resistance_n` itself).

One step of length ``dt`` from speed ``v_k`` — **in this order** (controllers may rely on it):

1. **Envelope clip** of the command ``u_cmd`` at the current speed ``v_k``:

   * traction: ``u ≤ F_max(v_k)/m_eff`` with ``F_max(v) = min(F0, P/max(v, ε))`` (constant force, then
     constant power); flag ``traction_limited`` when the constant-force branch clipped, ``power_limited``
     when the constant-power branch clipped (the two are exclusive);
   * traction cut at the design speed: once ``v_k ≥ max_speed_mps`` the bound becomes ``u ≤ 0`` (flag
     ``overspeed_cut`` instead of the two above). Only traction is cut; the plant never brakes on its own, so a
     down gradient may still push the train past ``max_speed_mps`` (the ATO must brake);
   * braking: ``u ≥ −service_decel_mps2``, or ``u ≥ −emergency_decel_mps2`` when the command is flagged
     emergency (flag ``brake_limited``).

   ``±inf`` is a valid command ("as much as the envelope allows"); NaN is rejected.
2. **Jerk limit** on the *target* acceleration: ``|u_k − u_{k−1}| ≤ jerk_limit_mps3·dt`` (flag ``jerk_limited``
   when it changed the target). An emergency command bypasses it (the target jumps to the clipped command).
   The envelope is a hard limit (physics, overspeed protection) and the jerk limit a comfort limit, so when
   the previous target lies outside the current envelope — the traction cut at ``max_speed_mps``, an
   emergency brake being released to service braking — the envelope wins: the target is clipped again and
   the step may exceed the jerk limit (flag ``jerk_overridden`` plus the envelope's flag). This is the only
   way a non-emergency step can break the jerk limit.
3. **First-order actuator lag** (time constant ``τ = actuator_time_constant_s``), the papers' "actuator
   delay", applied to the *applied* acceleration: ``a_k = a_{k−1} + (u_k − a_{k−1})·(1 − exp(−dt/τ))``, the
   exact zero-order-hold discretisation of ``τ·da/dt = u − a`` over one step; ``τ = 0`` gives ``a_k = u_k``.
   Reading: ``a_k`` is the lag state at the end of the step and acts over the whole step (for a step
   command the applied acceleration equals ``1 − exp(−t/τ)`` at the sample times ``t = (k+1)·dt``). The
   lagged value is clipped to the envelope once more (a traction force can never exceed ``F_max(v_k)``,
   whatever the lag remembers), with the same flags.
4. **Net acceleration** ``a_net = a_k − R(v_k, gradient)/m_eff`` (Davis + gradient, explicit in ``v_k``).
5. **Speed** ``v_{k+1} = v_k + a_net·dt``, never negative — trains do not roll backwards:

   * a standing train (``v_k = 0``) is held by its holding brake unless the applied traction is positive and
     exceeds the resistance (``a_k > 0`` and ``a_net > 0``); so a train on a 30 ‰ down gradient with zero
     command stays put, but once moving the gradient acts on it like any other force;
   * an update that would cross zero stops the train: ``v_{k+1} = 0``.

   Flag ``standstill_hold`` exactly when this rule changed ``v_{k+1}`` (a train standing on level track with
   zero command is not flagged: nothing was held back).
6. **Report** (:class:`StepResult`): ``v_{k+1}``, ``a_k``, ``u_k``, the realised net acceleration
   ``(v_{k+1} − v_k)/dt``, the position advance under the chosen ``step_method``, the traction energy of the
   step ``max(0, a_k·m_eff)·(v_k + v_{k+1})/2·dt`` [J] (mechanical work at the wheel; it equals force × the
   *ballistic* distance) and the saturation flags.

Position update (``step_method``) — which discrete model a run uses must match SUMO's and the paper's:

* ``"euler"`` — SUMO's default semi-implicit Euler: ``x_{k+1} = x_k + v_{k+1}·dt``;
* ``"ballistic"`` — SUMO's ``--step-method.ballistic``: ``x_{k+1} = x_k + (v_k + v_{k+1})/2·dt``; with constant
  ``u`` this is the exact zero-order hold ``x + v·T + u·T²/2`` of spec 000 §2.1 eq. (2) and spec 003 eq. (17);
  it is evaluated with SUMO's own operation order so positions agree to the last bit;
* ``"forward"`` — explicit Euler ``x_{k+1} = x_k + v_k·dt`` of spec 002 eq. (1). SUMO has no such mode: the
  engine reproduces it with the spec 002 §7.3 adapter (set SUMO's speed to ``v_k`` under the Euler update and
  keep ``v_{k+1}`` one step ahead in Python).

Units are SI throughout. :func:`step` is pure float arithmetic (no numpy) because the engine calls it for every
train every step; :func:`step_many` is the same plant over numpy arrays for many trains at once and gives
bit-identical results; :func:`simulate` runs one train open-loop or under a callable law (numpy-only paper
reproductions and tests).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from railsim.physics.vehicle import G_MPS2, VehicleParams

__all__ = [
    "BRAKE_LIMITED",
    "JERK_LIMITED",
    "JERK_OVERRIDDEN",
    "OVERSPEED_CUT",
    "POWER_LIMITED",
    "SATURATION_FLAGS",
    "STANDSTILL_HOLD",
    "STEP_METHODS",
    "TRACTION_LIMITED",
    "FleetParams",
    "FleetStepResult",
    "PlantState",
    "StepResult",
    "brake_limit_mps2",
    "braking_distance_m",
    "flags_from_mask",
    "simulate",
    "step",
    "step_many",
    "step_values",
    "traction_limit_mps2",
]

# Floor on the speed in P/v: keeps the power branch finite at standstill (F0 caps the force there anyway).
SPEED_EPS_MPS = 1e-6

STEP_METHODS = ("euler", "ballistic", "forward")

TRACTION_LIMITED = "traction_limited"
POWER_LIMITED = "power_limited"
OVERSPEED_CUT = "overspeed_cut"
BRAKE_LIMITED = "brake_limited"
JERK_LIMITED = "jerk_limited"
JERK_OVERRIDDEN = "jerk_overridden"
STANDSTILL_HOLD = "standstill_hold"

# Bit order of the saturation mask used by step_many (and internally by step, to reuse frozensets).
_FLAG_ORDER = (
    TRACTION_LIMITED,
    POWER_LIMITED,
    OVERSPEED_CUT,
    BRAKE_LIMITED,
    JERK_LIMITED,
    JERK_OVERRIDDEN,
    STANDSTILL_HOLD,
)
SATURATION_FLAGS = frozenset(_FLAG_ORDER)
_BIT = {name: 1 << i for i, name in enumerate(_FLAG_ORDER)}
_B_TRACTION, _B_POWER, _B_OVERSPEED, _B_BRAKE, _B_JERK, _B_OVERRIDE, _B_HOLD = (_BIT[n] for n in _FLAG_ORDER)
_MASK_SETS: tuple[frozenset[str], ...] = tuple(
    frozenset(name for name in _FLAG_ORDER if mask & _BIT[name]) for mask in range(1 << len(_FLAG_ORDER))
)
_MASK_OF = {flags: mask for mask, flags in enumerate(_MASK_SETS)}
_INF = math.inf


def flags_from_mask(mask: int) -> frozenset[str]:
    """The saturation flags encoded in a mask from :func:`step_many` (bit ``i`` = ``_FLAG_ORDER[i]``)."""
    return _MASK_SETS[int(mask)]


@dataclass(frozen=True, slots=True)
class PlantState:
    """What the plant remembers between steps.

    ``applied_accel_mps2`` is the actuator lag state ``a_{k−1}``; ``target_accel_mps2`` the jerk-limited target
    ``u_{k−1}``. A train inserted at rest starts with both at 0.
    """

    speed_mps: float
    applied_accel_mps2: float = 0.0
    target_accel_mps2: float = 0.0


@dataclass(frozen=True, slots=True)
class StepResult:
    """The outcome of one :func:`step`.

    ``state`` is the state after the step (``v_{k+1}``, ``a_k``, ``u_k``); ``net_accel_mps2`` the realised
    ``(v_{k+1} − v_k)/dt``; ``advance_m`` the position change under the chosen step method;
    ``traction_energy_j`` the traction work of the step; ``saturations`` the flags (see module docstring).
    """

    state: PlantState
    net_accel_mps2: float
    advance_m: float
    traction_energy_j: float
    saturations: frozenset[str]

    @property
    def v_next_mps(self) -> float:
        return self.state.speed_mps

    @property
    def applied_accel_mps2(self) -> float:
        return self.state.applied_accel_mps2

    @property
    def target_accel_mps2(self) -> float:
        return self.state.target_accel_mps2


def traction_limit_mps2(vehicle: VehicleParams, speed_mps: float) -> float:
    """Largest applied traction acceleration ``F_max(v)/m_eff`` [m/s²], ``F_max = min(F0, P/max(v, ε))``.

    The traction cut at ``max_speed_mps`` is not included (the plant applies it on top).
    """
    v = speed_mps if speed_mps > SPEED_EPS_MPS else SPEED_EPS_MPS
    power_force_n = vehicle.traction_max_power_w / v
    f0 = vehicle.traction_max_force_n
    return (f0 if f0 <= power_force_n else power_force_n) / (vehicle.mass_kg * vehicle.rotating_mass_factor)


def brake_limit_mps2(vehicle: VehicleParams, emergency: bool = False) -> float:
    """Largest braking deceleration [m/s², a positive number]: service, or emergency when flagged."""
    return vehicle.emergency_decel_mps2 if emergency else vehicle.service_decel_mps2


def braking_distance_m(vehicle: VehicleParams, speed_mps: float, decel_mps2: float | None = None) -> float:
    """Closed-form braking distance ``v²/(2b)`` [m] at constant deceleration ``b`` (default: service braking).

    No lag, jerk or resistance: a helper for supervision margins and tests, not the plant's exact answer.
    """
    b = vehicle.service_decel_mps2 if decel_mps2 is None else decel_mps2
    if not b > 0.0 or math.isinf(b):
        raise ValueError(f"decel_mps2 must be a finite number > 0, got {b!r}")
    if not speed_mps >= 0.0 or math.isinf(speed_mps):
        raise ValueError(f"speed_mps must be a finite number >= 0, got {speed_mps!r}")
    return speed_mps * speed_mps / (2.0 * b)


def least_stop_distance_m(vehicle: VehicleParams, speed_mps: float, gradient_permille: float = 0.0) -> float:
    """The shortest distance [m] in which the train can stand from ``speed_mps``: the emergency brake at once, with
    the running resistance and the gradient helping, ``v² / (2·(b_e + ρ))`` (infinite on a downhill steeper than the
    brake). The plant's lag, jerk limit and step only lengthen it: a lower bound, for deciding what is impossible."""
    rho = vehicle.resistance_n(speed_mps, gradient_permille) / vehicle.effective_mass_kg
    decel = vehicle.emergency_decel_mps2 + rho
    if decel <= 0.0:
        return math.inf
    return speed_mps * speed_mps / (2.0 * decel)


@lru_cache(maxsize=256)
def _lag_gain(tau_s: float, dt_s: float) -> float:
    """``1 − exp(−dt/τ)`` (computed as −expm1 for accuracy when dt ≪ τ); 1.0 for τ = 0."""
    if not tau_s >= 0.0:
        raise ValueError(f"actuator_time_constant_s must be >= 0, got {tau_s!r}")
    if tau_s == 0.0:
        return 1.0
    return -math.expm1(-dt_s / tau_s)


def _check_inputs(speed_mps: float, u_cmd_mps2: float, dt_s: float, gradient_permille: float, step_method: str) -> None:
    # One place for the messages; called only when the fast checks in step() fail.
    if not (dt_s > 0.0 and dt_s < _INF):
        raise ValueError(f"dt_s must be a finite number > 0, got {dt_s!r}")
    if u_cmd_mps2 != u_cmd_mps2:
        raise ValueError("u_cmd_mps2 is NaN: the controller produced no valid command (refusing to propagate it)")
    if not (speed_mps >= 0.0 and speed_mps < _INF):
        raise ValueError(f"state.speed_mps must be a finite number >= 0, got {speed_mps!r}")
    if not (-_INF < gradient_permille < _INF):
        raise ValueError(f"gradient_permille must be a finite number, got {gradient_permille!r}")
    if step_method not in STEP_METHODS:
        raise ValueError(f"step_method must be one of {', '.join(STEP_METHODS)}, got {step_method!r}")
    raise AssertionError("unreachable: _check_inputs called with valid inputs")  # pragma: no cover


def step(
    vehicle: VehicleParams,
    state: PlantState,
    u_cmd_mps2: float,
    dt_s: float,
    gradient_permille: float = 0.0,
    emergency: bool = False,
    step_method: str = "euler",
) -> StepResult:
    """Advance one train by one step of ``dt_s`` under the applied-acceleration command ``u_cmd_mps2``.

    See the module docstring for the exact order of operations. ``gradient_permille`` is the gradient under the
    train (uphill positive); ``emergency`` marks an emergency-brake command (emergency deceleration allowed, jerk
    limit bypassed). Raises ValueError for ``dt_s ≤ 0``, a NaN command, a negative/NaN speed or gradient, or an
    unknown ``step_method``.
    """
    v_next, a, u, net, advance, energy, mask = step_values(
        vehicle, state, u_cmd_mps2, dt_s, gradient_permille, emergency, step_method
    )
    return StepResult(PlantState(v_next, a, u), net, advance, energy, _MASK_SETS[mask])


def step_values(
    vehicle: VehicleParams,
    state: PlantState,
    u_cmd_mps2: float,
    dt_s: float,
    gradient_permille: float = 0.0,
    emergency: bool = False,
    step_method: str = "euler",
) -> tuple[float, float, float, float, float, float, int]:
    """:func:`step` as plain values: ``(v_next, applied a_k, target u_k, net acceleration, advance, traction
    energy, saturation mask)`` (:func:`flags_from_mask` turns the mask into the flags). The engine calls this
    for every train every step; :func:`step` builds its :class:`StepResult` from it.
    """
    v = state.speed_mps
    # Fast path validation: chained comparisons are False for NaN, so one test per input catches it.
    if not (
        0.0 < dt_s < _INF
        and u_cmd_mps2 == u_cmd_mps2
        and 0.0 <= v < _INF
        and -_INF < gradient_permille < _INF
        and step_method in STEP_METHODS
    ):
        _check_inputs(v, u_cmd_mps2, dt_s, gradient_permille, step_method)

    m_eff = vehicle.mass_kg * vehicle.rotating_mass_factor
    mask = 0

    # 1. Envelope at the current speed.
    if v >= vehicle.max_speed_mps:
        upper, upper_bit = 0.0, _B_OVERSPEED
    else:
        power_force_n = vehicle.traction_max_power_w / (v if v > SPEED_EPS_MPS else SPEED_EPS_MPS)
        f0 = vehicle.traction_max_force_n
        if f0 <= power_force_n:
            upper, upper_bit = f0 / m_eff, _B_TRACTION
        else:
            upper, upper_bit = power_force_n / m_eff, _B_POWER
    lower = -vehicle.emergency_decel_mps2 if emergency else -vehicle.service_decel_mps2

    u_env = u_cmd_mps2
    if u_env > upper:
        u_env = upper
        mask |= upper_bit
    elif u_env < lower:
        u_env = lower
        mask |= _B_BRAKE

    # 2. Jerk limit on the target (bypassed by emergency); the envelope has the last word.
    u = u_env
    if not emergency:
        u_prev = state.target_accel_mps2
        du = vehicle.jerk_limit_mps3 * dt_s
        if u > u_prev + du:
            u = u_prev + du
        elif u < u_prev - du:
            u = u_prev - du
        if u > upper:
            u = upper
            mask |= upper_bit | _B_OVERRIDE
        elif u < lower:
            u = lower
            mask |= _B_BRAKE | _B_OVERRIDE
        if u != u_env:
            mask |= _B_JERK

    # 3. First-order actuator lag (exact ZOH), then the physical envelope on the applied force.
    gain = _lag_gain(vehicle.actuator_time_constant_s, dt_s)
    if gain == 1.0:
        a = u
    else:
        a_prev = state.applied_accel_mps2
        a = a_prev + (u - a_prev) * gain
        if a > upper:
            a = upper
            mask |= upper_bit
        elif a < lower:
            a = lower
            mask |= _B_BRAKE

    # 4.–5. Resistance and speed; no rolling backwards, holding brake at standstill.
    a_net = a - vehicle.resistance_n(v, gradient_permille) / m_eff
    v_raw = v + a_net * dt_s
    if v_raw < 0.0 or (v == 0.0 and a <= 0.0 and v_raw > 0.0):
        v_next = 0.0
        mask |= _B_HOLD
    else:
        v_next = v_raw

    # 6. Position advance and energy.
    if step_method == "euler":
        advance = v_next * dt_s
    elif step_method == "ballistic":
        # SUMO's MSVehicle::getDeltaPos: (v + 0.5·ACCEL2SPEED(SPEED2ACCEL(v_next − v)))·dt, same operation order.
        advance = (v + 0.5 * ((v_next - v) / dt_s * dt_s)) * dt_s
    else:
        advance = v * dt_s
    energy = a * m_eff * (v + v_next) * 0.5 * dt_s if a > 0.0 else 0.0

    return v_next, a, u, (v_next - v) / dt_s, advance, energy, mask


# ----------------------------------------------------------------------------------------------------------------
# Many trains at once


@dataclass(frozen=True)
class FleetParams:
    """Per-train parameter arrays for :func:`step_many` (build with :meth:`from_vehicles`)."""

    vehicles: tuple[VehicleParams, ...]
    mass_kg: np.ndarray
    m_eff_kg: np.ndarray
    davis_a_n: np.ndarray
    davis_b_n_per_mps: np.ndarray
    davis_c_n_per_mps2: np.ndarray
    max_speed_mps: np.ndarray
    traction_max_force_n: np.ndarray
    traction_max_power_w: np.ndarray
    service_decel_mps2: np.ndarray
    emergency_decel_mps2: np.ndarray
    jerk_limit_mps3: np.ndarray
    actuator_time_constant_s: np.ndarray
    _gain_cache: dict[float, np.ndarray] = field(default_factory=dict, compare=False, repr=False)

    @classmethod
    def from_vehicles(cls, vehicles: Sequence[VehicleParams]) -> FleetParams:
        vs = tuple(vehicles)

        def col(name: str) -> np.ndarray:
            arr = np.array([float(getattr(v, name)) for v in vs], dtype=float)
            arr.flags.writeable = False
            return arr

        m_eff = np.array([v.mass_kg * v.rotating_mass_factor for v in vs], dtype=float)
        m_eff.flags.writeable = False
        return cls(
            vehicles=vs,
            mass_kg=col("mass_kg"),
            m_eff_kg=m_eff,
            davis_a_n=col("davis_a_n"),
            davis_b_n_per_mps=col("davis_b_n_per_mps"),
            davis_c_n_per_mps2=col("davis_c_n_per_mps2"),
            max_speed_mps=col("max_speed_mps"),
            traction_max_force_n=col("traction_max_force_n"),
            traction_max_power_w=col("traction_max_power_w"),
            service_decel_mps2=col("service_decel_mps2"),
            emergency_decel_mps2=col("emergency_decel_mps2"),
            jerk_limit_mps3=col("jerk_limit_mps3"),
            actuator_time_constant_s=col("actuator_time_constant_s"),
        )

    def __len__(self) -> int:
        return len(self.vehicles)

    def lag_gain(self, dt_s: float) -> np.ndarray:
        """Per-train ``1 − exp(−dt/τ)``, from the same scalar function as :func:`step` (bit-identical)."""
        gain = self._gain_cache.get(dt_s)
        if gain is None:
            gain = np.array([_lag_gain(float(t), dt_s) for t in self.actuator_time_constant_s], dtype=float)
            self._gain_cache[dt_s] = gain
        return gain


@dataclass(frozen=True)
class FleetStepResult:
    """Arrays (one entry per train) of :func:`step_many`; ``saturation_mask`` decodes with :func:`flags_from_mask`."""

    speed_mps: np.ndarray
    applied_accel_mps2: np.ndarray
    target_accel_mps2: np.ndarray
    net_accel_mps2: np.ndarray
    advance_m: np.ndarray
    traction_energy_j: np.ndarray
    saturation_mask: np.ndarray

    def saturations(self, i: int) -> frozenset[str]:
        return _MASK_SETS[int(self.saturation_mask[i])]


def step_many(
    fleet: FleetParams,
    speed_mps: np.ndarray,
    applied_accel_mps2: np.ndarray,
    target_accel_mps2: np.ndarray,
    u_cmd_mps2: np.ndarray,
    dt_s: float,
    gradient_permille: float | np.ndarray = 0.0,
    emergency: bool | np.ndarray = False,
    step_method: str = "euler",
) -> FleetStepResult:
    """:func:`step` for all trains of ``fleet`` at once (same order of operations, bit-identical results)."""
    n = len(fleet)
    v = np.asarray(speed_mps, dtype=float)
    a_prev = np.asarray(applied_accel_mps2, dtype=float)
    u_prev = np.asarray(target_accel_mps2, dtype=float)
    u_cmd = np.asarray(u_cmd_mps2, dtype=float)
    grad = np.broadcast_to(np.asarray(gradient_permille, dtype=float), (n,))
    emerg = np.broadcast_to(np.asarray(emergency, dtype=bool), (n,))
    for name, arr in (
        ("speed_mps", v),
        ("applied_accel_mps2", a_prev),
        ("target_accel_mps2", u_prev),
        ("u_cmd_mps2", u_cmd),
    ):
        if arr.shape != (n,):
            raise ValueError(f"{name} must have shape ({n},), got {arr.shape}")
    if not (0.0 < dt_s < _INF):
        raise ValueError(f"dt_s must be a finite number > 0, got {dt_s!r}")
    if np.isnan(u_cmd).any():
        bad = [fleet.vehicles[i].name for i in np.flatnonzero(np.isnan(u_cmd))[:5]]
        raise ValueError(
            f"u_cmd_mps2 is NaN for train(s) at index {np.flatnonzero(np.isnan(u_cmd))[:5].tolist()} "
            f"({', '.join(bad)}): refusing to propagate it"
        )
    if not ((v >= 0.0) & (v < _INF)).all():
        raise ValueError("speed_mps must be finite and >= 0 for every train")
    if not np.isfinite(grad).all():
        raise ValueError("gradient_permille must be finite for every train")
    if step_method not in STEP_METHODS:
        raise ValueError(f"step_method must be one of {', '.join(STEP_METHODS)}, got {step_method!r}")

    m_eff = fleet.m_eff_kg
    mask = np.zeros(n, dtype=np.int64)

    # 1. Envelope.
    overspeed = v >= fleet.max_speed_mps
    power_force = fleet.traction_max_power_w / np.maximum(v, SPEED_EPS_MPS)
    f0 = fleet.traction_max_force_n
    force_branch = f0 <= power_force
    upper = np.where(overspeed, 0.0, np.where(force_branch, f0, power_force) / m_eff)
    upper_bit = np.where(overspeed, _B_OVERSPEED, np.where(force_branch, _B_TRACTION, _B_POWER))
    lower = np.where(emerg, -fleet.emergency_decel_mps2, -fleet.service_decel_mps2)
    hi = u_cmd > upper
    lo = ~hi & (u_cmd < lower)
    u_env = np.where(hi, upper, np.where(lo, lower, u_cmd))
    mask |= np.where(hi, upper_bit, 0) | np.where(lo, _B_BRAKE, 0)

    # 2. Jerk limit (not for emergency), envelope wins.
    du = fleet.jerk_limit_mps3 * dt_s
    up_j = u_prev + du
    dn_j = u_prev - du
    u_j = np.where(u_env > up_j, up_j, np.where(u_env < dn_j, dn_j, u_env))
    hi2 = u_j > upper
    lo2 = ~hi2 & (u_j < lower)
    u_j = np.where(hi2, upper, np.where(lo2, lower, u_j))
    normal = ~emerg
    mask |= np.where(normal & hi2, upper_bit | _B_OVERRIDE, 0) | np.where(normal & lo2, _B_BRAKE | _B_OVERRIDE, 0)
    mask |= np.where(normal & (u_j != u_env), _B_JERK, 0)
    u = np.where(normal, u_j, u_env)

    # 3. Actuator lag, envelope on the applied value.
    gain = fleet.lag_gain(dt_s)
    instant = gain == 1.0
    a_lag = a_prev + (u - a_prev) * gain
    hi3 = ~instant & (a_lag > upper)
    lo3 = ~instant & ~hi3 & (a_lag < lower)
    a = np.where(instant, u, np.where(hi3, upper, np.where(lo3, lower, a_lag)))
    mask |= np.where(hi3, upper_bit, 0) | np.where(lo3, _B_BRAKE, 0)

    # 4.–5. Same expression as VehicleParams.resistance_n, element-wise.
    speed_abs = np.abs(v)
    davis = np.where(
        speed_abs == 0.0,
        0.0,
        fleet.davis_a_n + fleet.davis_b_n_per_mps * speed_abs + fleet.davis_c_n_per_mps2 * speed_abs * speed_abs,
    )
    resistance = davis + fleet.mass_kg * G_MPS2 * grad / 1000.0
    a_net = a - resistance / m_eff
    v_raw = v + a_net * dt_s
    hold = (v_raw < 0.0) | ((v == 0.0) & (a <= 0.0) & (v_raw > 0.0))
    v_next = np.where(hold, 0.0, v_raw)
    mask |= np.where(hold, _B_HOLD, 0)

    # 6.
    if step_method == "euler":
        advance = v_next * dt_s
    elif step_method == "ballistic":
        advance = (v + 0.5 * ((v_next - v) / dt_s * dt_s)) * dt_s
    else:
        advance = v * dt_s
    energy = np.where(a > 0.0, a * m_eff * (v + v_next) * 0.5 * dt_s, 0.0)
    return FleetStepResult(v_next, a, u, (v_next - v) / dt_s, advance, energy, mask)


# ----------------------------------------------------------------------------------------------------------------
# Open-loop / closed-loop runs of one train


CommandLaw = Callable[[float, float, float], float]  # (t_s, x_m, speed_mps) -> u_cmd_mps2


def simulate(
    vehicle: VehicleParams,
    v0: float,
    u_sequence_or_callable: Sequence[float] | np.ndarray | CommandLaw,
    dt_s: float,
    n_steps: int,
    gradient_permille: float | Callable[[float], float] = 0.0,
    step_method: str = "euler",
    *,
    x0_m: float = 0.0,
    initial_accel_mps2: float = 0.0,
    emergency: bool = False,
) -> dict[str, np.ndarray]:
    """Run :func:`step` ``n_steps`` times from speed ``v0`` (numpy-only runs of papers, tests).

    ``u_sequence_or_callable`` is a sequence of at least ``n_steps`` commands or a law
    ``u(t_s, x_m, speed_mps)``; ``gradient_permille`` a constant or a function of the position ``x_m``.
    ``initial_accel_mps2`` sets both the applied and the target acceleration at ``t = 0`` (e.g. already braking).

    Returns arrays ``t``, ``x``, ``v`` (length ``n_steps + 1``, sample times ``k·dt``) and the per-step arrays
    (length ``n_steps``; entry ``k`` acts over ``[t_k, t_{k+1}]``): ``a`` applied acceleration, ``u`` jerk-limited
    target, ``a_net`` realised net acceleration, ``energy_j`` traction energy, ``mask`` saturation bits
    (:func:`flags_from_mask`).
    """
    if not isinstance(n_steps, (int, np.integer)) or n_steps < 0:
        raise ValueError(f"n_steps must be an integer >= 0, got {n_steps!r}")
    law: CommandLaw | None
    if callable(u_sequence_or_callable):
        law, seq = u_sequence_or_callable, None
    else:
        law, seq = None, np.asarray(u_sequence_or_callable, dtype=float).ravel()
        if len(seq) < n_steps:
            raise ValueError(f"u_sequence has {len(seq)} commands, need at least n_steps = {n_steps}")
    grad_fn = gradient_permille if callable(gradient_permille) else None
    grad_const = 0.0 if callable(gradient_permille) else float(gradient_permille)

    t = np.arange(n_steps + 1, dtype=float) * dt_s
    x = np.empty(n_steps + 1)
    v = np.empty(n_steps + 1)
    a = np.empty(n_steps)
    u = np.empty(n_steps)
    a_net = np.empty(n_steps)
    energy = np.empty(n_steps)
    mask = np.empty(n_steps, dtype=np.int64)
    x[0], v[0] = float(x0_m), float(v0)
    state = PlantState(float(v0), float(initial_accel_mps2), float(initial_accel_mps2))
    pos = float(x0_m)
    for k in range(n_steps):
        cmd = float(law(float(t[k]), pos, state.speed_mps)) if law is not None else float(seq[k])  # type: ignore[index]
        grad = float(grad_fn(pos)) if grad_fn is not None else grad_const
        res = step(vehicle, state, cmd, dt_s, grad, emergency, step_method)
        state = res.state
        pos += res.advance_m  # accumulate like SUMO's odometer: one addition per step
        x[k + 1], v[k + 1] = pos, state.speed_mps
        a[k], u[k], a_net[k], energy[k] = (
            state.applied_accel_mps2,
            state.target_accel_mps2,
            res.net_accel_mps2,
            res.traction_energy_j,
        )
        mask[k] = _MASK_OF[res.saturations]
    return {"t": t, "x": x, "v": v, "a": a, "u": u, "a_net": a_net, "energy_j": energy, "mask": mask}
