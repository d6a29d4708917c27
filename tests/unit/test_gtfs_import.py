"""GTFS import: reading a real feed (frequency expansion, rail filter, dates), stop matching, rotation building.

The real feed is a cut of SPTrans' São Paulo GTFS (tests/data/gtfs/README.md): every trip is a frequencies.txt
template and it has no block_id, so the block cases use a small feed built here.
"""

from __future__ import annotations

import csv
import io
import math
import zipfile
from datetime import date
from pathlib import Path

import pytest

from network.geo import distance_m, utm_to_lonlat
from railsim.engine.settings import EngineSettings
from railsim.errors import ConfigError
from railsim.timetable.builder import PlannedTrip, build_scenario, cut_to_routable, longest_routable
from railsim.timetable.gtfs import GtfsStop, read_trips
from railsim.timetable.matching import WorldStation, match_stops, normalise
from railsim.timetable.rotations import Leg, build_units

FEED = Path(__file__).resolve().parents[1] / "data" / "gtfs" / "sao_paulo_rail_cut.zip"
TUESDAY = date(2019, 10, 1)


def _table(name: str) -> list[dict[str, str]]:
    with zipfile.ZipFile(FEED) as zf:
        return list(csv.DictReader(io.TextIOWrapper(zf.open(name), encoding="utf-8-sig")))


def _secs(hms: str) -> int:
    h, m, s = (int(x) for x in hms.split(":"))
    return 3600 * h + 60 * m + s


def test_frequencies_expand_into_one_trip_per_headway_inside_the_window() -> None:
    feed = read_trips(FEED, TUESDAY, 7 * 3600, 9 * 3600)
    # expected from frequencies.txt directly: start, start + headway, ... < end, kept when in [07:00, 09:00)
    expected: dict[str, list[int]] = {}
    for row in _table("frequencies.txt"):
        t, end, h = _secs(row["start_time"]), _secs(row["end_time"]), int(row["headway_secs"])
        while t < end:
            if 7 * 3600 <= t < 9 * 3600:
                expected.setdefault(row["trip_id"], []).append(t)
            t += h
    rail_trips = {t["trip_id"] for t in _table("trips.txt") if t["route_id"] != "2002-10"}
    got: dict[str, list[int]] = {}
    for trip in feed.trips:
        template = trip.trip_id.split("@")[0]
        got.setdefault(template, []).append(int(round(trip.departure_s)))
    assert set(got) == {k for k in expected if k in rail_trips}
    for template, times in got.items():
        assert sorted(times) == expected[template], template
    assert all(t.route_type in (1, 2) for t in feed.trips)  # the bus route 2002-10 is not rail
    assert feed.rail_routes == 13
    one = next(t for t in feed.trips if t.trip_id.startswith("METRÔ L1-0@"))
    assert one.trip_id == f"METRÔ L1-0@{one.trip_id.split('@')[1]}" and len(one.calls) > 10
    # a copy keeps the template's running times: the call offsets are the template's
    offsets = [c.arrival_s - one.departure_s for c in one.calls]
    assert offsets == sorted(offsets) and offsets[0] == 0.0


def test_a_date_the_feed_does_not_run_is_refused_naming_its_span() -> None:
    with pytest.raises(ConfigError, match=r"--date: expected a date the feed runs on \(2008-01-01 to 2020-05-01\)"):
        read_trips(FEED, date(2024, 5, 1), 0, 86400)


def test_bad_feeds_give_one_line_errors(tmp_path: Path) -> None:
    not_zip = tmp_path / "feed.zip"
    not_zip.write_text("hello")
    with pytest.raises(ConfigError, match="not a zip"):
        read_trips(not_zip, TUESDAY, 0, 86400)
    partial = tmp_path / "partial.zip"
    with zipfile.ZipFile(partial, "w") as zf:
        zf.writestr("routes.txt", "route_id,route_type\nr,1\n")
    with pytest.raises(ConfigError, match="expected the GTFS table trips.txt"):
        read_trips(partial, TUESDAY, 0, 86400)
    with pytest.raises(ConfigError, match="--routes"):
        read_trips(FEED, TUESDAY, 0, 86400, routes=["no such line"])


def _write_feed(path: Path, trips: list[tuple[str, str, str]], times: dict[str, list[tuple[str, str]]]) -> Path:
    """A small GTFS feed: trips (trip_id, route_id, block_id) with stop times [(stop_id, HH:MM:SS)]."""
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("agency.txt", "agency_id,agency_name,agency_url,agency_timezone\na,A,http://a,UTC\n")
        zf.writestr(
            "calendar.txt",
            "service_id,monday,tuesday,wednesday,thursday,friday,saturday,sunday,start_date,end_date\nwk,1,1,1,1,1,1,1,20190101,20191231\n",
        )
        zf.writestr("routes.txt", "route_id,route_short_name,route_type\nM,M,1\nB,B,3\n")
        zf.writestr("stops.txt", "stop_id,stop_name,stop_lat,stop_lon\nA,Alpha,0.0,0.0\nZ,Zulu,0.0,0.01\n")
        zf.writestr(
            "trips.txt",
            "route_id,service_id,trip_id,block_id\n" + "".join(f"{r},wk,{t},{b}\n" for t, r, b in trips),
        )
        rows = "".join(f"{t},{hms},{hms},{s},{k}\n" for t, calls in times.items() for k, (s, hms) in enumerate(calls))
        zf.writestr("stop_times.txt", "trip_id,arrival_time,departure_time,stop_id,stop_sequence\n" + rows)
    return path


