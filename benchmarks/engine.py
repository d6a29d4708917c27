"""Engine benchmark: the demo scenario under railsim's controlled loop vs the same trains driven by SUMO alone.

Prints one JSON object: wall time of the demo scenario, simulated seconds per wall second, and the ratio of our
controlled loop's wall time to SUMO alone on the same net, trips and step (both measured in this run, each in
its own process because libsumo hosts one simulation per process).

    .venv/bin/python benchmarks/engine.py [SCENARIO]
"""

from __future__ import annotations

import json
import multiprocessing as mp
import platform
import sys
import tempfile
from pathlib import Path

DEFAULT = Path(__file__).resolve().parents[1] / "scenarios" / "chongqing_line3_peak.yaml"


def _railsim(path: str, q: mp.Queue[dict]) -> None:
    from railsim import api as engine, scenario

    with tempfile.TemporaryDirectory() as out:
        s = engine.run(scenario.load(path), Path(out), progress=False)
    q.put({k: s[k] for k in ("wall_s", "sim_s", "steps", "n_trains", "n_arrived", "collisions")})


def _sumo_only(path: str, q: mp.Queue[dict]) -> None:
    from railsim import scenario
    from railsim.studies import baseline

    q.put(baseline.run_sumo_only(scenario.load(path)))


def _in_process(target, path: str) -> dict:
    ctx = mp.get_context("spawn")
    q = ctx.Queue()
    p = ctx.Process(target=target, args=(path, q))
    p.start()
    res = q.get()
    p.join()
    return res


def main() -> None:
    path = sys.argv[1] if len(sys.argv) > 1 else str(DEFAULT)
    _in_process(_sumo_only, path)  # warm the network cache so neither side pays for netconvert
    sumo = _in_process(_sumo_only, path)
    ours = _in_process(_railsim, path)
    print(
        json.dumps(
            {
                "benchmark": "engine",
                "scenario": Path(path).name,
                "python": platform.python_version(),
                "railsim": {**ours, "sim_s_per_wall_s": ours["sim_s"] / ours["wall_s"]},
                "sumo_only": {**sumo, "sim_s_per_wall_s": sumo["sim_s"] / sumo["wall_s"]},
                "overhead_ratio": ours["wall_s"] / sumo["wall_s"],
                "per_step_ms": {
                    "railsim": 1000 * ours["wall_s"] / ours["steps"],
                    "sumo_only": 1000 * sumo["wall_s"] / sumo["steps"],
                },
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
