"""One trip's run-time state (:class:`TrainRuntime`): what changes about a train while the loop runs.

Fields are general to every train; what one paper family needs per train (a carriage model, a state machine)
lives in that family's extension (:mod:`railsim.engine.extensions`), reachable through :attr:`exact_plant` only
where the loop itself must call it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

from railsim.engine import slot_columns
from railsim.engine.routeview import RouteView
from railsim.engine.settings import INF
from railsim.engine.trips import Trip
from railsim.physics import dynamics


class SlotWriter(Protocol):
    """Where a train's resident fields go as well (:class:`railsim.engine.slots.SlotStore`)."""

    def write(self, column: int, slot: int, value: float) -> None:
        """Set one column of one slot."""


class ExactPlant(Protocol):
    """A plant integrated inside the step (Paper B carriages, Paper D monorail drive) instead of
    :func:`railsim.physics.dynamics.step`; SUMO then gets the step's mean speed (see :mod:`.control`)."""

    def advance(
        self, t: float, tr: TrainRuntime, cmd: Any, grad_permille: float, dt_s: float
    ) -> tuple[float, float, float]:
        """Advance one step; return ``(advance_m, new_speed_mps, applied_accel_mps2)``."""

    def resync(self, t: float, chainage_m: float, speed_mps: float) -> None:
        """Adopt SUMO's position and speed (after SUMO held the train at a stop)."""


@dataclass
class TrainRuntime:
    """Everything that changes about one trip during the run."""

    trip: Trip
    view: RouteView
    controllers: dict[str, Any]
    plant: dynamics.PlantState = field(default_factory=lambda: dynamics.PlantState(speed_mps=0.0))
    status: str = "scheduled"  # scheduled | inserting | running | arrived | removed (left the line early)
    inserted_s: float | None = None
    departed_s: float | None = None
    arrived_s: float | None = None
    next_stop: int = 1
    front_m: float = 0.0
    halted_s: float | None = None
    halt_error_m: float | None = None
    sumo_stopped: bool = False
    dwell_started_s: float | None = None
    energy_j: float = 0.0
    min_gap_m: float = INF
    coupled_s: float = 0.0
    max_jerk_mps3: float = 0.0
    fallbacks: int = 0
    saturations: dict[str, int] = field(default_factory=dict)
    locks: dict[str, Any] = field(default_factory=dict)  # switch id -> LockRequest (own or group)
    released: set[str] = field(default_factory=set)
    violations: set[str] = field(default_factory=set)
    last_role: str = "ato"
    last_cmd_mps2: float = 0.0
    last_gap_m: float = INF
    stale_max_s: float = 0.0
    degraded: bool = False
    stops_served: int = 0
    _depart_chainage_m: float = 0.0
    sumo_stopped_now: bool = False
    held_for_route: bool = False  # its dwell is over, but its route beyond the stop is not set (it stays there)
    dwell_until_s: float | None = None  # its dwell lasts at least until then (passenger demand, passenger_dwell)
    vc_target_gap_m: float | None = None  # the coupled controller's effective target (gap policy), last step
    last_plan: Any = None  # the winning controller's broadcast plan (Command.info["plan"]) of the last step
    sent_speed_mps: float | None = None  # the speed handed to SUMO last step
    emergency_since_s: float | None = None  # start of the current emergency-braking interval
    vc_solve_s: float | None = None  # the coupled controller's solve time this step (Command.info["solve_time_s"])
    vc_objective: float | None = None  # and its objective value (Command.info["J"])
    exact_plant: ExactPlant | None = None  # set by a plant extension (multipoint, monorail) at insertion

    train_id: str = ""  # = trip.trip_id (a plain field: it is read millions of times per run)
    sumo_id: str = ""  # the SUMO vehicle: the trip id, or the unit id when trips are chained (rotations)
    unit_id: str | None = None  # the rolling-stock unit running this trip (rotations), else None
    sumo_edge: str = ""  # SUMO's edge of the train this step
    _reversing: bool = False  # on its way to / at its reversal stop: SUMO may flip it (railsim.engine.turnback)
    hold_until_s: float | None = None  # a reversing unit stands at least until then (early for its departure)
    start_front_m: float = 0.0  # front chainage where the trip came on the line (inserted or handed over)
    edge_i: int = 0  # the route edge under the front this step (RouteView.edge_near from last step's)
    slot: int = -1  # its row in the engine's per-train arrays (railsim.engine.slots), given when first read
    store: SlotWriter | None = field(default=None, repr=False, compare=False)  # the arrays its slot is a row of

    def __post_init__(self) -> None:
        self.train_id = self.trip.trip_id
        self.sumo_id = self.trip.trip_id

    def adopt_sumo_speed(self, t: float, speed_mps: float) -> None:
        """SUMO imposed ``speed_mps`` (it holds a dwelling train at 0): the plant takes it, so it never drifts from
        the world; a standing train keeps no acceleration."""
        if self.exact_plant is not None:
            self.exact_plant.resync(t, self.front_m, speed_mps)
        standing = speed_mps == 0
        self.plant = dynamics.PlantState(
            speed_mps=speed_mps,
            applied_accel_mps2=0.0 if standing else self.plant.applied_accel_mps2,
            target_accel_mps2=0.0 if standing else self.plant.target_accel_mps2,
        )

    def exact_step(self, t: float, role: str, cmd: Any, grad_permille: float, dt_s: float) -> float:
        """A step of the exactly integrated plant under ``cmd`` (the winning ``role``'s); returns the speed for
        SUMO, the step's mean speed ``Δx/dt``: SUMO's Euler update moves a train by the speed it is given times dt,
        a plant that integrates within the step moves by ``Δx`` that is not ``v_new·dt``, so handing SUMO ``Δx/dt``
        keeps its front on the plant's."""
        assert self.exact_plant is not None
        advance_m, v_new, applied_mps2 = self.exact_plant.advance(t, self, cmd, grad_permille, dt_s)
        jerk = abs(applied_mps2 - self.plant.applied_accel_mps2) / dt_s
        self.max_jerk_mps3 = max(self.max_jerk_mps3, jerk)
        self.plant = dynamics.PlantState(
            speed_mps=float(v_new), applied_accel_mps2=float(applied_mps2), target_accel_mps2=float(applied_mps2)
        )
        self.last_role = role
        self.last_cmd_mps2 = cmd.accel_mps2
        self.last_plan = None
        self.sent_speed_mps = max(advance_m / dt_s, 0.0)
        return self.sent_speed_mps

    # Resident fields: a write sets the train's value and, once the train has a slot, its column in the slot store
    # (railsim.engine.slots), so the truth pass reads the store and never a stale copy. For fields written rarely.
    @property
    def depart_chainage_m(self) -> float:
        """Route chainage of the front where the train left its last stop (resident: ``slot_columns.DEPART_M``)."""
        return self._depart_chainage_m

    @depart_chainage_m.setter
    def depart_chainage_m(self, value: float) -> None:
        self._depart_chainage_m = value
        store = self.store
        if store is not None:
            store.write(slot_columns.DEPART_M, self.slot, value)

    @property
    def reversing(self) -> bool:
        """On its way to / at its reversal stop (resident: ``slot_columns.REVERSING``)."""
        return self._reversing

    @reversing.setter
    def reversing(self, value: bool) -> None:
        self._reversing = value
        store = self.store
        if store is not None:
            store.write(slot_columns.REVERSING, self.slot, value)

    @property
    def on_line(self) -> bool:
        """Inserted and not yet arrived or removed."""
        return self.status in ("inserting", "running")
