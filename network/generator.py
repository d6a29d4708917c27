"""Line description -> SUMO plain XML -> netconvert -> .net.xml + trainStops + track graph.

How a line becomes a SUMO net (facts measured in ``shared/notes/sumo_rail_findings.md`` §1):

* **Pieces.** Each line (main line, branches) is cut at *break points*: its ends, the junctions on it, the
  boundaries of speed limits and turnout zones, and one point in the gap between every two platforms (so
  each station owns a piece and every trainStop lies wholly on one edge). Break points inside a platform
  are a :class:`ConfigError`.
* **Edges.** Double track: one one-way edge per piece and direction (``<line>_up_<i>``, ``<line>_down_<i>``)
  between shared nodes with ``spreadType="right"`` (the two tracks are drawn side by side). Single track:
  the same pair with ``spreadType="center"``, which SUMO turns into bidi edges. All edges
  ``allow="rail rail_urban rail_fast rail_electric subway"``; the lane speed is the lowest limit on that
  piece (line speed, speed limits for that direction, switch speeds on the turnout zones).
* **No rail signals.** Plain XML nodes are ``priority``/``dead_end`` and we never ask netconvert to guess
  signals: interlocking is ours (docs/architecture.md). The built net is checked for ``rail_signal`` nodes.
* **Exact chainage.** netconvert's rail junction shapes are long (≈67 m at a turnout) and their internal
  lanes would add to the odometer. We write every connection explicitly with a fixed internal-lane length
  (:data:`INTERNAL_LANE_M`) and give each edge an explicit ``length`` = design length minus the internal
  lane in front of it, so the odometer between two stations equals their design chainage difference.
  Every edge is shortened, also the first one of a line (whose start then lies 0.1 m inside the design
  extent): single-track bidi edge pairs must have equal lengths, or netconvert averages them.
  Explicit connections also rule out any movement we did not intend (no reversal, no branch-to-branch).
* **Turnback tracks.** Every free line end whose outer station has ``turnback: true`` gets a single-track
  (``bidi``) turnback track of :data:`TURNBACK_TRACK_M` beyond the end of the line's overrun: the arriving
  track runs into it, a turnaround connection at its far end lets SUMO reverse a unit there, and its partner
  runs back onto the departing track. The track graph gets its two edges (``direction="turnback"``, with
  ``bidi`` partners, so the interlocking treats it as a single-track section) and the turnaround in
  ``graph.graph["reversals"]``; service routes never use it, rotations do (``railsim.engine.turnback``).
  Intermediate turnback stations' crossovers are kept in the topology only.
* **Depot leads.** Each ``depots:`` entry gets a bidi lead track (``<id>_lead`` into the depot,
  ``-<id>_lead`` out of it; :attr:`network.line.Depot.length_m` long, drawn off to the side) joined at one
  node to both running tracks. Per running track one switch (``<id>_up``, ``<id>_down``, an interlocking
  resource with the depot's throw time and speed, like the pocket switches) carries three movements: through
  (normal), into the lead and out of the lead (reverse). A trainStop on each lead edge (``<id>.in`` at the far
  end of the track in, ``<id>.out`` at the line end of the track out) is where a unit ends and starts its day;
  the track graph's lead nodes carry ``station=<id>`` and ``direction="depot"`` (through routes never use
  them) and ``graph.graph["depots"]`` maps each depot id to its name, line, km, the edge a unit starts on
  (``start_edge``) and the one it ends on (``end_edge``) (``railsim.engine.depot``).
* **Flat crossings.** A double-track junction is one node for all four tracks: the track towards the branch
  crosses the opposite main track at grade (the branch lies to one side of the line), and a depot lead joined to
  both tracks at one node has its far track's movements cross the near track. netconvert marks such internal
  lanes as *foes* and SUMO reports a collision when two trains overlap on them; the switches lock one track each
  and do not protect it. :func:`read_net` reads the foe pairs back and ``graph.graph["crossings"]``
  (:func:`network.topology.flat_crossings`) lists them, so the engine interlocks each such node as a crossing.

The result is read back from the .net.xml with sumolib (lane lengths, speeds, internal lanes), so the track
graph and the routes reflect what SUMO will actually simulate.
"""

from __future__ import annotations

import json
import logging
import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import quoteattr

import networkx as nx

from network.line import PLATFORM_CLEARANCE_M, Branch, Depot, LineDescription, Station, SwitchSpec
from network.topology import (
    NetworkBundle,
    PlatformInfo,
    StationInfo,
    SwitchInfo,
    bundle_to_json,
    flat_crossings,
    make_route,
)
from railsim.errors import ConfigError

log = logging.getLogger(__name__)

GENERATOR_VERSION = "6"  # 4: depot leads; 5: flat crossings (graph.graph["crossings"]); 6: depot exit clear
INTERNAL_LANE_M = 0.1  # length of every internal junction lane (what netconvert gives a straight rail node)
ALLOW = "rail rail_urban rail_fast rail_electric subway"
TRACK_WIDTH_M = 3.0
BRANCH_OFFSET_M = 60.0  # lateral drawing offset of a branch from its parent (geometry only)
DIRECTIONS = ("up", "down")
TURNBACK_TRACK_M = 180.0  # a turnback track beyond a terminus: a 6/8-car unit (≤ 120 m) plus margin
POCKET_SPEED_MPS = 30.0 / 3.6  # estimated: pocket switches like the other Line 3 turnouts (data pack, S15)
POCKET_THROW_S = 15.0  # estimated: as the Bijin switches in the shipped world
DEPOT_STOP_MARGIN_M = 5.0  # a depot lead's trainStops end this far from the lead's ends ...
DEPOT_EXIT_CLEAR_M = 60.0  # ... but a unit starts its day this far before the line end: clear of the points it
# waits for (the overlap, and the separation margin of a train that passes on the running track meanwhile)
DEPOT_DRAW_OFFSET_M = 40.0  # the lead's far end lies this far to the side of the line (drawing only)


