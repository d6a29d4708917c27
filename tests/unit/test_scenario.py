"""Scenario loading and validation (railsim.scenario), in-process.

The command-line face (``railsim validate`` on the broken files) is in test_scenario_cli.py. Controllers used
here are the test-only ``_test_ctrl`` / ``_test_follow`` of tests/data/plugins, so these tests do not depend
on the real controller library.
"""

from __future__ import annotations

import copy
import math
import sys
import uuid
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from hypothesis import given, settings, strategies as st

HERE = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(HERE / "data" / "plugins"))
import railsim_test_controllers  # noqa: E402,F401  (registers _test_ctrl, _test_follow)

from controllers.base import Command, register  # noqa: E402
from railsim import scenario as S  # noqa: E402
from railsim.errors import ConfigError  # noqa: E402
from railsim.physics.vehicle import preset  # noqa: E402

VALID = HERE / "data" / "scenario" / "valid.yaml"

# A small valid scenario as a mapping; tests derive variants with with_overrides.
BASE: dict[str, Any] = {
    "name": "base",
    "world": "straight_corridor",
    "simulation": {"step_s": 0.5, "duration_s": 3600},
    "vehicles": {"cq6": {"preset": "cq3_6car"}},
    "controllers": {"drive": {"type": "_test_ctrl"}, "keep": {"type": "_test_follow", "params": {"margin_m": 50}}},
    "roles": {"ato": "drive", "separation": "keep", "coupled": "keep"},
    "services": [
        {
            "id": "a",
            "from": "s0",
            "to": "s9",
            "vehicle": "cq6",
            "departures": {"first": 0, "last": 600, "headway_s": 300},
        },
        {"id": "b", "from": "s0", "to": "s5", "vehicle": "cq6", "departures": {"times": [60, 420]}},
    ],
}


def build(overrides: dict[str, Any] | None = None, base: dict[str, Any] | None = None) -> S.Scenario:
    data = S.with_overrides(base or BASE, overrides or {})
    return S.from_mapping(data, source="base.yaml")


def error_of(overrides: dict[str, Any], base: dict[str, Any] | None = None) -> str:
    with pytest.raises(ConfigError) as info:
        build(overrides, base)
    return str(info.value)


# ---- the valid example ------------------------------------------------------------------------------------------


