"""The scenario model: what a validated scenario *is* — frozen dataclasses and the schema's vocabulary, no I/O.

Everything here is plain data. A :class:`Scenario` is built only by the validator
(:mod:`railsim.scenario.validate_scenario`, reached through :func:`railsim.scenario.load`), which has already
checked every value, so the engine and the analyses can trust these objects without re-checking them.

How the pieces fit (one dataclass per YAML section, nested like the file)::

    Scenario
    ├── world: WorldSpec              which world to build (shipped name, line file or SUMO net)
    ├── simulation: SimulationSpec    step, duration, clock time of t = 0, seed
    ├── vehicles: {name: VehicleParams}        (railsim.physics.vehicle; plants: {name: PlantSpec})
    ├── controllers: {name: ControllerSpec}    + roles: {role: controller instance}
    ├── services: (ServiceSpec, ...)  route, departures_s, trip_ids ("airport.000"), dwell times
    │                                 (departures_after: RelativeDeparturesSpec when timed against a service)
    ├── formations: (FormationSpec, ...)       two TripRefs, a target gap, couple/decouple TriggerSpecs
    ├── events: (EventSpec, ...)      timed commands; their kinds live in railsim.scenario.events
    ├── faults: FaultSpec             comm ChannelSpecs (DelaySpec, OutageSpecs), sensor/actuator noise, bias
    ├── outputs: OutputSpec           trace stride, SUMO outputs, table formats
    ├── interlocking: InterlockingSpec overlap, stall timeout (optional)
    ├── cooperative: CooperativeSpec  graph-coupled group (Paper C)
    ├── junction: JunctionSpec | None trains planned through a junction (Paper E)
    └── disturbances: DisturbanceSpec | None   primary delays (railsim.scenario.disturbances)

Conventions: units are in the names (``_s``, ``_m``, ``_mps``, ``_mps2``); times are seconds from t = 0;
trains are named by trip id. The tuples of names below (:data:`ROLES`, :data:`STEP_METHODS`, ...) are the
allowed values of the corresponding YAML keys; the validator's "expected one of ..." messages list them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from railsim.physics.vehicle import VehicleParams
from railsim.scenario.disturbances import DisturbanceSpec

ROLES = ("ato", "separation", "coupled", "ca")  # ca: collision avoidance on the train's own sensor
REQUIRED_ROLES = ("ato", "separation")
STEP_METHODS = ("euler", "ballistic", "forward")
SUMO_OUTPUTS = ("tripinfo", "stops", "fcd", "collisions")
OUTPUT_FORMATS = ("csv", "parquet")
COMM_CHANNELS = ("t2t", "t2g")
# Parameters of each delay distribution (all in seconds).
DELAY_DISTS: dict[str, tuple[str, ...]] = {
    "constant": ("value",),
    "uniform": ("low", "high"),
    "normal": ("mean", "sd"),
    "lognormal": ("mean", "sd"),
    "exponential": ("mean",),
}
MAX_STEP_S = 5.0
MIN_STEP_S = 0.001  # SUMO counts time in whole milliseconds
MAX_STEPS = 10_000_000  # duration_s / step_s: two days at 0.02 s; more is a mistake, not a study
MAX_SEED = 2**31 - 1  # SUMO's --seed is a 32-bit int
MAX_OVERLAP_M = 1000.0  # an interlocking overlap: tens of metres in CBTC, ~200 m on main lines; more is a slip
MIN_RUNNING_TIME_FACTOR = 0.5  # a train held to less than half its envelope is a failure, not a disturbance
MAX_TRIPS_PER_SERVICE = 10_000  # a whole day at a 10 s headway; more is a typo (and would exhaust memory)
DEFAULT_DWELL_S = 30.0
DEFAULT_COUPLING_TIMEOUT_S = 300.0


# ---- the frozen specification ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class WorldSpec:
    """Which world to build. ``kind`` is ``"shipped"`` (``name`` + ``params``), ``"line"`` (a line description
    file) or ``"net"`` (a ready SUMO net plus additional files, for a later feature). Paths are absolute."""

    kind: str
    name: str | None = None
    params: dict[str, Any] = field(default_factory=dict)
    line: Path | None = None
    net: Path | None = None
    additional: tuple[Path, ...] = ()
    signals: str = "strip"  # net worlds: strip | keep SUMO's rail signals (network.external)
    vclass: str | None = None  # net worlds: the rail vClass of our trains (None: chosen from the net)
    throw_time_s: float = 6.0  # net worlds: throw time of every switch (a SUMO net has none)
    running_side: str = "right"  # net worlds: the track each direction keeps on double track (network.running_side)
    unrestricted_lanes: str | None = None  # net worlds: the rail vClass of lanes that allow every class

    @property
    def label(self) -> str:
        """A short human name for messages."""
        if self.kind == "shipped":
            return str(self.name)
        return str(self.line if self.kind == "line" else self.net)

    def build_args(self) -> tuple[str, dict[str, Any]]:
        """``(name_or_path, params)`` for ``network.build``; a ``net`` world is not built (ValueError)."""
        if self.kind == "shipped":
            return str(self.name), dict(self.params)
        if self.kind == "line":
            return str(self.line), {}
        raise ValueError("a 'net' world is used as is, not built")


@dataclass(frozen=True)
class SimulationSpec:
    """Step length, horizon and randomness of one run. ``start_time_s`` is the clock time of t = 0 in
    seconds after midnight (only used to convert clock strings and to label outputs)."""

    step_s: float
    duration_s: float
    start_time_s: float = 0.0
    seed: int = 0
    step_method: str = "euler"


@dataclass(frozen=True)
class ControllerSpec:
    """A named controller instance: a registered controller ``type`` and its parameters."""

    type: str
    params: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class RelativeDeparturesSpec:
    """Departures defined against another service's (``departures: {after: {...}}``): trip ``k`` of the dependent
    service departs its origin at ``t_i + phase·(t_{i+1} − t_i) + offset_s`` with ``i = first_trip + k·every ≤ last_trip`` and
    ``t`` the reference service's origin departures (the last reference trip uses the interval before it). Changing
    the reference's headway re-times the dependent service consistently (one dependent trip per ``every`` reference
    trips, at the same phase). A dependent trip that would depart before t = 0 (negative ``offset_s``) is dropped;
    ``reference_trips`` holds the reference trip of each remaining dependent trip."""

    service: str  # the reference service id
    every: int = 1
    first_trip: int = 0
    offset_s: float = 0.0
    phase: float = 0.0  # fraction of the reference interval, in [0, 1)
    last_trip: int | None = None  # the last reference trip index taken (None: to the reference's last trip)
    reference_trips: tuple[int, ...] = ()  # resolved: the reference trip index of each dependent trip


@dataclass(frozen=True)
class ServiceSpec:
    """A line service: a route between two stations and the trips that run it.

    ``departures_s`` are sorted seconds from t = 0; trip ``k`` departs at ``departures_s[k]`` and is called
    ``trip_ids[k]``. ``roles`` maps every role to a controller instance name (scenario roles merged with the
    service's overrides).
    """

    id: str
    from_station: str
    to_station: str
    vehicle: str
    departures_s: tuple[float, ...]
    trip_ids: tuple[str, ...]
    via: tuple[str, ...] = ()
    dwell_default_s: float = DEFAULT_DWELL_S
    dwell_by_station: dict[str, float] = field(default_factory=dict)
    skip: tuple[str, ...] = ()
    roles: dict[str, str] = field(default_factory=dict)
    start_offset_m: float = 0.0  # trips start this far beyond the origin's stopping mark (paper experiments)
    start_speed_mps: float = 0.0  # ... at this speed (0: a normal departure from the platform)
    start_before_switch: str | None = None  # or: the front starts start_distance_m before this switch's point
    start_distance_m: float = 0.0
    departures_after: RelativeDeparturesSpec | None = None  # set when the departures are relative to a service
    platforms: dict[str, str] = field(default_factory=dict)  # pinned platforms: station -> stop id (external nets)

    def dwell_s(self, station: str) -> float:
        """Scheduled dwell at ``station`` [s]."""
        return self.dwell_by_station.get(station, self.dwell_default_s)


@dataclass(frozen=True)
class TripRef:
    """One trip: ``trip`` is the 0-based index into the service's sorted departures."""

    service: str
    trip: int


@dataclass(frozen=True)
class TriggerSpec:
    """When a formation couples or decouples.

    ``kind`` is one of ``at_s`` (simulation time ``at_s``), ``at_station`` (coupling: the follower joins its
    leader standing at ``station``, which waits for it; decoupling: on departing ``station``), ``on_departure`` (couple from the
    follower's departure on), ``after_switch`` (couple once the follower's front is past ``switch`` with its
    leader ahead on its track: a merge) or ``before_switch`` (decouple before the follower reaches ``switch``).
    """

    kind: str
    at_s: float | None = None
    station: str | None = None
    switch: str | None = None


@dataclass(frozen=True)
class FormationSpec:
    """Two trips that run virtually coupled for part of their journey (``target_gap_m`` front-to-rear).
    ``couple``/``decouple`` are ``None`` when only events (or nothing) trigger them."""

    id: str
    leader: TripRef
    follower: TripRef
    target_gap_m: float
    couple: TriggerSpec | None = None
    decouple: TriggerSpec | None = None
    coupling_timeout_s: float = DEFAULT_COUPLING_TIMEOUT_S
    # the coupled pair leaves every station both serve together: the leader waits for its follower's dwell
    # (:meth:`railsim.engine.coupling.FormationBook.holds_departure`); False: each unit keeps its own dwell
    depart_together: bool = False


@dataclass(frozen=True)
class EventSpec:
    """A timed command at simulation time ``at_s``: ``couple``/``decouple`` a ``formation``, or a ``train`` (a trip
    id, or a service id with one trip) that ``leave``s the line (removed from the world, e.g. to another track).

    ``type`` names an event kind of :data:`railsim.scenario.events.EVENT_KINDS`; that table says which of the
    optional attributes below the kind sets (the others stay ``None``) and how each is checked.
    """

    at_s: float
    type: str
    formation: str | None = None
    train: str | None = None
    ahead_m: float | None = None  # obstacle: appears this far ahead of the named train's front
    duration_s: float | None = None  # obstacle: removed after this long (None: stays)


PLANT_KINDS = ("single", "multipoint", "monorail")


@dataclass(frozen=True)
class PlantSpec:
    """The train model the engine integrates for a vehicle: ``multipoint`` = Paper B's carriage-by-carriage model
    (:mod:`railsim.physics.multipoint`), ``monorail`` = Paper D's monorail drive (dead time, response lag, efficiency,
    load-dependent limits; :mod:`railsim.physics.monorail`), with ``params`` overriding the model's
    defaults; absent = the single-mass plant (:mod:`railsim.physics.dynamics`)."""

    kind: str
    params: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class CooperativeEdge:
    """A communication edge of a cooperative (graph-coupled) group: ``x_a − x_b`` should tend to ``d_m`` and stay in
    ``[lower_m, upper_m]`` (front positions). Active for ``from_s <= t < until_s``."""

    a: str  # trip id
    b: str
    d_m: float
    lower_m: float
    upper_m: float
    from_s: float = 0.0
    until_s: float = math.inf


@dataclass(frozen=True)
class CooperativeSpec:
    """Trains controlled by a graph law (Paper C): the neighbour graph as edges with activity windows."""

    edges: tuple[CooperativeEdge, ...] = ()


JUNCTION_METHODS = ("improved_pso", "plain_pso", "qp_order", "naive1", "naive2")


@dataclass(frozen=True)
class JunctionSpec:
    """Trains coordinated through a junction by the cooperative-game planner (Paper E, spec 004 §7).

    ``trains`` are trip ids; ``method`` is the planner (improved/plain PSO, ``qp_order``) or a naive baseline; the ground
    re-plans every ``replan_s`` seconds; ``target_gap_m`` is the coupled gap handed to the formations after
    the junction (``None``: the planner's standstill gap ``S_0``); ``params``/``pso``/``replan_pso`` override
    :class:`controllers.junction.model.JunctionParams` and :class:`controllers.junction.pso.PSOParams` fields;
    ``fixed_order``: the trains pass the merge switch in the order listed (a formation's leader first), not in the
    order the planner would choose.
    """

    trains: tuple[str, ...]
    method: str = "improved_pso"
    replan_s: float = 2.0
    target_gap_m: float | None = None
    params: dict[str, Any] = field(default_factory=dict)
    pso: dict[str, Any] = field(default_factory=dict)
    replan_pso: dict[str, Any] = field(default_factory=dict)
    fixed_order: bool = False


@dataclass(frozen=True)
class DelaySpec:
    """A message delay distribution in seconds: ``dist`` and its parameters (see :data:`DELAY_DISTS`)."""

    dist: str = "constant"
    params: dict[str, float] = field(default_factory=lambda: {"value": 0.0})

    def sample(self, rng: np.random.Generator, size: int | None = None) -> Any:
        """Draw delays [s] (never negative).

        ``normal`` is clipped at 0 (a message cannot arrive before it is sent); ``lognormal`` is parametrised
        by the mean ``m`` and standard deviation ``s`` of the delay itself: ``σ² = ln(1 + s²/m²)``,
        ``μ = ln m − σ²/2``.
        """
        p = self.params
        if self.dist == "constant":
            return p["value"] if size is None else np.full(size, p["value"])
        if self.dist == "uniform":
            return rng.uniform(p["low"], p["high"], size)
        if self.dist == "normal":
            return np.maximum(rng.normal(p["mean"], p["sd"], size), 0.0)
        if self.dist == "lognormal":
            sigma2 = math.log1p((p["sd"] / p["mean"]) ** 2)
            return rng.lognormal(math.log(p["mean"]) - sigma2 / 2.0, math.sqrt(sigma2), size)
        if self.dist == "exponential":
            return rng.exponential(p["mean"], size)
        raise ValueError(f"unknown delay distribution {self.dist!r}")


@dataclass(frozen=True)
class OutageSpec:
    """A channel outage on ``[start_s, end_s)`` for ``trains`` (trip ids; ``None`` = every train)."""

    start_s: float
    end_s: float
    trains: tuple[str, ...] | None = None


@dataclass(frozen=True)
class ChannelSpec:
    """One communication channel: delay distribution, independent loss probability, outage windows."""

    delay: DelaySpec = field(default_factory=DelaySpec)
    loss_prob: float = 0.0
    outages: tuple[OutageSpec, ...] = ()


@dataclass(frozen=True)
class SensorNoiseSpec:
    """Zero-mean Gaussian noise on the train's own odometry (standard deviations)."""

    position_sd_m: float = 0.0
    speed_sd_mps: float = 0.0


@dataclass(frozen=True)
class ActuatorBiasSpec:
    """A faulty actuator: ``train`` (trip id) gets ``accel_mps2`` added to every applied command in
    ``[from_s, until_s)`` (Paper D's departure case: a follower accelerating 1.2 m/s² instead of 1.0)."""

    train: str
    accel_mps2: float
    from_s: float = 0.0
    until_s: float = math.inf


@dataclass(frozen=True)
class ActuatorNoiseSpec:
    """Zero-mean Gaussian noise added to the applied acceleration command (Paper A's N(0, σ²) disturbance) of
    ``trains`` (trip ids; None = every train)."""

    accel_sd_mps2: float = 0.0
    trains: tuple[str, ...] | None = None


def _default_channels() -> dict[str, ChannelSpec]:
    return {name: ChannelSpec() for name in COMM_CHANNELS}


@dataclass(frozen=True)
class FaultSpec:
    """Injected faults; ``comm`` always holds every channel of :data:`COMM_CHANNELS`."""

    comm: dict[str, ChannelSpec] = field(default_factory=_default_channels)
    sensor_noise: SensorNoiseSpec = field(default_factory=SensorNoiseSpec)
    actuator_noise: ActuatorNoiseSpec = field(default_factory=ActuatorNoiseSpec)
    actuator_bias: tuple[ActuatorBiasSpec, ...] = ()


@dataclass(frozen=True)
class OutputSpec:
    """What to write: trace decimation [s], SUMO's own outputs, table formats."""

    trace_stride_s: float = 1.0
    sumo: tuple[str, ...] = ()
    formats: tuple[str, ...] = ("csv",)


@dataclass(frozen=True)
class InterlockingSpec:
    """Interlocking knobs (docs/model.md, "Interlocking"); None keeps the engine's default.

    ``overlap_m``: the distance between the end of a train's movement authority and the first point, single-track
    section or crossing not reserved for it (and beyond the destination platform's end): what a train may overrun
    its stopping point by without fouling a route set for another train. ``stall_timeout_s``: how long a train
    may stand for no reason before the run stops as stalled. ``platform_berths``: a train does not run into a
    platform the train ahead stands on (``railsim.engine.platforms``; on by default, ``false`` turns it off)."""

    overlap_m: float | None = None
    stall_timeout_s: float | None = None
    platform_berths: bool | None = None


@dataclass(frozen=True)
class Scenario:
    """A validated scenario. ``source`` is the file it came from (not compared: a resolved copy elsewhere is
    the same scenario); ``raw`` is the resolved mapping (see module docstring)."""

    name: str
    description: str
    source: Path | None = field(compare=False)
    world: WorldSpec
    simulation: SimulationSpec
    vehicles: dict[str, VehicleParams]
    controllers: dict[str, ControllerSpec]
    roles: dict[str, str]
    services: tuple[ServiceSpec, ...]
    formations: tuple[FormationSpec, ...]
    events: tuple[EventSpec, ...]
    faults: FaultSpec
    outputs: OutputSpec
    raw: dict[str, Any] = field(repr=False)
    cooperative: CooperativeSpec = field(default_factory=CooperativeSpec)
    plants: dict[str, PlantSpec] = field(default_factory=dict)  # vehicle name -> non-default plant
    junction: JunctionSpec | None = None
    rotations: RotationSpec | None = None
    interlocking: InterlockingSpec = field(default_factory=InterlockingSpec)
    disturbances: DisturbanceSpec | None = None  # None: no section, nothing injected, no delay accounting

    def service(self, service_id: str) -> ServiceSpec:
        """The service called ``service_id`` (KeyError if none)."""
        for svc in self.services:
            if svc.id == service_id:
                return svc
        raise KeyError(service_id)

    def trip_id(self, ref: TripRef) -> str:
        """The trip id (``airport.000``) of a trip reference."""
        return self.service(ref.service).trip_ids[ref.trip]

    @property
    def n_trips(self) -> int:
        return sum(len(s.departures_s) for s in self.services)

    def vehicle_of(self, service_id: str) -> VehicleParams:
        """The vehicle that runs ``service_id``."""
        return self.vehicles[self.service(service_id).vehicle]


@dataclass(frozen=True)
class RotationSpec:
    """Rolling-stock rotations (vehicle blocks): which trips one unit runs, one after the other.

    ``units`` is ``None`` for ``auto`` (first-in-first-out at each terminal: the unit that arrived first and
    has had its minimum turnback takes the next departure) or ``{unit id: (trip id, …)}`` in running order.
    Between two trips a unit reverses (``railsim.engine.turnback``); it may leave no earlier than its
    arrival + the minimum turnback time of that station (driver / cab change). With ``depot`` each unit starts
    its day with a run out of a depot and ends it with a run into one (``railsim.engine.depot``).
    """

    units: dict[str, tuple[str, ...]] | None = None
    turnback_min_s: float = 120.0
    turnback_min_by_station: dict[str, float] = field(default_factory=dict)
    max_layover_s: float = 1800.0  # auto: a unit ready longer than this before a departure leaves service instead
    # depot runs (railsim.engine.depot): None = none; "auto" = the nearest depot by track; else a depot id
    depot: str | None = None
    depot_by_unit: dict[str, str] = field(default_factory=dict)  # unit id -> depot id (overrides ``depot``)

    def turnback_min_at(self, station_id: str) -> float:
        """The minimum turnback time at ``station_id`` [s]."""
        return float(self.turnback_min_by_station.get(station_id, self.turnback_min_s))
