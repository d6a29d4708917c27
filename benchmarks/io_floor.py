"""The I/O floor: SUMO driving its own trains, plus the libsumo traffic the engine has with every train each step.

:func:`add_engine_io` patches :meth:`railsim.engine.sumo.SumoBridge.step` (in this process only: every benchmark
side runs in its own) so that before each SUMO step the bridge does what the engine's loop does with SUMO — the ids
of the trains present, the reading of every train (:meth:`SumoBridge.read`: four getters, and the edge where it
may have changed) and one ``setSpeed`` per train (:meth:`SumoBridge.set_speeds`, with -1: SUMO's car-following
keeps the train) — and nothing else. Run the bare
twin (:func:`railsim.studies.baseline.run_sumo_only`) after it: what any controller that drives SUMO train by train
through libsumo costs before it decides anything. ``busy_objects``: that many small dicts summed between two
steps, unrelated work that leaves SUMO's data out of the CPU caches (as a real engine's step does).
"""

from __future__ import annotations

import time
from typing import Any


def add_engine_io(busy_objects: int = 0) -> list[float]:
    """Patch the bridge's step; returns the list that receives the CPU seconds of each SUMO step."""
    from railsim.engine import sumo

    sumo_cpu: list[float] = []
    sumo_step = sumo.SumoBridge.step
    working_set = [{"k": i, "x": float(i)} for i in range(busy_objects)]

    def step_with_io(bridge: Any) -> None:
        total = 0.0
        for obj in working_set:
            total += obj["x"]
        ids = bridge.present_ids()
        bridge.read(ids)
        bridge.set_speeds(ids, [-1.0] * len(ids))
        c0 = time.process_time()
        sumo_step(bridge)
        sumo_cpu.append(time.process_time() - c0)

    sumo.SumoBridge.step = step_with_io  # type: ignore[method-assign]
    return sumo_cpu