def test_valid_example_loads() -> None:
    scn = S.load(VALID)
    assert scn.name == "cq3_peak_test"
    assert scn.source == VALID
    assert scn.world == S.WorldSpec(kind="shipped", name="chongqing_line3")
    # start_time is written unquoted (07:30): it must be the clock time, not a YAML 1.1 base-60 integer.
    assert scn.simulation.start_time_s == 7.5 * 3600
    assert scn.simulation.step_method == "ballistic" and scn.simulation.seed == 42

    heavy, base = scn.vehicles["cq6_heavy"], preset("cq3_6car")
    assert heavy.name == "cq6_heavy" and heavy.mass_kg == 271000.0
    assert heavy.max_speed_mps == pytest.approx(72 / 3.6)
    assert heavy.length_m == base.length_m and heavy.davis_c_n_per_mps2 == base.davis_c_n_per_mps2
    assert scn.vehicles["cq6"] == base.with_overrides(name="cq6")

    airport, jurenba = scn.services
    # first 07:30, last 09:30 (= t 7200, on the grid, so included), headway 150 s
    assert airport.departures_s == tuple(150.0 * k for k in range(7200 // 150 + 1))
    assert airport.trip_ids[:2] == ("airport.000", "airport.001") and len(airport.trip_ids) == 49
    assert airport.dwell_s("lianglukou") == 45.0 and airport.dwell_s("bijin") == 30.0
    assert airport.via == ("bijin",) and airport.skip == ("jinzhu",)
    # times: "07:36:30", "07:31" (clock, relative to 07:30), 1200.0 and 1e3 (seconds from t=0) -> sorted
    assert jurenba.departures_s == (60.0, 390.0, 1000.0, 1200.0)
    assert jurenba.dwell_default_s == 25.0 and jurenba.dwell_by_station == {}
    # per-service role override merged over the scenario roles
    assert airport.roles == {"ato": "drive", "separation": "sep", "coupled": "vc"}
    assert jurenba.roles == {"ato": "drive", "separation": "vc", "coupled": "vc"}

    pair1, pair2 = scn.formations
    assert scn.trip_id(pair1.leader) == "airport.000" and scn.trip_id(pair1.follower) == "jurenba.000"
    assert pair1.couple == S.TriggerSpec("at_station", station="liugongli")
    assert pair1.decouple == S.TriggerSpec("before_switch", switch="bijin_up")
    assert pair2.couple == S.TriggerSpec("on_departure") and pair2.decouple is None
    assert pair2.coupling_timeout_s == S.DEFAULT_COUPLING_TIMEOUT_S
    assert scn.events == (S.EventSpec(600.0, "couple", "pair1"), S.EventSpec(3000.0, "decouple", "pair2"))

    t2t, t2g = scn.faults.comm["t2t"], scn.faults.comm["t2g"]
    assert t2t.delay == S.DelaySpec("lognormal", {"mean": 0.2, "sd": 0.05}) and t2t.loss_prob == 0.01
    # a service id in an outage expands to all its trips
    assert t2t.outages == (S.OutageSpec(100.0, 130.0, ("airport.002",) + jurenba.trip_ids),)
    assert t2g == S.ChannelSpec()  # defaults: constant 0 s delay, no loss, no outages
    assert scn.faults.sensor_noise == S.SensorNoiseSpec(position_sd_m=0.5, speed_sd_mps=0.0)
    assert scn.outputs == S.OutputSpec(trace_stride_s=1.0, sumo=("tripinfo", "fcd"), formats=("csv", "parquet"))
    assert scn.n_trips == 49 + 4


def test_defaults_are_filled_in() -> None:
    scn = build()
    assert scn.description == ""
    assert scn.simulation == S.SimulationSpec(
        step_s=0.5, duration_s=3600.0, start_time_s=0.0, seed=0, step_method="euler"
    )
    assert scn.faults == S.FaultSpec()
    assert set(scn.faults.comm) == {"t2t", "t2g"}
    assert scn.outputs == S.OutputSpec(trace_stride_s=1.0, sumo=(), formats=("csv",))
    assert scn.formations == () and scn.events == ()
    assert all(s.dwell_default_s == S.DEFAULT_DWELL_S for s in scn.services)
    # a coarse step raises the default trace stride to the step
    assert build({"simulation.step_s": 2.0}).outputs.trace_stride_s == 2.0


# ---- departures ------------------------------------------------------------------------------------------------


@settings(max_examples=150, deadline=None)
@given(
    first=st.integers(0, 20000),
    headway=st.floats(1.0, 900.0, allow_nan=False),
    n=st.integers(0, 60),
    frac=st.floats(0.0, 0.999),
)
def test_headway_grid_expansion(first: int, headway: float, n: int, frac: float) -> None:
    last = first + (n + frac) * headway
    svc = build({"services[0].departures": {"first": first, "last": last, "headway_s": headway}}).services[0]
    deps = svc.departures_s
    assert len(deps) == n + 1 and deps[0] == first
    assert np.allclose(np.diff(deps), headway)
    assert deps[-1] <= last + 1e-6 < deps[-1] + headway
    assert svc.trip_ids == tuple(f"a.{k:03d}" for k in range(n + 1))


def test_last_on_the_grid_is_included_despite_float_rounding() -> None:
    # 0.1 * 3 != 0.3 in floats; the last departure must still be there
    svc = build({"services[0].departures": {"first": 0.0, "last": 0.3, "headway_s": 0.1}}).services[0]
    assert len(svc.departures_s) == 4


def test_clock_strings_are_relative_to_start_time() -> None:
    scn = build(
        {
            "simulation.start_time": "06:59:30",
            "services[0].departures": {"first": "07:00", "last": "07:10", "headway_s": 300},
            "services[1].departures": {"times": ["07:01:15.5", 10, "06:59:30"]},
        }
    )
    assert scn.services[0].departures_s == (30.0, 330.0, 630.0)
    assert scn.services[1].departures_s == (0.0, 10.0, 105.5)


def test_more_than_a_thousand_trips_keep_ids_sortable() -> None:
    svc = build(
        {"simulation.step_s": 0.1, "services[0].departures": {"first": 0, "last": 1000, "headway_s": 1}}
    ).services[0]
    assert svc.trip_ids[0] == "a.0000" and svc.trip_ids[-1] == "a.1000"
    assert list(svc.trip_ids) == sorted(svc.trip_ids)


@pytest.mark.parametrize(
    "departures, message",
    [
        (
            {"times": [60, 120, 60.0]},
            "services[1].departures.times[2]: expected distinct departure times, got 60.0 twice",
        ),
        ({"times": []}, "services[1].departures.times: expected a non-empty list of departure times, got []"),
        (
            {"first": 600, "last": 0, "headway_s": 60},
            "services[1].departures.last: expected a time at or after first (600), got 0",
        ),
        ({"first": 0, "last": 60, "headway_s": 0}, "services[1].departures.headway_s: expected a number > 0, got 0"),
        ({"first": 0, "last": 60}, "services[1].departures.headway_s: missing required key"),
        (
            {"first": 0, "last": 1e6, "headway_s": 10},
            "services[1].departures: expected at most 10000 departures, got 100001 (from first to last every headway_s)",
        ),
        (  # a subnormal headway: the count overflows a float (an OverflowError traceback before)
            {"first": 0, "last": 0, "headway_s": 2.225073858507e-311},
            "services[1].departures: expected at most 10000 departures, got more (from first to last every headway_s)",
        ),
        ({"times": [-5]}, "services[1].departures.times[0]: expected a number >= 0, got -5"),
        (
            {"times": ["25:61"]},
            'services[1].departures.times[0]: expected a clock time "HH:MM" or "HH:MM:SS", got \'25:61\'',
        ),
    ],
)
def test_bad_departures(departures: dict[str, Any], message: str) -> None:
    assert error_of({"services[1].departures": departures}) == f"base.yaml: {message}"


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 48 * 3600 - 1))
def test_clock_parse_format_round_trip(seconds: int) -> None:
    assert S.parse_clock(S.format_clock(seconds)) == seconds


