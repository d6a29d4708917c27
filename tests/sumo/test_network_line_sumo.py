"""Line descriptions: validation messages a user sees, and the CLI's one-line errors (exit code 2).

Here: the tests of it that run SUMO or a railsim child process; the others are in ``tests/unit/test_network_line.py``.
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest
import yaml

from railsim.errors import ConfigError
from tests.unit.test_network_line import BAD_CASES, GOOD, _bad

REPO = Path(__file__).resolve().parents[2]


RAILSIM = REPO / ".venv" / "bin" / "railsim"


CLI_CASES = [
    c
    for c in BAD_CASES
    if c[0]
    in (
        "missing_station_id",
        "decreasing_chainage",
        "unknown_branch_target",
        "negative_length",
        "unknown_key",
        "wrong_type",
    )
]


@pytest.mark.parametrize("name,mutate,field,message", CLI_CASES, ids=[c[0] for c in CLI_CASES])
def test_cli_reports_bad_file_in_one_line_with_exit_code_2(tmp_path: Path, name, mutate, field, message) -> None:
    bad = tmp_path / f"{name}.yaml"
    bad.write_text(yaml.safe_dump(_bad(mutate), sort_keys=False))
    env = dict(os.environ, RAILSIM_CACHE=str(tmp_path / "cache"))
    proc = subprocess.run(
        [str(RAILSIM), "network", "build", str(bad), "--out", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr + proc.stdout
    assert proc.stderr.strip().splitlines() == [f"railsim: error: {bad}: {field}: {message}"]
    assert not (tmp_path / "out").exists()


def test_cli_yaml_syntax_error_and_unknown_world(tmp_path: Path) -> None:
    bad = tmp_path / "broken.yaml"
    bad.write_text("name: x\nstations: [\n")
    env = dict(os.environ, RAILSIM_CACHE=str(tmp_path / "cache"))
    proc = subprocess.run(
        [str(RAILSIM), "network", "build", str(bad), "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert proc.stderr.startswith(f"railsim: error: {bad}: expected valid YAML, got a syntax error (line 3")
    proc = subprocess.run(
        [str(RAILSIM), "network", "show", "atlantis"], capture_output=True, text=True, env=env, timeout=120
    )
    assert proc.returncode == 2
    assert proc.stderr.strip() == (
        "railsim: error: unknown world 'atlantis': expected a line-description file "
        "(.yaml) or one of chongqing_line3, straight_corridor, y_junction"
    )
    proc = subprocess.run(
        [str(RAILSIM), "network", "show", "y_junction", "-p", "S1=-4"],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert proc.returncode == 2
    assert proc.stderr.strip() == "railsim: error: world y_junction: params.S1: expected a number > 0, got -4"


def test_netconvert_failure_is_reported_with_its_own_message(tmp_path: Path, monkeypatch) -> None:
    import network
    from network import generator

    fake = tmp_path / "netconvert"
    fake.write_text("#!/bin/sh\necho 'Error: something netconvert did not like.' >&2\nexit 1\n")
    fake.chmod(0o755)
    monkeypatch.setattr(generator, "netconvert_binary", lambda: fake)
    monkeypatch.setenv("RAILSIM_CACHE", str(tmp_path / "cache"))
    path = tmp_path / "mini.yaml"
    path.write_text(yaml.safe_dump(GOOD))
    with pytest.raises(ConfigError) as info:
        network.build(path)
    assert str(info.value) == f"{path}: netconvert failed: Error: something netconvert did not like."
    assert not any((tmp_path / "cache" / "networks").iterdir())  # nothing half-built left in the cache
