"""Plane geometry of track shapes on a SUMO net (x east, y north, metres): headings, turns, crossing paths.

A SUMO lane's ``shape`` is a polyline of points in the net's plane. The track graph (:mod:`network.external`)
records where each edge heads as it starts and ends (:func:`heading_rad`) and its compass direction
(:func:`compass`); switches order their legs by the heading change across the node (:func:`turn_rad`); the
running side compares a track with the one beside it (:mod:`network.running_side`); flat crossings without a foe
matrix are found by intersecting the movements' paths (:func:`paths_cross`, :mod:`network.net_crossings`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

Point = tuple[float, float]
_COMPASS = ("N", "NE", "E", "SE", "S", "SW", "W", "NW")


def heading_rad(shape: Sequence[tuple[float, ...]], at_end: bool) -> float:
    """Heading [rad] of a polyline at its end (``at_end``) or its start: the last/first non-zero segment."""
    pts = list(shape)[::-1] if at_end else list(shape)
    for (x0, y0, *_), (x1, y1, *_) in zip(pts, pts[1:]):
        if math.hypot(x1 - x0, y1 - y0) > 1e-6:
            return math.atan2(y0 - y1, x0 - x1) if at_end else math.atan2(y1 - y0, x1 - x0)
    return 0.0


def compass(dx: float, dy: float) -> str:
    """8-point compass label of a travel direction (SUMO's y axis points north)."""
    bearing = math.degrees(math.atan2(dx, dy)) % 360.0
    return _COMPASS[int((bearing + 22.5) // 45.0) % 8]


def turn_rad(a: float, b: float) -> float:
    """Absolute heading change from a to b [rad], in [0, pi]."""
    return abs((b - a + math.pi) % (2.0 * math.pi) - math.pi)


def paths_cross(a: list[Point], b: list[Point]) -> bool:
    """Do two polylines touch or intersect? Without a usable shape the movements are taken as crossing:
    protecting a crossing that is not one costs capacity; leaving one unprotected could cost a collision."""
    if len(a) < 2 or len(b) < 2:
        return True
    return any(_segments_meet(a[i], a[i + 1], b[j], b[j + 1]) for i in range(len(a) - 1) for j in range(len(b) - 1))


def _orient(a: Point, b: Point, c: Point) -> float:
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])


def _segments_meet(p1: Point, p2: Point, q1: Point, q2: Point) -> bool:
    """Segments p1p2 and q1q2 intersect or touch (orientation test, collinear overlap included)."""
    d1, d2, d3, d4 = _orient(q1, q2, p1), _orient(q1, q2, p2), _orient(p1, p2, q1), _orient(p1, p2, q2)
    if (d1 > 0 > d2 or d1 < 0 < d2) and (d3 > 0 > d4 or d3 < 0 < d4):
        return True
    for d, a, b, c in ((d1, q1, q2, p1), (d2, q1, q2, p2), (d3, p1, p2, q1), (d4, p1, p2, q2)):
        if d == 0 and min(a[0], b[0]) <= c[0] <= max(a[0], b[0]) and min(a[1], b[1]) <= c[1] <= max(a[1], b[1]):
            return True
    return False
