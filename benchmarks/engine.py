"""Engine benchmark: the demo scenario under railsim's controlled loop vs the same trains driven by SUMO alone.

Prints one JSON object: for each side the wall and process-CPU time of the stepping loop (set-up excluded:
world, fleet and free-run plans for railsim; the net for SUMO), simulated seconds per wall second, and the
ratio of our controlled loop's time to SUMO alone on the same net, trips and step. Both sides run ``--reps``
times (default 3), alternating, each run in its own process (libsumo hosts one simulation per process); the
ratios are the medians of the per-repetition ratios. On a shared machine wall time depends on the load;
the CPU ratio is the steadier figure. ``io_floor_cpu_ratio``: the twin plus the engine's per-train libsumo
traffic and no railsim logic (``benchmarks/io_floor.py``) ÷ the twin — the floor under the controlled ratio.
``core`` says whether the railsim side ran the compiled core (:mod:`railsim.native`, ``make native``);
``interpreted_cpu_overhead_ratio`` is the same loop on the interpreted modules (``RAILSIM_NATIVE=0``) in the same
run, and ``compiled_speedup`` the ratio of the two railsim sides' CPU.

    .venv/bin/python benchmarks/engine.py [SCENARIO] [--reps 3]
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import platform
import statistics
import tempfile
import time
from pathlib import Path

from spawn import in_process  # benchmarks/spawn.py (the scripts' folder is on sys.path)

DEFAULT = Path(__file__).resolve().parents[1] / "scenarios" / "chongqing_line3_peak.yaml"


def _railsim(path: str, q: mp.Queue[dict]) -> None:
    from railsim import native, scenario
    from railsim.engine.loop import Simulation

    with tempfile.TemporaryDirectory() as out:
        sim = Simulation(scenario.load(path), Path(out), progress=False)
        c0 = time.process_time()
        s = sim.run()
        cpu = time.process_time() - c0
    kept = {k: s[k] for k in ("wall_s", "sim_s", "steps", "n_trains", "n_arrived", "collisions")}
    q.put({**kept, "cpu_s": cpu, "core": native.STATUS})


def _sumo_only(path: str, q: mp.Queue[dict]) -> None:
    from railsim import scenario
    from railsim.studies import baseline

    q.put(baseline.run_sumo_only(scenario.load(path)))


def _io_floor(path: str, q: mp.Queue[dict]) -> None:
    from io_floor import add_engine_io  # benchmarks/io_floor.py

    from railsim import scenario
    from railsim.studies import baseline

    sumo_cpu, engine_io = add_engine_io()
    res = baseline.run_sumo_only(scenario.load(path), before_step=engine_io)
    q.put({**res, "sumo_step_cpu_s": sum(sumo_cpu)})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("scenario", nargs="?", default=str(DEFAULT))
    ap.add_argument("--reps", type=int, default=3, help="repetitions of each side (median reported)")
    args = ap.parse_args()
    path = args.scenario
    in_process(_sumo_only, path)  # warm the network cache so neither side pays for netconvert
    runs = []
    for _ in range(args.reps):
        sumo = in_process(_sumo_only, path)
        floor = in_process(_io_floor, path)
        ours = in_process(_railsim, path)
        interpreted = in_process(_railsim, path, env={"RAILSIM_NATIVE": "0"})
        runs.append({"railsim": ours, "sumo_only": sumo, "io_floor": floor, "railsim_interpreted": interpreted})
    wall = [r["railsim"]["wall_s"] / r["sumo_only"]["wall_s"] for r in runs]
    cpu = [r["railsim"]["cpu_s"] / r["sumo_only"]["cpu_s"] for r in runs]
    per_step = [
        (r["railsim"]["cpu_s"] / r["railsim"]["steps"]) / (r["sumo_only"]["cpu_s"] / r["sumo_only"]["steps"])
        for r in runs
    ]
    floor_cpu = [r["io_floor"]["cpu_s"] / r["sumo_only"]["cpu_s"] for r in runs]
    interp_cpu = [r["railsim_interpreted"]["cpu_s"] / r["sumo_only"]["cpu_s"] for r in runs]
    last = runs[-1]
    print(
        json.dumps(
            {
                "benchmark": "engine",
                "scenario": Path(path).name,
                "python": platform.python_version(),
                "reps": args.reps,
                "core": last["railsim"]["core"],  # railsim.native: the compiled core, or why not
                "runs": runs,
                "overhead_ratio": statistics.median(wall),
                "cpu_overhead_ratio": statistics.median(cpu),
                "cpu_per_step_ratio": statistics.median(per_step),
                # the twin plus the engine's per-train libsumo traffic, no railsim logic (benchmarks/io_floor.py)
                "io_floor_cpu_ratio": statistics.median(floor_cpu),
                # the same loop on railsim's interpreted modules (RAILSIM_NATIVE=0), and what compiling saves
                "interpreted_cpu_overhead_ratio": statistics.median(interp_cpu),
                "compiled_speedup": statistics.median(
                    r["railsim_interpreted"]["cpu_s"] / r["railsim"]["cpu_s"] for r in runs
                ),
                "ratios": {
                    "wall": wall,
                    "cpu": cpu,
                    "cpu_per_step": per_step,
                    "io_floor_cpu": floor_cpu,
                    "interpreted_cpu": interp_cpu,
                },
                "sim_s_per_wall_s": {
                    "railsim": last["railsim"]["sim_s"] / last["railsim"]["wall_s"],
                    "sumo_only": last["sumo_only"]["sim_s"] / last["sumo_only"]["wall_s"],
                },
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
