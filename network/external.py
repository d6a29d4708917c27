"""Bring your own SUMO rail network: an existing ``.net.xml`` (+ additional files) read into a NetworkBundle.

Users already have SUMO rail networks: OpenStreetMap imports made with netconvert, networks drawn in netedit,
inherited studies. :func:`load_net` reads one **read-only** and discovers what the engine needs, in the same
:class:`~network.topology.NetworkBundle` contract as our generated worlds (see :mod:`network.topology`):

* **Rail edges** are the normal edges with a lane that allows the chosen rail vClass and not ``passenger``
  cars (a road lane: SUMO's default "allow everything", or an OSM street type that forgets to disallow
  ``subway``; a ``tram`` may share a street lane) (``vclass``; by default
  the rail class allowed on the most stop lanes, then on the most edges, preferring ``rail_urban``). Only
  ``rail, rail_urban, rail_electric, rail_fast, subway, tram`` are train classes railsim drives (SUMO 1.28 has
  no ``monorail``: OSM monorails import as ``rail_urban``).
* **The track graph**: nodes = those edges (``length_m``, ``speed_mps`` of the allowed lane, ``bidi`` partner,
  ``direction`` = compass heading of the edge, ``heading_in``/``heading_out`` = heading [rad] where it ends/
  starts, ``stops`` = the platforms on it), graph edges = SUMO
  connections between allowed lanes, with their internal lanes (``via``, so route chainage equals SUMO's
  odometer). Turnaround connections (``dir="t"``, and any connection onto an edge's own ``bidi`` partner) are
  left out of the graph, so a *service* route never reverses; the turnarounds SUMO can drive (a connection
  from an edge onto its own ``bidi`` partner) are kept aside in ``graph.graph["reversals"]``
  (``{edge: [bidi edge, via]}``): the turnback of a unit between two trips (``railsim.engine.turnback``)
  reverses there, the way SUMO reverses a train (it flips the train on the bidi edge when it stands).
* **Switches** are SUMO nodes where a track *diverges* (one incoming rail edge with connections to two or more
  outgoing ones) or *merges* (two or more incoming edges connected to one outgoing edge); there is one
  :class:`~network.topology.SwitchInfo` per direction of travel. The **normal leg** is the straightest one
  (smallest heading change across the node, ties broken by the higher speed, then by edge id); every other
  leg is ``reverse``. On ``bidi`` track the diverge in one direction and the merge in the other are the *same
  physical turnout*: they become **one** switch (one lock), whose id both directions' connections carry, so
  the interlocking never lets two opposing trains use the points at once. Switch ids are the SUMO node id, or
  ``<node>/<trunk edge>`` where a node has several switches. A connection can be a leg of two switches: out of
  an edge that diverges onto an edge that others merge into. It carries both (the second in ``also``), and a
  route through it locks both: with the diverge alone, a train on it and one on the merge's other leg were each
  given their own points and met in the junction (Jena, node ``1831585450``). Throw time: ``throw_time_s`` (a
  net has none); diverging and normal speeds come from the connections' internal lanes.
* **Stations** come from the ``trainStop`` and ``busStop`` elements of the additional files, grouped into
  stations by their ``name`` (id = the name in lower case with ``-`` for other characters; a stop without a
  name is a station of its own, id = stop id). A scenario may name a station by that id, by its name or by
  the id of any of its stops (:attr:`NetworkBundle.station_aliases`). A platform's ``direction`` is the compass
  heading of travel along it (``"E"``, ``"NW"``...). A ``trainStop`` that is not on a rail edge is an error; a
  ``busStop`` on a road lane is a bus stop and is skipped.
* **Routes** (:meth:`NetworkBundle.route_between`) choose, among the platforms of every station named, the
  combination with a path in the direction of travel and the shortest length (Dijkstra on metres). Routes
  listed in the bundle (``railsim network show``) are those between every ordered pair of stations (up to
  :data:`MAX_LISTED_STATIONS` stations by ``route_between``, up to :data:`MAX_ROUTED_STATIONS` by one search per
  platform; beyond, none, and ``graph.graph["routes_note"]`` says why).
* **Line chainage** (what a generated world's line description gives: a ``line`` and a ``km`` per station, so
  the line studies — sections, UIC 406 capacity, the train graph, the report — work on a user's net too):
  :func:`network.chainage.line_chainage` takes the listed route along the most stations as the ``main`` line, km = distance
  along that route from its first station's platform centre (its direction of travel is ``up``, the opposite
  ``down``), and places the stations left on ``branch1``, ``branch2``... from the nearest station already
  placed. Nets with more stations than :data:`MAX_ROUTED_STATIONS` get none (``line`` "", ``km`` 0). There are
  no gradients (SUMO elevation is not read) and no named points; no topology JSON is written (the bundle's
  ``topology_file`` is the user's net, and reading a net again costs one sumolib parse).
* **Flat crossings**: foe movements inside one node that share no track, from SUMO's own foe matrix
  (``graph.graph["crossings"]``, :func:`network.net_crossings.mark_crossings`); the engine interlocks them, and single track, as
  route resources (docs/model.md, "Interlocking").

**Rail signals** (``signals``). Measured with SUMO 1.28 (``shared/notes/sumo_rail_findings.md``): fixed-block
signals hold virtually coupled followers back; moving-block arbitration is not platoon-aware (a crossing
train cut a platoon: a collision); overriding signal states through libsumo segfaults SUMO. So:

* ``strip`` (default): railsim simulates a copy of the net made with ``netconvert -s NET
  --railway.signals.discard`` (which works on .net.xml input, not on plain XML), stored in the network cache
  under the hash of the input files; our interlocking takes over every junction. The user's file is never
  changed.
* ``keep``: SUMO's signals stay, for trains railsim does not control (vehicles in the user's additional
  files). railsim's own trains run under ``speedMode 32`` and do **not** see those signals (SUMO lets them
  pass red silently), and SUMO's trains do not see our interlocking: mixing them is at the user's risk.

The choice is logged. Everything a user can get wrong raises :class:`railsim.errors.ConfigError` naming the
file and field: an unreadable net (not XML, not a ``<net>``, or a network version newer than this SUMO
writes — SUMO itself would read it without complaint), no rail edges, an unsupported vClass, a trainStop off
the rail network, or SUMO refusing the net or the additional files (a short SUMO run checks them once; the
result is cached).
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import logging
import math
import re
import subprocess
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import networkx as nx

from network.build import cache_root
from network.chainage import line_chainage
from network.generator import netconvert_binary, sumo_version
from network.names import ascii_letters
from network.net_crossings import mark_crossings
from network.net_switches import find_switches
from network.netcheck import check_net_structure
from network.plane import compass, heading_rad
from network.running_side import RUNNING_SIDES, WRONG_LINE_FACTOR, mark_wrong_line
from network.topology import (
    NetworkBundle,
    PlatformInfo,
    RouteInfo,
    StationInfo,
    make_route,
    serves_in_order,
)
from railsim.errors import ConfigError

log = logging.getLogger(__name__)

EXTERNAL_VERSION = "2"  # bump when the way a net is read changes (invalidates the cache)
RAIL_VCLASSES = ("rail_urban", "subway", "rail", "rail_electric", "rail_fast", "tram")  # auto preference order
SIGNAL_MODES = ("strip", "keep")
DEFAULT_THROW_TIME_S = 6.0  # a typical electric point machine (a SUMO net records no throw time)
MAX_LISTED_STATIONS = 30  # up to this many stations bundle.routes asks route_between for every station pair
MAX_ROUTED_STATIONS = 150  # ... up to this many, one search per platform; beyond, no routes (and no line km)
_STOP_TAGS = ("trainStop", "busStop")
INSERTION_CHECKS = "collision leaderGap followerGap junction stop arrivalSpeed speedLimit pedestrian"

Where = tuple[Any, str]  # (source, field prefix) for errors in the options: (scenario, "world") or (cli, "--")


_WARNED: set[str] = set()  # warnings already given in this process (``railsim validate`` reads a net twice)


def _warn_once(message: str, *args: Any) -> None:
    """``log.warning`` once per process for one and the same message: a net read twice warns once."""
    text = message % args if args else message
    if text not in _WARNED:
        _WARNED.add(text)
        log.warning("%s", text)


def _opt(where: Where, name: str) -> str:
    """Field name of option ``name`` in an error: ``world.vclass`` in a scenario, ``--vclass`` on the CLI."""
    return f"--{name}" if where[1] == "--" else f"{where[1]}.{name}"


@dataclass(frozen=True)
class _Stop:
    """One trainStop/busStop element as written in an additional file."""

    tag: str
    id: str
    lane: str
    start_raw: float | None
    end_raw: float | None
    name: str
    file: Path


def _sumo_tool(name: str) -> Path:
    return netconvert_binary().with_name(name)


def _file_hash(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _version_tuple(text: str) -> tuple[int, ...] | None:
    try:
        return tuple(int(x) for x in text.strip().split("."))
    except ValueError:
        return None


def supported_net_version() -> str:
    """The network version this SUMO's netconvert writes (the newest its SUMO reads), probed once and cached."""
    root = cache_root()
    marker = root / f"netversion-{sumo_version()}.txt"
    try:
        return marker.read_text(encoding="utf-8").strip()
    except OSError:
        pass
    with tempfile.TemporaryDirectory(prefix="railsim-netversion-") as tmp:
        t = Path(tmp)
        (t / "p.nod.xml").write_text('<nodes><node id="a" x="0" y="0"/><node id="b" x="100" y="0"/></nodes>\n')
        (t / "p.edg.xml").write_text('<edges><edge id="e" from="a" to="b" allow="rail"/></edges>\n')
        subprocess.run(
            [
                str(netconvert_binary()),
                "-n",
                str(t / "p.nod.xml"),
                "-e",
                str(t / "p.edg.xml"),
                "-o",
                str(t / "p.net.xml"),
            ],
            capture_output=True,
            timeout=120,
            check=True,
        )
        version = _net_root(t / "p.net.xml")[1]
    root.mkdir(parents=True, exist_ok=True)
    marker.write_text(version + "\n", encoding="utf-8")
    return version