def test_clock_parsing() -> None:
    assert S.parse_clock("07:30") == 27000.0
    assert S.parse_clock("7:05:09") == 7 * 3600 + 5 * 60 + 9
    assert S.parse_clock("24:30") == 88200.0  # after-midnight service
    for bad in ("7:75", "48:00", "07:30:60", "0730", "07:3", "", "aa:bb"):
        with pytest.raises(ValueError):
            S.parse_clock(bad)


# ---- YAML reading ------------------------------------------------------------------------------------------------


def test_yaml_numbers_and_clock_times() -> None:
    text = (
        VALID.read_text()
        .replace("start_time: 07:30 ", "start_time: 17:30 ")
        .replace('first: "07:30", last: "09:30"', "first: 17:30, last: 17:40")
        .replace('times: ["07:36:30", "07:31",', "times: [17:36:30, 17:31,")
    )
    scn = S.loads(text)
    assert scn.simulation.start_time_s == 17.5 * 3600  # YAML 1.1 would read 1050
    assert scn.services[0].departures_s == (0.0, 150.0, 300.0, 450.0, 600.0)
    # "1e3" is a number, not the string PyYAML makes of it; 17:31 and 17:36:30 unquoted are clock times
    assert scn.services[1].departures_s == (60.0, 390.0, 1000.0, 1200.0)


def test_file_errors(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"^.*nope\.yaml: file not found$"):
        S.load(tmp_path / "nope.yaml")
    (tmp_path / "empty.yaml").write_text("\n# only a comment\n")
    with pytest.raises(ConfigError) as info:
        S.load(tmp_path / "empty.yaml")
    assert str(info.value) == f"{tmp_path / 'empty.yaml'}: expected a scenario mapping, got an empty file"
    with pytest.raises(ConfigError) as info:
        S.loads("name: x\nsimulation: {step_s: 1\n", source="s.yaml")
    assert str(info.value).startswith("s.yaml: line 3, column 1: YAML syntax error: expected ',' or '}'")


