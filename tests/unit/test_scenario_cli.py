"""``railsim validate``: every kind of broken scenario gives one exact line on stderr and exit code 2.

The broken files live in tests/data/broken/ (one mistake each). They run through the installed entry point
``.venv/bin/railsim`` in a subprocess, with tests/data/plugins on PYTHONPATH so that its ``sitecustomize``
registers the test-only controllers ``_test_ctrl`` and ``_test_follow`` (the real library is not needed).
The world check (:mod:`railsim.studies.world`) is exercised in-process with a fake ``network.build``.
"""

from __future__ import annotations

import sys
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

REPO = Path(__file__).resolve().parents[2]
PLUGINS = REPO / "tests" / "data" / "plugins"
BROKEN = Path("tests") / "data" / "broken"  # relative to REPO: the messages name the file as given
VALID = Path("tests") / "data" / "scenario" / "valid.yaml"

sys.path.insert(0, str(PLUGINS))
import railsim_test_controllers  # noqa: E402,F401

from railsim.cli import main as cli  # noqa: E402
from railsim.studies import world  # noqa: E402  (the world check behind `railsim validate`)

# file stem -> the message after "railsim: error: tests/data/broken/<stem>.yaml: "
EXPECTED: dict[str, str] = {
    "unknown_key": "simulation.sead: unknown key (did you mean 'seed'?); "
    "allowed keys: duration_s, seed, start_time, step_method, step_s",
    "wrong_type": "simulation.duration_s: expected a number > 0, got 'one hour'",
    "negative_step": "simulation.step_s: expected a number in (0, 5], got -0.5",
    "bad_clock_time": 'simulation.start_time: expected a clock time "HH:MM" or "HH:MM:SS", got \'7:75\'',
    "unknown_vehicle_preset": "vehicles.cq6.preset: expected a vehicle preset ({presets}), got 'cq3_6carr' "
    "(did you mean 'cq3_6car'?)",
    "unknown_controller_type": "controllers.keep.type: expected a registered controller type ({registered}), "
    "got '_test_folow' (did you mean '_test_follow'?)",
    "bad_controller_param": "controllers.keep.params.margin_m: expected a number >= 0, got -5",
    "controller_param_vs_vehicle": "controllers.keep.params.brake_mps2: expected at most the emergency deceleration "
    "of cq6 (1.25), got 1.3",
    "unknown_vehicle_ref": "services[0].vehicle: expected one of the vehicles (cq6), got 'cq8' (did you mean 'cq6'?)",
    "formation_trip_out_of_range": "formations[0].leader.trip: expected a trip index in [0, 2] "
    "(service 'a' has 3 departures), got 5",
    "yaml_syntax": "line 9, column 1: YAML syntax error: expected ',' or '}', but got '<scalar>' "
    "(while parsing a flow mapping at line 8, column 9)",
    "duplicate_key": "line 3, column 1: YAML syntax error: found duplicate key 'world' "
    "(while constructing a mapping at line 1, column 1)",
    "empty": "expected a scenario mapping, got an empty file",
    "top_level_list": "expected a mapping at the top level, got a list of 2 items",  # the content is never echoed
    "missing_name": "name: missing required key",
    "unknown_role_controller": "roles.separation: expected a controller instance (drive, keep), got 'kep' "
    "(did you mean 'keep'?)",
    "missing_coupled_role": "roles.coupled: missing required key (the scenario has formations)",
    "follower_twice": "formations[1].follower: expected a train that follows in at most one formation, "
    "got b.000 (already the follower in 'pair1')",
    "event_unknown_formation": "events[0].formation: expected a formation id (pair1), got 'pair_1' "
    "(did you mean 'pair1'?)",
    "departure_before_start": "services[0].departures.first: expected a time at or after start_time (07:30:00), "
    "got '07:00'",
    "bool_seed": "simulation.seed: expected an integer >= 0, got True",
    "unknown_delay_dist": "faults.comm.t2t.delay_s.dist: expected one of constant, uniform, normal, lognormal, "
    "exponential, got 'gaussian'",
    "outage_unknown_train": "faults.comm.t2g.outages[0].trains[0]: expected a trip id (like 'a.000') or a service "
    "id, got 'a.007' (did you mean 'a.002'?)",
}


def test_every_broken_file_has_an_expected_message() -> None:
    stems = {p.stem for p in (REPO / BROKEN).glob("*.yaml")}
    assert stems == set(EXPECTED)
    assert len(stems) >= 10


# ---- the world check, in-process with a fake network.build -----------------------------------------------------

STATIONS = ["yudong", "jinzhu", "bijin", "lianglukou", "liugongli", "jurenba", "jiangbei-airport-t2"]


def _fake_build(stations: list[str], switches: list[str], calls: list[Any]) -> Any:
    def build(name_or_path: str, **params: Any) -> Any:
        calls.append((name_or_path, params))
        return SimpleNamespace(stations={s: object() for s in stations}, switches={s: object() for s in switches})

    return build


def test_world_check_passes(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    calls: list[Any] = []
    monkeypatch.setattr(world, "_network_build", lambda: _fake_build(STATIONS, ["bijin_up"], calls))
    monkeypatch.setattr(world, "_simulation", lambda: lambda scn, out, **kw: calls.append(("engine", out)))
    assert cli.main(["validate", str(REPO / VALID)]) == 0
    assert calls == [("chongqing_line3", {}), ("engine", None)]  # run's own checks after the world check
    assert capsys.readouterr().out == "ok: cq3_peak_test: 2 services, 53 trips, 2 formations\n"


def test_world_check_rejects_unknown_station(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    calls: list[Any] = []
    stations = [s for s in STATIONS if s != "liugongli"] + ["liugongli-east"]
    monkeypatch.setattr(world, "_network_build", lambda: _fake_build(stations, ["bijin_up"], calls))
    assert cli.main(["validate", str(REPO / VALID)]) == 2
    err = capsys.readouterr().err
    assert err == (
        f"railsim: error: {REPO / VALID}: formations[0].couple.at_station: expected a station id of world "
        "'chongqing_line3', got 'liugongli' (did you mean 'liugongli-east'?)\n"
    )


def test_world_check_skipped_with_a_warning(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(world, "_network_build", lambda: None)
    assert cli.main(["validate", str(REPO / VALID)]) == 0
    out = capsys.readouterr()
    assert out.err == "railsim: warning: world check skipped: network.build is not available yet\n"
    assert out.out.startswith("ok: cq3_peak_test:")
    # --no-world-check does not even try
    monkeypatch.setattr(world, "_network_build", lambda: pytest.fail("world built despite --no-world-check"))
    assert cli.main(["validate", str(REPO / VALID), "--no-world-check"]) == 0
