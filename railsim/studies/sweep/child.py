"""One case in a fresh child process: :func:`run_case` and the child's entry point.

libsumo hosts one simulation per process and a SUMO crash kills its interpreter, so every case runs in a new
``python -c`` child: the coordinator writes ``spec.json`` (scenario, overrides, seed, where to put the result),
the child (:func:`_child_main`) runs the engine, reduces the run folder to metrics
(:mod:`railsim.studies.sweep.metrics`) and writes ``result.json``; the coordinator turns that, a crash or a
timeout into one flat row and never raises for a failing case.

Children lead their own process group, so a terminal Ctrl-C reaches only the coordinator, which kills them through
the :class:`ChildControl` it passed to :func:`run_case`; a child also exits by itself when its parent dies.

A child is a new process, but not a new interpreter where the platform allows: the coordinator's first case starts
a ``multiprocessing`` fork server that imports the engine once (:data:`_PRELOAD`), and each case is forked from it
(:func:`_forked_main`) — its own pid, memory, exit status and process group, with the coordinator's environment,
working folder and stderr captured as for a ``python -c`` child, but without the second and a half of interpreter
start and imports that each case would otherwise spend before its first step. Where there is no fork server (not
POSIX) or the coordinator is a daemonic process (which may not start children that way, e.g. a Dask worker), a case
starts its own interpreter as above.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Protocol

from railsim.record import output
from railsim.studies.sweep.metrics import summary_metrics, trip_metrics
from railsim.studies.sweep.spec import case_id, override_cells

_PRELOAD = ["railsim.studies.sweep.child", "railsim.api", "railsim.scenario", "railsim.engine", "railsim.engine.sumo"]
_TAIL_CHARS = 600  # how much of a crashed child's stderr goes into the error column
_PARENT_POLL_S = 1.0  # how often a child checks that its parent is still alive


class SweepInterrupted(Exception):
    """The sweep is stopping (Ctrl-C): the case's child was killed and its result must not be recorded."""


class _Process(Protocol):
    """What :class:`ChildControl` needs of a case's child: its pid (= its process group)."""

    @property
    def pid(self) -> int | None: ...


class ChildControl:
    """Live child processes of one coordinator, so that an interrupt can kill them all."""

    def __init__(self) -> None:
        self.stopping = threading.Event()
        self._lock = threading.Lock()
        self._live: set[_Process] = set()

    def add(self, proc: _Process) -> None:
        with self._lock:
            self._live.add(proc)
        if self.stopping.is_set():
            _kill(proc)

    def remove(self, proc: _Process) -> None:
        with self._lock:
            self._live.discard(proc)

    def stop(self) -> None:
        self.stopping.set()
        with self._lock:
            live = list(self._live)
        for proc in live:
            _kill(proc)


_DEFAULT_CONTROL = ChildControl()


def _kill(proc: _Process) -> None:
    if proc.pid is None:  # never started
        return
    try:
        os.killpg(proc.pid, signal.SIGKILL)  # the child leads its own process group
    except (ProcessLookupError, PermissionError):
        try:  # a forked child killed before it made its group
            os.kill(proc.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass


def _watch_parent(parent_pid: int) -> None:
    while True:
        time.sleep(_PARENT_POLL_S)
        if os.getppid() != parent_pid:
            os._exit(3)  # the coordinator (or the fork server, which ends with it) is gone: nobody reads our result


def _child_main(spec_path: str, forked: bool = False) -> None:
    """Entry point of the case child process (see :func:`run_case`): run, then write the result file. A forked
    child's parent is the fork server, which ends when the coordinator does; it watches that one."""
    spec = json.loads(Path(spec_path).read_text(encoding="utf-8"))
    parent = os.getppid() if forked else int(spec["parent_pid"])
    threading.Thread(target=_watch_parent, args=(parent,), daemon=True).start()
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
        if ctl.stopping.is_set():
            raise SweepInterrupted(row["case_id"])
        context = _fork_context()
        if context is not None:
            returncode, err, timed_out = _run_forked(context, spec_file, Path(io_dir) / "stderr", timeout_s, ctl)
        else:
            returncode, err, timed_out = _run_interpreter(spec_file, timeout_s, ctl)
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
                f"killed by signal {signal.Signals(-returncode).name}"
                if returncode < 0
                else f"exited with code {returncode}"
            )
            row["error"] = f"child process {how} without a result" + (f": {tail}" if tail else "")
        elif not result["ok"]:
            row["error"] = result["error"]
        else:
            row["status"] = "ok"
            row.update(result["metrics"])
    return row


def _run_interpreter(spec_file: Path, timeout_s: float | None, ctl: ChildControl) -> tuple[int, bytes, bool]:
    """The case in a new ``python -c`` interpreter: (exit code, stderr, timed out)."""
    code = f"from railsim.studies.sweep.child import _child_main; _child_main({str(spec_file)!r})"
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
    return proc.returncode, err, timed_out


def _fork_context() -> Any:
    """The ``forkserver`` start method with the engine preloaded, or None where a case needs its own interpreter."""
    if "forkserver" not in multiprocessing.get_all_start_methods() or multiprocessing.current_process().daemon:
        return None
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(_PRELOAD)
    return context


def _run_forked(
    context: Any, spec_file: Path, err_file: Path, timeout_s: float | None, ctl: ChildControl
) -> tuple[int, bytes, bool]:
    """The case in a child forked from the fork server: (exit code, stderr, timed out)."""
    env, cwd = dict(os.environ), os.getcwd()
    proc = context.Process(target=_forked_main, args=(str(spec_file), str(err_file), env, cwd), name="railsim-case")
    proc.start()
    ctl.add(proc)
    timed_out = False
    try:
        proc.join(timeout_s)
        if proc.exitcode is None:
            timed_out = True
            _kill(proc)
            proc.join()
    finally:
        ctl.remove(proc)
    err = err_file.read_bytes() if err_file.is_file() else b""
    return int(proc.exitcode if proc.exitcode is not None else -signal.SIGKILL), err, timed_out


def _forked_main(spec_path: str, err_path: str, env: dict[str, str], cwd: str) -> None:
    """A forked case child: become what ``python -c`` would start — its own process group, the coordinator's
    environment and folder, stdin and stdout on the null device, stderr captured — then run the case."""
    os.setsid()
    os.chdir(cwd)
    os.environ.clear()
    os.environ.update(env)
    null = os.open(os.devnull, os.O_RDWR)
    os.dup2(null, 0)
    os.dup2(null, 1)
    err = os.open(err_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    os.dup2(err, 2)
    _child_main(spec_path, forked=True)
