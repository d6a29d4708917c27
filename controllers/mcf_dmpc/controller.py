"""Paper A's controllers for the ``follow`` role of a virtually coupled follower (spec 000 §2.6, §2.8, §7).

Registered names (factory ``(params, vehicle)``, parameters as in the dataclasses below):

* ``cf_idm``, ``cf_cacc``, ``cf_fvd`` — CF-DMPC of Section IV-A: one model for the whole horizon (m ≡ const),
  fixed Θ. Reading: the applied control *is* that CF law at the current state (``u_0`` of the single-model
  rollout); the rollout is the prediction broadcast to the follower and scored by J^(DMPC).
* ``mcf_dmpc`` — MCF-DMPC: every step an integer optimiser (``controllers.mcf_dmpc.optim.minimize_sequence``,
  MSMFO by default) picks the model-index sequence m(t_j) ∈ {IDM, CACC, FVD} minimising J^(DMPC) (Eq. 19 +
  penalty for Eq. 20); the first control of the best rollout is applied (A16: re-solve every τ). Decision
  dimension D = Np (A15), option ``decision_dim`` = Nc with the last index held (move blocking).
  Warm start (reading, not in the paper): the optimiser's first individuals are the previous best sequence
  shifted by one step and the three single-model sequences, so MCF never does worse than the best single model
  it was offered.
* ``opo_mcf_dmpc`` — as ``mcf_dmpc`` after OPO (:mod:`controllers.mcf_dmpc.opo`) re-tunes Θ every step (A29:
  before the sequence search), warm-started from the previous step's Θ. By default (``opo_bias: true``, ours)
  OPO also corrects a control offset per law (:mod:`~controllers.mcf_dmpc.cf_models` docstring);
  ``opo_bias: false`` is the paper's reading (θ1 … θ7 only).
* ``dmpc`` — the continuous-u baseline as a sparse OSQP QP (:mod:`controllers.mcf_dmpc.dmpc`); solver failure →
  service braking with ``fallback=True`` and a counter.

Information flow: the predecessor's broadcast plan arrives in ``obs.predecessor.planned_*`` (delayed by the
communication layer); while fresh (age ≤ ``plan_max_age_s``, default 1 s: one lost message at τ = 1 s) it is
shifted by ``age_s`` and extended at constant speed; without a plan, or when it is stale, the last reported state
is extrapolated at constant speed (:func:`~controllers.mcf_dmpc.rollout.predecessor_horizon`). ``info
["predecessor_plan"]`` says which (``plan``/``stale``/``absent``) every step, and a change between using the plan
and extrapolating is ``info["event"]`` = ``leader_plan_lost`` / ``leader_plan_restored`` (the engine records it
in events.csv); a predecessor that never sent a plan raises no event.
Each controller returns its own plan (``Np + 1`` samples, observer's route frame) in ``info["plan"]`` plus
``info["J"]``, ``info["solve_time_s"]`` (wall), ``info["cpu_time_s"]`` and, where relevant, ``info["model_sequence"]`` / ``info["theta"]``.
The previous control ``u_{−1}`` of Eq. (17) is this controller's own last command (A19: 0 at the first step,
option ``u_prev_init: resistance`` for ω(v0)). Controllers add no noise and are deterministic given ``seed``.
The prediction model comes from the train's own :class:`~railsim.physics.vehicle.VehicleParams` (one physics).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from controllers.base import Command, Observation, register
from controllers.braking import params_from_mapping, require
from controllers.mcf_dmpc.cf_models import MODEL_CACC, MODEL_FVD, MODEL_IDM, MODEL_NAMES, THETA_TRAIN2, THETA_TRAIN3
from controllers.mcf_dmpc.cost import CostWeights, dmpc_cost, sequence_costs
from controllers.mcf_dmpc.dmpc import DmpcQp, shift_controls
from controllers.mcf_dmpc.kernels import NUMBA_AVAILABLE, train_vector, weight_vector
from controllers.mcf_dmpc.msmfo_jit import msmfo_mcf
from controllers.mcf_dmpc.opo import OpoSettings, opo_step
from controllers.mcf_dmpc.opo_jit import opo_step_compiled
from controllers.mcf_dmpc.rollout import (
    PredecessorHorizon,
    expand_sequence,
    plan_dict,
    predecessor_horizon,
    rollout_controls,
    rollout_models,
)
from controllers.mcf_dmpc.spacing import TABLE_I, train_params_from_vehicle
from railsim.physics.vehicle import VehicleParams

__all__ = [
    "CfDmpc",
    "CfParams",
    "CommonParams",
    "DmpcController",
    "DmpcParams",
    "McfDmpc",
    "McfParams",
    "OpoMcfDmpc",
    "OpoMcfParams",
]

SequenceOptimizer = Callable[..., Any]  # the interface of controllers.mcf_dmpc.optim.minimize_sequence
_THETA_PRESETS = {"train2": THETA_TRAIN2, "train3": THETA_TRAIN3}


def _int_field(obj: Any, name: str, low: int) -> None:
    value = getattr(obj, name)
    ok = (
        isinstance(value, (int, float))
        and not isinstance(value, bool)
        and math.isfinite(value)
        and float(value).is_integer()
        and value >= low
    )
    require(name, ok, f"an integer >= {low}", value)
    object.__setattr__(obj, name, int(value))


@dataclass(frozen=True)
class CommonParams:
    """Horizon, Table I margin and Table II weights shared by every Paper A controller."""

    horizon_steps: int = 60  # Np
    dt_s: float = 1.0  # τ, prediction step (and the plan's sample interval)
    safety_margin_m: float = TABLE_I.safety_margin_m  # L^(s) = 1.5·v_m
    xi_v: float = 1.0
    xi_s: float = 0.05
    xi_u: float = 200.0
    xi_du: float = 400.0
    xi_term: float = 10.0
    penalty_weight: float = 1.0e6  # A21
    u_prev_init: str = "zero"  # A19: "zero" or "resistance"
    plan_max_age_s: float = 1.0  # the predecessor's plan is used up to this message age, then extrapolated
    seed: int = 0

    def __post_init__(self) -> None:
        _int_field(self, "horizon_steps", 1)
        _int_field(self, "seed", 0)
        require("dt_s", self.dt_s > 0.0, "a number > 0", self.dt_s)
        require("safety_margin_m", self.safety_margin_m >= 0.0, "a number >= 0", self.safety_margin_m)
        require("plan_max_age_s", self.plan_max_age_s >= 0.0, "a number >= 0", self.plan_max_age_s)
        for name in ("xi_v", "xi_s", "xi_u", "xi_du", "xi_term", "penalty_weight"):
            require(name, getattr(self, name) >= 0.0, "a number >= 0", getattr(self, name))
        require("u_prev_init", self.u_prev_init in ("zero", "resistance"), "'zero' or 'resistance'", self.u_prev_init)

    def weights(self) -> CostWeights:
        return CostWeights(self.xi_v, self.xi_s, self.xi_u, self.xi_du, self.xi_term, self.penalty_weight)


@dataclass(frozen=True)
class CfParams(CommonParams):
    """CF parameters: Θ from a Table preset (Θ_2 "train2", Θ_3 "train3") with optional per-θ overrides."""

    theta_preset: str = "train2"
    theta1: float = math.nan  # NaN = take the preset's value
    theta2: float = math.nan
    theta3: float = math.nan
    theta4: float = math.nan
    theta5: float = math.nan
    theta6: float = math.nan
    theta7: float = math.nan
    cacc_feedforward: str = "net"  # A13: predecessor's "net" acceleration or its "applied" control
    resistance_feedforward: bool = False  # A9 option: u = a_CF + ω(v)

    def __post_init__(self) -> None:
        super().__post_init__()
        require(
            "theta_preset",
            isinstance(self.theta_preset, str) and self.theta_preset in _THETA_PRESETS,
            "'train2' or 'train3'",
            self.theta_preset,
        )
        require(
            "cacc_feedforward", self.cacc_feedforward in ("net", "applied"), "'net' or 'applied'", self.cacc_feedforward
        )
        theta = self.theta()
        for k, value in enumerate(theta[:7], start=1):
            low_ok = value > 0.0 if k <= 2 else value >= 0.0
            require(f"theta{k}", math.isfinite(value) and low_ok, "a number > 0" if k <= 2 else "a number >= 0", value)

    def theta(self) -> np.ndarray:
        base = _THETA_PRESETS.get(self.theta_preset, THETA_TRAIN2).as_array()
        over = np.array([getattr(self, f"theta{k}") for k in range(1, 8)] + [np.nan] * 3, dtype=float)
        return np.where(np.isnan(over), base, over)  # θ1 … θ7 and the control offsets (0: the paper's laws)


@dataclass(frozen=True)
class McfParams(CfParams):
    """MCF-DMPC: the sequence optimiser and its budget (Table II: P = 50, K = 100)."""

    optimizer: str = "msmfo"  # msmfo | mfo | ga | pso | sa
    population: int = 50
    iterations: int = 100
    decision_dim: int = 0  # 0: D = Np (A15 default); else D = decision_dim ≤ Np with the last index held
    warm_start: bool = True  # seed with the shifted previous best and the three single-model sequences

    def __post_init__(self) -> None:
        super().__post_init__()
        _int_field(self, "population", 4)
        _int_field(self, "iterations", 1)
        _int_field(self, "decision_dim", 0)
        require(
            "optimizer",
            self.optimizer in ("msmfo", "mfo", "ga", "pso", "sa"),
            "one of msmfo, mfo, ga, pso, sa",
            self.optimizer,
        )
        require(
            "decision_dim", self.decision_dim <= self.horizon_steps, "an integer <= horizon_steps", self.decision_dim
        )


@dataclass(frozen=True)
class OpoMcfParams(McfParams):
    """OPO: compass-search budget and the Θ box (A29 defaults)."""

    opo_iterations: int = 8
    opo_initial_step: float = 0.1
    opo_min_step: float = 1e-3
    theta1_min: float = 0.5
    theta1_max: float = 5.0
    theta2_min: float = 2.0
    theta2_max: float = 40.0
    theta3_min: float = 0.0
    theta3_max: float = 1.0
    theta4_min: float = 1e-3
    theta4_max: float = 0.1
    theta5_min: float = 1e-3
    theta5_max: float = 0.1
    theta6_min: float = 1e-3
    theta6_max: float = 0.1
    theta7_min: float = 0.0
    theta7_max: float = 1e-2
    opo_bias: bool = True  # ours: OPO also corrects each law's control offset within ±bias_max_mps2
    bias_max_mps2: float = 0.2

    def __post_init__(self) -> None:
        super().__post_init__()
        _int_field(self, "opo_iterations", 0)
        for k in range(1, 8):
            lo, hi = getattr(self, f"theta{k}_min"), getattr(self, f"theta{k}_max")
            require(f"theta{k}_max", hi >= lo, f"a number >= theta{k}_min ({lo})", hi)
        require("opo_initial_step", 0.0 < self.opo_initial_step <= 1.0, "a number in (0, 1]", self.opo_initial_step)
        require("opo_bias", isinstance(self.opo_bias, bool), "true or false", self.opo_bias)
        require("bias_max_mps2", 0.0 <= self.bias_max_mps2 <= 1.0, "a number in [0, 1]", self.bias_max_mps2)
        require(
            "opo_min_step",
            0.0 < self.opo_min_step <= self.opo_initial_step,
            "a number in (0, opo_initial_step]",
            self.opo_min_step,
        )

    def opo_settings(self) -> OpoSettings:
        rows = [[getattr(self, f"theta{k}_min"), getattr(self, f"theta{k}_max")] for k in range(1, 8)]
        b = self.bias_max_mps2 if self.opo_bias else 0.0
        bounds = np.array(rows + [[-b, b]] * 3)
        return OpoSettings(self.opo_iterations, self.opo_initial_step, self.opo_min_step, bounds)


@dataclass(frozen=True)
class DmpcParams(CommonParams):
    """DMPC baseline: OSQP tolerances and the SQP (re-linearisation) budget."""

    eps_abs: float = 1e-5
    eps_rel: float = 1e-5
    max_iter: int = 4000
    sqp_iterations: int = 2
    sqp_tol_m: float = 0.1

    def __post_init__(self) -> None:
        super().__post_init__()
        _int_field(self, "max_iter", 1)
        _int_field(self, "sqp_iterations", 1)
        require("eps_abs", self.eps_abs > 0.0, "a number > 0", self.eps_abs)
        require("eps_rel", self.eps_rel >= 0.0, "a number >= 0", self.eps_rel)
        require("sqp_tol_m", self.sqp_tol_m >= 0.0, "a number >= 0", self.sqp_tol_m)


# ------------------------------------------------------------------------------------------------------------------


class _PaperAController:
    """Shared plumbing: prediction model, predecessor horizon, ``u_{−1}``, plan and info."""

    def __init__(self, params: CommonParams, vehicle: VehicleParams) -> None:
        self.params = params
        self.vehicle = vehicle
        self.train = train_params_from_vehicle(vehicle, params.safety_margin_m, params.dt_s)
        self.weights = params.weights()
        self.n_steps = params.horizon_steps
        self.fallbacks = 0
        self._u_prev: float | None = None
        self._plan_used: bool | None = None  # None until a plan was first used (no event for a plan never sent)

    def reset(self) -> None:
        self._u_prev = None
        self.fallbacks = 0
        self._plan_used = None

    def _feedforward(self) -> str:
        return getattr(self.params, "cacc_feedforward", "net")

    def _u_prev_value(self, v0: float) -> float:
        if self._u_prev is not None:
            return self._u_prev
        return float(self.train.resistance_mps2(v0)) if self.params.u_prev_init == "resistance" else 0.0

    def command(self, obs: Observation) -> Command:
        pred = obs.predecessor
        if pred is None:
            # nothing to follow: the traction limit, so the engine's min() leaves the ATO in charge
            return Command(self.train.max_accel_mps2, info={"phase": "free"})
        t0, c0 = time.perf_counter(), time.thread_time()
        p = self.params
        hz = predecessor_horizon(pred, self.n_steps, p.dt_s, self._feedforward(), max_plan_age_s=p.plan_max_age_s)
        x0, v0 = float(obs.own.position_m), max(float(obs.own.speed_mps), 0.0)
        u_prev = self._u_prev_value(v0)
        u0, plan, info, fallback = self._decide(x0, v0, u_prev, hz)
        self._u_prev = u0
        info["plan"] = plan
        info["solve_time_s"] = time.perf_counter() - t0  # wall clock (inflated on a loaded machine)
        info["cpu_time_s"] = time.thread_time() - c0  # this thread's CPU time (numba runs in it too)
        info["predecessor_plan"] = hz.source
        event = self._plan_event(hz.source == "plan")
        if event is not None:
            info["event"] = event
            info["plan_age_s"] = round(float(pred.age_s), 3)
        info.setdefault("phase", "track")
        return Command(u0, fallback=fallback, info=info)

    def _plan_event(self, used: bool) -> str | None:
        """``leader_plan_lost`` / ``leader_plan_restored`` when the use of the predecessor's plan changes."""
        before, self._plan_used = self._plan_used, (used if (used or self._plan_used is not None) else None)
        if before is True and not used:
            return "leader_plan_lost"
        if before is False and used:
            return "leader_plan_restored"
        return None

    def _decide(
        self, x0: float, v0: float, u_prev: float, hz: PredecessorHorizon
    ) -> tuple[float, dict[str, Any], dict[str, Any], bool]:
        raise NotImplementedError


