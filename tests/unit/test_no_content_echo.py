"""Messages never echo another file's content, and quote a user's value in at most 80 characters.

A scenario's ``world.line`` may name any file; one that is not a line description (a password file) must be
refused without printing anything of it. A 3,000-character station id is quoted cut to 80 characters.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from railsim.cli.main import main
from tests.helpers import DATA

SECRET = "secret:$6$Xq3bV9$kq1vEoS0bN0lJp2r5uQm4T7a8ZcYwHdGfE3sR6tU9iP0oL1kJ2hG:19000:0:99999:7:::"


def _scenario(tmp_path: Path, **changes: object) -> Path:
    data = yaml.safe_load((DATA / "scenarios" / "disturbed_line.yaml").read_text(encoding="utf-8"))
    data.update(changes)
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


@pytest.mark.parametrize("content", [f"{SECRET}\nroot:x:0:0::/root:/bin/bash\n", f"{SECRET}\n", "secret: hunter2\n"])
def test_world_line_at_a_foreign_file_prints_nothing_of_it(
    tmp_path: Path, content: str, capsys: pytest.CaptureFixture[str]
) -> None:
    shadow = tmp_path / "shadow"
    shadow.write_text(content, encoding="utf-8")
    rc = main(["validate", str(_scenario(tmp_path, world={"line": str(shadow)}))])
    err = capsys.readouterr().err
    assert rc == 2 and len(err.strip().splitlines()) == 1, err
    assert str(shadow) in err
    message = err.replace(str(shadow), "<FILE>").replace(str(tmp_path), "<TMP>")
    for piece in ("secret", "hunter2", "$6$", "19000", "root"):
        assert piece not in message, err


def test_a_3000_character_station_id_is_quoted_in_80(tmp_path: Path) -> None:
    from railsim import scenario
    from railsim.errors import ConfigError

    data = yaml.safe_load((DATA / "scenarios" / "disturbed_line.yaml").read_text(encoding="utf-8"))
    data["services"][0]["from"] = "Q" * 3000  # checked against the world's stations, then quoted back
    path = tmp_path / "long.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    scn = scenario.load(path)
    with pytest.raises(ConfigError) as err:
        scenario.check_against_world(scn, ["s1", "s2", "s3", "s4"], [])
    text = str(err.value).replace(str(path), "FILE")  # the file's own path is not user data (its length varies)
    assert err.value.field == "services[0].from"
    assert "Q" * 60 in text  # the id is quoted, cut short
    longest = max(len(tok) for tok in text.replace("'", " ").split())
    assert longest <= 80, (longest, len(text))


def test_an_apostrophe_is_not_a_quote_so_a_long_explanation_stays_whole() -> None:
    """A message that quotes a short value and says "the platform's edge" is not cut between the two marks (it was:
    the apostrophe closed a 'quote' that began at the closing mark of 'mid'); a long quoted value still is."""
    from railsim.errors import QUOTE_CHARS, bound_quotes

    why = "standing at 'mid' (" + "the platform's edge is too short for both trains; " * 3 + "shorten target_gap_m)"
    assert bound_quotes(why) == why
    cut = bound_quotes("got '" + "Q" * 3000 + "' instead")
    assert len(cut) < 3000 and "'" + "Q" * (QUOTE_CHARS - 5) + "...'" in cut and cut.endswith(" instead")
