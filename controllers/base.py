"""The controller interface: what a train knows (an :class:`Observation`) and what it asks for (a :class:`Command`).

Every controller in this package — the line controllers (ATO, moving-block separation, CACC) and the research
controllers of the papers — is an object with one method::

    command(obs: Observation) -> Command

Controllers are created once per train (so model-predictive controllers can keep warm starts) and called every
control step. They never see ground truth and never import libsumo: the engine builds the observation from
what the train *knows* — its own odometry, messages delivered by the communication layer (delayed, lossy,
possibly stale), its movement authority from the interlocking and the route data of its timetable.

Coordinates
    All positions in an observation are **route chainage of the train front** in metres, measured along the
    observing train's own route from its start (``position_m``). Objects ahead (the predecessor, the stop mark,
    the end of authority) are expressed in the same frame, so ``gap`` arithmetic is plain subtraction.
    ``pred.rear_position_m = pred.position_m - pred.length_m``; the front-to-rear gap is
    ``pred.rear_position_m - own.position_m`` (named ``gap_m`` throughout), the front-to-front spacing is
    ``pred.position_m - own.position_m`` (named ``spacing_m``; Paper A uses it).

Acceleration semantics
    :attr:`Command.accel_mps2` is the **applied** specific force: traction (>0) or braking (<0) force divided by
    the effective mass. Running resistance and gradient act on top of it in the plant
    (:mod:`railsim.physics.dynamics`), exactly as in the papers' models ``dv/dt = u − ω(v)``. A controller that wants a
    net acceleration ``a`` asks for ``vehicle.net_to_applied(a, v, gradient)`` (same physics as the plant). The plant clips
    the command to the traction/brake envelope and the jerk limit and logs every saturation.

Roles
    A train's final command is the minimum over its *active* roles (the most restrictive wins):

    * ``ato``      — runs to the line speed, obeys speed limits, stops at the stop mark and before the end of
      movement authority (every train has one);
    * ``follow``   — keeps distance to the train ahead: ``separation`` (absolute braking distance, for trains
      that are not coupled) or a virtual-coupling law (CACC, the papers' controllers) when coupling/coupled.

The engine does this arbitration (:func:`arbitrate`), so a research controller only implements its own law.
    One exception, opt-in: a command marked ``additive`` (Paper D's collision avoidance in the arrival case,
    spec 003 A27) does not compete in the minimum — its braking is *added* to the winner's command, bounded by
    the brake envelope.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

from railsim.physics.vehicle import VehicleParams


@dataclass(frozen=True)
class SpeedLimit:
    """A speed restriction on ``[start_m, end_m)`` of the observer's route (route chainage, train front)."""

    start_m: float
    end_m: float
    speed_mps: float


@dataclass(frozen=True)
class StopTarget:
    """The next scheduled station stop.

    ``mark_m`` is where the train front should halt (the stopping mark); ``window_start_m``/``window_end_m`` is the
    range of front positions SUMO accepts as "whole train on the platform" (``[startPos + length, endPos]``).
    ``dwell_remaining_s`` is > 0 while the train is dwelling at this stop, ``None`` before arrival.
    ``departure_not_before_s`` is the timetable departure (absolute simulation time) if any.
    """

    station_id: str
    mark_m: float
    window_start_m: float
    window_end_m: float
    dwelling: bool = False
    departure_not_before_s: float | None = None


@dataclass(frozen=True)
class PredecessorState:
    """The train ahead as *this train knows it*: from the last delivered message (or on-board sensing).

    ``position_m`` is the predecessor's **front** in the observer's route frame at the time the message was
    sent (``stamp_s``); ``age_s = obs.t_s - stamp_s`` tells how stale it is. ``planned_*`` carry the
    predecessor's broadcast plan (DMPC-style), sampled every ``plan_dt_s`` from ``stamp_s`` on, if it sent one.
    """

    train_id: str
    position_m: float
    speed_mps: float
    accel_mps2: float
    length_m: float
    stamp_s: float
    age_s: float
    service_decel_mps2: float = 1.0
    emergency_decel_mps2: float = 1.2
    planned_position_m: tuple[float, ...] = ()
    planned_speed_mps: tuple[float, ...] = ()
    planned_accel_mps2: tuple[float, ...] = ()
    plan_dt_s: float = 0.0
    source: str = "t2t"  # "t2t" radio message, "ground" (moving-block server) or "sensor"

    @property
    def rear_position_m(self) -> float:
        return self.position_m - self.length_m


@dataclass(frozen=True)
class OwnState:
    """The train's own state from odometry (possibly with sensor noise)."""

    train_id: str
    position_m: float  # front, route chainage [m]
    speed_mps: float
    accel_mps2: float  # applied acceleration last step (after the plant) [m/s²]
    length_m: float
    gradient_permille: float = 0.0  # gradient under the train front (uphill positive)


@dataclass(frozen=True)
class Observation:
    """Everything a controller may use at one control step."""

    t_s: float
    dt_s: float
    own: OwnState
    vehicle: VehicleParams
    route_length_m: float
    speed_limits: tuple[SpeedLimit, ...] = ()  # restrictions that apply now or ahead (within look-ahead)
    line_speed_mps: float = 20.0  # the general line speed where no restriction applies
    next_stop: StopTarget | None = None
    authority_end_m: float | None = None  # the train front must not pass this point (switch not locked, end of route)
    predecessor: PredecessorState | None = None
    formation_state: str = "free"  # free | coupling | coupled | decoupling (railsim.engine.events.formations)
    target_gap_m: float | None = None  # front-to-rear target gap while coupling/coupled
    extras: Mapping[str, Any] = field(default_factory=dict)  # scenario-specific signals (e.g. junction plan)


