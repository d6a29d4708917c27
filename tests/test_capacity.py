"""Capacity analyses: UIC 406 compression against closed forms, and invariants on a real run.

Closed forms (module docstring of railsim.analysis.capacity): identical trains at constant speed v in moving block have the
minimum headway H = (L + S(v) + margin) / v, S the absolute braking distance, so n of them in a period U occupy
n·H / U; with fixed blocks of length B it is (B + L + S(v) + margin) / v. A slow train followed by a fast one is
limited at the section's end, a fast one followed by a slow one at its start — both headways by hand.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from controllers.braking import stopping_distance_m
from railsim.analysis.capacity import (
    BlockModel,
    CapacityReport,
    Stairway,
    analyse_run,
    claim_m,
    compress,
    first_time_at,
    min_headway_s,
    stairway,
)
from railsim.analysis.sections import section_table
from railsim.errors import ConfigError
from tests.helpers import DATA, read_csv

MINI = DATA / "scenarios" / "mini_line.yaml"
DECEL, DELAY, MARGIN, LENGTH = 1.11, 2.5, 50.0, 89.4


def _constant_speed_stairway(name: str, t_ref: float, v: float, section_m: float, blocks: tuple) -> Stairway:
    """A train at constant ``v`` whose front passes the section start (x = 0) at ``t_ref``."""
    t = np.linspace(t_ref - 400.0, t_ref + 400.0, 801)
    x = v * (t - t_ref)
    claim = claim_m(x, np.full_like(t, v), DECEL, DELAY, MARGIN)
    return stairway(name, t_ref, t, claim, t, x - LENGTH, blocks, t[-1])


@pytest.mark.parametrize("v", [8.0, 15.0, 20.0])
@pytest.mark.parametrize("n", [1, 4, 12])
def test_identical_constant_speed_trains_occupy_n_times_the_minimum_headway(v: float, n: int) -> None:
    section = 1500.0
    model = BlockModel(0.0, 5.0)
    blocks = model.blocks(section)
    h_min = (LENGTH + stopping_distance_m(v, DECEL, DELAY) + MARGIN) / v
    stairs = [_constant_speed_stairway(f"t{k}", 300.0 * k, v, section, blocks) for k in range(n)]
    compressed, heads = compress(stairs)
    assert heads == pytest.approx([h_min] * n, abs=1e-6)
    assert compressed / 3600.0 == pytest.approx(n * h_min / 3600.0, abs=1e-9)


def test_fixed_virtual_blocks_add_one_block_length_of_running() -> None:
    v, block = 15.0, 400.0
    blocks = BlockModel(block).blocks(1500.0)
    assert list(blocks[0]) == [0, 400, 800, 1200] and list(blocks[1]) == [400, 800, 1200, 1500]
    a = _constant_speed_stairway("a", 0.0, v, 1500.0, blocks)
    b = _constant_speed_stairway("b", 500.0, v, 1500.0, blocks)
    assert min_headway_s(a, b) == pytest.approx((block + LENGTH + stopping_distance_m(v, DECEL, DELAY) + MARGIN) / v)


def test_slow_then_fast_and_fast_then_slow_by_hand() -> None:
    section, slow, fast = 1200.0, 10.0, 20.0
    blocks = BlockModel(0.0, 1.0).blocks(section)
    a = _constant_speed_stairway("slow", 0.0, slow, section, blocks)
    b = _constant_speed_stairway("fast", 0.0, fast, section, blocks)
    d_slow = stopping_distance_m(slow, DECEL, DELAY) + MARGIN
    d_fast = stopping_distance_m(fast, DECEL, DELAY) + MARGIN
    # slow ahead: the fast one catches up, the binding point is the section end
    h_ab = (section + LENGTH) / slow - (section - d_fast) / fast
    # fast ahead: it pulls away, the binding point is the section start
    h_ba = LENGTH / fast + d_slow / slow
    assert min_headway_s(a, b) == pytest.approx(h_ab, abs=1e-6)
    assert min_headway_s(b, a) == pytest.approx(h_ba, abs=1e-6)
    compressed, _ = compress([a, b])
    assert compressed == pytest.approx(h_ab + h_ba, abs=1e-6)


def test_first_time_at_interpolates_and_flags_never_reached() -> None:
    t = np.array([0.0, 10.0, 20.0, 30.0])
    x = np.array([0.0, 100.0, 100.0, 400.0])  # a stop between 10 and 20 s
    got = first_time_at(t, x, np.array([-5.0, 50.0, 100.0, 250.0, 500.0]))
    assert got[:4] == pytest.approx([0.0, 5.0, 10.0, 25.0])
    assert math.isnan(got[4])


def test_bad_block_model_is_a_config_error() -> None:
    with pytest.raises(ConfigError, match="block_length_m"):
        BlockModel(-1.0)
    with pytest.raises(ConfigError, match="resolution_m"):
        BlockModel(0.0, 0.0)


# ---------------------------------------------------------------------------------------------------- real run


@pytest.fixture(scope="module")
def report(mini_run: Path) -> CapacityReport:
    return analyse_run(mini_run, period_s=600.0)


@pytest.mark.sumo
def test_throughput_counts_units_and_paths(mini_run: Path, report: CapacityReport) -> None:
    thr = report.tables["throughput"].set_index(["direction", "section"])
    trunk = thr.loc[("up", "b → c")]
    # three main_up units plus the coupled branch unit: 4 trains and their passengers on 3 paths
    assert trunk["paths_per_h"] == pytest.approx(3 * 6.0)
    assert trunk["trains_per_h"] == pytest.approx(4 * 6.0)
    assert trunk["pax_per_h"] == pytest.approx(4 * 1342 * 6.0)
    assert thr.loc[("up", "a → b")]["trains_per_h"] == pytest.approx(3 * 6.0)


@pytest.mark.sumo
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


@pytest.mark.sumo
def test_junction_passes_every_unit_through_its_switch(mini_run: Path, report: CapacityReport) -> None:
    trips = read_csv(mini_run / "trips.csv")
    j = report.tables["junction"].set_index("switch")
    ups = [t for t in trips if t["service"] in ("main_up", "br_up")]
    downs = [t for t in trips if t["service"] in ("main_down", "br_down")]
    assert j.loc["c_up", "trains"] == len(ups) and j.loc["c_up", "reverse_leg"] == 1
    assert j.loc["c_down", "trains"] == len(downs) and j.loc["c_down", "reverse_leg"] == 1
    assert j.loc["c_up", "min_s"] > 0


@pytest.mark.sumo
def test_markdown_and_summary(report: CapacityReport) -> None:
    md = report.to_markdown()
    for heading in ("UIC 406 occupancy per section", "Throughput per section", "Junction headways"):
        assert heading in md
    assert "| up | b → c |" in md
    s = report.summary()
    assert s["up.trains_per_h"] >= s["up.paths_per_h"]


def test_bad_folder_and_parameters(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="run folder"):
        analyse_run(tmp_path / "missing")
    with pytest.raises(ConfigError, match="period_s"):
        analyse_run(tmp_path, period_s=0.0)