# ---- resolved round trip ------------------------------------------------------------------------------------------


def test_resolved_round_trip(tmp_path: Path) -> None:
    scn = S.load(VALID)
    text = S.resolved_yaml(scn)
    out = tmp_path / "elsewhere" / "scenario.resolved.yaml"
    out.parent.mkdir()
    out.write_text(text)
    again = S.load(out)
    assert again == scn
    assert again.raw == scn.raw and again.source != scn.source
    # resolving is idempotent and the raw mapping is plain YAML data
    assert S.from_mapping(copy.deepcopy(scn.raw)).raw == scn.raw
    assert "cq3_6car" in text and "max_speed_kmh" not in text  # km/h converted at the edge


def test_round_trip_keeps_relative_world_paths_working(tmp_path: Path) -> None:
    (tmp_path / "lines").mkdir()
    (tmp_path / "lines" / "my_line.yaml").write_text("stations: []\n")
    data = S.with_overrides(BASE, {"world": {"line": "lines/my_line.yaml"}})
    (tmp_path / "scn.yaml").write_text(yaml.safe_dump(data))
    scn = S.load(tmp_path / "scn.yaml")
    assert scn.world == S.WorldSpec(kind="line", line=(tmp_path / "lines" / "my_line.yaml").resolve())
    other = tmp_path / "out"
    other.mkdir()
    (other / "resolved.yaml").write_text(S.resolved_yaml(scn))
    assert S.load(other / "resolved.yaml") == scn


def test_default_filled_raw_has_every_section() -> None:
    raw = build().raw
    assert list(raw) == [
        "name",
        "description",
        "world",
        "simulation",
        "vehicles",
        "controllers",
        "roles",
        "services",
        "formations",
        "events",
        "faults",
        "outputs",
    ]
    assert raw["simulation"] == {
        "step_s": 0.5,
        "duration_s": 3600.0,
        "start_time": "00:00",
        "seed": 0,
        "step_method": "euler",
    }
    assert raw["faults"]["comm"]["t2g"] == {
        "delay_s": {"dist": "constant", "value": 0.0},
        "loss_prob": 0.0,
        "outages": [],
    }
    assert set(raw["vehicles"]["cq6"]) == {"preset"} | set(S.VEHICLE_FIELDS)


# ---- overrides ----------------------------------------------------------------------------------------------------


def test_overrides_by_dotted_path() -> None:
    scn = S.load(VALID, overrides={"simulation.seed": 3, "services[0].departures.headway_s": 180})
    assert scn.simulation.seed == 3
    assert np.allclose(np.diff(scn.services[0].departures_s), 180.0)
    assert S.load(VALID).simulation.seed == 42  # the file is untouched


def test_with_overrides_copies_and_creates_missing_mappings() -> None:
    before = copy.deepcopy(BASE)
    data = S.with_overrides(BASE, {"faults.comm.t2t.loss_prob": 0.25, "vehicles.cq6.mass_kg": 250000})
    assert BASE == before
    scn = S.from_mapping(data)
    assert scn.faults.comm["t2t"].loss_prob == 0.25 and scn.vehicles["cq6"].mass_kg == 250000.0


@pytest.mark.parametrize(
    "path, message",
    [
        ("services[5].id", "<overrides>: services[5].id: index 5 out of range (services has 2 items)"),
        ("name.first", "<overrides>: name.first: name is not a mapping, got 'base'"),
        (
            "simulation[0]",
            "<overrides>: simulation[0]: simulation is not a list, got {'step_s': 0.5, 'duration_s': 3600}",
        ),
        ("simulation..seed", '<overrides>: simulation..seed: expected a path like "a.b[0].c"'),
    ],
)
def test_bad_override_paths(path: str, message: str) -> None:
    with pytest.raises(ConfigError) as info:
        S.with_overrides(BASE, {path: 1})
    assert str(info.value) == message


