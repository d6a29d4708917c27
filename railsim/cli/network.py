"""``railsim network build|show|import``: build a world into a folder, print a summary of it, or import OSM.

    railsim network build NAME|FILE --out DIR [-p KEY=VALUE ...]
    railsim network import OSM_FILE --out DIR [--bbox W,S,E,N] [--lines L1,L2] [--light-rail-as-tram]
    railsim network show  NAME|FILE [-p KEY=VALUE ...]
    railsim network show  FILE.net.xml [-a stops.add.xml ...] [--signals strip|keep] [--vclass CLASS]
                          [--unrestricted-lanes CLASS]

A ``.net.xml`` is an existing SUMO network read as it is (:mod:`network.external`): stations come from the
trainStops/busStops of the ``-a`` additional files.

``import`` runs netconvert on an OpenStreetMap extract with the options a rail study needs and writes the
net, one stops file per rail class, the lines and stations as YAML (:mod:`network.osm_import`).

``-p`` sets a parameter of a shipped world (``railsim network show y_junction -p S1=600``); values are read
as YAML scalars. ConfigError propagates to ``railsim.cli.main`` (one line, exit code 2).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import yaml

from railsim.cli import values
from railsim.errors import ConfigError


def _params(pairs: list[str] | None) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for pair in pairs or []:
        key, sep, value = pair.partition("=")
        if not sep or not key:
            raise ConfigError("<command line>", "-p", f"expected KEY=VALUE, got {pair!r}")
        try:
            out[key] = yaml.safe_load(value)
        except yaml.YAMLError:
            out[key] = value
    return out


def _world_arg(name: str) -> str | Path:
    return Path(name) if name.endswith((".yaml", ".yml")) or Path(name).is_file() else name


def cmd_build(args: argparse.Namespace) -> int:
    from network import build

    bundle = build(_world_arg(args.world), out_dir=Path(args.out), **_params(args.param))
    print(
        f"{bundle.name}: wrote {bundle.net_file}, {bundle.stops_file}, {bundle.topology_file} "
        f"({len(bundle.stations)} stations, {len(bundle.switches)} switches, {len(bundle.routes)} routes)"
    )
    return 0


def summary(bundle: Any) -> str:
    """Readable text summary of a NetworkBundle (stations, switches, routes)."""
    lines = [f"world {bundle.name}", f"  net:   {bundle.net_file}", f"  stops: {bundle.stops_file}"]
    external = bundle.graph.graph.get("kind") == "external"  # a user's net: derived line km, platforms = trainStops
    if external:
        lines.append(f"  rail vClass {bundle.vclass}; rail signals: {bundle.n_rail_signals} ({bundle.signals})")
    lines += ["", f"stations ({len(bundle.stations)}):"]
    if external:
        for st in bundle.stations.values():
            plats = ", ".join(
                f"{p.stop_id} on {p.edge} {p.start_pos_m:.0f}-{p.end_pos_m:.0f} m heading {p.direction}"
                for p in st.platforms
            )
            km = f"{st.line:<8} km {st.km:7.3f}" if st.line else "no line km"
            lines.append(f"  {st.id:<24} {st.name!r:<26} {km}  {plats}")
    else:
        lines.append(f"  {'id':<48} {'line':<10} {'km':>9} {'platform':>9}  turnback")
        for st in bundle.stations.values():  # main line first, then each branch, by chainage
            tb = "yes" if st.turnback else ""
            lines.append(f"  {st.id:<48} {st.line:<10} {st.km:9.3f} {st.platform_length_m:7.0f} m  {tb}")
    lines.append("")
    lines.append(f"switches ({len(bundle.switches)}):")
    for sw in bundle.switches.values():
        lines.append(
            f"  {sw.id:<12} {sw.kind:<8} node {sw.sumo_node:<12} trunk {sw.trunk_edge:<16} "
            f"normal {sw.normal_edge:<16} reverse {sw.reverse_edge:<16} throw {sw.throw_time_s:g} s, "
            f"diverging {sw.diverging_speed_mps * 3.6:g} km/h"
        )
    lines.append("")
    lines.append(f"routes ({len(bundle.routes)}; km = first stop to last stop along the route):")
    if not bundle.routes and bundle.graph.graph.get("routes_note"):
        lines.append(f"  none listed: {bundle.graph.graph['routes_note']}")
    for r in bundle.routes.values():
        sws = ", ".join(f"{s.switch_id}({s.leg}) @{s.point_m:.0f} m" for s in r.switches) or "no switches"
        lines.append(
            f"  {r.id:<36} {route_distance_m(r) / 1000:8.3f} km  {len(r.edges):3d} edges  {len(r.stops):2d} stops  "
            f"{sws}"
        )
    return "\n".join(lines)


def route_distance_m(route: Any) -> float:
    """Metres a train runs on ``route`` (id ``"a->b"`` or ``"a->b via ..."``): from its stopping mark at the
    first station to its stopping mark at the last, along the route. Not ``length_m``, which counts the
    whole first and last edges (a 2.8 km service on two long edges would read 6.5 km)."""
    first, _, last = route.id.split(" via ")[0].partition("->")
    starts = [s for s in route.stops if s.station_id == first]
    ends = [s for s in route.stops if s.station_id == last]
    if not starts or not ends:
        return float(route.length_m)
    return float(ends[-1].end_m - starts[0].end_m)


def cmd_show(args: argparse.Namespace) -> int:
    from network import build

    if args.world.endswith(".net.xml"):
        from network.external import load_net

        if args.param:
            raise ConfigError("<command line>", "-p", "expected no world parameters for a .net.xml")
        bundle = load_net(
            args.world,
            args.additional or (),
            signals=args.signals,
            vclass=args.vclass,
            where=("<command line>", "--"),
            unrestricted_lanes=args.unrestricted_lanes,
        )
        print(summary(bundle))
        return 0
    if args.additional or args.vclass or args.signals != "strip" or args.unrestricted_lanes:
        raise ConfigError(
            "<command line>", "-a/--signals/--vclass/--unrestricted-lanes", "expected these only with a .net.xml file"
        )
    print(summary(build(_world_arg(args.world), **_params(args.param))))
    return 0


def cmd_import(args: argparse.Namespace) -> int:
    from network.osm_import import import_osm, parse_bbox

    lines = [x for x in (args.lines or "").split(",") if x.strip()] or None
    summary = import_osm(
        args.osm_file,
        Path(args.out),
        bbox=parse_bbox(args.bbox),
        lines=lines,
        light_rail_as_tram=args.light_rail_as_tram,
        platform_m=args.platform_m,
    )
    print(summary.text())
    return 0


def add_commands(subparsers: Any) -> None:
    net = subparsers.add_parser("network", help="build or inspect a world (SUMO net + topology)")
    sub = net.add_subparsers(dest="network_command", metavar="ACTION", required=True)
    b = sub.add_parser("build", help="build a world: DIR/<name>.net.xml, .stops.add.xml, .topology.json")
    b.add_argument(
        "world", metavar="NAME|FILE", type=values.path, help="a shipped world name or a line-description YAML file"
    )
    b.add_argument("--out", required=True, metavar="DIR", type=values.path, help="output folder")
    b.add_argument("-p", "--param", action="append", metavar="KEY=VALUE", help="world parameter (repeatable)")
    b.set_defaults(func=cmd_build)
    s = sub.add_parser("show", help="print a readable summary of a world (or of an existing SUMO .net.xml)")
    s.add_argument(
        "world", metavar="NAME|FILE", type=values.path, help="a shipped world, a line description or a SUMO .net.xml"
    )
    s.add_argument("-p", "--param", action="append", metavar="KEY=VALUE", help="world parameter (repeatable)")
    s.add_argument(
        "-a",
        "--additional",
        action="append",
        metavar="FILE",
        help=".net.xml only: an additional file with trainStops/busStops (repeatable)",
    )
    s.add_argument(
        "--signals",
        choices=("strip", "keep"),
        default="strip",
        help=".net.xml only: strip SUMO's rail signals in railsim's copy (default) or keep them",
    )
    s.add_argument("--vclass", default=None, help=".net.xml only: rail vClass of railsim's trains (default: auto)")
    s.add_argument(
        "--unrestricted-lanes",
        default=None,
        metavar="CLASS",
        help=".net.xml only: lanes without permissions are track of this rail vClass (world.unrestricted_lanes)",
    )
    s.set_defaults(func=cmd_show)
    i = sub.add_parser("import", help="import an OpenStreetMap extract: rail net, stops per class, lines, stations")
    i.add_argument("osm_file", metavar="OSM_FILE", help="OpenStreetMap XML (.osm, .osm.xml, .osm.gz)")
    i.add_argument("--out", required=True, metavar="DIR", help="output folder")
    i.add_argument("--bbox", metavar="W,S,E,N", help="keep only the track inside this lon/lat box")
    i.add_argument("--lines", metavar="L1,L2", help="keep only these line refs (OSM route 'ref') and their stops")
    i.add_argument(
        "--light-rail-as-tram",
        action="store_true",
        help="railway=light_rail track is tram track (one fleet on both, a Stadtbahn): one class, one network",
    )
    i.add_argument(
        "--platform-m",
        type=values.metres,
        default=None,
        metavar="M",
        help="widen every stop shorter than M metres to M (within its track edge; default 30 tram, 60 other): "
        "OSM has stop positions, not platform lengths, and a coupled pair needs room for two units",
    )
    i.set_defaults(func=cmd_import)
