"""From an OpenStreetMap file to a railsim world: ``railsim network import OSM_FILE --out DIR``.

One netconvert run (the eclipse-sumo wheel's) turns the OSM data into a rail-only SUMO net plus the public
transport stops and lines OSM records; this module then splits and summarises what came out, so the folder
can go straight into a scenario (``world: {net: DIR/<name>.net.xml, additional: [DIR/<name>.stops.<class>.add.xml]}``)
and into ``railsim timetable import``.

**The netconvert options** (:func:`netconvert_args`; SUMO's railway tutorial, ``docs/web/docs/Tutorials/
RailwayScenario.md``, is where most come from; where we depart from it, the reason is railsim's own driving):

``--type-files osmNetconvert.typ.xml,osmNetconvertExtraRail.typ.xml``
    SUMO's OSM type map plus its extra rail types (monorail and funicular import as ``rail_urban``).
``--keep-edges.by-vclass rail,rail_urban,rail_electric,rail_fast,subway,tram``
    Rail classes only: roads, paths and waterways are dropped at the source (a street that carries a tram
    stays, with its tram permission). The tutorial filters with osmfilter first; this does it in one step.
``--keep-edges.in-geo-boundary W,S,E,N`` (``--bbox``)
    Keep a study small: only edges inside the box (lon/lat).
``--light-rail-as-tram`` (an option of the import, off by default)
    SUMO's type map gives ``railway=light_rail`` track the class ``rail_urban`` and ``railway=tram`` track
    ``tram``. Where one fleet runs on both — a German *Stadtbahn* such as Cologne's, light rail in the tunnels
    and on its own right of way, tram track in the streets — that splits its stations into two classes, no
    vehicle class can drive a line from one to the other, and netconvert drops every ``railway=tram_stop``
    beside light-rail track (no compatible lane). The option adds railsim's type file
    (:func:`light_rail_as_tram_types`) that makes ``railway.light_rail`` a ``tram`` track. The import names the
    case when it sees stations of both classes.
``--railway.topology.repair.minimal``
    Repair the OSM track graph only as far as the OSM lines need it (missing connections, a direction error
    on a line's way), and add as few ``bidi`` edges as it can. The tutorial's ``--railway.topology.all-bidi``
    (and the plain ``repair``) make *both* tracks of a double-track line ``bidi`` far more often; railsim then
    has to work out which track each direction should use. Minimal repair keeps OSM's own one-way tracks.
    An extract **without route relations** gives minimal repair nothing to follow. ``RAILSIM_OSM_REPAIR=full``
    then runs netconvert a second time with the full ``--railway.topology.repair``, which joins more tracks
    that meet without a connection at the price of more ``bidi`` edges (on São Paulo's extract it joined
    nothing a timetable needed and made line 1 single track in places, so it is not the default).
``--railway.topology.repair.stop-turn``
    A turnaround connection at every stop: a unit can reverse at a terminus platform (railsim's turnbacks
    between trips need a connection from an edge onto its bidi partner; a dead-end terminus has none).
``--railway.signals.discard``
    railsim runs its own interlocking and strips SUMO's rail signals anyway (``network.external``);
    discarding them here saves the second netconvert pass.
``--ptstop-output`` / ``--ptline-output``
    The stops (``trainStop``/``busStop`` on the track, from OSM stop positions and platforms) and the lines
    (from OSM route relations: name, ref, vClass, stop sequence, route edges). The tutorial's
    ``--ptline-clean-up`` (drop stops no line serves) is done here afterwards instead, and reported: an
    extract without route relations (many are cut without them) would otherwise lose every stop.
``--output.street-names``
    Edges keep the OSM track name, so ``railsim network show`` and SUMO's GUI read like the map.

Not used, and why: ``--no-internal-links`` (the tutorial's speed-up) — railsim measures routes along the
internal lanes of junctions, so they stay; ``--railway.signal.guess.by-stops`` — no signals are wanted.
``.pbf`` input: the wheel's netconvert is built without PBF support (it reads OSM XML and ``.osm.gz``); a
``.pbf`` is refused with the command that converts it (``osmium cat FILE -o FILE.osm``).

**What is written** to ``--out`` (names from the input file, ``<name>``): ``<name>.net.xml``; one stops file per
rail class, ``<name>.stops.<class>.add.xml`` (each stop in the file of the rail class its lane allows — SUMO's
ptstop output mixes tram, metro and train stops, and railsim runs one class per scenario); ``<name>.lines.yaml``
(the lines: id, ref, name, class, stop sequence with station names, in both directions when OSM has both);
``<name>.stations.yaml`` (each station: name, class, stop ids, lon/lat of its platforms' centre — what the
GTFS import matches against); ``<name>.import.yaml`` (the summary below) and ``netconvert.log``.

**Stops are completed** before they are written: a station OSM maps with a stop position on one track only
gets a copy on the opposite track within :data:`~network.osm_stops.TWIN_RADIUS_M`, unless that track has a platform of the station
just before or after (staggered stops; :func:`network.osm_stops.twin_stops`); a stop on an edge shorter
than a platform moves to the end of the single edge before it (:func:`network.osm_stops.move_off_short_edges`); a stop shorter
than :data:`~network.osm_stops.MIN_STOP_M` (netconvert writes some tram stops 0 m long) — or than ``platform_m`` when the import
asks for it (OSM maps a stop position, not the platform's length: trams coupled in pairs need longer platforms
than one unit) — is widened around its centre within its lane; stops no line serves are dropped when the extract
has lines. Each is counted in the summary.

**The summary** (:class:`ImportSummary`, printed by the CLI): lines per class, stations per class, km of track
(a ``bidi`` pair counted once), switches (nodes where a rail track diverges or merges), the bidi share of the
track length, and what was dropped and why (lines of road classes, lines without a stop in the extract,
stops no line serves, and netconvert's own warnings grouped by kind).

**Cache**: the result is stored under ``$RAILSIM_CACHE/networks/osm-<key>`` where the key hashes the input
file's bytes, the options, :data:`OSM_IMPORT_VERSION` and the SUMO version; a second import of the same file
with the same options copies the cached files (no netconvert).
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import re
import shutil
import subprocess
import tempfile
import time
import xml.etree.ElementTree as ET
from collections import Counter, defaultdict
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import yaml

from network.build import cache_root
from network.generator import netconvert_binary, sumo_version
from network.geo import net_to_lonlat, read_location
from network.osm_check import check_input, check_osm_content, input_name
from network.osm_glued_tracks import separate
from network.osm_stops import (
    MIN_STOP_M,
    RAIL_CLASSES,
    UNNAMED_RADIUS_M,
    Stop,
    ensure_length,
    lane_class,
    move_off_short_edges,
    name_unnamed_stops,
    osm_named_stops,
    twin_stops,
)
from railsim.errors import ConfigError

log = logging.getLogger(__name__)

OSM_IMPORT_VERSION = "11"  # bump when the options, the checks or the outputs change (invalidates the cache)
_WARN_SUMMARY = re.compile(r"^Warning: (\d+) total messages of type: (.*)$")


@dataclass
class ImportSummary:
    """What an import found (``<name>.import.yaml``); counts per rail class where it matters."""

    name: str
    seconds: float
    cached: bool
    lines: dict[str, int] = field(default_factory=dict)  # class -> lines (both directions of a ref count once)
    line_refs: dict[str, list[str]] = field(default_factory=dict)  # class -> line refs
    stations: dict[str, int] = field(default_factory=dict)  # class -> stations (stops grouped by name)
    stops: dict[str, int] = field(default_factory=dict)  # class -> stops kept
    track_km: float = 0.0
    switches: int = 0
    bidi_share: float = 0.0
    files: dict[str, str] = field(default_factory=dict)
    dropped: list[str] = field(default_factory=list)
    separated: list[str] = field(default_factory=list)  # glued pairs of one-way tracks (network.osm_glued_tracks)

    def text(self) -> str:
        """The printed summary: one line per fact."""
        out = [f"{self.name}: imported in {self.seconds:.1f} s{' (cached)' if self.cached else ''}"]
        for vc in sorted(set(self.lines) | set(self.stations)):
            refs = ", ".join(self.line_refs.get(vc, [])) or "-"
            out.append(
                f"  {vc}: {self.lines.get(vc, 0)} lines ({refs}), {self.stations.get(vc, 0)} stations, "
                f"{self.stops.get(vc, 0)} stops"
            )
        out.append(
            f"  track {self.track_km:.1f} km, {self.switches} switches, bidi {100 * self.bidi_share:.0f} % of the track"
        )
        for kind, path in self.files.items():
            out.append(f"  {kind}: {path}")
        if self.separated:
            out.append("  double track drawn on shared nodes, kept two tracks:")
            out += [f"    {d}" for d in self.separated]
        if self.dropped:
            out.append("  dropped:")
            out += [f"    {d}" for d in self.dropped]
        return "\n".join(out)


LIGHT_RAIL_AS_TRAM_TYPES = "light_rail_as_tram.typ.xml"


def light_rail_as_tram_types() -> str:
    """railsim's netconvert type file for ``--light-rail-as-tram``: ``railway.light_rail`` is ``tram`` track
    (SUMO's own entry, with the class changed; later type files override earlier ones of the same id)."""
    return (
        "<types>\n"
        '    <type id="railway.light_rail" numLanes="1" speed="27.78" priority="19" oneway="true" allow="tram"/>\n'
        "</types>\n"
    )


def netconvert_args(
    osm_file: Path,
    out: Path,
    name: str,
    bbox: Sequence[float] | None,
    repair: str = "minimal",
    light_rail_as_tram: bool = False,
) -> list[str]:
    """The netconvert command line for ``osm_file`` (module docstring: each option and why); ``repair`` is
    ``minimal`` (the extract has rail lines) or ``full`` (it has none: nothing for a minimal repair to follow);
    ``light_rail_as_tram`` adds ``out/``:data:`LIGHT_RAIL_AS_TRAM_TYPES` (the caller writes it)."""
    typemap = netconvert_binary().parents[1] / "data" / "typemap"
    types = [typemap / "osmNetconvert.typ.xml", typemap / "osmNetconvertExtraRail.typ.xml"]
    if light_rail_as_tram:
        types.append(out / LIGHT_RAIL_AS_TRAM_TYPES)
    args = [
        str(netconvert_binary()),
        "--osm-files",
        str(osm_file),
        "--type-files",
        ",".join(str(t) for t in types),
        "--keep-edges.by-vclass",
        ",".join(RAIL_CLASSES),
        "--railway.topology.repair.minimal" if repair == "minimal" else "--railway.topology.repair",
        "true",
        "--railway.topology.repair.stop-turn",
        "true",
        "--railway.signals.discard",
        "true",
        "--ptstop-output",
        str(out / f"{name}.ptstops.xml"),
        "--ptline-output",
        str(out / f"{name}.ptlines.xml"),
        "--output.street-names",
        "true",
        "--no-warnings",
        "false",
        "--aggregate-warnings",
        "5",
        "-o",
        str(out / f"{name}.net.xml"),
    ]
    if bbox is not None:
        args += ["--keep-edges.in-geo-boundary", ",".join(f"{v:.7f}" for v in bbox)]
    return args


def parse_bbox(text: str | None) -> tuple[float, float, float, float] | None:
    """``W,S,E,N`` in degrees -> a tuple (ConfigError on anything else)."""
    if text is None:
        return None
    parts = text.split(",")
    try:
        w, s, e, n = (float(p) for p in parts)
    except ValueError:
        raise ConfigError("<command line>", "--bbox", f"expected W,S,E,N in degrees, got {text!r}") from None
    if not (-180 <= w < e <= 180 and -90 <= s < n <= 90):
        raise ConfigError("<command line>", "--bbox", f"expected W < E and S < N within lon/lat ranges, got {text!r}")
    return (w, s, e, n)


def _file_hash(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _cache_key(
    osm_file: Path,
    bbox: Sequence[float] | None,
    lines: Sequence[str] | None,
    light_rail_as_tram: bool = False,
    platform_m: float | None = None,
) -> str:
    options = {"platform_m": platform_m} if platform_m else {}  # (absent by default: earlier keys stay valid)
    payload = json.dumps(
        options
        | {
            "input": _file_hash(osm_file),
            "name": input_name(osm_file),  # the files are named after it: a renamed copy is its own entry
            "light_rail_as_tram": light_rail_as_tram,
            "bbox": list(bbox) if bbox else None,
            "lines": sorted(lines) if lines else None,
            "version": OSM_IMPORT_VERSION,
            "sumo": sumo_version(),
        },
        sort_keys=True,
    )
    return hashlib.sha256(payload.encode()).hexdigest()[:24]


def _has_rail_lines(ptlines: Path) -> bool:
    return any(ln["vclass"] in RAIL_CLASSES for ln in _read_lines(ptlines))


def _run_netconvert(
    osm_file: Path, work: Path, name: str, bbox: Sequence[float] | None, light_rail_as_tram: bool = False
) -> list[str]:
    """Run netconvert (minimal repair; again with full repair when no rail line came out); its warnings on
    success, a ConfigError naming SUMO's error otherwise."""
    if light_rail_as_tram:
        (work / LIGHT_RAIL_AS_TRAM_TYPES).write_text(light_rail_as_tram_types(), encoding="utf-8")
    warnings = _netconvert_once(osm_file, work, name, bbox, "minimal", light_rail_as_tram)
    if _has_rail_lines(work / f"{name}.ptlines.xml") or os.environ.get("RAILSIM_OSM_REPAIR") != "full":
        return warnings
    log.info("%s: no rail lines in the extract: repairing the whole track topology", osm_file.name)
    return _netconvert_once(osm_file, work, name, bbox, "full", light_rail_as_tram)


def _netconvert_once(
    osm_file: Path,
    work: Path,
    name: str,
    bbox: Sequence[float] | None,
    repair: str,
    light_rail_as_tram: bool = False,
) -> list[str]:
    args = netconvert_args(osm_file, work, name, bbox, repair, light_rail_as_tram)
    try:
        proc = subprocess.run(args, capture_output=True, text=True, timeout=1800)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise ConfigError(osm_file, None, f"netconvert could not run: {exc}") from None
    text = proc.stdout + proc.stderr
    (work / "netconvert.log").write_text(" ".join(args) + "\n\n" + text, encoding="utf-8")
    if proc.returncode != 0 or not (work / f"{name}.net.xml").exists():
        errors = [ln for ln in text.splitlines() if ln.startswith("Error")]
        raise ConfigError(
            osm_file, None, "netconvert refused it: " + (" | ".join(errors[:3]) or text.strip()[-300:] or "no output")
        )
    return [ln for ln in text.splitlines() if ln.startswith("Warning")]


def _read_lines(ptlines: Path) -> list[dict[str, Any]]:
    if not ptlines.exists():
        return []
    out = []
    for ln in ET.parse(ptlines).getroot().iter("ptLine"):
        stops = [(s.get("id", ""), s.get("name", "")) for s in ln if s.tag in ("busStop", "trainStop")]
        route = ln.find("route")
        out.append(
            {
                "id": ln.get("id", ""),
                "ref": ln.get("line", "") or ln.get("id", ""),
                "name": ln.get("name", ""),
                "vclass": ln.get("vClass", ""),
                "stops": stops,
                "route_edges": len((route.get("edges") or "").split()) if route is not None else 0,
            }
        )
    return out


def _track_stats(net: Any) -> tuple[float, int, float]:
    """(km of rail track, switches, bidi share of the length) of a rail-only net.

    A bidi pair is one track. A switch is a node where a rail edge leads to two or more rail edges, or two or
    more rail edges lead to one (turnarounds onto an edge's own bidi partner do not count)."""
    rail = {
        e.getID(): e
        for e in net.getEdges(withInternal=False)
        if any(lane_class(set(ln.getPermissions())) for ln in e.getLanes())
    }
    total = bidi = 0.0
    seen: set[str] = set()
    for eid, e in rail.items():
        if eid in seen:
            continue
        seen.add(eid)
        total += e.getLength()
        partner = e.getBidi()
        if partner is not None:
            seen.add(partner.getID())
            bidi += e.getLength()
    switches = 0
    for node in net.getNodes():
        sources: dict[str, set[str]] = defaultdict(set)
        diverge = False
        for e in node.getIncoming():
            if e.getID() not in rail:
                continue
            outs = {t.getID() for t in e.getOutgoing() if t.getID() in rail and t is not e.getBidi()}
            diverge |= len(outs) > 1
            for t in outs:
                sources[t].add(e.getID())
        switches += int(diverge or any(len(v) > 1 for v in sources.values()))
    return total / 1000.0, switches, (bidi / total if total else 0.0)


def _split(
    work: Path,
    name: str,
    lines_wanted: Sequence[str] | None,
    warnings: list[str],
    osm_file: Path | None = None,
    platform_m: float | None = None,
) -> ImportSummary:
    """Split the ptstops by class, write lines/stations YAML and the summary (files stay in ``work``)."""
    import sumolib

    net = sumolib.net.readNet(str(work / f"{name}.net.xml"), withInternal=False)
    loc = read_location(work / f"{name}.net.xml")
    summary = ImportSummary(name=name, seconds=0.0, cached=False)
    stops_tree = ET.parse(work / f"{name}.ptstops.xml") if (work / f"{name}.ptstops.xml").exists() else None
    stops: dict[str, Stop] = {}
    off_rail = 0
    for elem in stops_tree.getroot() if stops_tree is not None else []:
        if elem.tag not in ("busStop", "trainStop"):
            continue
        try:
            lane = net.getLane(elem.get("lane", ""))
        except KeyError:
            off_rail += 1
            continue
        vc = lane_class(set(lane.getPermissions()))
        if vc is None:
            off_rail += 1
            continue
        stops[elem.get("id", "")] = Stop(elem, vc, elem.get("name") or elem.get("id") or "")
    if off_rail:
        summary.dropped.append(f"{off_rail} stops on lanes of no rail class (bus stops on streets)")
    n_unnamed = sum(1 for st in stops.values() if not st.elem.get("name"))
    if n_unnamed:
        named = name_unnamed_stops(net, loc, stops, osm_named_stops(osm_file) if osm_file is not None else [])
        summary.dropped.append(
            f"{n_unnamed} stops without a name in OSM: {named} named after a named stop or platform within "
            f"{UNNAMED_RADIUS_M:g} m, {n_unnamed - named} called 'stop <id>'"
        )
    all_lines = _read_lines(work / f"{name}.ptlines.xml")
    road = Counter(ln["vclass"] for ln in all_lines if ln["vclass"] not in RAIL_CLASSES)
    if road:
        summary.dropped.append("lines of road classes: " + ", ".join(f"{n} {vc}" for vc, n in sorted(road.items())))
    rail_lines = [ln for ln in all_lines if ln["vclass"] in RAIL_CLASSES]
    if lines_wanted:
        wanted = {w.strip() for w in lines_wanted}
        missing = wanted - {ln["ref"] for ln in rail_lines}
        if missing:
            known = sorted({ln["ref"] for ln in rail_lines})
            raise ConfigError(
                "<command line>", "--lines", f"no rail line {sorted(missing)} in the extract; its lines: {known}"
            )
        rail_lines = [ln for ln in rail_lines if ln["ref"] in wanted]
    kept_lines = []
    short: set[str] = set()
    for ln in rail_lines:
        seq = [(sid, nm) for sid, nm in ln["stops"] if sid in stops]
        if len({stops[sid].name for sid, _ in seq}) < 2:
            short.add(ln["ref"])
            continue
        kept_lines.append({**ln, "stops": seq})
    if short:
        summary.dropped.append(
            f"{len(short)} rail lines with fewer than 2 of their stops in the extract: {', '.join(sorted(short))}"
        )
    served = {sid for ln in kept_lines for sid, _ in ln["stops"]}
    if kept_lines:  # the tutorial's --ptline-clean-up, reported: stops no kept line serves go
        unserved = [sid for sid in stops if sid not in served]
        if unserved:
            summary.dropped.append(f"{len(unserved)} stops no imported line serves")
        stops = {sid: st for sid, st in stops.items() if sid in served}
    twins = twin_stops(net, stops)
    if twins:
        summary.dropped.append(
            f"{twins} platforms added on the opposite track of stations OSM maps with a stop on one track only"
        )
    moved = move_off_short_edges(net, stops)
    if moved:
        summary.dropped.append(
            f"{moved} stops on edges shorter than a platform moved back to the end of the single edge before them"
        )
    by_class: dict[str, list[Stop]] = defaultdict(list)
    lengthened = 0
    for st in stops.values():
        by_class[st.vclass].append(st)
        lengthened += ensure_length(st, net.getLane(st.elem.get("lane", "")).getLength(), platform_m)
    if lengthened:
        to = f"{platform_m:g} m" if platform_m else f"{MIN_STOP_M['tram']:g} m (tram) / {MIN_STOP_M['other']:g} m"
        summary.dropped.append(
            f"{lengthened} stops shorter than a platform (netconvert gives some tram stops 0 m) widened around "
            f"their centre to {to}, within their lane"
        )
    for vc, members in sorted(by_class.items()):
        root = ET.Element("additional")
        for st in members:
            elem = ET.SubElement(root, "trainStop", {k: v for k, v in st.elem.attrib.items() if k != "lines"})
            del elem  # attributes copied; trainStop for every rail class (railsim reads both tags)
        ET.indent(root, space="    ")
        path = work / f"{name}.stops.{vc}.add.xml"
        ET.ElementTree(root).write(path, encoding="utf-8", xml_declaration=True)
        summary.files[f"stops ({vc})"] = path.name
        summary.stops[vc] = len(members)
        summary.stations[vc] = len({st.name for st in members})
    if summary.stations.get("tram") and summary.stations.get("rail_urban"):
        summary.dropped.append(
            f"stations on tram track ({summary.stations['tram']}) and on light-rail track "
            f"({summary.stations['rail_urban']}): if one fleet runs on both (a Stadtbahn), import with "
            "--light-rail-as-tram"
        )
    stations = _stations(net, loc, stops)
    (work / f"{name}.stations.yaml").write_text(
        yaml.safe_dump({"stations": stations}, sort_keys=False, allow_unicode=True), encoding="utf-8"
    )
    lines_doc = _lines_doc(kept_lines, stops)
    (work / f"{name}.lines.yaml").write_text(
        yaml.safe_dump({"lines": lines_doc}, sort_keys=False, allow_unicode=True, width=120), encoding="utf-8"
    )
    for doc in lines_doc:
        summary.line_refs.setdefault(doc["class"], []).append(doc["ref"])
    summary.lines = {vc: len(refs) for vc, refs in summary.line_refs.items()}
    summary.track_km, summary.switches, summary.bidi_share = _track_stats(net)
    for warning in warnings:
        m = _WARN_SUMMARY.match(warning)
        if m:
            summary.dropped.append(f"netconvert: {m.group(1)} x {m.group(2)}")
    summary.files.update(
        {
            "net": f"{name}.net.xml",
            "lines": f"{name}.lines.yaml",
            "stations": f"{name}.stations.yaml",
            "log": "netconvert.log",
        }
    )
    return summary


def _stations(net: Any, loc: Any, stops: dict[str, Stop]) -> list[dict[str, Any]]:
    """Stations (stops grouped by class and name) with the lon/lat of their platforms' centre."""
    from sumolib.geomhelper import positionAtShapeOffset

    groups: dict[tuple[str, str], list[tuple[str, float, float]]] = defaultdict(list)
    for sid, st in stops.items():
        lane = net.getLane(st.elem.get("lane", ""))
        start = float(st.elem.get("startPos", 0.0))
        end = float(st.elem.get("endPos", lane.getLength()))
        x, y = positionAtShapeOffset(lane.getShape(), 0.5 * (start + end))[:2]
        groups[(st.vclass, st.name)].append((sid, x, y))
    out = []
    for (vc, nm), members in sorted(groups.items()):
        x = sum(m[1] for m in members) / len(members)
        y = sum(m[2] for m in members) / len(members)
        row: dict[str, Any] = {"name": nm, "class": vc, "stops": [m[0] for m in members]}
        if loc is not None:
            lon, lat = net_to_lonlat(loc, x, y)
            row["lon"], row["lat"] = round(lon, 7), round(lat, 7)
        out.append(row)
    return out


def _lines_doc(lines: list[dict[str, Any]], stops: dict[str, Stop]) -> list[dict[str, Any]]:
    """The lines YAML: one entry per ref and class, its directions (OSM route relations) with station names."""
    by_ref: dict[tuple[str, str], list[dict[str, Any]]] = defaultdict(list)
    for ln in lines:
        by_ref[(ln["vclass"], ln["ref"])].append(ln)
    out = []
    for (vc, ref), variants in sorted(by_ref.items()):
        directions = []
        for v in variants:
            names = [stops[sid].name for sid, _ in v["stops"]]
            directions.append(
                {
                    "osm_relation": v["id"],
                    "name": v["name"],
                    "from": names[0],
                    "to": names[-1],
                    "stations": names,
                    "stops": [sid for sid, _ in v["stops"]],
                }
            )
        out.append({"ref": ref, "class": vc, "directions": directions})
    return out


def import_osm(
    osm_file: str | Path,
    out_dir: str | Path,
    *,
    bbox: Sequence[float] | None = None,
    lines: Sequence[str] | None = None,
    light_rail_as_tram: bool = False,
    platform_m: float | None = None,
) -> ImportSummary:
    """Import an OSM file into ``out_dir`` (module docstring); cached by input hash and options. ``platform_m``:
    the length every stop is widened to (within its lane) when shorter; default :data:`~network.osm_stops.MIN_STOP_M`."""
    t0 = time.perf_counter()
    osm_path = Path(osm_file).resolve()
    check_input(osm_path)
    name = re.sub(r"[^A-Za-z0-9_.-]+", "_", input_name(osm_path))
    key = _cache_key(osm_path, bbox, lines, light_rail_as_tram, platform_m)
    folder = cache_root() / f"osm-{key}"
    summary_file = folder / f"{name}.import.yaml"
    cached = summary_file.exists()
    if not cached:
        folder.parent.mkdir(parents=True, exist_ok=True)
        check_osm_content(osm_path)
        work = Path(tempfile.mkdtemp(prefix=f".osm-{key}-", dir=folder.parent))
        try:
            glued = separate(osm_path, work)  # two one-way tracks drawn on shared nodes, kept two tracks
            warnings = _run_netconvert(glued.source, work, name, bbox, light_rail_as_tram)
            if glued.source != osm_path:
                glued.source.unlink()
            summary = _split(work, name, lines, warnings, osm_path, platform_m)
            summary.separated = [
                f"ways {a} and {b}: one-way tracks drawn on shared nodes, kept two tracks" for a, b in glued.pairs
            ]
            (work / f"{name}.import.yaml").write_text(yaml.safe_dump(asdict(summary), sort_keys=False), "utf-8")
            try:
                os.replace(work, folder)
            except OSError:  # another process published the same key first
                pass
        finally:
            shutil.rmtree(work, ignore_errors=True)
    data = yaml.safe_load(summary_file.read_text(encoding="utf-8"))
    summary = ImportSummary(**data)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    for path in folder.iterdir():
        if path.name.endswith((".ptstops.xml", ".ptlines.xml")) or path.name == LIGHT_RAIL_AS_TRAM_TYPES:
            continue  # netconvert's raw outputs stay in the cache; the split files are what a user needs
        shutil.copyfile(path, out / path.name)
    summary.cached = cached
    summary.seconds = time.perf_counter() - t0
    summary.files = {k: str(out / v) for k, v in summary.files.items()}
    if not summary.stops:
        log.warning("%s: no rail stops in the extract: the net has no stations", osm_path.name)
    return summary


def stop_files(world_dir: Path) -> dict[str, Path]:
    """``{rail class: stops file}`` of an imported world folder."""
    out = {}
    for path in sorted(world_dir.glob("*.stops.*.add.xml")):
        vc = path.name.rsplit(".stops.", 1)[1].removesuffix(".add.xml")
        out[vc] = path
    return out