def test_overridden_values_are_validated() -> None:
    assert error_of({"simulation.seed": -1}) == "base.yaml: simulation.seed: expected an integer >= 0, got -1"


# ---- world checks -------------------------------------------------------------------------------------------------


def test_check_against_world() -> None:
    scn = build(
        {
            "services[0].via": ["s3"],
            "services[0].dwell_s": {"stations": {"s4": 40}},
            "formations": [
                {
                    "id": "p",
                    "leader": {"service": "a", "trip": 0},
                    "follower": {"service": "b", "trip": 0},
                    "target_gap_m": 20,
                    "couple": {"at_station": "s1"},
                    "decouple": {"before_switch": "sw_2"},
                },
            ],
        }
    )
    stations = [f"s{i}" for i in range(10)]
    S.check_against_world(scn, stations, ["sw_1", "sw_2"])  # all present: no error

    with pytest.raises(ConfigError) as info:
        S.check_against_world(scn, [s for s in stations if s != "s3"], ["sw_1", "sw_2"])
    assert (
        str(info.value) == "base.yaml: services[0].via[0]: expected a station id of world 'straight_corridor', got 's3'"
    )
    with pytest.raises(ConfigError) as info:
        S.check_against_world(scn, [s for s in stations if s != "s4"] + ["s44"], ["sw_2"])
    assert str(info.value) == (
        "base.yaml: services[0].dwell_s.stations.s4: expected a station id of world 'straight_corridor', got 's4'"
        " (did you mean 's44'?)"
    )
    with pytest.raises(ConfigError) as info:
        S.check_against_world(scn, stations, ["sw_1", "crossover_7"])
    assert str(info.value) == (
        "base.yaml: formations[0].decouple.before_switch: expected a switch id of world 'straight_corridor', "
        "got 'sw_2' (did you mean 'sw_1'?)"
    )


def test_world_forms(tmp_path: Path) -> None:
    (tmp_path / "x.net.xml").write_text("<net/>")
    (tmp_path / "stops.add.xml").write_text("<additional/>")
    scn = S.from_mapping(
        S.with_overrides(BASE, {"world": {"net": "x.net.xml", "additional": ["stops.add.xml"]}}), base_dir=tmp_path
    )
    assert scn.world.kind == "net" and scn.world.additional == ((tmp_path / "stops.add.xml").resolve(),)
    assert build({"world": {"name": "straight_corridor", "params": {"length_km": 60}}}).world.build_args() == (
        "straight_corridor",
        {"length_km": 60},
    )
    assert error_of({"world": {"name": "a", "line": "b"}}) == (
        "base.yaml: world: expected exactly one of name, line, net, got {'name': 'a', 'line': 'b'}"
    )
    assert error_of({"world": {"nmae": "a"}}) == (
        "base.yaml: world.nmae: unknown key (did you mean 'name'?); allowed keys: additional, line, name, net, params"
    )
    assert error_of({"world": {"line": "missing.yaml"}}).startswith(
        "base.yaml: world.line: expected an existing file, got 'missing.yaml' (looked for "
    )


# ---- vehicles, controllers, formations -----------------------------------------------------------------------------


def test_vehicle_without_preset_needs_every_field() -> None:
    fields = {f: getattr(preset("cq3_8car"), f) for f in S.VEHICLE_FIELDS}
    scn = build({"vehicles.cq6": fields})
    assert scn.vehicles["cq6"] == preset("cq3_8car").with_overrides(name="cq6")
    partial = {k: v for k, v in fields.items() if k not in ("davis_a_n", "capacity_pax")}
    assert error_of({"vehicles.cq6": partial}) == (
        "base.yaml: vehicles.cq6.davis_a_n: missing required key (a vehicle without preset needs every field: "
        "davis_a_n, capacity_pax)"
    )


