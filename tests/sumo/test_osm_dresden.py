"""A third whole-line tram network from OpenStreetMap: four of Dresden's tram lines (3, 9, 10, 11;
tests/data/osm/dresden_tram_2025.osm.gz, source, licence and converter in the README there) imported with
``railsim network import``, and three of them (3 and 9 share the trunk Walpurgisstraße - Postplatz - Neustädter
Markt, 9 and 10 the stretch Lennéplatz - Gret-Palucca-Straße) run for an hour from ``railsim timetable import
--from-lines`` with rotations: units turn round the loops at Messe and Kaditz, and at Coschütz and Wilder Mann
(loop termini with one platform) depart from the platform they arrive at."""

from __future__ import annotations

import json
from pathlib import Path

import yaml

from tests.helpers import ok_stdout, read_csv, read_summary, run_railsim

DRESDEN = Path(__file__).resolve().parents[1] / "data" / "osm" / "dresden_tram_2025.osm.gz"


def test_dresden_imports_four_lines_and_three_run_clean_with_units_turning_round_the_loops(tmp_path: Path) -> None:
    cache = tmp_path / "cache"
    world = tmp_path / "dresden"
    out = ok_stdout(run_railsim(["network", "import", str(DRESDEN), "--out", str(world)], cache_dir=cache))
    assert "tram: 4 lines (10, 11, 3, 9), 105 stations" in out
    assert "bidi 0 % of the track" in out  # each direction has its own OSM track
    lines = yaml.safe_load((world / "dresden_tram_2025.lines.yaml").read_text(encoding="utf-8"))["lines"]
    served_by: dict[str, set[str]] = {}
    for line in lines:
        for direction in line["directions"]:
            for station in direction["stations"]:
                served_by.setdefault(station, set()).add(line["ref"])
    assert served_by["Postplatz"] == {"3", "9", "11"} and served_by["Lennéplatz"] == {"9", "10", "11"}

    scenario = tmp_path / "hour.yaml"
    args = ["timetable", "import", "--from-lines", "--headway-s", "900", "--lines", "3,9,10", "--world", str(world)]
    ok_stdout(run_railsim([*args, "--from", "07:00", "--to", "08:00", "--out", str(scenario)], cache_dir=cache))
    ok_stdout(run_railsim(["run", str(scenario), "--out", str(tmp_path / "run"), "--no-progress"], cache_dir=cache))
    summary = read_summary(tmp_path / "run")
    assert summary["status"] == "completed"
    assert summary["n_arrived"] == summary["n_trains"] == 24
    assert summary["n_stops_served"] == summary["n_stops_scheduled"] == 728
    assert summary["collisions"] == 0 and summary["sumo_collisions"] == 0 and summary["switch_violations"] == 0
    stops = read_csv(tmp_path / "run" / "stops.csv")
    visits = [(row["trip_id"], row["station"]) for row in stops]
    twice = {station for trip, station in set(visits) if visits.count((trip, station)) > 1}
    assert twice == {"lenneplatz"}  # once at every station (no copied platform) but where OSM's line 9 has two
    turns = {(t["station"], t["from_trip"].split("_")[0]) for t in summary["fleet"]["turnbacks"]}
    # the loops the routes reach: round the loop to the departure platform at Messe and Kaditz; line 3's units
    # arrive at the very platform they leave from at Coschütz and Wilder Mann and depart where they stand
    assert turns == {
        ("messe-gleisschleife", "10"),
        ("kaditz-riegelplatz", "9"),
        ("coschutz", "3"),
        ("wilder-mann", "3"),
    }
    events = read_csv(tmp_path / "run" / "events.csv")
    in_place = {
        json.loads(e["detail"])["station"]
        for e in events
        if e["kind"] == "unit_turnback" and json.loads(e["detail"]).get("in_place")
    }
    assert in_place == {"coschutz", "wilder-mann"}
