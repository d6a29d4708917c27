"""A pure-numpy closed-loop runner for Paper A platoons (spec 000 §4): N trains on a straight, flat line.

Plant: :func:`railsim.physics.dynamics.step_many` with the Table I unit (:func:`~controllers.mcf_dmpc.spacing.paper000_vehicle`)
and ``step_method="ballistic"`` — with τ = 1 s, no lag and no jerk limit this is exactly Eq. (2)
``x+ = x + τv + τ²/2·(u − ω(v))``, ``v+ = v + τ(u − ω(v))`` (plus the plant's envelope clip and v ≥ 0).

Leader (A32/A34): a controller like the followers — by default the engine's ``speed_profile``
(:func:`paper000_leader`: constant speed for S-A…S-D, :data:`S_E_SEGMENTS` for S-E), so the numpy runner and a
``railsim run`` of the same scenario drive the leader with the same law, and it broadcasts its plan (A17 "leader
future known") or not (``plan=False``: the follower extrapolates). No noise on the leader (A8).

Followers: any controller of :mod:`controllers.base` (Paper A's or others). Perfect communication: every train
broadcasts its state and ``Command.info["plan"]`` each step. What a follower reads at ``t_k`` (``messages``):

* ``"engine"`` (default) — the engine's zero-delay t2t (:mod:`railsim.engine.knowledge`): the predecessor's state
  at ``t_k`` (age 0) and the plan it decided at ``t_{k−1}``, aligned so that entry 0 is ``t_k`` (parallel DMPC,
  the A17 alternative; the plan leaves with the next position report);
* ``"previous"`` — the whole message of ``t_{k−1}`` (state and plan, age τ);
* ``"sequential"`` — the fresh message of ``t_k`` (the predecessor decided first, A17 default).

Why ``"engine"`` is the default: with a leader that sends no plan the follower extrapolates the last
reported state, and a report one step old (``"previous"``, this runner's former default) misses the leader's
last step of a 0.2 m/s² ramp — S-E mean |ΔS − D^(e)| 10.5 m against 7.2 m for the engine's age-0 report, the
whole engine-vs-numpy disagreement. ``tests/sumo/test_paper000_agreement.py`` pins the two to each other.

Control noise N(0, σ²) is added to each follower's command after the controller (A8: followers only, not inside
predictions), from a seeded generator. ``t0_s`` is the clock the controllers see at the first step (the engine
inserts departures at 0 in its first step and controls them from ``t = 1`` s: ``t0_s = 1`` replays that clock;
the run's ``t`` stays the paper time ``k·τ``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from controllers.base import Controller, Observation, OwnState, PredecessorState
from controllers.mcf_dmpc.spacing import (
    TrainParamsA,
    desired_spacing_m,
    paper000_vehicle,
    safe_spacing_m,
    train_params_from_vehicle,
)
from controllers.speed_profile import make_speed_profile
from railsim.physics.dynamics import FleetParams, step_many
from railsim.physics.vehicle import VehicleParams

__all__ = ["MESSAGES", "S_E_SEGMENTS", "PlatoonRun", "paper000_leader", "run_platoon"]

KMH = 1.0 / 3.6
MESSAGES = ("engine", "previous", "sequential")
# S-E (A32): 220 -> 180 km/h at 0.2 m/s^2 from t0 = 20 s (55.56 s), hold 100 s, back to 220 km/h from 175.556 s
S_E_SEGMENTS: tuple[Mapping[str, float], ...] = (
    {"at_s": 20.0, "to_kmh": 180.0, "accel_mps2": 0.2},
    {"at_s": 175.556, "to_kmh": 220.0, "accel_mps2": 0.2},
)


def paper000_leader(
    initial_kmh: float = 220.0,
    segments: Sequence[Mapping[str, float]] = (),
    *,
    plan: bool = True,
    horizon_s: float = 60.0,
    vehicle: VehicleParams | None = None,
) -> Controller:
    """The Paper A leader as the engine runs it: ``speed_profile`` with the paper000 scenarios' parameters."""
    params: dict[str, Any] = {"initial_kmh": initial_kmh, "segments": [dict(s) for s in segments]}
    if plan:
        params["plan_horizon_s"] = horizon_s
    return make_speed_profile(params, vehicle if vehicle is not None else paper000_vehicle())


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
    leader: Controller | None = None,
    vehicle: VehicleParams | None = None,
    noise_sd_mps2: float = 0.01,
    seed: int = 0,
    messages: str = "engine",
    dt_s: float = 1.0,
    t0_s: float = 0.0,
) -> PlatoonRun:
    """Run a leader and ``len(followers)`` followers (train ``i`` follows ``i − 1``) for ``n_steps`` steps.

    ``leader`` defaults to :func:`paper000_leader` at the leader's initial speed (constant, plan broadcast).
    """
    n = len(followers) + 1
    if len(x0_m) != n or len(v0_mps) != n:
        raise ValueError(f"x0_m and v0_mps need {n} entries (leader + {n - 1} followers)")
    if messages not in MESSAGES:
        raise ValueError(f"messages: expected one of {', '.join(MESSAGES)}, got {messages!r}")
    veh = vehicle if vehicle is not None else paper000_vehicle()
    train = train_params_from_vehicle(veh, dt_s=dt_s)
    fleet = FleetParams.from_vehicles([veh] * n)
    lead = leader if leader is not None else paper000_leader(float(v0_mps[0]) / KMH, vehicle=veh)
    controllers_: list[Controller] = [lead, *followers]
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

    for k in range(n_steps):
        t = t0_s + k * dt_s
        fresh: list[PredecessorState] = []
        step_info: list[dict[str, Any]] = []
        for i in range(n):
            own = OwnState(f"T{i + 1}", float(x[k, i]), float(v[k, i]), float(applied[i]), veh.length_m)
            pred = None if i == 0 else _message(fresh[i - 1], last_msg[i - 1], messages, t)
            obs = Observation(
                t_s=t,
                dt_s=dt_s,
                own=own,
                vehicle=veh,
                route_length_m=1.0e9,
                predecessor=pred,
                formation_state="coupled" if i > 0 else "free",
            )
            cmd = controllers_[i].command(obs)
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
                    # the engine reports the plant's applied acceleration of the last step, not this command
                    float(applied[i]) if messages == "engine" else float(cmd.accel_mps2),
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


def _message(now: PredecessorState, previous: PredecessorState | None, messages: str, t_s: float) -> PredecessorState:
    """What a follower reads of its predecessor at ``t_s`` under the ``messages`` convention (module docstring)."""
    if messages == "sequential" or (previous is None and messages == "previous"):
        return now
    if messages == "previous":
        assert previous is not None
        return replace(previous, age_s=t_s - previous.stamp_s)
    # "engine": the state now, the plan decided one step ago with its entry for the previous step dropped (no plan
    # at the first step: nothing was decided before it)
    if previous is None or not previous.planned_position_m:
        return replace(now, planned_position_m=(), planned_speed_mps=(), planned_accel_mps2=(), plan_dt_s=0.0)
    drop = 1 if len(previous.planned_position_m) > 1 else 0
    return replace(
        now,
        planned_position_m=previous.planned_position_m[drop:],
        planned_speed_mps=previous.planned_speed_mps[drop:],
        planned_accel_mps2=previous.planned_accel_mps2[drop:],
        plan_dt_s=previous.plan_dt_s,
    )
