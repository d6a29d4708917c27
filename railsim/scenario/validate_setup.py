"""Validating the frame of a run: which ``world``, how long and how finely (``simulation``), what to record
(``outputs``).

A world is a shipped world name (optionally ``{name, params}``), a line description file (``{line}``) or a
ready SUMO net (``{net, additional, signals, vclass, throw_time_s}``, see :mod:`network.external`). File
paths resolve against the scenario file's directory and are written to the resolved scenario as absolute
paths, so a resolved copy loads from anywhere. Whether the stations and switches a scenario names exist is
a question for the *built* world: :mod:`railsim.scenario.world`.
"""

from __future__ import annotations

import copy
from typing import Any

from railsim.scenario.model import (
    MAX_OVERLAP_M,
    MAX_SEED,
    MAX_STEP_S,
    MAX_STEPS,
    MIN_STEP_S,
    OUTPUT_FORMATS,
    STEP_METHODS,
    SUMO_OUTPUTS,
    InterlockingSpec,
    OutputSpec,
    SimulationSpec,
    WorldSpec,
)
from railsim.scenario.validate import Checker, short_repr


def world(ck: Checker, value: Any) -> tuple[WorldSpec, Any]:
    """``world:`` → a :class:`WorldSpec`; a net world's defaults come from :mod:`network.external`."""
    what = "a world name or a mapping {name, params} | {line} | {net, additional}"
    if isinstance(value, str):
        return WorldSpec(kind="shipped", name=ck.string(value, "world")), value
    if not isinstance(value, dict):
        raise ck.expect("world", what, value)
    forms = [k for k in ("name", "line", "net") if k in value]
    if len(forms) != 1:
        ck.mapping(value, "world", (), ("name", "params", "line", "net", "additional"))  # unknown keys first
        raise ck.fail("world", f"expected exactly one of name, line, net, got {short_repr(value)}")
    form = forms[0]
    if form == "name":
        m = ck.mapping(value, "world", ("name",), ("params",))
        name = ck.string(m["name"], "world.name")
        params = dict(ck.free_mapping(m.get("params") or {}, "world.params"))
        ck.plausible_tree(params, "world.params")
        return WorldSpec(kind="shipped", name=name, params=params), {"name": name, "params": copy.deepcopy(params)}
    if form == "line":
        m = ck.mapping(value, "world", ("line",))
        line = ck.path_value(m["line"], "world.line")
        return WorldSpec(kind="line", line=line), {"line": str(line)}
    from network.external import DEFAULT_THROW_TIME_S, RAIL_VCLASSES, SIGNAL_MODES
    from network.running_side import RUNNING_SIDES

    m = ck.mapping(
        value,
        "world",
        ("net",),
        ("additional", "signals", "vclass", "throw_time_s", "running_side", "unrestricted_lanes"),
    )
    net = ck.path_value(m["net"], "world.net")
    extra = m.get("additional") or []
    if not isinstance(extra, list):
        raise ck.expect("world.additional", "a list of file paths", extra)
    additional = tuple(ck.path_value(v, f"world.additional[{i}]") for i, v in enumerate(extra))
    signals = ck.string(m.get("signals", "strip"), "world.signals", SIGNAL_MODES)
    vclass = m.get("vclass")
    vclass = None if vclass in (None, "auto") else ck.string(vclass, "world.vclass", RAIL_VCLASSES)
    throw = ck.number(m.get("throw_time_s", DEFAULT_THROW_TIME_S), "world.throw_time_s", ge=0.0)
    side = ck.string(m.get("running_side", "right"), "world.running_side", RUNNING_SIDES)
    open_as = m.get("unrestricted_lanes")
    open_as = None if open_as in (None, "none") else ck.string(open_as, "world.unrestricted_lanes", RAIL_VCLASSES)
    spec = WorldSpec(
        kind="net",
        net=net,
        additional=additional,
        signals=signals,
        vclass=vclass,
        throw_time_s=throw,
        running_side=side,
        unrestricted_lanes=open_as,
    )
    raw: dict[str, Any] = {
        "net": str(net),
        "additional": [str(p) for p in additional],
        "signals": signals,
        "vclass": vclass or "auto",
        "throw_time_s": throw,
    }
    if "running_side" in m:  # written back only when given: the raw of older scenarios stays as it was
        raw["running_side"] = side
    if open_as is not None:
        raw["unrestricted_lanes"] = open_as
    return spec, raw