class CfDmpc(_PaperAController):
    """CF-DMPC with one enhanced law (Section IV-A)."""

    def __init__(self, params: CfParams, vehicle: VehicleParams, model: int) -> None:
        super().__init__(params, vehicle)
        self.model = int(model)
        self.theta = params.theta()

    def _decide(self, x0, v0, u_prev, hz):
        p: CfParams = self.params  # type: ignore[assignment]
        seq = np.full((1, self.n_steps), self.model, dtype=np.int64)
        traj = rollout_models(seq, x0, v0, hz, self.theta, self.train, resistance_feedforward=p.resistance_feedforward)
        j = float(dmpc_cost(traj, hz, u_prev, self.train, self.weights)[0])
        info = {"J": j, "model": MODEL_NAMES[self.model], "model_sequence": tuple(int(m) for m in seq[0])}
        return float(traj.u[0, 0]), plan_dict(traj, 0, p.dt_s), info, False


@dataclass(frozen=True)
class _Search:
    """What the controller keeps of a compiled MSMFO call (the fields it reads of an ``OptimResult``)."""

    best: np.ndarray
    best_cost: float
    evaluations: int
    rollouts: int


def _default_optimizer() -> SequenceOptimizer:
    from controllers.mcf_dmpc.optim import minimize_sequence  # imported late: optim imports this package

    return minimize_sequence


