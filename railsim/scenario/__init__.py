"""Scenario files: one YAML file describes one simulation; this module loads it into frozen dataclasses.

A scenario says *which world* (a shipped line, a line description, or a SUMO net), *how long and how finely*
to simulate, *which trains* (vehicle types, services with their departures), *which controllers* drive them
and in which role, which trains run *virtually coupled* (formations and their couple/decouple triggers),
which *faults* to inject (communication delay/loss/outages, sensor noise) and what to *record*.

Loading is validation: :func:`load` either returns a :class:`Scenario` whose every value has been checked
(types, ranges, cross references, controller parameters) or raises :class:`railsim.errors.ConfigError` naming
the file, the field path and what was expected, e.g.::

    scenarios/peak.yaml: services[2].departures.headway_s: expected a number > 0, got -150

Checks that need the built world (station and switch ids) live in :func:`check_against_world`, because
building a world runs netconvert; ``railsim validate`` does both.

The schema (every key; ``#`` comments give type, range and default)::

    name: chongqing_line3_peak            # required, str
    description: "AM peak, airport expresses coupled to Jurenba trains"   # optional, default ""
    world: chongqing_line3                # required: a shipped world name, or one of the mappings
                                          #   {name: straight_corridor, params: {length_km: 60}}
                                          #   {line: lines/my_line.yaml}            (relative to this file)
                                          #   {net: my.net.xml, additional: [stops.add.xml],   (a SUMO net:
                                          #    signals: strip, vclass: auto, throw_time_s: 6}   network.external)
    simulation:                           # required
      step_s: 0.5                         # required, 0 < step_s <= 5
      duration_s: 7200                    # required, > 0: simulated seconds after t = 0
      start_time: "07:30"                 # clock time of t = 0, "HH:MM" or "HH:MM:SS"; default "00:00"
      seed: 42                            # int >= 0; default 0
      step_method: euler                  # euler | ballistic | forward; default euler (forward: x+ = x + v·T)
    vehicles:                             # required, name -> vehicle
      cq6: {preset: cq3_6car}             # a shipped preset (railsim.physics.vehicle.preset_names())...
      cq6_heavy: {preset: cq3_6car, mass_kg: 271000, max_speed_kmh: 70}   # ...with field overrides, or
      # {length_m: ..., mass_kg: ..., <every other VehicleParams field>} without a preset
    controllers:                          # required, instance name -> {type: <registered name>, params: {...}}
      ato: {type: ato, params: {}}
      sep: {type: separation, params: {margin_m: 50}}
      vc: {type: cacc}                    # params default {}
    roles:                                # required, role -> controller instance
      ato: ato                            # required
      separation: sep                     # required: following a train that is not coupled
      coupled: vc                         # required if there is any formation: following while coupling/coupled
    services:                             # required, at least one
      - id: airport                       # unique; trips are named airport.000, airport.001, ...
        from: yudong                      # station ids of the world
        to: jiangbei-airport-t2
        via: [bijin]                      # optional, default []
        vehicle: cq6                      # a key of vehicles
        departures: {first: "07:30", last: "09:30", headway_s: 150}
        dwell_s: {default: 30, stations: {lianglukou: 45}}   # or a number; default 30
        skip: []                          # stations not served; default []
        roles: {}                         # per-service role overrides; default {}
        start: {offset_m: 0, speed_kmh: 0}  # optional: trips start this far beyond the origin's stopping mark,
                                          #   already at this speed (paper experiments that begin in motion)
      - id: jurenba
        from: yudong
        to: jurenba
        vehicle: cq6
        departures: {times: ["07:31", "07:36:30", 900.0]}
    formations:                           # optional, default []
      - id: pair1
        leader: {service: airport, trip: 0}     # trip = 0-based index into that service's sorted departures
        follower: {service: jurenba, trip: 0}
        target_gap_m: 30                        # > 0, front-to-rear
        couple: {at_station: liugongli}         # or {at_s: 0} or {on_departure: true}; omitted: only by events
        decouple: {before_switch: bijin_up}     # or {at_s: 3000} or {at_station: bijin}; omitted: never
        coupling_timeout_s: 300                 # > 0; default 300
    events:                               # optional timed commands, default []
      - {at_s: 600, type: couple, formation: pair1}    # type: couple | decouple
    faults:                               # optional
      comm:                               # channels t2t (train-to-train) and t2g (train-to-ground)
        t2t: {delay_s: {dist: constant, value: 0.2}, loss_prob: 0.0,
              outages: [{start_s: 100, end_s: 130, trains: [airport.000]}]}
        t2g: {delay_s: {dist: uniform, low: 0.1, high: 0.5}, loss_prob: 0.01}
      sensor_noise: {position_sd_m: 0.0, speed_sd_mps: 0.0}
      actuator_noise: {accel_sd_mps2: 0.0}   # Gaussian noise on every applied acceleration (Paper A)
    outputs:                              # optional
      trace_stride_s: 1.0                 # >= step_s; default max(1.0, step_s)
      sumo: []                            # subset of [tripinfo, stops, fcd, collisions]; default []
      formats: [csv]                      # subset of [csv, parquet]; default [csv]

Readings and conventions (where the schema alone is ambiguous):

* **Times.** Inside the program every time is seconds from t = 0 (the start of the simulation). In
  ``departures`` a *string* is a clock time ("07:35" or "07:35:30", hours up to 47 for after-midnight
  service) and is converted relative to ``simulation.start_time``; a *number* is already seconds from t = 0.
  A departure before t = 0 is an error; one after ``duration_s`` is only logged (a study may look at the
  first hour of a longer timetable).
* **Headway grids.** ``{first, last, headway_s}`` expands to ``first + k·headway_s`` for every k with the
  result ≤ ``last`` (``last`` is included when it falls on the grid, with a 1 µs tolerance for float
  arithmetic). Departures are sorted; two trips of one service may not depart at the same time.
* **Unquoted clock times.** YAML 1.1 reads ``17:30`` as the base-60 integer 1050; our loader does not, so
  ``start_time: 17:30`` means half past five whether quoted or not. It also reads ``1e3`` and ``1.0e9``
  as numbers (PyYAML would give strings).
* **Vehicles.** A vehicle's :attr:`VehicleParams.name` is its key in ``vehicles`` (two keys may share a
  preset with different overrides). ``max_speed_kmh`` is the only non-SI field accepted (DESIGN §6: km/h
  only at the YAML edge) and is converted to ``max_speed_mps``. Without ``preset`` every field is required:
  no silent defaults borrowed from some other train.
* **Controller parameters** are checked by building the controller (``controllers.create``) once for every
  vehicle that uses it (or every vehicle when no service does); a factory's ``ValueError("margin_m: expected
  ...")`` becomes ``controllers.sep.params.margin_m: expected ...``. The registry is read when a scenario is
  validated, so controllers registered after import (plugins, tests) are found.
* **Communication delay** distributions are in seconds; ``normal`` draws are clipped at 0 and ``lognormal``
  takes the mean and standard deviation *of the delay itself* (not of its logarithm), see
  :meth:`DelaySpec.sample`.
* **Outage trains** are trip ids (``airport.003``) or service ids (all trips of the service); the spec holds
  the expanded trip ids, or ``None`` for "every train".
* **Round trip.** :attr:`Scenario.raw` is the resolved mapping: defaults filled in, vehicles written out field
  by field, world paths absolute. :func:`resolved_yaml` dumps it; loading that text gives an equal
  :class:`Scenario` (the output folder of every run carries it).
* **Overrides** (:func:`with_overrides`, ``load(path, overrides)``) address values by dotted path with list
  indices, ``{"simulation.seed": 3, "services[0].departures.headway_s": 180}``; they are applied to the raw
  mapping before validation, so an overridden value is checked like any other.

Sections for the papers' experiments (optional):

* ``services[].start: {offset_m, speed_kmh}`` — trips begin in motion, ``offset_m`` beyond the origin's mark.
* ``faults.actuator_noise: {accel_sd_mps2}`` — Gaussian noise on every applied command (Paper A's disturbance).
* ``faults.actuator_bias: [{train, accel_mps2, from_s, until_s}]`` — a faulty actuator adds a constant error.
* ``events: [{at_s, type: leave, train}]`` — a train leaves the line (removed; e.g. to another track).
* ``events: [{at_s, type: obstacle, train, ahead_m, duration_s}]`` — a static obstacle appears ``ahead_m`` ahead of
  the train's front (Paper D); trains sense it with their own sensor (role ``ca``).
* ``roles.ca`` — an optional collision-avoidance role (e.g. ``monorail_ca``) fed by the train's own sensor.
* ``cooperative: {edges: [{between: [a, b], d_m, lower_m, upper_m, from_s, until_s}]}`` — a graph-coupled
  group (Paper C): ``x_a − x_b`` (front positions) tends to ``d_m`` within ``[lower_m, upper_m]`` while the edge
  is active (``from_s <= t < until_s``); ``a``/``b`` are trip ids or one-trip service ids. The engine gives each
  member its active neighbours in ``Observation.extras`` (``edges``, ``neighbours`` from t2t messages, ``k``).
"""

