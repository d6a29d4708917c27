"""Reproducers, one regression test each: inputs that once crashed, hung, leaked or passed validation.

Each case writes a shipped scenario with one change and runs ``railsim validate`` in this process (through
:func:`tests.fuzz.validate_in_process`: a time limit, exactly one ``railsim: error:`` line, no traceback) and
checks the message names the field (and, where there is one, the YAML line and column). Before the fix: deep
nesting was a ``RecursionError`` (exit 1, the collision code), a start speed of 1e308 km/h passed and became NaN
in ``controllers/braking.py``, an alias bomb under ``description`` took > 20 s and 800 MB, ``world: /dev/zero``
hung, ``world: /etc/passwd`` printed the file, and ``step_s: 1e-300``, ``duration_s: 1e-300``, extreme
``speed_profile`` segments, ``initial_kmh: .inf`` and ``switch_speed_margin_mps: inf`` were accepted.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from railsim.cli import main as cli_main
from railsim.inputs import EXCERPT_CHARS, MAX_DEPTH
from tests import fuzz
from tests.helpers import ROOT

CORRIDOR = ROOT / "scenarios" / "sweeps" / "corridor_small.yaml"
PROFILE = ROOT / "scenarios" / "paper000_se_variable_speed_dmpc.yaml"
JUNCTION = ROOT / "scenarios" / "paper004_table3_s1.yaml"
CORRIDOR_WORLD = (
    "world: {name: straight_corridor, params: {length_km: 6, stations: 4, line_speed_kmh: 80, platform_length_m: 220}}"
)
ALIAS_BOMB = fuzz.ALIAS_BOMB


def _variant(tmp_path: Path, base: Path, old: str, new: str, name: str = "case.yaml") -> Path:
    text = base.read_text(encoding="utf-8")
    assert old in text, f"{old!r} not in {base.name}"
    path = tmp_path / name
    path.write_text(text.replace(old, new, 1), encoding="utf-8")
    return path


def _rejected(path: Path, world_check: bool = False) -> str:
    """The one error line of validating ``path`` (asserting exit 2 and the contract)."""
    res = fuzz.validate_in_process(path, world_check=world_check)
    assert res.problem is None, res.problem
    assert res.rc == 2, res.stderr
    return res.stderr.strip()


# (base, old text, new text, what the message must contain)
CASES = {
    "deep_nesting": (
        CORRIDOR,
        "description: 6 km",
        "nested: " + "[" * 5000 + "]" * 5000 + "\ndescription: 6 km",
        f"line 6, column {8 + MAX_DEPTH}: expected nesting at most {MAX_DEPTH} levels deep",
    ),
    "alias_bomb_in_description": (
        CORRIDOR,
        "description: 6 km straight corridor, 4 stations, 6 trains per direction under moving block",
        "description: " + ALIAS_BOMB,
        "values with aliases expanded",
    ),
    "start_speed_1e308": (
        PROFILE,
        "speed_kmh: 220}}",
        "speed_kmh: 1e308}}",
        "services[1].start.speed_kmh: expected a speed in km/h of magnitude at most 1000",
    ),
    "start_speed_above_vehicle_max": (
        PROFILE,
        "speed_kmh: 220}}",
        "speed_kmh: 500}}",
        "services[1].start.speed_kmh: expected a speed in km/h at most the vehicle's max_speed_kmh (350), got 500",
    ),
    "step_1e-300": (
        CORRIDOR,
        "step_s: 0.5",
        "step_s: 1e-300",
        "simulation.step_s: expected a whole number of milliseconds >= 0.001 s",
    ),
    "step_not_whole_ms": (CORRIDOR, "step_s: 0.5", "step_s: 0.0015", "simulation.step_s"),
    "duration_1e-300": (
        CORRIDOR,
        "duration_s: 3600",
        "duration_s: 1e-300",
        "simulation.duration_s: expected a number >= step_s (0.5)",
    ),
    "too_many_steps": (CORRIDOR, "duration_s: 3600", "duration_s: 9e6", "expected at most 10,000,000 steps"),
    "no_departure_within_horizon": (
        CORRIDOR,
        "departures: {first: 0, last: 600, headway_s: 120}, dwell_s: 30}\n  - {id: down, from: s4, to: s1, vehicle: cq6, "
        "departures: {first: 0, last: 600, headway_s: 120}",
        "departures: {first: 3700, last: 4000, headway_s: 120}, dwell_s: 30}\n  - {id: down, from: s4, to: s1, "
        "vehicle: cq6, departures: {first: 3700, last: 4000, headway_s: 120}",
        "simulation.duration_s: expected a horizon that reaches the first departure (3700 s)",
    ),
    "speed_profile_to_kmh_1e300": (
        PROFILE,
        "to_kmh: 180",
        "to_kmh: 1e300",
        "controllers.lead.params.segments[0].to_kmh: expected a speed in km/h of magnitude at most 1000",
    ),
    "speed_profile_accel_1e300": (
        PROFILE,
        "accel_mps2: 0.2}]",
        "accel_mps2: 1e300}]",
        "controllers.lead.params.segments[1].accel_mps2: expected an acceleration in m/s^2",
    ),
    "initial_kmh_inf": (
        PROFILE,
        "initial_kmh: 220",
        "initial_kmh: .inf",
        "controllers.lead.params.initial_kmh: expected a finite speed in km/h, got inf",
    ),
    "switch_speed_margin_inf": (
        JUNCTION,
        "switch_speed_margin_mps: 0.3",
        "switch_speed_margin_mps: inf",  # YAML reads `inf` as a string
        "junction.params.switch_speed_margin_mps: expected a number, got 'inf'",
    ),
    "switch_speed_margin_dot_inf": (
        JUNCTION,
        "switch_speed_margin_mps: 0.3",
        "switch_speed_margin_mps: .inf",
        "junction.params.switch_speed_margin_mps: expected a finite speed in m/s",
    ),
    "target_gap_minus_9.2e18": (
        PROFILE,
        "target_gap_m: 612.654",
        "target_gap_m: -9.2e18",
        "formations[0].target_gap_m: expected a number > 0",
    ),
    "target_gap_9.2e18": (
        PROFILE,
        "target_gap_m: 612.654",
        "target_gap_m: 9.2e18",
        "formations[0].target_gap_m: expected a length in m of magnitude at most 1e+06",
    ),
    "margin_in_controller_params": (
        CORRIDOR,
        "margin_m: 50",
        "margin_m: 9.2e18",
        "controllers.sep.params.margin_m: expected a length in m",
    ),
    "world_params_inf": (CORRIDOR, "length_km: 6", "length_km: .inf", "world.params.length_km: expected a finite"),
    "seed_beyond_sumo": (CORRIDOR, "seed: 3", "seed: 4294967296", "simulation.seed: expected an integer in [0, "),
    "integer_of_5000_digits": (CORRIDOR, "seed: 3", "seed: " + "9" * 5000, "expected an integer of at most 100"),
    "recursive_alias": (
        CORRIDOR,
        "description: 6 km",
        "loop: &a [*a]\ndescription: 6 km",
        "expected no alias inside its own anchor",
    ),
    "nul_character": (
        CORRIDOR,
        "seed: 3",
        "seed: \x003",
        "line 8, column 51: YAML syntax error: special characters are not allowed (character #x0000)",
    ),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_issue_reproducer_is_one_clean_error(tmp_path: Path, case: str) -> None:
    base, old, new, expected = CASES[case]
    line = _rejected(_variant(tmp_path, base, old, new))
    assert line.startswith(f"railsim: error: {tmp_path / 'case.yaml'}: ")
    assert expected is not None and expected in line, line
    assert len(line) < 400, line  # a short excerpt at most, never the expanded value


@pytest.mark.parametrize("form", ["world: {line: /dev/zero}", "world: /dev/zero", "world: {net: /dev/zero}"])
def test_world_device_is_refused_not_read(tmp_path: Path, form: str) -> None:
    line = _rejected(_variant(tmp_path, CORRIDOR, CORRIDOR_WORLD, form), world_check=True)
    assert "/dev/zero" in line and ("regular file" in line or "existing file" in line), line


@pytest.mark.parametrize("form", ["world: {line: /etc/passwd}", "world: /etc/passwd"])
def test_world_file_content_is_never_echoed(tmp_path: Path, form: str) -> None:
    line = _rejected(_variant(tmp_path, CORRIDOR, CORRIDOR_WORLD, form), world_check=True)
    assert line.endswith("/etc/passwd: expected a mapping, got a string of " + line.rsplit("of ", 1)[1]), line
    assert "root" not in line


def test_world_line_description_with_deep_nesting(tmp_path: Path) -> None:
    (tmp_path / "line.yaml").write_text("name: x\nstations: " + "[" * 3000 + "]" * 3000 + "\n", encoding="utf-8")
    line = _rejected(_variant(tmp_path, CORRIDOR, CORRIDOR_WORLD, "world: {line: line.yaml}"), world_check=True)
    assert f"line.yaml: line 2, column {10 + MAX_DEPTH}: expected nesting at most {MAX_DEPTH} levels" in line


def test_scenario_path_that_is_not_a_regular_file(tmp_path: Path) -> None:
    fifo = tmp_path / "pipe.yaml"
    os.mkfifo(fifo)  # opening it for reading would block forever
    assert _rejected(fifo).endswith(
        "pipe.yaml: expected a scenario file (a regular file), got a device, pipe or socket"
    )
    assert _rejected(Path("/dev/zero")).startswith("railsim: error: /dev/zero: expected a scenario file")
    assert _rejected(tmp_path).endswith(": expected a scenario file, got a directory")


def test_top_level_content_is_described_not_quoted(tmp_path: Path) -> None:
    path = tmp_path / "notes.yaml"
    path.write_text("the secret token is 12345\n", encoding="utf-8")
    line = _rejected(path)
    assert line.endswith("expected a mapping at the top level, got a string of 25 characters") and "secret" not in line


def test_long_value_is_quoted_as_a_short_excerpt(tmp_path: Path) -> None:
    line = _rejected(_variant(tmp_path, CORRIDOR, "step_method: euler", "step_method: " + "x" * 5000))
    quoted = line.split("got ", 1)[1]
    assert len(quoted) <= EXCERPT_CHARS, quoted


def test_internal_error_is_one_line_and_a_log_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A bug (here: the run checks raising ZeroDivisionError) is exit 4 with the traceback in a log file."""

    def broken(scn: object) -> None:
        raise ZeroDivisionError("float division by zero")

    monkeypatch.setattr("railsim.cli.scenario.run_checks", broken)
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", None)  # re-read TMPDIR
    rc = cli_main.main(["validate", str(CORRIDOR)])
    err = capsys.readouterr().err.strip()
    assert rc == 4
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert err.startswith("railsim: internal error (ZeroDivisionError: float division by zero)")
    logs = list(tmp_path.glob("railsim-error-*.log"))
    assert len(logs) == 1 and str(logs[0]) in err
    text = logs[0].read_text(encoding="utf-8")
    assert "Traceback (most recent call last)" in text and "ZeroDivisionError" in text


def test_shipped_sweep_files_validate() -> None:
    for sweep in sorted((ROOT / "scenarios" / "sweeps").glob("*.yaml")):
        res = fuzz.validate_in_process(sweep)
        assert res.problem is None and res.rc == 0, f"{sweep.name}: {res.stderr}"


def test_paper_a_run_without_formations_gets_no_paper000_analysis() -> None:
    """Deleting a Paper A scenario's formations is valid input; its finished run once failed with exit 2 because
    the paper000 analysis (it scores formations) found nothing to score."""
    from railsim import scenario
    from railsim.analysis import registry

    assert "paper000" in registry.applicable(scenario.load(PROFILE))
    assert "paper000" not in registry.applicable(scenario.load(PROFILE, {"formations": []}))