class McfDmpc(_PaperAController):
    """MCF-DMPC: the model sequence chosen by an integer optimiser every step."""

    def __init__(
        self,
        params: McfParams,
        vehicle: VehicleParams,
        sequence_optimizer: SequenceOptimizer | None = None,
        compiled: bool = True,
    ) -> None:
        super().__init__(params, vehicle)
        self.theta = params.theta()
        self.optimizer = sequence_optimizer if sequence_optimizer is not None else _default_optimizer()
        # the compiled MSMFO (same draws, same result) unless a custom optimiser or another method is asked for
        self._compiled = compiled and sequence_optimizer is None and params.optimizer == "msmfo" and NUMBA_AVAILABLE
        self._train_vec = train_vector(self.train)
        self._weight_vec = weight_vector(self.weights)
        self.rng = np.random.default_rng(params.seed)
        self.dim = params.decision_dim or params.horizon_steps
        self._best: np.ndarray | None = None

    def reset(self) -> None:
        super().reset()
        self.rng = np.random.default_rng(self.params.seed)
        self._best = None

    def _batch_cost(self, x0, v0, u_prev, hz):
        p: McfParams = self.params  # type: ignore[assignment]

        def cost(seqs: np.ndarray, thetas: np.ndarray) -> np.ndarray:
            full = expand_sequence(seqs, self.n_steps)
            # = dmpc_cost(rollout_models(...)); fused in plain floats for the optimisers' small batches
            return sequence_costs(
                full,
                x0,
                v0,
                hz,
                thetas,
                self.train,
                u_prev,
                self.weights,
                resistance_feedforward=p.resistance_feedforward,
            )

        return cost

    def _select(self, x0, v0, u_prev, hz, theta) -> tuple[np.ndarray, Any]:
        p: McfParams = self.params  # type: ignore[assignment]
        if self._compiled:
            return self._select_compiled(x0, v0, u_prev, hz, theta)
        batch = self._batch_cost(x0, v0, u_prev, hz)

        def fitness(seqs: np.ndarray) -> np.ndarray:
            return batch(np.asarray(seqs), theta)

        init = self._warm_start()
        res = self.optimizer(
            fitness,
            self.dim,
            3,
            method=p.optimizer,
            population=p.population,
            iterations=p.iterations,
            rng=self.rng,
            init=init,
        )
        best = np.asarray(res.best, dtype=np.int64).ravel()
        self._best = best
        return best, res

    def _warm_start(self) -> np.ndarray | None:
        p: McfParams = self.params  # type: ignore[assignment]
        if not p.warm_start:
            return None
        seeds = [np.full(self.dim, m, dtype=np.int64) for m in (MODEL_IDM, MODEL_CACC, MODEL_FVD)]
        if self._best is not None:
            seeds.insert(0, np.append(self._best[1:], self._best[-1]))
        return np.stack(seeds[: p.population])

    def _fitness_args(self, x0, v0, u_prev, hz) -> tuple:
        """The MCF fitness of this step for the compiled searches (everything but Θ and the rows)."""
        p: McfParams = self.params  # type: ignore[assignment]
        return (
            x0,
            v0,
            hz.position_m,
            hz.speed_mps,
            hz.accel_mps2,
            hz.length_m,
            hz.emergency_decel_mps2,
            self._train_vec,
            self._weight_vec,
            u_prev,
            p.resistance_feedforward,
            self.n_steps,
        )

    def _select_compiled(self, x0, v0, u_prev, hz, theta) -> tuple[np.ndarray, Any]:
        """The same search as ``_select`` with the default MSMFO, compiled (:mod:`controllers.mcf_dmpc.msmfo_jit`)."""
        p: McfParams = self.params  # type: ignore[assignment]
        args = (theta, *self._fitness_args(x0, v0, u_prev, hz))
        best, cost, evaluations, rollouts = msmfo_mcf(
            args, self.dim, 3, population=p.population, iterations=p.iterations, rng=self.rng, init=self._warm_start()
        )
        self._best = best
        return best, _Search(best, cost, evaluations, rollouts)

    def _finish(self, x0, v0, u_prev, hz, theta, best, res, extra: dict[str, Any]):
        p: McfParams = self.params  # type: ignore[assignment]
        full = expand_sequence(best[None, :], self.n_steps)
        traj = rollout_models(full, x0, v0, hz, theta, self.train, resistance_feedforward=p.resistance_feedforward)
        j = float(dmpc_cost(traj, hz, u_prev, self.train, self.weights)[0])
        info = {
            "J": j,
            "model_sequence": tuple(int(m) for m in full[0]),
            "model_counts": tuple(int(np.sum(full[0] == m)) for m in range(3)),
            "evaluations": int(getattr(res, "evaluations", 0)),
            "rollouts": int(getattr(res, "rollouts", getattr(res, "evaluations", 0))),  # compiled: repeats looked up
            **extra,
        }
        return float(traj.u[0, 0]), plan_dict(traj, 0, p.dt_s), info, False

    def _decide(self, x0, v0, u_prev, hz):
        best, res = self._select(x0, v0, u_prev, hz, self.theta)
        return self._finish(x0, v0, u_prev, hz, self.theta, best, res, {})


