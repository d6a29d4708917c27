"""The unit tier's guard trips: every way of starting a process or SUMO raises inside ``forbid_processes``.

Each door is tried for real inside the guard (a real ``subprocess.run``, ``os.fork``, ``multiprocessing`` start,
libsumo import and start); had the guard missed one, the test would start a process and fail its ``raises``.
The tier's own guard (``tests/unit/conftest.py``) stays up around these tests; the inner guard patches over it,
so each refusal is the inner one's. The last test checks the conftest wires it and the CPU budget to this tier.
"""

from __future__ import annotations

import multiprocessing
import os
import subprocess
import sys
import types

import pytest

from tests.process_guard import ProcessStarted, forbid_processes


def test_subprocess_is_refused_and_reported() -> None:
    seen: list[str] = []
    with forbid_processes(seen.append), pytest.raises(ProcessStarted, match="subprocess.Popen"):
        subprocess.run([sys.executable, "-c", "pass"], check=False)
    assert seen == ["subprocess.Popen"]


def test_os_popen_and_system_are_refused() -> None:
    with forbid_processes(), pytest.raises(ProcessStarted):
        os.popen("true")
    with forbid_processes(), pytest.raises(ProcessStarted, match="os.system"):
        os.system("true")


def test_fork_and_spawn_are_refused() -> None:
    with forbid_processes(), pytest.raises(ProcessStarted, match="os.fork"):
        os.fork()
    with forbid_processes(), pytest.raises(ProcessStarted, match="os.posix_spawn"):
        os.posix_spawn(sys.executable, [sys.executable, "-c", "pass"], dict(os.environ))


@pytest.mark.parametrize("method", ["fork", "spawn", "forkserver"])
def test_multiprocessing_start_is_refused(method: str) -> None:
    process = multiprocessing.get_context(method).Process(target=print)
    with forbid_processes(), pytest.raises(ProcessStarted, match="multiprocessing"):
        process.start()


def test_importing_libsumo_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delitem(sys.modules, "libsumo", raising=False)
    with forbid_processes(), pytest.raises(ProcessStarted, match="import libsumo"):
        import libsumo  # noqa: F401


def test_starting_an_imported_libsumo_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    started: list[list[str]] = []
    fake = types.ModuleType("libsumo")
    fake.start = started.append  # type: ignore[attr-defined]
    fake.simulationStep = lambda: None  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "libsumo", fake)
    with forbid_processes():
        with pytest.raises(ProcessStarted, match="libsumo.start"):
            fake.start(["sumo"])
        with pytest.raises(ProcessStarted, match="libsumo.simulationStep"):
            fake.simulationStep()
    fake.start(["after"])  # the guard restores what it patched
    assert started == [["after"]]


def test_the_guard_restores_every_door() -> None:
    before = (subprocess.Popen._execute_child, os.fork, multiprocessing.process.BaseProcess.start, len(sys.meta_path))
    with forbid_processes():
        pass
    after = (subprocess.Popen._execute_child, os.fork, multiprocessing.process.BaseProcess.start, len(sys.meta_path))
    assert after == before


def test_the_unit_tier_runs_under_the_guard_and_the_budget(request: pytest.FixtureRequest) -> None:
    # the tier's hooks patched the doors for this very test: what subprocess would call is the refusing stand-in
    assert subprocess.Popen._execute_child.__name__ == "refused"
    assert request.node.get_closest_marker("unit") is not None
    from tests.unit import conftest

    assert 1.0 <= conftest.CPU_BUDGET_S <= 60.0
