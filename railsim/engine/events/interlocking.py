"""Switch interlocking: who may pass a switch, on which leg, and when the switch may move.

Where trains run virtually coupled SUMO's rail signals are off (docs/architecture.md), so route protection is ours.
Each switch is a small resource served by one simpy process. A train (or a coupled formation) asks for the
switch on one leg — ``normal`` or ``reverse`` — and may pass the protection point only once the request is
**granted**; a train that is not granted brakes to stop before the switch.

What happens in time
--------------------
Requests queue **first in, first out** per switch (ties at the same instant in call order); the head of
the queue is served first even if a later request wants the leg the switch already lies in. Strict FIFO
is what guarantees that no request waits forever while the holders keep releasing.

The switch's process loops:

1. wait until the queue is non-empty;
2. if the head wants the other leg, **throw**: log ``throw_start``, wait exactly ``throw_time_s``
   (monorail beam switches take 10–30 s), set the new position, log ``throw_end``. A throw only ever starts
   while no lock is held, and no lock is granted until it has ended;
3. grant the head (log ``lock_granted``) and wait for the lock to be released (log ``lock_released``).

So a request that changes the leg waits exactly ``throw_time_s`` beyond the moment the switch became free
(or the moment it arrived, if later): ``granted = max(requested, previous release) + throw_time_s``.

Invariant: a switch never has two lock holders at once and never changes position while locked. The code
checks it at every grant and every position change and raises ``RuntimeError`` if it is ever violated (that
would be a bug here, not a user mistake).

Group locks and release — the safe reading
------------------------------------------
A coupled formation may hold ONE lock for all its members: ``holder_ids`` lists them. The lock protects
the route until the **last** member's tail has cleared the switch, so :meth:`Interlocking.release` by one
member only marks that member as through; the lock is freed when every member has released. (Freeing it at
the first member's release would let the switch move under the followers.) After a member has released,
:meth:`Interlocking.is_locked_for` is False for that member.

A cancelled request leaves the queue. If it was the head while the switch was throwing, the throw still
completes (a moving beam is not stopped half way) and the next request is served from the new position.
Cancelling a granted request frees the whole lock at once (an operator's override, e.g. a train withdrawn).

A grant is an event: a request made at ``now`` on a free switch is granted at ``now``, visible after the
next ``layer.advance_to`` (``advance_to(now)`` suffices). Inside a process, ``yield request.granted``.

Multi-switch routes are not locked atomically here; a route-level manager must request switches in a
fixed global order to stay deadlock-free.

Log kinds (subject = switch id): ``lock_requested``, ``throw_start``, ``throw_end``, ``lock_granted``,
``member_released``, ``lock_released``, ``request_cancelled``, ``release_ignored``.
"""

from __future__ import annotations

import enum
import math
from collections import deque
from collections.abc import Generator
from dataclasses import dataclass, field
from typing import Literal

import simpy

from railsim.engine.events.clock import EventLayer
from railsim.errors import ConfigError

Leg = Literal["normal", "reverse"]
LEGS: tuple[str, ...] = ("normal", "reverse")


@dataclass(frozen=True)
class Switch:
    """Parameters of one switch: id, throw time (s) and initial position (leg)."""

    id: str
    throw_time_s: float = 15.0
    position: Leg = "normal"

    def __post_init__(self) -> None:
        t = self.throw_time_s
        if not (isinstance(t, (int, float)) and math.isfinite(t) and t >= 0.0):
            raise ConfigError(None, f"switches.{self.id}.throw_time_s", f"expected a finite number >= 0, got {t!r}")
        if self.position not in LEGS:
            raise ConfigError(
                None, f"switches.{self.id}.position", f"expected 'normal' or 'reverse', got {self.position!r}"
            )


class RequestState(enum.StrEnum):
    """Life of a lock request."""

    SCHEDULED = "scheduled"  # made for a future time, not yet queued
    WAITING = "waiting"
    GRANTED = "granted"
    RELEASED = "released"
    CANCELLED = "cancelled"


