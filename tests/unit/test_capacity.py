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
    Stairway,
    analyse_run,
    claim_m,
    compress,
    first_time_at,
    min_headway_s,
    stairway,
)
from railsim.errors import ConfigError
from tests.helpers import DATA

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


def test_bad_folder_and_parameters(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="run folder"):
        analyse_run(tmp_path / "missing")
    with pytest.raises(ConfigError, match="period_s"):
        analyse_run(tmp_path, period_s=0.0)