@pytest.mark.parametrize(
    "override, message",
    [
        (
            {"vehicles.cq6.max_speed_kmh": 70, "vehicles.cq6.max_speed_mps": 19.0},
            "vehicles.cq6.max_speed_kmh: expected either max_speed_kmh or max_speed_mps, got both",
        ),
        (
            {"vehicles.cq6.emergency_decel_mps2": 1.0},
            "vehicles.cq6.emergency_decel_mps2: expected a number >= service_decel_mps2 (1.11), got 1.0",
        ),
        ({"vehicles.cq6.capacity_pax": 12.5}, "vehicles.cq6.capacity_pax: expected an integer >= 0, got 12.5"),
        ({"vehicles.cq6.name": "x"}, "vehicles.cq6.name: unknown key (a vehicle is named by its key in 'vehicles')"),
        (
            {"vehicles.cq6.mass_kgs": 1},
            "vehicles.cq6.mass_kgs: unknown key (did you mean 'mass_kg'?); allowed keys: "
            + ", ".join(sorted(["preset", "max_speed_kmh", "plant", "plant_params", *S.VEHICLE_FIELDS])),
        ),
        ({"vehicles.cq6.mass_kg": float("nan")}, "vehicles.cq6.mass_kg: expected a finite number > 0, got nan"),
    ],
)
def test_bad_vehicles(override: dict[str, Any], message: str) -> None:
    assert error_of(override) == f"base.yaml: {message}"


def test_controller_params_are_checked_with_the_vehicles_that_use_them() -> None:
    soft = {"preset": "cq3_6car", "service_decel_mps2": 1.0, "emergency_decel_mps2": 1.1}
    strict = {"controllers.keep.params.brake_mps2": 1.2, "vehicles.soft": soft}
    # "keep" (brake 1.2 m/s2) is fine for cq6 (emergency 1.25); "soft" is not used by any service
    assert build(strict).vehicles["soft"].emergency_decel_mps2 == 1.1
    # ...until a service that uses "keep" runs with it
    assert error_of({**strict, "services[1].vehicle": "soft"}) == (
        "base.yaml: controllers.keep.params.brake_mps2: expected at most the emergency deceleration of soft (1.1), got 1.2"
    )
    # a per-service role override makes the check follow the controller actually used
    assert (
        build(
            {
                **strict,
                "controllers.other": {"type": "_test_follow"},
                "services[1].vehicle": "soft",
                "services[1].roles": {"separation": "other", "coupled": "other"},
            }
        )
        .services[1]
        .roles["separation"]
        == "other"
    )


def test_controller_registry_is_read_at_validation_time() -> None:
    late = f"_test_late_{uuid.uuid4().hex[:8]}"
    assert error_of({"controllers.drive.type": late}).startswith(
        "base.yaml: controllers.drive.type: expected a registered"
    )

    @register(late)
    def _factory(params: Any, vehicle: Any) -> Any:
        return type("C", (), {"command": lambda self, obs: Command(0.0)})()

    assert build({"controllers.drive.type": late}).controllers["drive"].type == late