def netconvert_binary() -> Path:
    """netconvert from the eclipse-sumo wheel (never a system SUMO)."""
    import sumo

    exe = Path(sumo.SUMO_HOME) / "bin" / "netconvert"
    if not exe.exists():  # pragma: no cover - broken installation
        raise ConfigError(None, None, f"netconvert not found at {exe} (is the eclipse-sumo wheel installed?)")
    return exe


def sumo_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("eclipse-sumo")
    except PackageNotFoundError:  # pragma: no cover
        return "unknown"


@dataclass
class _Piece:
    line: str
    index: int
    a_m: float  # design chainage of the low end
    b_m: float
    node_a: str
    node_b: str
    speed_mps: dict[str, float] = field(default_factory=dict)  # direction -> lane speed

    def edge_id(self, direction: str) -> str:
        return f"{self.line}_{direction}_{self.index}"


@dataclass(frozen=True)
class _TurnbackTrack:
    """A bidi turnback track beyond a free line end (module docstring)."""

    line: str
    station: str
    out: str  # edge from the line end into the track
    back: str  # its bidi partner, back to the line
    node: str  # the line end
    far: str  # the track's far end (the turnaround)
    x_m: float  # design chainage of the line end
    sign: float  # +1 beyond the high end, -1 beyond the low end
    arrive_edge: str
    depart_edge: str
    speed_mps: float
    through_arrive: str | None = None  # a pocket: the arriving track's continuation past the pocket's switch
    through_depart: str | None = None  # a pocket: the departing track's feed from beyond the switch


@dataclass(frozen=True)
class _DepotLead:
    """A depot's bidi lead track and the running-track edges it joins at ``node`` (module docstring)."""

    depot: Depot
    node: str
    far: str
    into: str  # node -> far: units end their day on it
    out: str  # far -> node: units start their day on it
    up_in: str  # running-track edges meeting at the node
    up_out: str
    down_in: str
    down_out: str
    speed_mps: float

    def connections(self) -> list[tuple[str, str, str]]:
        """(from edge, to edge, node): into the lead from both tracks, out of it onto both."""
        n = self.node
        return [
            (self.up_in, self.into, n),
            (self.down_in, self.into, n),
            (self.out, self.up_out, n),
            (self.out, self.down_out, n),
        ]


@dataclass
class _Switch:
    spec: SwitchSpec
    direction: str
    node: str
    kind: str
    normal_edge: str
    reverse_edge: str
    trunk_edge: str
    normal_speed_mps: float