from __future__ import annotations

import copy
import dataclasses
import difflib
import logging
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Collection, Iterable, Mapping, Sequence

import numpy as np
import yaml

from railsim.errors import ConfigError
from railsim.physics.vehicle import VehicleParams, preset, preset_names

log = logging.getLogger(__name__)

ROLES = ("ato", "separation", "coupled", "ca")  # ca: collision avoidance on the train's own sensor
REQUIRED_ROLES = ("ato", "separation")
STEP_METHODS = ("euler", "ballistic", "forward")
SUMO_OUTPUTS = ("tripinfo", "stops", "fcd", "collisions")
OUTPUT_FORMATS = ("csv", "parquet")
COMM_CHANNELS = ("t2t", "t2g")
EVENT_TYPES = ("couple", "decouple", "leave", "obstacle")
# Parameters of each delay distribution (all in seconds).
DELAY_DISTS: dict[str, tuple[str, ...]] = {
    "constant": ("value",),
    "uniform": ("low", "high"),
    "normal": ("mean", "sd"),
    "lognormal": ("mean", "sd"),
    "exponential": ("mean",),
}
MAX_STEP_S = 5.0
MAX_TRIPS_PER_SERVICE = 10_000  # a whole day at a 10 s headway; more is a typo (and would exhaust memory)
DEFAULT_DWELL_S = 30.0
DEFAULT_COUPLING_TIMEOUT_S = 300.0
_GRID_TOL_S = 1e-6  # tolerance for "last falls on the headway grid"
_STRING_SOURCE = "<string>"