@dataclass(eq=False)
class LockRequest:
    """One request for a switch on one leg by one train or one formation (``holder_ids``).

    ``granted`` is a simpy event that succeeds when the lock is granted (never, if cancelled first).
    Times are exact simulated seconds; ``None`` until they happen.
    """

    seq: int
    holder_ids: tuple[str, ...]
    switch_id: str
    leg: Leg
    requested_s: float
    granted: simpy.Event
    state: RequestState = RequestState.SCHEDULED
    granted_s: float | None = None
    released_s: float | None = None
    released_by: set[str] = field(default_factory=set)
    _done: simpy.Event | None = None  # succeeded when the lock is freed


@dataclass(eq=False)
class _SwitchRuntime:
    spec: Switch
    position: str
    queue: deque[LockRequest] = field(default_factory=deque)
    holder: LockRequest | None = None
    throwing: bool = False
    wakeup: simpy.Event | None = None
    throws: int = 0


class Interlocking:
    """All switches of a simulation, each served by its own simpy process."""

    def __init__(self, layer: EventLayer) -> None:
        self._layer = layer
        self._switches: dict[str, _SwitchRuntime] = {}
        self._seq = 0
        self.versions: dict[str, int] = {}  # train id -> changes to the locks it is one of the holders of (version)

    def add_switch(self, switch: Switch) -> None:
        """Register a switch (unlocked, in ``switch.position``) and start its process."""
        if switch.id in self._switches:
            raise ValueError(f"switch {switch.id!r} already exists")
        sw = _SwitchRuntime(switch, switch.position)
        self._switches[switch.id] = sw
        self._layer.env.process(self._serve(sw))

    # ------------------------------------------------------------------ commands
    def request(self, holder_ids: tuple[str, ...], switch_id: str, leg: Leg, t_s: float | None = None) -> LockRequest:
        """Queue a request by ``holder_ids`` for ``switch_id`` on ``leg`` now, or at exactly ``t_s``.

        A train may have at most one waiting or held request per switch (ValueError otherwise: a second
        one would queue behind the first and wait for itself).
        """
        sw = self._get(switch_id)
        if isinstance(holder_ids, str):
            holder_ids = (holder_ids,)
        holder_ids = tuple(holder_ids)
        if not holder_ids or len(set(holder_ids)) != len(holder_ids):
            raise ValueError(f"holder_ids must be non-empty and distinct, got {holder_ids!r}")
        if leg not in LEGS:
            raise ValueError(f"leg must be 'normal' or 'reverse', got {leg!r}")
        now = self._layer.now_s
        t = now if t_s is None else float(t_s)
        if not math.isfinite(t) or t < now:
            raise ValueError(f"cannot request switch {switch_id} at {t!r} s (now {now} s)")
        for train in holder_ids:
            active = self._active_request_of(sw, train)
            if active is not None:
                raise ValueError(
                    f"train {train!r} already has request #{active.seq} ({active.state}) on switch {switch_id!r}"
                )
        self._seq += 1
        req = LockRequest(self._seq, holder_ids, switch_id, leg, t, self._layer.env.event())
        req._done = self._layer.env.event()
        if t == now:
            self._enqueue(sw, req)
        else:
            self._layer.env.process(self._enqueue_later(sw, req))
        return req

    def _enqueue_later(self, sw: _SwitchRuntime, req: LockRequest) -> Generator[simpy.Event, None, None]:
        yield self._layer.timeout_at(req.requested_s)
        if req.state is RequestState.SCHEDULED:
            self._enqueue(sw, req)

    def _enqueue(self, sw: _SwitchRuntime, req: LockRequest) -> None:
        req.state = RequestState.WAITING
        sw.queue.append(req)
        self._layer.log.record(
            req.requested_s, "lock_requested", sw.spec.id, request=req.seq, holders=list(req.holder_ids), leg=req.leg
        )
        self._wake(sw)

    def release(self, holder_id: str, switch_id: str) -> bool:
        """Member ``holder_id`` has cleared ``switch_id``. Returns True if this freed the lock.

        The lock is freed when every member of the holding group has released (see the module docstring).
        A release by a train that holds no lock here, or releases twice, is logged and ignored (False).
        """
        sw = self._get(switch_id)
        req = sw.holder
        t = self._layer.now_s
        if req is None or holder_id not in req.holder_ids or holder_id in req.released_by:
            self._layer.log.record(t, "release_ignored", switch_id, train=holder_id)
            return False
        req.released_by.add(holder_id)
        self._changed(req)
        if len(req.released_by) < len(req.holder_ids):
            self._layer.log.record(t, "member_released", switch_id, request=req.seq, train=holder_id)
            return False
        self._free(sw, req, t, reason="released")
        return True

    def cancel(self, request: LockRequest) -> None:
        """Withdraw ``request``: leave the queue, or free the lock at once if it was granted."""
        sw = self._get(request.switch_id)
        t = self._layer.now_s
        if request.state in (RequestState.SCHEDULED, RequestState.WAITING):
            if request.state is RequestState.WAITING:
                sw.queue.remove(request)
            request.state = RequestState.CANCELLED
            self._changed(request)
            self._layer.log.record(t, "request_cancelled", sw.spec.id, request=request.seq)
            # The head may have changed: let the process look again (it is idle or mid-throw).
            self._wake(sw)
        elif request.state is RequestState.GRANTED:
            self._free(sw, request, t, reason="cancelled")
        # Released or already cancelled: nothing to do.

    def _free(self, sw: _SwitchRuntime, req: LockRequest, t_s: float, reason: str) -> None:
        if sw.holder is not req:
            raise RuntimeError(f"switch {sw.spec.id}: freeing request #{req.seq} that does not hold the lock")
        sw.holder = None
        self._changed(req)
        req.state = RequestState.RELEASED if reason == "released" else RequestState.CANCELLED
        req.released_s = t_s
        self._layer.log.record(
            t_s,
            "lock_released",
            sw.spec.id,
            request=req.seq,
            reason=reason,
            held_s=t_s - (req.granted_s if req.granted_s is not None else t_s),
        )
        assert req._done is not None
        req._done.succeed()

    def _changed(self, req: LockRequest) -> None:
        """A lock or request of ``req``'s holders changed (:meth:`version`)."""
        versions = self.versions
        for h in req.holder_ids:
            versions[h] = versions.get(h, 0) + 1

    def _wake(self, sw: _SwitchRuntime) -> None:
        if sw.wakeup is not None and not sw.wakeup.triggered:
            sw.wakeup.succeed()

    # ------------------------------------------------------------------ the switch's process
    def _serve(self, sw: _SwitchRuntime) -> Generator[simpy.Event, None, None]:
        env = self._layer.env
        while True:
            while not sw.queue:
                sw.wakeup = env.event()
                yield sw.wakeup
            sw.wakeup = None
            head = sw.queue[0]
            if head.leg != sw.position:
                yield from self._throw(sw, head.leg)
                continue  # the head may have been cancelled during the throw
            sw.queue.popleft()
            self._grant(sw, head)
            assert head._done is not None
            yield head._done

    def _throw(self, sw: _SwitchRuntime, leg: str) -> Generator[simpy.Event, None, None]:
        if sw.holder is not None:
            raise RuntimeError(f"switch {sw.spec.id}: throw while locked by request #{sw.holder.seq}")
        start_s = self._layer.now_s
        sw.throwing = True
        self._layer.log.record(start_s, "throw_start", sw.spec.id, from_leg=sw.position, to_leg=leg)
        # A throw lasts exactly throw_time_s from its start: the promise behind "a change of leg costs
        # throw_time_s", so a plain relative timeout, not timeout_at.
        yield self._layer.env.timeout(sw.spec.throw_time_s)
        self._set_position(sw, leg)
        sw.throwing = False
        sw.throws += 1
        self._layer.log.record(self._layer.now_s, "throw_end", sw.spec.id, leg=leg, throw_s=self._layer.now_s - start_s)

    def _set_position(self, sw: _SwitchRuntime, leg: str) -> None:
        if sw.holder is not None:
            raise RuntimeError(f"switch {sw.spec.id}: position change while locked by request #{sw.holder.seq}")
        sw.position = leg

    def _grant(self, sw: _SwitchRuntime, req: LockRequest) -> None:
        if sw.holder is not None:
            raise RuntimeError(f"switch {sw.spec.id}: granting #{req.seq} while #{sw.holder.seq} holds the lock")
        if sw.throwing or sw.position != req.leg:
            raise RuntimeError(
                f"switch {sw.spec.id}: granting #{req.seq} for {req.leg} but switch is "
                f"{'throwing' if sw.throwing else sw.position}"
            )
        sw.holder = req
        self._changed(req)
        req.state = RequestState.GRANTED
        req.granted_s = self._layer.now_s
        self._layer.log.record(
            req.granted_s,
            "lock_granted",
            sw.spec.id,
            request=req.seq,
            holders=list(req.holder_ids),
            leg=req.leg,
            waited_s=req.granted_s - req.requested_s,
        )
        req.granted.succeed(req)

    # ------------------------------------------------------------------ queries
    def _get(self, switch_id: str) -> _SwitchRuntime:
        try:
            return self._switches[switch_id]
        except KeyError:
            raise KeyError(f"unknown switch {switch_id!r}") from None

    def _active_request_of(self, sw: _SwitchRuntime, train_id: str) -> LockRequest | None:
        if sw.holder is not None and train_id in sw.holder.holder_ids and train_id not in sw.holder.released_by:
            return sw.holder
        for req in sw.queue:
            if train_id in req.holder_ids:
                return req
        return None

    def is_granted(self, request: LockRequest) -> bool:
        """True while ``request`` holds its lock (granted and not yet freed)."""
        return request.state is RequestState.GRANTED

    def holder(self, switch_id: str) -> tuple[str, ...] | None:
        """The ``holder_ids`` of the request holding ``switch_id``'s lock (whole group), or None."""
        req = self._get(switch_id).holder
        return None if req is None else req.holder_ids

    def lock(self, switch_id: str) -> LockRequest | None:
        """The request holding ``switch_id``'s lock, or None."""
        return self._get(switch_id).holder

    def position(self, switch_id: str) -> str:
        """Current leg of ``switch_id`` (during a throw: the leg it is leaving)."""
        return self._get(switch_id).position

    def is_throwing(self, switch_id: str) -> bool:
        """True while ``switch_id`` is moving."""
        return self._get(switch_id).throwing

    def queue(self, switch_id: str) -> tuple[LockRequest, ...]:
        """Waiting requests of ``switch_id`` in FIFO order."""
        return tuple(self._get(switch_id).queue)

    def is_locked_for(self, train_id: str, switch_id: str, leg: str) -> bool:
        """True if ``train_id`` may pass ``switch_id`` on ``leg`` now: its group holds the lock on that leg
        and it has not released its part yet."""
        sw = self._get(switch_id)
        req = sw.holder
        return (
            req is not None
            and req.leg == leg
            and sw.position == leg
            and train_id in req.holder_ids
            and train_id not in req.released_by
        )

    def version(self, train_id: str) -> int:
        """A count that moves on whenever :meth:`is_locked_for` may have changed for ``train_id`` on some switch
        (a lock it is one of the holders of granted, released by a member, or freed; a request of it cancelled):
        while it stays the same, so does every answer of :meth:`is_locked_for` for the train."""
        return self.versions.get(train_id, 0)

    def throw_count(self, switch_id: str) -> int:
        """Completed throws of ``switch_id``."""
        return self._get(switch_id).throws
