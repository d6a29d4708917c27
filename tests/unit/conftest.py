"""The unit tier's two promises, checked on every test in ``tests/unit/``: it starts no process, and it is cheap.

No process. Setup, call and teardown of each test run inside :func:`tests.process_guard.forbid_processes`: a
``subprocess``, ``fork``, ``multiprocessing`` child, or libsumo/traci import or start raises
:class:`~tests.process_guard.ProcessStarted`, and an attempt the test swallowed (a broad ``except``) still fails it
afterwards. The guard wraps the runtest hooks rather than sitting in a fixture so a module- or session-scoped
fixture of the tier is held to the promise too.

Cheap. A test may use at most :data:`CPU_BUDGET_S` seconds of CPU (``time.process_time``: this process's CPU,
its threads included) over setup, call and teardown. CPU time, not wall time: a loaded shared machine stretches
wall time several-fold but barely changes the CPU a test needs, so the check does not flake under load. Each
test's CPU goes into its report (``user_properties``) and ``tests/conftest.py`` prints the tier's total and its
heaviest tests at the end of the run.

The budget, from measurements on the shared 2-core machine under load: the tier's ~810 tests use ~160 s of CPU
in all; the median test 2.5 ms; the heaviest (closed-loop MPC, PSO statistics) 7-12 s with numba's kernels
already compiled. On a fresh clone numba compiles its kernels (cached on disk after) inside the first test that
reaches them: the mcf/opo optimiser test then used 21.7-24.1 s. :data:`CPU_BUDGET_S` = 40 s is 1.7 times that
cold worst case, room for a slower CPU, and still fails a test that has grown a simulation (a minutes-long
closed loop, a day of service in pure Python): such a test belongs in ``tests/long/`` or needs a smaller case.
The tier's total and its heaviest tests are printed at the end of every run that includes it.
"""

from __future__ import annotations

import time
from collections.abc import Generator, Iterator
from contextlib import contextmanager

import pytest

from tests.process_guard import ProcessStarted, forbid_processes

CPU_BUDGET_S = 40.0
CPU_KEY = pytest.StashKey[float]()
HITS_KEY = pytest.StashKey[list[str]]()


@contextmanager
def _guarded_phase(item: pytest.Item) -> Iterator[None]:
    """One runtest phase under the guard, its CPU added to the item's total."""
    hits = item.stash.setdefault(HITS_KEY, [])
    start = time.process_time()
    try:
        with forbid_processes(hits.append):
            yield
    finally:
        item.stash[CPU_KEY] = item.stash.get(CPU_KEY, 0.0) + time.process_time() - start


@pytest.hookimpl(wrapper=True)
def pytest_runtest_setup(item: pytest.Item) -> Generator[None, None, None]:
    with _guarded_phase(item):
        return (yield)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item: pytest.Item) -> Generator[None, None, None]:
    with _guarded_phase(item):
        result = yield
    _fail_on_swallowed(item)
    return result


@pytest.hookimpl(wrapper=True)
def pytest_runtest_teardown(item: pytest.Item, nextitem: pytest.Item | None) -> Generator[None, None, None]:
    with _guarded_phase(item):
        result = yield
    used = item.stash.get(CPU_KEY, 0.0)
    item.user_properties += [("cpu_s", round(used, 3)), ("cpu_budget_s", CPU_BUDGET_S)]
    if used > CPU_BUDGET_S:
        raise AssertionError(
            f"{item.nodeid} used {used:.1f} s of CPU, over the unit tier's budget of {CPU_BUDGET_S:.0f} s "
            "(tests/unit/conftest.py): make the case smaller, or move the test to tests/long/"
        )
    return result


def _fail_on_swallowed(item: pytest.Item) -> None:
    hits = item.stash.get(HITS_KEY, [])
    if hits:
        raise ProcessStarted(f"{item.nodeid} tried to start a process ({', '.join(hits)}) and caught the refusal")
