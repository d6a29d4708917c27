"""Stopping a run cleanly on Ctrl-C (SIGINT) or SIGTERM: nothing lost.

A signal arriving in the middle of a step would leave the ports half updated, so the handler only *notes* the
signal; the step loop asks :meth:`StopRequest.reason` between steps and, once it is set, ends the run there as
if the horizon had been reached. The outputs are then written as usual (every table up to the simulated time
reached) and ``summary.json`` says ``status: interrupted``, the signal and ``sim_s``. The command exits with
``128 + signal number`` (130 for SIGINT, 143 for SIGTERM), as a shell expects of a program a signal stopped.

A second signal of the same kind does not wait for the step to end: the previous handler is back in place,
so a second Ctrl-C raises :class:`KeyboardInterrupt` (for a run stuck inside SUMO) and a second SIGTERM ends
the process.

Only the CLI installs the handlers (:func:`stop_on_signals`); a Python caller of :func:`railsim.engine.run`
passes a :class:`StopRequest` of its own, or none.

::

    with stop_on_signals() as stop:
        summary = engine.run(scn, out_dir, stop=stop)
    if stop.signum is not None:
        sys.exit(stop.exit_code)
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType
from typing import Any

STOP_SIGNALS: tuple[signal.Signals, ...] = (signal.SIGINT, signal.SIGTERM)


class StopRequest:
    """A flag the step loop reads between steps: which signal asked the run to stop, if any."""

    def __init__(self) -> None:
        self.signum: int | None = None

    def request(self, signum: int) -> None:
        """Ask the run to stop at the end of the current step (the first request wins)."""
        if self.signum is None:
            self.signum = int(signum)

    @property
    def reason(self) -> str | None:
        """The signal's name (``"SIGINT"``), or None while nobody asked the run to stop."""
        return None if self.signum is None else signal.Signals(self.signum).name

    @property
    def exit_code(self) -> int:
        """``128 + signal number``: 130 for SIGINT, 143 for SIGTERM (0 when no signal came)."""
        return 0 if self.signum is None else 128 + self.signum


@contextmanager
def stop_on_signals(signals: tuple[signal.Signals, ...] = STOP_SIGNALS) -> Iterator[StopRequest]:
    """Route ``signals`` to a :class:`StopRequest` while the block runs; the old handlers come back after.

    The first signal of a kind sets the request and re-installs that signal's previous handler, so a second one
    acts as it would have without us. Outside the main thread (where Python cannot install handlers) the request
    is returned unwired.
    """
    stop = StopRequest()
    if threading.current_thread() is not threading.main_thread():
        yield stop
        return
    previous: dict[signal.Signals, Any] = {}

    def handler(signum: int, _frame: FrameType | None) -> None:
        stop.request(signum)
        sig = signal.Signals(signum)
        signal.signal(sig, previous[sig])

    for sig in signals:
        previous[sig] = signal.signal(sig, handler)
    try:
        yield stop
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)
