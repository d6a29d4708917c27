"""Ground truth: which train is directly ahead of which, the true gaps, and overlaps (collisions).

This module sees the world as it *is* (positions from SUMO's odometer), never as a train knows it. The engine
uses it for three things only:

* the recorder's gaps and collision detection (an overlap of two trains on the same track is a collision,
  whatever SUMO's own checks say);
* deciding *whose* messages a train listens to for separation (the train physically ahead on its route) —
  the *contents* a controller sees still come through the communication layer, delayed and lossy;
* feeding formations their true gap (coupling completes on the real gap, not a believed one).

Trains are indexed by the SUMO edges their body covers (rear to front, in their own route frame). A follower
walks its own route forward from the edge under its front; the first edge holding any part of another train
ahead gives the predecessor. Frames are changed on the shared track only (:meth:`RouteView.map_body`): the tail
of a train that is merging from the other leg is not on our track, so it is not "ahead" of a train waiting at
the switch — the interlocking, not the gap, protects the junction itself.

**Trains facing each other.** On ``bidi`` track one physical track is two SUMO edges, one per direction, and a
train running (or standing, turned back) the other way is on the partner edge: the index by edge never puts it
ahead of anybody. :meth:`Occupancy.facing` finds it (given the partner of every bidi edge and the edge lengths,
:meth:`Occupancy.set_bidi`): the nearest train on the partner edges of the track ahead, with the part of its body
there in this train's frame. A position ``x`` metres into an edge is ``length - x`` metres into its partner. The
safety check counts two such bodies overlapping as a head-on collision, and no movement authority reaches into
track a facing train stands on.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import repeat
from typing import Any, NamedTuple

import numpy as np

from railsim.engine import occupancy_kernel
from railsim.engine.routeview import RouteView
from railsim.engine.settings import FACING_DECEL_MPS2
from railsim.engine.truth_kernel import INTERNAL, UNKNOWN


@dataclass(slots=True)
class Body:
    """A train's body for occupancy: front chainage in its own route frame and its length; ``edge_i`` is the
    route edge under the front (a hint: :meth:`RouteView.edge_near`), ``rear_i`` is set by :meth:`Occupancy.update`."""

    train_id: str
    view: RouteView
    front_m: float
    length_m: float
    edge_i: int = 0
    rear_i: int = 0

    @property
    def rear_m(self) -> float:
        return self.front_m - self.length_m


class Ahead(NamedTuple):
    """The train directly ahead of a follower, in the follower's frame (ground truth). (Immutable; a named tuple
    rather than a frozen dataclass because one is built per train and step.)"""

    train_id: str
    front_m: float
    rear_m: float
    gap_m: float  # front-to-rear: rear of the train ahead minus front of the follower (negative = overlap)
    offset_m: float  # add to the leader's own chainage to get the follower's frame


_new_tuple = tuple.__new__  # tuple.__new__(Ahead, fields): an Ahead, as Ahead(*fields) makes it


class Facing(NamedTuple):
    """The nearest train on the track ahead running (or standing) the other way, in the observer's frame."""

    train_id: str
    near_m: float  # the end of its body nearest the observer's front (its front, facing us)
    far_m: float  # the other end


class _EdgeCodes(dict[str, int]):
    """SUMO edge id -> the truth pass's code for it (:meth:`Occupancy.edge_codes`), looked up in C: an id not asked
    for before is coded on the miss — :data:`INTERNAL` for an internal junction lane, :data:`UNKNOWN` for an edge
    not numbered yet — and kept; numbering an edge (:meth:`Occupancy._number`) overwrites its entry."""

    def __missing__(self, edge: str) -> int:
        code = self[edge] = INTERNAL if edge[:1] == ":" else UNKNOWN
        return code


