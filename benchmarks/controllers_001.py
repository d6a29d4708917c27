"""Paper B benchmark: SEMPC and MPC QP solve time per control step at the paper's horizon (N = 3, 6 carriages).

Runs Scenario A (single section, default 5 km) in closed loop on the multi-point plant for each controller and
prints one JSON object: per controller the median / p95 / max solve time per step [ms] (model update + QP set-up
+ OSQP solve, as measured inside the controller), the control period, the share of the period used at p95, the
QP size and the number of fallbacks.

    .venv/bin/python benchmarks/controllers_001.py [LENGTH_M]
"""

from __future__ import annotations

import json
import platform
import sys
import time

import numpy as np

from controllers.ato_mpc.sim import run, scenario_a


def main() -> None:
    length_m = float(sys.argv[1]) if len(sys.argv) > 1 else 5000.0
    sc = scenario_a(length_m)
    out: dict = {
        "scenario": f"A ({length_m:.0f} m)",
        "period_s": sc.period_s,
        "horizon": 3,
        "n_cars": 6,
        "python": platform.python_version(),
        "machine": platform.machine(),
    }
    for name in ("sempc", "mpc"):
        t0 = time.perf_counter()
        r = run(sc, name)
        wall = time.perf_counter() - t0
        st = np.array(r.solve_times_s) * 1e3
        out[name] = {
            "steps": int(st.size),
            "solve_ms_median": round(float(np.median(st)), 3),
            "solve_ms_p95": round(float(np.percentile(st, 95)), 3),
            "solve_ms_max": round(float(np.max(st)), 3),
            "p95_share_of_period": round(float(np.percentile(st, 95)) / (sc.period_s * 1e3), 4),
            "qp_variables": 18 + 21,
            "qp_constraints": 2 * 21 + 21 + 18 + 18,
            "fallbacks": r.metrics["fallbacks"],
            "closed_loop_wall_s": round(wall, 2),
        }
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
