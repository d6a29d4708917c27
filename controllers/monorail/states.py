"""Follower state machine of the virtual-coupling process (Paper D Fig 4, spec §3.1 and §3.2.4).

The paper's Fig 4 numbering was lost; the states are the spec's reading:

``independent`` → (couple command) → ``coupling`` → (|g − d_c| < ε_g and |Δv| < ε_v held ``hold_s``) →
``coupled`` → (decouple command | passive | active) → ``decoupling`` → ``independent``; ``separating`` is the
"unanticipated disassembly" before a switch (ends at ``separation_gap_m``); ``ca_active`` pre-empts every state;
``stopped`` is standstill outside a formation (and the end of a latched CA brake).

In-operation decoupling (§3.2.4):

* **passive** (excessive spacing): ``g > d_max`` while the gap opens (``v_f < v_l``);
* **active** (insufficient spacing): ``g < d_min`` while the gap closes (``v_f > v_l``).

Every threshold has a trigger and a release value (hysteresis): a coupled follower that dips to ``d_min`` is
decoupled only once the gap is below ``d_min − active_band_m`` *and* closing faster than ``closing_tol_mps``, and
the CA trigger (``gap ≤ trigger``) is released only above ``release`` after ``ca_min_on_s``. After a CA release
the follower is ``independent``: re-coupling needs an explicit command (A12).

:func:`transition` is pure: ``(memory, inputs, params) → (memory, events)``; :func:`ca_hysteresis` is the CA
part alone, shared with :mod:`.collision_avoidance`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from enum import Enum

from controllers.braking import require


class VcState(str, Enum):
    INDEPENDENT = "independent"
    COUPLING = "coupling"
    COUPLED = "coupled"
    DECOUPLING = "decoupling"
    SEPARATING = "separating"
    CA_ACTIVE = "ca_active"
    STOPPED = "stopped"


@dataclass(frozen=True)
class StateParams:
    """Thresholds of the state machine. ``None`` thresholds derive from ``target_gap_m`` (d_c), see below."""

    target_gap_m: float = 5.0  # d_c
    couple_gap_tol_m: float = 0.5  # ε_g
    couple_speed_tol_mps: float = 0.1  # ε_v
    hold_s: float = 1.0  # both held this long → coupled
    passive_gap_m: float | None = None  # d_max; None → max(2·d_c, d_c + 20 m) (A24)
    passive_band_m: float = 1.0  # passive decoupling fires above d_max + band
    active_gap_m: float | None = None  # d_min; None → d_c (the paper's assumption)
    active_band_m: float = 1.0  # active decoupling fires below d_min − band
    closing_tol_mps: float = 0.05  # |Δv| that counts as opening/closing
    decouple_duration_s: float = 0.0  # decoupling → independent after this long (0: next step)
    separation_gap_m: float = 50.0  # separating → independent once the gap exceeds this
    standstill_mps: float = 0.01

    def __post_init__(self) -> None:
        require("target_gap_m", self.target_gap_m >= 0.0, "a number >= 0", self.target_gap_m)
        for name in (
            "couple_gap_tol_m",
            "couple_speed_tol_mps",
            "hold_s",
            "passive_band_m",
            "active_band_m",
            "closing_tol_mps",
            "decouple_duration_s",
            "standstill_mps",
        ):
            require(name, getattr(self, name) >= 0.0, "a number >= 0", getattr(self, name))

    @property
    def d_max_m(self) -> float:
        return (
            self.passive_gap_m
            if self.passive_gap_m is not None
            else max(2.0 * self.target_gap_m, self.target_gap_m + 20.0)
        )

    @property
    def d_min_m(self) -> float:
        return self.active_gap_m if self.active_gap_m is not None else self.target_gap_m


@dataclass(frozen=True)
class VcInputs:
    """What the follower knows at one step. ``closing_speed_mps = v_follower − v_ahead`` (> 0: gap shrinking)."""

    t_s: float
    gap_m: float
    closing_speed_mps: float
    speed_mps: float
    couple_command: bool = False
    decouple_command: bool = False
    separate_command: bool = False
    ca_trigger_m: float = 28.0
    ca_release_m: float = 28.0
    ca_latch_to_standstill: bool = False
    ca_min_on_s: float = 0.1
    ca_enabled: bool = True


@dataclass(frozen=True)
class VcMemory:
    state: VcState = VcState.INDEPENDENT
    since_s: float = 0.0
    hold_start_s: float | None = None
    ca_latched: bool = False
    reason: str = ""


def ca_hysteresis(
    active: bool,
    on_since_s: float,
    t_s: float,
    gap_m: float,
    trigger_m: float,
    release_m: float,
    min_on_s: float,
    latched: bool,
    speed_mps: float,
    standstill_mps: float = 0.01,
) -> bool:
    """Whether CA is active after this step: on at ``gap ≤ trigger``; off at ``gap > release`` after ``min_on_s``;
    a latched brake stays on until standstill and, standing, as long as the object is still within the release
    distance (the vehicle holds, "awaiting assistance"; it releases once the obstacle is cleared)."""
    if not active:
        return gap_m <= trigger_m
    if latched:
        return speed_mps > standstill_mps or gap_m <= release_m
    return not (gap_m > release_m and t_s - on_since_s >= min_on_s - 1e-9)


def ca_should_fire(
    gap_m: float,
    trigger_m: float,
    t_s: float,
    below_since_s: float | None,
    off_since_s: float,
    dwell_s: float,
    band_m: float,
    rearm_s: float,
    urgent_object: bool = False,
    braking_suffices: bool = False,
) -> bool:
    """Debounced CA *trigger* (our design; the paper's §3.2 trigger is the bare ``gap ≤ S_trig``).

    During normal accelerated coupling the coupling law brakes *along* the RDBM curve, so the measured gap grazes
    the trigger distance by centimetres for a step or two (the pure runner: ``track_accel`` loaded F2 touched it
    10 times by 0.01–0.17 m at 1–3.4 m/s closing) and the bare trigger fires the emergency brake each time. Here
    the CA fires when either

    * the intrusion is **deep**: ``gap ≤ trigger − band_m`` (always immediate), or the object is an obstacle
      (``urgent_object``: latched, never debounced), or
    * the own braking does **not** suffice (``braking_suffices`` False: see :func:`braking_suffices`) and the
      gap has stayed at or below the trigger **continuously for** ``dwell_s`` (``below_since_s`` = first
      sample of the current run below it) **and** at least ``rearm_s`` have passed since the last release
      (``off_since_s``), so one grazing episode does not re-fire right after the brake let go.

    Safety bound: without firing the gap can only be within ``band_m`` below the trigger (deeper fires at once),
    so the debounce costs at most ``band_m`` plus one step of closing of the trigger's margin; pick
    ``band_m`` below the trigger's built-in margin. ``dwell_s = band_m = rearm_s = 0`` is the bare trigger.
    """
    if gap_m > trigger_m:
        return False
    if urgent_object or gap_m <= trigger_m - band_m:
        return True
    if braking_suffices:  # shallow intrusion while the own braking already stops the closing in time
        return False
    if below_since_s is None or t_s - off_since_s < rearm_s - 1e-9:
        return False
    return t_s - below_since_s >= dwell_s - 1e-9


def braking_suffices(gap_m: float, closing_speed_mps: float, own_accel_mps2: float, floor_m: float) -> bool:
    """Whether the vehicle's *present* deceleration already ends the closing before the gap falls to
    ``floor_m``, with the object ahead holding its present speed: ``gap − v_c²/(2·a_brake) ≥ floor_m``
    (``v_c`` closing speed > 0, ``a_brake = −own_accel`` > 0). Opening gaps suffice trivially; a vehicle that
    is not braking while closing never does. Re-evaluated every step from the sensor, so an object that starts
    braking raises ``v_c`` and the answer turns False.
    """
    if closing_speed_mps <= 0.0:
        return gap_m >= floor_m
    brake = -own_accel_mps2
    if brake <= 0.0:
        return False
    return gap_m - closing_speed_mps * closing_speed_mps / (2.0 * brake) >= floor_m


def transition(mem: VcMemory, inp: VcInputs, p: StateParams) -> tuple[VcMemory, tuple[str, ...]]:
    """One step of the follower state machine; returns the new memory and the events it emitted."""
    s, t = mem.state, inp.t_s
    events: list[str] = []

    def go(state: VcState, reason: str = "", **kw: object) -> VcMemory:
        events.append(f"{state.value}" + (f":{reason}" if reason else ""))
        return replace(mem, state=state, since_s=t, hold_start_s=None, reason=reason, **kw)  # type: ignore[arg-type]

    # ---- CA pre-empts everything
    if s is VcState.CA_ACTIVE:
        if mem.ca_latched and inp.speed_mps <= p.standstill_mps:
            return go(VcState.STOPPED, "ca_standstill", ca_latched=False), tuple(events)
        still = ca_hysteresis(
            True,
            mem.since_s,
            t,
            inp.gap_m,
            inp.ca_trigger_m,
            inp.ca_release_m,
            inp.ca_min_on_s,
            mem.ca_latched,
            inp.speed_mps,
            p.standstill_mps,
        )
        if still:
            return mem, ()
        return go(VcState.INDEPENDENT, "ca_released"), tuple(events)
    if inp.ca_enabled and ca_hysteresis(
        False, t, t, inp.gap_m, inp.ca_trigger_m, inp.ca_release_m, 0.0, False, inp.speed_mps
    ):
        if s in (VcState.COUPLING, VcState.COUPLED):
            events.append("decouple:active_ca")  # A12: a CA trigger also leaves the formation
        return go(VcState.CA_ACTIVE, "ca_trigger", ca_latched=inp.ca_latch_to_standstill), tuple(events)

    standing = inp.speed_mps <= p.standstill_mps
    if s in (VcState.INDEPENDENT, VcState.STOPPED):
        if inp.couple_command:
            return go(VcState.COUPLING, "command"), tuple(events)
        if s is VcState.INDEPENDENT and standing:
            return go(VcState.STOPPED), tuple(events)
        if s is VcState.STOPPED and not standing:
            return go(VcState.INDEPENDENT, "departed"), tuple(events)
        return mem, ()
    if s in (VcState.COUPLING, VcState.COUPLED):
        if inp.decouple_command:
            return go(VcState.DECOUPLING, "command"), tuple(events)
        if inp.separate_command:
            return go(VcState.SEPARATING, "command"), tuple(events)
        if (
            inp.gap_m > p.d_max_m + p.passive_band_m
            and inp.closing_speed_mps < -p.closing_tol_mps
            and s is VcState.COUPLED
        ):
            return go(VcState.DECOUPLING, "passive"), tuple(events)
        if inp.gap_m < p.d_min_m - p.active_band_m and inp.closing_speed_mps > p.closing_tol_mps:
            return go(VcState.DECOUPLING, "active"), tuple(events)
        if s is VcState.COUPLING:
            ok = (
                abs(inp.gap_m - p.target_gap_m) < p.couple_gap_tol_m
                and abs(inp.closing_speed_mps) < p.couple_speed_tol_mps
            )
            if not ok:
                return (replace(mem, hold_start_s=None) if mem.hold_start_s is not None else mem), ()
            if mem.hold_start_s is None:
                return replace(mem, hold_start_s=t), ()
            if t - mem.hold_start_s >= p.hold_s - 1e-9:
                return go(VcState.COUPLED, "converged"), tuple(events)
        return mem, ()
    if s is VcState.DECOUPLING:
        if t - mem.since_s >= p.decouple_duration_s - 1e-9:
            return go(VcState.INDEPENDENT, "decoupled"), tuple(events)
        return mem, ()
    if s is VcState.SEPARATING:
        if inp.gap_m >= p.separation_gap_m:
            return go(VcState.INDEPENDENT, "separated"), tuple(events)
        return mem, ()
    raise AssertionError(f"unhandled state {s}")  # pragma: no cover
