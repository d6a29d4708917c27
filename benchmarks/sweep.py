"""Sweep throughput: cases per minute with 1 and 2 local workers on the same case set, and the speed-up.

Runs scenarios/sweeps/corridor_headway.yaml (8 cases of the small corridor, ~1-3 s each) twice into fresh temporary
folders, first with one worker then with two, through the public API (:func:`railsim.studies.sweep.run_sweep`), and prints
JSON. Each case is a fresh child Python process, so the numbers include interpreter start-up and scenario loading,
as a user's sweep does. The speed-up is bounded by the free cores (2 on the reference machine) and by start-up
overhead that does not parallelise (validation of every case before the first run)::

    .venv/bin/python benchmarks/sweep.py [--sweep FILE] [--repeat N]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from railsim.studies import sweep  # noqa: E402

DEFAULT_SWEEP = ROOT / "scenarios" / "sweeps" / "corridor_headway.yaml"


def measure(sweep_file: Path, workers: int) -> dict[str, float]:
    """Wall time of one complete sweep (validation included) with ``workers`` local workers."""
    with tempfile.TemporaryDirectory(prefix="railsim_bench_sweep_") as tmp:
        t0 = time.perf_counter()
        result = sweep.run_sweep(sweep_file, Path(tmp) / "out", workers=workers, progress=False)
        wall = time.perf_counter() - t0
    if result.n_ok != result.n_cases:
        raise SystemExit(f"benchmark sweep had {result.n_failed} failed cases")
    return {"wall_s": round(wall, 3), "cases": result.n_cases, "cases_per_min": round(result.n_cases / wall * 60, 2)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweep", type=Path, default=DEFAULT_SWEEP, help="sweep file (default: corridor_headway)")
    parser.add_argument("--repeat", type=int, default=1, help="measure each worker count N times, keep the best")
    args = parser.parse_args()
    runs = {}
    for workers in (1, 2):
        best = min((measure(args.sweep, workers) for _ in range(args.repeat)), key=lambda m: m["wall_s"])
        runs[f"workers_{workers}"] = best
    print(
        json.dumps(
            {
                "benchmark": "sweep_throughput",
                "sweep": str(args.sweep.relative_to(ROOT) if args.sweep.is_relative_to(ROOT) else args.sweep),
                "cores": os.cpu_count(),
                "load_avg_1min": round(os.getloadavg()[0], 2),
                **runs,
                "speedup_2_vs_1": round(runs["workers_1"]["wall_s"] / runs["workers_2"]["wall_s"], 2),
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
