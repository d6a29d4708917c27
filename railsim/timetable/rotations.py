"""Rotations for an imported timetable: which unit runs which trips.

GTFS rarely says which vehicle runs which trips (``block_id`` is optional and often absent). Two sources:

* **Explicit blocks**: trips sharing a ``block_id`` are one unit's day, in departure order. A block whose
  consecutive trips do not connect (the next trip leaves from another station than the last one ended at,
  or before it arrived plus the minimum turnback) is split there and reported, since railsim's units cannot
  jump between stations.
* **Built rotations** for the other trips (:func:`build_units`): trips are taken in departure order; a trip
  is run by a unit **of the same line** (GTFS route) that stands at its first station and is ready
  (arrived at least ``turnback_min_s`` before) — among the ready units, the one that became ready **last**
  (best fit: the shortest turnback, so early arrivals stay free for earlier departures); with none ready, a
  new unit enters service. Taking trips in time order and reusing any ready unit where one exists gives the
  **fewest units** for a given set of trips when units do not run empty between stations (interval
  partitioning per terminus); the best-fit choice only decides which of the equivalent units turns.
  A unit waiting longer than ``max_layover_s`` is retired (it would be back at a depot in reality).

Stations are compared by the world station each trip's ends matched (so two GTFS stop ids of one station
connect). Units are named ``<line>_u01``...; the result is ``{unit: [trip key, ...]}`` in running order.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Callable, Sequence
from dataclasses import dataclass

DEFAULT_TURNBACK_MIN_S = 180.0
DEFAULT_MAX_LAYOVER_S = 1800.0


@dataclass(frozen=True)
class Leg:
    """What rotation building needs of a trip: key, line, block, first/last station and times [s]."""

    key: str
    line: str
    block: str
    origin: str
    destination: str
    departure_s: float
    arrival_s: float
    stations: tuple[str, ...] = ()  # the whole station sequence (for the world's turnaround check)


@dataclass
class Rotations:
    units: dict[str, list[str]]
    from_blocks: int = 0  # units taken from block_id
    block_splits: int = 0  # places where a block did not connect and was split


def _slug(text: str) -> str:
    out = "".join(ch if ch.isalnum() else "_" for ch in text.lower()).strip("_")
    return out or "line"


def build_units(
    legs: Sequence[Leg],
    turnback_min_s: float = DEFAULT_TURNBACK_MIN_S,
    max_layover_s: float = DEFAULT_MAX_LAYOVER_S,
    can_turn: Callable[[Sequence[str], Sequence[str]], bool] | None = None,
) -> Rotations:
    """Units from explicit blocks, then built for the rest (module docstring). ``can_turn(arriving stations,
    departing stations)`` says whether the world lets a unit reverse from one trip into the next (default:
    everywhere); where it does not, the next trip needs another unit."""
    turns = can_turn or (lambda a, b: True)
    units: dict[str, list[str]] = {}
    counters: dict[str, int] = defaultdict(int)

    def new_unit(line: str) -> str:
        counters[line] += 1
        uid = f"{_slug(line)}_u{counters[line]:02d}"
        units[uid] = []
        return uid

    result = Rotations(units)
    blocks: dict[str, list[Leg]] = defaultdict(list)
    loose: list[Leg] = []
    for leg in legs:
        (blocks[leg.block] if leg.block else loose).append(leg)
    for _, chain in sorted(blocks.items()):
        chain.sort(key=lambda x: x.departure_s)
        uid = new_unit(chain[0].line)
        result.from_blocks += 1
        for prev, nxt in zip([None, *chain], chain):
            if prev is not None and (
                prev.destination != nxt.origin
                or nxt.departure_s < prev.arrival_s + turnback_min_s
                or not turns(prev.stations, nxt.stations)
            ):
                uid = new_unit(nxt.line)
                result.block_splits += 1
            units[uid].append(nxt.key)
    # built rotations: per (line, station) the units standing there, as (ready time, unit)
    standing: dict[tuple[str, str], list[tuple[float, str, tuple[str, ...]]]] = defaultdict(list)
    for leg in sorted(loose, key=lambda x: (x.departure_s, x.key)):
        here = standing[(leg.line, leg.origin)]
        here[:] = [x for x in here if leg.departure_s - x[0] <= max_layover_s + turnback_min_s]
        ready = [x for x in here if x[0] <= leg.departure_s and turns(x[2], leg.stations)]
        if ready:
            chosen = max(ready)
            here.remove(chosen)
            uid = chosen[1]
        else:
            uid = new_unit(leg.line)
        units[uid].append(leg.key)
        standing[(leg.line, leg.destination)].append((leg.arrival_s + turnback_min_s, uid, leg.stations))
    return result
