"""Moving-block separation with the absolute braking distance (the ``follow`` role of uncoupled trains).

Rule (ETCS level 3 / CBTC moving block, "brick wall"): the follower must at every moment be able to stop
behind the predecessor's rear **as last known**, minus a safety margin, assuming the predecessor could stand
still there. A stale message is conservative because trains do not reverse: the true rear is at or ahead of the
last reported one.

Free distance and braking distance (dead-time model of :mod:`controllers.braking`)::

    d_free = rear_known − margin − x_front
    S(v)   = v·T + a0·T²/2 + (v + a0·T)² / (2·b)
    T      = reaction_time + message age + dt + actuator lag τ + ½·jerk ramp (a0 → −b)

(``dt``: a command is held for one control step before the next decision.)

with ``b`` the service braking as a net deceleration (gradient included, running resistance left out so that
one's own braking is not over-estimated). The safety invariant is ``h = d_free − S(v) ≥ 0``.

Control law (a control-barrier-function reading of "stay on or below the braking curve"): the command is
capped so that ``h`` decays no faster than ``−γ·h``. Differentiating with a brick-wall predecessor
(``d_free`` shrinks at ``v``) and ``∂S/∂v = T + (v + a0·T)/b``::

    a ≤ (γ·h − v) / (T + (v + a0·T)/b)

Far from the predecessor the cap is large and ATO is in charge (the engine takes the minimum). Approaching a
standing train the cap starts biting about ``v/γ`` before the braking curve and then brings the train to rest
with ``h → 0``, i.e. before ``rear − margin`` (the barrier is taken one step of travel ``v·dt`` plus a 1 m
standstill buffer short of the boundary, so the sampled, lagged plant halts before it rather than on it;
the last metre at a crawl is replaced by a gentle halt). Behind a running predecessor the follower settles
at roughly ``S(v) + v/γ + margin`` behind the last known rear. When ``h < 0`` (a new predecessor appears close, a
long message outage) the same cap asks for more than ``v/(∂S/∂v)`` of braking (clipped to service), and
``emergency=True`` if service braking with no
reaction allowance (predicted with the plant's exact discrete recursion, see :mod:`controllers.braking`)
would no longer stop before ``rear − margin``.

Reading of the brief: the message age is added to the reaction time although a brick-wall rear is already the
worst case for a stale message — the extra distance is the degraded-mode behaviour of a train whose data is old.
Without a predecessor there is no restriction: the command is the traction limit, so ``min()`` leaves ATO in
charge.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from controllers import line_kernels
from controllers.base import Command, Observation, register
from controllers.braking import (
    params_from_mapping,
    require,
    traction_limit_mps2,
)
from railsim.physics.vehicle import VehicleParams


@dataclass(frozen=True)
class SeparationParams:
    """Absolute-braking-distance separation parameters."""

    margin_m: float = 50.0  # stop at least this far behind the predecessor's last known rear [m]
    reaction_time_s: float = 1.0  # reaction/latency allowance on top of the message age [s]
    barrier_rate_per_s: float = 0.5  # γ: how fast the free distance may be used up [1/s] (capped at 0.5/dt)

    def __post_init__(self) -> None:
        require("margin_m", self.margin_m >= 0.0, "a number >= 0", self.margin_m)
        require("reaction_time_s", self.reaction_time_s >= 0.0, "a number >= 0", self.reaction_time_s)
        require("barrier_rate_per_s", self.barrier_rate_per_s > 0.0, "a number > 0", self.barrier_rate_per_s)


class Separation:
    """Moving-block separation for one train (stateless)."""

    def __init__(self, params: SeparationParams, vehicle: VehicleParams) -> None:
        self.params = params
        self.vehicle = vehicle
        self._packed = np.zeros(0)  # the kernel's packed inputs for the vehicle and dt last seen
        self._packed_vehicle: VehicleParams | None = None
        self._packed_dt = math.nan

    def reset(self) -> None:
        """Nothing to forget: the law keeps no state."""

    def command(self, obs: Observation) -> Command:
        own = obs.own
        pred = obs.predecessor
        if pred is None:
            return Command(traction_limit_mps2(obs.vehicle, max(own.speed_mps, 0.0)), info={"phase": "free"})
        return self.decide(
            obs.vehicle,
            obs.dt_s,
            own.position_m,
            own.speed_mps,
            own.accel_mps2,
            own.gradient_permille,
            pred.rear_position_m,
            pred.age_s,
        )

    def decide(
        self,
        veh: VehicleParams,
        dt_s: float,
        x: float,
        speed_mps: float,
        a0: float,
        grade: float,
        pred_rear_m: float,
        pred_age_s: float,
    ) -> Command:
        """The law against a known predecessor rear, on plain values; :meth:`command` is this on an observation.
        The engine calls it directly for a train whose separation role is this class (no observation built).

        The law itself is :func:`controllers.line_kernels.separation`, written once and compiled; this packs its
        inputs."""
        accel, emergency, phase, free_m, h = line_kernels.separation(
            self.packed(veh, dt_s), x, speed_mps, a0, grade, pred_rear_m, pred_age_s
        )
        info = {"phase": line_kernels.SEPARATION_PHASES[phase], "free_m": free_m, "barrier_m": h}
        return Command(accel, emergency=emergency, info=info)

    def packed(self, veh: VehicleParams, dt_s: float) -> np.ndarray:
        """The law's inputs for ``veh`` and step ``dt_s`` as :func:`controllers.line_kernels.separation` reads
        them (packed once per vehicle and step; also for a caller's own compiled step,
        ``railsim.engine.line_step_kernel``)."""
        if veh is not self._packed_vehicle or dt_s != self._packed_dt:
            self._packed = line_kernels.pack(line_kernels.SEPARATION_FIELDS, veh, self.params, dt_s)
            self._packed_vehicle, self._packed_dt = veh, dt_s
        return self._packed


@register("separation")
def make_separation(params: Mapping[str, Any], vehicle: VehicleParams) -> Separation:
    """Factory for scenarios: ``controllers: {follow: {type: separation, margin_m: 50}}``."""
    return Separation(params_from_mapping(SeparationParams, params), vehicle)
