"""Validating ``faults``: what goes wrong on purpose — communication, sensors, actuators.

* ``faults.comm.<channel>`` for every channel of :data:`COMM_CHANNELS` (``t2t`` train-to-train, ``t2g``
  train-to-ground): a message delay distribution (:class:`DelaySpec`, seconds; its parameters per
  :data:`DELAY_DISTS`), an independent loss probability and outage windows. An outage names trains by trip
  id or by service id (all its trips); the spec holds the expanded trip ids, or ``None`` for every train.
* ``faults.sensor_noise``: Gaussian noise on the train's own odometry.
* ``faults.actuator_noise`` / ``faults.actuator_bias``: Gaussian noise on, or a constant error added to,
  every applied acceleration command (Papers A and D).

The resolved raw mapping always lists every channel and every noise field, defaults filled in, so a
``scenario.resolved.yaml`` shows exactly which faults a run had.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from railsim.scenario.model import (
    COMM_CHANNELS,
    DELAY_DISTS,
    ActuatorBiasSpec,
    ActuatorNoiseSpec,
    ChannelSpec,
    DelaySpec,
    FaultSpec,
    OutageSpec,
    SensorNoiseSpec,
    ServiceSpec,
)
from railsim.scenario.validate import Checker, did_you_mean
from railsim.scenario.validate_services import trip_name

_NO_DELAY = {"dist": "constant", "value": 0.0}


def faults(ck: Checker, value: Any, services: Sequence[ServiceSpec]) -> tuple[FaultSpec, dict[str, Any]]:
    """``faults:`` (every part optional) → a :class:`FaultSpec` and its fully written-out raw mapping."""
    m = ck.mapping(value, "faults", (), ("comm", "sensor_noise", "actuator_noise", "actuator_bias"))
    comm_in = ck.mapping(m.get("comm") or {}, "faults.comm", (), COMM_CHANNELS)
    channels: dict[str, ChannelSpec] = {}
    comm_raw: dict[str, Any] = {}
    for name in COMM_CHANNELS:
        channels[name], comm_raw[name] = channel(ck, comm_in.get(name) or {}, f"faults.comm.{name}", services)
    noise_in = ck.mapping(m.get("sensor_noise") or {}, "faults.sensor_noise", (), ("position_sd_m", "speed_sd_mps"))
    noise = SensorNoiseSpec(
        position_sd_m=ck.number(noise_in.get("position_sd_m", 0.0), "faults.sensor_noise.position_sd_m", ge=0.0),
        speed_sd_mps=ck.number(noise_in.get("speed_sd_mps", 0.0), "faults.sensor_noise.speed_sd_mps", ge=0.0),
    )
    act_in = ck.mapping(m.get("actuator_noise") or {}, "faults.actuator_noise", (), ("accel_sd_mps2", "trains"))
    noise_trains = None
    if "trains" in act_in:
        if not isinstance(act_in["trains"], list):
            raise ck.expect("faults.actuator_noise.trains", "a list of trains", act_in["trains"])
        noise_trains = tuple(
            trip_name(ck, x, f"faults.actuator_noise.trains[{i}]", services) for i, x in enumerate(act_in["trains"])
        )
    act = ActuatorNoiseSpec(
        accel_sd_mps2=ck.number(act_in.get("accel_sd_mps2", 0.0), "faults.actuator_noise.accel_sd_mps2", ge=0.0),
        trains=noise_trains,
    )
    biases, biases_raw = actuator_biases(ck, m.get("actuator_bias") or [], services)
    raw = {
        "comm": comm_raw,
        "sensor_noise": {"position_sd_m": noise.position_sd_m, "speed_sd_mps": noise.speed_sd_mps},
        "actuator_noise": {
            "accel_sd_mps2": act.accel_sd_mps2,
            **({"trains": list(noise_trains)} if noise_trains is not None else {}),
        },
    }
    if biases_raw:
        raw["actuator_bias"] = biases_raw  # type: ignore[assignment]
    return FaultSpec(comm=channels, sensor_noise=noise, actuator_noise=act, actuator_bias=biases), raw


def channel(ck: Checker, value: Any, path: str, services: Sequence[ServiceSpec]) -> tuple[ChannelSpec, dict[str, Any]]:
    """One communication channel ``{delay_s, loss_prob, outages}`` (all optional: a perfect channel)."""
    ch = ck.mapping(value, path, (), ("delay_s", "loss_prob", "outages"))
    delay_spec, delay_raw = delay(ck, ch.get("delay_s", _NO_DELAY), f"{path}.delay_s")
    loss = ck.number(ch.get("loss_prob", 0.0), f"{path}.loss_prob", ge=0.0, le=1.0)
    outages_in = ch.get("outages") or []
    if not isinstance(outages_in, list):
        raise ck.expect(f"{path}.outages", "a list of {start_s, end_s, trains}", outages_in)
    service_trips = {s.id: s.trip_ids for s in services}
    outages: list[OutageSpec] = []
    outages_raw: list[Any] = []
    for j, body in enumerate(outages_in):
        spec, raw = outage(ck, body, f"{path}.outages[{j}]", service_trips)
        outages.append(spec)
        outages_raw.append(raw)
    return ChannelSpec(delay_spec, loss, tuple(outages)), {
        "delay_s": delay_raw,
        "loss_prob": loss,
        "outages": outages_raw,
    }


def outage(
    ck: Checker, value: Any, path: str, service_trips: Mapping[str, tuple[str, ...]]
) -> tuple[OutageSpec, dict[str, Any]]:
    """``{start_s, end_s, trains}``: ``trains`` (trip or service ids) expand to trip ids; absent = every train."""
    om = ck.mapping(value, path, ("start_s", "end_s"), ("trains",))
    start = ck.number(om["start_s"], f"{path}.start_s", ge=0.0)
    end = ck.number(om["end_s"], f"{path}.end_s", gt=start)
    raw: dict[str, Any] = {"start_s": start, "end_s": end}
    if om.get("trains") is None:
        return OutageSpec(start, end, None), raw
    trips = {t for ids in service_trips.values() for t in ids}
    names = ck.string_list(om["trains"], f"{path}.trains")
    expanded: list[str] = []
    for k, t in enumerate(names):
        if t in service_trips:
            expanded.extend(service_trips[t])
        elif t in trips:
            expanded.append(t)
        else:
            raise ck.fail(
                f"{path}.trains[{k}]",
                f"expected a trip id (like {next(iter(sorted(trips)))!r}) or a service id, "
                f"got {t!r}{did_you_mean(t, list(trips) + list(service_trips))}",
            )
    raw["trains"] = names
    return OutageSpec(start, end, tuple(dict.fromkeys(expanded))), raw


def delay(ck: Checker, value: Any, path: str) -> tuple[DelaySpec, dict[str, Any]]:
    """``{dist: <name>, <its parameters>}`` → a :class:`DelaySpec` (seconds; means of lognormal/exponential > 0)."""
    if not isinstance(value, dict):
        raise ck.expect(path, "a mapping {dist: ..., <parameters>}", value)
    if "dist" not in value:
        raise ck.fail(f"{path}.dist", "missing required key")
    dist = ck.string(value["dist"], f"{path}.dist", tuple(DELAY_DISTS))
    names = DELAY_DISTS[dist]
    m = ck.mapping(value, path, ("dist", *names))
    p = {k: m[k] for k in names}
    if dist == "constant":
        params = {"value": ck.number(p["value"], f"{path}.value", ge=0.0)}
    elif dist == "uniform":
        low = ck.number(p["low"], f"{path}.low", ge=0.0)
        params = {"low": low, "high": ck.number(p["high"], f"{path}.high", ge=low)}
    elif dist == "normal":
        mean = ck.number(p["mean"], f"{path}.mean", ge=0.0)
        params = {"mean": mean, "sd": ck.number(p["sd"], f"{path}.sd", ge=0.0)}
    elif dist == "lognormal":
        mean = ck.number(p["mean"], f"{path}.mean", gt=0.0)
        params = {"mean": mean, "sd": ck.number(p["sd"], f"{path}.sd", ge=0.0)}
    else:
        params = {"mean": ck.number(p["mean"], f"{path}.mean", gt=0.0)}
    return DelaySpec(dist, params), {"dist": dist, **params}


def actuator_biases(
    ck: Checker, value: Any, services: Sequence[ServiceSpec]
) -> tuple[tuple[ActuatorBiasSpec, ...], list[Any]]:
    """``faults.actuator_bias: [{train, accel_mps2, from_s, until_s}]`` (raw ``until_s`` only when finite)."""
    if not isinstance(value, list):
        raise ck.expect("faults.actuator_bias", "a list of {train, accel_mps2, from_s, until_s}", value)
    biases: list[ActuatorBiasSpec] = []
    raws: list[Any] = []
    for i, body in enumerate(value):
        path = f"faults.actuator_bias[{i}]"
        b = ck.mapping(body, path, ("train", "accel_mps2"), ("from_s", "until_s"))
        train = trip_name(ck, b["train"], f"{path}.train", services)
        acc = ck.number(b["accel_mps2"], f"{path}.accel_mps2")
        frm, until = ck.window(b, path)
        biases.append(ActuatorBiasSpec(train, acc, frm, until))
        r = {"train": train, "accel_mps2": acc, "from_s": frm}
        if math.isfinite(until):
            r["until_s"] = until
        raws.append(r)
    return tuple(biases), raws
