"""One case in a fresh child process: :func:`run_case` and the child's entry point.

libsumo hosts one simulation per process and a SUMO crash kills its interpreter, so every case runs in a new
``python -c`` child: the coordinator writes ``spec.json`` (scenario, overrides, seed, where to put the result),
the child (:func:`_child_main`) runs the engine, reduces the run folder to metrics
(:mod:`railsim.studies.sweep.metrics`) and writes ``result.json``; the coordinator turns that, a crash or a
timeout into one flat row and never raises for a failing case.

Children lead their own process group, so a terminal Ctrl-C reaches only the coordinator, which kills them through
the :class:`ChildControl` it passed to :func:`run_case`; a child also exits by itself when its parent dies.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from railsim.record import output
from railsim.studies.sweep.metrics import summary_metrics, trip_metrics
from railsim.studies.sweep.spec import case_id, override_cells

_TAIL_CHARS = 600  # how much of a crashed child's stderr goes into the error column
_PARENT_POLL_S = 1.0  # how often a child checks that its parent is still alive


class SweepInterrupted(Exception):
    """The sweep is stopping (Ctrl-C): the case's child was killed and its result must not be recorded."""


class ChildControl:
    """Live child processes of one coordinator, so that an interrupt can kill them all."""

    def __init__(self) -> None:
        self.stopping = threading.Event()
        self._lock = threading.Lock()
        self._live: set[subprocess.Popen[bytes]] = set()

    def add(self, proc: subprocess.Popen[bytes]) -> None:
        with self._lock:
            self._live.add(proc)
        if self.stopping.is_set():
            _kill(proc)

    def remove(self, proc: subprocess.Popen[bytes]) -> None:
        with self._lock:
            self._live.discard(proc)

    def stop(self) -> None:
        self.stopping.set()
        with self._lock:
            live = list(self._live)
        for proc in live:
            _kill(proc)


_DEFAULT_CONTROL = ChildControl()


def _kill(proc: subprocess.Popen[bytes]) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)  # the child leads its own process group
    except (ProcessLookupError, PermissionError):
        pass


def _watch_parent(parent_pid: int) -> None:
    while True:
        time.sleep(_PARENT_POLL_S)
        if os.getppid() != parent_pid:
            os._exit(3)  # the coordinator is gone: nobody will read our result


def _child_main(spec_path: str) -> None:
    """Entry point of the case child process (see :func:`run_case`): run, then write the result file."""
    spec = json.loads(Path(spec_path).read_text(encoding="utf-8"))
    threading.Thread(target=_watch_parent, args=(int(spec["parent_pid"]),), daemon=True).start()
    result_path = Path(spec["result"])
    try:
        from railsim import api, scenario

        scn = scenario.load(spec["scenario"], spec["overrides"])
        with tempfile.TemporaryDirectory(prefix="railsim_case_") as tmp:
            run_dir = Path(spec["out_dir"]) if spec.get("out_dir") else Path(tmp)
            api.run(scn, run_dir, seed=int(spec["seed"]), progress=False)
            summary = json.loads((run_dir / "summary.json").read_text(encoding="utf-8"))
            metrics = summary_metrics(summary)
            metrics.update(trip_metrics(run_dir))
        output.write_json(result_path, {"ok": True, "metrics": metrics})
    except BaseException as exc:  # noqa: BLE001 - every failure of a case becomes its error text
        output.write_json(result_path, {"ok": False, "error": f"{type(exc).__name__}: {exc}"})
        raise SystemExit(1) from None


def run_case(
    scenario_path: str | Path,
    overrides: Mapping[str, Any],
    seed: int,
    out_dir: Path | None = None,
    timeout_s: float | None = None,
    *,
    control: ChildControl | None = None,
) -> dict[str, Any]:
    """Run one case of ``scenario_path`` in a fresh child process and return its flat row.

    Never raises for a failing case: an exception in the child, a crash (signal) or a timeout gives
    ``status: failed`` with the reason in ``error``. With ``out_dir`` the run's full outputs are kept there.
    Raises :class:`SweepInterrupted` only when ``control`` is stopping (the sweep was interrupted).
    """
    ctl = control or _DEFAULT_CONTROL
    overrides = dict(overrides)
    row: dict[str, Any] = {"case_id": case_id(overrides, seed), "status": "failed", "error": "", "seed": int(seed)}
    row.update(override_cells(overrides))
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="railsim_case_io_") as io_dir:
        spec_file = Path(io_dir) / "spec.json"
        result_file = Path(io_dir) / "result.json"
        output.write_json(
            spec_file,
            {
                "scenario": str(Path(scenario_path).resolve()),
                "overrides": overrides,
                "seed": int(seed),
                "out_dir": str(Path(out_dir).resolve()) if out_dir else None,
                "result": str(result_file),
                "parent_pid": os.getpid(),
            },
        )
        code = f"from railsim.studies.sweep.child import _child_main; _child_main({str(spec_file)!r})"
        if ctl.stopping.is_set():
            raise SweepInterrupted(row["case_id"])
        proc = subprocess.Popen(
            [sys.executable, "-c", code], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True
        )
        ctl.add(proc)
        timed_out = False
        try:
            try:
                _, err = proc.communicate(timeout=timeout_s)
            except subprocess.TimeoutExpired:
                timed_out = True
                _kill(proc)
                _, err = proc.communicate()
        finally:
            ctl.remove(proc)
        row["wall_s"] = time.perf_counter() - t0
        if ctl.stopping.is_set():
            raise SweepInterrupted(row["case_id"])
        result = None
        if result_file.is_file():
            result = json.loads(result_file.read_text(encoding="utf-8"))
        if timed_out:
            row["error"] = f"timed out after {timeout_s:g} s"
        elif result is None:
            tail = err.decode("utf-8", "replace").strip()[-_TAIL_CHARS:]
            how = (
                f"killed by signal {signal.Signals(-proc.returncode).name}"
                if proc.returncode < 0
                else f"exited with code {proc.returncode}"
            )
            row["error"] = f"child process {how} without a result" + (f": {tail}" if tail else "")
        elif not result["ok"]:
            row["error"] = result["error"]
        else:
            row["status"] = "ok"
            row.update(result["metrics"])
    return row