class _Plan:
    """Pure geometry: pieces, nodes, switches and stops of a line description (no SUMO involved)."""

    def __init__(self, desc: LineDescription) -> None:
        self.desc = desc
        self.line_speed_mps = desc.line_speed_kmh / 3.6
        self.node_xy: dict[str, tuple[float, float]] = {}
        self.pieces: dict[str, list[_Piece]] = {}
        self.line_y: dict[str, float] = {}
        self.switches: list[_Switch] = []
        self._junction_nodes: dict[tuple[str, float], str] = {}
        self._build_pieces()
        self._assign_speeds()
        self._build_switches()
        self.tails = self._turnback_tracks() + self._pocket_tracks()
        self.leads = self._depot_leads()

    # -- break points -------------------------------------------------------------------------------------
    def _stations_of(self, line: str) -> tuple[Station, ...]:
        d = self.desc
        if line == d.main_line_id:
            return d.stations
        return next(b for b in d.branches if b.id == line).stations

    def _turnout_zones(self) -> list[tuple[str, float, float, str, Branch, str]]:
        """(line, a_m, b_m, direction, branch, leg) for every turnout zone next to a switch point."""
        zones = []
        for b in self.desc.branches:
            j = b.at_km * 1000.0
            t = b.turnout_length_m
            # the branch's own stretch next to the junction, and the parent's stretch on the branch side
            if b.side == "up":
                branch_zone, parent_zone = (j, j + t), (j, j + t)
            else:
                branch_zone, parent_zone = (j - t, j), (j - t, j)
            parent_leg = "normal" if b.leg == "reverse" else "reverse"
            for direction in DIRECTIONS:
                zones.append((b.id, *branch_zone, direction, b, b.leg))
                zones.append((b.joins, *parent_zone, direction, b, parent_leg))
        return zones

    def _break_points(self, line: str) -> list[tuple[float, str]]:
        d = self.desc
        lo_km, hi_km = d.line_extent_km(line)
        pts: list[tuple[float, str]] = [(lo_km * 1000.0, "extent"), (hi_km * 1000.0, "extent")]
        stations = self._stations_of(line)
        for s1, s2 in zip(stations, stations[1:]):
            end1 = s1.km * 1000.0 + s1.platform_length_m / 2
            start2 = s2.km * 1000.0 - s2.platform_length_m / 2
            pts.append((0.5 * (end1 + start2), "gap"))
        for b in d.branches:
            if b.joins == line:
                pts.append((b.at_km * 1000.0, f"{b.path}.at_km"))
        for zl, za, zb, _, b, _ in self._turnout_zones():
            if zl == line:
                pts += [(za, f"{b.path}.turnout_length_m"), (zb, f"{b.path}.turnout_length_m")]
        for sl in d.speed_limits:
            if sl.line == line:
                pts += [(sl.from_km * 1000.0, f"{sl.path}.from_km"), (sl.to_km * 1000.0, f"{sl.path}.to_km")]
        pts += [(dp.km * 1000.0, f"{dp.path}.km") for dp in d.depots if dp.line == line]
        # a break point inside a platform would put the trainStop on two edges
        for x, origin in pts:
            for s in stations:
                half = s.platform_length_m / 2 + PLATFORM_CLEARANCE_M
                if abs(x - s.km * 1000.0) < half and origin != "gap":
                    raise ConfigError(
                        d.source,
                        origin,
                        f"expected an edge break outside the platform of {s.id} "
                        f"(km {s.km:g} +/- {s.platform_length_m / 2:g} m), got km {x / 1000:g}",
                    )
        pts.sort()
        merged: list[tuple[float, str]] = []
        for x, origin in pts:
            if merged and x - merged[-1][0] < 0.5:  # closer than half a metre: one node
                continue
            merged.append((x, origin))
        return merged

    def _build_pieces(self) -> None:
        d = self.desc
        y_of = {d.main_line_id: 0.0}
        for i, b in enumerate(d.branches):
            y_of[b.id] = y_of[b.joins] + BRANCH_OFFSET_M * (i + 1) * (1 if i % 2 == 0 else -1)
        self.line_y = y_of
        for line in d.line_ids():
            pts = [x for x, _ in self._break_points(line)]
            nodes = []
            for k, x in enumerate(pts):
                nid = self._junction_nodes.get((line, round(x, 3)))
                if nid is None:
                    nid = f"{line}_n{k}"
                    y = y_of[line]
                    b = self._branch(line)  # type: ignore[assignment]
                    if b is not None:
                        # ease the branch away from its parent over its first pieces (drawing only)
                        dist = abs(x - b.at_km * 1000.0)
                        y = y_of[b.joins] + (y - y_of[b.joins]) * min(1.0, dist / 400.0)
                    self.node_xy[nid] = (x, y)
                nodes.append(nid)
                for b in d.branches:  # junction points of child branches are shared nodes
                    if b.joins == line and abs(b.at_km * 1000.0 - x) < 0.5:
                        self._junction_nodes[(b.id, round(b.at_km * 1000.0, 3))] = nid
            self.pieces[line] = [
                _Piece(line, k, pts[k], pts[k + 1], nodes[k], nodes[k + 1]) for k in range(len(pts) - 1)
            ]

    def _branch(self, line: str) -> Branch | None:
        return next((b for b in self.desc.branches if b.id == line), None)

    def _assign_speeds(self) -> None:
        d = self.desc
        zones = self._turnout_zones()
        for line, pieces in self.pieces.items():
            for p in pieces:
                mid = 0.5 * (p.a_m + p.b_m)
                for direction in DIRECTIONS:
                    v = self.line_speed_mps
                    for sl in d.speed_limits:
                        if (
                            sl.line == line
                            and sl.direction in (direction, "both")
                            and sl.from_km * 1000.0 <= mid <= sl.to_km * 1000.0
                        ):
                            v = min(v, sl.speed_kmh / 3.6)
                    for zl, za, zb, zdir, b, leg in zones:
                        if zl == line and zdir == direction and za <= mid <= zb:
                            spec = b.switch_up if direction == "up" else b.switch_down
                            if leg == "reverse":
                                v = min(v, spec.diverging_speed_kmh / 3.6)
                            elif spec.normal_speed_kmh is not None:
                                v = min(v, spec.normal_speed_kmh / 3.6)
                    p.speed_mps[direction] = v

    def _piece_at(self, line: str, x_m: float, side: str) -> _Piece:
        """The piece of ``line`` touching node position x on the ``side`` ('low'|'high') of it."""
        for p in self.pieces[line]:
            if side == "high" and abs(p.a_m - x_m) < 0.5:
                return p
            if side == "low" and abs(p.b_m - x_m) < 0.5:
                return p
        raise AssertionError(f"no piece of {line} at {x_m} ({side})")  # pragma: no cover

    def _build_switches(self) -> None:
        for b in self.desc.branches:
            j = b.at_km * 1000.0
            far = "high" if b.side == "up" else "low"
            near = "low" if b.side == "up" else "high"
            branch_piece = self._piece_at(b.id, j, far)
            parent_piece = self._piece_at(b.joins, j, far)
            trunk_piece = self._piece_at(b.joins, j, near)
            node = branch_piece.node_a if b.side == "up" else branch_piece.node_b
            for direction, spec in (("up", b.switch_up), ("down", b.switch_down)):
                # up trains move towards higher chainage: a side-up branch is ahead of them (diverge)
                kind = "diverge" if (direction == "up") == (b.side == "up") else "merge"
                legs = {
                    b.leg: branch_piece.edge_id(direction),
                    ("normal" if b.leg == "reverse" else "reverse"): parent_piece.edge_id(direction),
                }
                normal_piece = branch_piece if b.leg == "normal" else parent_piece
                self.switches.append(
                    _Switch(
                        spec,
                        direction,
                        node,
                        kind,
                        legs["normal"],
                        legs["reverse"],
                        trunk_piece.edge_id(direction),
                        normal_piece.speed_mps[direction],
                    )
                )

    def _turnback_tracks(self) -> list[_TurnbackTrack]:
        """One turnback track per free line end whose outer station turns trains back (module docstring)."""
        d = self.desc
        ends: list[tuple[str, str]] = [(d.main_line_id, "lo"), (d.main_line_id, "hi")]
        ends += [(b.id, "hi" if b.side == "up" else "lo") for b in d.branches]
        tails: list[_TurnbackTrack] = []
        for line, end in ends:
            stations = self._stations_of(line)
            outer = stations[-1] if end == "hi" else stations[0]
            if not outer.turnback:
                continue
            pieces = self.pieces[line]
            piece = pieces[-1] if end == "hi" else pieces[0]
            node = piece.node_b if end == "hi" else piece.node_a
            x_m = piece.b_m if end == "hi" else piece.a_m
            sign = 1.0 if end == "hi" else -1.0
            far = f"{line}_tb_{end}"
            self.node_xy[far] = (x_m + sign * TURNBACK_TRACK_M, self.line_y[line])
            arriving, departing = ("up", "down") if end == "hi" else ("down", "up")
            tails.append(
                _TurnbackTrack(
                    line,
                    outer.id,
                    f"{line}_tb_{end}",
                    f"-{line}_tb_{end}",
                    node,
                    far,
                    x_m,
                    sign,
                    piece.edge_id(arriving),
                    piece.edge_id(departing),
                    min(piece.speed_mps.values()),
                )
            )
        return tails

    def _pocket_tracks(self) -> list[_TurnbackTrack]:
        """A pocket track between the tracks beyond each ``pocket:`` station's platform, and its two switches."""
        out: list[_TurnbackTrack] = []
        for line in self.desc.line_ids():
            pieces = self.pieces[line]
            for st in self._stations_of(line):
                if st.pocket is None:
                    continue
                i = next(k for k, p in enumerate(pieces) if p.a_m <= st.km * 1000.0 <= p.b_m)
                low = st.pocket == "low"
                if (low and i == 0) or (not low and i == len(pieces) - 1):
                    raise ConfigError(
                        self.desc.source, f"{st.path}.pocket", f"no track beyond {st.id} on its {st.pocket} side"
                    )
                here, beyond = pieces[i], pieces[i - 1 if low else i + 1]
                arriving, departing = ("down", "up") if low else ("up", "down")
                node, x_m, sign = (here.node_a, here.a_m, -1.0) if low else (here.node_b, here.b_m, 1.0)
                far = f"{st.id}_pk_end"
                self.node_xy[far] = (x_m + sign * TURNBACK_TRACK_M, self.line_y[line])
                pk = _TurnbackTrack(
                    line,
                    st.id,
                    f"{st.id}_pk",
                    f"-{st.id}_pk",
                    node,
                    far,
                    x_m,
                    sign,
                    here.edge_id(arriving),
                    here.edge_id(departing),
                    POCKET_SPEED_MPS,
                    beyond.edge_id(arriving),
                    beyond.edge_id(departing),
                )
                out.append(pk)
                for sid, direction, kind, normal, trunk, reverse in (
                    (f"{st.id}_pk_in", arriving, "diverge", pk.through_arrive, pk.arrive_edge, pk.out),
                    (f"{st.id}_pk_out", departing, "merge", pk.through_depart, pk.depart_edge, pk.back),
                ):
                    spec = SwitchSpec(sid, POCKET_THROW_S, POCKET_SPEED_MPS * 3.6, None, st.path)
                    speed = beyond.speed_mps[direction]
                    self.switches.append(_Switch(spec, direction, node, kind, str(normal), reverse, trunk, speed))
        return out

    def _depot_leads(self) -> list[_DepotLead]:
        """A lead track per depot, joined to both running tracks by one switch each (module docstring)."""
        out: list[_DepotLead] = []
        for dp in self.desc.depots:
            x_m = dp.km * 1000.0
            pieces = self.pieces[dp.line]
            i = next(k for k, p in enumerate(pieces) if abs(p.a_m - x_m) < 0.5)  # a break point is there
            low, high = pieces[i - 1], pieces[i]
            far = f"{dp.id}_depot"
            self.node_xy[far] = (x_m, self.line_y[dp.line] - DEPOT_DRAW_OFFSET_M)
            speed = dp.speed_kmh / 3.6
            lead = _DepotLead(
                dp,
                high.node_a,
                far,
                f"{dp.id}_lead",
                f"-{dp.id}_lead",
                low.edge_id("up"),
                high.edge_id("up"),
                high.edge_id("down"),
                low.edge_id("down"),
                speed,
            )
            out.append(lead)
            for direction, trunk, normal, beyond in (
                ("up", lead.up_in, lead.up_out, high),
                ("down", lead.down_in, lead.down_out, low),
            ):
                spec = SwitchSpec(f"{dp.id}_{direction}", dp.throw_time_s, dp.speed_kmh, None, dp.path)
                sw = _Switch(
                    spec, direction, lead.node, "diverge", normal, lead.into, trunk, beyond.speed_mps[direction]
                )
                self.switches.append(sw)
        return out

    def lead_switch_legs(self) -> dict[tuple[str, str], tuple[str, str]]:
        """(lead out, running track) -> (switch, leg): leaving a depot sets the running track's switch reverse."""
        return {
            (lead.out, track): (f"{lead.depot.id}_{direction}", "reverse")
            for lead in self.leads
            for direction, track in (("up", lead.up_out), ("down", lead.down_out))
        }

    def tail_connections(self) -> list[tuple[str, str, str]]:
        """(from edge, to edge, node) of the turnback tracks: in, the turnaround, out."""
        out = []
        for t in self.tails:
            out += [(t.arrive_edge, t.out, t.node), (t.out, t.back, t.far), (t.back, t.depart_edge, t.node)]
        for lead in self.leads:
            out += lead.connections()
        return out

    # -- edges and connections in travel order --------------------------------------------------------------
    def edges(self) -> list[tuple[str, _Piece, str, str, str]]:
        """(edge id, piece, direction, from node, to node) for every edge."""
        out = []
        for pieces in self.pieces.values():
            for p in pieces:
                out.append((p.edge_id("up"), p, "up", p.node_a, p.node_b))
                out.append((p.edge_id("down"), p, "down", p.node_b, p.node_a))
        return out

    def connections(self) -> list[tuple[str, str, str, str]]:
        """(from edge, to edge, node, direction): every movement a train may make (same direction only)."""
        by_to: dict[tuple[str, str], list[str]] = {}
        by_from: dict[tuple[str, str], list[str]] = {}
        for eid, _, direction, fn, tn in self.edges():
            by_to.setdefault((tn, direction), []).append(eid)
            by_from.setdefault((fn, direction), []).append(eid)
        out = []
        for (node, direction), ins in sorted(by_to.items()):
            for e_in in ins:
                for e_out in by_from.get((node, direction), []):
                    out.append((e_in, e_out, node, direction))
        return out


