"""Shared layer of the ATO laws: what a carriage-level law sees each step, and the stop/hold supervisor.

Every law of this package (SEMPC, MPC-A/B, AFSMC, PID) maps a :class:`Situation` — the relative-coordinate
state of the multi-point train, the slopes under the carriages, the current section's speed–distance profile
and (for the paper's time-indexed tracking) the time reference — to one force per carriage. The
:class:`AtoDriver` around it does what every ATO does regardless of the law (cf. :mod:`controllers.ato`):

* **hold** while dwelling, and once the train stands within ``stop_tolerance_m`` of (or past) the stop point:
  the forces ramp to the holding-brake level at the force-rate limit (so the rate limit holds in every
  phase, also for the baselines' outputs), and the law is reset (no stale warm start after a dwell);
* otherwise ask the law; a law that returns a non-finite force is reset and the forces ramp towards the holding
  brake at the rate limit (a logged fallback), so neither the plant nor the next step ever sees NaN.

Reference modes (spec A11): ``"distance"`` rebuilds the horizon from the measured position on the speed
cap (:func:`controllers.ato_mpc.reference.distance_window`) — robust, and what makes the ±0.3 m stop work
with the paper's weights, whose displacement weight (0.5 vs 10⁹ on speed) cannot recover a position lag —
and ``"time"`` reads the paper's expected speed/displacement at ``t − t_departure`` (paper-literal).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from controllers.ato_mpc.reference import SpeedDistanceProfile, TimeReference, distance_window
from railsim.physics.multipoint import MultipointParams

REFERENCE_MODES = ("distance", "time")


@dataclass(frozen=True)
class Situation:
    """One control step as a carriage-level law sees it."""

    t_s: float
    rel_state: np.ndarray  # [x_1, x_{i,i−1}…, v_1, v_{i,i−1}…]
    gradient_permille: np.ndarray  # θ_i under every carriage at time k
    profile: SpeedDistanceProfile
    time_ref: TimeReference | None = None
    t_since_departure_s: float = 0.0
    wind_mps2: float = 0.0  # disturbance known to the controller (0 unless the scenario says it is known)

    @property
    def x1_m(self) -> float:
        return float(self.rel_state[0])

    @property
    def v1_mps(self) -> float:
        return float(self.rel_state[self.rel_state.size // 2])


def reference_window(sit: Situation, period_s: float, n_p: int, mode: str) -> tuple[np.ndarray, np.ndarray, float]:
    """``(x_ref[k+1..k+N], v_ref[k+1..k+N], v_r(k))`` in the chosen reference mode."""
    if mode == "time" and sit.time_ref is not None:
        k = int(round(sit.t_since_departure_s / sit.time_ref.period_s))
        scale = period_s / sit.time_ref.period_s
        idx = k + np.rint(scale * np.arange(1, n_p + 1)).astype(int)
        xr, vr = sit.time_ref.at(idx)
        _, v0 = sit.time_ref.at(k)
        return np.asarray(xr, dtype=float), np.asarray(vr, dtype=float), float(v0)
    return distance_window(sit.profile, sit.x1_m, sit.v1_mps, period_s, n_p)


def limit_forces(u_des_n: np.ndarray, u_prev_n: np.ndarray, params: MultipointParams, period_s: float) -> np.ndarray:
    """Actuator envelope shared by every law (spec §2.10, Eq. 14–15; Table 1): first the force-rate limit
    ``Δu_min·T ≤ u − u_prev ≤ Δu_max·T`` (±60 kN/s × T), then the force box ``[u_min, u_max]``.

    The box comes second and ``u_prev`` is always inside it (it was produced here or by the hold ramp), so the
    clip only ever moves ``u`` back towards ``u_prev``: the result satisfies *both* limits.
    """
    prev = np.asarray(u_prev_n, dtype=float)
    step = np.clip(
        np.asarray(u_des_n, dtype=float) - prev,
        params.force_rate_min_n_per_s * period_s,
        params.force_rate_max_n_per_s * period_s,
    )
    return np.clip(prev + step, params.force_min_n, params.force_max_n)


class CarriageLaw(Protocol):
    def forces(self, sit: Situation, u_prev_n: np.ndarray) -> tuple[np.ndarray, dict[str, Any]]: ...

    def reset(self) -> None: ...


@dataclass
class DriverStats:
    steps: int = 0
    fallbacks: int = 0
    solve_times_s: list[float] = field(default_factory=list)


class AtoDriver:
    """Hold/stop supervisor around a carriage-level law (see module docstring)."""

    def __init__(
        self,
        law: CarriageLaw,
        params: MultipointParams,
        period_s: float,
        hold_decel_mps2: float = 0.3,
        stop_tolerance_m: float = 0.3,
    ) -> None:
        self.law = law
        self.p = params
        self.period_s = period_s
        self.hold_force_n = -min(hold_decel_mps2 * params.car_mass_kg, -params.force_min_n)
        self.stop_tolerance_m = stop_tolerance_m
        self.u_prev = np.zeros(params.n_cars)
        self.holding = False
        self.stats = DriverStats()

    def reset(self, u_prev_n: np.ndarray | None = None) -> None:
        self.law.reset()
        self.u_prev = np.zeros(self.p.n_cars) if u_prev_n is None else np.asarray(u_prev_n, dtype=float).copy()
        self.holding = False

    def should_hold(self, sit: Situation, dwelling: bool) -> bool:
        standing = sit.v1_mps <= self.p.standstill_mps
        at_stop = sit.x1_m >= sit.profile.stop_m - self.stop_tolerance_m
        return dwelling or (standing and at_stop)

    def ramp_to(self, target_n: np.ndarray) -> np.ndarray:
        step_hi = self.p.force_rate_max_n_per_s * self.period_s
        step_lo = self.p.force_rate_min_n_per_s * self.period_s
        return self.u_prev + np.clip(target_n - self.u_prev, step_lo, step_hi)

    def step(self, sit: Situation, dwelling: bool = False) -> tuple[np.ndarray, dict[str, Any]]:
        self.stats.steps += 1
        if self.should_hold(sit, dwelling):
            if not self.holding:
                self.law.reset()
            self.holding = True
            u = self.ramp_to(np.full(self.p.n_cars, self.hold_force_n))
            info: dict[str, Any] = {"phase": "hold"}
        else:
            self.holding = False
            u, info = self.law.forces(sit, self.u_prev)
            info = dict(info)
            info.setdefault("phase", "run")
            if not np.all(np.isfinite(u)):  # never hand NaN on (nor keep it as u_prev): brake at the rate limit
                self.law.reset()
                u = self.ramp_to(np.full(self.p.n_cars, self.hold_force_n))
                info.update(fallback=True, fallback_reason="non-finite carriage forces from the law; braking")
            if info.get("fallback"):
                self.stats.fallbacks += 1
            if "solve_time_s" in info:
                self.stats.solve_times_s.append(float(info["solve_time_s"]))
        u = np.clip(u, self.p.force_min_n, self.p.force_max_n)
        self.u_prev = u
        return u, info
