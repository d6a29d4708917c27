"""``railsim validate``: every kind of broken scenario gives one exact line on stderr and exit code 2.

Here: the tests of it that run SUMO or a railsim child process; the others are in ``tests/unit/test_scenario_cli.py``.
"""

from __future__ import annotations

import json
import os
import subprocess

import pytest

from railsim.physics.vehicle import preset_names

# (importing the unit module also puts tests/data/plugins on sys.path and registers the test controllers)
from tests.unit.test_scenario_cli import BROKEN, EXPECTED, PLUGINS, REPO, VALID

RAILSIM = REPO / ".venv" / "bin" / "railsim"


PYTHON = REPO / ".venv" / "bin" / "python"


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(PLUGINS), env.get("PYTHONPATH", "")) if p)
    return env


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(RAILSIM), *args], cwd=REPO, env=_env(), capture_output=True, text=True, timeout=120)


@pytest.fixture(scope="module")
def registered_in_subprocess() -> str:
    """The controller names a fresh `railsim` process knows (built-ins, whatever exists of them, + test ones)."""
    out = subprocess.run(
        [str(PYTHON), "-c", "import json, controllers; print(json.dumps(sorted(controllers.registered())))"],
        cwd=REPO,
        env=_env(),
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    )
    names = json.loads(out.stdout)
    assert {"_test_ctrl", "_test_follow"} <= set(names)
    return ", ".join(names)


@pytest.mark.parametrize("stem", sorted(EXPECTED))
def test_validate_rejects_broken_file(stem: str, registered_in_subprocess: str) -> None:
    path = BROKEN / f"{stem}.yaml"
    message = EXPECTED[stem].replace("{presets}", ", ".join(preset_names()))
    message = message.replace("{registered}", registered_in_subprocess)
    proc = _run("validate", str(path), "--no-world-check")
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr == f"railsim: error: {path}: {message}\n"
    assert "Traceback" not in proc.stderr and proc.stdout == ""


def test_validate_missing_file() -> None:
    proc = _run("validate", "tests/data/broken/no_such_file.yaml", "--no-world-check")
    assert proc.returncode == 2
    assert proc.stderr == "railsim: error: tests/data/broken/no_such_file.yaml: file not found\n"


def test_validate_valid_file() -> None:
    proc = _run("validate", str(VALID), "--no-world-check")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == "ok: cq3_peak_test: 2 services, 53 trips, 2 formations\n"
    assert proc.stderr == ""
