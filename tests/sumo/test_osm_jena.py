"""A whole real tram network from OpenStreetMap: Jena's eight tram lines (tests/data/osm/jena_tram_2014.osm.gz,
source and licence in the README there) imported with ``railsim network import``, and a tram of line 4 each way
run on it from ``railsim timetable import --from-lines``."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from tests.helpers import read_summary, run_railsim

JENA = Path(__file__).resolve().parents[1] / "data" / "osm" / "jena_tram_2014.osm.gz"

pytestmark = pytest.mark.sumo


def _ok(res: object) -> str:
    assert res.returncode == 0, res.stderr + res.stdout  # type: ignore[attr-defined]
    return str(res.stdout)  # type: ignore[attr-defined]


def test_jena_imports_as_a_multi_line_tram_network_and_line_4_runs_clean(tmp_path: Path) -> None:
    cache = tmp_path / "cache"
    world = tmp_path / "jena"
    out = _ok(run_railsim(["network", "import", str(JENA), "--out", str(world)], cache_dir=cache))
    assert "tram: 8 lines" in out
    lines = yaml.safe_load((world / "jena_tram_2014.lines.yaml").read_text(encoding="utf-8"))["lines"]
    assert {"1", "2", "3", "4", "5"} <= {line["ref"] for line in lines}
    stations = yaml.safe_load((world / "jena_tram_2014.stations.yaml").read_text(encoding="utf-8"))["stations"]
    assert len(stations) >= 40
    assert not any(
        s["name"].isdigit() for s in stations
    )  # six OSM stop positions have no name: named after their platform
    # lines 1-5 share the trunk through the centre: a station several lines serve is a merge of lines
    served_by: dict[str, set[str]] = {}
    for line in lines:
        for direction in line["directions"]:
            for station in direction["stations"]:
                served_by.setdefault(station, set()).add(line["ref"])
    assert len(served_by["Stadtzentrum Löbdergraben"] & {"1", "2", "3", "4", "5"}) >= 4

    scenario = tmp_path / "line4.yaml"
    args = ["timetable", "import", "--from-lines", "--headway-s", "600", "--lines", "4", "--world", str(world)]
    _ok(run_railsim([*args, "--from", "07:00", "--to", "07:10", "--out", str(scenario)], cache_dir=cache))
    _ok(run_railsim(["run", str(scenario), "--out", str(tmp_path / "run"), "--no-progress"], cache_dir=cache))
    summary = read_summary(tmp_path / "run")
    assert summary["status"] == "completed"
    assert summary["n_arrived"] == summary["n_trains"] == 2
    assert summary["n_stops_served"] == summary["n_stops_scheduled"] > 40
    assert summary["collisions"] == 0 and summary["sumo_collisions"] == 0 and summary["switch_violations"] == 0
