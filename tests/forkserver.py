"""``railsim`` child processes without the interpreter start: a fork server that has imported railsim once.

Every SUMO run of the suite happens in a child process (a SUMO crash kills its interpreter, so one crash must fail
one test). A fresh ``python -m railsim.cli.main`` spends about a second and a half of CPU before it reads its
arguments: the interpreter starts and imports numpy, pandas, numba, scipy, libsumo, matplotlib and railsim. The
suite starts several hundred such children, so that start-up was a large part of ``make test``.

The fork server is a plain child process (``python -m tests.forkserver``, one per pytest process, started on first
use) that imports those modules once and then, for every command, **forks**: the forked child is a new process
(its own pid, memory, exit status; a crash or ``os._exit`` ends it alone), already past the imports. In it the
command runs exactly as ``python -m railsim.cli.main ARGS`` runs it — ``sys.argv``, the working folder and the
environment set as asked, stdin from ``/dev/null``, stdout and stderr into files, ``railsim.cli.main.main()`` called
and its result (or ``SystemExit``) the exit code, ``atexit`` handlers run, output flushed, exit. The caller gets a
:class:`subprocess.CompletedProcess` as from :func:`subprocess.run` (``text=True``), and
:class:`subprocess.TimeoutExpired` (the child killed) on a timeout.

A child forked from the server is what a fresh interpreter would be, or the server is not used:

* an environment that differs in anything read while the interpreter starts or the modules import (``PYTHON*``,
  ``NUMBA_*``, ``SUMO_HOME``, ``MPLBACKEND``, ``RAILSIM_NATIVE``, ``OMP_*``/``OPENBLAS_*``/``MKL_*``) gets a server started with it;
* a server whose imports wrote anything to stderr (a warning a fresh process would print on every run), no
  ``os.fork`` (not POSIX), or a server that died: :func:`run` falls back to :func:`subprocess.run`.

Tests *about* the process itself (Ctrl-C while the modules import, the console script) start their own
interpreter with :mod:`subprocess` and do not come here.
"""

from __future__ import annotations

import atexit
import json
import locale
import os
import select
import signal
import subprocess
import sys
import tempfile
import threading
from pathlib import Path
from typing import IO, Any

# environment variables read when an interpreter starts or its modules import: a different value needs a real start
START_UP_PREFIXES = (
    "PYTHON",
    "NUMBA_",
    "OMP_",
    "OPENBLAS_",
    "MKL_",
    "SUMO_HOME",
    "MPLBACKEND",
    "LD_",
    "RAILSIM_NATIVE",
)
# what the server imports before it forks (what ``railsim run``/``plot``/``report``/``validate`` import)
PRELOAD = (
    "railsim.cli.main",
    "railsim.api",
    "railsim.engine",
    "railsim.engine.sumo",
    "railsim.report",
    "railsim.report.plots.line",
    "railsim.analysis",
    "railsim.studies.world",
    "network.build",
    "pandas",
    "pyarrow.parquet",
)
ROOT = Path(__file__).resolve().parents[1]


def _start_up_env(env: dict[str, str]) -> dict[str, str]:
    return {k: v for k, v in env.items() if k.startswith(START_UP_PREFIXES)}


