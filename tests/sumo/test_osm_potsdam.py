"""A second whole tram network from OpenStreetMap: Potsdam's seven tram lines (tests/data/osm/potsdam_tram_2025.osm.gz,
source and licence in the README there) imported with ``railsim network import``, and three of its lines through
the shared trunk (Platz der Einheit, Potsdam Hauptbahnhof) run from ``railsim timetable import --from-lines``."""

from __future__ import annotations

from pathlib import Path

import yaml

from tests.helpers import ok_stdout, read_csv, read_summary, run_railsim

POTSDAM = Path(__file__).resolve().parents[1] / "data" / "osm" / "potsdam_tram_2025.osm.gz"


def test_potsdam_imports_as_a_multi_line_tram_network_and_three_lines_run_clean(tmp_path: Path) -> None:
    cache = tmp_path / "cache"
    world = tmp_path / "potsdam"
    out = ok_stdout(run_railsim(["network", "import", str(POTSDAM), "--out", str(world)], cache_dir=cache))
    assert "tram: 7 lines (91, 92, 93, 94, 96, 98, 99), 68 stations" in out
    lines = yaml.safe_load((world / "potsdam_tram_2025.lines.yaml").read_text(encoding="utf-8"))["lines"]
    served_by: dict[str, set[str]] = {}
    for line in lines:
        for direction in line["directions"]:
            for station in direction["stations"]:
                served_by.setdefault(station, set()).add(line["ref"])
    assert len(served_by) >= 40
    assert served_by["Platz der Einheit/West"] == {"91", "92", "93", "94", "96", "98", "99"}  # the lines merge

    scenario = tmp_path / "peak.yaml"
    args = ["timetable", "import", "--from-lines", "--headway-s", "600", "--lines", "91,94,99", "--world", str(world)]
    ok_stdout(run_railsim([*args, "--from", "07:00", "--to", "07:20", "--out", str(scenario)], cache_dir=cache))
    ok_stdout(run_railsim(["run", str(scenario), "--out", str(tmp_path / "run"), "--no-progress"], cache_dir=cache))
    summary = read_summary(tmp_path / "run")
    assert summary["status"] == "completed"
    assert summary["n_arrived"] == summary["n_trains"] == 24
    assert summary["n_stops_served"] == summary["n_stops_scheduled"] > 400
    assert summary["collisions"] == 0 and summary["sumo_collisions"] == 0 and summary["switch_violations"] == 0
    stations = {row["station"] for row in read_csv(tmp_path / "run" / "stops.csv")}
    assert {"platz-der-einheit-west", "waldstrasse-horstweg"} <= stations  # ß written ss in station ids