def _net_root(net_file: Path) -> tuple[str, str]:
    """(root tag, version attribute) of an XML file, reading only its first element."""
    try:
        for _, elem in ET.iterparse(str(net_file), events=("start",)):
            return elem.tag, elem.get("version", "")
    except ET.ParseError as exc:
        raise ConfigError(net_file, None, f"not a SUMO network: the file is not XML ({exc})") from None
    raise ConfigError(net_file, None, "not a SUMO network: the file is empty")  # pragma: no cover


def check_net_header(net_file: Path) -> None:
    """A ``<net>`` root whose ``version`` this SUMO can read (SUMO 1.28 does not refuse newer versions itself)."""
    tag, version = _net_root(net_file)
    if tag != "net":
        raise ConfigError(net_file, None, f"not a SUMO network: expected a <net> root element, got <{tag}>")
    have = _version_tuple(version)
    newest = supported_net_version()
    if have is None:
        raise ConfigError(net_file, "net.version", f"expected a network version like {newest!r}, got {version!r}")
    if have > (_version_tuple(newest) or ()):
        raise ConfigError(
            net_file,
            "net.version",
            f"network version {version} is newer than this SUMO ({sumo_version()}) reads (up to "
            f"{newest}); re-export it with this SUMO's netconvert or install a newer eclipse-sumo",
        )


