"""Point-mass monorail vehicle with transmission delay, response delay and output efficiency (Paper D §3.3).

Paper D (Hou et al., PLOS ONE 2026, spec 003 §3.4) models one CRT Line 3 cab car as a point mass with three
operating stages — traction (start-up, re-traction), coasting, braking (traction cut-off is the decay of the
traction force after a cut-off command) — and two delays between a command and the force it produces:

* the **transmission delay** ``t_d``: the command has not reached the drive yet; the output is unchanged;
* the **response delay** ``t_r``: the drive builds up (or sheds) its force with the vehicle's inertia;
* the **output efficiency** ``η``: only ``η·u`` of the commanded acceleration ``u`` is delivered.

Equation (5) was lost; this module implements the spec's **Form B** reading (dead time + first-order lag),
separately for traction (``u > 0``) and braking (``u ≤ 0``)::

    a(t) = a0 + (η·u − a0)·(1 − exp(−(t − t_issue − t_d)/t_r))     for t ≥ t_issue + t_d, a0 before

In discrete time (step ``T``) the lag is the exact zero-order-hold recursion ``a ← a + (η·u − a)·(1 − e^{−T/t_r})``
(``t_r → 0`` leaves a pure dead time) and Eq. (17) integrates the point mass::

    x(k+1) = x(k) + T·v(k) + ½·T²·a_net(k),   v(k+1) = v(k) + T·a_net(k),   a_net = a − w0(v) − w1

with the speed clamped at zero (a braking vehicle stands; it does not reverse). Which delay applies is decided
by the sign of the command when it is *issued*; the effective command at any time is the most recently issued
command that has already arrived (so a late-arriving older command never overrides a newer one).

Start-up, re-traction and cut-off are not separate code paths: they are this same filter driven by a command
step 0 → a_c (start-up), a_c → 0 (cut-off: the traction acceleration decays to zero) and 0 → a_c again
(re-traction). :func:`step_response_mps2` gives the closed form for tests and for reading the figures.

Load cases (A7/A8). Masses come from the Chongqing Line 3 data pack (``vehicle`` section): tare 27.0 t per car,
Mc car capacity 211 passengers at AW2 ("full") and 285 at AW3 ("overloaded", 9 pax/m²), 60 kg per passenger:
empty 27.0 t, full 27.0 + 211·0.06 = 39.66 t, overloaded 27.0 + 285·0.06 = 44.1 t. Braking and traction are
**force-limited** by default (a heavier car brakes weaker, as the paper's narrative requires):
``a_max(m) = a_max_empty · m_empty / m``; ``load_compensated`` keeps the empty-car accelerations for every load.
The empty-car emergency deceleration 1.5 m/s² is the paper-consistent reading of the 23 m braking distance
(25 km/h, t_eq 1 s, spec §3.10); the data pack's proxy value is 1.25 m/s².

Everything is pure: :func:`plant_step` maps a frozen :class:`PlantState` to the next one, so the engine can use it as
a plant and the controllers as their prediction model (:func:`lag_prediction_matrices`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from railsim.errors import require
from railsim.physics.vehicle import G_MPS2, VehicleParams

# ---- Chongqing Line 3 data pack (vehicle section), see module docstring
TARE_MASS_PER_CAR_KG = 27_000.0
MC_CAPACITY_AW2_PAX = 211
MC_CAPACITY_AW3_PAX = 285
PASSENGER_MASS_KG = 60.0
CAB_CAR_LENGTH_M = 15.5

LOAD_CASES = ("empty", "full", "overloaded")


def load_mass_kg(load: str) -> float:
    """Mass of one Mc cab car [kg] for load case ``empty`` / ``full`` / ``overloaded`` (data-pack derivation)."""
    pax = {"empty": 0, "full": MC_CAPACITY_AW2_PAX, "overloaded": MC_CAPACITY_AW3_PAX}
    if load not in pax:
        raise ValueError(f"load: expected one of {', '.join(LOAD_CASES)}, got {load!r}")
    return TARE_MASS_PER_CAR_KG + pax[load] * PASSENGER_MASS_KG


@dataclass(frozen=True)
class MonorailParams:
    """Longitudinal model of one monorail vehicle (every lost paper value is a parameter; defaults = spec §4.1)."""

    mass_empty_kg: float = TARE_MASS_PER_CAR_KG
    traction_max_empty_mps2: float = 1.0  # a_t,max of the empty car [m/s²]
    emergency_decel_empty_mps2: float = 1.5  # a_eb,max of the empty car [m/s²] (reproduces the 23 m)
    service_decel_empty_mps2: float = 1.0  # full service braking of the empty car [m/s²]
    braking_model: str = "force_limited"  # "force_limited": a = a_empty·m_empty/m; "load_compensated": a = a_empty
    traction_delay_s: float = 0.1  # t_d for traction commands [s]
    traction_response_s: float = 0.3  # t_r (first-order lag) for traction [s]
    traction_efficiency: float = 0.9  # η for traction
    brake_delay_s: float = 0.1  # t_d for braking commands [s]
    brake_response_s: float = 0.3  # t_r for braking [s]
    brake_efficiency: float = 1.0  # η for braking
    davis_a_mps2: float = 0.0  # w0 = A + B·v + C·v² (specific, m/s²); 0 = the paper's straight level track
    davis_b_per_s: float = 0.0
    davis_c_per_m: float = 0.0
    max_speed_mps: float = 80.0 / 3.6  # design limit (paper: "typically 80 km/h")

    def __post_init__(self) -> None:
        require("mass_empty_kg", self.mass_empty_kg > 0.0, "a number > 0", self.mass_empty_kg)
        for name in (
            "traction_max_empty_mps2",
            "emergency_decel_empty_mps2",
            "service_decel_empty_mps2",
            "max_speed_mps",
        ):
            require(name, getattr(self, name) > 0.0, "a number > 0", getattr(self, name))
        require(
            "braking_model",
            self.braking_model in ("force_limited", "load_compensated"),
            "'force_limited' or 'load_compensated'",
            self.braking_model,
        )
        for name in (
            "traction_delay_s",
            "traction_response_s",
            "brake_delay_s",
            "brake_response_s",
            "davis_a_mps2",
            "davis_b_per_s",
            "davis_c_per_m",
        ):
            require(name, getattr(self, name) >= 0.0, "a number >= 0", getattr(self, name))
        for name in ("traction_efficiency", "brake_efficiency"):
            require(name, 0.0 < getattr(self, name) <= 1.0, "a number in (0, 1]", getattr(self, name))

    def _scale(self, mass_kg: float) -> float:
        return self.mass_empty_kg / mass_kg if self.braking_model == "force_limited" else 1.0

    def traction_max_mps2(self, mass_kg: float) -> float:
        """Largest commandable traction acceleration at ``mass_kg`` (before efficiency) [m/s²]."""
        return self.traction_max_empty_mps2 * self._scale(mass_kg)

    def emergency_decel_mps2(self, mass_kg: float) -> float:
        """Largest commandable braking deceleration at ``mass_kg`` (positive) [m/s²]."""
        return self.emergency_decel_empty_mps2 * self._scale(mass_kg)

    def service_decel_mps2(self, mass_kg: float) -> float:
        """Full service braking at ``mass_kg`` (positive) [m/s²]."""
        return self.service_decel_empty_mps2 * self._scale(mass_kg)

    def resistance_mps2(self, speed_mps: float, gradient_permille: float = 0.0) -> float:
        """w0 + w1: Davis resistance (zero at standstill) plus gradient [m/s²]."""
        v = abs(speed_mps)
        w0 = 0.0 if v == 0.0 else self.davis_a_mps2 + self.davis_b_per_s * v + self.davis_c_per_m * v * v
        return w0 + G_MPS2 * gradient_permille / 1000.0

    def delivered_accel_mps2(self, command_mps2: float) -> float:
        """η·u with the stage's efficiency (what the lag converges to)."""
        return command_mps2 * (self.traction_efficiency if command_mps2 > 0.0 else self.brake_efficiency)

    def delay_s(self, command_mps2: float) -> float:
        return self.traction_delay_s if command_mps2 > 0.0 else self.brake_delay_s

    def response_s(self, command_mps2: float) -> float:
        return self.traction_response_s if command_mps2 > 0.0 else self.brake_response_s

    def total_delay_s(self) -> float:
        """Worst-case command-to-force dead time + lag (used as the controllers' equivalent delay) [s]."""
        return max(self.traction_delay_s + self.traction_response_s, self.brake_delay_s + self.brake_response_s)