class _Client:
    """The pytest process's handle on its fork server: started on first use with the caller's environment, and
    started again with the new one when a command's start-up environment differs (a test that set ``OMP_*`` for a
    Dask cluster, say), so every child is forked from a server that started as a fresh interpreter would."""

    def __init__(self) -> None:
        self.proc: subprocess.Popen[bytes] | None = None
        self.env: dict[str, str] = {}
        self.sumo_home = ""
        self.broken = not hasattr(os, "fork")
        self.registered = False
        self.lock = threading.Lock()

    def _start(self, env: dict[str, str]) -> bool:
        if self.broken:
            return False
        if self.proc is not None and self.proc.poll() is None:
            return True
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "tests.forkserver"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            cwd=ROOT,
            env=env,
        )
        assert self.proc.stdout is not None
        hello = self.proc.stdout.readline().decode().strip()
        if not hello.startswith("ready "):
            self.broken = True  # its imports printed something, or it could not start: never used again
            self.proc.kill()
            self.proc.wait()
            return False
        self.env = _start_up_env(env)
        self.sumo_home = json.loads(hello.removeprefix("ready "))["SUMO_HOME"]
        if not self.registered:
            atexit.register(self._stop)
            self.registered = True
        return True

    def _stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            assert self.proc.stdin is not None
            self.proc.stdin.close()
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()

    def serves(self, env: dict[str, str]) -> bool:
        """True if a child forked from the server is what a fresh interpreter with ``env`` would be."""
        if not self._start(env):
            return False
        if self._same_start(env):
            return True
        self._stop()  # a different start-up environment: a server that started with it
        return self._start(env) and self._same_start(env)

    def _same_start(self, env: dict[str, str]) -> bool:
        asked, served = _start_up_env(env), dict(self.env)
        # SUMO_HOME unset or empty: railsim.engine.sumo sets the package's when it is imported, as the server did
        if not asked.get("SUMO_HOME"):
            asked["SUMO_HOME"] = self.sumo_home
        if not served.get("SUMO_HOME"):
            served["SUMO_HOME"] = self.sumo_home
        return asked == served

    def run(self, args: list[str], env: dict[str, str], cwd: Path, timeout: float) -> subprocess.CompletedProcess[str]:
        assert self.proc is not None and self.proc.stdin is not None and self.proc.stdout is not None
        with tempfile.TemporaryDirectory(prefix="railsim-fork-") as tmp:
            out, err = Path(tmp) / "stdout", Path(tmp) / "stderr"
            request = {"args": args, "env": env, "cwd": str(cwd), "stdout": str(out), "stderr": str(err)}
            self.proc.stdin.write(json.dumps(request).encode() + b"\n")
            self.proc.stdin.flush()
            pid = int(self.proc.stdout.readline())
            ready, _, _ = select.select([self.proc.stdout], [], [], timeout)
            timed_out = not ready
            if timed_out:
                os.kill(pid, signal.SIGKILL)
            code = int(self.proc.stdout.readline())
            stdout, stderr = _read_text(out), _read_text(err)
        cmd = [sys.executable, "-m", "railsim.cli.main", *args]
        if timed_out:
            raise subprocess.TimeoutExpired(cmd, timeout, output=stdout, stderr=stderr)
        return subprocess.CompletedProcess(cmd, code, stdout, stderr)


def _read_text(path: Path) -> str:
    # as subprocess.run(text=True) decodes: the locale's encoding, universal newlines
    with open(path, encoding=locale.getpreferredencoding(False)) as fh:
        return fh.read()


_CLIENT = _Client()


def run(args: list[str], env: dict[str, str], cwd: Path, timeout: float) -> subprocess.CompletedProcess[str]:
    """``python -m railsim.cli.main ARGS`` with ``env`` in ``cwd``, as :func:`subprocess.run` with
    ``capture_output=True, text=True`` would give it; forked from the fork server where it can reproduce the
    command exactly, else a real interpreter start."""
    with _CLIENT.lock:
        if _CLIENT.serves(env):
            try:
                return _CLIENT.run(args, env, cwd, timeout)
            except (OSError, ValueError):  # the server died (its pipe closed): fall back from now on
                _CLIENT.broken = True
    cmd = [sys.executable, "-m", "railsim.cli.main", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env, cwd=cwd)