@pytest.mark.parametrize(
    "formations, message",
    [
        (
            [
                {
                    "id": "p",
                    "leader": {"service": "a", "trip": 0},
                    "follower": {"service": "a", "trip": 0},
                    "target_gap_m": 9,
                }
            ],
            "formations[0].follower: expected a train other than the leader, got a.000",
        ),
        (
            [
                {
                    "id": "p",
                    "leader": {"service": "a", "trip": 0},
                    "follower": {"service": "b", "trip": 0},
                    "target_gap_m": 9,
                },
                {
                    "id": "q",
                    "leader": {"service": "b", "trip": 0},
                    "follower": {"service": "a", "trip": 0},
                    "target_gap_m": 9,
                },
            ],
            "formations[1].follower: expected formations without a cycle, got a.000 following itself",
        ),
        (
            [
                {
                    "id": "p",
                    "leader": {"service": "c", "trip": 0},
                    "follower": {"service": "b", "trip": 0},
                    "target_gap_m": 9,
                }
            ],
            "formations[0].leader.service: expected a service id (a, b), got 'c'",
        ),
        (
            [
                {
                    "id": "p",
                    "leader": {"service": "a", "trip": 0},
                    "follower": {"service": "b", "trip": 0},
                    "target_gap_m": 9,
                    "couple": {"at_s": 5, "on_departure": True},
                }
            ],
            "formations[0].couple: expected exactly one of at_s, at_station, on_departure, after_switch, "
            "got {'at_s': 5, 'on_departure': True}",
        ),
        (
            [
                {
                    "id": "p",
                    "leader": {"service": "a", "trip": 0},
                    "follower": {"service": "b", "trip": 0},
                    "target_gap_m": 9,
                    "couple": {"on_departure": False},
                }
            ],
            "formations[0].couple.on_departure: expected true, got False",
        ),
        (
            [
                {
                    "id": "p",
                    "leader": {"service": "a", "trip": 0},
                    "follower": {"service": "b", "trip": 0},
                    "target_gap_m": 0,
                }
            ],
            "formations[0].target_gap_m: expected a number > 0, got 0",
        ),
        (
            [
                {
                    "id": "p",
                    "leader": {"service": "a", "trip": 0},
                    "follower": {"service": "b", "trip": 0},
                    "target_gap_m": 9,
                    "decouple": {"before_swtich": "x"},
                }
            ],
            "formations[0].decouple.before_swtich: unknown key (did you mean 'before_switch'?); "
            "allowed keys: at_s, at_station, before_switch",
        ),
    ],
)
def test_bad_formations(formations: list[Any], message: str) -> None:
    assert error_of({"formations": formations}) == f"base.yaml: {message}"


def test_chained_formations_are_allowed() -> None:
    # a.000 <- b.000 <- a.001: a train may lead one formation and follow in another
    fms = [
        {"id": "p", "leader": {"service": "a", "trip": 0}, "follower": {"service": "b", "trip": 0}, "target_gap_m": 9},
        {"id": "q", "leader": {"service": "b", "trip": 0}, "follower": {"service": "a", "trip": 1}, "target_gap_m": 9},
    ]
    assert [f.id for f in build({"formations": fms}).formations] == ["p", "q"]


def test_other_ranges() -> None:
    assert (
        error_of({"outputs.trace_stride_s": 0.25})
        == "base.yaml: outputs.trace_stride_s: expected a number >= 0.5, got 0.25"
    )
    assert (
        error_of({"outputs.formats": ["csv", "csv"]})
        == "base.yaml: outputs.formats[1]: expected distinct values, got 'csv' twice"
    )
    assert error_of({"outputs.sumo": ["fdc"]}) == (
        "base.yaml: outputs.sumo[0]: expected one of tripinfo, stops, fcd, collisions, got 'fdc' (did you mean 'fcd'?)"
    )
    assert (
        error_of({"faults.comm.t2t.loss_prob": 1.5})
        == "base.yaml: faults.comm.t2t.loss_prob: expected a number in [0, 1], got 1.5"
    )
    assert error_of({"faults.comm.t2t.delay_s": {"dist": "uniform", "low": 0.5, "high": 0.1}}) == (
        "base.yaml: faults.comm.t2t.delay_s.high: expected a number >= 0.5, got 0.1"
    )
    assert error_of({"faults.comm.t2t.delay_s": {"dist": "exponential", "mean": 0.1, "sd": 0.1}}) == (
        "base.yaml: faults.comm.t2t.delay_s.sd: unknown key; allowed keys: dist, mean"
    )
    assert error_of({"faults.comm.t2t.outages": [{"start_s": 50, "end_s": 50}]}) == (
        "base.yaml: faults.comm.t2t.outages[0].end_s: expected a number > 50, got 50"
    )
    assert error_of({"services[1].id": "a"}) == "base.yaml: services[1].id: expected a unique service id, got 'a' twice"
    assert (
        error_of({"services[1].skip": ["s5"]})
        == "base.yaml: services[1].skip[0]: expected an intermediate station, got the terminal 's5'"
    )
    assert error_of({"services[1].roles": {"folow": "keep"}}) == (
        "base.yaml: services[1].roles.folow: unknown key; allowed keys: ato, ca, coupled, separation"
    )


