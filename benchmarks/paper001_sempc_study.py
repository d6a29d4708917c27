"""When does SEMPC's terminal cost make a measurable difference against MPC-A? (Paper B, spec 001 §2.12)

SEMPC and MPC-A (:mod:`controllers.ato_mpc.mpc`) are the same condensed QP except for the last stage weight: the
DARE tail cost ``P`` (SEMPC) against the ordinary stage weight ``Q_ξ`` (MPC-A). With the paper's single-section
weights (``q_v1 = 1e9`` against ``r_du = 1e-5``) and ``N = 3`` every step wants far more than the 6 kN force step
the 60 kN/s rate limit allows, so both programmes return the same rate-limited move and the terminal weight
changes nothing. The terminal cost can only matter where the *unconstrained* optimum lies inside the rate box
and the horizon is too short to see the consequences of a move: small ``N``, weights that trade tracking
against effort (Scenario B's ``q_v1 = 50``, ``r_du = 1e-8``), a paper-literal forward-Euler model whose coupler
modes are unstable, disturbances, the time-indexed reference. This script runs SEMPC and MPC-A side by side on the
numpy runner (:func:`controllers.ato_mpc.sim.run`, Scenario A on a 2 km section, flat-to-±12 ‰ synthetic
gradient) over those conditions and prints JSON: per condition both controllers' E_x (= the paper's E_d), E_p,
E_v, E_u, the largest coupler deviation and relative carriage speed, fallbacks, force-rate violations, and
the SEMPC − MPC differences.

    .venv/bin/python benchmarks/paper001_sempc_study.py [--jobs 1] [--length-m 2000] > out.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from controllers.ato_mpc.sim import MULTI_WEIGHTS, SINGLE_WEIGHTS, run, scenario_a, scenario_c  # noqa: E402
from railsim.physics.multipoint import MultipointParams  # noqa: E402

KEYS = (
    "e_x_m",
    "e_p_m",
    "e_v_mps",
    "e_u_1e12",
    "max_coupler_deviation_m",
    "max_relative_speed_mps",
    "coupler_band_violations",
    "rate_violations",
    "force_violations",
    "fallbacks",
    "duration_s",
)
WEIGHTS = {"single": SINGLE_WEIGHTS, "multi": MULTI_WEIGHTS}


def conditions() -> list[dict[str, Any]]:
    """The grid: horizon × weights × rate limit (nominal otherwise), then horizon 1/3 × the other factors."""
    base = {"horizon": 3, "weights": "single", "rate_kn_per_s": 60.0, "wind": "none", "mode": "distance"}
    base["discretisation"] = "zoh"
    out = []
    for n in (1, 2, 3, 5):
        for w in ("single", "multi"):
            for rate in (60.0, 15.0):
                out.append({**base, "horizon": n, "weights": w, "rate_kn_per_s": rate})
    for n in (1, 3):
        for w in ("single", "multi"):
            out.append({**base, "horizon": n, "weights": w, "wind": "constant"})
            out.append({**base, "horizon": n, "weights": w, "wind": "harmonic"})
            out.append({**base, "horizon": n, "weights": w, "mode": "time"})
            out.append({**base, "horizon": n, "weights": w, "discretisation": "euler"})
    return out


def _job(args: tuple[dict[str, Any], str, float]) -> tuple[str, str, dict[str, Any]]:
    cond, controller, length_m = args
    rate = cond["rate_kn_per_s"] * 1e3
    p = MultipointParams(force_rate_max_n_per_s=rate, force_rate_min_n_per_s=-rate)
    weights = dict(WEIGHTS[cond["weights"]])
    if cond["wind"] == "none":
        sc = scenario_a(length_m, weights=weights, max_time_s=600.0)
    else:
        sc = scenario_c(cond["wind"], length_m, weights=weights, max_time_s=600.0)
    n = cond["horizon"]
    overrides = {"horizon_p": n, "horizon_c": n, "discretisation": cond["discretisation"]}
    t0 = time.process_time()
    r = run(sc, controller, p, cond["mode"], overrides)
    m = {k: r.metrics[k] for k in KEYS}
    n_cars = p.n_cars
    m["rms_relative_speed_mps"] = float(np.sqrt(np.mean(r.rel[:, n_cars + 1 :] ** 2))) if n_cars > 1 else 0.0
    m["solve_ms_median"] = r.metrics.get("solve_ms_median")
    m["cpu_s"] = time.process_time() - t0
    return json.dumps(cond, sort_keys=True), controller, m


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--length-m", type=float, default=2000.0)
    args = ap.parse_args()
    jobs = [(c, ctl, args.length_m) for c in conditions() for ctl in ("sempc", "mpc")]
    with ProcessPoolExecutor(args.jobs) as pool:
        done = list(pool.map(_job, jobs))
    table: dict[str, dict[str, Any]] = {}
    for key, ctl, m in done:
        table.setdefault(key, {"condition": json.loads(key)})[ctl] = m
    rows = []
    for row in table.values():
        s, m = row["sempc"], row["mpc"]
        row["sempc_minus_mpc"] = {
            k: (None if s[k] is None or m[k] is None else s[k] - m[k])
            for k in ("e_x_m", "e_p_m", "e_v_mps", "e_u_1e12", "max_coupler_deviation_m", "rms_relative_speed_mps")
        }
        rows.append(row)
    print(json.dumps({"length_m": args.length_m, "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
