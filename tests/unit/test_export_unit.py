"""``railsim export``: a run's tables (or a sweep's cases) as CSV, Parquet and JSON, each read by pandas in one line.

Here: the tests of it that start no process; the others are in ``tests/sumo/test_export.py``.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from railsim.record import output
from railsim.report import export
from tests.sumo.test_export import _cli_error, _read_back


def test_sweep_folder_exports_its_cases(tmp_path: Path) -> None:
    sweep = tmp_path / "sweep"
    rows = [
        {
            "case_id": "a1",
            "status": "ok",
            "error": "",
            "seed": 1,
            "services[0].departures.headway_s": 60.0,
            "wall_s": 2.5,
            "collisions": 0,
            "min_gap_m": 21.5,
        },
        {
            "case_id": "b2",
            "status": "failed",
            "error": "boom",
            "seed": 1,
            "services[0].departures.headway_s": 45.0,
            "wall_s": 0.5,
            "collisions": None,
            "min_gap_m": None,
        },
    ]
    columns = list(rows[0])
    output.write_csv(sweep / "cases.csv", rows, columns)
    output.write_parquet(sweep / "cases.parquet", rows, columns)
    for fmt in export.FORMATS:
        (path,) = export.export(sweep, fmt, tmp_path / fmt)
        assert path.name == f"cases.{fmt}"
        back = _read_back(path, fmt)
        assert list(back.columns) == columns
        assert list(back["case_id"]) == ["a1", "b2"]
        assert back["min_gap_m"].iloc[0] == 21.5 and pd.isna(back["min_gap_m"].iloc[1])


def test_missing_folder_exits_2_naming_it(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    err = _cli_error(["export", str(tmp_path / "nope")], capsys)
    assert str(tmp_path / "nope") in err


def test_folder_without_tables_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "empty").mkdir()
    err = _cli_error(["export", str(tmp_path / "empty")], capsys)
    assert "not a railsim run folder" in err
