"""Solve-time benchmark of Paper A's controllers (spec 000 §7 "Wall-clock solve time per step", Fig. 11, A39).

For each registered controller (``cf_idm``, ``cf_cacc``, ``cf_fvd``, ``dmpc``, ``mcf_dmpc``, ``opo_mcf_dmpc``) it
runs the S-A…S-D platoon (leader 2000 m at 220 km/h, followers at 1500 m / 200 km/h and 0 m / 180 km/h, Θ_2 and
Θ_3, Np = 60, τ = 1 s, noise SD 0.01 m/s²) in the pure-numpy closed loop :func:`controllers.mcf_dmpc.sim.run_platoon`
and collects each follower's ``info["solve_time_s"]`` (the wall time of ``command()``: predecessor horizon,
optimisation, final rollout). The first ``--steps`` steps are the transient (largest errors, hardest problems);
the MCF variants get ``--mcf-steps`` steps because each solve is ~10³× a CF law. The first train-step (numba JIT
compilation or cache load of :mod:`controllers.mcf_dmpc.kernels`) is reported apart as ``first_step_s``;
``--mcf-iterations`` lowers MSMFO's K (Table II: 100) to show what budget a time target buys.

Reported per controller: median, p95 and mean solve time per train-step — wall clock (``info["solve_time_s"]``,
inflated when other processes share the cores) and the controller thread's CPU time (``info["cpu_time_s"]``) —
the number of train-steps, and the ratio to the paper's MATLAB figures (0.439 s per solve for fmincon DMPC,
0.282 s for OPO-MCF-DMPC; A39: compare ratios, not seconds), plus ``paper_speedup_check``: our
(t_DMPC − t_OPO)/t_DMPC next to the paper's 35.8 %. Targets (not tests): DMPC ≤ 1 ms, OPO-MCF-DMPC ≤ 20 ms per
train-step (``meets_target`` on the median wall time, ``meets_target_cpu`` on the median CPU time).

Baseline in the same run: the MCF variants are also timed on their Python optimiser path (the same
search, :func:`controllers.mcf_dmpc.optim.minimize_sequence` over the numba fitness — what every step cost before
the compiled MSMFO of :mod:`controllers.mcf_dmpc.msmfo_jit`), ``baseline_python`` with ``speedup_cpu`` /
``speedup_wall`` = baseline median / compiled median. ``--budget-sweep K1 K2 …`` times OPO-MCF-DMPC at lower
MSMFO iteration counts (Table II: K = 100) to show what budget a time target buys. ``--repeats R`` runs each MCF
timing (and its baseline) R times after a warm-up run: ``repeats`` lists each repetition's medians and its whole-
process CPU time (``time.process_time``, all threads, plant and leader included) per train-step, and
``repeat_median_*`` the medians over the repetitions (``speedup_process_cpu`` against the baseline's); the load
average at the start and the end says how much the cores were shared.

    .venv/bin/python benchmarks/controllers_000.py [--steps 60] [--mcf-steps 8] [--optimizer-seeds 5]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import controllers  # noqa: E402  (registers the Paper A controllers)
from controllers.mcf_dmpc.sim import run_platoon  # noqa: E402
from controllers.mcf_dmpc.spacing import paper000_vehicle  # noqa: E402

PAPER_S = {"dmpc": 0.439, "opo_mcf_dmpc": 0.282}
TARGET_S = {"dmpc": 1e-3, "opo_mcf_dmpc": 20e-3}
CONTROLLERS = ("cf_idm", "cf_cacc", "cf_fvd", "dmpc", "mcf_dmpc", "opo_mcf_dmpc")
X0_M, V0_MPS = (2000.0, 1500.0, 0.0), (220 / 3.6, 200 / 3.6, 180 / 3.6)


def _followers(name: str, mcf_iterations: int = 100, compiled: bool = True) -> list[Any]:
    veh = paper000_vehicle()
    if name == "dmpc":
        return [controllers.create(name, {}, veh), controllers.create(name, {}, veh)]
    extra = {"iterations": mcf_iterations} if "mcf" in name else {}
    out = [controllers.create(name, {"theta_preset": preset, **extra}, veh) for preset in ("train2", "train3")]
    for f in out:
        if not compiled and hasattr(f, "_compiled"):
            f._compiled = False  # the Python optimiser path: the same search, uncompiled
    return out


def _stats(values: np.ndarray, prefix: str) -> dict[str, float]:
    return {
        f"{prefix}median_s": float(np.median(values)),
        f"{prefix}p95_s": float(np.percentile(values, 95)),
        f"{prefix}mean_s": float(np.mean(values)),
    }


def time_controller(
    name: str, steps: int, seed: int = 0, mcf_iterations: int = 100, compiled: bool = True, repeats: int = 1
) -> dict[str, Any]:
    runs, process_cpu, process_wall = [], [], []
    if repeats > 1:  # warm-up: numba's cache load (or compilation) outside the timed repetitions
        run_platoon(_followers(name, mcf_iterations, compiled), X0_M, V0_MPS, 2, noise_sd_mps2=0.01, seed=seed)
    for _ in range(repeats):
        c0, t0 = time.process_time(), time.perf_counter()
        runs.append(
            run_platoon(_followers(name, mcf_iterations, compiled), X0_M, V0_MPS, steps, noise_sd_mps2=0.01, seed=seed)
        )
        # the whole process (all threads: numpy/BLAS helpers too) per train-step, plant and leader included
        process_cpu.append((time.process_time() - c0) / (steps * (len(X0_M) - 1)))
        process_wall.append((time.perf_counter() - t0) / (steps * (len(X0_M) - 1)))
    run = runs[0]
    # The first train-step of each follower includes numba's JIT compilation (or its on-disk cache load):
    # report it apart from the steady-state figures.
    first = run.solve_time_s[0, 1:]
    k0 = 1 if steps > 1 else 0
    wall = np.concatenate([r.solve_time_s[k0:, 1:].ravel() for r in runs])
    wall = wall[np.isfinite(wall)]
    cpu = np.array(
        [info.get("cpu_time_s", np.nan) for r in runs for step in r.infos[k0:] for info in step[1:]], dtype=float
    )
    cpu = cpu[np.isfinite(cpu)]
    row: dict[str, Any] = {"train_steps": int(wall.size), **_stats(wall, "")}
    if cpu.size:
        row.update(_stats(cpu, "cpu_"))
    if repeats > 1:
        per_rep = [
            {
                "median_s": float(np.median(r.solve_time_s[k0:, 1:])),
                "cpu_median_s": float(np.median([i["cpu_time_s"] for st in r.infos[k0:] for i in st[1:]])),
                "process_cpu_per_step_s": pc,
                "process_wall_per_step_s": pw,
            }
            for r, pc, pw in zip(runs, process_cpu, process_wall)
        ]
        row["repeats"] = per_rep
        for key in ("median_s", "cpu_median_s", "process_cpu_per_step_s", "process_wall_per_step_s"):
            row[f"repeat_median_{key}"] = float(np.median([rep[key] for rep in per_rep]))
    row["first_step_s"] = float(np.nanmax(first))
    row["fallbacks"] = int(run.fallback[:, 1:].sum())
    if "mcf" in name:
        row["msmfo_iterations"] = mcf_iterations
        row["evaluations_per_step"] = float(np.mean([i["evaluations"] for step in run.infos for i in step[1:]]))
        row["rollouts_per_step"] = float(np.mean([i["rollouts"] for step in run.infos for i in step[1:]]))
    if name in PAPER_S:
        row["paper_s"] = PAPER_S[name]
        row["ratio_to_paper"] = row["mean_s"] / PAPER_S[name]
        row["target_s"] = TARGET_S[name]
        row["meets_target"] = bool(row["median_s"] <= TARGET_S[name])
        if cpu.size:
            row["meets_target_cpu"] = bool(row["cpu_median_s"] <= TARGET_S[name])
    return row


def optimizer_comparison(seeds: int, budget: int = 5000) -> dict[str, Any]:
    """MSMFO vs the baselines on S-B′ at an equal budget (the problem and trace of optimizers_000.py)."""
    try:
        import benchmarks.optimizers_000 as ob  # noqa: PLC0415
        from controllers.mcf_dmpc.optim import METHODS, minimize_sequence  # noqa: PLC0415
    except ImportError as exc:  # the optimiser package or the other benchmark is not there yet
        return {"skipped": f"not importable: {exc}"}
    fitness = ob._colleague_fitness()
    out: dict[str, Any] = {"budget": budget, "seeds": seeds, "methods": {}}
    for method in METHODS:
        best, wall = [], []
        for seed in range(seeds):
            res = minimize_sequence(
                fitness,
                ob.NP,
                3,
                method=method,
                population=50,
                iterations=100,
                rng=np.random.default_rng(seed),
                options={"budget": budget},
            )
            best.append(res.best_cost)
            wall.append(res.wall_s)
        out["methods"][method] = {
            "best_J_mean": float(np.mean(best)),
            "best_J_min": float(np.min(best)),
            "wall_s_mean": float(np.mean(wall)),
        }
    ms = out["methods"].get("msmfo")
    if ms is not None:
        out["msmfo_improvement"] = {
            m: {
                "best_J": (v["best_J_mean"] - ms["best_J_mean"]) / v["best_J_mean"],
                "wall_s": (v["wall_s_mean"] - ms["wall_s_mean"]) / v["wall_s_mean"],
            }
            for m, v in out["methods"].items()
            if m != "msmfo"
        }
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=60, help="closed-loop steps for CF and DMPC")
    parser.add_argument("--mcf-steps", type=int, default=8, help="closed-loop steps for the MCF variants")
    parser.add_argument("--optimizer-seeds", type=int, default=5, help="0 skips the optimiser comparison")
    parser.add_argument(
        "--mcf-iterations",
        type=int,
        default=100,
        help="MSMFO iterations K (Table II: 100); lower to see what budget a time target buys",
    )
    parser.add_argument("--only", nargs="*", default=list(CONTROLLERS), choices=CONTROLLERS)
    parser.add_argument("--baseline-steps", type=int, default=3, help="steps of the Python-path baseline (0: skip)")
    parser.add_argument("--budget-sweep", type=int, nargs="*", default=[], help="also time OPO at these K")
    parser.add_argument("--repeats", type=int, default=1, help="timed repetitions of each MCF run (medians over them)")
    args = parser.parse_args()
    out: dict[str, Any] = {
        "benchmark": "controllers_000",
        "python": platform.python_version(),
        "numpy": np.__version__,
        "horizon_steps": 60,
        "load_average": list(os.getloadavg()),  # other processes share the cores: CPU figures, not wall
        "controllers": {},
    }
    for name in args.only:
        steps = args.mcf_steps if "mcf" in name else args.steps
        repeats = args.repeats if "mcf" in name else 1
        row = time_controller(name, steps, mcf_iterations=args.mcf_iterations, repeats=repeats)
        if "mcf" in name and args.baseline_steps > 0:
            base = time_controller(
                name, args.baseline_steps + 1, mcf_iterations=args.mcf_iterations, compiled=False, repeats=repeats
            )
            keys = ("train_steps", "median_s", "cpu_median_s", "repeat_median_process_cpu_per_step_s")
            row["baseline_python"] = {k: base[k] for k in keys if k in base}
            row["speedup_wall"] = base["median_s"] / row["median_s"]
            row["speedup_cpu"] = base["cpu_median_s"] / row["cpu_median_s"]
            if repeats > 1:
                key = "repeat_median_process_cpu_per_step_s"
                row["speedup_process_cpu"] = base[key] / row[key]
        out["controllers"][name] = row
    if args.budget_sweep:
        out["opo_budget_sweep"] = {
            str(k): {
                key: v
                for key, v in time_controller("opo_mcf_dmpc", args.mcf_steps, mcf_iterations=k).items()
                if key in ("median_s", "cpu_median_s", "evaluations_per_step", "meets_target", "meets_target_cpu")
            }
            for k in args.budget_sweep
        }
    c = out["controllers"]
    if "dmpc" in c and "opo_mcf_dmpc" in c:
        ours = (c["dmpc"]["mean_s"] - c["opo_mcf_dmpc"]["mean_s"]) / c["dmpc"]["mean_s"]
        out["paper_speedup_check"] = {"paper": (0.439 - 0.282) / 0.439, "ours": ours}
    if args.optimizer_seeds > 0:
        out["optimizers"] = optimizer_comparison(args.optimizer_seeds)
    out["load_average_end"] = list(os.getloadavg())
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
