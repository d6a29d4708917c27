"""Validating a whole scenario: the walk over the top-level sections, in dependency order.

:func:`validate` is what :func:`railsim.scenario.from_mapping` runs. It visits the sections in an order
where every section can check its references against what came before::

    name, description
    world, simulation                 (validate_setup)
    vehicles, controllers, roles      (validate_vehicles)
    services                          (validate_services: needs vehicles, controllers, roles, simulation)
    formations                        (validate_formations: needs services)
    events                            (events: needs formations and services)
    cooperative                       (validate_formations)
    faults                            (validate_faults: needs services)
    outputs                           (validate_setup: needs simulation)
    junction                          (validate_formations: needs services and formations)
    rotations                         (validate_rotations: needs services)
    disturbances                      (validate_disturbances: needs services)
    controller parameters             (validate_vehicles.check_controllers, last: reads the registry)

Each section returns ``(spec, raw)``; the specs become the :class:`~railsim.scenario.model.Scenario`, the
raws its ``raw`` mapping (the resolved scenario, written next to every run's outputs). The first error
stops the walk, so the order above is also the order in which a file's problems are reported.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from railsim.scenario import (
    events as event_section,
    validate_disturbances,
    validate_faults,
    validate_formations,
    validate_rotations,
    validate_services,
    validate_setup,
    validate_vehicles,
)
from railsim.scenario.model import Scenario
from railsim.scenario.validate import Checker, require_top_mapping

_TOP_REQUIRED = ("name", "world", "simulation", "vehicles", "controllers", "roles", "services")
_TOP_OPTIONAL = (
    "description",
    "formations",
    "events",
    "faults",
    "outputs",
    "cooperative",
    "junction",
    "rotations",
    "interlocking",
    "disturbances",
)


def validate(data: Any, source: str, base_dir: Path, src_path: Path | None) -> Scenario:
    """Check the parsed mapping ``data`` of file ``source`` and build its :class:`Scenario` (``ConfigError``)."""
    ck = Checker(source, base_dir)
    require_top_mapping(data, ck.source)
    top = ck.mapping(data, "", _TOP_REQUIRED, _TOP_OPTIONAL)
    raw: dict[str, Any] = {}
    name = ck.string(top["name"], "name")
    description = top.get("description")
    description = "" if description is None else description
    if not isinstance(description, str):
        raise ck.expect("description", "a string", description)
    raw["name"], raw["description"] = name, description

    world, raw["world"] = validate_setup.world(ck, top["world"])
    sim, raw["simulation"] = validate_setup.simulation(ck, top["simulation"])
    vehicles, raw["vehicles"], plants = validate_vehicles.vehicles(ck, top["vehicles"])
    ctrls, raw["controllers"] = validate_vehicles.controller_specs(ck, top["controllers"])
    formations_in = top.get("formations") or []
    roles, raw["roles"] = validate_vehicles.roles(ck, top["roles"], ctrls, "roles", need_coupled=bool(formations_in))
    services, raw["services"] = validate_services.services(ck, top["services"], sim, vehicles, ctrls, roles)
    formations, raw["formations"] = validate_formations.formations(ck, formations_in, services)
    events, raw["events"] = event_section.events(ck, top.get("events") or [], formations, services)
    cooperative, coop_raw = validate_formations.cooperative(ck, top.get("cooperative") or {}, services)
    if cooperative.edges:
        raw["cooperative"] = coop_raw
    faults, raw["faults"] = validate_faults.faults(ck, top.get("faults") or {}, services)
    outputs, raw["outputs"] = validate_setup.outputs(ck, top.get("outputs") or {}, sim)
    interlocking, interlocking_raw = validate_setup.interlocking(ck, top.get("interlocking") or {})
    if interlocking_raw:  # only when given: the resolved copy of older scenarios stays as it was
        raw["interlocking"] = interlocking_raw
    junction = None
    if top.get("junction") is not None:
        junction, raw["junction"] = validate_formations.junction(ck, top["junction"], services, formations)
    rotation_spec = None
    if top.get("rotations") is not None:
        rotation_spec, raw["rotations"] = validate_rotations.rotations(ck, top["rotations"], services)
    disturbance_spec = None
    if "disturbances" in top:  # present (even empty): the run accounts for primary and knock-on delays
        disturbance_spec, raw["disturbances"] = validate_disturbances.disturbances(ck, top["disturbances"], services)
    # Last, because it depends on code outside this package (the controller registry).
    validate_vehicles.check_controllers(ck, ctrls, services, vehicles)

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
        plants=plants,
        junction=junction,
        rotations=rotation_spec,
        interlocking=interlocking,
        disturbances=disturbance_spec,
    )