def _fmt(x: float) -> str:
    return f"{x:.6f}"


def write_plain_xml(plan: _Plan, folder: Path) -> tuple[Path, Path, Path]:
    d = plan.desc
    spread = "right" if d.track == "double" else "center"
    nod = ["<nodes>"]
    for nid, (x, y) in plan.node_xy.items():
        nod.append(f'  <node id={quoteattr(nid)} x="{_fmt(x)}" y="{_fmt(y)}" type="priority"/>')
    nod.append("</nodes>")
    edg = ["<edges>"]
    rows = [(eid, fn, tn, p.speed_mps[direction], spread, p.b_m - p.a_m) for eid, p, direction, fn, tn in plan.edges()]
    for t in plan.tails:
        for eid, fn, tn in ((t.out, t.node, t.far), (t.back, t.far, t.node)):
            rows.append((eid, fn, tn, t.speed_mps, "center", TURNBACK_TRACK_M))
    for lead in plan.leads:
        for eid, fn, tn in ((lead.into, lead.node, lead.far), (lead.out, lead.far, lead.node)):
            rows.append((eid, fn, tn, lead.speed_mps, "center", lead.depot.length_m))
    for eid, fn, tn, speed, spread_type, design_m in rows:
        edg.append(
            f'  <edge id={quoteattr(eid)} from={quoteattr(fn)} to={quoteattr(tn)} numLanes="1" '
            f'speed="{speed:.6f}" allow="{ALLOW}" spreadType="{spread_type}" '
            f'width="{TRACK_WIDTH_M}" length="{_fmt(design_m - INTERNAL_LANE_M)}"/>'
        )
    edg.append("</edges>")
    speed_of = {eid: p.speed_mps[direction] for eid, p, direction, _, _ in plan.edges()}
    speed_of.update({e: t.speed_mps for t in plan.tails for e in (t.out, t.back)})
    speed_of.update({e: lead.speed_mps for lead in plan.leads for e in (lead.into, lead.out)})
    con = ["<connections>"]
    for e_in, e_out in [(a, b) for a, b, _, _ in plan.connections()] + [(a, b) for a, b, _ in plan.tail_connections()]:
        v = min(speed_of[e_in], speed_of[e_out])
        con.append(
            f'  <connection from={quoteattr(e_in)} to={quoteattr(e_out)} fromLane="0" toLane="0" '
            f'length="{INTERNAL_LANE_M}" speed="{v:.6f}"/>'
        )
    con.append("</connections>")
    paths = (folder / "plain.nod.xml", folder / "plain.edg.xml", folder / "plain.con.xml")
    for path, lines in zip(paths, (nod, edg, con)):
        path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return paths


