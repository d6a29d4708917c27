"""The GTFS fuzz at CI size (reading layer, in this process), and one regression test per defect it found.

Every mutant of the committed feed (:mod:`tests.fuzz_gtfs`) is read or refused with a ``ConfigError`` naming
the feed and a field: no other exception, no hang, no trip with a non-finite, negative or backwards time, no stop
outside WGS84. ``python -m tests.fuzz_gtfs --reader --mutants 1000`` is the larger campaign.

The regression tests start from a minimal valid feed (:data:`MINIMAL`) and change one cell or one table: each
case is an input the fuzz found that once gave a traceback, a hang, an error without its field, or a silently
wrong trip. The last tests hold the streamed reading (:mod:`railsim.timetable.feed_tables`): text read in chunks
splits into the same lines and names the same line of a bad byte, whatever the chunk size; the rows of trips not
kept are checked as text only; a damaged member is refused as it is read.
"""

from __future__ import annotations

import io
import math
from datetime import date
from pathlib import Path

import pytest

from railsim.errors import ConfigError
from railsim.timetable import feed_tables
from railsim.timetable.gtfs import read_trips
from tests import fuzz_gtfs

N_MUTANTS = 60
TUESDAY = date(2019, 10, 1)
MINIMAL = {
    "agency.txt": "agency_id,agency_name,agency_url,agency_timezone\na,A,http://a,UTC\n",
    "calendar.txt": "service_id,monday,tuesday,wednesday,thursday,friday,saturday,sunday,start_date,end_date\n"
    "wk,1,1,1,1,1,0,0,20190101,20191231\n",
    "routes.txt": "route_id,route_short_name,route_type\nM,M,1\n",
    "stops.txt": "stop_id,stop_name,stop_lat,stop_lon\nA,Alpha,0.0,0.0\nZ,Zulu,0.0,0.01\n",
    "trips.txt": "route_id,service_id,trip_id\nM,wk,t1\n",
    "stop_times.txt": "trip_id,arrival_time,departure_time,stop_id,stop_sequence\n"
    "t1,07:00:00,07:00:00,A,1\nt1,07:10:00,07:10:00,Z,2\n",
    "frequencies.txt": "trip_id,start_time,end_time,headway_secs\nt1,07:00:00,08:00:00,600\n",
}


def _feed(tmp_path: Path, table: str = "", old: str = "", new: str = "") -> Path:
    """:data:`MINIMAL` with ``old`` replaced by ``new`` in ``table`` (which must contain it)."""
    files = dict(MINIMAL)
    if table:
        assert old in files[table], (table, old)
        files[table] = files[table].replace(old, new)
    path = tmp_path / "feed.zip"
    path.write_bytes(fuzz_gtfs.zip_bytes({n: t.encode() for n, t in files.items()}))
    return path


def test_mutants_of_the_feed_are_read_or_refused_by_field(tmp_path: Path) -> None:
    fig = fuzz_gtfs.campaign(N_MUTANTS, tmp_path)
    print(f"fuzz_gtfs: mutants {fig.mutants}, ok {fig.ok}, refused {fig.refused}, {fig.seconds:.1f} s")
    assert fig.problems == [], "\n".join(fig.problems[:20])
    assert fig.ok + fig.refused == N_MUTANTS
    assert fig.ok >= 5 and fig.refused >= 30  # the mutator reaches both sides


def test_the_minimal_feed_expands_its_frequencies(tmp_path: Path) -> None:
    feed = read_trips(_feed(tmp_path), TUESDAY, 7 * 3600, 8 * 3600)
    assert [t.trip_id for t in feed.trips] == [f"t1@07:{m:02d}:00" for m in range(0, 60, 10)]
    assert feed.expanded_from_frequencies == 6 and feed.outside_window == 0
    assert feed.trips[-1].calls[-1].arrival_s == 7 * 3600 + 60 * 60
    assert feed.stops["Z"].lon == 0.01


