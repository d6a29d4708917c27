"""pytest configuration shared by the suite: tiers, the world cache, shared runs, warnings.

Tiers by folder. Every test file lives in one of four folders, and its folder sets its markers
(:func:`pytest_collection_modifyitems`), so no test can forget one:

* ``tests/unit/`` (marker ``unit``): no process started — ``tests/unit/conftest.py`` fails any test that starts
  one (``tests/process_guard.py``) or uses more than its CPU budget. ``make check`` runs lint and this tier.
* ``tests/sumo/`` (``sumo``): runs SUMO or a railsim child process; one short run per behaviour.
* ``tests/golden/`` (``golden``): the byte-for-byte golden runs and the checks read from them.
* ``tests/long/`` (``long`` and ``slow``): fuzz campaigns, studies, the README's commands; minutes each.

A test file anywhere else is a collection error. ``make test`` runs every tier.

One world cache per test session. Building a world (netconvert) takes seconds to tens of seconds, so every test
of a session — every xdist worker and every child process they start — shares one cache,
:func:`tests.helpers.session_shared_dir` ``/railsim-cache``, through ``RAILSIM_CACHE`` (:func:`world_cache`). The cache
publishes a built world atomically (``network/build.py``), so two workers building one world at once both get a
whole one. A test about the cache itself sets its own folder.

Shared runs. A run several tests read is made once per session, whichever worker asks first, under a file lock
(:func:`tests.helpers.shared_run`): the others wait and read the same folder.

Hypothesis: no per-example deadline (a loaded 2-core machine makes timing deadlines flaky); under CI
(``CI=true``) examples are derandomized so a CI run is reproducible — local runs keep exploring.

Numpy floating-point warnings (``invalid value``, ``divide by zero``, ``overflow encountered``) are errors: in
this process through ``filterwarnings`` in ``pyproject.toml``, and in every child process a test starts (each
SUMO run) through :data:`FP_WARNINGS_AS_ERRORS` in ``PYTHONWARNINGS``, set here before any child starts. A NaN
born in the step loop then fails the run that made it instead of flowing silently into a command.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

# This process runs railsim's interpreted modules, the readable reference: unit tests hand engine functions
# stand-ins (a namespace for a train) that the compiled core's classes would refuse. Its children — every SUMO run,
# the golden tier's included — run the compiled core when it is built (railsim/native.py): RAILSIM_NATIVE is set
# only while railsim imports here, and the environment the children inherit is the caller's.
_NATIVE_ENV = os.environ.get("RAILSIM_NATIVE")
os.environ["RAILSIM_NATIVE"] = "0"
import railsim  # noqa: E402, F401

if _NATIVE_ENV is None:
    del os.environ["RAILSIM_NATIVE"]
else:
    os.environ["RAILSIM_NATIVE"] = _NATIVE_ENV

from tests.helpers import session_shared_dir, shared_run  # noqa: E402

settings.register_profile("local", deadline=None)
settings.register_profile(
    "ci", deadline=None, derandomize=True, print_blob=True, suppress_health_check=[HealthCheck.too_slow]
)
settings.load_profile("ci" if os.environ.get("CI", "").lower() in ("1", "true", "yes") else "local")

# numpy's floating-point RuntimeWarnings (their messages start with these words) become exceptions in children
FP_WARNINGS_AS_ERRORS = ",".join(
    f"error:{start}:RuntimeWarning" for start in ("invalid value encountered", "divide by zero", "overflow encountered")
)
os.environ["PYTHONWARNINGS"] = ",".join(p for p in (os.environ.get("PYTHONWARNINGS"), FP_WARNINGS_AS_ERRORS) if p)


TESTS = Path(__file__).resolve().parent
TIERS = ("unit", "sumo", "golden", "long")
SLOW_TIERS = ("long",)


def tier_of(path: Path) -> str | None:
    """The tier of a test file: the first folder under ``tests/``, if it is one of :data:`TIERS`."""
    try:
        parts = path.resolve().relative_to(TESTS).parts
    except ValueError:
        return None
    return parts[0] if len(parts) > 1 and parts[0] in TIERS else None


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark every test with its folder's tier (and ``slow`` in the long tier); refuse a test outside the tiers."""
    for item in items:
        tier = tier_of(item.path)
        if tier is None:
            raise pytest.UsageError(
                f"{item.path}: a test file must live in one of tests/{{{','.join(TIERS)}}}/ (its folder is its tier)"
            )
        declared = {m.name for m in item.iter_markers() if m.name in (*TIERS, "slow")}
        if declared:
            raise pytest.UsageError(
                f"{item.nodeid}: marks {sorted(declared)} by hand; the tier markers come from the folder only"
            )
        item.add_marker(tier)
        if tier in SLOW_TIERS:
            item.add_marker("slow")


@pytest.fixture(scope="session", autouse=True)
def world_cache(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """The session's world cache, in ``RAILSIM_CACHE`` for this process and every child a test starts."""
    cache = session_shared_dir(tmp_path_factory) / "railsim-cache"
    cache.mkdir(exist_ok=True)
    old = os.environ.get("RAILSIM_CACHE")
    os.environ["RAILSIM_CACHE"] = str(cache)
    yield cache
    if old is None:
        os.environ.pop("RAILSIM_CACHE", None)
    else:
        os.environ["RAILSIM_CACHE"] = old


@pytest.fixture(scope="session")
def mini_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One SUMO run of ``tests/data/scenarios/mini_line.yaml`` (small Y line, a coupled pair) shared by the tests
    that analyse a finished run (sections, capacity, engine outputs); read-only for them."""
    from tests.helpers import DATA, run_railsim

    def make(out: Path) -> None:
        res = run_railsim(["run", str(DATA / "scenarios" / "mini_line.yaml"), "--out", str(out), "--no-progress"])
        assert res.returncode == 0, res.stderr + res.stdout
        assert "Traceback" not in res.stderr

    return shared_run(tmp_path_factory, "mini_run", make)


# The unit tier's CPU, as its tests report it (tests/unit/conftest.py puts ``cpu_s`` in each report); collected
# here, in the process that prints the summary (under xdist: the controller, from the workers' reports).
_UNIT_CPU_S: dict[str, float] = {}
_UNIT_CPU_BUDGET_S: list[float] = []


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    if report.when != "teardown":
        return
    props = dict(report.user_properties)
    if "cpu_s" in props:
        _UNIT_CPU_S[report.nodeid] = float(props["cpu_s"])
        _UNIT_CPU_BUDGET_S[:] = [float(props["cpu_budget_s"])]


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    """The unit tier's total CPU and its five heaviest tests (what the per-test budget is measured against)."""
    if not _UNIT_CPU_S:
        return
    total = sum(_UNIT_CPU_S.values())
    budget = f"; budget {_UNIT_CPU_BUDGET_S[0]:.0f} s per test" if _UNIT_CPU_BUDGET_S else ""
    terminalreporter.write_sep("-", f"unit tier: {len(_UNIT_CPU_S)} tests, {total:.1f} s of CPU in all{budget}")
    for nodeid, cpu_s in sorted(_UNIT_CPU_S.items(), key=lambda kv: -kv[1])[:5]:
        terminalreporter.write_line(f"{cpu_s:7.2f} s CPU  {nodeid}")