def run_netconvert(nod: Path, edg: Path, con: Path, net: Path, source: str) -> None:
    cmd = [
        str(netconvert_binary()),
        "--node-files",
        str(nod),
        "--edge-files",
        str(edg),
        "--connection-files",
        str(con),
        "--output-file",
        str(net),
        "--no-turnarounds",
        "true",
        "--offset.disable-normalization",
        "true",
        "--geometry.remove",
        "false",
        "--junctions.join",
        "false",
        "--precision",
        "6",
    ]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise ConfigError(source, None, f"netconvert could not run: {exc}") from None
    msgs = [ln for ln in (proc.stderr + proc.stdout).splitlines() if ln.strip() and "SUMO_HOME" not in ln]
    if proc.returncode != 0 or not net.exists():
        errors = [ln for ln in msgs if ln.startswith("Error")] or msgs[-3:]
        raise ConfigError(source, None, "netconvert failed: " + " | ".join(errors))
    for ln in msgs:
        if ln.startswith("Warning"):
            log.debug("netconvert: %s", ln)


def write_stops(plan: _Plan, path: Path) -> dict[str, list[PlatformInfo]]:
    """One trainStop per station and direction, centred on the station chainage, platform-long."""
    lines = ["<additional>"]
    platforms: dict[str, list[PlatformInfo]] = {}
    for line, station in plan.desc.all_stations():
        centre = station.km * 1000.0
        half = station.platform_length_m / 2
        piece = next(p for p in plan.pieces[line] if p.a_m <= centre <= p.b_m)
        for direction in DIRECTIONS:
            eid = piece.edge_id(direction)
            lead = INTERNAL_LANE_M  # the internal lane (or, at a free line end, nothing) sits before pos 0
            if direction == "up":
                start = centre - half - (piece.a_m + lead)
            else:
                start = (piece.b_m - lead) - (centre + half)
            end = start + station.platform_length_m
            length = piece.b_m - piece.a_m - lead
            if start < -1e-6 or end > length + 1e-6:  # pragma: no cover - break points keep platforms whole
                raise AssertionError(f"platform of {station.id} does not fit on {eid}")
            stop_id = f"{station.id}.{direction}"
            lines.append(
                f"  <trainStop id={quoteattr(stop_id)} lane={quoteattr(eid + '_0')} "
                f'startPos="{_fmt(start)}" endPos="{_fmt(end)}" name={quoteattr(station.name)}/>'
            )
            platforms.setdefault(station.id, []).append(PlatformInfo(direction, stop_id, eid, start, end))
    for dl in plan.leads:
        for eid, stop_id in depot_stops(dl):
            start, end = depot_stop_span(dl, eid, dl.depot.length_m - INTERNAL_LANE_M)
            lines.append(
                f"  <trainStop id={quoteattr(stop_id)} lane={quoteattr(eid + '_0')} "
                f'startPos="{_fmt(start)}" endPos="{_fmt(end)}" name={quoteattr(dl.depot.name)}/>'
            )
    lines.append("</additional>")
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return platforms