# ------------------------------------------------------------------------------------------------- the server
def _child(request: dict[str, Any]) -> None:
    """In the forked child: become ``python -m railsim.cli.main ARGS`` and exit with its code (never returns)."""
    code = 1
    try:
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        signal.signal(signal.SIGPIPE, signal.SIG_IGN)  # as the interpreter sets it at start-up
        os.chdir(request["cwd"])
        sumo_home = os.environ.get("SUMO_HOME")
        os.environ.clear()
        os.environ.update(request["env"])
        if not os.environ.get("SUMO_HOME") and sumo_home:
            os.environ["SUMO_HOME"] = sumo_home  # what railsim.engine.sumo set when it was imported
        null = os.open(os.devnull, os.O_RDONLY)
        os.dup2(null, 0)
        for fd, name in ((1, "stdout"), (2, "stderr")):
            f = os.open(request[name], os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
            os.dup2(f, fd)
            os.close(f)
        sys.argv = [str(ROOT / "railsim" / "cli" / "main.py"), *request["args"]]
        from railsim.cli.main import main

        try:
            code = main()
        except SystemExit as exc:
            code = _exit_code(exc)
        except BaseException:  # noqa: BLE001 - as the interpreter does: the traceback on stderr, exit 1
            import traceback

            traceback.print_exc()
            code = 1
        try:
            atexit._run_exitfuncs()
        except BaseException:  # noqa: BLE001
            pass
    finally:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except BaseException:  # noqa: BLE001 - a closed pipe: nothing more to say
                pass
        os._exit(code)


def _exit_code(exc: SystemExit) -> int:
    if exc.code is None:
        return 0
    if isinstance(exc.code, int):
        return exc.code
    print(exc.code, file=sys.stderr)
    return 1


def _load_compiled_kernels() -> None:
    """Load every numba kernel of railsim, controllers and network that is compiled in numba's on-disk cache (``make
    test`` warms it first: :mod:`tests.warm`) for each signature cached, so a child does not load it again; a kernel
    not cached yet stays as it is (the first child that needs it compiles it). Best effort: numba's cache index is
    not a public API, and any surprise there only leaves the loading to the children."""
    try:
        from numba.core.dispatcher import Dispatcher
    except ImportError:
        return
    for name, module in list(sys.modules.items()):
        if not name.startswith(("railsim", "controllers", "network")):
            continue
        for value in list(vars(module).values()):
            if not isinstance(value, Dispatcher) or value.__module__ != name:
                continue
            try:
                for key in value._cache._cache_file._load_index():
                    value.compile(key[0])
            except Exception:  # noqa: BLE001, S112 - best effort (see above)
                continue


def serve(requests: IO[bytes], replies: IO[bytes]) -> None:
    """Import :data:`PRELOAD`, say ``ready {"SUMO_HOME": ...}`` (or ``noisy`` if the imports wrote to stderr), then fork a child per
    request line and answer with its pid and, when it ended, its exit status."""
    import importlib

    with tempfile.TemporaryFile() as noise:
        saved = os.dup(2)
        os.dup2(noise.fileno(), 2)
        try:
            for name in PRELOAD:
                importlib.import_module(name)
            _load_compiled_kernels()
        finally:
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
        noise.seek(0)
        noisy = bool(noise.read())
    hello = "noisy" if noisy else "ready " + json.dumps({"SUMO_HOME": os.environ.get("SUMO_HOME", "")})
    replies.write(hello.encode() + b"\n")
    replies.flush()
    if noisy:
        return
    for line in requests:
        request = json.loads(line)
        sys.stdout.flush()
        sys.stderr.flush()
        pid = os.fork()
        if pid == 0:
            requests.close()
            replies.close()
            _child(request)
        replies.write(f"{pid}\n".encode())
        replies.flush()
        _, status = os.waitpid(pid, 0)
        replies.write(f"{os.waitstatus_to_exitcode(status)}\n".encode())
        replies.flush()


if __name__ == "__main__":
    # the protocol runs on private copies of the pipes; fds 0 and 1 are left for what the children inherit
    requests = os.fdopen(os.dup(0), "rb")
    replies = os.fdopen(os.dup(1), "wb")
    devnull = os.open(os.devnull, os.O_RDWR)
    os.dup2(devnull, 0)
    os.dup2(devnull, 1)  # a stray print of the server must not land in the replies
    os.close(devnull)
    serve(requests, replies)
