"""The unit tier's hooks (``tests/unit/conftest.py``) fail the tests that break its two promises, end to end.

A child pytest runs a copy of the tier's conftest (its CPU budget lowered to 1 s) over five tests: one starts a
process, one swallows the refusal, one gets a process from a module-scoped fixture, one burns 2 s of CPU, one is
plain. Only the plain one may pass (the CPU burner's call passes, its teardown fails). It runs as a child process, so it lives in this tier, not in the unit tier.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from tests.helpers import ROOT

CASES = """
import subprocess, sys, time
import pytest

@pytest.fixture(scope="module")
def a_child():
    return subprocess.run([sys.executable, "-c", "pass"])

def test_starts_a_process():
    subprocess.run([sys.executable, "-c", "pass"])

def test_swallows_the_refusal():
    try:
        subprocess.run(["true"])
    except Exception:
        pass

def test_fixture_starts_a_process(a_child):
    pass

def test_burns_cpu():
    start = time.process_time()
    while time.process_time() - start < 2.0:
        pass

def test_plain():
    assert sum(range(10)) == 45
"""


def test_the_unit_hooks_fail_processes_and_cpu_hogs(tmp_path: Path) -> None:
    tier = tmp_path / "unit"
    tier.mkdir()
    conftest = (ROOT / "tests" / "unit" / "conftest.py").read_text(encoding="utf-8")
    assert "CPU_BUDGET_S = " in conftest
    lowered = "\n".join(
        "CPU_BUDGET_S = 1.0" if line.startswith("CPU_BUDGET_S = ") else line for line in conftest.splitlines()
    )
    (tier / "conftest.py").write_text(lowered + "\n", encoding="utf-8")
    (tier / "test_cases.py").write_text(CASES, encoding="utf-8")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p))
    res = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-rA", "-p", "no:cacheprovider", "-p", "no:xdist", str(tier)],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path,
        env=env,
    )
    out = res.stdout
    assert res.returncode == 1, out[-3000:]
    for outcome, name in (
        ("PASSED", "test_plain"),
        ("FAILED", "test_starts_a_process"),
        ("FAILED", "test_swallows_the_refusal"),
        ("ERROR", "test_fixture_starts_a_process"),
        ("ERROR", "test_burns_cpu"),  # its call passes; the budget check fails its teardown
    ):
        assert f"{outcome} unit/test_cases.py::{name}" in out, (outcome, name, out[-3000:])
    assert "caught the refusal" in out and "over the unit tier's budget of 1 s" in out, out[-3000:]
    assert "2 failed, 2 passed, 2 errors" in out, out[-3000:]
