"""Run one side of a benchmark in a fresh process and return the dictionary it puts on its queue.

libsumo hosts one simulation per process, so every SUMO run of a benchmark gets its own (spawned: nothing of
the parent's state, the same ``sys.path``). ``target(*args, queue)`` puts exactly one result.
"""

from __future__ import annotations

import multiprocessing as mp
from typing import Any


def in_process(target: Any, *args: Any) -> dict[str, Any]:
    ctx = mp.get_context("spawn")
    q = ctx.Queue()
    p = ctx.Process(target=target, args=(*args, q))
    p.start()
    res: dict[str, Any] = q.get()
    p.join()
    return res
