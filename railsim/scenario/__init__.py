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
      step_s: 0.5                         # required, whole milliseconds, 0.001 <= step_s <= 5
      duration_s: 7200                    # required, >= step_s, <= 1e7 steps: simulated seconds after t = 0
      start_time: "07:30"                 # clock time of t = 0, "HH:MM" or "HH:MM:SS"; default "00:00"
      seed: 42                            # int in [0, 2**31 - 1] (SUMO's); default 0
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
      - id: branch                        # departures relative to another service (a list or grid one):
        from: liugongli                   #   trip k leaves at t_i + phase·(t_{i+1} − t_i) + offset_s,
        to: jurenba                       #   i = first_trip + k·every (trips before t = 0 are dropped)
        vehicle: cq6
        departures: {after: {service: airport, every: 4, first_trip: 0, offset_s: 1659.5, phase: 0.0}}
    formations:                           # optional, default []
      - id: pair1
        leader: {service: airport, trip: 0}     # trip = 0-based index into that service's sorted departures
        follower: {service: jurenba, trip: 0}
        target_gap_m: 30                        # > 0, front-to-rear
        couple: {at_station: liugongli}         # or {at_s: 0} or {on_departure: true} or {after_switch: bijin_down}
                                                # (a merge: once the follower is past it behind its leader);
                                                # omitted: only by events
        decouple: {before_switch: bijin_up}     # or {at_s: 3000} or {at_station: bijin}; omitted: never
        coupling_timeout_s: 300                 # > 0; default 300
        depart_together: false                  # true: the coupled pair leaves each station both serve as one
                                                # (the leader waits for its follower's dwell); default false
      - {id: vc, pairs: {leader: airport, follower: branch}, target_gap_m: 30, couple: {on_departure: true}}
                                                # one formation vc0, vc1, ... per branch trip with the airport
                                                # trip it departs after (the follower must be timed `after:` it)
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
    interlocking:                         # optional (docs/model.md, "Interlocking")
      overlap_m: 20                       # >= 0; authority ends this far before what is not reserved; default 20
      stall_timeout_s: 300                # > 0; a train standing this long for no reason stalls the run

Readings and conventions (where the schema alone is ambiguous):

* **Times.** Inside the program every time is seconds from t = 0 (the start of the simulation). In
  ``departures`` a *string* is a clock time ("07:35" or "07:35:30", hours up to 47 for after-midnight
  service) and is converted relative to ``simulation.start_time``; a *number* is already seconds from t = 0.
  A departure before t = 0 is an error; one after ``duration_s`` is only logged (a study may look at the
  first hour of a longer timetable), but a horizon that reaches no departure at all is an error (nothing would
  run).
* **Plausible numbers.** Every number is finite and, by the unit in its field's name, physically plausible
  (:mod:`.plausible`: ``_kmh`` at most 1,000, ``_mps2`` at most 100, ``_m`` at most 1,000 km, ...), free parameter
  blocks (``controllers.*.params``, ``world.params``, ``junction.params``) included; a start speed is at most the
  vehicle's maximum.
* **Headway grids.** ``{first, last, headway_s}`` expands to ``first + k·headway_s`` for every k with the
  result ≤ ``last`` (``last`` is included when it falls on the grid, with a 1 µs tolerance for float
  arithmetic). Departures are sorted; two trips of one service may not depart at the same time.
* **Unquoted clock times.** YAML 1.1 reads ``17:30`` as the base-60 integer 1050; our loader does not, so
  ``start_time: 17:30`` means half past five whether quoted or not. It also reads ``1e3`` and ``1.0e9``
  as numbers (PyYAML would give strings).