class OpoMcfDmpc(McfDmpc):
    """OPO-MCF-DMPC: Θ re-tuned by OPO, then the MCF sequence search with the new Θ."""

    def __init__(
        self,
        params: OpoMcfParams,
        vehicle: VehicleParams,
        sequence_optimizer: SequenceOptimizer | None = None,
        compiled: bool = True,
    ) -> None:
        super().__init__(params, vehicle, sequence_optimizer, compiled)
        self.opo_settings = params.opo_settings()
        lo, hi = self.opo_settings.bounds.T
        self.theta = np.clip(params.theta(), lo, hi)  # the warm start must lie in the box too

    def reset(self) -> None:
        super().reset()
        lo, hi = self.opo_settings.bounds.T
        self.theta = np.clip(self.params.theta(), lo, hi)  # type: ignore[attr-defined]

    def _decide(self, x0, v0, u_prev, hz):
        t0 = time.perf_counter()
        if self._compiled:  # the same compass search in one compiled call (same Θ, tested)
            opo = opo_step_compiled(self.theta, self._fitness_args(x0, v0, u_prev, hz), self.opo_settings)
        else:
            batch = self._batch_cost(x0, v0, u_prev, hz)
            opo = opo_step(self.theta, lambda seqs, thetas: batch(seqs, thetas), self.n_steps, self.opo_settings)
        self.theta = opo.theta
        opo_time = time.perf_counter() - t0
        best, res = self._select(x0, v0, u_prev, hz, self.theta)
        return self._finish(
            x0,
            v0,
            u_prev,
            hz,
            self.theta,
            best,
            res,
            {"theta": tuple(float(x) for x in self.theta), "opo_time_s": opo_time, "opo_evaluations": opo.evaluations},
        )


