"""What the ground knows in the junction coordination (Paper E online, :mod:`.coordinator`).

The planner runs on the ground, so it sees the trains through their train-to-ground reports — each one the
sender's route, front, speed and acceleration stamped with its send time, delivered late or not at all by the
``t2g`` channel — and the switches through the interlocking. A report is extrapolated at constant speed to now;
before a train's first report the ground knows its insertion point and speed; with no radio modelled it sees
the truth.
"""

from __future__ import annotations

import math
from typing import Any

from controllers.junction.model import SwitchState
from controllers.junction.planner import TrainState

SWITCHES = ("sw1", "sw2")


def ground_front(channels: dict[str, Any], tr: Any, t: float) -> tuple[float, float]:
    """A train's front [route m] and speed as the ground knows them at ``t``."""
    ch = channels.get("t2g")
    msg = ch.latest("ground", tr.train_id) if ch is not None else None
    if msg is not None:
        _route, pos, v, _acc, stamp = msg.payload[:5]
    elif ch is None:
        pos, v, stamp = tr.front_m, tr.plant.speed_mps, t
    else:
        pos, v, stamp = tr.start_front_m, tr.trip.start_speed_mps, tr.inserted_s or 0.0
    return float(pos) + float(v) * max(0.0, t - float(stamp)), float(v)


def ground_states(
    channels: dict[str, Any], members: dict[str, Any], trains: list[Any], t: float, min_speed_mps: float
) -> tuple[list[TrainState], dict[str, float]]:
    """The planner's inputs for the planned trains (track, distance to the next switch, speed) and their fronts."""
    states, fronts = [], {}
    for tr in trains:
        front, v = ground_front(channels, tr, t)
        fronts[tr.train_id] = front
        track, dist = members[tr.train_id].track(front)
        states.append(TrainState(tr.train_id, track, dist, max(v, min_speed_mps)))
    return states, fronts


def switch_states(interlocking: Any, members: dict[str, Any], with_own_holders: bool) -> list[SwitchState]:
    """Position and lock of each junction switch. A lock held outside the plan has no known end (``inf``);
    ``with_own_holders`` also names a planned train holding a granted lock (``qp_order``: it must pass first)."""
    out = []
    for sid in SWITCHES:
        lock = interlocking.lock(sid)
        holders = tuple(lock.holder_ids) if lock is not None else ()
        foreign = [h for h in holders if h not in members]
        own = [h for h in holders if h in members] if with_own_holders else []
        out.append(
            SwitchState(
                sid,
                interlocking.position(sid),
                locked_until_s=math.inf if foreign else 0.0,
                locked_for=foreign[0] if foreign else (own[0] if own else None),
            )
        )
    return out