def read_stops(additional: Sequence[Path]) -> list[_Stop]:
    """Every trainStop/busStop of the additional files, in file order."""
    out: list[_Stop] = []
    for path in additional:
        try:
            tree = ET.parse(str(path))
        except ET.ParseError as exc:
            raise ConfigError(path, None, f"expected an XML additional file, got a parse error ({exc})") from None
        for elem in tree.getroot().iter():
            if elem.tag not in _STOP_TAGS:
                continue
            sid = elem.get("id")
            lane = elem.get("lane")
            where = f"{elem.tag}[id={sid}]"
            if not sid or not lane:
                raise ConfigError(path, where, "expected the attributes id and lane")
            vals = []
            for key in ("startPos", "endPos"):
                raw = elem.get(key)
                try:
                    vals.append(None if raw is None else float(raw))
                except ValueError:
                    raise ConfigError(path, f"{where}.{key}", f"expected a number, got {raw!r}") from None
            out.append(_Stop(elem.tag, sid, lane, vals[0], vals[1], elem.get("name") or "", path))
    return out


def _slug(text: str) -> str:
    """A station id from a stop name: letters transliterated to ASCII (``Colón`` -> ``colon``, ``Straße`` ->
    ``strasse``: :func:`network.names.ascii_letters`), lower case, ``-`` for anything else."""
    ascii_text = ascii_letters(text)
    return re.sub(r"[^a-z0-9]+", "-", ascii_text.lower()).strip("-")


