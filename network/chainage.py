"""Line chainage for a net that has none: a ``line`` and a ``km`` per station, from the net's routes.

A generated world's line description gives every station a line and a km, and the line studies (sections,
UIC 406 capacity, the train graph, the report) read them. A user's SUMO net has only tracks and stops, so
:func:`line_chainage` makes them from the routes between its stations (:mod:`network.external`): the route along
the most stations is the ``main`` line, km = distance along it from its first station's platform centre (its
direction of travel is ``up``, the opposite ``down``), and the stations left are placed on ``branch1``,
``branch2``... from the nearest station already placed.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

from network.topology import RouteInfo


def _stations_along(route: RouteInfo) -> list[tuple[str, float]]:
    """``(station, platform centre [route chainage m])`` of every station whose platform the route runs along,
    in route order (first platform of a station only)."""
    out: dict[str, float] = {}
    for rs in route.stops:
        out.setdefault(rs.station_id, 0.5 * (rs.start_m + rs.end_m))
    return list(out.items())


def line_chainage(station_order: Sequence[str], routes: Iterable[RouteInfo]) -> dict[str, tuple[str, float]]:
    """``{station: (line id, km)}``: a chainage for a net that has none, from its routes (module docstring).

    The **main line** is the route along the most stations (ties: the one starting at the station listed first,
    then the longer one); its stations get ``km`` = platform centre minus the first station's centre, in km
    (so its direction of travel is ``up``, the other ``down``). Then, while stations are left, the route along
    the most of them becomes branch ``branch<k>``: each new station is placed from the nearest already placed
    station on that route, in the direction the placed stations run on it (``+`` if fewer than two).
    """
    index = {sid: i for i, sid in enumerate(station_order)}
    along = [(r, _stations_along(r)) for r in routes]
    placed: dict[str, tuple[str, float]] = {}
    k = 0
    while True:
        best = None
        for r, seq in along:
            new = sum(1 for sid, _ in seq if sid not in placed)
            if new == 0 or len(seq) < 2:
                continue
            key = (new, -index.get(seq[0][0], len(index)), r.length_m, r.id)
            if best is None or key > best[0]:
                best = (key, seq)
        if best is None:
            return placed
        seq = best[1]
        line_id = "main" if k == 0 else f"branch{k}"
        known = [(c, placed[sid][1]) for sid, c in seq if sid in placed]
        if not known:
            known = [(seq[0][1], 0.0)]
        sign = 1.0
        if len(known) >= 2 and known[-1][1] < known[0][1]:
            sign = -1.0
        for sid, c in seq:
            if sid not in placed:
                c0, km0 = min(known, key=lambda ck: abs(ck[0] - c))
                placed[sid] = (line_id, round(km0 + sign * (c - c0) / 1000.0, 6))
        k += 1
