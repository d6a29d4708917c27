"""Capacity analyses: UIC 406 compression against closed forms, and invariants on a real run.

Here: the tests of it that run SUMO or a railsim child process; the others are in ``tests/unit/test_capacity.py``.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from railsim.analysis.capacity import (
    CapacityReport,
    analyse_run,
)
from railsim.analysis.sections import section_table
from tests.helpers import read_csv


@pytest.fixture(scope="module")
def report(mini_run: Path) -> CapacityReport:
    return analyse_run(mini_run, period_s=600.0)


def test_throughput_counts_units_and_paths(mini_run: Path, report: CapacityReport) -> None:
    thr = report.tables["throughput"].set_index(["direction", "section"])
    trunk = thr.loc[("up", "b → c")]
    # three main_up units plus the coupled branch unit: 4 trains and their passengers on 3 paths
    assert trunk["paths_per_h"] == pytest.approx(3 * 6.0)
    assert trunk["trains_per_h"] == pytest.approx(4 * 6.0)
    assert trunk["pax_per_h"] == pytest.approx(4 * 1342 * 6.0)
    assert thr.loc[("up", "a → b")]["trains_per_h"] == pytest.approx(3 * 6.0)


def test_uic406_occupancy_is_compressed_time_over_period_with_no_negative_buffer(
    mini_run: Path, report: CapacityReport
) -> None:
    uic = report.tables["uic406"]
    assert (uic["occupancy"] == uic["compressed_s"] / 600.0).all()
    assert ((uic["occupancy"] > 0) & (uic["occupancy"] < 1)).all()
    # the simulated trains kept moving-block separation (the separation controller's braking distance), so no
    # pair of consecutive paths has a negative buffer; the pairs are the paths' departures in order
    pairs = report.tables["uic406_pairs"]
    assert len(pairs) == (uic["paths"] - 1).sum()
    assert (pairs["buffer_s"] >= -1.0).all(), pairs.sort_values("buffer_s").head()
    assert (pairs["min_headway_s"] > 30.0).all()  # a train length plus a braking distance at least
    secs = section_table(mini_run)
    paths = secs[(secs["formation_role"] != "follower") & (secs["from_station"] == "a")]
    deps = sorted(paths["departure_s"])
    ab = pairs[pairs["section"] == "a → b"]
    assert list(ab["achieved_s"]) == pytest.approx([b - a for a, b in zip(deps, deps[1:])])


def test_junction_passes_every_unit_through_its_switch(mini_run: Path, report: CapacityReport) -> None:
    trips = read_csv(mini_run / "trips.csv")
    j = report.tables["junction"].set_index("switch")
    ups = [t for t in trips if t["service"] in ("main_up", "br_up")]
    downs = [t for t in trips if t["service"] in ("main_down", "br_down")]
    assert j.loc["c_up", "trains"] == len(ups) and j.loc["c_up", "reverse_leg"] == 1
    assert j.loc["c_down", "trains"] == len(downs) and j.loc["c_down", "reverse_leg"] == 1
    assert j.loc["c_up", "min_s"] > 0


def test_markdown_and_summary(report: CapacityReport) -> None:
    md = report.to_markdown()
    for heading in ("UIC 406 occupancy per section", "Throughput per section", "Junction headways"):
        assert heading in md
    assert "| up | b → c |" in md
    s = report.summary()
    assert s["up.trains_per_h"] >= s["up.paths_per_h"]
