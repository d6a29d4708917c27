"""What trains know of each other: position reports over the radio channels, and registration snapshots.

Truth vs knowledge (docs/architecture.md): a controller never sees another train's true state. Every step each
train sends a *report* — ``(route id, front chainage, speed, applied acceleration, time)`` plus the plan its
controller returned at the previous step — to the ground (``t2g``) and, as a formation leader, to its followers
(``t2t``; an extension may add receivers, e.g. Paper C's graph neighbours). :meth:`Knowledge.known_state` turns
the latest delivered report into a :class:`controllers.base.PredecessorState` in the observer's route frame
(stale when late; only the part of the body on the observer's track).

Before any message has arrived a train falls back on a *registration*: a follower knows where its leader stood
when the pair registered (:meth:`handshake`), the ground knows where each train was inserted (behind the truth:
conservative).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from itertools import repeat
from operator import attrgetter, itemgetter
from typing import Any

import numpy as np

from controllers.base import PredecessorState
from railsim.engine.coupling import FormationBook
from railsim.engine.events import Channel, DelaySpec, Message, Outage
from railsim.engine.events.clock import EventLayer
from railsim.engine.extensions.base import ExtensionSet
from railsim.engine.routeview import BodyFrame
from railsim.engine.train import TrainRuntime

Report = tuple[Any, ...]
# the occupancy's mapping of reported fronts (own frame) and send times into each follower's frame: (rear, age) per
# slot, NaN where it has none (railsim.engine.occupancy.Occupancy.reported_rears)
Placer = Callable[[float, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
ASK: tuple[float, float] = (math.nan, math.nan)  # Knowledge.ground_rears: no answer, ask known_rear_age (a NaN rear)
_NOTHING = Message("", "ground", (None, math.nan, 0.0, 0.0, math.nan, None), math.nan, math.nan, 0.0, -1, "t2g")
_PAYLOAD = attrgetter("payload")
_FRONT = itemgetter(1)  # a report's front chainage (Knowledge.report)
_SENT = itemgetter(4)  # and its time


def comm_channels(layer: EventLayer, scenario: Any) -> dict[str, Channel]:
    """The scenario's radio channels (``faults.comm``: ``t2t``, ``t2g``) with their delays, losses and outages."""
    channels = {}
    for name, spec in scenario.faults.comm.items():
        delay = DelaySpec.from_scenario(spec.delay, str(scenario.source), f"faults.comm.{name}.delay_s")
        outages = tuple(Outage(o.start_s, o.end_s, frozenset(o.trains) if o.trains else None) for o in spec.outages)
        channels[name] = Channel(layer, name, delay, float(spec.loss_prob), outages)
    return channels