def _rail_lane(lane: Any, vclass: str, open_as: str | None = None) -> bool:
    """A lane railsim's trains (``vclass``) may use: it allows the class and is not a road lane.

    A road lane is one that also allows ``passenger`` cars: SUMO lanes without an ``allow`` list allow every
    class, and OSM imports' road types disallow only some rail classes (a street in SUMO's A10KW OSM net
    allows ``subway`` and ``rail_fast``), so "allows a rail class" alone would make streets into track. Trams
    run on streets: for ``tram`` a lane shared with cars counts unless it is open to every class (SUMO's
    default, recognised by ``ship``, which no street lists). ``open_as`` (the world option
    ``unrestricted_lanes``) makes such open lanes track of that one rail class: a net drawn without any lane
    permissions (nothing but trains on it) is then usable.
    """
    if open_as is not None and lane.allows("ship"):
        return vclass == open_as
    if not lane.allows(vclass):
        return False
    return not lane.allows("ship") if vclass == "tram" else not lane.allows("passenger")


def _open_lanes_hint(edges: Any, open_as: str | None) -> str:
    """The way past a refusal of a net drawn without lane permissions: name the rail class of its open lanes."""
    n_open = sum(1 for e in edges if any(ln.allows("ship") for ln in e.getLanes()))
    if not n_open or open_as is not None:
        return ""
    return (
        f"; {n_open} edge(s) have lanes without permissions: if they are track, name their rail class with the"
        " world option unrestricted_lanes (e.g. `unrestricted_lanes: rail`; network show: --unrestricted-lanes rail)"
    )


def _choose_vclass(
    net: Any, stops: list[_Stop], vclass: str | None, net_file: Path, where: Where, open_as: str | None = None
) -> str:
    src = where[0]
    if vclass is not None:
        if vclass not in RAIL_VCLASSES:
            raise ConfigError(
                src,
                _opt(where, "vclass"),
                f"expected a rail vClass railsim can drive ({', '.join(RAIL_VCLASSES)}), got {vclass!r}",
            )
    edges = net.getEdges(withInternal=False)
    counts = {
        vc: sum(1 for e in edges if any(_rail_lane(ln, vc, open_as) for ln in e.getLanes())) for vc in RAIL_VCLASSES
    }
    if not any(counts.values()):
        found = sorted({p for e in edges for ln in e.getLanes() for p in ln.getPermissions()})
        raise ConfigError(
            net_file,
            None,
            "no rail edges (vClass " + "/".join(RAIL_VCLASSES) + "): no lane allows any of them "
            "without also allowing passenger cars"
            f" (the lanes allow: {', '.join(found[:8]) + (', ...' if len(found) > 8 else '') if found else 'nothing'})"
            + _open_lanes_hint(edges, open_as),
        )
    if vclass is not None:
        if counts[vclass] == 0:
            usable = [vc for vc in RAIL_VCLASSES if counts[vc]]
            raise ConfigError(
                src,
                _opt(where, "vclass"),
                f"no lane of {net_file.name} allows {vclass!r}; its rail edges allow {', '.join(usable)}",
            )
        return vclass
    lane_ok: dict[str, int] = dict.fromkeys(RAIL_VCLASSES, 0)
    for st in stops:
        ln = _lane(net, st.lane)
        if ln is not None:
            for vc in RAIL_VCLASSES:
                lane_ok[vc] += int(_rail_lane(ln, vc, open_as))
    return max(RAIL_VCLASSES, key=lambda vc: (lane_ok[vc], counts[vc], -RAIL_VCLASSES.index(vc)))


def _lane(net: Any, lane_id: str) -> Any:
    """The sumolib lane ``lane_id`` (``<edge>_<index>``), or None if the net has no such lane."""
    edge_id = lane_id.rsplit("_", 1)[0]
    if not net.hasEdge(edge_id):
        return None
    return next((ln for ln in net.getEdge(edge_id).getLanes() if ln.getID() == lane_id), None)


