"""Is a user's ``.net.xml`` whole? A check of its structure before sumolib and SUMO read it.

sumolib reads a net leniently and leaves holes that surface far away: an edge whose ``from`` junction is missing
becomes a node without lanes (a ``TypeError`` when the switches are sought), a connection ``via`` an internal lane
that does not exist a ``KeyError`` when a route is measured, an edge without lanes an ``IndexError``; a lane of
length ``nan`` is read as it is and blamed on the stops file, and a lane of speed 0 runs until a train stands on
it for ever. :func:`check_net_structure` reads the net once (:func:`network.xmlscan.scan`: well-formed XML
without entity declarations) and refuses, naming the element and attribute:

* a lane whose ``length`` is not a finite number >= 0 (> 0 on a normal edge) or whose ``speed`` is not a finite
  number > 0;
* an edge without lanes; a normal edge whose ``from``/``to`` junction is not in the net;
* a connection whose ``from``/``to`` edge, ``fromLane``/``toLane`` index or ``via`` lane is not in the net.
"""

from __future__ import annotations

import math
from pathlib import Path

from network.xmlscan import scan
from railsim.errors import ConfigError
from railsim.inputs import excerpt

_WHAT = "a SUMO network"


def _number(raw: str | None) -> float:
    try:
        return float(raw) if raw is not None else math.nan
    except ValueError:
        return math.nan


def check_net_structure(net_file: Path) -> None:
    """Refuse a net that is not whole (module docstring) with a ConfigError naming the element."""
    junctions: set[str] = set()
    edges: dict[str, dict[str, str]] = {}
    lanes: dict[str, list[str]] = {}
    connections: list[tuple[dict[str, str], int]] = []
    current = [""]

    def on_start(tag: str, attrs: dict[str, str], line: int) -> None:
        if tag == "junction":
            junctions.add(attrs.get("id", ""))
        elif tag == "edge":
            current[0] = attrs.get("id", "")
            edges[current[0]] = dict(attrs) | {"line": str(line)}
            lanes[current[0]] = []
        elif tag == "lane" and current[0] in lanes:
            lid = attrs.get("id", "")
            lanes[current[0]].append(lid)
            normal = edges[current[0]].get("function", "normal") == "normal"
            length_m, speed_mps = _number(attrs.get("length")), _number(attrs.get("speed"))
            if not (math.isfinite(length_m) and (length_m > 0 if normal else length_m >= 0)):
                raise ConfigError(
                    net_file,
                    f"lane[id={lid}].length",
                    f"expected a length {'>' if normal else '>='} 0 m, got {excerpt(attrs.get('length'))} (line {line})",
                )
            if not (math.isfinite(speed_mps) and speed_mps > 0):
                raise ConfigError(
                    net_file,
                    f"lane[id={lid}].speed",
                    f"expected a speed > 0 m/s, got {excerpt(attrs.get('speed'))} (line {line})",
                )
        elif tag == "connection":
            connections.append((dict(attrs), line))

    scan(net_file, _WHAT, on_start)
    lane_ids = {lid for ids in lanes.values() for lid in ids}
    for eid, attrs in edges.items():
        if not lanes[eid]:
            raise ConfigError(
                net_file, f"edge[id={eid}]", f"expected at least one <lane>, got none (line {attrs['line']})"
            )
        if attrs.get("function", "normal") != "normal":
            continue
        for key in ("from", "to"):
            if attrs.get(key) not in junctions:
                raise ConfigError(
                    net_file,
                    f"edge[id={eid}].{key}",
                    f"expected a junction of the network, got {excerpt(attrs.get(key))} (line {attrs['line']})",
                )
    for attrs, line in connections:
        where = f"connection[from={attrs.get('from')},to={attrs.get('to')}]"
        for key in ("from", "to"):
            edge = attrs.get(key, "")
            if edge not in lanes:
                raise ConfigError(
                    net_file, f"{where}.{key}", f"expected an edge of the network, got {excerpt(edge)} (line {line})"
                )
            index = attrs.get(f"{key}Lane", "")
            if not (index.isdigit() and int(index) < len(lanes[edge])):
                raise ConfigError(
                    net_file,
                    f"{where}.{key}Lane",
                    f"expected a lane index below {len(lanes[edge])} (edge {edge!r}), got {excerpt(index)} (line {line})",
                )
        via = attrs.get("via")
        if via is not None and via not in lane_ids:
            raise ConfigError(
                net_file, f"{where}.via", f"expected a lane of the network, got {excerpt(via)} (line {line})"
            )
