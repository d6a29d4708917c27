"""Paper B baselines under one actuator envelope (spec 001 §2.10, Table 1): per controller and scenario
the force / force-rate violation counts and the paper's metrics E_d (= E_x), E_p, E_v, E_u from the numpy runner
:func:`controllers.ato_mpc.sim.run`. E_p is the controller's own stopping error: |stop − x_1| at the first
standstill near the mark, i.e. where the law itself brought the train to rest, before the hold supervisor of
:class:`~controllers.ato_mpc.core.AtoDriver` takes over. JSON on stdout.

    .venv/bin/python benchmarks/paper001_limits_study.py [--controllers sempc mpc afsmc pid] [--jobs 2]
"""

from __future__ import annotations

import argparse
import json
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from controllers.ato_mpc.sim import run, scenario_a, scenario_b, scenario_c  # noqa: E402

SCENARIOS = {
    "A": scenario_a,
    "B": scenario_b,
    "C-constant": lambda: scenario_c("constant"),
    "C-harmonic": lambda: scenario_c("harmonic"),
}
KEYS = (
    "e_x_m",
    "e_p_m",
    "e_v_mps",
    "e_u_1e12",
    "rate_violations",
    "force_violations",
    "max_force_rate_n_per_s",
    "fallbacks",
    "stop_errors_m",
)


def _job(args: tuple[str, str]) -> tuple[tuple[str, str], dict[str, Any]]:
    scenario, controller = args
    r = run(SCENARIOS[scenario](), controller)
    return args, {k: r.metrics[k] for k in KEYS}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--controllers", nargs="*", default=["sempc", "mpc", "afsmc", "pid"])
    ap.add_argument("--scenarios", nargs="*", default=list(SCENARIOS))
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args()
    jobs = [(s, c) for s in args.scenarios for c in args.controllers]
    with ProcessPoolExecutor(args.jobs) as pool:
        res = dict(pool.map(_job, jobs))
    out = {s: {c: res[(s, c)] for c in args.controllers} for s in args.scenarios}
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
