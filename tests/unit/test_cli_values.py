"""Bad command-line values: one line, exit 2, never a traceback or exit 4 (railsim.cli.values)."""

from __future__ import annotations

import pytest

from railsim.cli.main import main


@pytest.mark.parametrize(
    "argv",
    [
        ["run", "s.yaml", "--out", "o", "--seed", "-5"],
        ["run", "s.yaml", "--out", "o", "--seed", str(2**31)],
        ["run", "s.yaml", "--out", "o", "--seed", "1e3"],
        ["sweep", "s.yaml", "--out", "o", "--timeout", "nan"],
        ["sweep", "s.yaml", "--out", "o", "--timeout", "1e-9"],
        ["sweep", "s.yaml", "--out", "o", "--workers", "0"],
        ["min-headway", "s.yaml", "--path", "p", "--lo", "1", "--hi", "2", "--timeout", "inf"],
        ["robustness", "s.yaml", "--out", "o", "--runs", "1000000000"],
        ["robustness", "s.yaml", "--out", "o", "--first-seed", str(2**31)],
        ["run", "s\x00.yaml", "--out", "o"],
        ["run", "s.yaml", "--out", "o\x00x"],
        ["validate", ""],
        ["network", "import", "x.osm", "--out", "w", "--platform-m", "-3"],
        ["network", "import", "x.osm", "--out", "w", "--platform-m", "nan"],
    ],
)
def test_bad_cli_value_is_one_line_exit_2(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert err.startswith("railsim: error: argument") and "expected" in err
    assert "\x00" not in err
