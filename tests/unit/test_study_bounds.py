"""Studies are bounded and checked before they expand anything (railsim.studies.bounds, sweep spec, robustness)."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
import yaml

from railsim.errors import ConfigError
from railsim.studies.robustness import RobustnessPlan, check_plan
from railsim.studies.sweep import load_sweep
from tests.helpers import DATA

BASE = DATA / "scenarios" / "disturbed_line.yaml"


def _sweep(tmp_path: Path, **body: object) -> Path:
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump({"base": str(BASE), **body}), encoding="utf-8")
    return path


def test_a_million_case_grid_is_refused_in_under_two_seconds(tmp_path: Path) -> None:
    grid = {
        "services[0].dwell_s": list(range(10, 20)),
        "disturbances.incidents[0].hold_s": list(range(100, 110)),
        "simulation.duration_s": list(range(3000, 3010)),
        "services[0].departures.times[0]": [float(x) for x in range(10)],
        "services[0].departures.times[1]": [float(x) for x in range(120, 130)],
        "services[0].departures.times[2]": [float(x) for x in range(240, 250)],
    }
    path = _sweep(tmp_path, grid=grid, seeds=[1])
    t0 = time.perf_counter()
    with pytest.raises(ConfigError) as err:
        load_sweep(path)
    elapsed = time.perf_counter() - t0
    assert elapsed < 2.0, elapsed
    assert str(path) in str(err.value) and "1,000,000 cases" in str(err.value) and "RAILSIM_MAX_CASES" in str(err.value)


def test_the_case_limit_is_configurable(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = _sweep(tmp_path, grid={"services[0].dwell_s": [10, 20, 30]}, seeds=[1, 2])
    monkeypatch.setenv("RAILSIM_MAX_CASES", "5")
    with pytest.raises(ConfigError, match="6 cases exceed the limit of 5"):
        load_sweep(path)
    monkeypatch.setenv("RAILSIM_MAX_CASES", "6")
    assert len(load_sweep(path).cases) == 6


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ({"seeds": [2**31]}, "seeds[0]"),
        ({"seeds": [1], "timeout_s": 1e-9}, "timeout_s"),
        ({"seeds": [1], "timeout_s": float("nan")}, "timeout_s"),
    ],
)
def test_sweep_file_values_beyond_range_name_the_file_and_field(tmp_path: Path, body: dict, field: str) -> None:
    path = _sweep(tmp_path, **body)
    with pytest.raises(ConfigError) as err:
        load_sweep(path)
    assert str(err.value).startswith(f"{path}: {field}: expected")


def test_a_billion_robustness_runs_are_refused_at_once() -> None:
    t0 = time.perf_counter()
    with pytest.raises(ConfigError) as err:
        check_plan(RobustnessPlan(scenario=BASE, runs=1_000_000_000))
    assert time.perf_counter() - t0 < 1.0
    assert "--runs" in str(err.value) and "limit" in str(err.value)


def test_robustness_seeds_beyond_sumos_range_are_refused() -> None:
    with pytest.raises(ConfigError, match="--first-seed"):
        check_plan(RobustnessPlan(scenario=BASE, runs=10, first_seed=2**31 - 5))


def test_an_empty_row_file_does_not_block_resuming(tmp_path: Path) -> None:
    from railsim.studies.sweep.tables import read_rows, write_row

    write_row(tmp_path, "aaaaaaaaaaaa", {"case_id": "aaaaaaaaaaaa", "status": "ok"})
    (tmp_path / "rows" / "bbbbbbbbbbbb.json").write_bytes(b"")  # a row file a failed disk left empty
    (tmp_path / "rows" / "cccccccccccc.json").write_text("[1, 2]", encoding="utf-8")  # not a row
    assert list(read_rows(tmp_path)) == ["aaaaaaaaaaaa"]
