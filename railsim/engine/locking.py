"""Route locking on the train side: when a train asks the interlocking for a switch, how far its movement
authority reaches, and when it releases (the engine side of :mod:`railsim.engine.events.interlocking`).

Every switch on a train's route is requested ``lock_request_distance_m`` before its point; until the lock is
granted the train's movement authority ends ``protection_margin_m`` before the switch point; the lock is
released when the train's rear is ``clearance_m`` past the point. A coupled follower on the same leg rides on
its leader's request (one lock for the formation). Passing a switch without its lock is a ``switch_violation``
event. An extension may take over the requests for some trains and switches (``managed_by``: the junction
planner requests in its planned order).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

import networkx as nx

from railsim.engine.coupling import COUPLED_STATES, FormationBook
from railsim.engine.events.interlocking import Interlocking
from railsim.engine.events.log import EventLog
from railsim.engine.fleet import Fleet
from railsim.engine.settings import EngineSettings
from railsim.engine.train import TrainRuntime

log = logging.getLogger(__name__)


class RouteLocks:
    """Requests, authority and releases of switch locks for every train."""

    def __init__(
        self,
        fleet: Fleet,
        interlocking: Interlocking,
        formations: FormationBook,
        events: EventLog,
        settings: EngineSettings,
    ) -> None:
        self.fleet = fleet
        self.interlocking = interlocking
        self.formations = formations
        self.events = events
        self.settings = settings
        self.managed_by: Callable[[str, str], bool] = lambda _train, _switch: False

    def bookkeeping(self, t: float, tr: TrainRuntime) -> None:
        """Request locks ahead, detect a pass without a lock, release behind the rear."""
        length = tr.trip.vehicle.length_m
        for rs in tr.trip.route.switches:
            sid = rs.switch_id
            if sid in tr.released:
                continue
            if rs.point_m < tr.trip.depart_chainage_m - length:
                continue
            if (
                sid not in tr.locks
                and rs.point_m - tr.front_m <= self.settings.lock_request_distance_m
                and not self.managed_by(tr.train_id, sid)
            ):
                holders = self._lock_group(tr, rs)
                if holders is not None:
                    req = self.interlocking.request(holders, sid, rs.leg)
                    for h in holders:
                        self.fleet.trains[h].locks[sid] = req
            if (
                sid in tr.locks
                and tr.front_m > rs.point_m
                and sid not in tr.violations
                and not self.interlocking.is_locked_for(tr.train_id, sid, rs.leg)
            ):
                tr.violations.add(sid)
                self.events.record(t, "switch_violation", tr.train_id, switch=sid, leg=rs.leg)
                log.error("%s passed switch %s without its lock", tr.train_id, sid)
            if sid in tr.locks and tr.front_m - length > rs.point_m + self.settings.clearance_m:
                self.interlocking.release(tr.train_id, sid)
                tr.released.add(sid)

    def _lock_group(self, tr: TrainRuntime, rs: Any) -> tuple[str, ...] | None:
        """Who requests: a coupled follower on the same leg rides on its leader's request."""
        f = self.formations.of_follower.get(tr.train_id)
        if f is not None and self.formations.manager.state(f.id) in COUPLED_STATES:
            leader = self.formations.leader_of(f)
            if rs.switch_id in leader.locks and rs.switch_id not in leader.released:
                req = leader.locks[rs.switch_id]
                if tr.train_id in getattr(req, "holder_ids", ()):
                    return None  # already in the leader's group
        group = [tr.train_id]
        for f2 in self.formations.of_leader.get(tr.train_id, ()):  # include coupled followers on the same leg
            if self.formations.manager.state(f2.id) not in COUPLED_STATES:
                continue
            fol = self.formations.follower_of(f2)
            if fol.status not in ("inserting", "running") or rs.switch_id in fol.locks:
                continue
            if any(s.switch_id == rs.switch_id and s.leg == rs.leg for s in fol.trip.route.switches):
                group.append(fol.train_id)
        return tuple(group)

    def release_all(self, tr: TrainRuntime) -> None:
        """A train that arrived or left the line gives up every lock it still holds."""
        for sid in list(tr.locks):
            if sid not in tr.released:
                self.interlocking.release(tr.train_id, sid)
                tr.released.add(sid)

    # ------------------------------------------------------------------ who waits for whom
    def held_by(self, tr: TrainRuntime) -> list[str]:
        """Switches whose lock ``tr`` (or its group) holds and has not released."""
        return [sid for sid, req in tr.locks.items() if sid not in tr.released and self.interlocking.is_granted(req)]

    def waiting_for(self, tr: TrainRuntime) -> list[str]:
        """Switches ``tr`` has asked for and not been granted yet."""
        return [
            sid for sid, req in tr.locks.items() if sid not in tr.released and not self.interlocking.is_granted(req)
        ]

    def blockers(self, tr: TrainRuntime) -> dict[str, tuple[str, ...]]:
        """For each switch ``tr`` waits for: the trains it waits behind (the lock holder and the requests queued
        ahead of its own, FIFO), excluding its own group."""
        out: dict[str, tuple[str, ...]] = {}
        for sid in self.waiting_for(tr):
            own = tr.locks[sid]
            ahead: list[str] = list(self.interlocking.holder(sid) or ())
            for req in self.interlocking.queue(sid):
                if req is own:
                    break
                ahead.extend(req.holder_ids)
            out[sid] = tuple(dict.fromkeys(h for h in ahead if h not in own.holder_ids))
        return out

    def deadlock(self, trains: list[TrainRuntime]) -> tuple[list[str], list[str]] | None:
        """A circular wait among ``trains``: ``(train ids in the cycle, switches involved)``, or None.

        Train A waits for B when B holds (or is queued ahead for) a switch A asked for. A cycle in that graph can
        never resolve by itself: the interlocking serves each switch first-in-first-out and nobody releases a
        lock without moving past the switch.
        """
        by_id = {tr.train_id: tr for tr in trains}
        waits: dict[str, dict[str, str]] = {}  # train -> {blocking train: switch}
        for tr in trains:
            for sid, others in self.blockers(tr).items():
                for other in others:
                    if other in by_id:
                        waits.setdefault(tr.train_id, {})[other] = sid
        graph = nx.DiGraph()
        for a in sorted(waits):  # insertion order keeps the search deterministic
            for b in sorted(waits[a]):
                graph.add_edge(a, b, switch=waits[a][b])
        try:
            edges = nx.find_cycle(graph)
        except nx.NetworkXNoCycle:
            return None
        return [a for a, _ in edges], sorted({graph.edges[a, b]["switch"] for a, b in edges})

    def authority_end_m(self, tr: TrainRuntime) -> float:
        """Route chainage where the train's movement authority ends (before the first switch not locked for it)."""
        end = tr.view.length_m - 1.0
        for rs in tr.trip.route.switches:
            if rs.point_m <= tr.front_m - 1e-6 or rs.switch_id in tr.released:
                continue
            if not self.interlocking.is_locked_for(tr.train_id, rs.switch_id, rs.leg):
                return min(end, rs.point_m - self.settings.protection_margin_m)
        return end