class DmpcController(_PaperAController):
    """The continuous-u DMPC baseline (OSQP, warm-started, safe brake on failure)."""

    def __init__(self, params: DmpcParams, vehicle: VehicleParams) -> None:
        super().__init__(params, vehicle)
        self.qp = DmpcQp(
            self.n_steps,
            self.train,
            self.weights,
            eps_abs=params.eps_abs,
            eps_rel=params.eps_rel,
            max_iter=params.max_iter,
            sqp_iterations=params.sqp_iterations,
            sqp_tol_m=params.sqp_tol_m,
        )
        self._u_plan: np.ndarray | None = None

    def reset(self) -> None:
        super().reset()
        self.qp.reset()
        self._u_plan = None

    def _decide(self, x0, v0, u_prev, hz):
        nominal = shift_controls(self._u_plan) if self._u_plan is not None else None
        sol = self.qp.solve(x0, v0, u_prev, hz, nominal)
        info: dict[str, Any] = {
            "status": sol.status,
            "sqp_iterations": sol.sqp_iterations,
            "admm_iterations": sol.admm_iterations,
            "qp_time_s": sol.solve_time_s,
        }
        if not sol.ok:
            self.fallbacks += 1
            self._u_plan = None  # the next solve starts from cruise, not from a failed plan
            brake = np.full((1, self.n_steps), -self.train.service_decel_mps2)
            info.update(
                phase="fallback",
                fallbacks=self.fallbacks,
                J=math.nan,
                fallback_reason=f"SQP not solved ({sol.status}); service brake",
            )
            return (
                -self.train.service_decel_mps2,
                plan_dict(rollout_controls(brake, x0, v0, self.train), 0, self.params.dt_s),
                info,
                True,
            )
        self._u_plan = sol.u
        info.update(J=sol.J, safety_margin_m=sol.safety_margin_m, fallbacks=self.fallbacks)
        return float(sol.u[0]), plan_dict(sol.trajectory, 0, self.params.dt_s), info, False


