"""Formation order at a merge: the interlocking serves a formation's leader first and its follower next.

A formation that asks to couple after a merge (``couple: {after_switch: X}``) with its two units coming to ``X``
from different legs can only couple if the follower passes ``X`` right after its leader; so can one that joins at
a station (``couple: {at_station: S}``) with its units coming over a merge before ``S`` from different legs (the
last such switch before ``S`` is its ``X``: a train of the leader's leg between them would stand at ``S`` behind
the waiting leader). The interlocking serves a
switch first come, first served (:mod:`railsim.engine.events.interlocking`), so without help a train of the
leader's leg that asks between the two takes the points between them, and a follower that reaches the merge first
passes it first. This extension keeps the order by holding requests back (the ``defers_lock`` hook); it never
requests or grants anything itself, so every train's authority still ends before a switch not locked for it and
its moving-block separation is untouched — the same guards as any train.

What happens in time, per such formation (a :class:`MergePair`):

1. **The follower first (the rule: it waits).** While the leader has not asked for ``X`` (and has not passed
   it), the follower's request for ``X`` is held back: its authority ends before the merge and it stands there,
   as at a signal at danger (``merge_wait_for_leader`` event, once). The alternative, swapping the roles, would
   change which unit leads the coupled train beyond the merge — its stops, its decoupling point, the formation
   the user described — so the follower waits. The wait is bounded: :func:`wait_limit_s` after it began (the
   formation's coupling timeout, ending 30 s before the stall timeout would: a wait never reads as a stall) the
   follower goes on alone (``merge_wait_ended``, ``reason: timeout``) and, passing ``X`` first, its formation logs
   ``coupling_failed`` with ``wrong_order`` (:meth:`railsim.engine.joins.Joins.merge_out_of_order`). A leader
   that is not coming (left the line, or past ``X``) ends the wait at once.
2. **The leader asked: the follower is next.** From the leader's request until the follower's, no other train
   taking ``X`` from the leader's leg may ask for it (it stops short of the merge): the follower's request, made
   by the engine's distance rule as soon as it may, queues right behind its leader's. Trains that asked before
   the leader are committed and keep their place; a train on the follower's leg in front of the follower is never
   held (it must pass first: holding it would hold the follower too). Bounded by the same limit from the moment the
   leader's front passes ``X`` — before that no train behind it on its leg may ask anyway — after which
   (``merge_priority_lapsed``) a train that passes between them makes the formation ``blocked``.
3. **A train between them on the follower's leg goes first.** While the leader has not asked (from the moment it
   is within the engine's lock request distance of ``X``), a train that
   comes to ``X`` on the follower's leg ahead of the follower and has not asked yet would pass between the two
   if the leader asked before it; the leader's request waits for it (``merge_leader_yields``, naming it; at
   most the wait limit), so it passes before the leader.
4. **On the run or standing.** When the pairs are found (the first step), each ``after_switch`` pair whose leader
   stops at a platform just past ``X`` is checked with :func:`railsim.engine.merge_reach.on_run_reach`: if the
   switch interval on the leader's own profile, the follower's run to its slot and the coupled state's hold do
   not fit before the leader stands, the run says so (``coupling_on_run_infeasible`` event with the numbers, and
   ``on_run`` in the summary's ``formations_asked`` entry) and the pair couples standing, as below.
5. **Past the merge** the engine takes over: the follower asks to couple once past ``X`` with its leader
   directly ahead and close enough (:meth:`railsim.engine.joins.Joins.close_enough`), and the leader waits at the first station past ``X`` both serve until they are coupled
   (:meth:`railsim.engine.joins.Joins.join_station`). Two legs cannot both be set at once: the follower passes
   ``X`` at least the leader's clearing time plus one switch throw after it, so the pair closes up on the run to
   that station or standing there.

More than one formation may share a merge: each pair holds back only trains of its leader's leg, so the
formations are served in the order their leaders ask, each leader's follower right after it. Two formations may
come *crossed*: each leader on the other's follower's leg, ahead of that follower. Then whichever leader passes
first, the other passes between the first one's two units, so at most one of the two can couple there. The
formation whose leader began to wait first (for the other leader, under rule 3) keeps its order; the other gives
way at once (``merge_crossed``, naming the formation it gives way to): its leader goes first, nothing is held for
it, and it fails as ``blocked`` when the other leader passes between its units. Without this, each leader would
wait for the other until the wait limit.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from railsim.engine.extensions.base import Extension
from railsim.engine.extensions.context import ExtensionContext
from railsim.engine.joins import shared_platform
from railsim.engine.merge_reach import OnRunReach, on_run_reach
from railsim.engine.settings import INF

if TYPE_CHECKING:  # pragma: no cover
    from railsim.engine.train import TrainRuntime
    from railsim.scenario import Scenario

ON_THE_WAY = ("scheduled", "inserting", "running")
STALL_MARGIN_S = 30.0  # a wait at a merge ends this long before the stall watchdog would call the train stalled


def wait_limit_s(coupling_timeout_s: float, stall_timeout_s: float) -> float:
    """How long a follower waits for its leader at a merge, and how long other trains are held back for it: the
    formation's coupling timeout, at most :data:`STALL_MARGIN_S` short of the stall timeout (a held train stands
    for a reason the stall watchdog does not see; it starts standing only after the wait began)."""
    return max(0.0, min(coupling_timeout_s, stall_timeout_s - STALL_MARGIN_S))


def _merge_before(leader: TrainRuntime, follower: TrainRuntime, f: object) -> str | None:
    """``couple: {at_station: X}``: the last switch before their join stop at ``X`` (the platform both stop at,
    :func:`railsim.engine.joins.shared_platform`) that the two units pass on different legs (where the follower's
    way joins its leader's), or None when they come to ``X`` on one way."""
    stops = shared_platform(leader, follower, str(f.couple.station))  # type: ignore[attr-defined]
    if stops is None:
        return None
    lead_mark_m, fol_mark_m = leader.trip.stops[stops[0]].mark_m, follower.trip.stops[stops[1]].mark_m
    legs = {rs.switch_id: rs.leg for rs in follower.trip.route.switches if rs.point_m < fol_mark_m}
    before = [
        rs
        for rs in leader.trip.route.switches
        if rs.point_m < lead_mark_m and rs.switch_id in legs and legs[rs.switch_id] != rs.leg
    ]
    return max(before, key=lambda rs: rs.point_m).switch_id if before else None


def _limit_at(tr: TrainRuntime, route_m: float) -> float:
    """The speed limit on ``tr``'s route just before chainage ``route_m`` (the line speed outside restrictions)."""
    for a, b, v in tr.trip.route.speed_limits:
        if a < route_m <= b + 0.5:
            return float(v)
    return float(tr.view.line_speed_mps)


@dataclass
class MergePair:
    """One formation coupling after merge ``switch_id``, its units on different legs there."""

    formation_id: str
    leader_id: str
    follower_id: str
    switch_id: str
    leader_leg: str
    follower_leg: str
    point_leader_m: float  # the switch point on the leader's route chainage
    point_follower_m: float
    limit_s: float
    wait_since_s: float | None = None  # the follower waits for its leader since
    leader_asked_s: float | None = None
    leader_past_s: float | None = None  # the leader's front passed the switch point (trains behind it may ask)
    yield_to: str | None = None  # the leader lets this train of the follower's leg ask first
    yield_since_s: float | None = None
    done: bool = False  # the follower asked (or gave up waiting): nothing more to keep


class MergeOrder(Extension):
    """Keeps formation order at merges (module docstring)."""

    @classmethod
    def applies(cls, scenario: Scenario) -> bool:
        """Any formation that asks to couple after a switch."""
        return any(
            f.couple is not None and f.couple.kind in ("after_switch", "at_station") for f in scenario.formations
        )

    def __init__(self, ctx: ExtensionContext) -> None:
        super().__init__(ctx)
        self.pairs: list[MergePair] | None = None  # found at the first step (the formation book is filled then)
        self.now_s = 0.0
        self._legs: dict[str, dict[str, str]] = {}  # train id -> switch id -> leg on its route

    # ------------------------------------------------------------------ set-up
    def _leg(self, tr: TrainRuntime, switch_id: str) -> str | None:
        legs = self._legs.get(tr.train_id)
        if legs is None:
            legs = self._legs[tr.train_id] = {rs.switch_id: rs.leg for rs in tr.trip.route.switches}
        return legs.get(switch_id)

    def _find_pairs(self) -> list[MergePair]:
        pairs = []
        stall_s = self.ctx.settings.stall_timeout_s
        for fid, f in self.ctx.formations.of_follower.items():
            if f.couple is None or f.couple.kind not in ("after_switch", "at_station"):
                continue
            leader, follower = self.ctx.formations.leader_of(f), self.ctx.trains[fid]
            sw = str(f.couple.switch) if f.couple.kind == "after_switch" else _merge_before(leader, follower, f)
            if sw is None:
                continue
            points = {}
            for tr in (leader, follower):
                points[tr.train_id] = next((rs for rs in tr.trip.route.switches if rs.switch_id == sw), None)
            lp, fp = points[leader.train_id], points[follower.train_id]
            if lp is None or fp is None or lp.leg == fp.leg:
                continue  # not a merge between them: the engine's order is the track's
            pairs.append(
                MergePair(
                    f.id,
                    leader.train_id,
                    follower.train_id,
                    sw,
                    lp.leg,
                    fp.leg,
                    lp.point_m,
                    fp.point_m,
                    wait_limit_s(float(f.coupling_timeout_s), stall_s),
                )
            )
        return pairs

    def _on_run_verdict(self, t: float, p: MergePair) -> None:
        """Record, for an ``after_switch`` pair, that it cannot couple on the run before its leader stands at its
        next stop past the merge (module docstring, item 4); nothing when it can or the leader does not stop."""
        f = self.ctx.formations.of_follower[p.follower_id]
        if f.couple is None or f.couple.kind != "after_switch":
            return
        reach = self.on_run(p, float(f.target_gap_m))
        if reach is None or reach.feasible:
            return
        detail = reach.detail()
        self.ctx.formations.note_on_run_infeasible(p.formation_id, detail)
        self.ctx.events.record(
            t, "coupling_on_run_infeasible", p.formation_id, switch=p.switch_id, leader=p.leader_id, **detail
        )

    def on_run(self, p: MergePair, target_gap_m: float) -> OnRunReach | None:
        """:func:`~railsim.engine.merge_reach.on_run_reach` with the engine's numbers for pair ``p`` (None when the
        leader has no stop past the merge)."""
        leader, follower = self.ctx.trains[p.leader_id], self.ctx.trains[p.follower_id]
        halt = next((s.mark_m for s in leader.trip.stops if s.mark_m > p.point_leader_m), None)
        if halt is None:
            return None
        ato = getattr(leader.controllers.get("ato"), "params", None)
        margin = float(getattr(ato, "speed_margin_mps", 0.0))
        share = float(getattr(ato, "planning_decel_fraction", 1.0))
        lveh, fveh = leader.trip.vehicle, follower.trip.vehicle
        return on_run_reach(
            leader_limit_mps=min(_limit_at(leader, p.point_leader_m), lveh.max_speed_mps),
            speed_margin_mps=margin,
            brake_mps2=share * lveh.service_decel_mps2,
            halt_m=halt - p.point_leader_m,
            leader_length_m=lveh.length_m,
            clearance_m=self.ctx.settings.clearance_m,
            throw_s=float(self.ctx.switch_throw_s.get(p.switch_id, 0.0)),
            follower_turnout_mps=min(_limit_at(follower, p.point_follower_m), fveh.max_speed_mps),
            follower_line_mps=min(_limit_at(follower, p.point_follower_m + 1.0), fveh.max_speed_mps),
            follower_length_m=fveh.length_m,
            target_gap_m=target_gap_m,
            hold_s=self.ctx.formations.manager.formation(p.formation_id).hold_s,
        )

    # ------------------------------------------------------------------ every step
    def before_bookkeeping(self, t: float) -> None:
        """Follow each pair: who asked for the merge, who waits, and when a wait or a priority lapses."""
        self.now_s = t
        if self.pairs is None:
            self.pairs = self._find_pairs()
            for p in self.pairs:
                self._on_run_verdict(t, p)
        for p in self.pairs:
            if not p.done:
                self._update(t, p)

    def _update(self, t: float, p: MergePair) -> None:
        trains = self.ctx.trains
        leader, follower = trains[p.leader_id], trains[p.follower_id]
        if p.switch_id in follower.locks or follower.status not in ON_THE_WAY or follower.front_m >= p.point_follower_m:
            p.done = True  # the follower asked (queued behind its leader), left, or is past: the order is kept
            return
        if p.leader_asked_s is None and (p.switch_id in leader.locks or self._leader_past(leader, p)):
            p.leader_asked_s = t
            if p.wait_since_s is not None:
                self._wait_ended(t, p, "leader_asked")
        if p.leader_asked_s is None:
            if not self._leader_coming(leader, p):
                p.done = True  # the leader will not come over the merge: the follower goes its own way
                return
            self._yield(t, leader, follower, p)
            if p.wait_since_s is None and self._would_ask(follower, p):
                p.wait_since_s = t
                self.ctx.events.record(
                    t,
                    "merge_wait_for_leader",
                    p.follower_id,
                    formation=p.formation_id,
                    switch=p.switch_id,
                    leader=p.leader_id,
                    limit_s=p.limit_s,
                )
            elif p.wait_since_s is not None and t - p.wait_since_s >= p.limit_s:
                p.done = True
                self._wait_ended(t, p, "timeout")
        elif p.leader_past_s is None:
            if self._leader_past(leader, p):
                p.leader_past_s = t
        elif t - p.leader_past_s >= p.limit_s:
            p.done = True
            self.ctx.events.record(
                t,
                "merge_priority_lapsed",
                p.follower_id,
                formation=p.formation_id,
                switch=p.switch_id,
                held_s=round(t - p.leader_past_s, 3),
            )

    def _wait_ended(self, t: float, p: MergePair, reason: str) -> None:
        """Record that the follower stops waiting for its leader before the merge (``leader_asked`` or ``timeout``)."""
        assert p.wait_since_s is not None
        self.ctx.events.record(
            t,
            "merge_wait_ended",
            p.follower_id,
            formation=p.formation_id,
            switch=p.switch_id,
            reason=reason,
            waited_s=round(t - p.wait_since_s, 3),
        )

    def _yield(self, t: float, leader: TrainRuntime, follower: TrainRuntime, p: MergePair) -> None:
        """Before the leader asked, once it is within the request distance: the train on the follower's leg ahead
        of the follower that has not asked for the merge yet, for which the leader waits (``p.yield_to``), or
        None — at most the wait limit. With the follower not on the line yet, a train due to leave before it
        (within the wait limit) from a platform before the merge counts too."""
        p.yield_to = None
        if leader.status != "running" or p.point_leader_m - leader.front_m > self.ctx.settings.lock_request_distance_m:
            return
        if p.yield_since_s is not None and t - p.yield_since_s >= p.limit_s:
            return
        own_m = p.point_follower_m - follower.front_m if follower.status == "running" else INF
        first, first_m = None, INF
        for tr in self.ctx.trains.values():
            if tr.train_id in (p.leader_id, p.follower_id) or p.switch_id in tr.locks:
                continue
            if self._leg(tr, p.switch_id) != p.follower_leg:
                continue
            point_m = next(rs.point_m for rs in tr.trip.route.switches if rs.switch_id == p.switch_id)
            if tr.status == "running":
                to_go_m = point_m - tr.front_m
            elif tr.status in ("scheduled", "inserting") and follower.status in ("scheduled", "inserting"):
                # not on the line yet, but due to leave before the follower (which is not on the line either)
                # from a platform before the merge: it will come between the two as well
                if tr.trip.depart_s >= follower.trip.depart_s or tr.trip.depart_s - t > p.limit_s:
                    continue
                to_go_m = point_m - tr.trip.depart_chainage_m
            else:
                continue
            if 0.0 < to_go_m < own_m and to_go_m < first_m:
                first, first_m = tr.train_id, to_go_m
        rival = self._crossed(first, p)
        if rival is not None:
            # crossed formations: the other leader already waits for this one (this one is ahead of its follower),
            # and this one would wait for it; whichever goes first, a unit passes between the other pair's two.
            # The formation whose leader waited first keeps its order; this one gives way at once (no hold, no
            # priority that would only delay the other pair) and says so
            p.done = True
            self.ctx.events.record(
                t,
                "merge_crossed",
                p.leader_id,
                formation=p.formation_id,
                switch=p.switch_id,
                gives_way_to=rival.formation_id,
            )
            return
        p.yield_to = first
        if first is not None and p.yield_since_s is None:
            p.yield_since_s = t
            self.ctx.events.record(
                t, "merge_leader_yields", p.leader_id, formation=p.formation_id, switch=p.switch_id, to=first
            )

    def _crossed(self, train_id: str | None, p: MergePair) -> MergePair | None:
        """The pair at ``p``'s merge that ``train_id`` leads and whose leader already waits for ``p``'s leader (two
        formations crossed at one merge: each leader ahead of the other's follower), or None."""
        if train_id is None:
            return None
        for q in self.pairs or ():
            if q is not p and not q.done and q.switch_id == p.switch_id and q.leader_id == train_id:
                if q.yield_to == p.leader_id:
                    return q
        return None

    @staticmethod
    def _leader_past(leader: TrainRuntime, p: MergePair) -> bool:
        return leader.status == "arrived" or (leader.status == "running" and leader.front_m >= p.point_leader_m)

    @staticmethod
    def _leader_coming(leader: TrainRuntime, p: MergePair) -> bool:
        return leader.status in ON_THE_WAY and leader.front_m < p.point_leader_m

    def _would_ask(self, follower: TrainRuntime, p: MergePair) -> bool:
        """The follower is on the line within the engine's request distance of the merge and has no stop left to
        serve before it (or stands at the last one, its route not set): from then on it waits for the merge. A
        follower still serving stops on its way there is not waiting yet — counted from its first held request,
        the wait ran out while it was still stations away (the request distance spans several tram stops)."""
        if follower.status != "running":
            return False
        if p.point_follower_m - follower.front_m > self.ctx.settings.lock_request_distance_m:
            return False
        stops = follower.trip.stops
        nxt = follower.next_stop
        return nxt >= len(stops) or stops[nxt].mark_m > p.point_follower_m or follower.held_for_route

    # ------------------------------------------------------------------ the hook
    def defers_lock(self, train_id: str, switch_id: str) -> bool:
        """Hold back the follower's request while it waits for its leader, and any request from the leader's leg
        between the leader's and the follower's (module docstring) — and, for a train held back at a merge, its
        requests for switches beyond that merge too: asked out of order, a switch past the merge would be held
        by a train standing before it, and a leader whose route runs on over it would wait for its own follower
        (a deadlock)."""
        tr = self.ctx.trains.get(train_id)
        for p in self.pairs or ():
            if p.done:
                continue
            if p.switch_id != switch_id and not (tr is not None and self._beyond(tr, switch_id, p.switch_id)):
                continue
            if self._holds_back(train_id, p):
                return True
        return False

    def _holds_back(self, train_id: str, p: MergePair) -> bool:
        """Train ``train_id``'s request for the merge of pair ``p`` waits (module docstring)."""
        if p.leader_asked_s is None:
            return train_id == p.follower_id or (train_id == p.leader_id and p.yield_to is not None)
        if train_id in (p.leader_id, p.follower_id):
            return False
        other = self.ctx.trains.get(train_id)
        return other is not None and self._leg(other, p.switch_id) == p.leader_leg

    @staticmethod
    def _beyond(tr: TrainRuntime, switch_id: str, merge_id: str) -> bool:
        """``switch_id`` lies past merge ``merge_id`` on ``tr``'s route, and ``tr`` has not asked for the merge."""
        if merge_id in tr.locks:
            return False
        points = {rs.switch_id: rs.point_m for rs in tr.trip.route.switches}
        return switch_id in points and merge_id in points and points[switch_id] > points[merge_id]
