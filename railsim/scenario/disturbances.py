"""Primary delays: the scenario's ``disturbances:`` section as plain data, and how one delay is drawn.

A *primary* delay is one injected into a single train — a longer dwell because more passengers board, a late
departure from the origin, a driver or ATO running below the traction/speed envelope, an incident holding a
train. What other trains suffer because of it is the *secondary* (knock-on) delay; the engine injects the
primary ones (:mod:`railsim.engine.primary_delays`) and the analysis splits the two
(:mod:`railsim.analysis.punctuality`). These are not the sensor/actuator/radio *faults* of ``faults:``.

The section (every part optional, all zero by default; the validator is
:mod:`railsim.scenario.validate_disturbances`)::

    disturbances:
      intensity: 1.0          # scales every primary delay (0 = none); a sweep path for stability curves
      dwell:                  # dwell extensions: each rule that matches a stop adds one draw to its dwell
        - {stations: [sigongli], from_s: 0, until_s: 3600, prob: 0.5, dist: exponential, mean_s: 15}
        - {dist: lognormal, mean_s: 8, sd_s: 6}                  # every intermediate stop of every trip
        - {dist: empirical, values_s: [0, 10, 30], weights: [0.7, 0.2, 0.1]}
      departure:              # late departures from the origin platform
        - {services: [airport_up], prob: 0.3, dist: exponential, mean_s: 30}
      running_time:           # per-trip performance factor on the traction and speed envelope
        {services: [airport_up], low: 0.95, high: 1.0}           # uniform in [0.5, 1]; 1 = nominal
      incidents:
        - {trip: airport_up.004, station: sigongli, hold_s: 120} # hold one train at one stop
        - {rate_per_h: 2, hold_s: 90, stations: [sigongli], from_s: 0, until_s: 3600}   # Poisson incidents
      demand:                 # passenger-driven dwell: a train that finds more passengers than planned dwells longer
        s_per_passenger: 0.05                                     # extra dwell per extra boarding passenger
        stations: {sigongli: {"07:00": 3600, "08:30": 1800}}      # boarding passengers per hour, from each clock time
        default: {"07:00": 600}                                   # (optional) every other intermediate stop

A rule's ``from_s``/``until_s`` window applies to the planned time of the event it perturbs (the planned
arrival at the stop, the planned departure from the origin). ``prob`` is the chance the rule fires at one
stop/departure (default 1). Distributions (seconds, never negative): ``exponential`` (``mean_s``),
``lognormal`` (``mean_s``, ``sd_s`` of the delay itself), ``empirical`` (``values_s`` with optional
``weights``, drawn as a discrete table), ``constant`` (``value_s``).

**Demand** (:mod:`railsim.engine.passenger_dwell`) is the one primary delay that is not drawn: passengers
arrive at a platform at the table's rate, so a train that reaches it longer after the previous train left
than planned finds more people waiting, ``rate × (actual − planned interval)``, and each extra boarding costs
``s_per_passenger`` (doors in parallel: a whole-train figure). A late train is made later by its own lateness —
the mechanism that bunches metro services. A train closer than planned behind its leader keeps its planned dwell
(never shorter). The rate table is by clock time on the scenario's clock (``simulation.start_time``); each rate
holds from its time until the next one, and before the first there is no demand.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

DWELL_DISTS: dict[str, tuple[str, ...]] = {
    "constant": ("value_s",),
    "exponential": ("mean_s",),
    "lognormal": ("mean_s", "sd_s"),
    "empirical": ("values_s",),  # + optional weights
}


@dataclass(frozen=True)
class DelayDist:
    """A delay distribution in seconds (see :data:`DWELL_DISTS`)."""

    dist: str = "constant"
    value_s: float = 0.0
    mean_s: float = 0.0
    sd_s: float = 0.0
    values_s: tuple[float, ...] = ()
    weights: tuple[float, ...] = ()  # empirical: normalised; empty = equally likely

    def draw(self, rng: np.random.Generator) -> float:
        """One delay [s] ≥ 0. Every call draws exactly one uniform variate (so streams stay aligned)."""
        u = float(rng.random())
        if self.dist == "constant":
            return self.value_s
        if self.dist == "exponential":
            return -self.mean_s * math.log1p(-u)
        if self.dist == "lognormal":
            if self.mean_s <= 0.0:
                return 0.0
            sigma2 = math.log1p((self.sd_s / self.mean_s) ** 2)
            z = _normal_ppf(u)
            return math.exp(math.log(self.mean_s) - sigma2 / 2.0 + math.sqrt(sigma2) * z)
        if self.dist == "empirical":
            cum = np.cumsum(self.weights) if self.weights else np.arange(1, len(self.values_s) + 1) / len(self.values_s)
            k = int(np.searchsorted(cum, u * float(cum[-1]), side="right"))
            return self.values_s[min(k, len(self.values_s) - 1)]
        raise ValueError(f"unknown delay distribution {self.dist!r}")


def _normal_ppf(u: float) -> float:
    """The standard normal quantile of ``u`` (inverse transform: one uniform variate per draw)."""
    from scipy.special import ndtri

    return float(ndtri(min(max(u, 1e-300), 1.0 - 1e-16)))


@dataclass(frozen=True)
class DelayRule:
    """Where and when a delay distribution applies: stations (dwell) or services (departure), a time window
    on the planned time, and the chance ``prob`` it fires. Empty tuples mean every station/service."""

    delay: DelayDist
    stations: tuple[str, ...] = ()
    services: tuple[str, ...] = ()
    from_s: float = 0.0
    until_s: float = math.inf
    prob: float = 1.0

    def matches(self, service_id: str, station_id: str | None, planned_s: float) -> bool:
        """Does the rule apply to this service at this station at this planned time?"""
        if self.services and service_id not in self.services:
            return False
        if station_id is not None and self.stations and station_id not in self.stations:
            return False
        return self.from_s <= planned_s < self.until_s


@dataclass(frozen=True)
class PerformanceSpec:
    """A per-trip performance factor, uniform on ``[low, high]`` (0.5 ≤ low ≤ high ≤ 1), for ``services`` (empty = all)."""

    low: float = 1.0
    high: float = 1.0
    services: tuple[str, ...] = ()


@dataclass(frozen=True)
class IncidentSpec:
    """One train held ``hold_s`` at one stop (``trip`` + ``station``), or Poisson incidents at ``rate_per_h``
    over ``[from_s, until_s)``, each holding the first train planned to leave one of ``stations`` (empty =
    any intermediate stop) after the incident time."""

    hold_s: float
    trip: str | None = None
    station: str | None = None
    rate_per_h: float = 0.0
    stations: tuple[str, ...] = ()
    from_s: float = 0.0
    until_s: float = math.inf


@dataclass(frozen=True)
class DemandSpec:
    """Passenger-driven dwell (module docstring): ``rates`` per station as ``(clock time after midnight [s],
    boarding passengers per hour)`` steps in time order; ``default`` for the stations not listed."""

    s_per_passenger: float
    rates: tuple[tuple[str, tuple[tuple[float, float], ...]], ...] = ()
    default: tuple[tuple[float, float], ...] = ()

    def rate_per_h(self, station_id: str, clock_s: float) -> float:
        """Boarding passengers per hour at ``station_id`` at clock time ``clock_s`` (seconds after midnight)."""
        steps = next((st for sid, st in self.rates if sid == station_id), self.default)
        rate = 0.0
        for from_clock_s, value in steps:
            if clock_s < from_clock_s:
                break
            rate = value
        return rate


@dataclass(frozen=True)
class DisturbanceSpec:
    """The ``disturbances:`` section (module docstring). The default injects nothing."""

    intensity: float = 1.0
    dwell: tuple[DelayRule, ...] = ()
    departure: tuple[DelayRule, ...] = ()
    running_time: PerformanceSpec = field(default_factory=PerformanceSpec)
    incidents: tuple[IncidentSpec, ...] = ()
    demand: DemandSpec | None = None

    def station_ids(self) -> list[tuple[str, str]]:
        """Every station the section names, with its field path (checked against the world at set-up)."""
        out = []
        for k, r in enumerate(self.dwell):
            out += [(s, f"disturbances.dwell[{k}].stations") for s in r.stations]
        for k, inc in enumerate(self.incidents):
            if inc.station is not None:
                out.append((inc.station, f"disturbances.incidents[{k}].station"))
            out += [(s, f"disturbances.incidents[{k}].stations") for s in inc.stations]
        if self.demand is not None:
            out += [(sid, f"disturbances.demand.stations.{sid}") for sid, _ in self.demand.rates]
        return out
