"""Which track each direction keeps where a double-track line is drawn as two ``bidi`` tracks.

OpenStreetMap rail data, and netconvert's ``--railway.topology.repair``, often make *both* tracks of a double-track
line ``bidi`` (each track has an edge for either direction). A router that only minimises metres then sends both
directions along whichever track happens to be shorter: the line is run as a single track (opposing trains take it
in turns, or meet head-on) while its twin stays empty.

Real railways run on one side: on a double-track line a train keeps the track on its running side (right-hand
running in most metros, left-hand in the UK, Japan, and elsewhere) and uses the other track only where the line
offers nothing else (a single-track section, a crossover to reverse). This module finds, for every edge of the
track graph, whether it is the **wrong line** for its direction of travel: another rail edge runs *parallel* to it
(within :data:`PARALLEL_MAX_M` sideways, heading within :data:`PARALLEL_MAX_TURN_DEG`), in the *same* direction,
on the running side. Such an edge is the left-hand track of a right-hand-running pair (or the right-hand one of a
left-hand pair). Its routing cost is multiplied by :data:`WRONG_LINE_FACTOR`, so routes keep their own track
wherever it exists and still use the other one where nothing else leads there.

A plain double-track line (one one-way edge per track and direction) has no parallel edge in the same direction,
and true single track has no parallel edge at all: neither is touched. The test is geometric (the lane shapes of
the net), sampled at three points along each edge; a parallel edge must be beside it at the majority of them.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from network.plane import Point, turn_rad

RUNNING_SIDES = ("right", "left")
PARALLEL_MAX_M = 12.0  # [m] centre-to-centre distance below which two tracks are a pair (metro: 3.5-5 m)
PARALLEL_MIN_M = 0.5  # [m] closer than this it is the same track (a bidi partner drawn on top)
PARALLEL_MAX_TURN_DEG = 25.0  # [deg] heading difference up to which two tracks run parallel
WRONG_LINE_FACTOR = 8.0  # routing cost multiplier on the wrong line (uses it only where nothing else leads)
_CELL_M = 25.0  # [m] grid cell of the spatial index (> PARALLEL_MAX_M + _SAMPLE_M / 2)
_SAMPLE_M = 12.5  # [m] step of the points along a segment whose cells index it


def _along(shape: Sequence[Point], frac: float) -> tuple[Point, float]:
    """Point at fraction ``frac`` of a polyline's length and the heading [rad] of the segment it lies on."""
    seglens = [math.dist(a, b) for a, b in zip(shape, shape[1:])]
    total = sum(seglens)
    target = frac * total
    for (a, b), ln in zip(zip(shape, shape[1:]), seglens):
        if ln > 1e-9 and target <= ln:
            t = target / ln
            return (a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])), math.atan2(b[1] - a[1], b[0] - a[0])
        target -= ln
    a, b = shape[-2], shape[-1]
    return b, math.atan2(b[1] - a[1], b[0] - a[0])


def _segments(shape: Sequence[Point]) -> Iterable[tuple[Point, Point]]:
    for a, b in zip(shape, shape[1:]):
        if math.dist(a, b) > 1e-9:
            yield a, b


def _cells(a: Point, b: Point) -> set[tuple[int, int]]:
    """The grid cells of points along segment ``ab`` every :data:`_SAMPLE_M` (ends included): time linear in its
    length. (Every cell of its bounding box was quadratic: a 5,000 km segment, one node of an extract misplaced
    by 45 degrees, took hours.) Every point of the segment lies within ``_SAMPLE_M / 2`` of a sample, so a point
    within :data:`PARALLEL_MAX_M` of the segment lies within ``_CELL_M`` of a sample: in one of the 3 x 3 cells
    around its own, which is where :func:`wrong_line_edges` looks."""
    n = max(1, math.ceil(math.dist(a, b) / _SAMPLE_M))
    return {
        (
            int(math.floor((a[0] + k / n * (b[0] - a[0])) / _CELL_M)),
            int(math.floor((a[1] + k / n * (b[1] - a[1])) / _CELL_M)),
        )
        for k in range(n + 1)
    }


def wrong_line_edges(shapes: Mapping[str, Sequence[Point]], bidi: Mapping[str, str | None], side: str) -> set[str]:
    """Edges that are the wrong line for their direction of travel under ``side`` running (module docstring).

    ``shapes`` maps each rail edge to its lane shape (x, y) in travel order; ``bidi`` to its bidi partner.
    """
    if side not in RUNNING_SIDES:
        raise ValueError(f"running side must be one of {RUNNING_SIDES}, got {side!r}")
    grid: dict[tuple[int, int], list[tuple[str, Point, Point]]] = {}
    for eid, shape in shapes.items():
        for a, b in _segments(shape):
            for c in _cells(a, b):
                grid.setdefault(c, []).append((eid, a, b))
    max_turn = math.radians(PARALLEL_MAX_TURN_DEG)
    sign = -1.0 if side == "right" else 1.0  # the running side: cross product < 0 = right of travel
    wrong: set[str] = set()
    for eid, shape in shapes.items():
        if bidi.get(eid) is None or len(shape) < 2:
            continue  # a one-way track is its own direction's track already
        hits = 0
        for frac in (0.25, 0.5, 0.75):
            (px, py), heading = _along(shape, frac)
            ci, cj = int(math.floor(px / _CELL_M)), int(math.floor(py / _CELL_M))
            found = False
            for di in (-1, 0, 1):
                for dj in (-1, 0, 1):
                    for other, a, b in grid.get((ci + di, cj + dj), ()):
                        if other in (eid, bidi.get(eid)):
                            continue
                        if turn_rad(heading, math.atan2(b[1] - a[1], b[0] - a[0])) > max_turn:
                            continue
                        dx, dy = b[0] - a[0], b[1] - a[1]
                        ln2 = dx * dx + dy * dy
                        t = ((px - a[0]) * dx + (py - a[1]) * dy) / ln2
                        if not 0.0 <= t <= 1.0:
                            continue
                        qx, qy = a[0] + t * dx, a[1] + t * dy
                        dist = math.hypot(px - qx, py - qy)
                        if not PARALLEL_MIN_M <= dist <= PARALLEL_MAX_M:
                            continue
                        cross = math.cos(heading) * (qy - py) - math.sin(heading) * (qx - px)
                        if cross * sign > 0.0:
                            found = True
                            break
                    if found:
                        break
                if found:
                    break
            hits += int(found)
        if hits >= 2:
            wrong.add(eid)
    return wrong


def mark_wrong_line(graph: Any, shapes: Mapping[str, Sequence[Point]], side: str) -> int:
    """Flag wrong-line edges on the track graph (``wrong_line`` node attribute) and raise the routing cost
    (``cost_m``) of every connection onto one by :data:`WRONG_LINE_FACTOR`. Returns how many edges were flagged."""
    bidi = {n: graph.nodes[n].get("bidi") for n in graph.nodes}
    wrong = wrong_line_edges(shapes, bidi, side)
    graph.graph["running_side"] = side
    for n in graph.nodes:
        graph.nodes[n]["wrong_line"] = n in wrong
    for _, b, attrs in graph.edges(data=True):
        if b in wrong:
            attrs["cost_m"] = attrs["cost_m"] * WRONG_LINE_FACTOR
    return len(wrong)