def test_block_ids_become_units_and_the_rest_are_built(tmp_path: Path) -> None:
    trips = [("t1", "M", "blk"), ("t2", "M", "blk"), ("t3", "M", ""), ("t4", "M", ""), ("bus", "B", "")]
    times = {
        "t1": [("A", "07:00:00"), ("Z", "07:10:00")],
        "t2": [("Z", "07:20:00"), ("A", "07:30:00")],
        "t3": [("A", "07:05:00"), ("Z", "07:15:00")],
        "t4": [("Z", "07:25:00"), ("A", "07:35:00")],
        "bus": [("A", "07:00:00"), ("Z", "07:30:00")],
    }
    feed = read_trips(_write_feed(tmp_path / "f.zip", trips, times), TUESDAY, 7 * 3600, 8 * 3600)
    assert [t.trip_id for t in feed.trips] == ["t1", "t3", "t2", "t4"]  # the bus is not rail
    assert {t.trip_id: t.block_id for t in feed.trips} == {"t1": "blk", "t2": "blk", "t3": "", "t4": ""}
    legs = [
        Leg(t.trip_id, t.route_name, t.block_id, t.calls[0].stop_id, t.calls[-1].stop_id, t.departure_s, t.arrival_s)
        for t in feed.trips
    ]
    rot = build_units(legs, turnback_min_s=300)
    assert rot.from_blocks == 1 and rot.block_splits == 0
    assert sorted(rot.units.values()) == [["t1", "t2"], ["t3", "t4"]]  # t3 -> t4: 10 min at Zulu >= 5 min


def test_built_rotations_use_the_fewest_units_and_respect_the_turnback() -> None:
    def leg(key: str, o: str, d: str, dep_min: float, arr_min: float, line: str = "L") -> Leg:
        return Leg(key, line, "", o, d, 60 * dep_min, 60 * arr_min)

    shuttle = [
        leg("a", "X", "Y", 0, 10),
        leg("b", "Y", "X", 14, 24),
        leg("c", "X", "Y", 28, 38),
        leg("d", "Y", "X", 42, 50),
    ]
    assert build_units(shuttle, turnback_min_s=180).units == {"l_u01": ["a", "b", "c", "d"]}
    # a 5 min minimum turnback: b leaves 4 min after a arrives and c 4 min after b: new units; d (32 min after
    # a arrived at Y) is run by a's unit
    assert build_units(shuttle, turnback_min_s=300).units == {"l_u01": ["a", "d"], "l_u02": ["b"], "l_u03": ["c"]}
    # best fit: of two ready units the one ready last turns (the shortest turnback)
    two = [leg("p", "X", "Y", 0, 10), leg("q", "X", "Y", 5, 15), leg("r", "Y", "X", 30, 40)]
    assert build_units(two, turnback_min_s=60).units["l_u02"] == ["q", "r"]
    # no turnaround in the world: every trip its own unit
    assert len(build_units(shuttle, turnback_min_s=60, can_turn=lambda a, b: False).units) == 4
    # units stay on their line
    mixed = [leg("m1", "X", "Y", 0, 10, "A"), leg("m2", "Y", "X", 20, 30, "B")]
    assert len(build_units(mixed, turnback_min_s=60).units) == 2


def test_a_block_that_does_not_connect_is_split() -> None:
    legs = [Leg("a", "L", "b1", "X", "Y", 0, 600), Leg("b", "L", "b1", "Z", "X", 900, 1500)]
    rot = build_units(legs, turnback_min_s=60)
    assert rot.block_splits == 1 and len(rot.units) == 2


def test_names_normalise_across_accents_brackets_and_punctuation() -> None:
    assert normalise("Japão - Liberdade") == normalise("Japão-Liberdade") == "japao liberdade"
    assert normalise("Colón") == "colon"
    assert normalise("Rautatieasema (M)") == "rautatieasema"
    assert normalise("Straße") == "strasse"
    assert normalise("Estação Sé") == "se"


