"""Which trains on the line a departure must be checked against: an index of their bodies and reaches by edge.

The dispatcher's departure rules (:mod:`railsim.engine.insertion`) compare the train to be put on with every
other train on the line, each in one route frame (``RouteView.map_body``). Only trains near the spot can make a
rule fire, so :class:`NearTrains` hands the dispatcher those, in scenario order, and the answer — the first train
whose rule fires, and its reason — is the full scan's.

**How far a rule looks.** With the departing body at ``[rear, front]`` and another train at
``[other_rear, other_front]`` in one frame, every rule that can fire needs ``front > other_rear − ahead`` and
``rear < other_front + reach(other)``, where

* ``ahead`` is the departing train's own look ahead: ``insertion_margin_m`` ("X ahead is less than 50 m clear")
  for a standing start, its least stopping distance for a start in motion (a train ahead closer than that);
* ``reach(other)`` is how far in front of its own front the other train can hold a departure: the larger of its
  approach distance (service braking + :data:`~railsim.engine.settings.INSERTION_REACTION_S` + the margin,
  :func:`approach_needed_m`) and its least stopping distance, and — while it holds any switch lock — up to the
  last switch of its route (it holds the route through a spot it has not reached).

**From distances to edges.** The frame change anchors on one edge the two routes share: an edge under the
departing body that lies on the other route (usually), or an edge under the other body that lies on the departing
train's route (a train put on at a platform shorter than itself, its tail on track before its route begins).
That edge starts at most one edge span (:attr:`NearTrains.span_max_m`, junction lane included) plus one train
length behind the body it anchors. So each train on the line is filed under

* its **zone**: the edges of its route starting within ``[rear − ahead − L − span, front + reach + L]`` (``L``
  the longest train): a departure whose body lies on one of them may be held by it;
* its **body**: the edges under it: a departure whose route passes one of them within
  ``[rear − max reach − L − span, front + ahead + L]`` of the departing body may be held by it.

A route passing an edge twice is covered: the index is by edge id, whichever pass the frame change takes. A train
whose front lies before the start of its route or whose rear lies beyond its end is always a candidate; a
departure there, or with an infinite look ahead (a steep downhill), scans every train.

**Kept current.** The index describes the line at one instant: which trains are on it, their fronts, speeds and
whether they hold locks. Each question first compares those with the current fleet (one pass of C-level list
comparisons, no frame changes); a train the dispatcher put on since is added to the index alone, anything else
(a step moved the trains, a train left) rebuilds it. Rebuilding is linear in the trains and their zones.
"""

from __future__ import annotations

import bisect
import math
from operator import attrgetter
from typing import Any

from railsim.engine.fleet import Fleet
from railsim.engine.settings import INSERTION_REACTION_S
from railsim.engine.train import TrainRuntime
from railsim.physics import dynamics

SLACK_M = 1.0  # added to every bound: the frame changes add offsets, and a sum may round the other way

_SIG = attrgetter("front_m", "plant")  # what a train's zone depends on, besides whether it holds locks
_LOCKS = attrgetter("locks")


def approach_needed_m(other: TrainRuntime, margin_m: float) -> float:
    """The room ``other`` needs to stop short of a rear in front of it: service braking from its speed, one
    :data:`INSERTION_REACTION_S` at that speed, and ``margin_m`` (the dispatcher's ``_cannot_stop_behind``)."""
    v = other.plant.speed_mps
    return v * v / (2.0 * other.trip.vehicle.service_decel_mps2) + v * INSERTION_REACTION_S + margin_m