def vehicle_params_for(
    load: str, params: MonorailParams = MonorailParams(), length_m: float = 0.0, name: str | None = None
) -> VehicleParams:
    """A :class:`railsim.physics.vehicle.VehicleParams` for one Mc car at ``load`` (point mass: rotating factor 1).

    ``length_m = 0`` is the paper's point mass (A1); 15.5 m is the cab car. Traction force and brake limits are the
    load-dependent envelope of ``params``; the engine's plant and the controllers then read the same numbers.
    """
    mass = load_mass_kg(load)
    return VehicleParams(
        name=name or f"cq3_mc_{load}",
        length_m=length_m,
        mass_kg=mass,
        rotating_mass_factor=1.0,
        max_speed_mps=params.max_speed_mps,
        traction_max_force_n=params.traction_max_mps2(mass) * mass,
        traction_max_power_w=1e12,
        service_decel_mps2=params.service_decel_mps2(mass),
        emergency_decel_mps2=params.emergency_decel_mps2(mass),
        jerk_limit_mps3=1e6,
        actuator_time_constant_s=params.brake_response_s,
        capacity_pax=MC_CAPACITY_AW2_PAX,
    )


@dataclass(frozen=True)
class PlantState:
    """State of one vehicle: position (front) [m], speed [m/s], delivered acceleration a (before resistance)
    [m/s²], the command in force, and the commands still in transmission ``(arrival_time_s, issue_time_s, u)``."""

    t_s: float = 0.0
    x_m: float = 0.0
    v_mps: float = 0.0
    a_mps2: float = 0.0
    active_command_mps2: float = 0.0
    active_issue_s: float = -math.inf
    pending: tuple[tuple[float, float, float], ...] = field(default_factory=tuple)

    @property
    def net_accel_mps2(self) -> float:
        return self.a_mps2


