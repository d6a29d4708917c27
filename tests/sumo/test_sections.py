"""Line sections read back from a real run (mini Y line: up/down trains, a coupled pair, a merging train).

The section table is checked against the recorder's own tables, computed independently here with the csv module:
running times are stop-table differences, headways are departure differences on the same section, lengths are the
stations' km differences, and the coupled pair shares its section runs.
"""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd
import pytest

from railsim.analysis.sections import SECTION_COLUMNS, LineFrame, section_table
from tests.helpers import DATA, read_csv

MINI = DATA / "scenarios" / "mini_line.yaml"


@pytest.fixture(scope="module")
def table(mini_run: Path) -> pd.DataFrame:
    return section_table(mini_run)


def _served(mini_run: Path) -> dict[str, list[tuple[str, float, float]]]:
    """trip -> [(station, arrival, departure)] in time order, origin first (from trips.csv and stops.csv)."""
    out: dict[str, list[tuple[str, float, float]]] = {}
    for t in read_csv(mini_run / "trips.csv"):
        out[t["trip_id"]] = [(t["origin"], math.nan, float(t["departure_s"]))]
    for s in sorted(read_csv(mini_run / "stops.csv"), key=lambda r: float(r["arrival_s"])):
        dep = float(s["departure_s"]) if s["departure_s"] else math.nan
        out[s["trip_id"]].append((s["station"], float(s["arrival_s"]), dep))
    return out


def test_one_row_per_completed_section_with_contract_columns(mini_run: Path, table: pd.DataFrame) -> None:
    assert list(table.columns) == SECTION_COLUMNS
    served = _served(mini_run)
    assert len(table) == sum(len(v) - 1 for v in served.values())
    assert set(table["direction"]) == {"up", "down"}
    assert (table["running_time_s"] > 0).all()


def test_running_times_are_stop_table_differences(mini_run: Path, table: pd.DataFrame) -> None:
    served = _served(mini_run)
    followers = set(table.loc[table["formation_role"] == "follower", "trip_id"])
    for row in table.itertuples(index=False):
        seq = served[row.trip_id]
        names = [s for s, _, _ in seq]
        i = names.index(row.from_station)
        assert names[i + 1] == row.to_station
        assert row.arrival_s == seq[i + 1][1]
        if row.trip_id not in followers:
            assert row.departure_s == seq[i][2]
            assert row.running_time_s == pytest.approx(seq[i + 1][1] - seq[i][2])


def test_headways_are_departure_differences_on_the_same_section(table: pd.DataFrame) -> None:
    for _, grp in table.groupby(["direction", "from_station", "to_station"]):
        deps = sorted(grp["departure_s"])
        got = sorted(grp["headway_s"].dropna())
        assert got == pytest.approx(sorted(b - a for a, b in zip(deps, deps[1:])))
        assert grp["headway_s"].isna().sum() == 1


def test_lengths_match_station_km(table: pd.DataFrame) -> None:
    for row in table.itertuples(index=False):
        assert row.length_m == pytest.approx(abs(row.to_km - row.from_km) * 1000.0, rel=0.01)
        assert (row.to_km > row.from_km) == (row.direction == "up")


def test_coupled_pair_runs_its_trunk_sections_as_one_formation(mini_run: Path, table: pd.DataFrame) -> None:
    pair = table[table["formation"] == "pair"]
    assert set(pair["trip_id"]) == {"main_up.001", "br_up.000"}
    lead = pair[pair["formation_role"] == "leader"].set_index(["from_station", "to_station"])
    fol = pair[pair["formation_role"] == "follower"].set_index(["from_station", "to_station"])
    assert list(lead.index) == list(fol.index) and len(lead) >= 1
    # the follower leaves with its leader, never before it
    assert (fol["departure_s"] == lead["departure_s"]).all()
    # after the fork they run different sections, outside the formation
    branch = table[(table["trip_id"] == "br_up.000") & (table["to_station"] == "f")]
    assert len(branch) == 1 and branch.iloc[0]["formation"] == ""


def test_line_frame_maps_platform_centres_to_station_km(mini_run: Path) -> None:
    frame = LineFrame.from_run(mini_run)
    for sf in frame.services.values():
        for st in sf.stations:
            stop = sf.route.stop(st)
            assert sf.km_of(0.5 * (stop.start_m + stop.end_m)) == pytest.approx(sf.km[st])
        assert frame.capacity_pax(sf.service) == 1342
