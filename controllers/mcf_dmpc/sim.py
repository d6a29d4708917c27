"""A pure-numpy closed-loop runner for Paper A platoons (spec 000 §4): N trains on a straight, flat line.

Plant: :func:`railsim.physics.dynamics.step_many` with the Table I unit (:func:`~controllers.mcf_dmpc.spacing.paper000_vehicle`)
and ``step_method="ballistic"`` — with τ = 1 s, no lag and no jerk limit this is exactly Eq. (2)
``x+ = x + τv + τ²/2·(u − ω(v))``, ``v+ = v + τ(u − ω(v))`` (plus the plant's envelope clip and v ≥ 0).

Leader (A32/A34): it follows a target speed profile exactly, ``u_1 = ω(v_1) + (v_ref(t + τ) − v_1)/τ``, without
noise — constant speed (S-A…S-D) or :func:`variable_speed_profile` (S-E: 220 → 180 km/h at 0.2 m/s², hold 100 s,
back to 220 km/h, starting at ``t0 = 20`` s). Its plan is either unknown to the follower (no plan, the follower
extrapolates constant speed) or the scheduled profile (``leader_future_known``, A17).

Followers: any controller of :mod:`controllers.base` (Paper A's or others). Perfect communication: every train
broadcasts its state and ``Command.info["plan"]`` each step; with ``plan_delay_steps = 1`` (default, parallel DMPC)
a follower sees its predecessor's message of the previous step (age τ), with ``0`` the fresh message of the same
step (sequential DMPC, A17). Control noise N(0, σ²) is added to each follower's command after the controller
(A8: followers only, not inside predictions), from a seeded generator.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from controllers.base import Command, Controller, Observation, OwnState, PredecessorState
from controllers.mcf_dmpc.spacing import (
    TrainParamsA,
    desired_spacing_m,
    paper000_vehicle,
    safe_spacing_m,
    train_params_from_vehicle,
)
from railsim.physics.dynamics import FleetParams, step_many
from railsim.physics.vehicle import VehicleParams

__all__ = ["PlatoonRun", "constant_speed_profile", "run_platoon", "variable_speed_profile"]

KMH = 1.0 / 3.6

SpeedProfile = Callable[[float], float]


def constant_speed_profile(speed_mps: float) -> SpeedProfile:
    return lambda t: speed_mps


def variable_speed_profile(
    high_mps: float = 220 * KMH,
    low_mps: float = 180 * KMH,
    rate_mps2: float = 0.2,
    hold_s: float = 100.0,
    start_s: float = 20.0,
) -> SpeedProfile:
    """S-E leader reference: decelerate at ``rate`` from ``start_s``, hold ``hold_s``, accelerate back."""
    ramp_s = (high_mps - low_mps) / rate_mps2
    t1, t2, t3 = start_s + ramp_s, start_s + ramp_s + hold_s, start_s + 2 * ramp_s + hold_s

    def v_ref(t: float) -> float:
        if t <= start_s:
            return high_mps
        if t <= t1:
            return high_mps - rate_mps2 * (t - start_s)
        if t <= t2:
            return low_mps
        if t <= t3:
            return low_mps + rate_mps2 * (t - t2)
        return high_mps

    return v_ref


@dataclass(frozen=True)
class PlatoonRun:
    """Arrays of one run. Samples ``t[k] = k·dt`` (T + 1); per-step arrays (T) act over ``[t_k, t_{k+1}]``.

    Column ``i`` is train ``i`` (0 = leader). Follower-only arrays hold NaN / 0 in the leader's column.
    """

    t: np.ndarray  # (T+1,)
    x: np.ndarray  # (T+1, N) front positions [m]
    v: np.ndarray  # (T+1, N) speeds [m/s]
    u_cmd: np.ndarray  # (T, N) controller command (before noise)
    u_applied: np.ndarray  # (T, N) command + noise, as sent to the plant
    J: np.ndarray  # (T, N) info["J"]
    solve_time_s: np.ndarray  # (T, N) info["solve_time_s"] (wall clock of command())
    fallback: np.ndarray  # (T, N) bool
    model_counts: np.ndarray  # (T, N, 3) how often each CF model appears in the chosen sequence
    lengths_m: np.ndarray  # (N,)
    train: TrainParamsA  # spacing parameters used for D^(e), D^(s)
    infos: list[list[dict[str, Any]]]  # per step, per train: the command's info without the plan

    @property
    def spacing_m(self) -> np.ndarray:
        """ΔS_{i,i−1} = x_{i−1} − x_i, shape (T+1, N−1) (column i−1 is follower i)."""
        return self.x[:, :-1] - self.x[:, 1:]

    @property
    def desired_m(self) -> np.ndarray:
        return desired_spacing_m(self.v[:, 1:], self.v[:, :-1], self.train, pred_length_m=None)

    @property
    def safe_m(self) -> np.ndarray:
        return safe_spacing_m(self.v[:, 1:], self.v[:, :-1], self.train)

    @property
    def speed_error_mps(self) -> np.ndarray:
        """Δv_i = v_{i−1} − v_i, shape (T+1, N−1)."""
        return self.v[:, :-1] - self.v[:, 1:]


def run_platoon(
    followers: Sequence[Controller],
    x0_m: Sequence[float],
    v0_mps: Sequence[float],
    n_steps: int,
    *,
    leader_speed: SpeedProfile | None = None,
    leader_future_known: bool = False,
    vehicle: VehicleParams | None = None,
    noise_sd_mps2: float = 0.01,
    seed: int = 0,
    plan_delay_steps: int = 1,
    dt_s: float = 1.0,
    horizon_steps: int = 60,
) -> PlatoonRun:
    """Run a leader and ``len(followers)`` followers (train ``i`` follows ``i − 1``) for ``n_steps`` steps."""
    n = len(followers) + 1
    if len(x0_m) != n or len(v0_mps) != n:
        raise ValueError(f"x0_m and v0_mps need {n} entries (leader + {n - 1} followers)")
    if plan_delay_steps not in (0, 1):
        raise ValueError(f"plan_delay_steps must be 0 or 1, got {plan_delay_steps!r}")
    veh = vehicle if vehicle is not None else paper000_vehicle()
    train = train_params_from_vehicle(veh, dt_s=dt_s)
    fleet = FleetParams.from_vehicles([veh] * n)
    v_ref = leader_speed if leader_speed is not None else constant_speed_profile(float(v0_mps[0]))
    rng = np.random.default_rng(seed)

    x = np.empty((n_steps + 1, n))
    v = np.empty((n_steps + 1, n))
    x[0], v[0] = np.asarray(x0_m, dtype=float), np.asarray(v0_mps, dtype=float)
    u_cmd = np.zeros((n_steps, n))
    u_app = np.zeros((n_steps, n))
    j_arr = np.full((n_steps, n), np.nan)
    t_arr = np.full((n_steps, n), np.nan)
    fb = np.zeros((n_steps, n), dtype=bool)
    counts = np.zeros((n_steps, n, 3), dtype=np.int64)
    infos: list[list[dict[str, Any]]] = []
    applied = np.zeros(n)
    target = np.zeros(n)
    last_msg: list[PredecessorState | None] = [None] * n

    def leader_command(t: float, v1: float) -> float:
        return float(train.resistance_mps2(v1)) + (v_ref(t + dt_s) - v1) / dt_s

    def leader_plan(t: float, x1: float, v1: float) -> dict[str, Any]:
        xs, vs, us = [x1], [v1], []
        for j in range(horizon_steps):
            uj = leader_command(t + j * dt_s, vs[-1])
            a = uj - float(train.resistance_mps2(vs[-1]))
            xs.append(xs[-1] + dt_s * vs[-1] + 0.5 * dt_s * dt_s * a)
            vs.append(vs[-1] + dt_s * a)
            us.append(uj)
        us.append(us[-1])
        return {"dt_s": dt_s, "position_m": tuple(xs), "speed_mps": tuple(vs), "accel_mps2": tuple(us)}

    for k in range(n_steps):
        t = k * dt_s
        fresh: list[PredecessorState] = []
        step_info: list[dict[str, Any]] = []
        for i in range(n):
            if i == 0:
                u = leader_command(t, float(v[k, 0]))
                plan = leader_plan(t, float(x[k, 0]), float(v[k, 0])) if leader_future_known else None
                cmd = Command(u, info={"plan": plan} if plan else {})
            else:
                if plan_delay_steps == 0 or last_msg[i - 1] is None:
                    msg = fresh[i - 1]
                else:
                    msg = last_msg[i - 1]
                assert msg is not None
                pred = PredecessorState(
                    msg.train_id,
                    msg.position_m,
                    msg.speed_mps,
                    msg.accel_mps2,
                    msg.length_m,
                    msg.stamp_s,
                    t - msg.stamp_s,
                    msg.service_decel_mps2,
                    msg.emergency_decel_mps2,
                    msg.planned_position_m,
                    msg.planned_speed_mps,
                    msg.planned_accel_mps2,
                    msg.plan_dt_s,
                )
                obs = Observation(
                    t_s=t,
                    dt_s=dt_s,
                    own=OwnState(f"T{i + 1}", float(x[k, i]), float(v[k, i]), float(applied[i]), veh.length_m),
                    vehicle=veh,
                    route_length_m=1.0e9,
                    predecessor=pred,
                    formation_state="coupled",
                )
                cmd = followers[i - 1].command(obs)
            info = dict(cmd.info)
            plan = info.pop("plan", None)
            step_info.append(info)
            u_cmd[k, i] = cmd.accel_mps2
            noise = rng.normal(0.0, noise_sd_mps2) if (i > 0 and noise_sd_mps2 > 0.0) else 0.0
            u_app[k, i] = cmd.accel_mps2 + noise
            fb[k, i] = cmd.fallback
            if i > 0:
                j_arr[k, i] = float(info.get("J", np.nan))
                t_arr[k, i] = float(info.get("solve_time_s", np.nan))
                seq = info.get("model_sequence")
                if seq is not None:
                    counts[k, i] = np.bincount(np.asarray(seq, dtype=np.int64), minlength=3)[:3]
            fresh.append(
                PredecessorState(
                    f"T{i + 1}",
                    float(x[k, i]),
                    float(v[k, i]),
                    float(cmd.accel_mps2),
                    veh.length_m,
                    t,
                    0.0,
                    veh.service_decel_mps2,
                    veh.emergency_decel_mps2,
                    tuple(plan["position_m"]) if plan else (),
                    tuple(plan["speed_mps"]) if plan else (),
                    tuple(plan["accel_mps2"]) if plan else (),
                    float(plan["dt_s"]) if plan else 0.0,
                )
            )
        last_msg = list(fresh)
        infos.append(step_info)
        res = step_many(
            fleet, v[k], applied, target, u_app[k], dt_s, emergency=np.array([False] * n), step_method="ballistic"
        )
        applied, target = res.applied_accel_mps2, res.target_accel_mps2
        v[k + 1] = res.speed_mps
        x[k + 1] = x[k] + res.advance_m
    return PlatoonRun(
        np.arange(n_steps + 1) * dt_s,
        x,
        v,
        u_cmd,
        u_app,
        j_arr,
        t_arr,
        fb,
        counts,
        np.full(n, veh.length_m),
        train,
        infos,
    )
