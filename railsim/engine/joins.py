"""Where formations couple: joining at a station, and a reason for every formation that does not couple where
it asked (the engine side of ``couple: {at_station: X}`` and ``couple: {after_switch: X}``; docs/model.md,
"Formations: where they couple").

* **Joining at a station.** Both trips stop at ``X`` and the pair fits on the leader's platform there
  (:meth:`Joins.check_platform`, before the run). The leader stays at ``X`` after its dwell
  (:meth:`Joins.holds`, the stop book's ``departure_held_for_follower``) with no route set beyond it
  (:meth:`Joins.route_waits`: the pair takes one lock once coupled), until the two are coupled and the follower's
  dwell there has ended — at most one coupling timeout after its own dwell. The follower runs in behind it and asks
  to couple on its final approach (:meth:`Joins.run_in`); as a coupling follower it halts the target gap behind
  its leader (:meth:`railsim.engine.coupling.FormationBook.mark_offset_m`) and locks in standing (Paper D's
  station-entry case).
* **Nothing silent.** A join or a merge that cannot couple is a ``coupling_failed`` event with its ``reason``:
  ``timeout``, ``wrong_order`` (the follower was first), ``blocked`` (a train between them), ``aborted``,
  ``not_reached`` (the run ended first); :meth:`Joins.where_asked` is the summary's ``formations_asked`` block.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

from railsim.engine.events.formations import FormationManager
from railsim.engine.fleet import Fleet
from railsim.engine.occupancy import Ahead
from railsim.engine.train import TrainRuntime
from railsim.engine.trips import TripStop
from railsim.errors import ConfigError

# a follower asks to couple once this close behind its leader standing at a platform: a unit that comes round by
# its turnback (before the separation controller, margin 50 m on Line 3, would stop it further back), or one that
# joins at a station (there, on its final approach if that comes first)
COUPLE_REACH_M = 150.0
MERGE_CLEAR_M = 10.0  # a leader waiting past a merge stands with its rear this far past the points (the lock's
# release clearance, ``EngineSettings.clearance_m``) — a platform closer to the merge is no join station
STANDING_MPS = 0.1  # a follower slower than this behind its waiting leader stands (at the berth limit)


def pair_length_m(f: Any, leader: TrainRuntime, follower: TrainRuntime) -> float:
    """Platform length formation ``f`` needs to stand on: leader, target gap, follower, and the 1 m the leader's
    front halts before the platform end."""
    return leader.trip.vehicle.length_m + float(f.target_gap_m) + follower.trip.vehicle.length_m + 1.0


def trig(trigger: Any, kind: str) -> bool:
    """True if a formation trigger (``couple``/``decouple``, possibly None) is of ``kind``."""
    return trigger is not None and trigger.kind == kind


def stop_index(tr: TrainRuntime, station: str) -> int | None:
    """Index of ``tr``'s first station stop at ``station``, or None."""
    return next((i for i, s in enumerate(tr.trip.stops) if s.station_id == station and s.kind != "reversal"), None)


def shared_platform(leader: TrainRuntime, follower: TrainRuntime, station: str) -> tuple[int, int] | None:
    """The two trips' stops at ``station`` where they join: the first platform both stop at (the follower can
    only run in behind its leader on the leader's track), else their first stops there; None if one does not stop
    there."""
    ours = [i for i, s in enumerate(leader.trip.stops) if s.station_id == station and s.kind != "reversal"]
    theirs = [i for i, s in enumerate(follower.trip.stops) if s.station_id == station and s.kind != "reversal"]
    if not ours or not theirs:
        return None
    for li in ours:
        fi = next((i for i in theirs if follower.trip.stops[i].stop_id == leader.trip.stops[li].stop_id), None)
        if fi is not None:
            return li, fi
    return ours[0], theirs[0]


