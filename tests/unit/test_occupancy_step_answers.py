"""The per-step occupancy answers (train ahead, facing trains, head-on contacts) are those of the per-train code
they replaced, on random states.

Each step the engine asks the occupancy index (railsim/engine/occupancy.py) for every train's train ahead
(:meth:`Occupancy.ahead_all`), the facing train within braking distance (:meth:`Occupancy.facing_within_braking`)
and the facing train under each body (:meth:`Occupancy.facing_own_bodies`, read by
:meth:`SafetyMonitor.head_on_checks`). The gaps, offsets and the filtering to trains that face one are done in the
compiled pass (:func:`railsim.engine.occupancy_kernel.ahead_all`, :func:`~railsim.engine.occupancy_kernel.facing_hits`).
The references below are the former Python forms, kept as they were: one search per train
(:func:`~railsim.engine.occupancy_kernel.ahead_one`, :func:`~railsim.engine.occupancy_kernel.facing_all` over
every slot) with the gap and offset taken in Python and every row filtered in Python. On random track and bodies
(those of ``tests/unit/test_occupancy_kernel.py``: merges, loops, bidi partners) the answers must be equal to the
bit (``repr``), the collisions recorded the same, in the same order.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from railsim.engine import occupancy_kernel
from railsim.engine.events.clock import EventLayer
from railsim.engine.events.log import EventLog
from railsim.engine.occupancy import Ahead, Occupancy
from railsim.engine.safety import SafetyMonitor
from railsim.engine.settings import FACING_DECEL_MPS2, EngineSettings
from tests.unit.test_occupancy_kernel import _bodies, _world


def _ahead_before(occ: Occupancy, lookahead_m: float) -> list[Ahead | None]:
    """The former :meth:`Occupancy.ahead_all`: the kernel's slot, front and rear, the gap and offset in Python."""
    out: list[Ahead | None] = []
    mine = occ._front.tolist()
    for me in range(len(occ.ids)):
        o, front, rear = occupancy_kernel.ahead_one(me, lookahead_m, occ._ahead_world())
        front, rear = float(front), float(rear)
        out.append(None if o < 0 else Ahead(occ.ids[o], front, rear, rear - mine[me], front - mine[o]))
    return out


def _facing_rows_before(occ: Occupancy, from_m: np.ndarray, lookahead_m: np.ndarray) -> tuple[Any, Any, Any]:
    """The former ``Occupancy._facing_rows``: :func:`occupancy_kernel.facing_all` for every slot, every row."""
    return occ._facing_kernel(np.arange(len(occ.ids), dtype=np.int64), from_m, lookahead_m)


def _facing_within_braking_before(occ: Occupancy, speed_mps: list[float], floor_m: float) -> dict[str, float]:
    lookahead_m = np.array([floor_m + v**2 / (2.0 * FACING_DECEL_MPS2) for v in speed_mps], float)
    hit, near, _ = _facing_rows_before(occ, occ._front, lookahead_m)
    ids = occ.ids
    return {ids[k]: near_m for k, near_m in zip(np.flatnonzero(hit >= 0).tolist(), near[hit >= 0].tolist())}


class HeadOnBefore(SafetyMonitor):
    """The former head-on check, on the former per-slot rows (every slot, filtered here)."""

    def head_on_checks(self, t: float, active: list[Any], own_bodies: Any) -> None:
        occ: Occupancy = own_bodies.__self__
        hit_slot, near = _facing_rows_before(occ, occ._front - occ._len, occ._len)[:2]
        ids = occ.ids
        for k in np.flatnonzero(hit_slot >= 0).tolist():
            tr, near_m = active[k], float(near[k])
            if near_m > tr.front_m:
                continue
            other_id = ids[int(hit_slot[k])]
            pair = (min(tr.train_id, other_id), max(tr.train_id, other_id))
            if pair in self._colliding_pairs:
                continue
            self._colliding_pairs.add(pair)
            overlap_m = tr.front_m - near_m
            self.collisions.append(
                {
                    "t_s": t,
                    "follower": tr.train_id,
                    "leader": other_id,
                    "overlap_m": overlap_m,
                    "chainage_m": tr.front_m,
                    "head_on": True,
                }
            )


def _monitor(cls: type[SafetyMonitor]) -> SafetyMonitor:
    layer = EventLayer(t0_s=0.0, rng=np.random.default_rng(1))
    return cls({}, layer, EventLog(), EngineSettings())


@pytest.mark.parametrize("seed", range(6))
def test_the_step_answers_are_the_per_train_answers(seed: int) -> None:
    found = {"ahead": 0, "braking": 0, "contacts": 0}
    for trial in range(25):
        rng = np.random.default_rng(100 * seed + trial)
        views, graph = _world(rng)
        occ = Occupancy()
        occ.set_bidi(graph)
        fast, before = _monitor(SafetyMonitor), _monitor(HeadOnBefore)
        for step in range(4):  # several steps: routes appear, contacts repeat (recorded once per pair)
            bodies = _bodies(rng, views, int(rng.integers(1, 40)))
            occ.update(bodies)
            lookahead_m = float(rng.choice([300.0, 5000.0]))
            ahead = occ.ahead_all(lookahead_m)
            assert repr(ahead) == repr(_ahead_before(occ, lookahead_m))
            found["ahead"] += sum(a is not None for a in ahead)
            speeds = [float(v) for v in rng.uniform(0.0, 30.0, len(bodies))]
            facing = occ.facing_within_braking(speeds, 150.0)
            assert repr(facing) == repr(_facing_within_braking_before(occ, speeds, 150.0))
            found["braking"] += len(facing)
            active = [SimpleNamespace(train_id=b.train_id, front_m=b.front_m) for b in bodies]
            fast.head_on_checks(float(step), active, occ.facing_own_bodies)  # type: ignore[arg-type]
            before.head_on_checks(float(step), active, occ.facing_own_bodies)  # type: ignore[arg-type]
            assert repr(fast.collisions) == repr(before.collisions)
        found["contacts"] += len(fast.collisions)
    assert found["ahead"] > 500 and found["braking"] > 100 and found["contacts"] > 20  # not only empty answers


def test_on_track_without_partners_nobody_faces_anybody() -> None:
    rng = np.random.default_rng(3)
    views, _ = _world(rng)
    occ = Occupancy()
    bodies = _bodies(rng, views, 20)
    occ.update(bodies)
    assert occ.facing_within_braking([10.0] * len(bodies), 150.0) == {}
    assert occ.facing_own_bodies()[:3] == ([], [], [])
