"""Service-day benchmark: how many times faster than real time railsim runs a whole Line 3 day, on one core.

Runs the day scenario (default ``scenarios/chongqing_line3_day.yaml``: 06:30-22:30, rotations, turnbacks,
virtually coupled peak pairs) once under railsim's controlled loop, and the same trips driven by SUMO alone
(``railsim.studies.baseline``: every trip its own train, no rotations, no controllers) as the baseline measured
in the same run. Each side runs in its own process (libsumo hosts one simulation per process) and measures its
own **process CPU time**, so the real-time factor is "on one core" whatever else the machine is doing; wall
times are printed beside it. Prints one JSON object::

    .venv/bin/python benchmarks/service_day.py [SCENARIO] [--hours H]

``cpu_s`` is the child process's CPU from loading the scenario to the written outputs (world, rotations and the
trips' plans included: at ``--hours 0.05`` that set-up is most of it; over a whole day it is a few seconds).
``--hours H`` simulates only the first H hours (the same scenario with ``simulation.duration_s`` cut), for a
quick look. The goal for the full day is a real-time factor of at least 300 on one core (`meets_goal`).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import platform
import tempfile
import time
from pathlib import Path
from typing import Any

from spawn import in_process  # benchmarks/spawn.py (the scripts' folder is on sys.path)

DEFAULT = Path(__file__).resolve().parents[1] / "scenarios" / "chongqing_line3_day.yaml"
GOAL_RTF = 300.0


def _load(path: str, duration_s: float | None) -> Any:
    from railsim import scenario

    return scenario.load(path, {"simulation.duration_s": duration_s} if duration_s else None)


def _railsim(path: str, duration_s: float | None, q: mp.Queue[dict[str, Any]]) -> None:
    from railsim import api

    scn = _load(path, duration_s)
    with tempfile.TemporaryDirectory() as out:
        c0 = time.process_time()
        s = api.run(scn, Path(out), progress=False)
        cpu_s = time.process_time() - c0
    fleet = s.get("fleet", {})
    keep = ("wall_s", "sim_s", "steps", "n_trains", "n_arrived", "collisions", "status")
    q.put({**{k: s.get(k) for k in keep}, "cpu_s": cpu_s, "units_used": fleet.get("units_used")})


def _sumo_only(path: str, duration_s: float | None, q: mp.Queue[dict[str, Any]]) -> None:
    from railsim.studies import baseline

    scn = _load(path, duration_s)
    c0 = time.process_time()
    res = baseline.run_sumo_only(scn)
    q.put({**res, "cpu_s": time.process_time() - c0})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario", nargs="?", default=str(DEFAULT))
    ap.add_argument("--hours", type=float, default=None, help="simulate only the first H hours")
    args = ap.parse_args()
    duration_s = args.hours * 3600.0 if args.hours else None
    sumo = in_process(_sumo_only, args.scenario, duration_s)  # also warms the world cache
    ours = in_process(_railsim, args.scenario, duration_s)
    rtf_cpu = ours["sim_s"] / ours["cpu_s"]
    print(
        json.dumps(
            {
                "benchmark": "service_day",
                "scenario": Path(args.scenario).name,
                "hours": args.hours,
                "python": platform.python_version(),
                "railsim": {**ours, "rtf_cpu": rtf_cpu, "rtf_wall": ours["sim_s"] / ours["wall_s"]},
                "sumo_only": {**sumo, "rtf_cpu": sumo["sim_s"] / sumo["cpu_s"]},
                "cpu_ratio_vs_sumo_only": ours["cpu_s"] / sumo["cpu_s"],
                "goal_rtf_cpu": GOAL_RTF,
                "meets_goal": rtf_cpu >= GOAL_RTF,
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