class FormationsView(Protocol):
    """What the joins ask of the formation book (:class:`railsim.engine.coupling.FormationBook`)."""

    manager: FormationManager
    fleet: Fleet
    of_follower: dict[str, Any]
    of_leader: dict[str, list[Any]]
    current_stop: Callable[[TrainRuntime], tuple[TripStop | None, float]]

    def follower_of(self, f: Any) -> TrainRuntime:
        """The follower of formation ``f``."""

    def leader_of(self, f: Any) -> TrainRuntime:
        """The leader of formation ``f``."""

    def mark_offset_m(self, tr: TrainRuntime, stop: TripStop) -> float:
        """How far behind the platform mark ``tr`` halts."""

    def in_final_approach(self, tr: TrainRuntime, mark_m: float) -> bool:
        """``tr`` is close enough to ``mark_m`` that station braking is (about to be) under way."""


class Joins:
    """Joins at stations and the coupled-where-asked record of every formation that asked for a place."""

    def __init__(self, book: FormationsView) -> None:
        self.book = book
        self.requested: set[str] = set()  # joins whose couple request went out at the station
        self.failed: dict[str, str] = {}  # formation -> why it did not couple where it asked
        self.coupled_where: dict[str, str] = {}  # formation -> where it coupled
        # formation -> why it cannot couple on the run after its merge (railsim.engine.merge_reach), if it cannot
        self.on_run_infeasible: dict[str, dict[str, float | None]] = {}
        self.held_since_s: dict[str, float] = {}  # formation -> when its leader's dwell at the station ended
        self._join: dict[str, tuple[int, int] | None] = {}  # formation -> (leader, follower) join stop indices

    def join_station(self, f: Any) -> str | None:
        """Where the leader of formation ``f`` waits for its follower (:meth:`join_stops`): a station id, or None."""
        stops = self.join_stops(f)
        return None if stops is None else self.book.leader_of(f).trip.stops[stops[0]].station_id

    def join_stops(self, f: Any) -> tuple[int, int] | None:
        """The leader's and the follower's stop (indices in their trips) where the leader of formation ``f`` waits
        for its follower: their first stops at ``X`` for ``couple: {at_station: X}``; for ``couple:
        {after_switch: X}`` the first stop past ``X`` where both stop (the two units come over the merge one switch
        throw apart at least, so the follower closes up there: it runs in behind its leader and couples standing or
        on the final approach) — if the pair fits on the leader's platform there, the leader standing there is
        clear of the merge, and it is not the leader's destination; None for other triggers or when there is no
        such stop. Indices, not station ids: a route may stop twice at one station, on two platforms one behind
        the other (OSM maps a stop position per platform), one before the merge and one after it."""
        if f.id not in self._join:
            leader, follower = self.book.leader_of(f), self.book.follower_of(f)
            if trig(f.couple, "at_station"):
                self._join[f.id] = shared_platform(leader, follower, str(f.couple.station))
            elif trig(f.couple, "after_switch"):
                self._join[f.id] = self._first_common_stop_after(f, leader, follower, f.couple.switch)
            else:
                self._join[f.id] = None
        return self._join[f.id]

    def _first_common_stop_after(
        self, f: Any, leader: TrainRuntime, follower: TrainRuntime, switch_id: str
    ) -> tuple[int, int] | None:
        after: dict[str, list[int]] = {}
        for tr in (leader, follower):
            point = next((rs.point_m for rs in tr.trip.route.switches if rs.switch_id == switch_id), None)
            # the leader waits there standing clear of the merge (its rear past the points' clearance), else it
            # would hold the points its follower needs
            clear_m = tr.trip.vehicle.length_m + MERGE_CLEAR_M if tr is leader else 0.0
            after[tr.train_id] = (
                []
                if point is None
                else [i for i, s in enumerate(tr.trip.stops) if s.kind == "station" and s.mark_m - clear_m > point]
            )
        theirs: dict[str, int] = {}
        for i in after[follower.train_id]:
            theirs.setdefault(follower.trip.stops[i].station_id, i)
        li = next((i for i in after[leader.train_id] if leader.trip.stops[i].station_id in theirs), None)
        if li is None:
            return None
        stop = leader.trip.stops[li]
        if stop.is_destination or stop.platform_m < pair_length_m(f, leader, follower):
            return None  # the pair would not stand on it: no wait there (they couple on the run, or time out)
        return li, theirs[stop.station_id]

    def check_platform(self, f: Any, leader: TrainRuntime, follower: TrainRuntime, where: str) -> None:
        """``couple: {at_station: X}``: both trips stop at ``X`` and the pair (leader, target gap, follower) fits
        on the leader's platform there, else a :class:`ConfigError` before the run."""
        station = f.couple.station
        field = f"{where}.couple.at_station"
        for role, tr in (("leader", leader), ("follower", follower)):
            if stop_index(tr, station) is None:
                raise ConfigError(
                    self.book.fleet.source,
                    field,
                    f"expected a station both trips stop at, got {station!r} "
                    f"(the {role} {tr.train_id} does not stop there)",
                )
        stop = leader.trip.stops[(shared_platform(leader, follower, station) or (0, 0))[0]]
        lead_m, fol_m, gap_m = leader.trip.vehicle.length_m, follower.trip.vehicle.length_m, float(f.target_gap_m)
        need_m = pair_length_m(f, leader, follower)
        if stop.platform_m < need_m:
            raise ConfigError(
                self.book.fleet.source,
                field,
                f"expected a platform the pair fits on, got {stop.platform_m:.1f} m at {station!r}: the pair needs "
                f"{need_m:.1f} m (leader {lead_m} m + gap {gap_m} m + follower {fol_m} m + 1 m before the end)",
            )

    def route_waits(self, tr: TrainRuntime, point_m: float) -> bool:
        """True while leader ``tr`` is at (or on its way to) the station where a follower joins it
        (``couple: {at_station: X}``) and the pair is not coupled yet, for a switch or section at ``point_m``
        beyond that platform: its route out is set once the two are coupled — one lock for the pair
        (:mod:`railsim.engine.locking`) — or once the join is given up. Set earlier, the lock would be the
        leader's alone and the follower would wait at the points for the leader to clear them."""
        for f in self.book.of_leader.get(tr.train_id, ()):
            stops = self.join_stops(f)
            if stops is None or f.id in self.failed:
                continue
            li, fi = stops
            if tr.next_stop != li or point_m <= tr.trip.stops[li].window_end_m:
                continue
            fol = self.book.follower_of(f)
            if self.book.manager.state(f.id) == "coupled" or fol.next_stop > fi:
                continue
            if fol.status in ("scheduled", "inserting", "running"):
                return True
        return False

    def holds(self, t: float, f: Any, stop: TripStop | None) -> bool:
        """``couple: {at_station: X}``, the leader at ``X`` after its dwell: until the pair is coupled and the
        follower's dwell there has ended (they leave together), at most one coupling timeout after the leader's
        own dwell ended. A join given up (wrong order, blocked) does not hold it; one that times out here is a
        ``coupling_failed`` event with the reason ``timeout`` (an attempt under way is aborted: the follower
        runs on on its own)."""
        stops = self.join_stops(f)
        if stops is None or stop is None or f.id in self.failed:
            return False
        leader, fol = self.book.leader_of(f), self.book.follower_of(f)
        li, fi = stops
        if leader.next_stop != li or leader.trip.stops[li] is not stop:
            return False  # not at the join stop (another stop of the same station is not it)
        state = self.book.manager.state(f.id)
        if state == "coupled":  # until the follower's dwell at the join stop itself has ended
            return fol.status == "running" and fol.next_stop == fi and not fol.held_for_route
        if fol.status not in ("scheduled", "inserting", "running") or fol.next_stop > fi:
            return False
        between = self._between_after_merge(f, leader, fol, stop) if state == "free" else None
        if between is not None:  # it runs in behind the leader: the follower cannot (no wait to the timeout)
            self.fail(t, f, "blocked", station=stop.station_id, by=between)
            return False
        waited_s = t - self.held_since_s.setdefault(f.id, t)
        if waited_s < float(f.coupling_timeout_s):
            return True
        self.fail(t, f, "timeout", station=stop.station_id, waited_s=round(waited_s, 3))
        if state == "coupling":
            self.book.manager.request_decouple(f.id)
        return False

    def _between_after_merge(self, f: Any, leader: TrainRuntime, fol: TrainRuntime, stop: TripStop) -> str | None:
        """``couple: {after_switch: X}``, the leader waiting at its join stop and the follower not past ``X``: the
        id of another train past ``X`` (or holding it, stopped short of it) whose next stop is the leader's platform (it
        will stand behind the leader, between the two), or None."""
        if not trig(f.couple, "after_switch"):
            return None
        sw = f.couple.switch

        def past(tr: TrainRuntime) -> bool:
            return any(rs.switch_id == sw and tr.front_m >= rs.point_m for rs in tr.trip.route.switches)

        if past(fol):
            return None
        for other in self.book.fleet.active():
            if other is leader or other is fol or other.status != "running":
                continue
            nxt = other.next_stop
            if nxt >= len(other.trip.stops) or other.trip.stops[nxt].stop_id != stop.stop_id:
                continue
            req = other.locks.get(sw)
            holds_points = req is not None and req.granted_s is not None and req.released_s is None
            if past(other) or holds_points:  # over the merge, or the points are its (it stands short of them)
                return other.train_id
        return None

    def run_in(self, t: float, follower: TrainRuntime, leader: TrainRuntime, f: Any, a: Ahead | None) -> None:
        """``couple: {at_station: X}``: the follower runs in behind its leader standing at ``X`` (held there,
        :meth:`holds`) and asks to couple once within :data:`COUPLE_REACH_M` of its rear or on its final approach
        to the coupled halt position, whichever comes first: it then halts ``target gap`` behind the leader
        (``FormationBook.mark_offset_m``) and the pair locks in standing or in the last metres (Paper D's
        station-entry case). Given up, with a ``coupling_failed`` event, when the follower stands at ``X`` before
        its leader (``wrong_order``) or another train that stops at ``X`` is between them (``blocked``)."""
        if f.id in self.requested or f.id in self.failed or follower.status != "running":
            return
        station = f.couple.station
        stops = self.join_stops(f)
        if stops is None or follower.next_stop != stops[1]:
            return
        li, fi = stops
        leader_there = leader.status == "running" and leader.next_stop == li and leader.sumo_stopped
        if not leader_there:
            if (
                follower.sumo_stopped
                and leader.status in ("scheduled", "inserting", "running")
                and leader.next_stop <= li
            ):
                self.fail(t, f, "wrong_order", station=station, detail="the follower stands at the station first")
            return
        if a is None:
            return
        if a.train_id != leader.train_id:
            other = self.book.fleet.trains.get(a.train_id)
            if other is not None and any(s.station_id == station for s in other.trip.stops[other.next_stop :]):
                self.fail(t, f, "blocked", station=station, by=a.train_id)  # it will stand at X between them
            return  # (one that turns off before X only delays the follower)
        if self.close_enough(follower, leader, f, a):
            self.requested.add(f.id)
            self.book.manager.request_couple(f.id)

    def close_enough(self, follower: TrainRuntime, leader: TrainRuntime, f: Any, a: Ahead) -> bool:
        """Follower ``follower`` (its leader directly ahead, ``a``) is close enough to ask to couple: within
        :data:`COUPLE_REACH_M` of its leader's rear, or — the leader standing at the station where it waits
        (:meth:`join_station`) — on its final approach to its coupled halt position there, ``target gap`` behind
        the leader, or standing (a berth limit held it before the platform: it is called on). Asked from farther back, the coupled controller's closing speed (meant for the last metres)
        would crawl the whole way."""
        if a.gap_m <= COUPLE_REACH_M:
            return True
        stops = self.join_stops(f)
        if stops is None:
            return False
        li, fi = stops
        if follower.next_stop != fi:
            return False
        if not (leader.status == "running" and leader.next_stop == li and leader.sumo_stopped):
            return False
        stop = follower.trip.stops[fi]
        lstop = leader.trip.stops[li]
        halt_m = stop.mark_m - (
            self.book.mark_offset_m(leader, lstop) + leader.trip.vehicle.length_m + float(f.target_gap_m)
        )
        # standing behind its waiting leader (held at the platform's berth limit, within one platform and the
        # couple reach of its halt; not at the station before, about to leave it): called on, it runs in
        standing = (
            follower.plant.speed_mps < STANDING_MPS and halt_m - follower.front_m <= stop.platform_m + COUPLE_REACH_M
        )
        return standing or self.book.in_final_approach(follower, halt_m)

    def merge_out_of_order(
        self, t: float, follower: TrainRuntime, leader: TrainRuntime, f: Any, a: Ahead | None
    ) -> None:
        """``couple: {after_switch: X}`` with the follower's front past ``X`` and its leader not directly ahead:
        the leader has not passed ``X`` yet (``wrong_order``: the follower reached the merge first) or another
        train runs between them (``blocked``). Logged once as ``coupling_failed``; a leader that comes to be
        directly ahead later still gets the couple request (``FormationBook._couple_after_merge``)."""
        if f.id in self.failed:
            return
        sw = f.couple.switch
        if not any(rs.switch_id == sw and follower.front_m >= rs.point_m for rs in follower.trip.route.switches):
            return
        leader_past = leader.status == "arrived" or (
            leader.status == "running"
            and any(rs.switch_id == sw and leader.front_m >= rs.point_m for rs in leader.trip.route.switches)
        )
        if not leader_past:
            self.fail(t, f, "wrong_order", switch=sw, detail="the follower reached the merge first")
        elif a is not None:
            self.fail(t, f, "blocked", switch=sw, by=a.train_id)

    def fail(self, t: float, f: Any, reason: str, **detail: Any) -> None:
        """Formation ``f`` cannot couple where it asked: a ``coupling_failed`` event with the reason, once."""
        self.failed[f.id] = reason
        self.book.manager.record(t, "coupling_failed", f.id, reason=reason, asked=asked(f), **detail)

    def note_coupled(self, f: Any, leader: TrainRuntime) -> None:
        """The pair just became coupled: where, for a formation that asked for a place."""
        if trig(f.couple, "at_station"):
            stops = self.join_stops(f)
            at_x = stops is not None and leader.status == "running" and leader.next_stop == stops[0]
            self.coupled_where[f.id] = f"at_station {f.couple.station}" if at_x else "elsewhere"
        elif trig(f.couple, "after_switch"):
            self.coupled_where[f.id] = f"after_switch {f.couple.switch}"
        else:
            self.coupled_where[f.id] = asked(f)

    def where_asked(self, t: float) -> dict[str, Any]:
        """The summary's ``formations_asked`` block — one entry per formation that asked to couple at a station or
        after a switch: ``{id, asked, coupled, where, reason}`` (``coupled``: there, as asked; plus ``on_run`` with
        the numbers when it cannot couple on the run after its merge and couples standing) — or nothing when
        none asked. A formation that neither coupled nor failed by the end of the run gets a ``coupling_failed``
        event with the reason ``not_reached`` (its units never met there), or ``timeout`` when its state machine
        gave up an attempt."""
        rows = []
        for f in self.book.of_follower.values():
            if not (trig(f.couple, "at_station") or trig(f.couple, "after_switch")):
                continue
            where = self.coupled_where.get(f.id)
            coupled = where is not None and where == asked(f)
            if not coupled and f.id not in self.failed:
                stats = self.book.manager.stats(f.id)
                if stats.failures:
                    self.failed[f.id] = "timeout"  # the state machine logged it (coupling_failed, timeout)
                elif stats.aborts:
                    self.fail(t, f, "aborted")
                else:
                    self.fail(t, f, "not_reached")
            row: dict[str, Any] = {
                "id": f.id,
                "asked": asked(f),
                "coupled": coupled,
                "where": where,
                "reason": None if coupled else self.failed.get(f.id),
            }
            if f.id in self.on_run_infeasible:  # it couples standing at the platform: the numbers why
                row["on_run"] = {"feasible": False, **self.on_run_infeasible[f.id]}
            rows.append(row)
        return {"formations_asked": rows} if rows else {}


def asked(f: Any) -> str:
    """Where formation ``f`` asked to couple, as the summary names it (``at_station X``, ``after_switch X`` …)."""
    c = f.couple
    if c is None:
        return "by event"
    if c.kind == "at_station":
        return f"at_station {c.station}"
    if c.kind == "after_switch":
        return f"after_switch {c.switch}"
    if c.kind == "at_s":
        return f"at_s {c.at_s}"
    return str(c.kind)
