"""Validating who drives what: ``vehicles`` (with their plants), ``controllers`` and ``roles``.

A vehicle is a :class:`railsim.physics.vehicle.VehicleParams` named by its key in ``vehicles``: either a
shipped preset with field overrides (``{preset: cq3_6car, mass_kg: 271000}``) or every field spelled out —
no silent defaults borrowed from another train. ``max_speed_kmh`` is the one non-SI key (km/h only at the
YAML edge). An optional ``plant`` selects the train model the engine integrates (:data:`PLANT_KINDS`).

Controllers are named instances of registered controller types; ``roles`` maps each role of
:data:`ROLES` to an instance. :func:`check_controllers` runs last in a scenario's validation: it reads the
controller registry (so controllers registered after import are found) and builds every instance once for
every vehicle that uses it, turning a factory's ``ValueError("margin_m: ...")`` into an error at
``controllers.<name>.params.margin_m``.
"""

from __future__ import annotations

import copy
import dataclasses
import re
from collections.abc import Mapping, Sequence
from typing import Any

from railsim.physics.vehicle import VehicleParams, preset, preset_names
from railsim.scenario.model import PLANT_KINDS, REQUIRED_ROLES, ROLES, ControllerSpec, PlantSpec, ServiceSpec
from railsim.scenario.validate import Checker, did_you_mean, field_type_name, short_repr

# VehicleParams' fields a scenario may set, and the type of each ("float", "int", "str")
VEHICLE_FIELDS = {f.name: field_type_name(f) for f in dataclasses.fields(VehicleParams) if f.name != "name"}
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


def vehicles(ck: Checker, value: Any) -> tuple[dict[str, VehicleParams], dict[str, Any], dict[str, PlantSpec]]:
    """``vehicles:`` → (name -> :class:`VehicleParams`, resolved raw, name -> non-default :class:`PlantSpec`)."""
    m = ck.free_mapping(value, "vehicles", what="a mapping of vehicle name -> vehicle")
    if not m:
        raise ck.expect("vehicles", "at least one vehicle", value)
    specs: dict[str, VehicleParams] = {}
    raws: dict[str, Any] = {}
    plants: dict[str, PlantSpec] = {}
    for key, body in m.items():
        specs[key], raws[key], plant = vehicle(ck, key, body, f"vehicles.{key}")
        if plant is not None:
            plants[key] = plant
    return specs, raws, plants