def depot_stops(lead: _DepotLead) -> list[tuple[str, str]]:
    """(lead edge, trainStop id) of a depot: where units end their day, where they start it."""
    return [(lead.into, f"{lead.depot.id}.in"), (lead.out, f"{lead.depot.id}.out")]


def depot_stop_span(lead: _DepotLead, eid: str, length_m: float) -> tuple[float, float]:
    """Lane positions (start, end) of the depot trainStop on lead edge ``eid`` of ``length_m``: the track in ends
    :data:`DEPOT_STOP_MARGIN_M` before the lead's far end; the track out :data:`DEPOT_EXIT_CLEAR_M` before the
    line (at most half the lead, on a short one)."""
    clear_m = min(DEPOT_EXIT_CLEAR_M, 0.5 * length_m) if eid == lead.out else DEPOT_STOP_MARGIN_M
    return DEPOT_STOP_MARGIN_M, length_m - clear_m


def read_net(
    net_file: Path,
) -> tuple[
    dict[str, tuple[float, float]], dict[tuple[str, str], list[list]], list[str], set[frozenset[tuple[str, str]]]
]:
    """Lane length/speed of every normal edge, internal lanes of every connection, rail_signal node ids, and the
    pairs of connections (``(from edge, to edge)``) that SUMO's foe matrix of their node has intersect."""
    import sumolib

    net = sumolib.net.readNet(str(net_file), withInternal=True)
    lanes: dict[str, tuple[float, float]] = {}
    vias: dict[tuple[str, str], list[list]] = {}
    for edge in net.getEdges(withInternal=False):
        lane = edge.getLane(0)
        lanes[edge.getID()] = (lane.getLength(), lane.getSpeed())
        for to_edge, conns in edge.getOutgoing().items():
            chain: list[list] = []
            via_id = conns[0].getViaLaneID()
            while via_id:
                via_lane = net.getLane(via_id)
                chain.append([via_id, via_lane.getLength(), via_lane.getSpeed()])
                nxt = [c for c in via_lane.getOutgoing() if c.getViaLaneID()]
                via_id = nxt[0].getViaLaneID() if nxt else ""
            vias[(edge.getID(), to_edge.getID())] = chain
    signals = [n.getID() for n in net.getNodes() if n.getType() == "rail_signal"]
    foes: set[frozenset[tuple[str, str]]] = set()
    for node in net.getNodes():
        links = [(node.getLinkIndex(c), c) for c in node.getConnections()]
        links = [(i, c) for i, c in links if i >= 0]  # internal-to-normal continuations have no link index
        for k, (i1, c1) in enumerate(links):
            for i2, c2 in links[k + 1 :]:
                if node.areFoes(i1, i2) or node.areFoes(i2, i1):
                    m1, m2 = ((c.getFrom().getID(), c.getTo().getID()) for c in (c1, c2))
                    foes.add(frozenset((m1, m2)))
    return lanes, vias, signals, foes


