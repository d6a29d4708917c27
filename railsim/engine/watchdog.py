"""The stall watchdog: a train that stands still for no reason stops the run instead of letting it idle on.

A train *stands for no reason* when it is on the line, before its destination, at speed 0, and not dwelling at
a stop (SUMO has not registered a halt there; a train whose dwell is over but whose route beyond the stop is not
set, ``held_for_route``, stands like any train waiting for a route). Held departures never reach this check (a held train is not
on the line yet). Standing like that for longer than ``stall_timeout_s`` is a deadlock, a lock never granted, a
controller that will not move: each such train gets a ``stalled`` event (where it stands and, if the route-lock
port can say, what it waits for: ``locks.waiting_for(tr)``), and the run fails (:attr:`StallWatch.failure`;
it stops, writes its outputs and exits 3).

**Deadlocks** are named sooner and more precisely: once trains have stood for ``deadlock_confirm_s``, the
route-lock port's wait-for graph (``locks.deadlock``: who holds or is queued ahead for the switch or section
another train waits for, plus **occupancy**: a standing train waits for the standing train directly ahead of it
within :data:`OCCUPANCY_WAIT_M`) is searched for a cycle among them; a cycle is a ``deadlock`` event naming the
trains and the resources (``ahead:T`` for "stands behind train T"), and the run fails the same way. Occupancy
closes cycles the locks alone do not show: a train that holds a single-track section stands behind a train that
waits for the section's opposing train, which waits for that section.

**Platform berths** (:mod:`railsim.engine.platforms`): a train standing at the limit of a platform that the train
ahead occupies waits for that train, as behind a platform entry signal at danger. In the wait-for graph that is an
edge to the occupant (resource ``platform:S`` for station S), however far back the train stands, and a ``stalled``
event names it (``waiting_for``: ``platform:S(T)``). While the occupant itself stands for a reason — it dwells, or
waits for its departure time — the wait is legitimate and the follower's clock does not run (each such reason
ends by itself); once the occupant stands for no reason, the follower's clock runs from then.

**Radio outages** (scenario ``faults.comm.*.outages``): a train standing behind a train ahead while an outage cuts
either off stands for a reason — its separation holds it behind the last position it heard — and its clock does
not run until the outage ends (found by fuzzing: a 550 s t2g outage stalled a run at 300 s "for no reason").
**Lock waits** likewise: a train waiting for a switch or section that a train on the line holds or is queued
ahead for (``locks.blockers``), or standing close behind a train (within :data:`OCCUPANCY_WAIT_M`), waits for a
reason while that train moves or stands for a reason of its own (a branch train waited 300 s for a flat crossing
held by a train standing out a radio outage; a follower stood 300 s behind its leader held for it at a platform
too short for both); its clock runs once every such train stands for no reason. A circular wait is still found
by the deadlock search below.

**Trains SUMO never puts on.** A train handed to SUMO waits in its insertion queue until SUMO finds the spot
free. While a train of ours stands on or near that spot (the dispatcher's departure rule names one), the wait has
a reason; once none does and SUMO still has not put it on after ``stall_timeout_s``, the train gets a ``stalled``
event (``waiting_for``: ``insertion by SUMO``) and the run fails: a train in railsim's books as on the line but
not in the world would otherwise hold its sections for ever, with no trace row and no report.

At the horizon the same rule runs once more with a shorter wait (:data:`END_STANDING_S`, or the timeout if that
is shorter): a run whose trains did not arrive because they stood still never ends as a silent success.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from railsim.engine.events.log import EventLog
from railsim.engine.occupancy import Ahead
from railsim.engine.settings import EngineSettings
from railsim.engine.train import TrainRuntime

END_STANDING_S = 60.0  # at the horizon, a train standing this long for no reason counts as stalled
DEADLOCK_CONFIRM_S = 30.0  # trains standing this long are searched for a circular wait
OCCUPANCY_WAIT_M = 400.0  # a standing train this close behind a standing train waits for it (front-to-rear gap)
STANDSTILL_MPS = 1e-6


class StallWatch:
    """Times how long each train has stood for no reason; reports stalls."""

    def __init__(
        self,
        events: EventLog,
        settings: EngineSettings,
        locks: Any,
        berths: Any = None,
        radio_out: Callable[[float, str, str], bool] | None = None,
    ) -> None:
        """``berths``: the berth rule's port (its ``waiting``: train -> (station, occupant)), or None;
        ``radio_out(t, train, train ahead)``: is the radio between them cut off (an outage), or None."""
        self.radio_out = radio_out
        self.events = events
        self.settings = settings
        self.locks = locks
        self.berth_waits: Mapping[str, tuple[str, str]] = berths.waiting if berths is not None else {}
        self.standing_since: dict[str, tuple[float, TrainRuntime]] = {}
        self.pending_since: dict[str, tuple[float, TrainRuntime]] = {}  # handed to SUMO, spot free, not put on
        self.failure: str | None = None

    def check(self, t: float, active: list[TrainRuntime], ahead: Mapping[str, Ahead | None] | None = None) -> None:
        """Every step: update the standing clocks; stall the run if one ran past ``stall_timeout_s``. ``ahead``
        is the occupancy's train directly ahead of each active train (for the deadlock search)."""
        ahead = ahead or {}
        busy: set[str] = set()  # moving, or standing for a reason of its own
        waiting: list[TrainRuntime] = []
        for tr in active:
            if tr.plant.speed_mps > STANDSTILL_MPS:  # moving: the commonest answer, asked first
                busy.add(tr.train_id)
                continue
            held = tr.hold_until_s is not None and t < tr.hold_until_s  # a unit early for its next departure
            dwelling = (tr.sumo_stopped or tr.sumo_stopped_now) and not tr.held_for_route
            if dwelling or held or self._radio_wait(t, tr, ahead):
                busy.add(tr.train_id)
            else:
                waiting.append(tr)
        busy |= self._waiting_for_busy(waiting, busy, ahead)
        standing_since = self.standing_since
        if standing_since:  # a busy train's clock stops (few clocks run: look among them)
            for train_id in [k for k in standing_since if k in busy]:
                del standing_since[train_id]
        for tr in waiting:  # the standing trains that wait for no busy train: their clocks run
            if tr.train_id not in busy and tr.train_id not in standing_since:
                standing_since[tr.train_id] = (t, tr)
        self._deadlock(t, ahead)
        self._report(t, self.settings.stall_timeout_s, "")

    def pending(self, t: float, pending: list[TrainRuntime], blocker: Callable[[TrainRuntime], str | None]) -> None:
        """Every step, the trains handed to SUMO that it has not put on yet; ``blocker(tr)``: why its spot is not
        free (a train of ours on or near it), or None. Stalls the run once one waited ``stall_timeout_s`` with its
        spot free (module docstring)."""
        waiting = {tr.train_id for tr in pending}
        for train_id in [k for k in self.pending_since if k not in waiting]:
            del self.pending_since[train_id]  # put on (or withdrawn)
        for tr in pending:
            if blocker(tr) is not None:
                self.pending_since.pop(tr.train_id, None)
            elif tr.train_id not in self.pending_since:
                self.pending_since[tr.train_id] = (t, tr)
        if self.failure is not None:
            return
        stuck = [(since, tr) for since, tr in self.pending_since.values() if t - since >= self.settings.stall_timeout_s]
        for since, tr in stuck:
            self.events.record(
                t,
                "stalled",
                tr.train_id,
                chainage_m=round(tr.front_m, 3),
                edge=tr.view.edges[tr.view.edge_at(tr.front_m)],
                standing_s=round(t - since, 3),
                waiting_for="insertion by SUMO",
            )
        if stuck:
            names = ", ".join(f"{tr.train_id} at {tr.front_m:.0f} m" for _, tr in stuck)
            self.failure = (
                f"stalled: {names} handed to SUMO but never put on (its spot free for at least "
                f"{self.settings.stall_timeout_s:g} s)"
            )

    def _radio_wait(self, t: float, tr: TrainRuntime, ahead: Mapping[str, Ahead | None]) -> bool:
        """Does ``tr`` stand behind a train ahead while an outage cuts either off? (Asked of standing trains only.)"""
        a = ahead.get(tr.train_id)
        return a is not None and self.radio_out is not None and self.radio_out(t, tr.train_id, a.train_id)

    def _waiting_for_busy(
        self, waiting: list[TrainRuntime], busy: set[str], ahead: Mapping[str, Ahead | None]
    ) -> set[str]:
        """The standing trains that wait for a busy train — the train directly ahead within
        :data:`OCCUPANCY_WAIT_M`, the occupant of the platform they wait to enter, or a train holding or queued
        ahead for a switch or section they asked for (``locks.blockers``) — directly or through other such trains
        (module docstring). A circular wait with no busy train in it never qualifies: the deadlock search finds
        it."""
        if not waiting:
            return set()
        blockers = getattr(self.locks, "blockers", None)
        waits: dict[str, set[str]] = {}
        for tr in waiting:
            others = {o for os in blockers(tr).values() for o in os} if blockers is not None else set()
            berth = self.berth_waits.get(tr.train_id)
            if berth is not None:
                others.add(berth[1])
            a = ahead.get(tr.train_id)
            if a is not None and a.gap_m <= OCCUPANCY_WAIT_M:
                others.add(a.train_id)
            waits[tr.train_id] = others
        # the least fixed point {w : waits[w] meets busy ∪ found}, grown outward from the busy trains along the
        # reversed waits (linear in the waits: a queue of hundreds at a terminus costs no pass per train)
        waited_for_by: dict[str, list[str]] = {}
        for train_id, others in waits.items():
            for other in others:
                waited_for_by.setdefault(other, []).append(train_id)
        found: set[str] = set()
        frontier = [b for b in busy if b in waited_for_by]
        while frontier:
            for train_id in waited_for_by.get(frontier.pop(), ()):
                if train_id not in found:
                    found.add(train_id)
                    frontier.append(train_id)
        return found

    def _deadlock(self, t: float, ahead: Mapping[str, Ahead | None]) -> None:
        finder = getattr(self.locks, "deadlock", None)
        if self.failure is not None or finder is None:
            return
        standing = [tr for since, tr in self.standing_since.values() if t - since >= DEADLOCK_CONFIRM_S]
        if len(standing) < 2:
            return
        behind: dict[str, tuple[str, str]] = {}  # standing train -> (the train it waits behind, the resource)
        for tr in standing:
            a = ahead.get(tr.train_id)
            berth = self.berth_waits.get(tr.train_id)
            if berth is not None:
                behind[tr.train_id] = (berth[1], f"platform:{berth[0]}")
            elif a is not None and a.gap_m <= OCCUPANCY_WAIT_M:
                behind[tr.train_id] = (a.train_id, f"ahead:{a.train_id}")
        found = finder(standing, behind)
        if found is None:
            return
        trains, resources = found
        self.events.record(t, "deadlock", "interlocking", trains=trains, resources=resources)
        self.failure = (
            f"deadlock: {', '.join(trains)} wait for each other ({', '.join(resources)}) — no train can move; "
            "cross them at a passing place or re-time them"
        )

    def at_end(self, t: float) -> None:
        """At the horizon: trains standing for no reason (and not arrived) fail the run too."""
        self._report(t, min(END_STANDING_S, self.settings.stall_timeout_s), " when the horizon ended")

    def _report(self, t: float, limit_s: float, when: str) -> None:
        if self.failure is not None:
            return
        stalled = [
            (since, tr)
            for since, tr in self.standing_since.values()
            if tr.on_line and t - since >= limit_s and tr.arrived_s is None
        ]
        if not stalled:
            return
        waiting_for = getattr(self.locks, "waiting_for", None)  # the route-lock port may say what blocks a train
        parts = []
        for since, tr in stalled:
            waits = list(waiting_for(tr)) if waiting_for is not None else []
            berth = self.berth_waits.get(tr.train_id)
            if berth is not None:
                waits.append(f"platform:{berth[0]}({berth[1]})")
            self.events.record(
                t,
                "stalled",
                tr.train_id,
                chainage_m=round(tr.front_m, 3),
                edge=tr.view.edges[tr.view.edge_at(tr.front_m)],
                standing_s=round(t - since, 3),
                waiting_for=";".join(waits) if waits else None,
            )
            parts.append(
                f"{tr.train_id} at {tr.front_m:.0f} m" + (f" (waiting for {', '.join(waits)})" if waits else "")
            )
        self.failure = f"stalled{when}: {'; '.join(parts)} stood still for no reason for at least {limit_s:g} s"