def vehicle(ck: Checker, key: str, body: Any, path: str) -> tuple[VehicleParams, dict[str, Any], PlantSpec | None]:
    """One vehicle: a preset with field overrides, or every :class:`VehicleParams` field; and its plant."""
    fields = list(VEHICLE_FIELDS)
    if isinstance(body, dict) and "name" in body:
        raise ck.fail(f"{path}.name", "unknown key (a vehicle is named by its key in 'vehicles')")
    body = ck.mapping(body, path, (), ["preset", "max_speed_kmh", "plant", "plant_params", *fields])
    plant = vehicle_plant(ck, body, path)
    body = {k: v for k, v in body.items() if k not in ("plant", "plant_params")}
    if "max_speed_kmh" in body and "max_speed_mps" in body:
        raise ck.fail(f"{path}.max_speed_kmh", "expected either max_speed_kmh or max_speed_mps, got both")
    values: dict[str, Any] = {}
    preset_name = body.get("preset")
    if preset_name is not None:
        names = preset_names()
        if not isinstance(preset_name, str) or preset_name not in names:
            hint = did_you_mean(preset_name, names) if isinstance(preset_name, str) else ""
            raise ck.fail(
                f"{path}.preset", f"expected a vehicle preset ({', '.join(names)}), got {short_repr(preset_name)}{hint}"
            )
        base = preset(preset_name)
        # Presets are our data, but coerce anyway: PyYAML reads "1.0e9" as a string.
        for fname, ftype in VEHICLE_FIELDS.items():
            v = getattr(base, fname)
            values[fname] = int(v) if ftype == "int" else float(v) if ftype == "float" else v
    else:
        missing = [f for f in fields if f not in body and not (f == "max_speed_mps" and "max_speed_kmh" in body)]
        if missing:
            raise ck.fail(
                f"{path}.{missing[0]}",
                "missing required key (a vehicle without preset needs every field: " + ", ".join(missing) + ")",
            )
    for fname, v in body.items():
        if fname == "preset":
            continue
        fpath = f"{path}.{fname}"
        if fname == "max_speed_kmh":
            values["max_speed_mps"] = ck.number(v, fpath, gt=0.0) / _KMH_PER_MPS
            continue
        kind, bound = _VEHICLE_BOUNDS.get(fname, ("", 0.0))
        ftype = VEHICLE_FIELDS[fname]
        if ftype == "int":
            values[fname] = ck.integer(v, fpath, ge=int(bound) if kind == "ge" else None)
        elif ftype == "float":
            gt, ge = (bound, None) if kind == "gt" else (None, bound) if kind == "ge" else (None, None)
            values[fname] = ck.number(v, fpath, gt=gt, ge=ge)
        else:
            values[fname] = ck.string(v, fpath)
    if values["emergency_decel_mps2"] < values["service_decel_mps2"]:
        raise ck.fail(
            f"{path}.emergency_decel_mps2",
            f"expected a number >= service_decel_mps2 ({values['service_decel_mps2']}), "
            f"got {values['emergency_decel_mps2']}",
        )
    raw: dict[str, Any] = {"preset": preset_name} if preset_name is not None else {}
    raw.update({f: values[f] for f in fields})
    if plant is not None:
        raw["plant"] = plant.kind
        raw["plant_params"] = dict(plant.params)
    return VehicleParams(name=key, **values), raw, plant


def vehicle_plant(ck: Checker, body: Mapping[str, Any], path: str) -> PlantSpec | None:
    """``plant: multipoint`` (+ ``plant_params`` overriding :class:`railsim.physics.multipoint.MultipointParams`, and
    ``wind``: Paper B's Scenario C disturbance, see :func:`_plant_wind`)."""
    if "plant" not in body and "plant_params" not in body:
        return None
    kind = ck.string(body.get("plant", "single"), f"{path}.plant", PLANT_KINDS)
    params_in = body.get("plant_params") or {}
    if kind == "single":
        if params_in:
            raise ck.fail(f"{path}.plant_params", "only a multipoint plant takes plant_params")
        return None
    if kind == "multipoint":
        from railsim.physics.multipoint import MultipointParams as plant_cls
    else:
        from railsim.physics.monorail import MonorailParams as plant_cls  # type: ignore[assignment]

    fields_ = {f.name: field_type_name(f) for f in dataclasses.fields(plant_cls)}
    extra = ("wind",) if kind == "multipoint" else ()
    m = dict(ck.mapping(params_in, f"{path}.plant_params", (), (*fields_, *extra)))
    params: dict[str, Any] = {}
    if "wind" in m:
        params["wind"] = _plant_wind(ck, m.pop("wind"), f"{path}.plant_params.wind")
    for name, v in m.items():
        ftype = fields_[name]
        if name == "n_cars":
            params[name] = ck.integer(v, f"{path}.plant_params.{name}", ge=1)
        elif ftype == "str":
            params[name] = ck.string(v, f"{path}.plant_params.{name}")
        else:
            params[name] = ck.number(v, f"{path}.plant_params.{name}")
    try:
        plant_cls(**{k: v for k, v in params.items() if k != "wind"})
    except (ValueError, TypeError) as exc:
        raise ck.fail(f"{path}.plant_params", str(exc)) from None
    return PlantSpec(kind, params)