class Knowledge:
    """Sends reports and answers "what does train A know of train B" from delivered messages."""

    def __init__(
        self, layer: EventLayer, channels: dict[str, Any], formations: FormationBook, extensions: ExtensionSet
    ) -> None:
        self.layer = layer
        self.channels = channels
        self.formations = formations
        # what a train knows of another before any message arrived: (receiver, sender) -> report
        self.registration: dict[tuple[str, str], Report] = {}
        self.extensions = extensions  # t2t_receivers: extra receivers of a train's report (Paper C's graph)
        # (observer, other) -> the frame change last used to map the other's reports (RouteView.map_body_memo)
        self._frames: dict[tuple[str, str], BodyFrame] = {}
        t2g = channels.get("t2g")
        self._ground: dict[str, Any] | None = t2g.mailbox("ground") if t2g is not None else None  # live, read-only

    def radio_out(self, t: float, train_id: str, other_id: str) -> bool:
        """Can the two trains' position reports be cut off at ``t`` (an outage of some channel covers either)? A
        train standing behind the last position it heard of the train ahead waits for the radio then."""
        return any(ch.out(train_id, t) or ch.out(other_id, t) for ch in self.channels.values())

    @staticmethod
    def report(t: float, tr: TrainRuntime) -> Report:
        """A position report: (route id, front chainage, speed, applied acceleration, time)."""
        return (tr.trip.route.id, tr.front_m, tr.plant.speed_mps, tr.plant.applied_accel_mps2, t)

    def communicate(self, active: list[TrainRuntime], reports: dict[str, Report]) -> None:
        """Send every train's report to the ground (t2g) and to its formation followers (t2t).

        A report is the state at ``t`` plus the plan its controller returned at the previous step
        (``Command.info["plan"]``: ``dt_s``, ``position_m``/``speed_mps``/``accel_mps2`` sequences and optionally
        ``t0_s``, the time entry 0 refers to) — the DMPC convention of broadcasting the last optimal plan.
        """
        t2g = self.channels.get("t2g")
        t2t = self.channels.get("t2t")
        senders = [tr.train_id for tr in active]
        payloads = [reports[sender] + (tr.last_plan,) for sender, tr in zip(senders, active)]
        by: list[int] = []  # per t2t message: the index of its sender in ``active``
        to: list[str] = []  # and its receiver
        if t2t is not None:
            of_leader = self.formations.of_leader
            follower_of = self.formations.follower_of
            receivers = self.extensions.t2t_receivers
            for k, sender in enumerate(senders):
                formations = of_leader.get(sender)
                if formations:  # leaders talk to their followers
                    for f in formations:
                        fol = follower_of(f)
                        if fol.status in ("inserting", "running"):
                            by.append(k)
                            to.append(fol.train_id)
                for other in receivers(sender):
                    by.append(k)
                    to.append(other)
        if not to:  # the ground's reports only: in one call
            if t2g is not None:
                t2g.send_all(senders, "ground", payloads)
            return
        # each channel draws its messages at once (its own stream, in the order sent); they go in flight in the
        # order sent: a train's ground report, then its reports to other trains, train after train
        assert t2t is not None
        ground = t2g.draw(senders, "ground", payloads) if t2g is not None else []
        radio = t2t.draw([senders[k] for k in by], to, [payloads[k] for k in by])
        if not t2t.watched and (t2g is None or not t2g.watched):
            # no one sees the deliveries of one channel between those of the other: each channel's messages go in
            # flight at once, still in the order sent on that channel, and every read of a mailbox (between
            # steps, or in an event before or after all of them) finds what the interleaved order gives
            if t2g is not None:
                t2g.post(ground)
            t2t.post(radio)
            return
        j = 0
        for k in range(len(active)):
            if t2g is not None:
                t2g.post(ground[k : k + 1])
            while j < len(radio) and by[j] == k:
                t2t.post(radio[j : j + 1])
                j += 1

    def handshake(self, tr: TrainRuntime) -> None:
        """Formation partners exchange a registration snapshot when both are on the line.

        Before the first radio message arrives, a follower knows where its leader was at this moment (it was
        placed behind it, or the pair registered together); without it a follower starting in motion would fall
        back to separation on ground data and brake for no reason.
        """
        now = self.layer.now_s
        pairs = []
        f = self.formations.of_follower.get(tr.train_id)
        if f is not None:
            pairs.append((tr, self.formations.leader_of(f)))
        for f2 in self.formations.of_leader.get(tr.train_id, ()):
            pairs.append((self.formations.follower_of(f2), tr))
        for follower, leader in pairs:
            if follower.on_line and leader.on_line:
                self.registration[(follower.train_id, leader.train_id)] = (
                    leader.trip.route.id,
                    leader.front_m,
                    leader.plant.speed_mps,
                    leader.plant.applied_accel_mps2,
                    now,
                )

    def known_state(
        self, observer: TrainRuntime, other: TrainRuntime, channel: str, receiver: str, ahead: bool = False
    ) -> PredecessorState | None:
        """What ``observer`` knows of ``other`` via ``channel`` (mapped into the observer's frame). ``ahead``:
        ``other`` is the train directly ahead on the observer's track (the occupancy says so) — a report that has
        it off our track then still gives a state (see :meth:`_known`) instead of None."""
        known = self._known(observer, other, channel, receiver, ahead)
        if known is None:
            return None
        front, rear, pos, v, acc, stamp, plan = known
        veh = other.trip.vehicle
        planned = _plan_in_frame(plan, front - pos, stamp) if plan else {}
        return PredecessorState(
            train_id=other.train_id,
            position_m=front,
            speed_mps=v,
            accel_mps2=acc,
            length_m=front - rear,
            stamp_s=stamp,
            age_s=max(0.0, self.layer.now_s - stamp),
            service_decel_mps2=veh.service_decel_mps2,
            emergency_decel_mps2=veh.emergency_decel_mps2,
            source=channel,
            **planned,
        )

    def known_rear_age(
        self, observer: TrainRuntime, other: TrainRuntime, channel: str, receiver: str, ahead: bool = False
    ) -> tuple[float, float] | None:
        """``(rear, age_s)`` of :meth:`known_state` without building it (``rear`` is its ``rear_position_m``,
        computed the same way): all that moving-block separation reads."""
        known = self._known(observer, other, channel, receiver, ahead)
        if known is None:
            return None
        front, rear = known[0], known[1]
        return front - (front - rear), max(0.0, self.layer.now_s - known[5])

    def ground_rears(self, t_s: float, ids: list[str], place: Placer) -> list[tuple[float, float]]:
        """What moving-block separation reads of the train directly ahead, for every train of the step (``ids``,
        in slot order) in one compiled pass: ``(rear, age_s)`` of :meth:`known_rear_age` with ``ahead`` (the same
        value), or a NaN rear (:data:`ASK`) where the caller asks :meth:`known_rear_age` itself (no train ahead, no
        report delivered yet, a report that has it off our track). ``place`` is the occupancy's
        :meth:`~railsim.engine.occupancy.Occupancy.reported_rears`: it maps the ground's latest report of each
        train (its front in its own frame, the time sent) into the frame of the train behind it."""
        box = self._ground
        n = len(ids)
        if box is None or n == 0:
            return [ASK] * n
        payloads = list(map(_PAYLOAD, map(box.get, ids, repeat(_NOTHING, n))))
        rear, age = place(
            t_s, np.fromiter(map(_FRONT, payloads), float, n), np.fromiter(map(_SENT, payloads), float, n)
        )
        return list(zip(rear.tolist(), age.tolist()))

    def _body_in_frame(self, observer: TrainRuntime, other: TrainRuntime, pos: float) -> tuple[float, float] | None:
        """``(front, rear)`` in the observer's frame of ``other``'s body reported with its front at ``pos`` (its own
        route's chainage): only the part on the observer's track; None if none of it is."""
        view = observer.view
        length_m = other.trip.vehicle.length_m
        if other.view is view and view.simple:  # one route, no edge twice: the report is in our frame (map_body's)
            return pos, pos - length_m
        # the pair's last frame change while the report stays on the same edges (the same value as map_body)
        return view.map_body_memo(
            self._frames, (observer.train_id, other.train_id), other.view, pos, length_m, other.edge_i, observer.edge_i
        )

    def _known(
        self, observer: TrainRuntime, other: TrainRuntime, channel: str, receiver: str, ahead: bool = False
    ) -> tuple[float, float, float, float, float, float, Any] | None:
        """The latest delivered report (or the registration) of ``other``: ``(front, rear)`` in the observer's
        frame, then the report's own position, speed, acceleration, stamp and plan; None if off our route —
        unless ``other`` is ahead of us on our track now (``ahead``): then where its route joins ours."""
        ch = self.channels.get(channel)
        msg = ch.latest(receiver, other.train_id) if ch is not None else None
        if msg is None:
            # no message yet: a registration report — a follower placed behind its leader knows where the leader
            # stood; the ground knows where each train came on the line (inserted, or handed over to its unit's
            # next trip: ``start_front_m``; stale and behind the truth: conservative)
            reg = self.registration.get((observer.train_id, other.train_id))
            route_id, pos, v, acc, stamp = (
                reg
                if reg is not None
                else (
                    other.trip.route.id,
                    other.start_front_m,
                    other.trip.start_speed_mps,
                    0.0,
                    other.inserted_s or 0.0,
                )
            )
            plan = None
        else:
            route_id, pos, v, acc, stamp, plan = msg.payload
        mapped = self._body_in_frame(observer, other, pos)
        if mapped is None:
            if not ahead:
                return None
            # the report has it on track our route does not use — short of a merge, or short of where our route
            # begins — yet it is ahead of us now: it came onto our track since, where its route joins ours, and
            # no part of it on our track is behind that point. Known: a train standing there (its speed on our
            # track unknown); without this the train behind ran with no separation at all (two fuzz-found
            # collisions in radio outages: tests/sumo/test_knowledge_off_route.py)
            join_m = other.view.join_m(observer.view, pos)
            if join_m is None:
                return None
            return join_m, join_m, pos, 0.0, 0.0, stamp, None
        return mapped[0], mapped[1], pos, v, acc, stamp, plan  # only the part of its body on our track


def _plan_in_frame(plan: dict[str, Any], shift_m: float, stamp_s: float) -> dict[str, Any]:
    """The sender's last plan, moved into our frame and aligned so that entry 0 is at ``stamp_s``."""
    dt_plan = float(plan.get("dt_s", 0.0))
    drop = 0
    if "t0_s" in plan and dt_plan > 0.0:  # entry 0 refers to t0_s: skip entries before the stamp
        drop = max(0, int(round((stamp_s - float(plan["t0_s"])) / dt_plan)))
    return {
        "planned_position_m": tuple(float(x) + shift_m for x in plan.get("position_m", ())[drop:]),
        "planned_speed_mps": tuple(float(x) for x in plan.get("speed_mps", ())[drop:]),
        "planned_accel_mps2": tuple(float(x) for x in plan.get("accel_mps2", ())[drop:]),
        "plan_dt_s": dt_plan,
    }
