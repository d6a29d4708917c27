"""What putting N trains on the line costs: CPU of ``Simulation.run`` on the scale corridor, and its share until
every train is on.

``benchmarks/scale.py`` measures the steps after its warm-up; this one measures the whole run, split at the first
step at which every train runs (set-up, the t = 0 departures, SUMO's insertion queue and the stall watchdog's
questions about it), and the CPU spent in the watchdog's questions (``Dispatcher.blocker_at_front``). One JSON line
per size.

    .venv/bin/python benchmarks/insertion_setup.py [--sizes 300,1000,3000] [--horizon-s 40]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from typing import Any

import scale  # benchmarks/scale.py (the scripts' folder is on sys.path)
from spawn import in_process


def measure(n_trains: int, horizon_s: float, q: Any) -> None:
    """One run in this process (libsumo hosts one simulation per process); its figures go on ``q``."""
    from railsim.engine import insertion
    from railsim.engine.loop import Simulation

    asked_s = [0.0]
    blocker_at_front = insertion.Dispatcher.blocker_at_front

    def timed(self: Any, tr: Any) -> Any:
        c0 = time.process_time()
        try:
            return blocker_at_front(self, tr)
        finally:
            asked_s[0] += time.process_time() - c0

    insertion.Dispatcher.blocker_at_front = timed  # type: ignore[method-assign]
    marks: list[tuple[float, int]] = []  # (CPU at the start of the step, trains running)

    class Marked(Simulation):
        def _step(self, t: float) -> None:
            marks.append((time.process_time(), sum(tr.status == "running" for tr in self.trains.values())))
            super()._step(t)

    with tempfile.TemporaryDirectory() as out:
        sim = Marked(scale._load(n_trains, horizon_s), Path(out), progress=False)
        c0 = time.process_time()
        sim.run()
        c1 = time.process_time()
    all_on = next((k for k, (_, running) in enumerate(marks) if running == n_trains), None)
    q.put(
        {
            "n_trains": n_trains,
            "run_cpu_s": round(c1 - c0, 2),
            "steps": len(marks),
            "all_on_at_step": all_on,
            "cpu_until_all_on_s": round((marks[all_on][0] if all_on is not None else c1) - c0, 2),
            "blocker_at_front_cpu_s": round(asked_s[0], 2),
            "collisions": len(sim.safety.collisions),
            "failure": sim.failure(),
        }
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="300,1000,3000")
    ap.add_argument("--horizon-s", type=float, default=40.0)
    args = ap.parse_args()
    for n in (int(s) for s in args.sizes.split(",")):
        print(json.dumps(in_process(measure, n, args.horizon_s)), flush=True)


if __name__ == "__main__":
    main()