@pytest.mark.parametrize(
    ("table", "old", "new", "field"),
    [
        # once ValueError from a GTFS time parser without the field, or silently 26:01 / a negative time
        ("stop_times.txt", "t1,07:10:00,", "t1,nan,", "stop_times.txt.arrival_time"),
        ("stop_times.txt", "t1,07:10:00,", "t1,7:10,", "stop_times.txt.arrival_time"),
        ("stop_times.txt", "t1,07:10:00,", "t1,07:10:00:00,", "stop_times.txt.arrival_time"),
        ("stop_times.txt", "t1,07:10:00,", "t1,25:61:00,", "stop_times.txt.arrival_time"),
        ("stop_times.txt", ",07:10:00,Z", ",-1:00:00,Z", "stop_times.txt.departure_time"),
        # once a hang: a copy every 0.001 s, or until hour 99999
        ("frequencies.txt", ",600\n", ",0.001\n", "frequencies.txt.headway_secs"),
        ("frequencies.txt", "08:00:00", "99999:00:00", "frequencies.txt.end_time"),
        ("frequencies.txt", ",600\n", ",0\n", "frequencies.txt.headway_secs"),
        ("frequencies.txt", "07:00:00,08:00:00", "08:00:00,07:00:00", "frequencies.txt.end_time"),
        ("frequencies.txt", "\nt1,07:00:00", "\nt1,07:30:00,09:00:00,300\nt1,07:00:00", "frequencies.txt.start_time"),
        # once AttributeError: frequencies.txt without its trip_id column
        ("frequencies.txt", "trip_id,", "trip,", "frequencies.txt.trip_id"),
        # once silently reordered or interpolated calls
        ("stop_times.txt", "A,1", "A,x", "stop_times.txt.stop_sequence"),
        ("stop_times.txt", "A,1", "A,", "stop_times.txt.stop_sequence"),
        ("stop_times.txt", "A,1", "A,1e309", "stop_times.txt.stop_sequence"),
        ("stop_times.txt", "Z,2", "Z,1", "stop_times.txt.stop_sequence"),
        ("stop_times.txt", "A,1", "A,3", "stop_times.txt.arrival_time"),  # calls out of sequence: times run back
        ("stop_times.txt", "07:00:00,07:00:00,A", "07:20:00,07:00:00,A", "stop_times.txt.arrival_time"),
        ("stop_times.txt", "07:10:00,07:10:00,Z", ",,Z", "stop_times.txt.arrival_time"),  # no time at the end
        # once carried into the trips: a stop outside WGS84, a call of a stop that does not exist
        ("stops.txt", "0.0,0.01", "91,0.01", "stops.txt.stop_lat"),
        ("stops.txt", "0.0,0.01", "0.0,inf", "stops.txt.stop_lon"),
        ("stops.txt", "0.0,0.01", "0.0,1e308", "stops.txt.stop_lon"),
        ("stops.txt", "Z,Zulu", "Y,Zulu", "stop_times.txt.stop_id"),
        # once ValueError / OverflowError converting route_type
        ("routes.txt", "M,1", "M,nan", "routes.txt.route_type"),
        ("routes.txt", "M,1", "M,", "routes.txt.route_type"),
        ("routes.txt", "M,1", "M,1e400", "routes.txt.route_type"),
        # once duplicated trips, or a trip silently dropped for a route that does not exist
        ("trips.txt", "M,wk,t1\n", "M,wk,t1\nM,wk,t1\n", "trips.txt.trip_id"),
        ("trips.txt", "M,wk,t1", "N,wk,t1", "trips.txt.route_id"),
        # once an error without its table: a ragged row, a quote left open, a NUL byte, invalid UTF-8
        ("stops.txt", "A,Alpha,0.0,0.0", "A,Alpha,0.0,0.0,x", "stops.txt"),
        ("stops.txt", "A,Alpha", 'A,"Alpha', "stops.txt"),
        ("stops.txt", "0.0,0.01", "0.0,0.01\x00", "stops.txt"),
        # calendar: a date that does not exist, a flag that is not 0 or 1
        ("calendar.txt", "20191231", "20191340", "calendar.txt.end_date"),
        ("calendar.txt", "1,1,1,1,1,0,0", "1,x,1,1,1,0,0", "calendar.txt.tuesday"),
    ],
)
def test_a_bad_cell_is_refused_naming_its_field(tmp_path: Path, table: str, old: str, new: str, field: str) -> None:
    path = _feed(tmp_path, table, old, new)
    with pytest.raises(ConfigError) as info:
        read_trips(path, TUESDAY, 7 * 3600, 8 * 3600)
    assert (info.value.source, info.value.field) == (str(path), field), str(info.value)
    assert str(info.value).startswith(f"{path}: {field}: expected ")


