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

    def authority_end_m(self, tr: TrainRuntime) -> float:
        """Route chainage where the train's movement authority ends (before the first switch not locked for it)."""
        end = tr.view.length_m - 1.0
        for rs in tr.trip.route.switches:
            if rs.point_m <= tr.front_m - 1e-6 or rs.switch_id in tr.released:
                continue
            if not self.interlocking.is_locked_for(tr.train_id, rs.switch_id, rs.leg):
                return min(end, rs.point_m - self.settings.protection_margin_m)
        return end