# --------------------------------------------------------------------------------------------------------------
# The frozen specification
# --------------------------------------------------------------------------------------------------------------


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

    ``kind`` is one of ``at_s`` (simulation time ``at_s``), ``at_station`` (when both trains depart
    ``station`` for coupling; on departing ``station`` for decoupling), ``on_departure`` (couple from the
    follower's departure on) or ``before_switch`` (decouple before the follower reaches ``switch``).
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


@dataclass(frozen=True)
class EventSpec:
    """A timed command at simulation time ``at_s``: ``couple``/``decouple`` a ``formation``, or a ``train`` (a trip
    id, or a service id with one trip) that ``leave``s the line (removed from the world, e.g. to another track)."""

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


JUNCTION_METHODS = ("improved_pso", "plain_pso", "naive1", "naive2")


@dataclass(frozen=True)
class JunctionSpec:
    """Trains coordinated through a junction by the cooperative-game planner (Paper E, spec 004 §7).

    ``trains`` are trip ids; ``method`` is the planner (improved/plain PSO) or a naive baseline; the ground
    re-plans every ``replan_s`` seconds; ``target_gap_m`` is the coupled gap handed to the formations after
    the junction (``None``: the planner's standstill gap ``S_0``); ``params``/``pso``/``replan_pso`` override
    :class:`controllers.junction.model.JunctionParams` and :class:`controllers.junction.pso.PSOParams` fields.
    """

    trains: tuple[str, ...]
    method: str = "improved_pso"
    replan_s: float = 2.0
    target_gap_m: float | None = None
    params: dict[str, Any] = field(default_factory=dict)
    pso: dict[str, Any] = field(default_factory=dict)
    replan_pso: dict[str, Any] = field(default_factory=dict)


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


# --------------------------------------------------------------------------------------------------------------
# Clock times
# --------------------------------------------------------------------------------------------------------------

_CLOCK_RE = re.compile(r"^(\d{1,2}):(\d{2})(?::(\d{2}(?:\.\d+)?))?$")
_CLOCK_WHAT = 'a clock time "HH:MM" or "HH:MM:SS"'


def parse_clock(text: str) -> float:
    """Seconds after midnight of ``"HH:MM"`` / ``"HH:MM:SS[.s]"`` (hours 0–47). ValueError if malformed."""
    m = _CLOCK_RE.match(text.strip()) if isinstance(text, str) else None
    if not m:
        raise ValueError(text)
    hours, minutes = int(m.group(1)), int(m.group(2))
    seconds = float(m.group(3)) if m.group(3) else 0.0
    if hours > 47 or minutes > 59 or seconds >= 60.0:
        raise ValueError(text)
    return hours * 3600.0 + minutes * 60.0 + seconds


def format_clock(seconds_after_midnight: float) -> str:
    """``"HH:MM:SS"`` (fractions of a second kept when present)."""
    whole = int(math.floor(seconds_after_midnight))
    frac = seconds_after_midnight - whole
    h, rem = divmod(whole, 3600)
    m, s = divmod(rem, 60)
    text = f"{h:02d}:{m:02d}:{s:02d}"
    return text + f"{frac:.3f}"[1:].rstrip("0").rstrip(".") if frac > 1e-9 else text


# --------------------------------------------------------------------------------------------------------------
# YAML reading
# --------------------------------------------------------------------------------------------------------------

_INT_TAG = "tag:yaml.org,2002:int"
_FLOAT_TAG = "tag:yaml.org,2002:float"


class _Loader(yaml.SafeLoader):
    """SafeLoader without YAML 1.1 base-60 numbers (``17:30`` stays a string), with ``1e3`` read as a float,
    and rejecting duplicate mapping keys (PyYAML silently keeps the last one)."""


_Loader.yaml_implicit_resolvers = {
    first: [(tag, rx) for tag, rx in resolvers if tag not in (_INT_TAG, _FLOAT_TAG)]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
_Loader.add_implicit_resolver(
    _INT_TAG,
    re.compile(r"^(?:[-+]?0b[0-1_]+|[-+]?0[0-7_]+|[-+]?(?:0|[1-9][0-9_]*)|[-+]?0x[0-9a-fA-F_]+)$"),
    list("-+0123456789"),
)
_Loader.add_implicit_resolver(
    _FLOAT_TAG,
    re.compile(
        r"^(?:[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)(?:[eE][-+]?[0-9]+)?"
        r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$"
    ),
    list("-+0123456789."),
)


def _construct_mapping_no_duplicates(loader: _Loader, node: yaml.MappingNode) -> dict[Any, Any]:
    loader.flatten_mapping(node)
    seen: set[Any] = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=True)
        try:
            duplicate = key in seen
        except TypeError:  # unhashable key: construct_mapping reports it
            continue
        if duplicate:
            raise yaml.constructor.ConstructorError(
                "while constructing a mapping", node.start_mark, f"found duplicate key {key!r}", key_node.start_mark
            )
        seen.add(key)
    return loader.construct_mapping(node, deep=True)


_Loader.add_constructor("tag:yaml.org,2002:map", _construct_mapping_no_duplicates)


def _parse_yaml(text: str, source: str) -> Any:
    try:
        return yaml.load(text, Loader=_Loader)  # noqa: S506 - _Loader is a SafeLoader
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark is not None else None
        problem = exc.problem or exc.context or "malformed YAML"
        ctx = exc.context_mark
        if exc.problem and exc.context and ctx is not None and mark is not None and ctx.line != mark.line:
            # The problem often surfaces a line later than its cause (an unclosed bracket): name both.
            problem += f" ({exc.context} at line {ctx.line + 1}, column {ctx.column + 1})"
        raise ConfigError(source, where, f"YAML syntax error: {problem}") from None
    except yaml.YAMLError as exc:
        raise ConfigError(source, None, f"YAML syntax error: {exc}") from None


def _read_text(path: Path, source: str) -> str:
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(source, None, "file not found") from None
    except IsADirectoryError:
        raise ConfigError(source, None, "expected a scenario file, got a directory") from None
    except UnicodeDecodeError:
        raise ConfigError(source, None, "expected UTF-8 text, got undecodable bytes") from None
    except OSError as exc:
        raise ConfigError(source, None, f"cannot read file: {exc.strerror or exc}") from None


# --------------------------------------------------------------------------------------------------------------
# Public API
# --------------------------------------------------------------------------------------------------------------


def load(path: str | Path, overrides: Mapping[str, Any] | None = None) -> Scenario:
    """Read, override (dotted paths, see :func:`with_overrides`) and validate a scenario file."""
    source = str(path)
    p = Path(path)
    data = _parse_yaml(_read_text(p, source), source)
    if overrides:
        _require_top_mapping(data, source)
        data = with_overrides(data, overrides)
    return from_mapping(data, source=p, base_dir=p.resolve().parent)


def loads(text: str, source: str = _STRING_SOURCE, base_dir: str | Path | None = None) -> Scenario:
    """Validate a scenario given as YAML text. Relative world paths resolve against ``base_dir`` (default: the
    directory of ``source`` if it is a path, else the working directory)."""
    data = _parse_yaml(text, source)
    is_path = not source.startswith("<")
    if base_dir is None:
        base_dir = Path(source).resolve().parent if is_path else Path.cwd()
    return from_mapping(data, source=Path(source) if is_path else source, base_dir=Path(base_dir))


def from_mapping(data: Any, source: str | Path | None = None, base_dir: str | Path | None = None) -> Scenario:
    """Validate an already parsed scenario mapping (what :func:`load` does after reading the file)."""
    label = str(source) if source is not None else "<scenario>"
    src_path = Path(source) if source is not None and not str(source).startswith("<") else None
    return _Validator(label, Path(base_dir) if base_dir is not None else Path.cwd()).scenario(data, src_path)


def resolved_yaml(scn: Scenario) -> str:
    """The resolved scenario as YAML text; ``loads(resolved_yaml(s)) == s``."""
    header = f"# resolved scenario {scn.name!r} (defaults filled in, paths absolute); loads back unchanged\n"
    return header + yaml.safe_dump(scn.raw, sort_keys=False, allow_unicode=True, default_flow_style=False)


_PATH_RE = re.compile(r"^[^.\[\]]+(?:\[\d+\])*(?:\.[^.\[\]]+(?:\[\d+\])*)*$")
_TOKEN_RE = re.compile(r"([^.\[\]]+)|\[(\d+)\]")


def with_overrides(scn_raw: Mapping[str, Any], overrides: Mapping[str, Any]) -> dict[str, Any]:
    """A deep copy of ``scn_raw`` with values replaced by dotted path (``"services[0].departures.headway_s"``).

    Missing mapping keys on the way are created (so ``faults.comm.t2t.loss_prob`` works on a file without
    ``faults``); list indices must exist. The result is not validated: pass it to :func:`from_mapping`.
    """
    out: dict[str, Any] = copy.deepcopy(dict(scn_raw))
    for dotted, value in overrides.items():
        if not isinstance(dotted, str) or not _PATH_RE.match(dotted):
            raise ConfigError("<overrides>", str(dotted), 'expected a path like "a.b[0].c"')
        tokens: list[str | int] = [
            name if name else int(index) for name, index in _TOKEN_RE.findall(dotted)
        ]
        node: Any = out
        walked = ""
        for pos, tok in enumerate(tokens):
            last = pos == len(tokens) - 1
            if isinstance(tok, int):
                if not isinstance(node, list):
                    raise ConfigError("<overrides>", dotted, f"{walked or '<top>'} is not a list, got {_short(node)}")
                if tok >= len(node):
                    raise ConfigError("<overrides>", dotted, f"index {tok} out of range ({walked} has {len(node)} items)")
                walked = f"{walked}[{tok}]"
            else:
                if not isinstance(node, dict):
                    raise ConfigError("<overrides>", dotted, f"{walked or '<top>'} is not a mapping, got {_short(node)}")
                if not last and tok not in node:
                    node[tok] = {}
                walked = _join(walked, tok)
            if last:
                node[tok] = copy.deepcopy(value)
            else:
                node = node[tok]
    return out


def _check_fields(checker: Any, values: Mapping[str, Any], path: str, module: str, cls_name: str) -> None:
    """Build ``module.cls_name(**values)`` once: unknown fields and rejected values name ``path.field``."""
    import importlib

    cls = getattr(importlib.import_module(module), cls_name)
    names = {f.name for f in dataclasses.fields(cls)}
    for key in values:
        if key not in names:
            raise checker.fail(f"{path}.{key}", f"unknown field{_hint(key, sorted(names))}; "
                                                f"known: {', '.join(sorted(names))}")
    try:
        cls(**values)
    except (TypeError, ValueError) as exc:
        msg = str(exc)
        field_name, _, rest = msg.partition(":")
        if field_name in values:
            raise checker.fail(f"{path}.{field_name}", rest.strip() or msg) from None
        raise checker.fail(path, msg) from None


def check_against_world(scn: Scenario, stations: Collection[str], switches: Collection[str],
                        aliases: Mapping[str, str] | None = None) -> None:
    """Check that every station id and switch id the scenario names exists in the built world.

    ``aliases`` (external nets) are other names a station may go by: its name or a stop id -> station id.
    """
    source = str(scn.source) if scn.source is not None else "<scenario>"
    world = scn.world.label
    station_set, switch_set = set(stations), set(switches)
    known = station_set | set(aliases or ())

    def station(value: str, path: str) -> None:
        if value not in known:
            hint = _hint(value, station_set)
            raise ConfigError(source, path, f"expected a station id of world {world!r}, got {value!r}{hint}")

    for i, svc in enumerate(scn.services):
        base = f"services[{i}]"
        station(svc.from_station, f"{base}.from")
        station(svc.to_station, f"{base}.to")
        for j, st in enumerate(svc.via):
            station(st, f"{base}.via[{j}]")
        for j, st in enumerate(svc.skip):
            station(st, f"{base}.skip[{j}]")
        for st in svc.dwell_by_station:
            station(st, f"{base}.dwell_s.stations.{st}")
    for i, fm in enumerate(scn.formations):
        for key, trig in (("couple", fm.couple), ("decouple", fm.decouple)):
            if trig is None:
                continue
            if trig.kind == "at_station":
                station(str(trig.station), f"formations[{i}].{key}.at_station")
            elif trig.kind == "before_switch" and trig.switch not in switch_set:
                raise ConfigError(
                    source,
                    f"formations[{i}].{key}.before_switch",
                    f"expected a switch id of world {world!r}, got {trig.switch!r}{_hint(str(trig.switch), switch_set)}",
                )


def with_station_ids(scn: Scenario, aliases: Mapping[str, str]) -> Scenario:
    """The scenario with every station it names by an alias (a name or stop id of an external net's station)
    replaced by the station id. ``raw`` keeps what the user wrote (it loads back to the same scenario)."""
    def sid(name: str) -> str:
        return aliases.get(name, name)

    def trig(t: TriggerSpec | None) -> TriggerSpec | None:
        return t if t is None or t.station is None else dataclasses.replace(t, station=sid(t.station))

    services = tuple(dataclasses.replace(
        svc, from_station=sid(svc.from_station), to_station=sid(svc.to_station),
        via=tuple(sid(v) for v in svc.via), skip=tuple(sid(v) for v in svc.skip),
        dwell_by_station={sid(k): v for k, v in svc.dwell_by_station.items()}) for svc in scn.services)
    formations = tuple(dataclasses.replace(f, couple=trig(f.couple), decouple=trig(f.decouple))
                       for f in scn.formations)
    return dataclasses.replace(scn, services=services, formations=formations)


# --------------------------------------------------------------------------------------------------------------
# Validation
# --------------------------------------------------------------------------------------------------------------

_ID_RE = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_\-]*$")
_TOP_REQUIRED = ("name", "world", "simulation", "vehicles", "controllers", "roles", "services")
_TOP_OPTIONAL = ("description", "formations", "events", "faults", "outputs", "cooperative", "junction")
_VEHICLE_FIELDS = {f.name: f for f in dataclasses.fields(VehicleParams) if f.name != "name"}
# Lower bounds of vehicle fields: ("gt"|"ge", bound). Fields not listed only need the right type.
_VEHICLE_BOUNDS: dict[str, tuple[str, float]] = {
    "length_m": ("gt", 0.0),
    "mass_kg": ("gt", 0.0),
    "rotating_mass_factor": ("ge", 1.0),
    "davis_a_n": ("ge", 0.0),
    "davis_b_n_per_mps": ("ge", 0.0),
    "davis_c_n_per_mps2": ("ge", 0.0),
    "max_speed_mps": ("gt", 0.0),
    "traction_max_force_n": ("gt", 0.0),
    "traction_max_power_w": ("gt", 0.0),
    "service_decel_mps2": ("gt", 0.0),
    "emergency_decel_mps2": ("gt", 0.0),
    "jerk_limit_mps3": ("gt", 0.0),
    "actuator_time_constant_s": ("ge", 0.0),
    "capacity_pax": ("ge", 0),
}
_KMH_PER_MPS = 3.6


def _join(path: str, key: Any) -> str:
    return f"{path}.{key}" if path else str(key)


