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

Units are SI throughout. The step itself is written once, compiled, in :mod:`railsim.physics.plant_kernel`;
:func:`step_values` (plain values, for the engine's every train and step) and :func:`step` (a :class:`StepResult`)
check their inputs and call it for one train, :func:`step_many` for many trains at once (numpy arrays), and
:func:`simulate` runs one train open-loop or under a callable law (numpy-only paper reproductions and tests).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from railsim.physics import forces, plant_kernel
from railsim.physics.plant_kernel import STEP_METHODS
from railsim.physics.vehicle import VehicleParams

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
_MASK_SETS: tuple[frozenset[str], ...] = tuple(
    frozenset(name for name in _FLAG_ORDER if mask & _BIT[name]) for mask in range(1 << len(_FLAG_ORDER))
)
_MASK_OF = {flags: mask for mask, flags in enumerate(_MASK_SETS)}
_INF = math.inf


def flags_from_mask(mask: int) -> frozenset[str]:
    """The saturation flags encoded in a mask from :func:`step_many` (bit ``i`` = ``_FLAG_ORDER[i]``)."""
    return _MASK_SETS[int(mask)]


@dataclass(slots=True, init=False)
class PlantState:
    """What the plant remembers between steps.

    ``applied_accel_mps2`` is the actuator lag state ``a_{k−1}``; ``target_accel_mps2`` the jerk-limited target
    ``u_{k−1}``. A train inserted at rest starts with both at 0.

    A value: each step makes a new one and nothing changes one in place. It is not declared frozen because one is
    made per train and step, and a frozen dataclass's constructor costs three times a plain one's; its
    constructor is written out because the one ``dataclass`` generates stays interpreted in the compiled core
    (:mod:`railsim.native`), a Python call per train and step.
    """

    speed_mps: float
    applied_accel_mps2: float
    target_accel_mps2: float

    def __init__(self, speed_mps: float, applied_accel_mps2: float = 0.0, target_accel_mps2: float = 0.0) -> None:
        self.speed_mps = speed_mps
        self.applied_accel_mps2 = applied_accel_mps2
        self.target_accel_mps2 = target_accel_mps2


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

    The traction cut at ``max_speed_mps`` is not included (the plant applies it on top). The law is
    :func:`railsim.physics.forces.traction_limit_mps2`, written once.
    """
    return forces.traction_limit_mps2(  # type: ignore[no-any-return]
        vehicle.mass_kg,
        vehicle.rotating_mass_factor,
        vehicle.traction_max_force_n,
        vehicle.traction_max_power_w,
        speed_mps,
    )


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

    return plant_kernel.step(  # type: ignore[no-any-return]
        _packed(vehicle, dt_s),
        float(v),
        float(state.applied_accel_mps2),
        float(state.target_accel_mps2),
        float(u_cmd_mps2),
        float(dt_s),
        float(gradient_permille),
        bool(emergency),
        _METHOD_INDEX[step_method],
    )


_METHOD_INDEX = {name: i for i, name in enumerate(STEP_METHODS)}
# The kernel's packed vehicle by the vehicle's identity (kept in the entry so its id cannot be reused), per dt.
_PACKED: dict[int, tuple[VehicleParams, float, np.ndarray]] = {}


def _packed(vehicle: VehicleParams, dt_s: float) -> np.ndarray:
    """:func:`plant_kernel.pack` for ``vehicle`` and ``dt_s``, remembered (a run steps a few vehicles at one dt)."""
    entry = _PACKED.get(id(vehicle))
    if entry is None or entry[0] is not vehicle or entry[1] != dt_s:
        if len(_PACKED) > 4096:
            _PACKED.clear()
        entry = _PACKED[id(vehicle)] = (vehicle, dt_s, plant_kernel.pack(vehicle, dt_s))
    return entry[2]


# ----------------------------------------------------------------------------------------------------------------
# Many trains at once


@dataclass(frozen=True)
class FleetParams:
    """The trains of :func:`step_many` (build with :meth:`from_vehicles`); their packed parameters per step length."""

    vehicles: tuple[VehicleParams, ...]
    _packed_cache: dict[float, np.ndarray] = field(default_factory=dict, compare=False, repr=False)

    @classmethod
    def from_vehicles(cls, vehicles: Sequence[VehicleParams]) -> FleetParams:
        return cls(vehicles=tuple(vehicles))

    def __len__(self) -> int:
        return len(self.vehicles)

    def packed(self, dt_s: float) -> np.ndarray:
        """Row ``i``: train ``i``'s :func:`plant_kernel.pack` for ``dt_s`` (remembered per ``dt_s``)."""
        packed = self._packed_cache.get(dt_s)
        if packed is None:
            packed = np.array([plant_kernel.pack(v, dt_s) for v in self.vehicles], dtype=np.float64)
            packed = packed.reshape(len(self.vehicles), len(plant_kernel.PLANT_FIELDS) + 1)
            self._packed_cache[dt_s] = packed
        return packed


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
    """:func:`step` for all trains of ``fleet`` at once (:func:`plant_kernel.step_fleet`: the same law, train by train)."""
    n = len(fleet)
    v = np.ascontiguousarray(speed_mps, dtype=float)
    a_prev = np.ascontiguousarray(applied_accel_mps2, dtype=float)
    u_prev = np.ascontiguousarray(target_accel_mps2, dtype=float)
    u_cmd = np.ascontiguousarray(u_cmd_mps2, dtype=float)
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

    out, mask = plant_kernel.step_fleet(
        fleet.packed(dt_s),
        v,
        a_prev,
        u_prev,
        u_cmd,
        float(dt_s),
        np.ascontiguousarray(grad),
        np.ascontiguousarray(emerg),
        _METHOD_INDEX[step_method],
    )
    return FleetStepResult(out[0], out[1], out[2], out[3], out[4], out[5], mask)


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
