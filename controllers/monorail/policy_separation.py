"""Separation by a selectable braking mode (Paper D §3.9): ADBM or RDBM, for the ``separation`` role of a line.

The engine's default ``separation`` keeps an absolute braking distance to the last *known* rear of the train ahead.
Paper D compares two modes for trains that are not coupled:

* **ADBM** (absolute): the follower must stop before the train ahead's current rear, as if it stopped dead;
* **RDBM** (relative): the follower may count on the train ahead's own braking distance and protects only the
  difference — shorter headways, but only safe if the train ahead really brakes as assumed.

This controller reads the train ahead from ``obs.predecessor`` (ground or radio data, stale when late — the age is
added to the reaction time) and caps the speed at :func:`controllers.monorail.braking_modes.max_safe_speed_mps` of
the chosen :class:`~controllers.monorail.braking_modes.BrakingPolicy`, tracked with a proportional law (``k_speed``)
and braking at up to service rate (emergency when even that is not enough). The same policy object drives the
collision-avoidance trigger (:mod:`.collision_avoidance`), so a scenario can run the whole line in one mode.

Parameters: ``mode`` (``adbm`` | ``rdbm``), ``t_eq_s`` (equivalent response time, default 1.0 s), ``margin_m``
(default 5 m), ``leader_decel_mps2`` (RDBM's assumed deceleration of the train ahead; default: own), ``k_speed_per_s``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from controllers.base import Command, Observation, register
from controllers.braking import require, traction_limit_mps2
from controllers.monorail.braking_modes import BrakingPolicy, max_safe_speed_mps
from railsim.physics.vehicle import VehicleParams


@dataclass(frozen=True)
class PolicySeparationParams:
    mode: str = "adbm"
    t_eq_s: float = 1.0
    margin_m: float = 5.0
    leader_decel_mps2: float = 0.0  # 0: same as own
    k_speed_per_s: float = 1.0


class PolicySeparation:
    def __init__(self, params: PolicySeparationParams, vehicle: VehicleParams) -> None:
        self.params = params
        self.vehicle = vehicle

    def reset(self) -> None:
        return None

    def policy(self, age_s: float) -> BrakingPolicy:
        p = self.params
        return BrakingPolicy(
            mode=p.mode,
            t_eq_s=p.t_eq_s + max(age_s, 0.0),
            margin_m=p.margin_m,
            leader_decel_mps2=p.leader_decel_mps2 or None,
        )

    def command(self, obs: Observation) -> Command:
        veh = obs.vehicle
        v = max(obs.own.speed_mps, 0.0)
        traction = traction_limit_mps2(veh, v)
        pred = obs.predecessor
        if pred is None:
            return Command(traction, info={"phase": "free"})
        gap = pred.rear_position_m - obs.own.position_m
        v_cap = max_safe_speed_mps(self.policy(pred.age_s), gap, pred.speed_mps, veh.emergency_decel_mps2)
        if math.isinf(v_cap):
            return Command(traction, info={"phase": "free", "gap_m": gap})
        a_net = self.params.k_speed_per_s * (v_cap - v)
        u = veh.net_to_applied(a_net, v, obs.own.gradient_permille)
        if u < -veh.service_decel_mps2 and v > 0.0:
            return Command(-veh.emergency_decel_mps2, emergency=True, info={"phase": "emergency", "v_cap_mps": v_cap})
        return Command(min(u, traction), info={"phase": "cap", "v_cap_mps": v_cap, "gap_m": gap})


@register("policy_separation")
def make_policy_separation(params: Mapping[str, Any], vehicle: VehicleParams) -> PolicySeparation:
    """Factory: ``{type: policy_separation, params: {mode: rdbm, t_eq_s: 1.0, margin_m: 5}}``."""
    params = dict(params or {})
    unknown = set(params) - {f for f in PolicySeparationParams.__dataclass_fields__}
    if unknown:
        raise ValueError(
            f"{sorted(unknown)[0]}: unknown parameter; expected mode, t_eq_s, margin_m, "
            "leader_decel_mps2, k_speed_per_s"
        )
    p = PolicySeparationParams(**params)
    require("mode", p.mode in ("adbm", "rdbm"), "'adbm' or 'rdbm'", p.mode)
    for name in ("t_eq_s", "margin_m", "leader_decel_mps2"):
        value = getattr(p, name)
        require(
            name, isinstance(value, (int, float)) and not isinstance(value, bool) and value >= 0, "a number >= 0", value
        )
    k = p.k_speed_per_s
    require("k_speed_per_s", isinstance(k, (int, float)) and not isinstance(k, bool) and k > 0, "a number > 0", k)
    return PolicySeparation(p, vehicle)