def test_invalid_utf8_is_refused_naming_its_table(tmp_path: Path) -> None:
    path = tmp_path / "feed.zip"
    files = {n: t.encode() for n, t in MINIMAL.items()}
    files["stops.txt"] += b"Q,\xff\xfe,0,0\n"
    path.write_bytes(fuzz_gtfs.zip_bytes(files))
    with pytest.raises(ConfigError, match=r"stops.txt: expected UTF-8 text, got an invalid byte in line 4"):
        read_trips(path, TUESDAY, 7 * 3600, 8 * 3600)


def test_a_table_twice_in_the_zip_is_refused_and_one_sub_folder_is_read(tmp_path: Path) -> None:
    files = {n: t.encode() for n, t in MINIMAL.items()}
    path = tmp_path / "feed.zip"
    path.write_bytes(fuzz_gtfs.zip_bytes({**files, "gtfs/stops.txt": files["stops.txt"]}))
    with pytest.raises(ConfigError, match=r"feed.zip: stops.txt: expected one stops.txt in the feed"):
        read_trips(path, TUESDAY, 7 * 3600, 8 * 3600)  # once a ValueError without the table
    path.write_bytes(fuzz_gtfs.zip_bytes({"gtfs/": b"", **{f"gtfs/{n}": d for n, d in files.items()}}))
    assert len(read_trips(path, TUESDAY, 7 * 3600, 8 * 3600).trips) == 6


def test_a_byte_order_mark_and_crlf_are_read_as_the_reference_allows(tmp_path: Path) -> None:
    files = {n: b"\xef\xbb\xbf" + t.replace("\n", "\r\n").encode() for n, t in MINIMAL.items()}
    path = tmp_path / "feed.zip"
    path.write_bytes(fuzz_gtfs.zip_bytes(files))
    assert len(read_trips(path, TUESDAY, 7 * 3600, 8 * 3600).trips) == 6


def test_a_calendar_over_millennia_and_a_one_second_headway_read_the_window_only(tmp_path: Path) -> None:
    # once a hang: the calendar resolved day by day over 8,000 years; every copy of the day made before the window
    path2 = tmp_path / "one_second.zip"
    files = {n: t.encode() for n, t in MINIMAL.items()}
    files["calendar.txt"] = MINIMAL["calendar.txt"].replace("20190101,20191231", "00010101,99991231").encode()
    files["frequencies.txt"] = b"trip_id,start_time,end_time,headway_secs\nt1,00:00:00,167:00:00,1\n"
    path2.write_bytes(fuzz_gtfs.zip_bytes(files))
    feed = read_trips(path2, TUESDAY, 7 * 3600, 7 * 3600 + 60)
    assert len(feed.trips) == 60 and feed.outside_window == 167 * 3600 - 60
    assert all(math.isfinite(c.arrival_s) for t in feed.trips for c in t.calls)


def test_empty_coordinates_are_unknown_and_the_stop_matches_by_name(tmp_path: Path) -> None:
    feed = read_trips(_feed(tmp_path, "stops.txt", "0.0,0.01", ","), TUESDAY, 7 * 3600, 8 * 3600)
    assert math.isnan(feed.stops["Z"].lat) and math.isnan(feed.stops["Z"].lon)


