"""Run one side of a benchmark in a fresh process and return the dictionary it puts on its queue.

libsumo hosts one simulation per process, so every SUMO run of a benchmark gets its own (spawned: nothing of
the parent's state, the same ``sys.path``). ``target(*args, queue)`` puts exactly one result.
"""

from __future__ import annotations

import multiprocessing as mp
import os
from typing import Any


def in_process(target: Any, *args: Any, env: dict[str, str] | None = None) -> dict[str, Any]:
    """``target(*args, queue)`` in a spawned process, with ``env`` added to its environment (e.g.
    ``RAILSIM_NATIVE=0``: railsim's interpreted modules instead of the compiled core)."""
    ctx = mp.get_context("spawn")
    q = ctx.Queue()
    p = ctx.Process(target=target, args=(*args, q))
    saved = {k: os.environ.get(k) for k in env or {}}
    os.environ.update(env or {})
    try:
        p.start()  # the spawned child takes the environment as it is now
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    res: dict[str, Any] = q.get()
    p.join()
    return res