def plant_step(
    state: PlantState,
    command_mps2: float,
    dt_s: float,
    params: MonorailParams,
    mass_kg: float,
    gradient_permille: float = 0.0,
) -> PlantState:
    """Advance one step of ``dt_s``: issue ``command_mps2`` now, deliver what has arrived, integrate Eq. (17).

    The command is clipped to the load-dependent envelope ``[−a_eb,max(m), a_t,max(m)]`` (Eq. 18). A command
    issued at ``t`` becomes the drive's input at the first step boundary ``≥ t + t_d`` (to within 1e-9 s), so a
    delay that is a multiple of ``dt_s`` is applied exactly.
    """
    if not (math.isfinite(command_mps2) and dt_s > 0.0):
        raise ValueError(f"command_mps2 must be finite and dt_s > 0, got {command_mps2!r}, {dt_s!r}")
    u = min(max(command_mps2, -params.emergency_decel_mps2(mass_kg)), params.traction_max_mps2(mass_kg))
    t = state.t_s
    pending = state.pending + ((t + params.delay_s(u), t, u),)
    active_u, active_issue = state.active_command_mps2, state.active_issue_s
    still: list[tuple[float, float, float]] = []
    for arrival, issue, cmd in pending:
        if arrival <= t + 1e-9:
            if issue >= active_issue:  # a newer command already in force is never overridden by an older one
                active_u, active_issue = cmd, issue
        else:
            still.append((arrival, issue, cmd))
    tau = params.response_s(active_u)
    gain = 1.0 - math.exp(-dt_s / tau) if tau > 0.0 else 1.0
    a = state.a_mps2 + (params.delivered_accel_mps2(active_u) - state.a_mps2) * gain
    net = a - params.resistance_mps2(state.v_mps, gradient_permille)
    v0 = state.v_mps
    if v0 + net * dt_s < 0.0:  # stands within this step: integrate to the halt, not through it
        t_stop = v0 / -net if net < 0.0 else 0.0
        x = state.x_m + v0 * t_stop + 0.5 * net * t_stop * t_stop
        v = 0.0
    else:
        x = state.x_m + v0 * dt_s + 0.5 * net * dt_s * dt_s
        v = v0 + net * dt_s
    if v > params.max_speed_mps:
        v = params.max_speed_mps
    return PlantState(
        t_s=t + dt_s,
        x_m=x,
        v_mps=v,
        a_mps2=a,
        active_command_mps2=active_u,
        active_issue_s=active_issue,
        pending=tuple(still),
    )


