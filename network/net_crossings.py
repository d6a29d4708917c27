"""Flat crossings of a SUMO net: movements inside one node whose paths cross but share no track.

A tram line crossing another at grade, or a rail line crossing a tram line, is one SUMO node whose connections
intersect. The interlocking makes each such pair of movements a route resource (docs/model.md,
"Interlocking"), as it does for a generated world's crossings (:func:`network.topology.flat_crossings` decides
which pairs count, here and there).
"""

from __future__ import annotations

from typing import Any

import networkx as nx

from network.plane import Point, paths_cross
from network.topology import flat_crossings


def mark_crossings(g: nx.DiGraph, net: Any) -> None:
    """Foe movements inside one node that share no track (a flat crossing): ``g.graph["crossings"]``.

    SUMO's own foe matrix of the node says which connections intersect (netconvert computes it from the geometry);
    movements that share an edge or its bidi partner are not crossings — a diverge/merge is a switch and head-on
    running on one track is single track, both protected by their own resources
    (:func:`network.topology.flat_crossings`, shared with generated worlds).
    """
    links = {(a, b): attrs.pop("link") for a, b, attrs in g.edges(data=True)}

    def foes(_node: str, m1: tuple[str, str], m2: tuple[str, str]) -> bool:
        c1, c2 = links[m1], links[m2]
        node = c1.getFrom().getToNode()
        i1, i2 = node.getLinkIndex(c1), node.getLinkIndex(c2)
        if i1 < 0 or i2 < 0:
            return False
        try:
            return bool(node.areFoes(i1, i2) or node.areFoes(i2, i1))
        except (KeyError, IndexError):  # no foe matrix (an unregulated node): decide from the geometry
            return paths_cross(_movement_shape(net, c1), _movement_shape(net, c2))

    g.graph["crossings"] = flat_crossings(g, foes)


def _movement_shape(net: Any, c: Any) -> list[Point]:
    """The path of a connection through its node: its internal lane's shape, else the straight line from the
    end of the incoming lane to the start of the outgoing one."""
    via = c.getViaLaneID()
    if via:
        try:
            return [(float(x), float(y)) for x, y, *_ in net.getLane(via).getShape()]
        except (KeyError, AttributeError):
            pass
    (x0, y0, *_), (x1, y1, *_) = c.getFromLane().getShape()[-1], c.getToLane().getShape()[0]
    return [(float(x0), float(y0)), (float(x1), float(y1))]