def generate(desc: LineDescription, folder: Path, cache_key: str = "") -> NetworkBundle:
    """Build the world of ``desc`` into ``folder`` (net, stops, topology JSON) and return its bundle."""
    t0 = time.perf_counter()
    plan = _Plan(desc)
    folder.mkdir(parents=True, exist_ok=True)
    nod, edg, con = write_plain_xml(plan, folder)
    net_file = folder / f"{desc.name}.net.xml"
    run_netconvert(nod, edg, con, net_file, desc.source)
    stops_file = folder / f"{desc.name}.stops.add.xml"
    platforms = write_stops(plan, stops_file)
    lanes, vias, signals, foes = read_net(net_file)
    if signals:  # pragma: no cover - plain XML never yields them; guard the invariant anyway
        raise AssertionError(f"generated net has rail_signal nodes: {signals}")
    wanted = {(a, b) for a, b, _, _ in plan.connections()} | {(a, b) for a, b, _ in plan.tail_connections()}
    if set(vias) != wanted:  # pragma: no cover - explicit connections leave netconvert no choice
        raise AssertionError(f"netconvert connections differ from the plan: {set(vias) ^ wanted}")

    graph = nx.DiGraph(name=desc.name)
    plat_by_edge = {p.edge: (sid, p) for sid, ps in platforms.items() for p in ps}
    for eid, piece, direction, fn, tn in plan.edges():
        length, speed = lanes[eid]
        lead = INTERNAL_LANE_M
        sid, plat = plat_by_edge.get(eid, (None, None))
        graph.add_node(
            eid,
            line=piece.line,
            direction=direction,
            length_m=length,
            speed_mps=speed,
            from_node=fn,
            to_node=tn,
            design_start_m=piece.a_m + lead if direction == "up" else piece.b_m - lead,
            design_sign=1 if direction == "up" else -1,
            station=sid,
            stop_id=plat.stop_id if plat else None,
            stop_start_pos_m=plat.start_pos_m if plat else None,
            stop_end_pos_m=plat.end_pos_m if plat else None,
        )
    sw_by_conn: dict[tuple[str, str], tuple[str, str]] = {}
    switches: dict[str, SwitchInfo] = {}
    for s in plan.switches:
        switches[s.spec.id] = SwitchInfo(
            id=s.spec.id,
            sumo_node=s.node,
            kind=s.kind,
            normal_edge=s.normal_edge,
            reverse_edge=s.reverse_edge,
            trunk_edge=s.trunk_edge,
            throw_time_s=s.spec.throw_time_s,
            diverging_speed_mps=s.spec.diverging_speed_kmh / 3.6,
            normal_speed_mps=s.normal_speed_mps,
        )
        for leg, leg_edge in (("normal", s.normal_edge), ("reverse", s.reverse_edge)):
            pair = (s.trunk_edge, leg_edge) if s.kind == "diverge" else (leg_edge, s.trunk_edge)
            sw_by_conn[pair] = (s.spec.id, leg)
    for a, b, node, _ in plan.connections():
        sw, leg = sw_by_conn.get((a, b), (None, None))  # type: ignore[assignment]
        graph.add_edge(a, b, node=node, via=vias[(a, b)], switch=sw, leg=leg)
    graph.graph["reversals"] = _add_turnback_tracks(plan, graph, lanes, vias, sw_by_conn)
    sw_by_conn.update(plan.lead_switch_legs())
    graph.graph["depots"] = _add_depot_leads(plan, graph, lanes, vias, sw_by_conn)
    graph.graph["gradients"] = {
        line: [[g.from_km * 1000.0, g.to_km * 1000.0, g.permille] for g in desc.gradients if g.line == line]
        for line in desc.line_ids()
    }
    graph.graph["points"] = {p.id: [p.line, p.km * 1000.0] for p in desc.points}
    # a double-track junction or a depot lead joined to both tracks crosses the other track at grade: SUMO's foe
    # matrix says where, and the interlocking holds each such node as a crossing (network.topology)
    graph.graph["crossings"] = flat_crossings(graph, lambda _node, m1, m2: frozenset((m1, m2)) in foes)

    xo_speed = {x.station: x.speed_kmh / 3.6 for x in desc.crossovers}
    stations = {
        st.id: StationInfo(
            st.id, st.name, line, st.km, st.platform_length_m, st.turnback, tuple(platforms[st.id]), xo_speed.get(st.id)
        )
        for line, st in desc.all_stations()
    }
    routes = {}
    end_names = _end_names(plan)
    for direction in DIRECTIONS:
        nodes = [n for n, a in graph.nodes(data=True) if a["direction"] == direction]
        one_way = graph.subgraph(nodes)  # the turnback tracks link the directions; through routes do not
        sources = [n for n in nodes if one_way.in_degree(n) == 0]
        sinks = [n for n in nodes if one_way.out_degree(n) == 0]
        for src in sources:
            reach = nx.descendants(one_way, src)
            for dst in sinks:
                if dst in reach:
                    rid = f"{end_names[graph.nodes[src]['from_node']]}->{end_names[graph.nodes[dst]['to_node']]}"
                    routes[rid] = make_route(graph, rid, nx.shortest_path(one_way, src, dst))
    topology_file = folder / f"{desc.name}.topology.json"
    bundle = NetworkBundle(
        desc.name,
        net_file,
        stops_file,
        topology_file,
        graph,
        stations,
        switches,
        routes,
        cache_key=cache_key,
        build_time_s=time.perf_counter() - t0,
    )
    payload = bundle_to_json(bundle)
    payload["description"] = {
        "name": desc.name,
        "description": desc.description,
        "track": desc.track,
        "line_speed_kmh": desc.line_speed_kmh,
        "source": desc.source,
    }
    topology_file.write_text(json.dumps(payload, indent=1, ensure_ascii=False), encoding="utf-8")
    for tmp in (nod, edg, con):
        tmp.unlink()
    return bundle