# ---- delay distributions -------------------------------------------------------------------------------------------


def test_delay_sampling_matches_the_documented_parametrisation() -> None:
    rng = np.random.default_rng(7)
    n = 200_000
    logn = S.DelaySpec("lognormal", {"mean": 0.2, "sd": 0.05}).sample(rng, n)
    assert logn.mean() == pytest.approx(0.2, rel=0.01) and logn.std() == pytest.approx(0.05, rel=0.02)
    normal = S.DelaySpec("normal", {"mean": 0.05, "sd": 0.1}).sample(rng, n)
    assert normal.min() == 0.0  # clipped, never negative
    # E[max(X, 0)] for X ~ N(mu, s): mu*Phi(mu/s) + s*phi(mu/s)
    z = 0.05 / 0.1
    expected = 0.05 * 0.5 * (1 + math.erf(z / math.sqrt(2))) + 0.1 * math.exp(-z * z / 2) / math.sqrt(2 * math.pi)
    assert normal.mean() == pytest.approx(expected, rel=0.01)
    assert S.DelaySpec("exponential", {"mean": 0.3}).sample(rng, n).mean() == pytest.approx(0.3, rel=0.01)
    uni = S.DelaySpec("uniform", {"low": 0.1, "high": 0.5}).sample(rng, n)
    assert uni.min() >= 0.1 and uni.max() <= 0.5 and uni.mean() == pytest.approx(0.3, rel=0.01)
    assert S.DelaySpec().sample(rng) == 0.0


# ---- robustness: any junk value gives a ConfigError, never another exception ----------------------------------------


def _leaf_paths(node: Any, prefix: str = "") -> list[str]:
    if isinstance(node, dict):
        return [p for k, v in node.items() for p in _leaf_paths(v, f"{prefix}.{k}" if prefix else k)] + (
            [prefix] if prefix else []
        )
    if isinstance(node, list):
        return [p for i, v in enumerate(node) for p in _leaf_paths(v, f"{prefix}[{i}]")] + [prefix]
    return [prefix]


_FULL = S.load(VALID).raw
_LEAVES = sorted(set(_leaf_paths(_FULL)))
_JUNK = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**6), 10**6),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=8),
    st.lists(st.integers(), max_size=3),
    st.dictionaries(st.text(max_size=4), st.integers(), max_size=2),
)


@settings(max_examples=300, deadline=None)
@given(path=st.sampled_from(_LEAVES), junk=_JUNK)
def test_junk_values_give_config_errors(path: str, junk: Any) -> None:
    data = S.with_overrides(_FULL, {path: junk})
    try:
        S.from_mapping(data, source="fuzz.yaml")
    except ConfigError as err:
        assert str(err).startswith("fuzz.yaml: ") and "\n" not in str(err)


def test_module_docstring_example_is_a_valid_scenario() -> None:
    doc = S.__doc__ or ""
    block = doc.split("give type, range and default)::\n\n", 1)[1].split("\nReadings and conventions", 1)[0]
    text = "\n".join(line[4:] for line in block.splitlines())
    # the test-only controllers stand in for the library's (the schema, not the library, is under test here)
    text = text.replace("type: ato", "type: _test_ctrl").replace("type: separation", "type: _test_follow")
    text = text.replace("type: cacc", "type: _test_follow")
    scn = S.loads(text)
    assert scn.name == "chongqing_line3_peak"
    assert scn.services[1].departures_s == (60.0, 390.0, 900.0)
    assert scn.vehicles["cq6_heavy"].max_speed_mps == pytest.approx(70 / 3.6)


def test_a_key_with_a_newline_is_named_on_one_line() -> None:
    """A user's key with a control character (here a newline) is shown escaped in the field path, so the error
    stays one line (found by test_junk_values_give_config_errors)."""
    data = S.with_overrides(_FULL, {"controllers": {"drive\n": 1}})
    with pytest.raises(ConfigError) as info:
        S.from_mapping(data, source="fuzz.yaml")
    assert "\n" not in str(info.value) and "drive\\n" in str(info.value)
