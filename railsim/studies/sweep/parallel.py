"""Many cases at once: local threads that each wait on one child process, or tasks on a Dask cluster.

:func:`execute` takes :class:`CaseTask` objects and yields ``(task, row)`` in completion order; every task is
:func:`railsim.studies.sweep.child.run_case`, so both back ends run each case in a fresh child process and give
identical metric columns. It knows nothing of sweep folders: :func:`railsim.studies.sweep.runner.run_sweep`
persists the rows, and the minimum-headway search (:mod:`railsim.studies.headway`) uses it for its probes.

**Why Dask.** Users who run large sweeps already have a cluster with a Dask scheduler; ``dask_address`` submits to
it with ``distributed.Client`` and needs nothing else installed or started. Its workers must see the same paths
(the base scenario, its world files, the kept run folders). A Dask task that is already running when the sweep
is interrupted finishes in the background (Dask cannot stop a running thread); its result is discarded.
"""

from __future__ import annotations

import concurrent.futures as cf
import os
import threading
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from railsim.errors import ConfigError
from railsim.inputs import excerpt
from railsim.studies.sweep.child import ChildControl, run_case
from railsim.studies.sweep.spec import Case, override_cells

DASK_CONNECT_TIMEOUT_S = 10.0  # how long to try reaching a Dask scheduler before giving up
DASK_HANDSHAKE_GRACE_S = 5.0  # and how much longer its handshake may take before the address is refused


@dataclass(frozen=True)
class CaseTask:
    """What :func:`execute` runs: a case of a scenario file, with where to keep its outputs (or None)."""

    scenario: Path
    case: Case
    out_dir: Path | None = None
    timeout_s: float | None = None


def _connect(dask_address: str) -> Any:
    """A ``distributed.Client`` of the scheduler at ``dask_address``, or one ConfigError (exit 2) within
    :data:`DASK_CONNECT_TIMEOUT_S` + :data:`DASK_HANDSHAKE_GRACE_S` seconds.

    ``Client(timeout=...)`` bounds the TCP connect but not always the handshake after it: a port that accepts and
    never answers kept it waiting for ever, and an HTTP server's reply read as a Dask frame header asked for
    exabytes of memory. So the client is made in a helper thread that is given a hard deadline, and anything it
    raises (a ``MemoryError`` too) means "not a Dask scheduler"; the thread is a daemon, so a connection that
    never answers does not keep railsim alive.
    """
    try:
        from distributed import Client
    except ImportError:  # an optional extra: only --dask needs it
        raise ConfigError(
            None, "--dask", "needs the dask extra: pip install 'railsim[dask]' (dask and distributed)"
        ) from None
    shown = excerpt(dask_address)
    result: dict[str, Any] = {}

    def attempt() -> None:
        try:
            result["client"] = Client(dask_address, timeout=f"{DASK_CONNECT_TIMEOUT_S}s")
        except BaseException as exc:  # noqa: BLE001 - whatever the address does, it is reported as one line
            result["error"] = exc

    thread = threading.Thread(target=attempt, name="railsim-dask-connect", daemon=True)
    thread.start()
    thread.join(DASK_CONNECT_TIMEOUT_S + DASK_HANDSHAKE_GRACE_S)
    if thread.is_alive():
        raise ConfigError(
            None,
            "--dask",
            f"no Dask scheduler answered at {shown} within {DASK_CONNECT_TIMEOUT_S + DASK_HANDSHAKE_GRACE_S:g} s "
            "(a port that accepts but never answers, or not a Dask scheduler)",
        )
    if "error" in result:
        exc = result["error"]
        reason = excerpt(f"{type(exc).__name__}: {exc}", 160)
        raise ConfigError(None, "--dask", f"cannot connect to the Dask scheduler at {shown}: {reason}")
    return result["client"]


def execute(
    tasks: Sequence[CaseTask],
    workers: int | None = None,
    dask_address: str | None = None,
) -> Iterator[tuple[CaseTask, dict[str, Any]]]:
    """Run ``tasks`` in parallel and yield ``(task, row)`` as each finishes (completion order).

    Locally ``workers`` threads (default: the number of cores) each wait on one child process; with
    ``dask_address`` every task is submitted to that Dask cluster. Closing the generator early, or an exception in
    the consumer (Ctrl-C), kills the local children and cancels the pending Dask tasks: no result arrives after.
    """
    if not tasks:
        return
    if dask_address is not None:
        yield from _execute_dask(tasks, dask_address)
        return
    n = max(1, int(workers or os.cpu_count() or 1))
    ctl = ChildControl()
    pool = cf.ThreadPoolExecutor(max_workers=min(n, len(tasks)), thread_name_prefix="railsim-case")
    try:
        futures = {
            pool.submit(run_case, t.scenario, t.case.overrides, t.case.seed, t.out_dir, t.timeout_s, control=ctl): t
            for t in tasks
        }
        for fut in cf.as_completed(futures):
            yield futures[fut], fut.result()
    finally:
        ctl.stop()
        pool.shutdown(wait=True, cancel_futures=True)


def _execute_dask(tasks: Sequence[CaseTask], dask_address: str) -> Iterator[tuple[CaseTask, dict[str, Any]]]:
    from distributed import as_completed

    client = _connect(dask_address)
    futures: dict[Any, CaseTask] = {}
    try:
        for t in tasks:
            fut = client.submit(
                run_case,
                str(t.scenario),
                t.case.overrides,
                t.case.seed,
                str(t.out_dir) if t.out_dir else None,
                t.timeout_s,
                pure=False,
                key=f"railsim-case-{t.case.case_id}-{os.urandom(4).hex()}",
            )
            futures[fut] = t
        for fut in as_completed(list(futures)):
            task = futures[fut]
            if fut.status == "error":  # the task itself died (a lost worker): a failed case, like a crash
                row = {
                    "case_id": task.case.case_id,
                    "status": "failed",
                    "seed": task.case.seed,
                    "error": f"Dask task failed: {type(fut.exception()).__name__}: {fut.exception()}",
                }
                row.update(override_cells(task.case.overrides))
            else:
                row = fut.result()
            yield task, row
    finally:
        pending = [f for f in futures if not f.done()]
        if pending:
            client.cancel(pending)
        client.close()
