"""World building for railsim: line descriptions -> SUMO nets with stations, switches and routes.

Public API::

    network.build(name_or_path, out_dir=None, **params) -> NetworkBundle
    network.shipped_worlds() -> list[str]

See :mod:`network.line` (the YAML schema), :mod:`network.generator` (how the SUMO net is made and why its
chainage matches SUMO's odometer), :mod:`network.topology` (the bundle, routes, the track graph) and
:mod:`network.worlds` (straight_corridor, y_junction, chongqing_line3).
"""

from network.build import build, cache_root
from network.line import LineDescription, load_description, parse_description
from network.topology import (
    NetworkBundle,
    PlatformInfo,
    RouteInfo,
    RoutePoint,
    RouteStop,
    RouteSwitch,
    StationInfo,
    SwitchInfo,
)
from network.worlds import shipped_worlds, world_params

__all__ = [
    "build",
    "cache_root",
    "shipped_worlds",
    "world_params",
    "load_description",
    "parse_description",
    "LineDescription",
    "NetworkBundle",
    "PlatformInfo",
    "RouteInfo",
    "RoutePoint",
    "RouteStop",
    "RouteSwitch",
    "StationInfo",
    "SwitchInfo",
]