@pytest.mark.parametrize("chunk_bytes", [1, 2, 3, 5, 7, 64])
def test_text_read_in_chunks_splits_lines_as_the_whole_text_does(chunk_bytes: int) -> None:
    text = 'a,b\r\nc,"d\r\ne"\rf,é€\n\ng,h\r'
    data = b"\xef\xbb\xbf" + text.encode()
    chunks = feed_tables.text_lines(Path("f.zip"), "t.txt", io.BytesIO(data), chunk_bytes)
    assert [ln for lines in chunks for ln in lines] == io.StringIO(text, newline="").readlines()


@pytest.mark.parametrize("chunk_bytes", [1, 4, 1 << 20])
@pytest.mark.parametrize(
    ("bad", "message"),
    [
        (b"\xff", "expected UTF-8 text, got an invalid byte in line 3"),
        (b"\x00", "expected text, got a NUL byte in line 3"),
    ],
)
def test_text_read_in_chunks_names_the_line_of_a_bad_byte(chunk_bytes: int, bad: bytes, message: str) -> None:
    data = b"a,b\r\n\xc3\xa9,x\nc," + bad + b"\nd,e\n"
    with pytest.raises(ConfigError, match=f"t.txt: {message}$"):
        list(feed_tables.text_lines(Path("f.zip"), "t.txt", io.BytesIO(data), chunk_bytes))


def test_rows_of_trips_not_kept_are_checked_as_text_only(tmp_path: Path) -> None:
    # a bus trip's bad time or unknown stop cannot reach the trips read: not parsed; its ragged row is refused
    files = dict(MINIMAL)
    files["routes.txt"] += "B,B,3\n"
    files["trips.txt"] += "B,wk,b1\n"
    bus = "b1,25:61:00,x,NOWHERE,y\nb1,07:10:00,07:10:00,Z,2\n"
    files["stop_times.txt"] = files["stop_times.txt"].replace(
        "trip_id,arrival_time,departure_time,stop_id,stop_sequence\n",
        "trip_id,arrival_time,departure_time,stop_id,stop_sequence\n" + bus,
    )
    path = tmp_path / "feed.zip"
    path.write_bytes(fuzz_gtfs.zip_bytes({n: t.encode() for n, t in files.items()}))
    assert len(read_trips(path, TUESDAY, 7 * 3600, 8 * 3600).trips) == 6
    files["stop_times.txt"] = files["stop_times.txt"].replace("NOWHERE,y", "NOWHERE,y,z")
    path.write_bytes(fuzz_gtfs.zip_bytes({n: t.encode() for n, t in files.items()}))
    with pytest.raises(ConfigError, match=r"stop_times.txt: expected 5 fields as in the header, got 6 in line 2$"):
        read_trips(path, TUESDAY, 7 * 3600, 8 * 3600)
    files["trips.txt"] += "B,wk,b1\n"
    path.write_bytes(fuzz_gtfs.zip_bytes({n: t.encode() for n, t in files.items()}))
    with pytest.raises(ConfigError, match=r"trips.txt.trip_id: expected unique ids, got 'b1' in lines 3 and 4$"):
        read_trips(path, TUESDAY, 7 * 3600, 8 * 3600)


def test_a_damaged_member_is_refused_naming_its_table(tmp_path: Path) -> None:
    data = bytearray(fuzz_gtfs.zip_bytes({n: t.encode() for n, t in MINIMAL.items()}))
    at = bytes(data).index(b"t1,07:10:00,07:10:00,Z,2")
    data[at + 3] ^= 1  # the stored bytes change; the member's checksum no longer matches
    path = tmp_path / "feed.zip"
    path.write_bytes(bytes(data))
    with pytest.raises(ConfigError, match=r"stop_times.txt: expected a readable zip member, got an error \(Bad CRC"):
        read_trips(path, TUESDAY, 7 * 3600, 8 * 3600)