def simulation(ck: Checker, value: Any) -> tuple[SimulationSpec, dict[str, Any]]:
    """``simulation:`` → a :class:`SimulationSpec`; the raw keeps ``start_time`` as written."""
    m = ck.mapping(value, "simulation", ("step_s", "duration_s"), ("start_time", "seed", "step_method"))
    step_s = ck.number(m["step_s"], "simulation.step_s", gt=0.0, le=MAX_STEP_S)
    if step_s < MIN_STEP_S or abs(step_s * 1000.0 - round(step_s * 1000.0)) > 1e-6:
        what = f"a whole number of milliseconds >= {MIN_STEP_S:g} s (SUMO's time resolution)"
        raise ck.expect("simulation.step_s", what, m["step_s"])
    duration_s = ck.number(m["duration_s"], "simulation.duration_s", gt=0.0)
    if duration_s < step_s:
        raise ck.expect("simulation.duration_s", f"a number >= step_s ({step_s:g}): at least one step", duration_s)
    if duration_s / step_s > MAX_STEPS:
        raise ck.fail(
            "simulation.duration_s",
            f"expected at most {MAX_STEPS:,} steps of {step_s:g} s (duration_s <= {MAX_STEPS * step_s:g} s), "
            f"got {duration_s:g} s",
        )
    start_text = m.get("start_time", "00:00")
    start_s = ck.clock(start_text, "simulation.start_time")
    seed = ck.integer(m.get("seed", 0), "simulation.seed", ge=0, le=MAX_SEED)
    method = ck.string(m.get("step_method", "euler"), "simulation.step_method", STEP_METHODS)
    spec = SimulationSpec(step_s=step_s, duration_s=duration_s, start_time_s=start_s, seed=seed, step_method=method)
    raw = {"step_s": step_s, "duration_s": duration_s, "start_time": start_text, "seed": seed, "step_method": method}
    return spec, raw


def outputs(ck: Checker, value: Any, sim: SimulationSpec) -> tuple[OutputSpec, dict[str, Any]]:
    """``outputs:`` → an :class:`OutputSpec`; the trace stride defaults to ``max(1 s, step_s)``."""
    m = ck.mapping(value, "outputs", (), ("trace_stride_s", "sumo", "formats"))
    stride = ck.number(m.get("trace_stride_s", max(1.0, sim.step_s)), "outputs.trace_stride_s", ge=sim.step_s)
    sumo = ck.subset(m.get("sumo", []), "outputs.sumo", SUMO_OUTPUTS)
    formats = ck.subset(m.get("formats", ["csv"]), "outputs.formats", OUTPUT_FORMATS)
    spec = OutputSpec(trace_stride_s=stride, sumo=tuple(sumo), formats=tuple(formats))
    return spec, {"trace_stride_s": stride, "sumo": sumo, "formats": formats}


def interlocking(ck: Checker, value: Any) -> tuple[InterlockingSpec, dict[str, Any]]:
    """``interlocking:`` → an :class:`InterlockingSpec`; only the keys given (the engine keeps its defaults)."""
    m = ck.mapping(value, "interlocking", (), ("overlap_m", "stall_timeout_s", "platform_berths"))
    raw: dict[str, Any] = {}
    if "overlap_m" in m:
        raw["overlap_m"] = ck.number(m["overlap_m"], "interlocking.overlap_m", ge=0.0, le=MAX_OVERLAP_M)
    if "stall_timeout_s" in m:
        raw["stall_timeout_s"] = ck.number(m["stall_timeout_s"], "interlocking.stall_timeout_s", gt=0.0)
    if "platform_berths" in m:
        raw["platform_berths"] = ck.boolean(m["platform_berths"], "interlocking.platform_berths")
    return InterlockingSpec(**raw), raw
