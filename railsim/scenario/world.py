"""Checks against the built world: do the stations and switches a scenario names exist?

Schema validation (:func:`railsim.scenario.load`) cannot know a world's station ids: building a world runs
netconvert, and an external SUMO net names its stations however its author did. So the world checks are
separate and run once the world is built (``railsim validate`` and the engine do both):

* :func:`check_against_world` — every station id (``from``, ``to``, ``via``, ``skip``, dwell overrides,
  ``at_station`` triggers) and switch id (``before_switch`` triggers) must exist, else a ``ConfigError`` at
  that field with a "did you mean";
* :func:`with_station_ids` — on an external net a station may also go by its name or a stop id (an
  *alias*); this returns the scenario with every alias replaced by the station id, leaving ``raw`` as the
  user wrote it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Collection, Mapping
from typing import Protocol

from railsim.errors import ConfigError
from railsim.scenario.model import Scenario, ServiceSpec, TriggerSpec
from railsim.scenario.validate import did_you_mean


def check_against_world(
    scn: Scenario, stations: Collection[str], switches: Collection[str], aliases: Mapping[str, str] | None = None
) -> None:
    """Check that every station id and switch id the scenario names exists in the built world.

    ``aliases`` (external nets) are other names a station may go by: its name or a stop id -> station id.
    """
    source = str(scn.source) if scn.source is not None else "<scenario>"
    world = scn.world.label
    station_set, switch_set = set(stations), set(switches)
    known = station_set | set(aliases or ())

    def station(value: str, path: str) -> None:
        if value not in known:
            hint = did_you_mean(value, station_set)
            raise ConfigError(source, path, f"expected a station id of world {world!r}, got {value!r}{hint}")

    for i, svc in enumerate(scn.services):
        base = f"services[{i}]"
        station(svc.from_station, f"{base}.from")
        station(svc.to_station, f"{base}.to")
        for st in svc.platforms:
            station(st, f"{base}.platforms.{st}")
        for j, st in enumerate(svc.via):
            station(st, f"{base}.via[{j}]")
        for j, st in enumerate(svc.skip):
            station(st, f"{base}.skip[{j}]")
        for st in svc.dwell_by_station:
            station(st, f"{base}.dwell_s.stations.{st}")
    if scn.rotations is not None:
        for st in scn.rotations.turnback_min_by_station:
            station(st, f"rotations.turnback_min_by_station.{st}")
    for i, fm in enumerate(scn.formations):
        for key, trig in (("couple", fm.couple), ("decouple", fm.decouple)):
            if trig is None:
                continue
            if trig.kind == "at_station":
                station(str(trig.station), f"formations[{i}].{key}.at_station")
            elif trig.kind in ("before_switch", "after_switch") and trig.switch not in switch_set:
                hint = did_you_mean(str(trig.switch), switch_set)
                raise ConfigError(
                    source,
                    f"formations[{i}].{key}.{trig.kind}",
                    f"expected a switch id of world {world!r}, got {trig.switch!r}{hint}",
                )


class NamedStations(Protocol):
    """What :func:`with_station_ids` needs of a world (a ``network.NetworkBundle``)."""

    @property
    def station_aliases(self) -> Mapping[str, str]: ...  # name or stop id -> station id

    @property
    def stop_stations(self) -> Mapping[str, str]: ...  # stop id -> station id


def with_station_ids(scn: Scenario, world: NamedStations) -> Scenario:
    """The scenario with every station it names by an alias (a name or stop id of an external net's station)
    replaced by the station id. ``raw`` keeps what the user wrote (it loads back to the same scenario).

    A stop id in a service's ``from``, ``to`` or ``via`` also *pins* that platform (``ServiceSpec.platforms``), as
    ``{station: X, platform: STOP_ID}`` does."""
    aliases, stops = world.station_aliases, world.stop_stations

    def sid(name: str) -> str:
        return aliases.get(name, name)

    def pins(svc: ServiceSpec) -> dict[str, str]:
        out = {sid(k): v for k, v in svc.platforms.items()}
        for name in (svc.from_station, svc.to_station, *svc.via):
            if name in stops:
                out.setdefault(stops[name], name)
        return out

    def trig(t: TriggerSpec | None) -> TriggerSpec | None:
        return t if t is None or t.station is None else dataclasses.replace(t, station=sid(t.station))

    services = tuple(
        dataclasses.replace(
            svc,
            from_station=sid(svc.from_station),
            to_station=sid(svc.to_station),
            via=tuple(sid(v) for v in svc.via),
            skip=tuple(sid(v) for v in svc.skip),
            dwell_by_station={sid(k): v for k, v in svc.dwell_by_station.items()},
            platforms=pins(svc),
        )
        for svc in scn.services
    )
    formations = tuple(dataclasses.replace(f, couple=trig(f.couple), decouple=trig(f.decouple)) for f in scn.formations)
    return dataclasses.replace(scn, services=services, formations=formations)
