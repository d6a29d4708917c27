"""Stops on an edge a route passes more than once: which stops SUMO can be told now, and which only later.

A route can pass a platform's edge twice: a unit's turnback path that runs out along the line to a reversal and
back past the platform it departs from, a route round a loop, a unit that reverses on the platform's own edge.
SUMO matches a stop handed to it (``vehicle.setStop``/``setBusStop``) to the **first** pass of its edge at or
after the edge the train is on, whatever stops it holds already, and sorts it into its stop list by that pass
(measured on SUMO 1.28: the stops of a Jena unit's next trip, handed over in order, went in front of its origin
stop, onto the first pass of their edges 2 km before it); its TraCI calls offer no way to name a later pass. A stop meant for the second pass would be made on the first one, and the train
would find no stop when it comes to the platform again: SUMO never registers the halt there (a unit that came
back to Jena's Winzerla stood 1 m short of its mark for good, and the trams behind it queued). Where the train
stands on the platform's edge already, SUMO even takes the stop for the one it is standing at and ends it at once.

So the stops are handed over in order up to the first one whose first pass, as SUMO would find it, comes before
the pass it is meant for (:func:`stops_now`); that one and all after it wait until the train has left that
earlier pass behind (its route index is past it), and are then handed over the same way. The pass a stop is meant for is the edge of the route that holds the stop's mark
(:func:`railsim.engine.trips.stop_edge_index`). Pure bookkeeping: the SUMO bridge asks and acts.
"""

from __future__ import annotations

from collections.abc import Sequence


def stops_now(
    route_edges: Sequence[str], stop_edges: Sequence[str], want: Sequence[int | None], search_from: int
) -> tuple[int, int | None]:
    """How many of the stops (in order) SUMO would match to the pass they are meant for if handed over now, and
    if not all: the route index of the earlier pass SUMO would match the next one to (hand the rest over once the
    train's route index is past it), else None.

    ``route_edges``: the train's whole route as SUMO holds it; ``stop_edges[i]``: the edge of stop ``i``;
    ``want[i]``: the route index of the pass stop ``i`` is meant for (None: any, the first SUMO finds);
    ``search_from``: the train's route index now."""
    edges = list(route_edges)
    search = max(0, search_from)
    for i, (edge, k) in enumerate(zip(stop_edges, want, strict=True)):
        first = edges.index(edge, search) if edge in edges[search:] else None
        meant = k is not None and 0 <= k < len(edges) and edges[k] == edge
        if meant and first is not None and k is not None and first < k:
            return i, first
    return len(stop_edges), None