def _via_chain(net: Any, conn: Any) -> list[list[Any]]:
    """``[internal lane id, length, speed]`` of a connection's internal lanes in travel order."""
    chain: list[list[Any]] = []
    via_id = conn.getViaLaneID()
    while via_id:
        lane = net.getLane(via_id)
        chain.append([via_id, lane.getLength(), lane.getSpeed()])
        nxt = [c.getViaLaneID() for c in lane.getOutgoing() if c.getViaLaneID()]
        via_id = nxt[0] if nxt else ""
    return chain


def _build_graph(
    net: Any, vclass: str, name: str, running_side: str = "right", open_as: str | None = None
) -> nx.DiGraph:
    g = nx.DiGraph(name=name, kind="external", vclass=vclass, gradients={}, points={}, reversals={})
    shapes: dict[str, list[tuple[float, float]]] = {}
    for e in net.getEdges(withInternal=False):
        lanes = [ln for ln in e.getLanes() if _rail_lane(ln, vclass, open_as)]
        if not lanes:
            continue
        ln = lanes[0]
        shape = ln.getShape()
        shapes[e.getID()] = [(float(p[0]), float(p[1])) for p in shape]
        (x0, y0, *_), (x1, y1, *_) = shape[0], shape[-1]
        bidi = e.getBidi()
        g.add_node(
            e.getID(),
            line="",
            direction=compass(x1 - x0, y1 - y0),
            length_m=ln.getLength(),
            speed_mps=ln.getSpeed(),
            from_node=e.getFromNode().getID(),
            to_node=e.getToNode().getID(),
            design_start_m=0.0,
            design_sign=1,
            station=None,
            stop_id=None,
            stop_start_pos_m=None,
            stop_end_pos_m=None,
            stops=[],
            bidi=bidi.getID() if bidi is not None else None,
            heading_in=heading_rad(shape, True),
            heading_out=heading_rad(shape, False),
        )
    for eid in list(g.nodes):
        e = net.getEdge(eid)
        bidi = g.nodes[eid]["bidi"]
        for to_edge, conns in e.getOutgoing().items():
            tid = to_edge.getID()
            if tid == bidi and tid in g:
                turn = [
                    c
                    for c in conns
                    if _rail_lane(c.getFromLane(), vclass, open_as) and _rail_lane(c.getToLane(), vclass, open_as)
                ]
                if turn:
                    g.graph["reversals"][eid] = [tid, _via_chain(net, turn[0])]
                continue
            if tid not in g:
                continue
            usable = [
                c
                for c in conns
                if c.getDirection() != "t"
                and _rail_lane(c.getFromLane(), vclass, open_as)
                and _rail_lane(c.getToLane(), vclass, open_as)
            ]
            if not usable:
                continue
            via = _via_chain(net, usable[0])
            cost = sum(v[1] for v in via) + g.nodes[tid]["length_m"]
            g.add_edge(eid, tid, node=e.getToNode().getID(), via=via, switch=None, leg=None, cost_m=cost)
            g.edges[eid, tid]["link"] = usable[0]  # removed again by mark_crossings (sumolib objects stay out)
    mark_crossings(g, net)
    n_wrong = mark_wrong_line(g, shapes, running_side)
    if n_wrong:
        log.info(
            "%s: %d bidi edges run beside a track of the same direction on the %s: routes keep to their own track",
            name,
            n_wrong,
            running_side,
        )
    return g