def step_response_mps2(
    t_s: float | np.ndarray, command_mps2: float, params: MonorailParams, a0_mps2: float = 0.0
) -> np.ndarray:
    """Closed form of Eq. (5), Form B: delivered acceleration ``t_s`` after a step command issued at 0.

    ``command_mps2 > 0`` from ``a0 = 0`` is start-up, ``0`` from ``a0 > 0`` is traction cut-off, a positive command
    from a decayed ``a0`` is re-traction; braking commands use the braking delays.
    """
    t = np.asarray(t_s, dtype=float)
    td, tr = params.delay_s(command_mps2), params.response_s(command_mps2)
    target = params.delivered_accel_mps2(command_mps2)
    after = np.clip(t - td, 0.0, None)
    rise = 1.0 - np.exp(-after / tr) if tr > 0.0 else (t >= td).astype(float)
    return np.where(t < td, a0_mps2, a0_mps2 + (target - a0_mps2) * rise)


def lag_prediction_matrices(
    dt_s: float, response_s: float, efficiency: float, horizon: int, control_horizon: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Linear prediction of Eq. (17) with the response lag: the controllers' model.

    State ``s = [x, v, a]``; ``a(k+1) = ρ·a(k) + (1−ρ)·η·u(k)``, ``ρ = e^{−T/t_r}``, resistance left out (it is
    a known offset the callers add). Inputs beyond ``control_horizon`` repeat the last one (Eq. 22's move
    blocking). Returns ``(Px, Gx, Pv, Gv)`` with ``x[1..N] = Px·s0 + Gx·U``, ``v[1..N] = Pv·s0 + Gv·U``.
    """
    rho = math.exp(-dt_s / response_s) if response_s > 0.0 else 0.0
    # The delivered acceleration that acts during step k is the lag output after the update with u(k)
    # (matches plant_step, which updates a before integrating).
    n, m = horizon, control_horizon
    phi = np.zeros((n, 3, 3))
    gam = np.zeros((n, 3, m))
    s_phi = np.eye(3)
    s_gam = np.zeros((3, m))
    for k in range(n):
        j = min(k, m - 1)
        # a_k = ρ·a_{k-1} + (1−ρ)·η·u_k, then x, v integrate with a_k
        a_row_phi = rho * s_phi[2]
        a_row_gam = rho * s_gam[2].copy()
        a_row_gam[j] += (1.0 - rho) * efficiency
        new_phi = np.vstack(
            [s_phi[0] + dt_s * s_phi[1] + 0.5 * dt_s * dt_s * a_row_phi, s_phi[1] + dt_s * a_row_phi, a_row_phi]
        )
        new_gam = np.vstack(
            [s_gam[0] + dt_s * s_gam[1] + 0.5 * dt_s * dt_s * a_row_gam, s_gam[1] + dt_s * a_row_gam, a_row_gam]
        )
        s_phi, s_gam = new_phi, new_gam
        phi[k], gam[k] = s_phi, s_gam
    return phi[:, 0, :], gam[:, 0, :], phi[:, 1, :], gam[:, 1, :]
