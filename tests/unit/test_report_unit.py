"""``railsim report``: one Markdown or self-contained HTML page for a run or a sweep, from real outputs.

Here: the tests of it that start no process; the others are in ``tests/sumo/test_report.py``.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from railsim.cli.main import main as cli_main


def test_report_mistakes_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert cli_main(["report", str(tmp_path / "nope")]) == 2
    err = capsys.readouterr().err
    assert str(tmp_path / "nope") in err and err.count("\n") == 1
    (tmp_path / "half").mkdir()
    (tmp_path / "half" / "trips.csv").write_text("trip_id\n")
    assert cli_main(["report", str(tmp_path / "half")]) == 2
    assert "summary.json" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        cli_main(["report", str(tmp_path), "--format", "pdf"])
    assert exc.value.code == 2
