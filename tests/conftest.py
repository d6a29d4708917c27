"""pytest configuration shared by the suite.

Hypothesis: no per-example deadline (a loaded 2-core machine makes timing deadlines flaky); under CI
(``CI=true``) examples are derandomized so a CI run is reproducible — local runs keep exploring.

Numpy floating-point warnings (``invalid value``, ``divide by zero``, ``overflow encountered``) are errors: in
this process through ``filterwarnings`` in ``pyproject.toml``, and in every child process a test starts (each
SUMO run) through :data:`FP_WARNINGS_AS_ERRORS` in ``PYTHONWARNINGS``, set here before any child starts. A NaN
born in the step loop then fails the run that made it instead of flowing silently into a command.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

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


@pytest.fixture(scope="session")
def mini_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One SUMO run of ``tests/data/scenarios/mini_line.yaml`` (small Y line, a coupled pair) shared by the tests
    that analyse a finished run (sections, capacity); read-only for them."""
    from tests.helpers import DATA, run_railsim

    cache = tmp_path_factory.mktemp("netcache")
    out = tmp_path_factory.mktemp("mini")
    res = run_railsim(
        ["run", str(DATA / "scenarios" / "mini_line.yaml"), "--out", str(out), "--no-progress"], cache_dir=cache
    )
    assert res.returncode == 0, res.stderr + res.stdout
    return out
