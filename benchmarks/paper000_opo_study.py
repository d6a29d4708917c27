"""Late-phase spacing tracking of MCF-DMPC vs OPO-MCF-DMPC on the numpy runner (spec 000 S-D, S-E).

For each setting and seed it runs :func:`controllers.mcf_dmpc.sim.run_platoon` with both controllers and reports
per follower the late-phase mean |ΔS − D^(e)| and |Δv| (A7: S-D late phase [300, 500) s; S-E: the last 40 % of
its 380 s cycle, [228, 380) s) as mean ± sd over seeds, plus the whole-run means. JSON on stdout.

    .venv/bin/python benchmarks/paper000_opo_study.py [--seeds 5] [--iterations 100] [--jobs 2]
"""

from __future__ import annotations

import argparse
import json
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import controllers  # noqa: E402
from controllers.mcf_dmpc.metrics import follower_metrics  # noqa: E402
from controllers.mcf_dmpc.sim import KMH, S_E_SEGMENTS, paper000_leader, run_platoon  # noqa: E402
from controllers.mcf_dmpc.spacing import desired_spacing_m, paper000_vehicle  # noqa: E402

METHODS = ("mcf_dmpc", "opo_mcf_dmpc")
SETTINGS = {
    "S-D": {
        "presets": ("train2", "train3"),
        "x0": (2000.0, 1500.0, 0.0),
        "v0": (220 * KMH, 200 * KMH, 180 * KMH),
        "steps": 500,
        "late": (300.0, 500.0),
    },
    "S-E": {"presets": ("train2",), "steps": 380, "late": (228.0, 380.0)},
}


def run_case(
    setting: str, method: str, seed: int, iterations: int, extra: dict[str, Any] | None = None, steps: int | None = None
) -> list[dict[str, float]]:
    cfg = SETTINGS[setting]
    veh = paper000_vehicle()
    params = {"iterations": iterations, "seed": seed, **(extra or {})}
    followers = [controllers.create(method, {"theta_preset": p, **params}, veh) for p in cfg["presets"]]
    n = steps or cfg["steps"]
    if setting == "S-E":
        d0 = float(desired_spacing_m(220 * KMH, 220 * KMH))
        run = run_platoon(
            followers,
            (d0, 0.0),
            (220 * KMH, 220 * KMH),
            n,
            seed=seed,
            leader=paper000_leader(220.0, S_E_SEGMENTS),
        )
    else:
        run = run_platoon(followers, cfg["x0"], cfg["v0"], n, seed=seed)
    lo, hi = cfg["late"]
    return [
        {
            "train": m.train,
            "late_abs_e_m": m.late_mean_abs_spacing_error_m,
            "late_abs_dv_mps": m.late_mean_abs_dv_mps,
            "abs_e_m": m.mean_abs_spacing_error_m,
            "min_safety_margin_m": m.min_safety_margin_m,
        }
        for m in follower_metrics(run, lo, hi)
    ]


def _job(args: tuple) -> tuple:
    setting, method, seed, iterations = args
    return args, run_case(setting, method, seed, iterations)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--iterations", type=int, default=100, help="MSMFO K (Table II: 100)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--settings", nargs="*", default=list(SETTINGS))
    args = ap.parse_args()
    jobs = [(s, m, seed, args.iterations) for s in args.settings for m in METHODS for seed in range(args.seeds)]
    with ProcessPoolExecutor(args.jobs) as pool:
        results = list(pool.map(_job, jobs))
    out: dict[str, Any] = {"seeds": args.seeds, "msmfo_iterations": args.iterations, "settings": {}}
    for s in args.settings:
        table: dict[str, Any] = {}
        for m in METHODS:
            rows = [r for (st, mm, _, _), r in results if st == s and mm == m]
            per_train = {}
            for k, tr in enumerate(rows[0]):
                vals = {key: np.array([r[k][key] for r in rows]) for key in tr if key != "train"}
                per_train[f"train{tr['train']}"] = {
                    key: {"mean": float(v.mean()), "sd": float(v.std(ddof=1)) if v.size > 1 else 0.0}
                    for key, v in vals.items()
                }
            table[m] = per_train
        out["settings"][s] = table
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