def _stations(
    net: Any, g: nx.DiGraph, stops: list[_Stop], vclass: str, open_as: str | None = None
) -> tuple[dict[str, StationInfo], dict[str, str]]:
    """Stations grouped by stop name, their platforms on the graph, and the alias table (name/stop id -> id)."""
    from sumolib.geomhelper import positionAtShapeOffset

    groups: dict[str, list[tuple[_Stop, PlatformInfo]]] = {}
    names: dict[str, str] = {}
    seen: set[str] = set()
    skipped: dict[str, list[str]] = {}  # other rail class -> stop ids on its track
    for st in stops:
        where = f"{st.tag}[id={st.id}]"
        if st.id in seen:
            raise ConfigError(st.file, where, "expected unique stop ids, got a second stop with this id")
        seen.add(st.id)
        lane = _lane(net, st.lane)
        if lane is None:
            raise ConfigError(st.file, f"{where}.lane", f"expected a lane of the network, got {st.lane!r}")
        edge_id = lane.getEdge().getID()
        if edge_id not in g or not _rail_lane(lane, vclass, open_as):
            if st.tag == "busStop":
                log.debug("skipping busStop %s on non-rail lane %s", st.id, st.lane)
                continue
            other = [vc for vc in RAIL_VCLASSES if vc != vclass and _rail_lane(lane, vc, open_as)]
            if other:  # a stop of another rail mode (a tram stop in a metro study): not ours
                skipped.setdefault(other[0], []).append(st.id)
                continue
            perms = ", ".join(sorted(lane.getPermissions())) or "nothing"
            raise ConfigError(
                st.file,
                f"{where}.lane",
                f"expected a lane of a rail edge (allowing {vclass}), got "
                f"{st.lane!r}, which allows {perms}: a station not on any "
                f"rail edge",
            )
        length = lane.getLength()
        start = 0.0 if st.start_raw is None else (st.start_raw if st.start_raw >= 0 else length + st.start_raw)
        end = length if st.end_raw is None else (st.end_raw if st.end_raw >= 0 else length + st.end_raw)
        if not (0.0 <= start < end <= length + 1e-6):
            raise ConfigError(
                st.file, where, f"expected 0 <= startPos < endPos <= {length:g} (lane length), got {start:g}..{end:g}"
            )
        shape = lane.getShape()
        x0, y0 = positionAtShapeOffset(shape, start)[:2]
        x1, y1 = positionAtShapeOffset(shape, end)[:2]
        plat = PlatformInfo(compass(x1 - x0, y1 - y0), st.id, edge_id, start, min(end, length))
        key = st.name or st.id
        groups.setdefault(key, []).append((st, plat))
    if skipped:
        _warn_once(
            "%d stops on track our %s trains do not run on skipped (%s)",
            sum(len(v) for v in skipped.values()),
            vclass,
            "; ".join(f"{vc}: {', '.join(ids[:3])}{', ...' if len(ids) > 3 else ''}" for vc, ids in skipped.items()),
        )
    stations: dict[str, StationInfo] = {}
    aliases: dict[str, str] = {}
    for key, members in groups.items():
        sid = _slug(key) or members[0][0].id
        base, n = sid, 2
        while sid in stations:
            sid, n = f"{base}-{n}", n + 1
        plats = tuple(p for _, p in members)
        stations[sid] = StationInfo(sid, key, "", 0.0, max(p.end_pos_m - p.start_pos_m for p in plats), False, plats)
        names[key] = sid
        for st, p in members:
            aliases[st.id] = sid
            g.nodes[p.edge]["stops"].append([sid, p.stop_id, p.start_pos_m, p.end_pos_m])
    for key, sid in names.items():
        aliases.setdefault(key, sid)
    for sid in stations:
        aliases.setdefault(sid, sid)
    for n in g.nodes:
        g.nodes[n]["stops"].sort(key=lambda s: (s[2], s[1]))
    return stations, aliases


def _preflight(net_file: Path, additional: Sequence[Path], folder: Path) -> None:
    """Let SUMO itself load the net and the additional files for one step (once per cache key)."""
    marker = folder / "sumo_check.ok"
    if marker.exists():
        return

    def run(extra: list[str]) -> list[str]:
        cmd = [
            str(_sumo_tool("sumo")),
            "-n",
            str(net_file),
            *extra,
            "--begin",
            "0",
            "--end",
            "1",
            "--no-step-log",
            "true",
            "--duration-log.disable",
            "true",
            "--no-warnings",
            "true",
        ]
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
        except (OSError, subprocess.TimeoutExpired) as exc:
            return [f"SUMO could not run: {exc}"]
        if proc.returncode == 0:
            return []
        lines = [ln for ln in (proc.stderr + proc.stdout).splitlines() if ln.startswith("Error")]
        return lines or [ln for ln in proc.stderr.splitlines() if ln.strip()][-2:] or ["unknown error"]

    errors = run(["-a", ",".join(str(p) for p in additional)] if additional else [])
    if errors:
        if additional and not run([]):
            raise ConfigError(
                ",".join(str(p) for p in additional),
                None,
                "SUMO cannot load these additional files: " + " | ".join(errors[:3]),
            )
        raise ConfigError(net_file, None, "SUMO cannot read this network: " + " | ".join(errors[:3]))
    folder.mkdir(parents=True, exist_ok=True)
    marker.write_text("ok\n", encoding="utf-8")