def test_stops_match_by_name_by_position_or_not_at_all() -> None:
    stations = [
        WorldStation("Sé", "subway", -46.6339, -23.5503),
        WorldStation("Japão - Liberdade", "subway", -46.6362, -23.5553),
        WorldStation("Luz", "subway", -46.6349, -23.5363),
    ]
    stops = [
        GtfsStop("1", "Se", -46.6341, -23.5504),  # same name without the accent
        GtfsStop("2", "Liberdade", -46.6363, -23.5555),  # renamed station, 25 m away
        GtfsStop("3", "Jabaquara", -46.6416, -23.6459),  # outside the world
        GtfsStop("4", "Luz", -46.60, -23.50),  # same name, 5 km away: doubtful
    ]
    m = match_stops(stops, stations)
    assert (m["1"].station, m["1"].how, m["1"].doubtful) == ("Sé", "name", False)
    assert (m["2"].station, m["2"].how, m["2"].doubtful) == ("Japão - Liberdade", "position", True)
    assert m["2"].distance_m < 50
    assert m["3"].station is None and m["3"].nearest == "Japão - Liberdade" and m["3"].distance_m > 9000
    assert m["4"].station == "Luz" and m["4"].doubtful and m["4"].distance_m > 4000


def test_a_trip_is_cut_to_its_longest_part_the_world_can_drive() -> None:
    # the world has track A-B-C and D-E-F-G but nothing from C to D
    def routable(chain: object) -> bool:
        s = "".join(chain)  # type: ignore[arg-type]
        return s in "ABC" or s in "DEFG"

    assert longest_routable(list("ABCDEFG"), routable) == (3, 6)
    trip = PlannedTrip("L", tuple("ABCDEFG"), tuple(range(7)), tuple(x + 0.5 for x in range(7)), "", "t")
    (cut,), notes = cut_to_routable([trip], routable)
    assert cut.stations == tuple("DEFG") and cut.departure_s == 3.5 and cut.arrival_s == 6
    assert len(notes) == 1 and "kept D-G (4 stations)" in notes[0]


def test_a_line_that_visits_a_stub_and_comes_back_is_cut_at_the_reversal() -> None:
    # Jena's line 34 runs ... Emil-Wölk-Straße, Lobeda-West, Emil-Wölk-Straße ...: a reversal at Lobeda-West,
    # even where the route search finds a way through all three (a turnaround loop or a bidi edge)
    def anywhere(chain: object) -> bool:
        return True

    assert longest_routable(list("ABCBDE"), anywhere) == (2, 5)  # C-B-D-E, not through the reversal at C
    assert longest_routable(list("ABCDA"), anywhere) == (0, 4)  # a ring back to its first station is no reversal


def test_utm_inverse_on_reference_points() -> None:
    lon0, lat0 = utm_to_lonlat(500000.0, 0.0, 31, south=False)
    assert math.isclose(lon0, 3.0, abs_tol=1e-9) and math.isclose(lat0, 0.0, abs_tol=1e-9)
    # on the central meridian the northing is k0 times the meridian arc: 4,984,944.378 m to 45 deg on WGS84
    lon, lat = utm_to_lonlat(500000.0, 0.9996 * 4984944.378, 31, south=False)
    assert distance_m(lon, lat, 3.0, 45.0) < 1.0
    lon, lat = utm_to_lonlat(500000.0, 10000000.0 - 0.9996 * 4984944.378, 31, south=True)
    assert distance_m(lon, lat, 3.0, -45.0) < 1.0
    # netconvert writes southern nets with negative northings and no +south (São Paulo): same point either way
    a = utm_to_lonlat(325680.33, -2610376.88, 23, south=False)
    b = utm_to_lonlat(325680.33, 10000000.0 - 2610376.88, 23, south=True)
    assert distance_m(*a, *b) < 0.01 and distance_m(*a, -46.708093, -23.595422) < 200.0


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--date", "2019-10-01"], "FEED: expected a GTFS feed (.zip), or --from-lines --headway-s H"),
        ([str(FEED), "--date", "1 Oct"], "--date: expected a date YYYY-MM-DD, got '1 Oct'"),
        ([str(FEED)], "--date: expected the service date YYYY-MM-DD"),
        (["--from-lines"], "--headway-s: expected a headway in seconds with --from-lines"),
        ([str(FEED), "--from-lines", "--headway-s", "300"], "--from-lines: expected either a FEED or --from-lines"),
        ([str(FEED), "--date", "2019-10-01", "--world", "/nonexistent"], "expected a world folder"),
    ],
)
def test_timetable_command_line_errors_are_one_line_exit_2(
    args: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    from railsim.cli.main import main

    world = [] if "--world" in args else ["--world", "/nonexistent"]
    code = main(["timetable", "import", *args, *world, "--from", "07:00", "--to", "08:00", "--out", "/tmp/x.yaml"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and message in err, err


def test_imported_trams_keep_the_overlap_behind_the_train_ahead_metro_and_rail_50_m(tmp_path: Path) -> None:
    """The separation margin an import writes: the default overlap for trams (they close up on sight), 50 m else."""
    trip = PlannedTrip("1", ("A", "Z"), (0.0, 600.0), (0.0, 600.0), "", "t1")
    overlap_m = EngineSettings().protection_margin_m
    for vclass, margin_m in (("tram", overlap_m), ("subway", 50.0), ("rail", 50.0)):
        built = build_scenario(
            [trip], name="x", net=tmp_path / "x.net.xml", stops_file=tmp_path / "x.add.xml", vclass=vclass, start_s=0.0
        )
        assert built.scenario["controllers"]["sep"]["params"]["margin_m"] == margin_m, vclass
