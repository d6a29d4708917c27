"""A whole real tram network from OpenStreetMap: Jena's eight tram lines (tests/data/osm/jena_tram_2014.osm.gz,
source and licence in the README there) imported with ``railsim network import``, and a tram of line 4 each way
run on it from ``railsim timetable import --from-lines``."""

from __future__ import annotations

import csv
from pathlib import Path

import yaml

from tests.helpers import ok_stdout, read_summary, run_railsim

JENA = Path(__file__).resolve().parents[1] / "data" / "osm" / "jena_tram_2014.osm.gz"


def test_jena_imports_as_a_multi_line_tram_network_and_line_4_runs_clean(tmp_path: Path) -> None:
    cache = tmp_path / "cache"
    world = tmp_path / "jena"
    out = ok_stdout(run_railsim(["network", "import", str(JENA), "--out", str(world)], cache_dir=cache))
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
    ok_stdout(run_railsim([*args, "--from", "07:00", "--to", "07:10", "--out", str(scenario)], cache_dir=cache))
    ok_stdout(run_railsim(["run", str(scenario), "--out", str(tmp_path / "run"), "--no-progress"], cache_dir=cache))
    summary = read_summary(tmp_path / "run")
    assert summary["status"] == "completed"
    assert summary["n_arrived"] == summary["n_trains"] == 2
    assert summary["n_stops_served"] == summary["n_stops_scheduled"] == 40
    assert summary["collisions"] == 0 and summary["sumo_collisions"] == 0 and summary["switch_violations"] == 0


def test_jena_line_5_trams_leave_their_single_track_terminus_at_once(tmp_path: Path) -> None:
    """Line 5 ends at Ernst-Abbe-Platz on a single bidi track. The tram that starts there while the opposing tram
    is still on the line (5 min behind it) must leave at its departure time. SUMO's block-based insertion (rail
    signal classes including tram) kept it in SUMO's queue until the opposing tram had cleared the line, while it
    held the single-track section in railsim's books: the opposing tram then waited for it and the run stalled
    with 0/2 arrived."""
    cache = tmp_path / "cache"
    world = tmp_path / "jena"
    ok_stdout(run_railsim(["network", "import", str(JENA), "--out", str(world)], cache_dir=cache))
    scenario = tmp_path / "line5.yaml"
    args = ["timetable", "import", "--from-lines", "--headway-s", "600", "--lines", "5", "--world", str(world)]
    ok_stdout(run_railsim([*args, "--from", "07:00", "--to", "07:10", "--out", str(scenario)], cache_dir=cache))
    ok_stdout(run_railsim(["run", str(scenario), "--out", str(tmp_path / "run"), "--no-progress"], cache_dir=cache))
    summary = read_summary(tmp_path / "run")
    assert summary["status"] == "completed"
    assert summary["n_arrived"] == summary["n_trains"] == 2
    assert summary["n_stops_served"] == summary["n_stops_scheduled"] == 24
    assert summary["collisions"] == 0 and summary["sumo_collisions"] == 0 and summary["switch_violations"] == 0
    events = list(csv.DictReader((tmp_path / "run" / "events.csv").open(encoding="utf-8")))
    inserted = {e["subject"]: float(e["t_s"]) for e in events if e["kind"] == "train_inserted"}
    departed = {e["subject"]: float(e["t_s"]) for e in events if e["kind"] == "train_departed"}
    assert inserted.keys() == departed.keys() and len(inserted) == 2
    for trip, t_s in inserted.items():
        assert departed[trip] - t_s <= 1.0, (trip, t_s, departed[trip])  # on the track at the next step


def test_jena_line_1_units_turn_round_the_zwatzen_loop_and_leave_on_time(tmp_path: Path) -> None:
    """Zwätzen Schleife is a turning loop: a tram arriving there runs on round the loop to the departure platform,
    no reversal. ``rotations: auto`` found no turnaround there ("dead end"), warned, and started a new unit for
    every departure (0 turnbacks); a unit that runs round the loop must also wait at its departure platform for its
    departure, not take the stop of its last trip for it."""
    cache = tmp_path / "cache"
    world = tmp_path / "jena"
    ok_stdout(run_railsim(["network", "import", str(JENA), "--out", str(world)], cache_dir=cache))
    scenario = tmp_path / "line1.yaml"
    args = ["timetable", "import", "--from-lines", "--headway-s", "600", "--lines", "1", "--world", str(world)]
    ok_stdout(run_railsim([*args, "--from", "07:00", "--to", "08:00", "--out", str(scenario)], cache_dir=cache))
    res = run_railsim(["run", str(scenario), "--out", str(tmp_path / "run"), "--no-progress"], cache_dir=cache)
    ok_stdout(res)
    assert "no unit can turn at zwatzen-schleife" not in res.stderr + res.stdout
    summary = read_summary(tmp_path / "run")
    assert summary["status"] == "completed"
    assert summary["n_arrived"] == summary["n_trains"] == 12
    assert summary["n_stops_served"] == summary["n_stops_scheduled"]
    assert summary["collisions"] == 0 and summary["sumo_collisions"] == 0 and summary["switch_violations"] == 0
    fleet = summary["fleet"]
    loops = [r for r in fleet["turnbacks"] if r["station"] == "zwatzen-schleife"]
    assert len(loops) == 3  # the three trams that arrive before the last departure from Zwätzen
    assert fleet["turnback_min_respected"] is True
    for r in loops:  # each leaves its platform at its departure, after the minimum turnback
        assert r["scheduled_departure_s"] <= r["departed_s"] <= r["scheduled_departure_s"] + 1.0, r
        assert r["departed_s"] - r["arrived_s"] >= r["min_s"], r
    events = list(csv.DictReader((tmp_path / "run" / "events.csv").open(encoding="utf-8")))
    turns = [e for e in events if e["kind"] == "unit_turnback" and '"loop":true' in e["detail"]]
    assert len(turns) == 3
    assert not [e for e in events if e["kind"] in ("stop_missed", "reversal_missed")]


def test_jena_lines_2_3_34_no_train_takes_the_points_beyond_a_switch_it_still_waits_for(tmp_path: Path) -> None:
    """Tram ``2_jena-ost_winzerla.000`` waited 52 s for points ``1839997594``, held by
    ``3_lobeda-ost_jena-ost.000``, and was meanwhile granted the next points on its route (``1854212868``). Tram 3
    then passed ``1839997594`` in front of it and needed ``1854212868``; tram 2 stood behind tram 3 and held the
    points tram 3 waited for: a deadlock, the run failed at 1,163.5 s. A train now asks for a switch only once it
    no longer waits for a switch before it on its route."""
    cache = tmp_path / "cache"
    world = tmp_path / "jena"
    ok_stdout(run_railsim(["network", "import", str(JENA), "--out", str(world)], cache_dir=cache))
    scenario = tmp_path / "lines.yaml"
    args = ["timetable", "import", "--from-lines", "--headway-s", "600", "--lines", "2,3,34", "--world", str(world)]
    ok_stdout(run_railsim([*args, "--from", "07:00", "--to", "07:20", "--out", str(scenario)], cache_dir=cache))
    ok_stdout(run_railsim(["run", str(scenario), "--out", str(tmp_path / "run"), "--no-progress"], cache_dir=cache))
    summary = read_summary(tmp_path / "run")
    assert summary["status"] == "completed"
    assert summary["n_arrived"] == summary["n_trains"] == 16
    assert summary["n_stops_served"] == summary["n_stops_scheduled"] == 380
    assert summary["collisions"] == 0 and summary["sumo_collisions"] == 0 and summary["switch_violations"] == 0
