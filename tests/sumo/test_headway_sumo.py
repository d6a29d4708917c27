"""Minimum feasible headway search (railsim.studies.headway): the feasibility rule on rows, the conservative frontier, and a
real search on the small corridor checked against an independent scan of every grid headway run directly.

Here: the tests of it that run SUMO or a railsim child process; the others are in ``tests/unit/test_headway.py``.
"""

from __future__ import annotations

from pathlib import Path

from tests.helpers import run_railsim
from tests.unit.test_headway import BASE, PATHS


def test_cli_bad_path_exit_2(tmp_path: Path) -> None:
    res = run_railsim(
        ["min-headway", str(BASE), "--path", "services[4].departures.headway_s", "--lo", "30", "--hi", "60"],
        timeout=120,
    )
    assert res.returncode == 2
    assert res.stderr.strip() == (
        f"railsim: error: {BASE}: headway 30 s: override: services[4].departures.headway_s: "
        "index 4 out of range (services has 2 items)"
    )


def test_cli_reports_lower_bound_and_no_feasible_range(tmp_path: Path) -> None:
    # 150-180 s is easily feasible on the corridor: the answer is the range's lower end
    res = run_railsim(
        [
            "min-headway",
            str(BASE),
            "--path",
            PATHS[0],
            "--path",
            PATHS[1],
            "--lo",
            "150",
            "--hi",
            "180",
            "--tol",
            "30",
            "--max-delay",
            "60",
            "--confirm-seed",
            "9",
            "--out",
            str(tmp_path / "a"),
        ],
        timeout=300,
    )
    assert res.returncode == 0, res.stderr
    assert "**150 s** (the range's lower end" in res.stdout and "confirmed with seeds 9" in res.stdout
    # 20-30 s with a 10 s delay limit is not
    res = run_railsim(
        ["min-headway", str(BASE), "--path", PATHS[0], "--lo", "20", "--hi", "30", "--tol", "10", "--max-delay", "10"],
        timeout=300,
    )
    assert res.returncode == 1, res.stderr
    assert "No feasible headway in the range" in res.stdout