def _short(value: Any, limit: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _hint(value: str, choices: Iterable[str]) -> str:
    close = difflib.get_close_matches(str(value), [str(c) for c in choices], n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _require_top_mapping(data: Any, source: str) -> None:
    if data is None:
        raise ConfigError(source, None, "expected a scenario mapping, got an empty file")
    if not isinstance(data, dict):
        raise ConfigError(source, None, f"expected a mapping at the top level, got {_short(data)}")


def _num(x: float) -> str:
    return f"{x:g}"


def _bound_text(gt: float | None, ge: float | None, le: float | None) -> str:
    lo = f"> {_num(gt)}" if gt is not None else f">= {_num(ge)}" if ge is not None else None
    if lo and le is not None:
        return f"in ({_num(gt)}, {_num(le)}]" if gt is not None else f"in [{_num(ge)}, {_num(le)}]"
    if lo:
        return lo
    return f"<= {_num(le)}" if le is not None else ""


class _Validator:
    """Walks the parsed mapping once, building the spec and the resolved raw mapping side by side."""

    def __init__(self, source: str, base_dir: Path) -> None:
        self.source = source
        self.base_dir = base_dir
        self.plants: dict[str, PlantSpec] = {}

    # ---- primitives ------------------------------------------------------------------------------------------

    def fail(self, path: str | None, message: str) -> ConfigError:
        return ConfigError(self.source, path or None, message)

    def expect(self, path: str, what: str, got: Any) -> ConfigError:
        return self.fail(path, f"expected {what}, got {_short(got)}")

    def mapping(
        self, value: Any, path: str, required: Sequence[str] = (), optional: Sequence[str] = (), what: str = "a mapping"
    ) -> dict[str, Any]:
        """Check a mapping with a fixed key set; returns it. ``required``/``optional`` empty = free keys."""
        if not isinstance(value, dict):
            raise self.expect(path, what, value)
        allowed = list(required) + list(optional)
        if allowed:
            for key in value:
                if key not in allowed:
                    hint = _hint(str(key), allowed)
                    raise self.fail(
                        _join(path, key), f"unknown key{hint}; allowed keys: {', '.join(sorted(allowed))}"
                    )
            for key in required:
                if key not in value:
                    raise self.fail(_join(path, key), "missing required key")
        return value

    def free_mapping(self, value: Any, path: str, what: str = "a mapping") -> dict[str, Any]:
        if not isinstance(value, dict):
            raise self.expect(path, what, value)
        for key in value:
            if not isinstance(key, str):
                raise self.expect(_join(path, key), "string keys", key)
        return value

    def number(
        self, value: Any, path: str, gt: float | None = None, ge: float | None = None, le: float | None = None
    ) -> float:
        bound = _bound_text(gt, ge, le)
        what = f"a number {bound}".rstrip()
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.expect(path, what, value)
        x = float(value)
        if not math.isfinite(x):
            raise self.expect(path, f"a finite number {bound}".rstrip(), value)
        if (gt is not None and not x > gt) or (ge is not None and not x >= ge) or (le is not None and not x <= le):
            raise self.expect(path, what, value)
        return x

    def integer(self, value: Any, path: str, ge: int | None = None) -> int:
        what = f"an integer >= {ge}" if ge is not None else "an integer"
        if isinstance(value, bool) or not isinstance(value, int) or (ge is not None and value < ge):
            raise self.expect(path, what, value)
        return int(value)

    def string(self, value: Any, path: str, choices: Sequence[str] | None = None, what: str = "a non-empty string") -> str:
        if choices is not None:
            if not isinstance(value, str) or value not in choices:
                hint = _hint(value, choices) if isinstance(value, str) else ""
                raise self.fail(path, f"expected one of {', '.join(choices)}, got {_short(value)}{hint}")
            return value
        if not isinstance(value, str) or not value.strip():
            raise self.expect(path, what, value)
        return value

    def ident(self, value: Any, path: str) -> str:
        if not isinstance(value, str) or not _ID_RE.match(value):
            raise self.expect(path, "an id of letters, digits, '_' or '-'", value)
        return value

    def string_list(self, value: Any, path: str) -> list[str]:
        if not isinstance(value, list):
            raise self.expect(path, "a list of strings", value)
        return [self.string(v, f"{path}[{i}]") for i, v in enumerate(value)]

    def subset(self, value: Any, path: str, choices: Sequence[str]) -> list[str]:
        if not isinstance(value, list):
            raise self.expect(path, f"a list, a subset of [{', '.join(choices)}]", value)
        out: list[str] = []
        for i, v in enumerate(value):
            item = self.string(v, f"{path}[{i}]", choices)
            if item in out:
                raise self.fail(f"{path}[{i}]", f"expected distinct values, got {item!r} twice")
            out.append(item)
        return out

    def clock(self, value: Any, path: str) -> float:
        try:
            return parse_clock(value)
        except ValueError:
            raise self.expect(path, _CLOCK_WHAT, value) from None

    def path_value(self, value: Any, path: str) -> Path:
        text = self.string(value, path, what="a file path")
        p = Path(text).expanduser()
        p = p if p.is_absolute() else (self.base_dir / p)
        p = p.resolve()
        if not p.is_file():
            raise self.fail(path, f"expected an existing file, got {text!r} (looked for {p})")
        return p

    # ---- the scenario ----------------------------------------------------------------------------------------

    def scenario(self, data: Any, src_path: Path | None) -> Scenario:
        _require_top_mapping(data, self.source)
        top = self.mapping(data, "", _TOP_REQUIRED, _TOP_OPTIONAL)
        raw: dict[str, Any] = {}
        name = self.string(top["name"], "name")
        description = top.get("description")
        description = "" if description is None else description
        if not isinstance(description, str):
            raise self.expect("description", "a string", description)
        raw["name"], raw["description"] = name, description

        world, raw["world"] = self.world(top["world"])
        sim, raw["simulation"] = self.simulation(top["simulation"])
        vehicles, raw["vehicles"] = self.vehicles(top["vehicles"])
        ctrls, raw["controllers"] = self.controllers(top["controllers"])
        formations_in = top.get("formations") or []
        roles, raw["roles"] = self.roles(top["roles"], ctrls, "roles", need_coupled=bool(formations_in))
        services, raw["services"] = self.services(top["services"], sim, vehicles, ctrls, roles)
        formations, raw["formations"] = self.formations(formations_in, services)
        events, raw["events"] = self.events(top.get("events") or [], formations, services)
        cooperative, coop_raw = self.cooperative(top.get("cooperative") or {}, services)
        if cooperative.edges:
            raw["cooperative"] = coop_raw
        faults, raw["faults"] = self.faults(top.get("faults") or {}, services)
        outputs, raw["outputs"] = self.outputs(top.get("outputs") or {}, sim)
        junction = None
        if top.get("junction") is not None:
            junction, raw["junction"] = self.junction(top["junction"], services, formations)
        # Last, because it depends on code outside this file (the controller registry).
        self.check_controllers(ctrls, services, vehicles)

        return Scenario(
            name=name,
            description=description,
            source=src_path,
            world=world,
            simulation=sim,
            vehicles=vehicles,
            controllers=ctrls,
            roles=roles,
            services=services,
            formations=formations,
            events=events,
            faults=faults,
            outputs=outputs,
            raw=raw,
            cooperative=cooperative,
            plants=dict(self.plants),
            junction=junction,
        )

    def world(self, value: Any) -> tuple[WorldSpec, Any]:
        what = "a world name or a mapping {name, params} | {line} | {net, additional}"
        if isinstance(value, str):
            return WorldSpec(kind="shipped", name=self.string(value, "world")), value
        if not isinstance(value, dict):
            raise self.expect("world", what, value)
        forms = [k for k in ("name", "line", "net") if k in value]
        if len(forms) != 1:
            self.mapping(value, "world", (), ("name", "params", "line", "net", "additional"))  # unknown keys first
            raise self.fail("world", f"expected exactly one of name, line, net, got {_short(value)}")
        form = forms[0]
        if form == "name":
            m = self.mapping(value, "world", ("name",), ("params",))
            name = self.string(m["name"], "world.name")
            params = dict(self.free_mapping(m.get("params") or {}, "world.params"))
            return WorldSpec(kind="shipped", name=name, params=params), {"name": name, "params": copy.deepcopy(params)}
        if form == "line":
            m = self.mapping(value, "world", ("line",))
            line = self.path_value(m["line"], "world.line")
            return WorldSpec(kind="line", line=line), {"line": str(line)}
        from network.external import DEFAULT_THROW_TIME_S, RAIL_VCLASSES, SIGNAL_MODES

        m = self.mapping(value, "world", ("net",), ("additional", "signals", "vclass", "throw_time_s"))
        net = self.path_value(m["net"], "world.net")
        extra = m.get("additional") or []
        if not isinstance(extra, list):
            raise self.expect("world.additional", "a list of file paths", extra)
        additional = tuple(self.path_value(v, f"world.additional[{i}]") for i, v in enumerate(extra))
        signals = self.string(m.get("signals", "strip"), "world.signals", SIGNAL_MODES)
        vclass = m.get("vclass")
        vclass = None if vclass in (None, "auto") else self.string(vclass, "world.vclass", RAIL_VCLASSES)
        throw = self.number(m.get("throw_time_s", DEFAULT_THROW_TIME_S), "world.throw_time_s", ge=0.0)
        return WorldSpec(kind="net", net=net, additional=additional, signals=signals, vclass=vclass,
                         throw_time_s=throw), {
            "net": str(net),
            "additional": [str(p) for p in additional],
            "signals": signals,
            "vclass": vclass or "auto",
            "throw_time_s": throw,
        }

    def simulation(self, value: Any) -> tuple[SimulationSpec, dict[str, Any]]:
        m = self.mapping(value, "simulation", ("step_s", "duration_s"), ("start_time", "seed", "step_method"))
        step_s = self.number(m["step_s"], "simulation.step_s", gt=0.0, le=MAX_STEP_S)
        duration_s = self.number(m["duration_s"], "simulation.duration_s", gt=0.0)
        start_text = m.get("start_time", "00:00")
        start_s = self.clock(start_text, "simulation.start_time")
        seed = self.integer(m.get("seed", 0), "simulation.seed", ge=0)
        method = self.string(m.get("step_method", "euler"), "simulation.step_method", STEP_METHODS)
        spec = SimulationSpec(step_s=step_s, duration_s=duration_s, start_time_s=start_s, seed=seed, step_method=method)
        raw = {"step_s": step_s, "duration_s": duration_s, "start_time": start_text, "seed": seed, "step_method": method}
        return spec, raw

    def vehicles(self, value: Any) -> tuple[dict[str, VehicleParams], dict[str, Any]]:
        m = self.free_mapping(value, "vehicles", what="a mapping of vehicle name -> vehicle")
        if not m:
            raise self.expect("vehicles", "at least one vehicle", value)
        specs: dict[str, VehicleParams] = {}
        raws: dict[str, Any] = {}
        for key, body in m.items():
            specs[key], raws[key] = self.vehicle(key, body, f"vehicles.{key}")
        return specs, raws

    def vehicle(self, key: str, body: Any, path: str) -> tuple[VehicleParams, dict[str, Any]]:
        fields = list(_VEHICLE_FIELDS)
        if isinstance(body, dict) and "name" in body:
            raise self.fail(f"{path}.name", "unknown key (a vehicle is named by its key in 'vehicles')")
        body = self.mapping(body, path, (), ["preset", "max_speed_kmh", "plant", "plant_params", *fields])
        plant = self.plant(body, path)
        if plant is not None:
            self.plants[key] = plant
        body = {k: v for k, v in body.items() if k not in ("plant", "plant_params")}
        if "max_speed_kmh" in body and "max_speed_mps" in body:
            raise self.fail(f"{path}.max_speed_kmh", "expected either max_speed_kmh or max_speed_mps, got both")
        values: dict[str, Any] = {}
        preset_name = body.get("preset")
        if preset_name is not None:
            names = preset_names()
            if not isinstance(preset_name, str) or preset_name not in names:
                hint = _hint(preset_name, names) if isinstance(preset_name, str) else ""
                raise self.fail(
                    f"{path}.preset", f"expected a vehicle preset ({', '.join(names)}), got {_short(preset_name)}{hint}"
                )
            base = preset(preset_name)
            # Presets are our data, but coerce anyway: PyYAML reads "1.0e9" as a string.
            for fname, f in _VEHICLE_FIELDS.items():
                v = getattr(base, fname)
                values[fname] = int(v) if f.type == "int" else float(v) if f.type == "float" else v
        else:
            missing = [f for f in fields if f not in body and not (f == "max_speed_mps" and "max_speed_kmh" in body)]
            if missing:
                raise self.fail(
                    f"{path}.{missing[0]}",
                    "missing required key (a vehicle without preset needs every field: " + ", ".join(missing) + ")",
                )
        for fname, v in body.items():
            if fname == "preset":
                continue
            fpath = f"{path}.{fname}"
            if fname == "max_speed_kmh":
                values["max_speed_mps"] = self.number(v, fpath, gt=0.0) / _KMH_PER_MPS
                continue
            kind, bound = _VEHICLE_BOUNDS.get(fname, ("", 0.0))
            ftype = _VEHICLE_FIELDS[fname].type
            if ftype == "int":
                values[fname] = self.integer(v, fpath, ge=int(bound) if kind == "ge" else None)
            elif ftype == "float":
                gt, ge = (bound, None) if kind == "gt" else (None, bound) if kind == "ge" else (None, None)
                values[fname] = self.number(v, fpath, gt=gt, ge=ge)
            else:
                values[fname] = self.string(v, fpath)
        if values["emergency_decel_mps2"] < values["service_decel_mps2"]:
            raise self.fail(
                f"{path}.emergency_decel_mps2",
                f"expected a number >= service_decel_mps2 ({values['service_decel_mps2']}), "
                f"got {values['emergency_decel_mps2']}",
            )
        raw: dict[str, Any] = {"preset": preset_name} if preset_name is not None else {}
        raw.update({f: values[f] for f in fields})
        if plant is not None:
            raw["plant"] = plant.kind
            raw["plant_params"] = dict(plant.params)
        return VehicleParams(name=key, **values), raw

    def plant(self, body: Mapping[str, Any], path: str) -> "PlantSpec | None":
        """``plant: multipoint`` (+ ``plant_params`` overriding :class:`railsim.physics.multipoint.MultipointParams`)."""
        if "plant" not in body and "plant_params" not in body:
            return None
        kind = self.string(body.get("plant", "single"), f"{path}.plant", PLANT_KINDS)
        params_in = body.get("plant_params") or {}
        if kind == "single":
            if params_in:
                raise self.fail(f"{path}.plant_params", "only a multipoint plant takes plant_params")
            return None
        if kind == "multipoint":
            from railsim.physics.multipoint import MultipointParams as plant_cls
        else:
            from railsim.physics.monorail import MonorailParams as plant_cls

        fields_ = {f.name: f for f in dataclasses.fields(plant_cls)}
        m = self.mapping(params_in, f"{path}.plant_params", (), tuple(fields_))
        params: dict[str, Any] = {}
        for name, v in m.items():
            ftype = str(fields_[name].type)
            if name == "n_cars":
                params[name] = self.integer(v, f"{path}.plant_params.{name}", ge=1)
            elif ftype == "str":
                params[name] = self.string(v, f"{path}.plant_params.{name}")
            else:
                params[name] = self.number(v, f"{path}.plant_params.{name}")
        try:
            plant_cls(**params)
        except (ValueError, TypeError) as exc:
            raise self.fail(f"{path}.plant_params", str(exc)) from None
        return PlantSpec(kind, params)

    def controllers(self, value: Any) -> tuple[dict[str, ControllerSpec], dict[str, Any]]:
        m = self.free_mapping(value, "controllers", what="a mapping of instance name -> {type, params}")
        if not m:
            raise self.expect("controllers", "at least one controller", value)
        specs: dict[str, ControllerSpec] = {}
        raws: dict[str, Any] = {}
        for key, body in m.items():
            path = f"controllers.{key}"
            body = self.mapping(body, path, ("type",), ("params",))
            ctype = self.string(body["type"], f"{path}.type")
            params = dict(self.free_mapping(body.get("params") or {}, f"{path}.params"))
            specs[key] = ControllerSpec(type=ctype, params=params)
            raws[key] = {"type": ctype, "params": copy.deepcopy(params)}
        return specs, raws

    def roles(
        self, value: Any, ctrls: Mapping[str, ControllerSpec], path: str, need_coupled: bool = False, required: bool = True
    ) -> tuple[dict[str, str], dict[str, str]]:
        if required:
            m = self.mapping(value, path, REQUIRED_ROLES, [r for r in ROLES if r not in REQUIRED_ROLES])
        else:  # per-service overrides: every role optional
            m = self.mapping(value, path, (), ROLES)
        if need_coupled and "coupled" not in m:
            raise self.fail(f"{path}.coupled", "missing required key (the scenario has formations)")
        out: dict[str, str] = {}
        for role, inst in m.items():
            if not isinstance(inst, str) or inst not in ctrls:
                hint = _hint(inst, ctrls) if isinstance(inst, str) else ""
                raise self.fail(
                    f"{path}.{role}", f"expected a controller instance ({', '.join(ctrls)}), got {_short(inst)}{hint}"
                )
            out[role] = inst
        return out, dict(out)

    def services(
        self,
        value: Any,
        sim: SimulationSpec,
        vehicles: Mapping[str, VehicleParams],
        ctrls: Mapping[str, ControllerSpec],
        roles: Mapping[str, str],
    ) -> tuple[tuple[ServiceSpec, ...], list[Any]]:
        if not isinstance(value, list) or not value:
            raise self.expect("services", "a non-empty list of services", value)
        specs: list[ServiceSpec] = []
        raws: list[Any] = []
        seen: set[str] = set()
        for i, body in enumerate(value):
            spec, raw = self.service(body, f"services[{i}]", sim, vehicles, ctrls, roles)
            if spec.id in seen:
                raise self.fail(f"services[{i}].id", f"expected a unique service id, got {spec.id!r} twice")
            seen.add(spec.id)
            specs.append(spec)
            raws.append(raw)
        return tuple(specs), raws

    def service(
        self,
        body: Any,
        path: str,
        sim: SimulationSpec,
        vehicles: Mapping[str, VehicleParams],
        ctrls: Mapping[str, ControllerSpec],
        roles: Mapping[str, str],
    ) -> tuple[ServiceSpec, dict[str, Any]]:
        m = self.mapping(
            body, path, ("id", "from", "to", "vehicle", "departures"), ("via", "dwell_s", "skip", "roles", "start")
        )
        sid = self.ident(m["id"], f"{path}.id")
        origin = self.string(m["from"], f"{path}.from")
        dest = self.string(m["to"], f"{path}.to")
        if origin == dest:
            raise self.fail(f"{path}.to", f"expected a station other than 'from', got {dest!r}")
        via = self.string_list(m.get("via") or [], f"{path}.via")
        skip = self.string_list(m.get("skip") or [], f"{path}.skip")
        for j, st in enumerate(skip):
            if st in (origin, dest):
                raise self.fail(f"{path}.skip[{j}]", f"expected an intermediate station, got the terminal {st!r}")
        vehicle = m["vehicle"]
        if not isinstance(vehicle, str) or vehicle not in vehicles:
            hint = _hint(vehicle, vehicles) if isinstance(vehicle, str) else ""
            raise self.fail(
                f"{path}.vehicle", f"expected one of the vehicles ({', '.join(vehicles)}), got {_short(vehicle)}{hint}"
            )
        departures, dep_raw = self.departures(m["departures"], f"{path}.departures", sim)
        dwell_default, dwell_stations, dwell_raw = self.dwell(m.get("dwell_s", DEFAULT_DWELL_S), f"{path}.dwell_s")
        own_roles, own_raw = self.roles(m.get("roles") or {}, ctrls, f"{path}.roles", required=False)
        start_in = self.mapping(m.get("start") or {}, f"{path}.start", (),
                                ("offset_m", "speed_kmh", "before_switch", "distance_m"))
        start_offset = self.number(start_in.get("offset_m", 0.0), f"{path}.start.offset_m", ge=0.0)
        start_kmh = self.number(start_in.get("speed_kmh", 0.0), f"{path}.start.speed_kmh", ge=0.0)
        start_switch = None
        start_distance = 0.0
        if "before_switch" in start_in or "distance_m" in start_in:
            if "offset_m" in start_in:
                raise self.fail(f"{path}.start", "give either offset_m or before_switch + distance_m, not both")
            if "before_switch" not in start_in or "distance_m" not in start_in:
                raise self.fail(f"{path}.start", "before_switch and distance_m go together")
            start_switch = self.string(start_in["before_switch"], f"{path}.start.before_switch")
            start_distance = self.number(start_in["distance_m"], f"{path}.start.distance_m", gt=0.0)
        width = max(3, len(str(len(departures) - 1)))
        trip_ids = tuple(f"{sid}.{k:0{width}d}" for k in range(len(departures)))
        late = [t for t in departures if t > sim.duration_s]
        if late:
            log.warning(
                "%s: %s: %d of %d departures fall after duration_s=%g and will not run",
                self.source, path, len(late), len(departures), sim.duration_s,
            )
        spec = ServiceSpec(
            id=sid,
            from_station=origin,
            to_station=dest,
            vehicle=vehicle,
            departures_s=departures,
            trip_ids=trip_ids,
            via=tuple(via),
            dwell_default_s=dwell_default,
            dwell_by_station=dwell_stations,
            skip=tuple(skip),
            roles={**roles, **own_roles},
            start_offset_m=start_offset,
            start_speed_mps=start_kmh / 3.6,
            start_before_switch=start_switch,
            start_distance_m=start_distance,
        )
        raw = {
            "id": sid, "from": origin, "to": dest, "via": via, "vehicle": vehicle, "departures": dep_raw,
            "dwell_s": dwell_raw, "skip": skip, "roles": own_raw,
        }
        if start_in and start_switch is not None:
            raw["start"] = {"before_switch": start_switch, "distance_m": start_distance, "speed_kmh": start_kmh}
        elif start_in:
            raw["start"] = {"offset_m": start_offset, "speed_kmh": start_kmh}
        return spec, raw

    def time_point(self, value: Any, path: str, sim: SimulationSpec) -> float:
        """A departure time: a clock string (relative to start_time) or seconds from t = 0."""
        if isinstance(value, str):
            t = self.clock(value, path) - sim.start_time_s
            if t < 0.0:
                raise self.fail(
                    path, f"expected a time at or after start_time ({format_clock(sim.start_time_s)}), got {value!r}"
                )
            return t
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.expect(path, f"{_CLOCK_WHAT} or seconds >= 0", value)
        return self.number(value, path, ge=0.0)

    def departures(self, value: Any, path: str, sim: SimulationSpec) -> tuple[tuple[float, ...], dict[str, Any]]:
        what = "a mapping {first, last, headway_s} or {times: [...]}"
        if not isinstance(value, dict):
            raise self.expect(path, what, value)
        if "times" in value:
            m = self.mapping(value, path, ("times",))
            times_in = m["times"]
            if not isinstance(times_in, list) or not times_in:
                raise self.expect(f"{path}.times", "a non-empty list of departure times", times_in)
            if len(times_in) > MAX_TRIPS_PER_SERVICE:
                raise self.fail(f"{path}.times", f"expected at most {MAX_TRIPS_PER_SERVICE} departures, got {len(times_in)}")
            times = [self.time_point(v, f"{path}.times[{i}]", sim) for i, v in enumerate(times_in)]
            order = sorted(range(len(times)), key=times.__getitem__)
            for a, b in zip(order, order[1:]):
                if times[a] == times[b]:
                    raise self.fail(
                        f"{path}.times[{b}]", f"expected distinct departure times, got {times_in[b]!r} twice"
                    )
            return tuple(times[k] for k in order), {"times": copy.deepcopy(times_in)}
        m = self.mapping(value, path, ("first", "last", "headway_s"), what=what)
        first = self.time_point(m["first"], f"{path}.first", sim)
        last = self.time_point(m["last"], f"{path}.last", sim)
        headway = self.number(m["headway_s"], f"{path}.headway_s", gt=0.0)
        if last < first:
            raise self.fail(f"{path}.last", f"expected a time at or after first ({m['first']!r}), got {m['last']!r}")
        n = int(math.floor((last - first) / headway + _GRID_TOL_S / headway)) + 1
        if n > MAX_TRIPS_PER_SERVICE:
            raise self.fail(
                path, f"expected at most {MAX_TRIPS_PER_SERVICE} departures, got {n} (from first to last every headway_s)"
            )
        times = tuple(first + k * headway for k in range(n))
        return times, {"first": m["first"], "last": m["last"], "headway_s": headway}

    def dwell(self, value: Any, path: str) -> tuple[float, dict[str, float], Any]:
        if isinstance(value, dict):
            m = self.mapping(value, path, (), ("default", "stations"))
            default = self.number(m.get("default", DEFAULT_DWELL_S), f"{path}.default", ge=0.0)
            st_in = self.free_mapping(m.get("stations") or {}, f"{path}.stations", what="a mapping station -> seconds")
            stations = {k: self.number(v, f"{path}.stations.{k}", ge=0.0) for k, v in st_in.items()}
            return default, stations, {"default": default, "stations": dict(stations)}
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.expect(path, "a number >= 0 or a mapping {default, stations}", value)
        default = self.number(value, path, ge=0.0)
        return default, {}, default

    def trip_ref(self, value: Any, path: str, services: Sequence[ServiceSpec]) -> TripRef:
        m = self.mapping(value, path, ("service", "trip"))
        by_id = {s.id: s for s in services}
        sid = m["service"]
        if not isinstance(sid, str) or sid not in by_id:
            hint = _hint(sid, by_id) if isinstance(sid, str) else ""
            raise self.fail(f"{path}.service", f"expected a service id ({', '.join(by_id)}), got {_short(sid)}{hint}")
        n = len(by_id[sid].departures_s)
        trip = m["trip"]
        if isinstance(trip, bool) or not isinstance(trip, int) or not 0 <= trip < n:
            raise self.fail(
                f"{path}.trip",
                f"expected a trip index in [0, {n - 1}] (service {sid!r} has {n} departures), got {_short(trip)}",
            )
        return TripRef(service=sid, trip=int(trip))

    def trigger(self, value: Any, path: str, kinds: Sequence[str]) -> tuple[TriggerSpec, dict[str, Any]]:
        m = self.mapping(value, path, (), kinds)
        if len(m) != 1:
            raise self.fail(path, f"expected exactly one of {', '.join(kinds)}, got {_short(m)}")
        kind, v = next(iter(m.items()))
        kpath = f"{path}.{kind}"
        if kind == "at_s":
            return TriggerSpec(kind, at_s=self.number(v, kpath, ge=0.0)), {kind: float(v)}
        if kind == "on_departure":
            if v is not True:
                raise self.expect(kpath, "true", v)
            return TriggerSpec(kind), {kind: True}
        text = self.string(v, kpath)
        if kind == "at_station":
            return TriggerSpec(kind, station=text), {kind: text}
        return TriggerSpec(kind, switch=text), {kind: text}

    def formations(
        self, value: Any, services: Sequence[ServiceSpec]
    ) -> tuple[tuple[FormationSpec, ...], list[Any]]:
        if not isinstance(value, list):
            raise self.expect("formations", "a list of formations", value)
        specs: list[FormationSpec] = []
        raws: list[Any] = []
        follower_of: dict[TripRef, str] = {}
        leader_of: dict[TripRef, TripRef] = {}
        trip_name = {s.id: s.trip_ids for s in services}
        for i, body in enumerate(value):
            path = f"formations[{i}]"
            m = self.mapping(
                body, path, ("id", "leader", "follower", "target_gap_m"), ("couple", "decouple", "coupling_timeout_s")
            )
            fid = self.ident(m["id"], f"{path}.id")
            if any(f.id == fid for f in specs):
                raise self.fail(f"{path}.id", f"expected a unique formation id, got {fid!r} twice")
            leader = self.trip_ref(m["leader"], f"{path}.leader", services)
            follower = self.trip_ref(m["follower"], f"{path}.follower", services)
            follower_name = trip_name[follower.service][follower.trip]
            if follower == leader:
                raise self.fail(f"{path}.follower", f"expected a train other than the leader, got {follower_name}")
            if follower in follower_of:
                raise self.fail(
                    f"{path}.follower",
                    f"expected a train that follows in at most one formation, got {follower_name} "
                    f"(already the follower in {follower_of[follower]!r})",
                )
            # Following must not loop back: walking leaders from the leader may not reach the follower.
            node: TripRef | None = leader
            while node is not None:
                if node == follower:
                    raise self.fail(
                        f"{path}.follower", f"expected formations without a cycle, got {follower_name} following itself"
                    )
                node = leader_of.get(node)
            follower_of[follower] = fid
            leader_of[follower] = leader
            gap = self.number(m["target_gap_m"], f"{path}.target_gap_m", gt=0.0)
            timeout = self.number(
                m.get("coupling_timeout_s", DEFAULT_COUPLING_TIMEOUT_S), f"{path}.coupling_timeout_s", gt=0.0
            )
            raw: dict[str, Any] = {
                "id": fid,
                "leader": {"service": leader.service, "trip": leader.trip},
                "follower": {"service": follower.service, "trip": follower.trip},
                "target_gap_m": gap,
            }
            couple = decouple = None
            if m.get("couple") is not None:
                couple, raw["couple"] = self.trigger(m["couple"], f"{path}.couple", ("at_s", "at_station", "on_departure"))
            if m.get("decouple") is not None:
                decouple, raw["decouple"] = self.trigger(
                    m["decouple"], f"{path}.decouple", ("before_switch", "at_s", "at_station")
                )
            raw["coupling_timeout_s"] = timeout
            specs.append(FormationSpec(fid, leader, follower, gap, couple, decouple, timeout))
            raws.append(raw)
        return tuple(specs), raws

    def trip_name(self, value: Any, path: str, services: Sequence[ServiceSpec]) -> str:
        """A trip id, or the id of a service that has exactly one trip (→ that trip's id)."""
        trips = {t for svc in services for t in svc.trip_ids}
        if isinstance(value, str) and value in trips:
            return value
        for svc in services:
            if value == svc.id:
                if len(svc.trip_ids) != 1:
                    raise self.fail(path, f"expected a trip id; service {svc.id!r} has {len(svc.trip_ids)} trips "
                                          f"(name one of {svc.trip_ids[0]}…)")
                return svc.trip_ids[0]
        names = [svc.id for svc in services]
        hint = _hint(value, names) if isinstance(value, str) else ""
        raise self.fail(path, f"expected a trip id or a one-trip service id, got {_short(value)}{hint}")

    def junction(self, value: Any, services: Sequence[ServiceSpec],
                 formations: Sequence[FormationSpec]) -> tuple[JunctionSpec, dict[str, Any]]:
        m = self.mapping(value, "junction", ("trains",),
                         ("method", "replan_s", "target_gap_m", "params", "pso", "replan_pso"))
        if not isinstance(m["trains"], list) or not 2 <= len(m["trains"]) <= 8:
            raise self.expect("junction.trains", "a list of 2 to 8 trains (trip ids or one-trip service ids)",
                              m["trains"])
        trains = [self.trip_name(v, f"junction.trains[{i}]", services) for i, v in enumerate(m["trains"])]
        if len(set(trains)) != len(trains):
            raise self.fail("junction.trains", f"a train is listed twice: {trains}")
        for f in formations:
            for ref in (f.leader, f.follower):
                tid = next(svc.trip_ids[ref.trip] for svc in services if svc.id == ref.service)
                if tid in trains:
                    raise self.fail("junction.trains", f"{tid} is in formation {f.id!r}; the junction planner "
                                                       "forms the formations of its trains itself (in passing order)")
        method = self.string(m.get("method", "improved_pso"), "junction.method", JUNCTION_METHODS)
        replan = self.number(m.get("replan_s", 2.0), "junction.replan_s", gt=0.0)
        gap = m.get("target_gap_m")
        gap = None if gap is None else self.number(gap, "junction.target_gap_m", gt=0.0)
        params = dict(self.free_mapping(m.get("params") or {}, "junction.params"))
        pso = dict(self.free_mapping(m.get("pso") or {}, "junction.pso"))
        replan_pso = dict(self.free_mapping(m.get("replan_pso") or {}, "junction.replan_pso"))
        _check_fields(self, params, "junction.params", "controllers.junction.model", "JunctionParams")
        _check_fields(self, pso, "junction.pso", "controllers.junction.pso", "PSOParams")
        _check_fields(self, replan_pso, "junction.replan_pso", "controllers.junction.pso", "PSOParams")
        spec = JunctionSpec(tuple(trains), method, replan, gap, params, pso, replan_pso)
        raw = {"trains": trains, "method": method, "replan_s": replan, "params": copy.deepcopy(params),
               "pso": copy.deepcopy(pso), "replan_pso": copy.deepcopy(replan_pso)}
        if gap is not None:
            raw["target_gap_m"] = gap
        return spec, raw

    def cooperative(self, value: Any, services: Sequence[ServiceSpec]) -> tuple[CooperativeSpec, dict[str, Any]]:
        m = self.mapping(value, "cooperative", (), ("edges",))
        edges_in = m.get("edges") or []
        if not isinstance(edges_in, list):
            raise self.expect("cooperative.edges", "a list of edges", edges_in)
        edges, raws = [], []
        for i, body in enumerate(edges_in):
            path = f"cooperative.edges[{i}]"
            e = self.mapping(body, path, ("between", "d_m", "lower_m", "upper_m"), ("from_s", "until_s"))
            pair = e["between"]
            if not isinstance(pair, list) or len(pair) != 2:
                raise self.expect(f"{path}.between", "a list of two trains [a, b] (x_a − x_b is constrained)", pair)
            a = self.trip_name(pair[0], f"{path}.between[0]", services)
            b = self.trip_name(pair[1], f"{path}.between[1]", services)
            if a == b:
                raise self.fail(f"{path}.between", f"expected two different trains, got {a!r} twice")
            lower = self.number(e["lower_m"], f"{path}.lower_m")
            upper = self.number(e["upper_m"], f"{path}.upper_m")
            d = self.number(e["d_m"], f"{path}.d_m")
            if not lower < d < upper:
                raise self.fail(f"{path}.d_m", f"expected lower_m < d_m < upper_m ({lower} < d < {upper}), got {d}")
            frm = self.number(e.get("from_s", 0.0), f"{path}.from_s", ge=0.0)
            until = self.number(e["until_s"], f"{path}.until_s", ge=frm) if "until_s" in e else math.inf
            edges.append(CooperativeEdge(a, b, d, lower, upper, frm, until))
            r = {"between": [a, b], "d_m": d, "lower_m": lower, "upper_m": upper, "from_s": frm}
            if math.isfinite(until):
                r["until_s"] = until
            raws.append(r)
        return CooperativeSpec(tuple(edges)), {"edges": raws}

    def events(self, value: Any, formations: Sequence[FormationSpec],
               services: Sequence[ServiceSpec] = ()) -> tuple[tuple[EventSpec, ...], list[Any]]:
        if not isinstance(value, list):
            raise self.expect("events", "a list of events", value)
        ids = [f.id for f in formations]
        specs: list[EventSpec] = []
        raws: list[Any] = []
        for i, body in enumerate(value):
            path = f"events[{i}]"
            m = self.mapping(body, path, ("at_s", "type"), ("formation", "train", "ahead_m", "duration_s"))
            at_s = self.number(m["at_s"], f"{path}.at_s", ge=0.0)
            etype = self.string(m["type"], f"{path}.type", EVENT_TYPES)
            if etype == "obstacle":
                for key in ("train", "ahead_m"):
                    if key not in m:
                        raise self.fail(f"{path}.{key}", "missing required key (an obstacle appears ahead of a train)")
                train = self.trip_name(m["train"], f"{path}.train", services)
                ahead = self.number(m["ahead_m"], f"{path}.ahead_m", gt=0.0)
                dur = self.number(m["duration_s"], f"{path}.duration_s", gt=0.0) if "duration_s" in m else None
                specs.append(EventSpec(at_s, etype, train=train, ahead_m=ahead, duration_s=dur))
                r = {"at_s": at_s, "type": etype, "train": train, "ahead_m": ahead}
                if dur is not None:
                    r["duration_s"] = dur
                raws.append(r)
                continue
            if etype == "leave":
                if "train" not in m:
                    raise self.fail(f"{path}.train", "missing required key (a leave event names the train)")
                train = self.trip_name(m["train"], f"{path}.train", services)
                specs.append(EventSpec(at_s, etype, train=train))
                raws.append({"at_s": at_s, "type": etype, "train": train})
                continue
            if "formation" not in m:
                raise self.fail(f"{path}.formation", "missing required key")
            fid = m["formation"]
            if not isinstance(fid, str) or fid not in ids:
                hint = _hint(fid, ids) if isinstance(fid, str) else ""
                listed = ", ".join(ids) if ids else "none defined"
                raise self.fail(f"{path}.formation", f"expected a formation id ({listed}), got {_short(fid)}{hint}")
            specs.append(EventSpec(at_s, etype, formation=fid))
            raws.append({"at_s": at_s, "type": etype, "formation": fid})
        return tuple(specs), raws

    def delay(self, value: Any, path: str) -> tuple[DelaySpec, dict[str, Any]]:
        if not isinstance(value, dict):
            raise self.expect(path, "a mapping {dist: ..., <parameters>}", value)
        if "dist" not in value:
            raise self.fail(f"{path}.dist", "missing required key")
        dist = self.string(value["dist"], f"{path}.dist", tuple(DELAY_DISTS))
        names = DELAY_DISTS[dist]
        m = self.mapping(value, path, ("dist", *names))
        p = {k: m[k] for k in names}
        if dist == "constant":
            params = {"value": self.number(p["value"], f"{path}.value", ge=0.0)}
        elif dist == "uniform":
            low = self.number(p["low"], f"{path}.low", ge=0.0)
            params = {"low": low, "high": self.number(p["high"], f"{path}.high", ge=low)}
        elif dist == "normal":
            mean = self.number(p["mean"], f"{path}.mean", ge=0.0)
            params = {"mean": mean, "sd": self.number(p["sd"], f"{path}.sd", ge=0.0)}
        elif dist == "lognormal":
            mean = self.number(p["mean"], f"{path}.mean", gt=0.0)
            params = {"mean": mean, "sd": self.number(p["sd"], f"{path}.sd", ge=0.0)}
        else:
            params = {"mean": self.number(p["mean"], f"{path}.mean", gt=0.0)}
        return DelaySpec(dist, params), {"dist": dist, **params}

    def faults(self, value: Any, services: Sequence[ServiceSpec]) -> tuple[FaultSpec, dict[str, Any]]:
        m = self.mapping(value, "faults", (), ("comm", "sensor_noise", "actuator_noise", "actuator_bias"))
        comm_in = self.mapping(m.get("comm") or {}, "faults.comm", (), COMM_CHANNELS)
        trips = {t for s in services for t in s.trip_ids}
        service_trips = {s.id: s.trip_ids for s in services}
        channels: dict[str, ChannelSpec] = {}
        comm_raw: dict[str, Any] = {}
        for name in COMM_CHANNELS:
            path = f"faults.comm.{name}"
            ch = self.mapping(comm_in.get(name) or {}, path, (), ("delay_s", "loss_prob", "outages"))
            delay, delay_raw = self.delay(ch.get("delay_s", {"dist": "constant", "value": 0.0}), f"{path}.delay_s")
            loss = self.number(ch.get("loss_prob", 0.0), f"{path}.loss_prob", ge=0.0, le=1.0)
            outages_in = ch.get("outages") or []
            if not isinstance(outages_in, list):
                raise self.expect(f"{path}.outages", "a list of {start_s, end_s, trains}", outages_in)
            outages: list[OutageSpec] = []
            outages_raw: list[Any] = []
            for j, o in enumerate(outages_in):
                opath = f"{path}.outages[{j}]"
                om = self.mapping(o, opath, ("start_s", "end_s"), ("trains",))
                start = self.number(om["start_s"], f"{opath}.start_s", ge=0.0)
                end = self.number(om["end_s"], f"{opath}.end_s", gt=start)
                o_raw: dict[str, Any] = {"start_s": start, "end_s": end}
                trains: tuple[str, ...] | None = None
                if om.get("trains") is not None:
                    names = self.string_list(om["trains"], f"{opath}.trains")
                    expanded: list[str] = []
                    for k, t in enumerate(names):
                        if t in service_trips:
                            expanded.extend(service_trips[t])
                        elif t in trips:
                            expanded.append(t)
                        else:
                            raise self.fail(
                                f"{opath}.trains[{k}]",
                                f"expected a trip id (like {next(iter(sorted(trips)))!r}) or a service id, "
                                f"got {t!r}{_hint(t, list(trips) + list(service_trips))}",
                            )
                    trains = tuple(dict.fromkeys(expanded))
                    o_raw["trains"] = names
                outages.append(OutageSpec(start, end, trains))
                outages_raw.append(o_raw)
            channels[name] = ChannelSpec(delay, loss, tuple(outages))
            comm_raw[name] = {"delay_s": delay_raw, "loss_prob": loss, "outages": outages_raw}
        noise_in = self.mapping(m.get("sensor_noise") or {}, "faults.sensor_noise", (), ("position_sd_m", "speed_sd_mps"))
        noise = SensorNoiseSpec(
            position_sd_m=self.number(noise_in.get("position_sd_m", 0.0), "faults.sensor_noise.position_sd_m", ge=0.0),
            speed_sd_mps=self.number(noise_in.get("speed_sd_mps", 0.0), "faults.sensor_noise.speed_sd_mps", ge=0.0),
        )
        act_in = self.mapping(m.get("actuator_noise") or {}, "faults.actuator_noise", (), ("accel_sd_mps2", "trains"))
        noise_trains = None
        if "trains" in act_in:
            if not isinstance(act_in["trains"], list):
                raise self.expect("faults.actuator_noise.trains", "a list of trains", act_in["trains"])
            noise_trains = tuple(self.trip_name(x, f"faults.actuator_noise.trains[{i}]", services)
                                 for i, x in enumerate(act_in["trains"]))
        act = ActuatorNoiseSpec(
            accel_sd_mps2=self.number(act_in.get("accel_sd_mps2", 0.0), "faults.actuator_noise.accel_sd_mps2", ge=0.0),
            trains=noise_trains)
        biases, biases_raw = [], []
        bias_in = m.get("actuator_bias") or []
        if not isinstance(bias_in, list):
            raise self.expect("faults.actuator_bias", "a list of {train, accel_mps2, from_s, until_s}", bias_in)
        for i, body in enumerate(bias_in):
            path = f"faults.actuator_bias[{i}]"
            b = self.mapping(body, path, ("train", "accel_mps2"), ("from_s", "until_s"))
            train = self.trip_name(b["train"], f"{path}.train", services)
            acc = self.number(b["accel_mps2"], f"{path}.accel_mps2")
            frm = self.number(b.get("from_s", 0.0), f"{path}.from_s", ge=0.0)
            until = self.number(b["until_s"], f"{path}.until_s", ge=frm) if "until_s" in b else math.inf
            biases.append(ActuatorBiasSpec(train, acc, frm, until))
            r = {"train": train, "accel_mps2": acc, "from_s": frm}
            if math.isfinite(until):
                r["until_s"] = until
            biases_raw.append(r)
        raw = {
            "comm": comm_raw,
            "sensor_noise": {"position_sd_m": noise.position_sd_m, "speed_sd_mps": noise.speed_sd_mps},
            "actuator_noise": {"accel_sd_mps2": act.accel_sd_mps2,
                               **({"trains": list(noise_trains)} if noise_trains is not None else {})},
        }
        if biases_raw:
            raw["actuator_bias"] = biases_raw
        return FaultSpec(comm=channels, sensor_noise=noise, actuator_noise=act, actuator_bias=tuple(biases)), raw

    def outputs(self, value: Any, sim: SimulationSpec) -> tuple[OutputSpec, dict[str, Any]]:
        m = self.mapping(value, "outputs", (), ("trace_stride_s", "sumo", "formats"))
        stride = self.number(m.get("trace_stride_s", max(1.0, sim.step_s)), "outputs.trace_stride_s", ge=sim.step_s)
        sumo = self.subset(m.get("sumo", []), "outputs.sumo", SUMO_OUTPUTS)
        formats = self.subset(m.get("formats", ["csv"]), "outputs.formats", OUTPUT_FORMATS)
        spec = OutputSpec(trace_stride_s=stride, sumo=tuple(sumo), formats=tuple(formats))
        return spec, {"trace_stride_s": stride, "sumo": sumo, "formats": formats}

    def check_controllers(
        self,
        ctrls: Mapping[str, ControllerSpec],
        services: Sequence[ServiceSpec],
        vehicles: Mapping[str, VehicleParams],
    ) -> None:
        """Types against the registry, parameters by building each controller for the vehicles that use it."""
        import controllers  # noqa: F401  (registers the built-in controllers)
        from controllers import base

        registry = base.registered()
        for name, spec in ctrls.items():
            if spec.type not in registry:
                known = ", ".join(sorted(registry)) or "none registered"
                raise self.fail(
                    f"controllers.{name}.type",
                    f"expected a registered controller type ({known}), got {spec.type!r}{_hint(spec.type, registry)}",
                )
        for name, spec in ctrls.items():
            users = [vehicles[s.vehicle] for s in services if name in s.roles.values()]
            for vehicle in {v.name: v for v in (users or vehicles.values())}.values():
                try:
                    base.create(spec.type, copy.deepcopy(spec.params), vehicle)
                except (ValueError, TypeError) as exc:
                    field_path, message = f"controllers.{name}.params", str(exc) or type(exc).__name__
                    head, sep, rest = message.partition(": ")
                    if sep and re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", head) and rest:
                        field_path, message = f"{field_path}.{head}", rest
                    raise self.fail(field_path, message) from None