def _plant_wind(ck: Checker, value: Any, path: str) -> dict[str, Any]:
    """``plant_params.wind`` of a multipoint plant: Paper B Scenario C's disturbance acting on the plant only
    (:class:`railsim.physics.multipoint.WindDisturbance`: ``kind`` none|constant|harmonic, ``constant``,
    ``offset``, ``amplitude``, ``omega_rad_per_s``, ``unit`` mps2|n_per_kn, ``onset_s``)."""
    from railsim.physics.multipoint import WindDisturbance

    names = tuple(f.name for f in dataclasses.fields(WindDisturbance))
    m = ck.mapping(value, path, (), names)
    wind: dict[str, Any] = {}
    for name, v in m.items():
        wind[name] = ck.string(v, f"{path}.{name}") if name in ("kind", "unit") else ck.number(v, f"{path}.{name}")
    try:
        WindDisturbance(**wind)
    except (ValueError, TypeError) as exc:
        raise ck.fail(path, str(exc)) from None
    return wind


def controller_specs(ck: Checker, value: Any) -> tuple[dict[str, ControllerSpec], dict[str, Any]]:
    """``controllers:`` → instance name -> :class:`ControllerSpec` (types and parameters checked later, by
    :func:`check_controllers`)."""
    m = ck.free_mapping(value, "controllers", what="a mapping of instance name -> {type, params}")
    if not m:
        raise ck.expect("controllers", "at least one controller", value)
    specs: dict[str, ControllerSpec] = {}
    raws: dict[str, Any] = {}
    for key, body in m.items():
        path = f"controllers.{key}"
        body = ck.mapping(body, path, ("type",), ("params",))
        ctype = ck.string(body["type"], f"{path}.type")
        params = dict(ck.free_mapping(body.get("params") or {}, f"{path}.params"))
        specs[key] = ControllerSpec(type=ctype, params=params)
        raws[key] = {"type": ctype, "params": copy.deepcopy(params)}
    return specs, raws


def roles(
    ck: Checker,
    value: Any,
    ctrls: Mapping[str, ControllerSpec],
    path: str,
    need_coupled: bool = False,
    required: bool = True,
) -> tuple[dict[str, str], dict[str, str]]:
    """``roles:`` (or a service's overrides, ``required=False``) → role -> controller instance name."""
    if required:
        m = ck.mapping(value, path, REQUIRED_ROLES, [r for r in ROLES if r not in REQUIRED_ROLES])
    else:  # per-service overrides: every role optional
        m = ck.mapping(value, path, (), ROLES)
    if need_coupled and "coupled" not in m:
        raise ck.fail(f"{path}.coupled", "missing required key (the scenario has formations)")
    out: dict[str, str] = {}
    for role, inst in m.items():
        if not isinstance(inst, str) or inst not in ctrls:
            hint = did_you_mean(inst, ctrls) if isinstance(inst, str) else ""
            raise ck.fail(
                f"{path}.{role}", f"expected a controller instance ({', '.join(ctrls)}), got {short_repr(inst)}{hint}"
            )
        out[role] = inst
    return out, dict(out)


def check_controllers(
    ck: Checker,
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
            hint = did_you_mean(spec.type, registry)
            raise ck.fail(
                f"controllers.{name}.type", f"expected a registered controller type ({known}), got {spec.type!r}{hint}"
            )
    for name, spec in ctrls.items():
        ck.plausible_tree(spec.params, f"controllers.{name}.params")
        users = [vehicles[s.vehicle] for s in services if name in s.roles.values()]
        for params in {v.name: v for v in (users or vehicles.values())}.values():
            try:
                base.create(spec.type, copy.deepcopy(spec.params), params)
            except (ValueError, TypeError) as exc:
                field_path, message = f"controllers.{name}.params", str(exc) or type(exc).__name__
                head, sep, rest = message.partition(": ")
                if sep and re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", head) and rest:
                    field_path, message = f"{field_path}.{head}", rest
                raise ck.fail(field_path, message) from None
