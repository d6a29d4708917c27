"""Virtual-coupling controllers of Paper D: the APF law (§3.6, Eqs 9–11) and the distributed MPC (§3.7).

Both are registered for the ``coupled`` role (a formation follower) and read ``obs.predecessor`` — the
predecessor's *broadcast* state, delayed and possibly stale — extrapolated by its message age at constant
acceleration. The target gap is ``obs.target_gap_m`` (fallback ``target_gap_m``).

**APF** (``monorail_apf``). Eq. (11) with the quadratic potentials of Eqs (9)–(10), in the spec's
predecessor-following form with acceleration feed-forward::

    u = sat( k_ff·â_p + k_x·(g − d_c) + k_v·(v_p − v) )

Far from the target the attraction ``k_x·(g − d_c)`` is limited to ``k_v·min(v_close, √(2·b_rel·(g − d_c)))``
(a shaped potential: the follower closes at a bounded relative speed it can shed at ``b_rel``), otherwise a
follower 100 m back would saturate traction and overshoot. :func:`apf_graph_accel` is Eq. (11) literally on a
graph (adjacency ``A``); :func:`laplacian` and :func:`incidence` are Eqs (7)–(8).

**DMPC** (``monorail_dmpc``). Eqs (12)–(16) (a Cao–Ren estimator) are not implemented literally (spec §3.7);
each follower solves the local QP of :mod:`.mpc` against the predecessor's broadcast plan
(``planned_position_m``/``planned_speed_mps``, shifted by the message age) or, without a plan, its
constant-acceleration extrapolation.

**Safety cap** (both). The braking-distance policy of :mod:`.braking_modes` (default RDBM with the vehicle's
real actuation delay, t_eq = 0.3 s, 1.5 m margin — A3: a 28 m fixed threshold cannot coexist with a 5 m coupling
gap) gives the highest safe speed ``v_safe(g, v_p)``; the command is capped at ``k_cap·(v_safe − v)`` so the
coupling law itself never drives into the collision-avoidance trigger. The emergency decision is left to the CA
role (:mod:`.collision_avoidance`). ``k_cap = 2/s`` (it was 1/s): a follower closing at ~3 m/s rides a
safe-speed curve that falls at ~0.2 m/s², and a proportional cap lags it by ``(dv_safe/dt)/k_cap``; at 1/s (plus
the 0.3 s drive lag) that put the follower ~0.5 m inside the CA's RDBM trigger during normal accelerated coupling
in SUMO, and the bare trigger fired the emergency brake 5 (empty) / 21 (loaded) times. At 2/s it stays outside.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from controllers.base import Command, Observation, register
from controllers.braking import params_from_mapping, require
from controllers.monorail.braking_modes import BrakingPolicy, max_safe_speed_mps
from controllers.monorail.mpc import GapTrackingQp, QpWeights, predict_ahead
from railsim.physics.vehicle import VehicleParams


def laplacian(adjacency: np.ndarray) -> np.ndarray:
    """Eq. (7): ``L_G = D − A`` (row sums of the link qualities on the diagonal)."""
    a = np.asarray(adjacency, dtype=float)
    return np.diag(a.sum(axis=1)) - a


def incidence(edges: list[tuple[int, int]], n: int) -> np.ndarray:
    """Eq. (8): ``B[k, i] = +1`` at the start vertex of edge k, ``−1`` at its end; ``BᵀB`` is the undirected L_G."""
    b = np.zeros((len(edges), n))
    for k, (i, j) in enumerate(edges):
        b[k, i], b[k, j] = 1.0, -1.0
    return b


def apf_graph_accel(
    positions_m: np.ndarray,
    speeds_mps: np.ndarray,
    adjacency: np.ndarray,
    offsets_m: np.ndarray,
    k_x_per_s2: float,
    k_v_per_s: float,
) -> np.ndarray:
    """Eq. (11): ``u_i = k_x Σ_j a_ij (x_j − x_i − d_ij) + k_v Σ_j a_ij (v_j − v_i)`` for all vehicles.

    ``offsets_m[i, j] = d_ij``, the desired ``x_j − x_i`` (positive when j is ahead of i).
    """
    x = np.asarray(positions_m, float)
    v = np.asarray(speeds_mps, float)
    a = np.asarray(adjacency, float)
    pos = (a * (x[None, :] - x[:, None] - np.asarray(offsets_m, float))).sum(axis=1)
    vel = (a * (v[None, :] - v[:, None])).sum(axis=1)
    return k_x_per_s2 * pos + k_v_per_s * vel


def predecessor_now(obs: Observation) -> tuple[float, float, float]:
    """(gap now [m], predecessor speed [m/s], acceleration [m/s²]), the message extrapolated by its age."""
    pred = obs.predecessor
    assert pred is not None
    age = max(pred.age_s, 0.0)
    v_p, a_p = max(pred.speed_mps, 0.0), pred.accel_mps2
    if v_p <= 0.01 and a_p < 0.0:
        a_p = 0.0  # a standing vehicle's holding brake does not move it: no feed-forward from it
    dx, v_now = predict_ahead(v_p, a_p, age, 1) if age > 0.0 else (np.zeros(1), np.array([v_p]))
    return float(pred.rear_position_m + dx[0] - obs.own.position_m), float(v_now[0]), a_p


def _limits(vehicle: VehicleParams) -> tuple[float, float, float]:
    """(traction max, service decel, emergency decel) of the vehicle [m/s²]."""
    return (
        vehicle.traction_max_force_n / vehicle.effective_mass_kg,
        vehicle.service_decel_mps2,
        vehicle.emergency_decel_mps2,
    )


@dataclass(frozen=True)
class CouplingSafety:
    safety_mode: str = "rdbm"
    safety_t_eq_s: float = 0.3
    safety_margin_m: float = 1.5
    k_cap_per_s: float = 2.0
    lookahead_s: float = 1.0

    def policy(self) -> BrakingPolicy:
        return BrakingPolicy(mode=self.safety_mode, t_eq_s=self.safety_t_eq_s, margin_m=self.safety_margin_m)


def _safety_cap(obs: Observation, gap_m: float, v_p: float, safety: CouplingSafety) -> float:
    _, _, b_e = _limits(obs.vehicle)
    # Anticipate the lag of the cap (actuation + 1/k_cap): judge the gap it will be after lookahead_s of closing.
    closing = max(obs.own.speed_mps - v_p, 0.0)
    v_safe = max_safe_speed_mps(safety.policy(), gap_m - closing * safety.lookahead_s, v_p, b_e)
    return math.inf if math.isinf(v_safe) else safety.k_cap_per_s * (v_safe - max(obs.own.speed_mps, 0.0))


def _finish(obs: Observation, net: float, cap: float, info: dict[str, Any]) -> Command:
    a_t, b_s, b_e = _limits(obs.vehicle)
    if cap < net:
        net, info["phase"] = cap, "safety"
    # The coupling law brakes with service braking; only the safety cap may reach into the emergency range.
    low = -b_e if info.get("phase") == "safety" else -b_s
    return Command(min(max(net, low), a_t), info=info)


@dataclass(frozen=True)
class ApfParams:
    k_x_per_s2: float = 0.04
    k_v_per_s: float = 0.4
    k_ff: float = 1.0
    target_gap_m: float = 5.0
    approach_speed_mps: float = 4.0
    approach_decel_mps2: float = 0.3
    safety_mode: str = "rdbm"
    safety_t_eq_s: float = 0.3
    safety_margin_m: float = 1.5
    k_cap_per_s: float = 2.0

    def __post_init__(self) -> None:
        for name in ("k_x_per_s2", "k_v_per_s", "approach_speed_mps", "approach_decel_mps2", "k_cap_per_s"):
            require(name, getattr(self, name) > 0.0, "a number > 0", getattr(self, name))
        require("k_ff", 0.0 <= self.k_ff <= 2.0, "a number in [0, 2]", self.k_ff)
        CouplingSafety(self.safety_mode, self.safety_t_eq_s, self.safety_margin_m).policy()


class MonorailApf:
    """APF coupling law for one follower (stateless)."""

    def __init__(self, params: ApfParams) -> None:
        self.params = params
        self.safety = CouplingSafety(
            params.safety_mode, params.safety_t_eq_s, params.safety_margin_m, params.k_cap_per_s
        )

    def command(self, obs: Observation) -> Command:
        a_t, _, _ = _limits(obs.vehicle)
        if obs.predecessor is None:
            return Command(a_t, info={"phase": "free"})
        p = self.params
        gap, v_p, a_p = predecessor_now(obs)
        d_c = obs.target_gap_m if obs.target_gap_m is not None else p.target_gap_m
        err = gap - d_c
        pos = p.k_x_per_s2 * err
        if err > 0.0:
            pos = min(pos, p.k_v_per_s * min(p.approach_speed_mps, math.sqrt(2.0 * p.approach_decel_mps2 * err)))
        v = max(obs.own.speed_mps, 0.0)
        net = p.k_ff * a_p + pos + p.k_v_per_s * (v_p - v)
        return _finish(
            obs, net, _safety_cap(obs, gap, v_p, self.safety), {"phase": "track", "gap_m": gap, "gap_error_m": err}
        )


@dataclass(frozen=True)
class DmpcParams:
    target_gap_m: float = 5.0
    horizon_steps: int = 20
    control_horizon_steps: int = 10
    dt_s: float = 0.1
    response_s: float = 0.3
    efficiency: float = 1.0
    q_gap: float = 1.0
    q_speed: float = 1.0
    r_u: float = 0.5
    r_du: float = 1.0
    s_min_m: float = 2.0
    approach_speed_mps: float = 4.0
    approach_decel_mps2: float = 0.3
    safety_mode: str = "rdbm"
    safety_t_eq_s: float = 0.3
    safety_margin_m: float = 1.5
    k_cap_per_s: float = 2.0

    def __post_init__(self) -> None:
        for name in ("horizon_steps", "control_horizon_steps"):
            require(
                name,
                float(getattr(self, name)).is_integer() and getattr(self, name) >= 1,
                "an integer >= 1",
                getattr(self, name),
            )
        require(
            "control_horizon_steps",
            self.control_horizon_steps <= self.horizon_steps,
            "at most horizon_steps",
            self.control_horizon_steps,
        )
        require("dt_s", self.dt_s > 0.0, "a number > 0", self.dt_s)
        require("efficiency", 0.0 < self.efficiency <= 1.0, "a number in (0, 1]", self.efficiency)
        for name in ("q_gap", "q_speed", "r_u", "r_du", "s_min_m", "response_s"):
            require(name, getattr(self, name) >= 0.0, "a number >= 0", getattr(self, name))
        CouplingSafety(self.safety_mode, self.safety_t_eq_s, self.safety_margin_m).policy()


class MonorailDmpc:
    """Local DMPC of one follower; keeps its QP (warm OSQP) and its last command."""

    def __init__(self, params: DmpcParams) -> None:
        p = self.params = params
        self.qp = GapTrackingQp(
            p.dt_s,
            p.response_s,
            p.efficiency,
            int(p.horizon_steps),
            int(p.control_horizon_steps),
            QpWeights(p.q_gap, p.q_speed, p.r_u, p.r_du),
        )
        self.safety = CouplingSafety(p.safety_mode, p.safety_t_eq_s, p.safety_margin_m, p.k_cap_per_s)
        self._u_prev = 0.0

    def reset(self) -> None:
        self._u_prev = 0.0

    def command(self, obs: Observation) -> Command:
        a_t, b_s, _ = _limits(obs.vehicle)
        pred = obs.predecessor
        if pred is None:
            return Command(a_t, info={"phase": "free"})
        p = self.params
        n = int(p.horizon_steps)
        gap, v_p, a_p = predecessor_now(obs)
        d_c = obs.target_gap_m if obs.target_gap_m is not None else p.target_gap_m
        if pred.planned_position_m and pred.plan_dt_s > 0.0:
            # The broadcast plan, resampled from "now" (its stamp + age) on at this controller's step.
            t_plan = pred.age_s + p.dt_s * np.arange(0, n + 1)
            grid = pred.plan_dt_s * np.arange(len(pred.planned_position_m))
            pos = np.interp(t_plan, grid, pred.planned_position_m)
            dx, vp = pos[1:] - pos[0], np.interp(t_plan[1:], grid, pred.planned_speed_mps)
        else:
            dx, vp = predict_ahead(v_p, a_p, p.dt_s, n)
        # Bounded approach far from the target (as in the APF law): reference gap slides towards d_c.
        err = gap - d_c
        d_ref = d_c
        if err > 0.0:
            close = min(p.approach_speed_mps, math.sqrt(2.0 * p.approach_decel_mps2 * err))
            d_ref = max(d_c, gap - close * p.dt_s * n)
        v = max(obs.own.speed_mps, 0.0)
        u = self.qp.solve(gap, v, obs.own.accel_mps2, dx, vp, d_ref, p.s_min_m, self._u_prev, -b_s, a_t)
        info: dict[str, Any] = {"phase": "track", "gap_m": gap, "gap_error_m": err}
        if u is None:
            info["phase"] = "fallback"
            info["fallback_reason"] = "coupling QP infeasible; service brake"
            cmd = Command(-b_s, fallback=True, info=info)
        else:
            cmd = _finish(obs, float(u[0]), _safety_cap(obs, gap, v_p, self.safety), info)
        self._u_prev = cmd.accel_mps2
        return cmd


@register("monorail_apf")
def make_apf(params: Mapping[str, Any], vehicle: VehicleParams) -> MonorailApf:
    """``controllers: {coupled: {type: monorail_apf, k_x_per_s2: 0.04, k_v_per_s: 0.4}}``."""
    return MonorailApf(params_from_mapping(ApfParams, params))


@register("monorail_dmpc")
def make_dmpc(params: Mapping[str, Any], vehicle: VehicleParams) -> MonorailDmpc:
    """``controllers: {coupled: {type: monorail_dmpc, horizon_steps: 20}}``."""
    return MonorailDmpc(params_from_mapping(DmpcParams, params))
