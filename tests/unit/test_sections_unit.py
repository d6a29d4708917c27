"""Line sections read back from a real run (mini Y line: up/down trains, a coupled pair, a merging train).

Here: the tests of it that start no process; the others are in ``tests/sumo/test_sections.py``.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from railsim.analysis.sections import LineFrame, read_table, section_table
from railsim.errors import ConfigError


def test_missing_folder_and_table_are_config_errors(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="no such folder"):
        section_table(tmp_path / "nope")
    with pytest.raises(ConfigError, match="trips.csv or trips.parquet"):
        read_table(tmp_path, "trips")
    with pytest.raises(ConfigError, match="scenario.resolved.yaml"):
        LineFrame.from_run(tmp_path)