@dataclass(frozen=True)
class Command:
    """A controller's request for one step.

    ``accel_mps2`` is the applied specific force (see module docstring). ``fallback`` is True when the controller
    could not compute its law (solver failure, infeasible QP) and returned its safe brake instead, with the
    reason in ``info["fallback_reason"]`` (the engine records it: ``controller_fallback`` events); ``info``
    carries diagnostics the recorder keeps (solve time, chosen model, status).

    ``additive``: ``accel_mps2`` is a braking *increment* on top of the other roles' command rather than a
    command of its own (see :func:`arbitrate`); a non-negative increment adds nothing.
    """

    accel_mps2: float
    fallback: bool = False
    emergency: bool = False
    info: Mapping[str, Any] = field(default_factory=dict)
    additive: bool = False


@runtime_checkable
class Controller(Protocol):
    """Anything with ``command(obs) -> Command``; ``reset()`` is optional."""

    def command(self, obs: Observation) -> Command: ...


ControllerFactory = Callable[[Mapping[str, Any], VehicleParams], Controller]
_REGISTRY: dict[str, ControllerFactory] = {}


def register(name: str) -> Callable[[ControllerFactory], ControllerFactory]:
    """Class/function decorator: make a controller available to scenarios under ``name``.

    The factory receives the scenario's parameter mapping and the train's :class:`VehicleParams` and must raise
    ``ValueError("<param>: <what was expected>")`` for bad parameters (the scenario loader adds file and path).
    """

    def deco(factory: ControllerFactory) -> ControllerFactory:
        if name in _REGISTRY and _REGISTRY[name] is not factory:
            raise RuntimeError(f"controller name {name!r} registered twice")
        _REGISTRY[name] = factory
        return factory

    return deco


def registered() -> dict[str, ControllerFactory]:
    """All registered controller factories by name (importing :mod:`controllers` registers the built-ins)."""
    return dict(_REGISTRY)


def family_of(name: str) -> str:
    """The controller family (the ``controllers`` sub-package) a registered type belongs to, e.g. ``mcf_dmpc``."""
    parts = _REGISTRY[name].__module__.split(".")
    return parts[1] if len(parts) > 1 else parts[0]


def create(name: str, params: Mapping[str, Any], vehicle: VehicleParams) -> Controller:
    """Instantiate controller ``name`` for one train (KeyError if unknown, ValueError for bad params)."""
    return _REGISTRY[name](params, vehicle)


def fallback_reason(cmd: Command) -> str:
    """Why ``cmd`` is a fallback: its ``info["fallback_reason"]`` (one short line), else its solver ``status``."""
    reason = cmd.info.get("fallback_reason") if cmd.info else None
    if not reason and cmd.info and cmd.info.get("status"):
        reason = f"solver status: {cmd.info['status']}"
    return str(reason or "not given by the controller")


def arbitrate(commands: Mapping[str, Command], brake_envelope_mps2: float = math.inf) -> tuple[str, Command]:
    """The most restrictive command wins (smallest acceleration; the first role on a tie). Returns ``(role, command)``.

    Commands marked ``additive`` do not compete: the braking part ``min(a, 0)`` of each is added to the winner
    of the others, and the sum is bounded below by the brake envelope ``−brake_envelope_mps2`` (the vehicle's
    emergency deceleration) — never beyond it, and never less braking than the winner asked for on its own:
    ``a = min(a_win, max(a_win + Σ min(a_add, 0), −envelope))``. The role is then the adding role with the
    strongest increment; the command is a new one (emergency or fallback if either part is) whose ``info`` is the
    adder's plus ``base_role`` and ``base_mps2``. Without an additive command (or with nothing to add) this is
    exactly the minimum (so is a winner already at the envelope). A non-finite increment makes the result NaN (the engine then brakes and logs it).
    ValueError if every command is additive (nothing to add to).
    """
    # one pass without a key function (this runs for every train in every step)
    role, cmd, any_additive = "", None, False
    for r, c in commands.items():
        if c.additive:
            any_additive = True
        elif cmd is None or c.accel_mps2 < cmd.accel_mps2:
            role, cmd = r, c
    if cmd is None:
        raise ValueError("arbitrate: no command that is not additive (nothing to add to)")
    if not any_additive:
        return role, cmd
    adders = {r: c for r, c in commands.items() if c.additive and not c.accel_mps2 >= 0.0}
    if not adders:
        return role, cmd
    extra = sum(min(c.accel_mps2, 0.0) for c in adders.values())
    total = min(cmd.accel_mps2, max(cmd.accel_mps2 + extra, -brake_envelope_mps2))
    if not math.isfinite(extra):  # a broken increment must reach the engine's non-finite check, not vanish
        total = math.nan
    elif total >= cmd.accel_mps2:  # the winner is already at the envelope: nothing was added
        return role, cmd
    add_role = min(adders, key=lambda r: adders[r].accel_mps2)
    add = adders[add_role]
    info = {**(add.info or {}), "base_role": role, "base_mps2": cmd.accel_mps2}
    merged = Command(total, fallback=cmd.fallback or add.fallback, emergency=cmd.emergency or add.emergency, info=info)
    return add_role, merged
