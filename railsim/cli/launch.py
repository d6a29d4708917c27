"""The ``railsim`` executable's entry point: a Ctrl-C at any moment of a command is one line and exit 130.

The command's modules import numpy, pandas and the engine, which takes a noticeable fraction of a second. A
``KeyboardInterrupt`` raised in the middle of an import can land where nobody can catch it (in importlib's module
lock callbacks: "Exception ignored", the command then carrying on). So while the command's modules are imported,
SIGINT only *records* that it came; once they are in, the usual handler is back and a recorded Ctrl-C ends the
command at once. From then on :func:`railsim.cli.main.run_guarded` turns a Ctrl-C into the same line and code, and
a run installs its own clean stop (:mod:`railsim.engine.interrupt`).

An interrupted command leaves with :func:`os._exit` after flushing its output: the interpreter may still carry a
KeyboardInterrupt that surfaced where nothing could catch it, and would then end itself *by the signal* (status
-2) instead of with 130. Everything a run writes is written and closed before this point. Once the command has
returned, SIGINT is ignored until the process is gone: a Ctrl-C that came while the interpreter was shutting down
would otherwise end it by the signal (status -2, no line) although the command had finished. This module imports
nothing of railsim at its top.
"""

from __future__ import annotations

import os
import signal
import sys
from types import FrameType

EXIT_INTERRUPTED = 130


def main() -> int:
    came: list[int] = []

    def record(signum: int, _frame: FrameType | None) -> None:
        came.append(signum)

    previous = signal.signal(signal.SIGINT, record)
    try:
        from railsim.cli.main import main as run_command
    finally:
        signal.signal(signal.SIGINT, previous)
    try:
        code = interrupted() if came else run_command()
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # the command is over: a Ctrl-C now has nothing to stop
    except KeyboardInterrupt:
        code = interrupted()
    if code == EXIT_INTERRUPTED:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code


def interrupted() -> int:
    print("railsim: interrupted", file=sys.stderr)
    return EXIT_INTERRUPTED


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