def _add_turnback_tracks(
    plan: _Plan,
    graph: nx.DiGraph,
    lanes: dict[str, tuple[float, float]],
    vias: dict[tuple[str, str], list[list]],
    sw_by_conn: dict[tuple[str, str], tuple[str, str]],
) -> dict[str, list[object]]:
    """The turnback tracks' edges and links in the track graph; returns the reversals (module docstring)."""
    reversals: dict[str, list[object]] = {}
    for t in plan.tails:
        out_e, back_e, node, far, x_m, sign = t.out, t.back, t.node, t.far, t.x_m, t.sign
        for eid, partner, fn, tn, start, s in (
            (out_e, back_e, node, far, x_m + sign * INTERNAL_LANE_M, sign),
            (back_e, out_e, far, node, x_m + sign * (TURNBACK_TRACK_M - INTERNAL_LANE_M), -sign),
        ):
            _add_side_edge(graph, eid, partner, t.line, "turnback", fn, tn, lanes[eid], start, int(s))
        for a, b in ((t.arrive_edge, out_e), (back_e, t.depart_edge)):
            _add_link(graph, a, b, node, vias, sw_by_conn)
        reversals[out_e] = [back_e, vias[(out_e, back_e)]]
    return reversals


def _add_side_edge(
    graph: nx.DiGraph,
    eid: str,
    partner: str,
    line: str,
    direction: str,
    from_node: str,
    to_node: str,
    lane: tuple[float, float],
    design_start_m: float,
    design_sign: int,
    stop: tuple[str, str, float, float] | None = None,
) -> None:
    """One edge of a bidi side track (turnback, pocket, depot lead) in the track graph; ``stop`` = (station,
    trainStop id, start and end position on the lane) of a trainStop on it."""
    station, stop_id, start_pos, end_pos = stop if stop is not None else (None, None, None, None)
    graph.add_node(
        eid,
        line=line,
        direction=direction,
        length_m=lane[0],
        speed_mps=lane[1],
        from_node=from_node,
        to_node=to_node,
        design_start_m=design_start_m,
        design_sign=design_sign,
        station=station,
        stop_id=stop_id,
        stop_start_pos_m=start_pos,
        stop_end_pos_m=end_pos,
        bidi=partner,
    )


def _add_link(
    graph: nx.DiGraph,
    a: str,
    b: str,
    node: str,
    vias: dict[tuple[str, str], list[list]],
    sw_by_conn: dict[tuple[str, str], tuple[str, str]],
) -> None:
    """The connection a -> b in the track graph, with the switch and leg it sets (if any)."""
    sw, leg = sw_by_conn.get((a, b), (None, None))
    graph.add_edge(a, b, node=node, via=vias[(a, b)], switch=sw, leg=leg)


def _add_depot_leads(
    plan: _Plan,
    graph: nx.DiGraph,
    lanes: dict[str, tuple[float, float]],
    vias: dict[tuple[str, str], list[list]],
    sw_by_conn: dict[tuple[str, str], tuple[str, str]],
) -> dict[str, dict[str, object]]:
    """The depot leads' edges and links in the track graph; returns ``graph.graph["depots"]`` (module docstring)."""
    depots: dict[str, dict[str, object]] = {}
    for lead in plan.leads:
        dp = lead.depot
        x_m = dp.km * 1000.0
        stop_of = dict(depot_stops(lead))
        for eid, partner, fn, tn in (
            (lead.into, lead.out, lead.node, lead.far),
            (lead.out, lead.into, lead.far, lead.node),
        ):
            stop = (dp.id, stop_of[eid], *depot_stop_span(lead, eid, lanes[eid][0]))
            # the lead runs off to the side: its whole length sits at the depot's km (design sign 0)
            _add_side_edge(graph, eid, partner, dp.line, "depot", fn, tn, lanes[eid], x_m, 0, stop)
        for a, b, node in lead.connections():
            _add_link(graph, a, b, node, vias, sw_by_conn)
        depots[dp.id] = {
            "name": dp.name,
            "line": dp.line,
            "km": dp.km,
            "start_edge": lead.out,
            "end_edge": lead.into,
            "basis": dp.basis,
        }
    return depots


def _end_names(plan: _Plan) -> dict[str, str]:
    """SUMO node id -> name of the free line end it is (used in through-route ids)."""
    d = plan.desc
    names = {
        plan.pieces[d.main_line_id][0].node_a: d.start_name,
        plan.pieces[d.main_line_id][-1].node_b: d.end_name,
    }
    for b in d.branches:
        node = plan.pieces[b.id][-1].node_b if b.side == "up" else plan.pieces[b.id][0].node_a
        names[node] = b.end_name
    return names
