"""A guard that makes starting a process (or SUMO) inside a test an error.

The unit tier (``tests/unit/``) promises that no test in it starts a process: no ``subprocess``, no ``fork``, no
``multiprocessing`` child, no SUMO through libsumo or traci. That promise is what keeps the tier fast, so it is
checked, not trusted: :func:`forbid_processes` replaces every door through which CPython starts a process with
one that raises :class:`ProcessStarted`, and ``tests/unit/conftest.py`` puts it around every unit test.

The doors, from the top of the stack down (a test reaching any of them fails with the door's name):

- ``subprocess.Popen._execute_child`` — ``subprocess.run``/``check_output``/``Popen`` and ``os.popen``;
- ``_posixsubprocess.fork_exec`` — what ``subprocess`` and ``multiprocessing``'s spawn/forkserver start with;
- ``os.fork``, ``os.forkpty``, ``os.posix_spawn``, ``os.posix_spawnp``, ``os.system``, ``os.spawnv*`` — the raw
  calls (``multiprocessing``'s fork start method calls ``os.fork``);
- ``multiprocessing.process.BaseProcess.start`` — a ``Process``, a ``Pool`` or a ``ProcessPoolExecutor`` child,
  refused before it picks a start method;
- libsumo and traci: ``start``, ``load`` and ``simulationStep`` on whichever of them is imported, and importing
  either while the guard is up (an import hook), because SUMO runs in-process under libsumo — a crash there takes
  the test runner with it.

The guard also calls ``on_start(door)`` before raising, so a caller can count attempts a test swallowed with a
broad ``except``.
"""

from __future__ import annotations

import _posixsubprocess
import importlib.abc
import importlib.machinery
import multiprocessing.process
import os
import subprocess
import sys
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from types import ModuleType
from typing import Any

import pytest

# SUMO's in-process bindings: importing one of these, or starting/stepping a simulation through it, is a SUMO run
SUMO_MODULES = ("libsumo", "traci")
SUMO_ENTRY_POINTS = ("start", "load", "simulationStep")
OS_DOORS = (
    "fork",
    "forkpty",
    "posix_spawn",
    "posix_spawnp",
    "system",
    "spawnv",
    "spawnve",
    "spawnvp",
    "spawnvpe",
)


class ProcessStarted(AssertionError):
    """A test in a tier that forbids processes tried to start one (the message names the door it used)."""


class _SumoImportBlocker(importlib.abc.MetaPathFinder):
    """Refuses to import libsumo/traci (they are not loaded yet, and loading them is the start of a SUMO run)."""

    def __init__(self, refuse: Callable[[str], None]) -> None:
        self._refuse = refuse

    def find_spec(
        self, fullname: str, path: Sequence[str] | None = None, target: ModuleType | None = None
    ) -> importlib.machinery.ModuleSpec | None:
        if fullname.split(".")[0] in SUMO_MODULES:
            self._refuse(f"import {fullname}")
        return None


@contextmanager
def forbid_processes(on_start: Callable[[str], None] = lambda door: None) -> Iterator[None]:
    """Within the block, every way of starting a process or SUMO raises :class:`ProcessStarted`."""

    def refuse(door: str) -> None:
        on_start(door)
        raise ProcessStarted(
            f"{door}: a test in this tier may not start a process or SUMO "
            "(move it to tests/sumo/, or split the part that runs SUMO from the part that does not)"
        )

    def door(name: str) -> Callable[..., Any]:
        def refused(*_args: Any, **_kwargs: Any) -> Any:
            refuse(name)

        return refused

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(subprocess.Popen, "_execute_child", door("subprocess.Popen"))
        mp.setattr(_posixsubprocess, "fork_exec", door("_posixsubprocess.fork_exec"))
        for name in OS_DOORS:
            if hasattr(os, name):
                mp.setattr(os, name, door(f"os.{name}"))
        mp.setattr(multiprocessing.process.BaseProcess, "start", door("multiprocessing Process.start"))
        for module_name in SUMO_MODULES:
            module = sys.modules.get(module_name)
            for entry in SUMO_ENTRY_POINTS if module is not None else ():
                if hasattr(module, entry):
                    mp.setattr(module, entry, door(f"{module_name}.{entry}"))
        blocker = _SumoImportBlocker(refuse)
        sys.meta_path.insert(0, blocker)
        try:
            yield
        finally:
            sys.meta_path.remove(blocker)