class Occupancy:
    """Per-step index of which train covers which edge, on per-train arrays (:mod:`.occupancy_kernel`).

    Each step :meth:`update_columns` (or :meth:`update`) puts the trains on the line in *slots* (their order in
    the step's list) and places them in one compiled pass; :meth:`ahead_all` and :meth:`facing_all` answer for
    every train in one call each, :meth:`ahead` and :meth:`facing` for one. Routes are registered the first time a
    train on them is seen (their edges numbered, their tables appended); nothing about a train outlives the step."""

    def __init__(self) -> None:
        self._bidi: dict[str, tuple[str, float]] = {}  # bidi edge -> (its partner, the partner's length [m])
        self._edge_id: dict[str, int] = {}  # SUMO edge -> global edge number
        self._codes = _EdgeCodes()  # SUMO edge id -> its code for the truth pass (edge_codes), filled as asked
        self._route_of: dict[int, int] = {}  # id(view) -> route number (the view is kept in _views: ids stay unique)
        self._views: list[RouteView] = []
        # per route: its global edge numbers in route order, edge starts, sorted look-up keys and values
        self._segs: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
        self._dirty = True  # tables to rebuild (a route or an edge was added)
        self._tables: tuple[np.ndarray, ...] = ()  # r_off, r_edges, r_starts, r_keys, r_vals, r_simple, r_len
        self._partner = np.full(0, -1, np.int64)
        self._partner_len = np.zeros(0)
        self.ids: list[str] = []  # slot -> train id, this step
        self._slot_of: dict[str, int] | None = {}  # train id -> slot, made when first asked for (None: not yet)
        self._route: np.ndarray = np.zeros(0, np.int64)
        self._front: np.ndarray = np.zeros(0)
        self._len: np.ndarray = np.zeros(0)
        self.edge_i: np.ndarray = np.zeros(0, np.int64)  # slot -> route edge under its front
        self.pointer_i: np.ndarray = np.zeros(0, np.int64)  # slot -> the train's own pointer (the truth pass's)
        self.ahead_slots: np.ndarray = np.zeros(0, np.int64)  # slot -> slot ahead (-1: none), last ahead_all
        self.rear_i: np.ndarray = np.zeros(0, np.int64)  # slot -> route edge under its rear
        self._by_off: np.ndarray = np.zeros(1, np.int64)
        self._by_slot: np.ndarray = np.zeros(0, np.int64)

    @property
    def has_bidi(self) -> bool:
        """True if the track has bidi edges (only there can trains face each other on one track)."""
        return bool(self._bidi)

    def set_bidi(self, graph: Any) -> None:
        """The partner of every bidi edge of the track graph and its length (:meth:`facing`)."""
        nodes = graph.nodes
        self._bidi = {
            e: (a["bidi"], float(nodes[a["bidi"]]["length_m"]))
            for e, a in nodes(data=True)
            if a.get("bidi") is not None and a["bidi"] in nodes
        }
        for e, (p, _) in self._bidi.items():
            self._number(e)
            self._number(p)
        n = len(self._edge_id)
        self._partner = np.full(n, -1, np.int64)
        self._partner_len = np.zeros(n)
        for e, (p, length_m) in self._bidi.items():
            self._partner[self._edge_id[e]] = self._edge_id[p]
            self._partner_len[self._edge_id[e]] = length_m
        self._dirty = True

    def _number(self, edge: str) -> int:
        k = self._edge_id.get(edge)
        if k is None:
            k = self._edge_id[edge] = len(self._edge_id)
            if edge[:1] != ":":  # (an internal junction lane keeps its code INTERNAL)
                self._codes[edge] = k
            self._dirty = True
        return k

    def _route_no(self, view: RouteView) -> int:
        r = self._route_of.get(id(view))
        if r is not None:  # (the view is kept in _views: no other object can have its id)
            return r
        r = self._route_of[id(view)] = len(self._views)
        self._views.append(view)
        edges = [self._number(e) for e in view.edges]
        last = {e: i for i, e in enumerate(edges)}  # the last occurrence, as RouteView.edge_index
        keys = sorted(edges)  # every occurrence: the look-up segment is the route's (r_off)
        self._segs.append(
            (
                np.array(edges, np.int64),
                np.array(view.edge_start_m, float),
                np.array(keys, np.int64),
                np.array([last[e] for e in keys], np.int64),
            )
        )
        self._dirty = True
        return r

    def _rebuild(self) -> None:
        """The flat route tables and the partner table (:mod:`.occupancy_kernel`, "Tables"): the routes' own
        arrays, made when each was registered, put end to end."""
        views, segs = self._views, self._segs
        r_off = np.zeros(len(segs) + 1, np.int64)
        r_off[1:] = np.cumsum([len(seg[0]) for seg in segs])

        def flat(k: int, dtype: Any) -> np.ndarray:
            return np.concatenate([seg[k] for seg in segs]) if segs else np.zeros(0, dtype)

        r_simple = np.array([v.simple for v in views], np.bool_)
        r_len = np.array([v.length_m for v in views], float)
        self._tables = (r_off, flat(0, np.int64), flat(1, float), flat(2, np.int64), flat(3, np.int64), r_simple, r_len)
        grown = len(self._edge_id) - len(self._partner)  # edges numbered since: none of them has a partner
        self._partner = np.concatenate([self._partner, np.full(grown, -1, np.int64)])
        self._partner_len = np.concatenate([self._partner_len, np.zeros(grown)])
        self._dirty = False

    def update(self, bodies: list[Body]) -> None:
        """Index ``bodies`` (:meth:`update_columns`); each body's ``edge_i`` and ``rear_i`` are set."""
        self.update_columns(
            [b.train_id for b in bodies],
            [b.view for b in bodies],
            [b.front_m for b in bodies],
            [b.length_m for b in bodies],
            [b.edge_i for b in bodies],
        )
        for b, i1, i0 in zip(bodies, self.edge_i.tolist(), self.rear_i.tolist(), strict=True):
            b.edge_i, b.rear_i = i1, i0

    @property
    def route_of(self) -> dict[int, int]:
        """``id(view)`` -> route number of every route registered (read-only; :meth:`route_numbers` registers)."""
        return self._route_of

    def route_numbers(self, views: list[RouteView]) -> np.ndarray:
        """The route number of each view (a route seen for the first time is registered)."""
        route_of = self._route_of
        try:  # every route known (the views are kept, so an id stays theirs)
            routes = [route_of[id(v)] for v in views]
        except KeyError:
            routes = [self._route_no(v) for v in views]
        return np.array(routes, np.int64)

    def route_tables(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The flat route tables ``(r_off, r_edges, r_starts, r_keys, r_vals)`` of every route registered so far
        (:mod:`.occupancy_kernel`, "Tables")."""
        if self._dirty:
            self._rebuild()
        r_off, r_edges, r_starts, r_keys, r_vals = self._tables[:5]
        return r_off, r_edges, r_starts, r_keys, r_vals

    def edge_codes(self, edges: list[str]) -> np.ndarray:
        """SUMO edge ids as global edge numbers: :data:`.truth_kernel.INTERNAL` for an internal junction lane (an id
        starting with ``:``), :data:`.truth_kernel.UNKNOWN` for an edge no registered route or bidi pair uses."""
        return np.fromiter(map(self._codes.__getitem__, edges), np.int64, len(edges))

    def _slots(self) -> dict[str, int]:
        """Train id -> slot this step (built on the first question by id: the per-step passes need none)."""
        if self._slot_of is None:
            self._slot_of = dict(zip(self.ids, range(len(self.ids))))
        return self._slot_of

    def update_columns(
        self, ids: list[str], views: list[RouteView], front_m: list[float], length_m: list[float], hints: list[int]
    ) -> None:
        """This step's trains as columns (slot ``k`` = ``ids[k]``): their route views, front chainages in their own
        frame, lengths, and a hint for the edge under each front (last step's, :meth:`RouteView.edge_near`)."""
        routes = self.route_numbers(views)
        self.update_arrays(ids, routes, np.array(front_m, float), np.array(length_m, float), np.array(hints, np.int64))

    def update_arrays(
        self, ids: list[str], routes: np.ndarray, front_m: np.ndarray, length_m: np.ndarray, hints: np.ndarray
    ) -> None:
        """:meth:`update_columns` on arrays already made: route numbers (:meth:`route_numbers`), fronts, lengths
        and edge hints (int64; the array is updated in place to the edge under each front)."""
        if self._dirty:
            self._rebuild()
        self.ids = ids
        self._slot_of = None
        self._route = routes
        self._front = front_m
        self._len = length_m
        self.pointer_i = hints.copy()  # the trains' own edge pointers (the truth pass's), before place() moves them
        self.edge_i = hints
        self.rear_i = np.empty(len(ids), np.int64)
        r_off, r_edges, r_starts = self._tables[:3]
        self._by_off, self._by_slot = occupancy_kernel.place(
            r_off, r_edges, r_starts, len(self._edge_id), self._route, self._front, self._len, self.edge_i, self.rear_i
        )

    def _ahead_world(self) -> occupancy_kernel.AheadWorld:
        """What the ahead kernels search (:data:`.occupancy_kernel.AheadWorld`): the route tables, this step's
        columns and the index by edge (:func:`.occupancy_kernel.ahead_one`, :func:`.occupancy_kernel.ahead_all`,
        :func:`.occupancy_kernel.reported_rears`)."""
        return (
            self._tables[:6],
            self._route,
            self._front,
            self._len,
            self.edge_i,
            self.rear_i,
            self._by_off,
            self._by_slot,
        )

    def ahead_all(self, lookahead_m: float = 5000.0) -> list[Ahead | None]:
        """:meth:`ahead` for every train of the step, in slot order (one compiled pass, gaps and offsets in it)."""
        slots, fronts, rears, gaps, offsets = occupancy_kernel.ahead_all(lookahead_m, self._ahead_world())
        self.ahead_slots = slots
        other = slots.tolist()
        # each Ahead made in C (what Ahead(...) does, without its Python-level __new__); slot -1 is None, after
        rows = zip(map(self.ids.__getitem__, other), fronts.tolist(), rears.tolist(), gaps.tolist(), offsets.tolist())
        out: list[Ahead | None] = list(map(_new_tuple, repeat(Ahead, len(other)), rows))
        if -1 in other:
            for k, o in enumerate(other):
                if o < 0:
                    out[k] = None
        return out

    def reported_rears(self, t_s: float, sent_front_m: np.ndarray, sent_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For every train of the step, the train ahead of it as the last :meth:`ahead_all` found it, placed where its
        last report put it (``sent_front_m``, its own chainage, sent at ``sent_s``; NaN: no report), as
        ``(rear, age)`` per slot, NaN where it has none (:func:`.occupancy_kernel.reported_rears`)."""
        return occupancy_kernel.reported_rears(
            t_s, self.ahead_slots, sent_front_m, sent_s, self.pointer_i, self._ahead_world()
        )

    def ahead(self, train_id: str, lookahead_m: float = 5000.0) -> Ahead | None:
        """The nearest train whose front is ahead of ``train_id``'s front on its route, within ``lookahead_m``."""
        me = self._slots()[train_id]
        o, front, rear = occupancy_kernel.ahead_one(me, lookahead_m, self._ahead_world())
        if o < 0:
            return None
        front, rear = float(front), float(rear)  # (numpy's floats when interpreted)
        return Ahead(self.ids[o], front, rear, rear - float(self._front[me]), front - float(self._front[o]))

    def facing_within_braking(self, speed_mps: list[float], floor_m: float) -> dict[str, float]:
        """For every train of the step (``speed_mps`` in slot order), where the nearest train facing it begins (its
        frame), looked for from its front as far as it brakes from its speed at a mild :data:`FACING_DECEL_MPS2`, at
        least ``floor_m`` (the sensor range); trains with none are left out. The route locks end authorities before
        it."""
        if not self._bidi:
            return {}
        lookahead_m = np.array([floor_m + v**2 / (2.0 * FACING_DECEL_MPS2) for v in speed_mps], float)
        mine, _, near = self._facing_hits(self._front, lookahead_m)
        return dict(zip(map(self.ids.__getitem__, mine.tolist()), near.tolist()))

    def facing_own_bodies(self) -> tuple[list[int], list[int], list[float], list[str]]:
        """The trains of the step that a train faces on the track under their own body (looked for from the rear
        over the length): their slots, the slot of the train facing each and where that train begins, ascending
        by slot, with the step's train ids (``SafetyMonitor.head_on_checks``: overlapping bodies collide)."""
        if not self._bidi:
            return [], [], [], self.ids
        mine, other, near = self._facing_hits(self._front - self._len, self._len)
        return mine.tolist(), other.tolist(), near.tolist(), self.ids

    def _facing_hits(self, from_m: np.ndarray, lookahead_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:func:`.occupancy_kernel.facing_hits` for every slot (query ``from_m[k]``, ``lookahead_m[k]``)."""
        return occupancy_kernel.facing_hits(from_m, lookahead_m, self._facing_world())

    def _facing_world(self) -> occupancy_kernel.FacingWorld:
        """What the facing kernels search (:data:`.occupancy_kernel.FacingWorld`): the route tables, partner edges
        and slot columns."""
        r_off, r_edges, r_starts, _, _, _, r_len = self._tables
        return (
            r_off,
            r_edges,
            r_starts,
            r_len,
            self._partner,
            self._partner_len,
            self._route,
            self._front,
            self._len,
            self.edge_i,
            self.rear_i,
            self._by_off,
            self._by_slot,
        )

    def _facing_kernel(
        self, slots: np.ndarray, from_m: np.ndarray, lookahead_m: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return occupancy_kernel.facing_all(slots, from_m, lookahead_m, self._facing_world())

    def facing(self, train_id: str, from_m: float, lookahead_m: float) -> Facing | None:
        """The nearest train on the partner edges of this train's route from ``from_m`` on (within
        ``lookahead_m``) whose body lies there at or beyond ``from_m`` (module docstring): it runs or stands
        the other way on the same track. None on track without partners."""
        return self.facing_all([(train_id, from_m, lookahead_m)])[0]

    def facing_all(self, queries: list[tuple[str, float, float]]) -> list[Facing | None]:
        """:meth:`facing` for every ``(train, from_m, lookahead_m)`` (one compiled pass)."""
        if not self._bidi:
            return [None] * len(queries)
        slot = self._slots()
        slots, nears, fars = self._facing_kernel(
            np.array([slot[q[0]] for q in queries], np.int64),
            np.array([q[1] for q in queries], float),
            np.array([q[2] for q in queries], float),
        )
        ids = self.ids
        return [
            None if o < 0 else Facing(ids[o], near, far)
            for o, near, far in zip(slots.tolist(), nears.tolist(), fars.tolist(), strict=True)
        ]