def _strip_signals(net_file: Path, out: Path) -> None:
    """railsim's copy of the net without rail signals (``netconvert --railway.signals.discard``)."""
    tmp = out.with_name(out.name + ".tmp.xml")
    cmd = [str(netconvert_binary()), "-s", str(net_file), "--railway.signals.discard", "true", "-o", str(tmp)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    if proc.returncode != 0 or not tmp.exists():
        errs = [ln for ln in (proc.stderr + proc.stdout).splitlines() if ln.startswith("Error")]
        raise ConfigError(
            net_file,
            None,
            "netconvert could not copy it without rail signals: " + (" | ".join(errs[:3]) or "unknown error"),
        )
    tmp.replace(out)


def _read_net(net_file: Path) -> Any:
    import sumolib

    try:
        return sumolib.net.readNet(str(net_file), withInternal=True)
    except Exception as exc:  # sumolib raises SAX/Key/Value errors on malformed nets
        raise ConfigError(net_file, None, f"not a SUMO network sumolib can read: {exc}") from None


def load_net(
    net_file: str | Path,
    additional: Sequence[str | Path] = (),
    *,
    signals: str = "strip",
    vclass: str | None = None,
    throw_time_s: float = DEFAULT_THROW_TIME_S,
    running_side: str = "right",
    unrestricted_lanes: str | None = None,
    where: Where = (None, "world"),
) -> NetworkBundle:
    """Read an existing SUMO net (+ additional files with trainStops) into a :class:`NetworkBundle`.

    ``signals`` is ``strip`` or ``keep`` (module docstring), ``vclass`` the rail vClass railsim's trains get
    (``None``: chosen from the net), ``throw_time_s`` the throw time of every switch, ``running_side`` the side
    trains keep on a double track drawn as two bidi tracks (:mod:`network.running_side`). ``where`` names the
    source and field prefix of these options in error messages (e.g. ``(scenario file, "world")``).
    """
    src = where[0]
    net_file = Path(net_file).resolve()
    adds = tuple(Path(p).resolve() for p in additional)
    for i, p in enumerate((net_file, *adds)):
        if not p.is_file():
            field = _opt(where, "net") if i == 0 else _opt(where, f"additional[{i - 1}]")
            raise ConfigError(src, field, f"expected an existing file, got {str(p)!r}")
    if signals not in SIGNAL_MODES:
        raise ConfigError(src, _opt(where, "signals"), f"expected one of {', '.join(SIGNAL_MODES)}, got {signals!r}")
    if not (isinstance(throw_time_s, (int, float)) and math.isfinite(throw_time_s) and throw_time_s >= 0):
        raise ConfigError(src, _opt(where, "throw_time_s"), f"expected a number >= 0, got {throw_time_s!r}")
    if unrestricted_lanes is not None and unrestricted_lanes not in RAIL_VCLASSES:
        raise ConfigError(
            src,
            _opt(where, "unrestricted_lanes"),
            f"expected a rail vClass ({', '.join(RAIL_VCLASSES)}), got {unrestricted_lanes!r}",
        )
    if running_side not in RUNNING_SIDES:
        raise ConfigError(
            src, _opt(where, "running_side"), f"expected one of {', '.join(RUNNING_SIDES)}, got {running_side!r}"
        )
    check_net_header(net_file)
    check_net_structure(net_file)
    stops = read_stops(adds)
    key_src = "|".join(
        [EXTERNAL_VERSION, sumo_version(), signals, _file_hash(net_file), *(_file_hash(p) for p in adds)]
    )
    key = hashlib.sha256(key_src.encode()).hexdigest()[:24]
    folder = cache_root() / f"external-{key}"

    net = _read_net(net_file)
    n_signals = sum(1 for n in net.getNodes() if n.getType() == "rail_signal")
    sim_net = net_file
    if n_signals and signals == "strip":
        sim_net = folder / net_file.name
        if not sim_net.exists():
            folder.mkdir(parents=True, exist_ok=True)
            _strip_signals(net_file, sim_net)
        net = _read_net(sim_net)
        log.info(
            "%s: %d rail signals stripped in railsim's copy %s (signals: strip); our interlocking takes over",
            net_file.name,
            n_signals,
            sim_net,
        )
    elif n_signals:
        _warn_once(
            "%s: keeping %d SUMO rail signals (signals: keep): railsim's trains do not obey them and "
            "SUMO-driven trains do not obey railsim's interlocking",
            net_file.name,
            n_signals,
        )
    else:
        log.info("%s: no rail signals (signals: %s has nothing to do)", net_file.name, signals)
    chosen = _choose_vclass(net, stops, vclass, net_file, where, unrestricted_lanes)
    name = net_file.name.removesuffix(".xml").removesuffix(".net")
    graph = _build_graph(net, chosen, name, running_side, unrestricted_lanes)
    graph.graph["signals"] = {"mode": signals, "count": n_signals}
    switches = find_switches(graph, throw_time_s)
    stations, aliases = _stations(net, graph, stops, chosen, unrestricted_lanes)
    _preflight(sim_net, adds, folder)  # last: our own checks give the more precise messages
    stops_file = next((p for p in adds if any(s.file == p for s in stops)), adds[0] if adds else net_file)
    bundle = NetworkBundle(
        name,
        sim_net,
        stops_file,
        net_file,
        graph,
        stations,
        switches,
        {},
        cache_key=key,
        additional_files=adds,
        vclass=chosen,
        station_aliases=aliases,
        signals=signals,
        n_rail_signals=n_signals,
    )
    routes = {}
    if len(stations) <= MAX_LISTED_STATIONS:
        for a, b in itertools.permutations(stations, 2):
            try:
                r = bundle.route_between(a, b)
            except ValueError:
                continue
            routes[r.id] = r
    elif len(stations) <= MAX_ROUTED_STATIONS:
        routes = _routes_one_search_per_platform(bundle)
    else:
        note = (
            f"{len(stations)} stations: no routes listed and no line chainage (more than {MAX_ROUTED_STATIONS}: "
            f"{len(stations) * (len(stations) - 1)} station pairs)"
        )
        graph.graph["routes_note"] = note
        log.info("%s: %s", name, note)
    placed = line_chainage(list(stations), routes.values())
    stations = {
        sid: dataclasses.replace(st, line=placed[sid][0], km=placed[sid][1]) if sid in placed else st
        for sid, st in stations.items()
    }
    return dataclasses.replace(bundle, routes=routes, stations=stations)


def _routes_one_search_per_platform(bundle: NetworkBundle) -> dict[str, RouteInfo]:
    """The route between every ordered pair of stations of a net too big for a search per pair: one Dijkstra from
    each platform (the same costs as :meth:`NetworkBundle.route_between`, the wrong line costed up), and for every
    other station the cheapest of its platforms' paths that serves both stations in order (a platform behind the
    first one on the same edge does not)."""
    g = bundle.graph
    routes: dict[str, RouteInfo] = {}
    for a, st in bundle.stations.items():
        found: dict[str, list[tuple[float, list[str]]]] = {}
        for p in st.platforms:
            factor = WRONG_LINE_FACTOR if g.nodes[p.edge].get("wrong_line") else 1.0
            first = float(g.nodes[p.edge]["length_m"]) * factor
            dist, paths = nx.single_source_dijkstra(g, p.edge, weight="cost_m")
            for b, other in bundle.stations.items():
                if b != a:
                    found.setdefault(b, []).extend(
                        (first + dist[q.edge], paths[q.edge]) for q in other.platforms if q.edge in dist
                    )
        for b, candidates in found.items():
            for _, path in sorted(candidates, key=lambda c: c[0]):
                route = make_route(g, f"{a}->{b}", path)
                if serves_in_order(route, (a, b)):
                    routes[route.id] = route
                    break
    return routes