* **Vehicles.** A vehicle's :attr:`VehicleParams.name` is its key in ``vehicles`` (two keys may share a
  preset with different overrides). ``max_speed_kmh`` is the only non-SI field accepted (docs/architecture.md: km/h
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

How the package is laid out (one concept per module; dependencies point up the list only)::

    model.py                the frozen spec dataclasses and the schema's vocabulary (no I/O)
    clock.py                "HH:MM[:SS]" <-> seconds after midnight
    plausible.py            physically plausible magnitudes by the unit in a field's name
    validate.py             the Checker: primitive checks, error wording, "did you mean"
    validate_setup.py       world, simulation, outputs
    validate_vehicles.py    vehicles (and plants), controllers, roles, controller parameters
    validate_services.py    services, departures, dwell times; trip references
    validate_formations.py  formations and their triggers, cooperative groups, junction
    events.py               timed events: the table of event kinds (EVENT_KINDS) and the events section
    validate_faults.py      communication channels, sensor/actuator noise and bias
    validate_scenario.py    the walk over all sections -> Scenario
    overrides.py            dotted override paths (with_overrides)
    loading.py              YAML reading (line/column errors, bounded structure: railsim.inputs), load/loads/
                            from_mapping, resolved_yaml
    shipped.py              the scenarios of scenarios/ by name, from any working directory (shipped)
    world.py                checks against the built world (check_against_world, with_station_ids)

Everything the rest of railsim uses is re-exported here, so callers write ``from railsim import scenario``
and ``scenario.load(...)`` regardless of which module defines a name.
"""

from __future__ import annotations

from railsim.scenario.clock import format_clock, parse_clock
from railsim.scenario.events import (
    EVENT_KINDS,
    EVENT_TYPES,
    EventContext,
    EventField,
    EventKind,
    event_kind,
    register_event_kind,
)
from railsim.scenario.loading import from_mapping, load, loads, parse_yaml, read_text, resolved_yaml
from railsim.scenario.model import (
    COMM_CHANNELS,
    DEFAULT_COUPLING_TIMEOUT_S,
    DEFAULT_DWELL_S,
    DELAY_DISTS,
    JUNCTION_METHODS,
    MAX_STEP_S,
    MAX_TRIPS_PER_SERVICE,
    OUTPUT_FORMATS,
    PLANT_KINDS,
    REQUIRED_ROLES,
    ROLES,
    STEP_METHODS,
    SUMO_OUTPUTS,
    ActuatorBiasSpec,
    ActuatorNoiseSpec,
    ChannelSpec,
    ControllerSpec,
    CooperativeEdge,
    CooperativeSpec,
    DelaySpec,
    EventSpec,
    FaultSpec,
    FormationSpec,
    InterlockingSpec,
    JunctionSpec,
    OutageSpec,
    OutputSpec,
    PlantSpec,
    Scenario,
    SensorNoiseSpec,
    ServiceSpec,
    SimulationSpec,
    TriggerSpec,
    TripRef,
    WorldSpec,
)
from railsim.scenario.overrides import OVERRIDE_PATH_RE, with_overrides
from railsim.scenario.shipped import shipped, shipped_names
from railsim.scenario.validate_vehicles import VEHICLE_FIELDS
from railsim.scenario.world import check_against_world, with_station_ids

__all__ = [
    # loading and writing
    "load",
    "loads",
    "from_mapping",
    "resolved_yaml",
    "with_overrides",
    # checks against the built world
    "check_against_world",
    "with_station_ids",
    # clock times
    "parse_clock",
    "format_clock",
    # the model
    "Scenario",
    "WorldSpec",
    "SimulationSpec",
    "ControllerSpec",
    "ServiceSpec",
    "TripRef",
    "TriggerSpec",
    "FormationSpec",
    "EventSpec",
    "PlantSpec",
    "CooperativeEdge",
    "CooperativeSpec",
    "JunctionSpec",
    "DelaySpec",
    "OutageSpec",
    "ChannelSpec",
    "SensorNoiseSpec",
    "ActuatorBiasSpec",
    "ActuatorNoiseSpec",
    "FaultSpec",
    "InterlockingSpec",
    "OutputSpec",
    # the schema's vocabulary
    "ROLES",
    "REQUIRED_ROLES",
    "STEP_METHODS",
    "SUMO_OUTPUTS",
    "OUTPUT_FORMATS",
    "COMM_CHANNELS",
    "DELAY_DISTS",
    "PLANT_KINDS",
    "JUNCTION_METHODS",
    "MAX_STEP_S",
    "MAX_TRIPS_PER_SERVICE",
    "DEFAULT_DWELL_S",
    "DEFAULT_COUPLING_TIMEOUT_S",
    # event kinds
    "EVENT_KINDS",
    "shipped",
    "shipped_names",
    "EVENT_TYPES",
    "EventKind",
    "EventField",
    "EventContext",
    "event_kind",
    "register_event_kind",
    # building blocks of other readers (sweep files read YAML the same way and check override paths)
    "OVERRIDE_PATH_RE",
    "parse_yaml",
    "read_text",
    "VEHICLE_FIELDS",
]
