"""Virtual-coupling formations: a leader, a follower, and the state machine between them.

A formation is two trains that may run virtually coupled — the follower keeps a short target gap behind
the leader by radio instead of by a drawbar. Commands to couple or decouple come from the timetable, the
junction planner or the scenario; they change what the follower's controller aims at (docs/architecture.md). The
states follow the follower state table of spec 003 §3.1 (Hou et al., PLOS ONE 2026, Fig 4), without its
emergency/standstill states, which belong to the controllers:

::

    free ──couple──► coupling ──in band for hold_s──► coupled ──decouple──► decoupling ──gap ≥ separation──► free
                        │  └──decouple (abort)──────────────────────────────►┘
                        └──no lock-in within coupling_timeout_s──► failed ──► free

What happens in time
--------------------
1. ``request_couple(fid)`` (now, or at an exact later time through simpy) moves a free formation to
   ``coupling`` and starts a timeout of ``coupling_timeout_s``.
2. Every step the engine calls ``observe(t, fid, gap_m, speed_diff_mps)`` with the **ground-truth**
   front-to-rear gap (leader rear to follower front) and the follower-minus-leader speed. The formation is
   *in band* when ``|gap − target_gap_m| ≤ gap_tolerance_m`` and ``|dv| ≤ speed_tolerance_mps``.
   Observations are read as sample-and-hold: the measurement at ``t_k`` stands until the next one. When an
   observation enters the band at ``t_in`` a hold timer is set for ``t_in + hold_s``; an out-of-band
   observation before then cancels it. If it survives, the formation becomes ``coupled`` at exactly
   ``t_in + hold_s`` (logged with the exact time-to-couple, measured from the request), even between steps.
3. If the timeout fires first the attempt ``failed`` (logged with the reason and the last observation) and
   the formation is ``free`` again. A hold that ends exactly at the deadline counts as a success.
4. ``request_decouple`` moves a coupled (or still coupling — an abort) formation to ``decoupling``; it is
   ``free`` at the first observation with ``gap ≥ separation_gap_m``.

A coupled formation stays coupled until a decouple command: keeping the gap is the controller's job, and
judging how well it did (gap error, near-misses) is the recorder's. Observations of a free or coupled
formation only update the "last observation" kept for the failure log.

Ground truth decides the *state* (this is the referee's view: did the pair actually lock in?); what the
follower's controller *knows* still comes through the comm channels.

Invalid commands — couple a formation that is not free, decouple one that is free or already decoupling —
arrive from timetables and planners at run time; they are logged as ``invalid_request`` and ignored, not
raised. Unknown formation ids are a programming error and raise ``KeyError``.

Target gap reading: :meth:`FormationManager.target_gap_m` gives the follower the coupled target while the
formation is ``coupling`` or ``coupled`` and ``None`` when it is ``free`` or ``decoupling`` (the follower
then runs on its own — plain headway/braking-distance protection — and opens the gap).

Log kinds (subject = formation id): ``couple_requested``, ``coupled``, ``coupling_failed``,
``coupling_aborted``, ``decouple_requested``, ``decoupled``, ``invalid_request``.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Generator
from dataclasses import dataclass, field

import simpy

from railsim.engine.events.clock import EventLayer
from railsim.errors import ConfigError


class FormationState(enum.StrEnum):
    """States of a formation (compare with plain strings: ``state == "coupled"`` works)."""

    FREE = "free"
    COUPLING = "coupling"
    COUPLED = "coupled"
    DECOUPLING = "decoupling"


@dataclass(frozen=True)
class Formation:
    """Parameters of one leader–follower pair.

    Attributes:
        id: formation id (log subject).
        leader_id, follower_id: train ids.
        target_gap_m: front-to-rear gap the follower holds when coupled.
        separation_gap_m: gap at which a decoupling formation counts as apart (> target).
        gap_tolerance_m: band half-width on the gap for "locked in".
        speed_tolerance_mps: band half-width on the follower − leader speed.
        hold_s: how long the pair must stay in band to count as coupled.
        coupling_timeout_s: give up a coupling attempt this long after the request.
    """

    id: str
    leader_id: str
    follower_id: str
    target_gap_m: float
    separation_gap_m: float
    gap_tolerance_m: float = 2.0
    speed_tolerance_mps: float = 0.3
    hold_s: float = 5.0
    coupling_timeout_s: float = 300.0

    def __post_init__(self) -> None:
        where = f"formations.{self.id}"
        if self.leader_id == self.follower_id:
            raise ConfigError(None, f"{where}.follower_id", f"a train cannot follow itself ({self.leader_id!r})")

        def positive(name: str, allow_zero: bool = False) -> None:
            value = getattr(self, name)
            ok = (
                isinstance(value, (int, float))
                and math.isfinite(value)
                and (value >= 0.0 if allow_zero else value > 0.0)
            )
            if not ok:
                bound = ">= 0" if allow_zero else "> 0"
                raise ConfigError(None, f"{where}.{name}", f"expected a finite number {bound}, got {value!r}")

        for name in (
            "target_gap_m",
            "separation_gap_m",
            "gap_tolerance_m",
            "speed_tolerance_mps",
            "coupling_timeout_s",
        ):
            positive(name)
        positive("hold_s", allow_zero=True)
        if self.separation_gap_m <= self.target_gap_m + self.gap_tolerance_m:
            raise ConfigError(
                None,
                f"{where}.separation_gap_m",
                f"expected more than target_gap_m + gap_tolerance_m = "
                f"{self.target_gap_m + self.gap_tolerance_m} m, got {self.separation_gap_m}",
            )


@dataclass(frozen=True)
class FormationStats:
    """Counters of one formation (a snapshot).

    ``couple_requests``/``decouple_requests`` count every command received, ``invalid_requests`` those of
    them that were ignored; ``successes + failures + aborts`` are the outcomes of coupling attempts;
    ``time_to_couple_s`` holds one entry per success (request to lock-in); ``coupled_time_s`` includes an
    ongoing coupled interval up to now.
    """

    couple_requests: int
    decouple_requests: int
    invalid_requests: int
    successes: int
    failures: int
    aborts: int
    time_to_couple_s: tuple[float, ...]
    coupled_time_s: float


@dataclass(eq=False)
class _Runtime:
    """Mutable state of one formation (private: callers see states and stats)."""

    spec: Formation
    state: FormationState = FormationState.FREE
    attempt: int = 0  # increments per coupling attempt; stale timers compare against it
    requested_s: float = math.nan
    in_band_since_s: float | None = None
    streak: int = 0  # increments whenever a band streak starts or breaks
    last_obs_s: float = -math.inf
    last_gap_m: float | None = None
    last_dv_mps: float | None = None
    coupled_since_s: float | None = None
    couple_requests: int = 0
    decouple_requests: int = 0
    invalid_requests: int = 0
    successes: int = 0
    failures: int = 0
    aborts: int = 0
    time_to_couple_s: list[float] = field(default_factory=list)
    coupled_time_s: float = 0.0


class FormationManager:
    """All formations of a simulation and the simpy timers that drive their state machines."""

    def __init__(self, layer: EventLayer) -> None:
        self._layer = layer
        self._formations: dict[str, _Runtime] = {}
        self._follower_of: dict[str, str] = {}  # train id -> formation id where it follows
        self._leader_of: dict[str, list[str]] = {}  # train id -> formation ids where it leads

    # ------------------------------------------------------------------ set-up
    def add(self, formation: Formation) -> None:
        """Register a formation (free). A train may follow in at most one formation (ValueError)."""
        if formation.id in self._formations:
            raise ValueError(f"formation {formation.id!r} already exists")
        other = self._follower_of.get(formation.follower_id)
        if other is not None:
            raise ValueError(
                f"train {formation.follower_id!r} already follows in formation {other!r}; "
                f"it cannot also follow in {formation.id!r}"
            )
        self._formations[formation.id] = _Runtime(formation)
        self._follower_of[formation.follower_id] = formation.id
        self._leader_of.setdefault(formation.leader_id, []).append(formation.id)

    def record(self, t_s: float, kind: str, fid: str, **detail: object) -> None:
        """Log an event about formation ``fid`` (the engine's formation book reports through here)."""
        self._layer.log.record(t_s, kind, fid, **detail)

    # ------------------------------------------------------------------ commands
    def request_couple(self, fid: str, at_s: float | None = None) -> None:
        """Ask formation ``fid`` to couple now, or at exactly ``at_s`` (a simpy timer)."""
        self._get(fid)
        if at_s is None:
            self._on_couple(fid, self._layer.now_s)
        else:
            self._layer.env.process(self._later(self._check_time(at_s, fid), self._on_couple, fid))

    def request_decouple(self, fid: str, at_s: float | None = None) -> None:
        """Ask formation ``fid`` to decouple now, or at exactly ``at_s``."""
        self._get(fid)
        if at_s is None:
            self._on_decouple(fid, self._layer.now_s)
        else:
            self._layer.env.process(self._later(self._check_time(at_s, fid), self._on_decouple, fid))

    def _check_time(self, at_s: float, fid: str) -> float:
        at_s = float(at_s)
        if not math.isfinite(at_s) or at_s < self._layer.now_s:
            raise ValueError(f"formation {fid}: cannot schedule a command at {at_s!r} s (now {self._layer.now_s} s)")
        return at_s

    def _later(self, t_s: float, action, fid: str) -> Generator[simpy.Event, None, None]:
        yield self._layer.timeout_at(t_s)
        action(fid, t_s)

    def _on_couple(self, fid: str, t_s: float) -> None:
        rt = self._formations[fid]
        rt.couple_requests += 1
        if rt.state is not FormationState.FREE:
            self._invalid(rt, t_s, "couple")
            return
        rt.state = FormationState.COUPLING
        rt.attempt += 1
        rt.requested_s = t_s
        rt.in_band_since_s = None
        rt.streak += 1
        self._layer.log.record(
            t_s, "couple_requested", fid, attempt=rt.attempt, deadline_s=t_s + rt.spec.coupling_timeout_s
        )
        self._layer.env.process(self._coupling_deadline(rt, rt.attempt, t_s + rt.spec.coupling_timeout_s))

    def _on_decouple(self, fid: str, t_s: float) -> None:
        rt = self._formations[fid]
        rt.decouple_requests += 1
        if rt.state is FormationState.COUPLED:
            self._leave_coupled(rt, t_s)
        elif rt.state is FormationState.COUPLING:
            rt.aborts += 1
            rt.in_band_since_s = None
            rt.streak += 1
            self._layer.log.record(t_s, "coupling_aborted", fid, attempt=rt.attempt)
        else:
            self._invalid(rt, t_s, "decouple")
            return
        rt.state = FormationState.DECOUPLING
        self._layer.log.record(t_s, "decouple_requested", fid)

    def _invalid(self, rt: _Runtime, t_s: float, request: str) -> None:
        rt.invalid_requests += 1
        self._layer.log.record(t_s, "invalid_request", rt.spec.id, request=request, state=str(rt.state))

    # ------------------------------------------------------------------ measurements
    def observe(self, t_s: float, fid: str, gap_m: float, speed_diff_mps: float) -> None:
        """Ground-truth gap (front-to-rear, m) and follower − leader speed (m/s) of ``fid`` at ``t_s``.

        Call after ``layer.advance_to(t_s)`` so that a hold timer starts at exactly ``t_s``.
        """
        rt = self._get(fid)
        t_s = float(t_s)
        if not (math.isfinite(t_s) and math.isfinite(gap_m) and math.isfinite(speed_diff_mps)):
            raise ValueError(f"formation {fid}: non-finite observation t={t_s} gap={gap_m} dv={speed_diff_mps}")
        if t_s < rt.last_obs_s:
            raise ValueError(f"formation {fid}: observation at {t_s} s is older than the last ({rt.last_obs_s} s)")
        rt.last_obs_s, rt.last_gap_m, rt.last_dv_mps = t_s, float(gap_m), float(speed_diff_mps)
        spec = rt.spec
        if rt.state is FormationState.COUPLING:
            in_band = (
                abs(gap_m - spec.target_gap_m) <= spec.gap_tolerance_m
                and abs(speed_diff_mps) <= spec.speed_tolerance_mps
            )
            if in_band and rt.in_band_since_s is None:
                rt.in_band_since_s = t_s
                rt.streak += 1
                # Never schedule into the past if the caller observes a time the layer has passed.
                lock_in_s = max(t_s + spec.hold_s, self._layer.now_s)
                self._layer.env.process(self._hold_timer(rt, rt.attempt, rt.streak, lock_in_s))
            elif not in_band and rt.in_band_since_s is not None:
                rt.in_band_since_s = None
                rt.streak += 1
        elif rt.state is FormationState.DECOUPLING and gap_m >= spec.separation_gap_m:
            rt.state = FormationState.FREE
            self._layer.log.record(t_s, "decoupled", fid, gap_m=float(gap_m))

    # ------------------------------------------------------------------ simpy processes
    def _hold_timer(self, rt: _Runtime, attempt: int, streak: int, t_s: float) -> Generator[simpy.Event, None, None]:
        yield self._layer.timeout_at(t_s)
        if rt.state is FormationState.COUPLING and rt.attempt == attempt and rt.streak == streak:
            self._enter_coupled(rt, t_s)

    def _coupling_deadline(self, rt: _Runtime, attempt: int, t_s: float) -> Generator[simpy.Event, None, None]:
        yield self._layer.timeout_at(t_s)
        if rt.state is not FormationState.COUPLING or rt.attempt != attempt:
            return
        if rt.in_band_since_s is not None and rt.in_band_since_s + rt.spec.hold_s <= t_s:
            # The hold timer is due at this same instant but sits later in the queue: success wins the tie.
            self._enter_coupled(rt, t_s)
            return
        if rt.last_obs_s < t_s:
            # The engine observes *after* advancing to an instant, so an observation at exactly the deadline
            # has not been made yet. Decide one ulp later: an in-band observation at the deadline with
            # hold_s = 0 then still counts (its hold timer runs at the deadline, before this re-check).
            yield self._layer.timeout_at(math.nextafter(t_s, math.inf))
            if rt.state is not FormationState.COUPLING or rt.attempt != attempt:
                return
            if rt.in_band_since_s is not None and rt.in_band_since_s + rt.spec.hold_s <= t_s:
                self._enter_coupled(rt, t_s)
                return
        rt.failures += 1
        rt.state = FormationState.FREE
        rt.in_band_since_s = None
        rt.streak += 1
        self._layer.log.record(
            t_s,
            "coupling_failed",
            rt.spec.id,
            attempt=attempt,
            reason="timeout",
            timeout_s=rt.spec.coupling_timeout_s,
            last_gap_m=rt.last_gap_m,
            last_speed_diff_mps=rt.last_dv_mps,
        )

    def _enter_coupled(self, rt: _Runtime, t_s: float) -> None:
        rt.state = FormationState.COUPLED
        rt.successes += 1
        ttc = t_s - rt.requested_s
        rt.time_to_couple_s.append(ttc)
        rt.coupled_since_s = t_s
        self._layer.log.record(t_s, "coupled", rt.spec.id, attempt=rt.attempt, time_to_couple_s=ttc)

    def _leave_coupled(self, rt: _Runtime, t_s: float) -> None:
        if rt.coupled_since_s is None:  # the clock was already stopped (a unit arrived): nothing to add
            return
        rt.coupled_time_s += t_s - rt.coupled_since_s
        rt.coupled_since_s = None

    def stop_clock(self, t_s: float, fid: str) -> None:
        """A unit of ``fid`` arrived or left the line: coupled time stops counting (the state is kept)."""
        self._leave_coupled(self._get(fid), t_s)

    def observe_apart(self, t_s: float, fid: str) -> None:
        """The units are on different tracks (no gap to measure): a decoupling formation is now free."""
        rt = self._get(fid)
        if rt.state is FormationState.DECOUPLING:
            rt.state = FormationState.FREE
            self._layer.log.record(t_s, "decoupled", fid, gap_m=None, apart=True)

    # ------------------------------------------------------------------ queries
    def _get(self, fid: str) -> _Runtime:
        try:
            return self._formations[fid]
        except KeyError:
            raise KeyError(f"unknown formation {fid!r}") from None

    def formation(self, fid: str) -> Formation:
        """The parameters of ``fid``."""
        return self._get(fid).spec

    def ids(self) -> tuple[str, ...]:
        """Formation ids in the order they were added."""
        return tuple(self._formations)

    def state(self, fid: str) -> FormationState:
        """Current state of ``fid``."""
        return self._get(fid).state

    def role_of(self, train_id: str) -> tuple[str, str, FormationState] | None:
        """``(formation id, 'leader'|'follower', state)`` of ``train_id``, or None if in no formation.

        A train in a chain (follower of the train ahead, leader of the one behind) is reported in its
        **follower** role: that is the role that sets its own controller's target. :meth:`roles_of` lists all.
        """
        roles = self.roles_of(train_id)
        return roles[0] if roles else None

    def roles_of(self, train_id: str) -> list[tuple[str, str, FormationState]]:
        """Every role of ``train_id``: its follower role first, then leader roles in order added."""
        out: list[tuple[str, str, FormationState]] = []
        fid = self._follower_of.get(train_id)
        if fid is not None:
            out.append((fid, "follower", self._formations[fid].state))
        for fid in self._leader_of.get(train_id, ()):
            out.append((fid, "leader", self._formations[fid].state))
        return out

    def target_gap_m(self, train_id: str) -> float | None:
        """Target gap for ``train_id`` as a follower while coupling/coupled; None otherwise."""
        fid = self._follower_of.get(train_id)
        if fid is None:
            return None
        rt = self._formations[fid]
        if rt.state in (FormationState.COUPLING, FormationState.COUPLED):
            return rt.spec.target_gap_m
        return None

    def stats(self, fid: str) -> FormationStats:
        """Counters of ``fid``; ``coupled_time_s`` counts an ongoing coupled interval up to now."""
        rt = self._get(fid)
        coupled = rt.coupled_time_s
        if rt.coupled_since_s is not None:
            coupled += self._layer.now_s - rt.coupled_since_s
        return FormationStats(
            couple_requests=rt.couple_requests,
            decouple_requests=rt.decouple_requests,
            invalid_requests=rt.invalid_requests,
            successes=rt.successes,
            failures=rt.failures,
            aborts=rt.aborts,
            time_to_couple_s=tuple(rt.time_to_couple_s),
            coupled_time_s=coupled,
        )

    def all_stats(self) -> dict[str, FormationStats]:
        """:meth:`stats` of every formation, in the order added."""
        return {fid: self.stats(fid) for fid in self._formations}
