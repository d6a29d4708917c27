"""Optimiser benchmark of Paper A (spec 000 §4 S-B′, Fig. 6–7): MSMFO vs MFO, GA, PSO, SA at equal budget.

Problem: the first prediction horizon of train 2 at t = 0 of scenario S-A — own state 1500 m at 200 km/h, the
leader 2000 m ahead-frame at a constant 220 km/h (u = ω, so a constant-speed plan), Θ_2, Np = 60, D = Np model
indices (A15), J^(DMPC) of Eq. (14)–(19) with the A21 penalty, u_{−1} = 0 (A19). It uses the colleague's
``controllers.mcf_dmpc.rollout``/``cost`` when importable, otherwise a compact stand-in of the same equations.

Protocol (A31 SUGGESTION): P = 50, K = 100 for the population methods, every method capped at the same budget
of P·K = 5,000 fitness evaluations (SA: a 5,000-step chain), ``--seeds`` independent runs (default 30) with
seeds 0…n−1. Prints one JSON object: per method the mean/SD of the best J, the mean/SD wall time, the mean
evaluations, the mean normalised best-so-far curve on the evaluations axis (every 5 % of the budget;
100·J/J_ref, J_ref = the worst best-of-the-first-50-evaluations over all runs), and MSMFO's improvement ratios ``(x_other − x_msmfo)/x_other`` for best J and for wall time.

    .venv/bin/python benchmarks/optimizers_000.py [--seeds 30] [--budget 5000]
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from controllers.mcf_dmpc.optim import METHODS, minimize_sequence  # noqa: E402

NP = 60
OWN_POSITION_M, OWN_SPEED_MPS = 1500.0, 200.0 / 3.6
LEADER_POSITION_M, LEADER_SPEED_MPS = 2000.0, 220.0 / 3.6


def _colleague_fitness() -> Callable[[np.ndarray], np.ndarray]:
    from controllers.mcf_dmpc.cf_models import THETA_TRAIN2
    from controllers.mcf_dmpc.cost import dmpc_cost
    from controllers.mcf_dmpc.rollout import constant_speed_horizon, rollout_models
    from controllers.mcf_dmpc.spacing import TABLE_I

    pred = constant_speed_horizon(
        LEADER_POSITION_M, LEADER_SPEED_MPS, NP, TABLE_I.dt_s, TABLE_I.length_m, TABLE_I.emergency_decel_mps2
    )
    theta = THETA_TRAIN2.as_array()

    def fitness(seq: np.ndarray) -> np.ndarray:
        traj = rollout_models(seq, OWN_POSITION_M, OWN_SPEED_MPS, pred, theta, TABLE_I)
        return dmpc_cost(traj, pred, 0.0, TABLE_I)

    return fitness


def _standin_fitness() -> Callable[[np.ndarray], np.ndarray]:
    """The same problem written out from spec §2.4–2.5 (Table I/II, Θ_2), for when the rollout is absent."""
    l_s, l_t, b_c, b_m, a_m, v_m = 1.5 * 350 / 3.6, 203.0, 0.8, 1.0, 1.0, 350 / 3.6
    th = (1.2, 12.1, 0.0, 0.011, 0.013, 0.012, 4.2e-4)
    t = np.arange(NP + 1)
    sp, vp = LEADER_POSITION_M + LEADER_SPEED_MPS * t, np.full(NP + 1, LEADER_SPEED_MPS)

    def omega(v):
        return 1.18e-2 + 7.76e-4 * v + 1e-5 * v * v

    def d_e(v, vq):
        return l_s + l_t + v * v / (2 * b_c) - vq * vq / (2 * b_m)

    def fitness(seq: np.ndarray) -> np.ndarray:
        p = seq.shape[0]
        s, v = np.full(p, OWN_POSITION_M), np.full(p, OWN_SPEED_MPS)
        us, vs, es, viol = [], [], [], np.zeros(p)
        for j in range(NP):
            gap, de = sp[j] - s, d_e(v, vp[j])
            idm = a_m * (2 - (v / vp[j]) ** th[0] - np.minimum(de / np.maximum(gap, 1e-3), 1e3) ** th[1])
            cacc = th[3] * (gap - de) + th[4] * (vp[j] - v)
            fvd = th[5] * (vp[j] * (vp[j] + gap - de) / np.maximum(v, 0.1) - v) + np.where(gap <= de, th[6], 0) * (
                vp[j] - v
            )
            u = np.clip(np.choose(seq[:, j], (idm, cacc, fvd)), -b_c, a_m)
            a = u - omega(v)
            s, v = s + v + 0.5 * a, v + a
            gap, de = sp[j + 1] - s, d_e(v, vp[j + 1])
            ds = l_s + l_t + v * v / (2 * b_m) - vp[j + 1] ** 2 / (2 * b_m)
            viol += np.maximum(ds - gap, 0) + np.maximum(-v, 0) + np.maximum(v - v_m, 0)
            us.append(u), vs.append(v - vp[j + 1]), es.append(gap - de)
        u, dv, e = np.array(us).T, np.array(vs).T, np.array(es).T
        du = np.diff(u, axis=1)
        return (
            (dv**2).sum(1)
            + 0.05 * (e**2).sum(1)
            + 200 * (u**2).sum(1)
            + 400 * ((du**2).sum(1) + u[:, 0] ** 2)
            + 10 * (dv[:, -1] ** 2 + 0.05 * e[:, -1] ** 2)
            + 1e6 * viol
        )

    return fitness


class _Trace:
    """Wraps the fitness to record the best cost after every evaluated row (the evaluations axis of Fig. 6)."""

    def __init__(self, fitness: Callable[[np.ndarray], np.ndarray]) -> None:
        self.fitness = fitness
        self.running: list[np.ndarray] = []
        self.best = np.inf

    def __call__(self, seq: np.ndarray) -> np.ndarray:
        costs = self.fitness(seq)
        run = np.minimum.accumulate(np.concatenate([[self.best], costs]))[1:]
        self.best = float(run[-1])
        self.running.append(run)
        return costs

    def best_at(self, evaluations: np.ndarray) -> np.ndarray:
        """Best-so-far after the first 50 evaluations (entry 0) and at each of ``evaluations``."""
        run = np.concatenate(self.running)
        idx = np.minimum(np.concatenate([[50], evaluations]) - 1, len(run) - 1)
        return run[idx]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=30)
    parser.add_argument("--budget", type=int, default=5000)
    args = parser.parse_args()
    try:
        fitness, source = _colleague_fitness(), "controllers.mcf_dmpc.rollout+cost"
    except ImportError:
        fitness, source = _standin_fitness(), "stand-in (spec §2.4–2.5)"

    # Single-model references (m ≡ const) — the CF-DMPC costs MCF should beat.
    single = fitness(np.repeat(np.arange(3)[:, None], NP, axis=1))
    checkpoints = np.linspace(0, args.budget, 21)[1:].astype(int)  # best-so-far every 5 % of the budget
    runs: dict[str, list] = {m: [] for m in METHODS}
    curves: dict[str, list] = {m: [] for m in METHODS}
    for seed in range(args.seeds):
        for method in METHODS:
            trace = _Trace(fitness)
            res = minimize_sequence(
                trace,
                NP,
                3,
                method=method,
                population=50,
                iterations=100,
                rng=np.random.default_rng(seed),
                options={"budget": args.budget},
            )
            runs[method].append(res)
            curves[method].append(trace.best_at(checkpoints))

    # A31: normalise by the worst initial best (best of the first 50 evaluations) over all runs.
    j_ref = max(float(trace_curve[0]) for cs in curves.values() for trace_curve in cs)
    out: dict[str, object] = {
        "benchmark": "optimizers_000",
        "problem": "Paper A S-B' (train 2, t = 0, Np = 60, D = 60, 3 models)",
        "fitness_source": source,
        "python": platform.python_version(),
        "seeds": args.seeds,
        "budget": args.budget,
        "population": 50,
        "iterations": 100,
        "single_model_J": {"idm": float(single[0]), "cacc": float(single[1]), "fvd": float(single[2])},
        "methods": {},
    }
    for method, rs in runs.items():
        best = np.array([r.best_cost for r in rs])
        wall = np.array([r.wall_s for r in rs])
        curve = np.mean([100.0 * c[1:] / j_ref for c in curves[method]], axis=0)
        out["methods"][method] = {
            "best_J_mean": float(best.mean()),
            "best_J_std": float(best.std(ddof=1)) if len(rs) > 1 else 0.0,
            "best_J_min": float(best.min()),
            "wall_s_mean": float(wall.mean()),
            "wall_s_std": float(wall.std(ddof=1)) if len(rs) > 1 else 0.0,
            "evaluations_mean": float(np.mean([r.evaluations for r in rs])),
            "normalised_best_every_5pct_budget": [round(float(x), 3) for x in curve],
        }
    ms = out["methods"]["msmfo"]
    out["msmfo_improvement"] = {
        m: {
            "best_J": (v["best_J_mean"] - ms["best_J_mean"]) / v["best_J_mean"],
            "wall_s": (v["wall_s_mean"] - ms["wall_s_mean"]) / v["wall_s_mean"],
        }
        for m, v in out["methods"].items()
        if m != "msmfo"
    }
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
