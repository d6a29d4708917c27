"""The executable's entry point (railsim/cli/launch.py): once the command has returned, a Ctrl-C has nothing to stop.

A SIGINT that came after the command finished but before the process was gone (the interpreter shutting down)
ended it *by the signal* — status -2, no line — although everything was done and written. The entry point now
ignores SIGINT from the moment the command returns; a Ctrl-C while the command runs is still one line and 130.
"""

from __future__ import annotations

import os
import signal
from collections.abc import Iterator

import pytest

from railsim.cli import launch


@pytest.fixture()
def sigint_restored() -> Iterator[None]:
    before = signal.getsignal(signal.SIGINT)
    yield
    signal.signal(signal.SIGINT, before)


def test_after_the_command_returns_a_ctrl_c_is_ignored(monkeypatch: pytest.MonkeyPatch, sigint_restored: None) -> None:
    import railsim.cli.main as cli_main

    signal.signal(signal.SIGINT, signal.default_int_handler)  # as an interactive Python starts
    monkeypatch.setattr(cli_main, "main", lambda: 0)
    assert launch.main() == 0
    assert signal.getsignal(signal.SIGINT) == signal.SIG_IGN
    os.kill(os.getpid(), signal.SIGINT)  # the Ctrl-C during shutdown: nothing happens (no KeyboardInterrupt)


def test_a_ctrl_c_while_the_command_runs_is_one_line_and_130(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], sigint_restored: None
) -> None:
    import railsim.cli.main as cli_main

    def command() -> int:
        os.kill(os.getpid(), signal.SIGINT)  # the Ctrl-C arrives while the command runs
        return 0

    signal.signal(signal.SIGINT, signal.default_int_handler)
    monkeypatch.setattr(cli_main, "main", command)
    exits: list[int] = []
    monkeypatch.setattr(os, "_exit", exits.append)  # launch leaves with os._exit(130) after flushing
    launch.main()
    assert exits == [launch.EXIT_INTERRUPTED]
    assert capsys.readouterr().err.strip().splitlines() == ["railsim: interrupted"]
