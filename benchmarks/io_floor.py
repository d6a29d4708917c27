"""The I/O floor: SUMO driving its own trains, plus the libsumo traffic the engine has with every train each step.

:func:`add_engine_io` gives the bare twin (:func:`railsim.studies.baseline.run_sumo_only`, its ``before_step``) what
the engine's loop does with SUMO before each step — the ids of the trains present, the reading of every train
(:meth:`SumoBridge.read`: four getters, and the edge where it may have changed) and one ``setSpeed`` per train
(:meth:`SumoBridge.set_speeds`, with -1: SUMO's car-following keeps the train) — and nothing else: what any
controller that drives SUMO train by train through libsumo costs before it decides anything. ``busy_objects``:
that many small dicts summed between two steps, unrelated work that leaves SUMO's data out of the CPU caches (as a
real engine's step does). :func:`time_sumo_steps` times SUMO's own step (libsumo's ``simulationStep``, wrapped in
this process only: every benchmark side runs in its own), whichever bridge calls it, compiled or not.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any


def time_sumo_steps() -> list[float]:
    """Wrap libsumo's ``simulationStep`` in this process; returns the list that receives the CPU seconds of each."""
    import libsumo

    sumo_cpu: list[float] = []
    sumo_step = libsumo.simulationStep

    def timed_step(*args: Any) -> Any:
        c0 = time.process_time()
        out = sumo_step(*args)
        sumo_cpu.append(time.process_time() - c0)
        return out

    libsumo.simulationStep = timed_step
    return sumo_cpu


def add_engine_io(busy_objects: int = 0) -> tuple[list[float], Callable[[Any], None]]:
    """The CPU seconds of each SUMO step (:func:`time_sumo_steps`) and the engine's traffic with SUMO, to call with
    the bridge before each step."""
    sumo_cpu = time_sumo_steps()
    working_set = [{"k": i, "x": float(i)} for i in range(busy_objects)]

    def engine_io(bridge: Any) -> None:
        total = 0.0
        for obj in working_set:
            total += obj["x"]
        ids = bridge.present_ids()
        bridge.read(ids)
        bridge.set_speeds(ids, [-1.0] * len(ids))

    return sumo_cpu, engine_io