# ------------------------------------------------------------------------------------------------------------------
# Registration (factories raise ValueError("<param>: ...") via params_from_mapping / require)


def _cf_factory(model: int) -> Callable[[Mapping[str, Any], VehicleParams], CfDmpc]:
    def make(params: Mapping[str, Any], vehicle: VehicleParams) -> CfDmpc:
        return CfDmpc(params_from_mapping(CfParams, params), vehicle, model)

    make.__doc__ = f"Factory: CF-DMPC with the enhanced {MODEL_NAMES[model].upper()} (spec 000 Section IV-A)."
    return make


make_cf_idm = register("cf_idm")(_cf_factory(MODEL_IDM))
make_cf_cacc = register("cf_cacc")(_cf_factory(MODEL_CACC))
make_cf_fvd = register("cf_fvd")(_cf_factory(MODEL_FVD))


@register("mcf_dmpc")
def make_mcf_dmpc(params: Mapping[str, Any], vehicle: VehicleParams) -> McfDmpc:
    """Factory: MCF-DMPC (sequence optimiser from :mod:`controllers.mcf_dmpc.optim`)."""
    return McfDmpc(params_from_mapping(McfParams, params), vehicle)


@register("opo_mcf_dmpc")
def make_opo_mcf_dmpc(params: Mapping[str, Any], vehicle: VehicleParams) -> OpoMcfDmpc:
    """Factory: OPO-MCF-DMPC."""
    return OpoMcfDmpc(params_from_mapping(OpoMcfParams, params), vehicle)


@register("dmpc")
def make_dmpc(params: Mapping[str, Any], vehicle: VehicleParams) -> DmpcController:
    """Factory: DMPC baseline (OSQP)."""
    return DmpcController(params_from_mapping(DmpcParams, params), vehicle)


PARAMS_BY_NAME = {
    "cf_idm": CfParams,
    "cf_cacc": CfParams,
    "cf_fvd": CfParams,
    "mcf_dmpc": McfParams,
    "opo_mcf_dmpc": OpoMcfParams,
    "dmpc": DmpcParams,
}