class NearTrains:
    """The trains on the line filed by edge (module docstring); :meth:`near` answers one departure."""

    def __init__(self, fleet: Fleet, margin_m: float) -> None:
        self.fleet = fleet
        self.margin_m = margin_m
        self.span_max_m = 0.0  # the longest edge span of any route of the fleet (its junction lane included)
        self.length_max_m = 0.0  # the longest train of the fleet
        self._rank: dict[str, int] = {}  # train id -> its place in scenario order
        self._last_switch: dict[str, float | None] = {}  # route id -> the chainage of its last switch
        self._ahead_m = -math.inf  # the look ahead the zones were built for (a larger question rebuilds them)
        # the instant the index describes: trains on the line (scenario order), (front, plant), number of locks
        self._trains: list[TrainRuntime] = []
        self._sig: list[tuple[float, Any]] = []
        self._locked: list[int] = []
        self._ranks: list[int] = []
        self._by_id: dict[str, TrainRuntime] = {}
        self._zone: dict[str, list[str]] = {}  # edge -> trains whose zone holds it
        self._body: dict[str, list[str]] = {}  # edge -> trains whose body is on it
        self._always: list[str] = []  # trains off their own route's ends: always candidates
        self._reach_max_m = 0.0  # the largest reach of a train in the index
        self._added: list[TrainRuntime] = []  # put on by the dispatcher since the index was last checked

    # ------------------------------------------------------------------ the question
    def near(
        self, tr: TrainRuntime, depart_m: float, length_m: float, ahead_m: float, trusted: bool = False
    ) -> list[TrainRuntime]:
        """The trains on the line (``tr`` left out) that a rule looking ``ahead_m`` in front of ``tr``'s body
        (front at ``depart_m`` of its route, ``length_m`` long) could hold it for, in scenario order. Every other
        train on the line would pass every rule (module docstring). ``trusted``: the caller knows that no train
        was put on, moved, sped up or took a lock since the last :meth:`check` (trains may have left the line)."""
        view = tr.view
        starts = view.edge_start_m
        if not ahead_m < math.inf or not starts or depart_m < starts[0] or depart_m - length_m >= view.length_m:
            return [other for other in self.fleet.active() if other is not tr]
        if not trusted or ahead_m > self._ahead_m:
            self.check(ahead_m)
        found: set[str] = set(self._always)
        edges = view.edges
        zone, body = self._zone, self._body
        for e in edges[view.edge_at(depart_m - length_m) : view.edge_at(depart_m) + 1]:
            found.update(zone.get(e, ()))
        lo = depart_m - length_m - self._reach_max_m - self.length_max_m - self.span_max_m - SLACK_M
        hi = depart_m + ahead_m + self.length_max_m + SLACK_M
        for e in edges[view.edge_at(lo) : view.edge_at(hi) + 1]:
            found.update(body.get(e, ()))
        found.discard(tr.train_id)
        rank = self._rank
        by_id = self._by_id
        return [t for t in (by_id[tid] for tid in sorted(found, key=rank.__getitem__)) if t.on_line]

    def inserted(self, tr: TrainRuntime) -> None:
        """``tr`` was put on the line just now (the next question adds it alone if nothing else changed)."""
        self._added.append(tr)

    # ------------------------------------------------------------------ keeping the index current
    def check(self, ahead_m: float = 0.0) -> None:
        """Bring the index up to the line as it is now (module docstring), for questions looking ``ahead_m``."""
        active = self.fleet.active()
        added, self._added = self._added, []
        if ahead_m > self._ahead_m or len(self._rank) != len(self.fleet.trains):
            self._rebuild(active, ahead_m)
            return
        sig = list(map(_SIG, active))
        locked = list(map(len, map(_LOCKS, active)))
        if active == self._trains and sig == self._sig and locked == self._locked:
            return
        new = sorted(
            (tr for tr in added if tr.on_line and tr.train_id not in self._by_id), key=lambda t: self._rank[t.train_id]
        )
        n_old = len(self._trains)
        if not new or len(active) != n_old + len(new):
            self._rebuild(active, ahead_m)
            return
        if not self._ranks or self._rank[new[0].train_id] > self._ranks[-1]:  # put on after all: appended
            same = active[:n_old] == self._trains and sig[:n_old] == self._sig and locked[:n_old] == self._locked
            same = same and active[n_old:] == new
            ranks = self._ranks + [self._rank[t.train_id] for t in new]
        else:  # spliced in at their places in scenario order
            trains, sig0, locked0, ranks = list(self._trains), list(self._sig), list(self._locked), list(self._ranks)
            for tr in new:
                r = self._rank[tr.train_id]
                k = bisect.bisect_left(ranks, r)
                trains.insert(k, tr)
                sig0.insert(k, _SIG(tr))
                locked0.insert(k, len(tr.locks))
                ranks.insert(k, r)
            same = active == trains and sig == sig0 and locked == locked0
        if not same:
            self._rebuild(active, ahead_m)
            return
        for tr in new:
            self._file(tr)
        self._trains, self._sig, self._locked, self._ranks = active, sig, locked, ranks

    def _rebuild(self, active: list[TrainRuntime], ahead_m: float) -> None:
        if len(self._rank) != len(self.fleet.trains):
            self._rank = {tid: k for k, tid in enumerate(self.fleet.trains)}
            views = {id(t.view): t.view for t in self.fleet.trains.values()}
            self.span_max_m = max((_span_max_m(v) for v in views.values()), default=0.0)
            self.length_max_m = max((t.trip.vehicle.length_m for t in self.fleet.trains.values()), default=0.0)
        self._ahead_m = max(ahead_m, self.margin_m, self._ahead_m)
        self._trains = list(active)
        self._sig = list(map(_SIG, active))
        self._locked = list(map(len, map(_LOCKS, active)))
        self._ranks = [self._rank[t.train_id] for t in active]
        self._by_id, self._zone, self._body, self._always = {}, {}, {}, []
        self._reach_max_m = 0.0
        for tr in active:
            self._file(tr)

    def _file(self, tr: TrainRuntime) -> None:
        """File ``tr`` under the edges of its zone and of its body (module docstring)."""
        tid, view = tr.train_id, tr.view
        self._by_id[tid] = tr
        front_m = tr.front_m
        rear_m = front_m - tr.trip.vehicle.length_m
        starts = view.edge_start_m
        if not starts or front_m < starts[0] or rear_m > view.length_m:
            self._always.append(tid)
            return
        reach_m = max(self._approach_m(tr), self._least_stop_m(tr))
        if tr.locks:
            last = self._last_switch_m(tr)
            if last is not None:
                reach_m = max(reach_m, last - front_m)
        self._reach_max_m = max(self._reach_max_m, reach_m)
        lo = rear_m - self._ahead_m - self.length_max_m - self.span_max_m - SLACK_M
        hi = front_m + reach_m + self.length_max_m + SLACK_M
        edges = view.edges
        for e in edges[view.edge_at(lo) : view.edge_at(hi) + 1]:
            self._zone.setdefault(e, []).append(tid)
        for e in edges[view.edge_at(rear_m) : view.edge_at(front_m) + 1]:
            self._body.setdefault(e, []).append(tid)

    def _approach_m(self, tr: TrainRuntime) -> float:
        if tr.trip.vehicle.service_decel_mps2 <= 0.0:
            return math.inf
        return approach_needed_m(tr, self.margin_m)

    @staticmethod
    def _least_stop_m(tr: TrainRuntime) -> float:
        return dynamics.least_stop_distance_m(tr.trip.vehicle, tr.plant.speed_mps, tr.view.gradient_at(tr.front_m))

    def _last_switch_m(self, tr: TrainRuntime) -> float | None:
        route = tr.trip.route
        if route.id not in self._last_switch:
            self._last_switch[route.id] = max((float(rs.point_m) for rs in route.switches), default=None)
        return self._last_switch[route.id]


def _span_max_m(view: Any) -> float:
    """The longest stretch one edge of ``view``'s route covers (the last edge: to the route's end)."""
    starts = list(view.edge_start_m)
    if not starts:
        return 0.0
    ends = starts[1:] + [max(view.length_m, starts[-1])]
    return max(b - a for a, b in zip(starts, ends))
