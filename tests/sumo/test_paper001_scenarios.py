"""Paper B's scenarios B, C-constant and C-harmonic in SUMO, and the measures the engine reports.

* ``scenarios/paper001_{multi_section,wind_constant,wind_harmonic}.yaml`` load, run briefly in SUMO (a child
  process), and report the ``paper001`` measures with every controller inside the force and force-rate envelope;
* the plant's wind acts on the carriages as spec A14 says (closed form, no SUMO): an extra resistance per unit
  mass, so a coasting train loses ``ŵ·Δt`` more speed;
* a bad wind block is one line naming the file and the field (exit 2);
* E_p is taken where the law itself stopped the train: it equals the engine's own stopping error on the
  single-section run.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from tests.helpers import ROOT, read_csv, read_summary, run_railsim

SCEN = ROOT / "scenarios"
NEW = ("paper001_multi_section", "paper001_wind_constant", "paper001_wind_harmonic")


def _write(tmp_path: Path, name: str, duration_s: float, ato: str | None = None) -> Path:
    raw = yaml.safe_load((SCEN / f"{name}.yaml").read_text())
    world = raw["world"]
    if isinstance(world, dict) and "line" in world:  # keep the line file found from the copy's folder
        world["line"] = str((SCEN / world["line"]).resolve())
    raw["simulation"]["duration_s"] = duration_s
    if ato is not None:
        raw["roles"]["ato"] = ato
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


@pytest.mark.parametrize(("name", "ato"), [(NEW[0], "sempc"), (NEW[1], "mpc"), (NEW[2], "afsmc")])
def test_new_scenarios_run_in_sumo_inside_the_envelope(tmp_path: Path, name: str, ato: str) -> None:
    out = tmp_path / "out"
    res = run_railsim(["run", str(_write(tmp_path, name, 40.0, ato)), "--out", str(out), "--no-progress"])
    assert res.returncode == 0, res.stderr[-2000:]
    (m,) = read_summary(out)["paper001"].values()
    assert m["running_steps"] >= 390 and m["e_v_mps"] is not None and m["e_x_m"] is not None
    assert m["rate_violations"] == 0 and m["force_violations"] == 0
    assert m["max_force_rate_n_per_s"] <= 60e3 * (1 + 1e-6)
    assert m["wind"] == {"paper001_multi_section": "none"}.get(name, name.rsplit("_", 1)[1])


def test_a_bad_wind_block_names_the_field(tmp_path: Path) -> None:
    raw = yaml.safe_load((SCEN / "paper001_wind_constant.yaml").read_text())
    raw["vehicles"]["dtype"]["plant_params"]["wind"] = {"kind": "gale", "constant": 0.2}
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    res = run_railsim(["validate", str(path)])
    assert res.returncode == 2 and "Traceback" not in res.stderr
    assert "vehicles.dtype.plant_params.wind" in res.stderr and "gale" in res.stderr


def test_e_p_is_where_the_law_stopped_the_train(tmp_path: Path) -> None:
    out = tmp_path / "out"
    res = run_railsim(
        ["run", str(SCEN / "paper001_single_section.yaml"), "--out", str(out), "--no-progress"],
    )
    assert res.returncode == 0, res.stderr[-2000:]
    (m,) = read_summary(out)["paper001"].values()
    (stop,) = read_csv(out / "stops.csv")
    assert m["stop_errors_m"] == [pytest.approx(float(stop["stopping_error_m"]), abs=2e-6)]
    assert m["e_p_m"] <= 0.3 and m["rate_violations"] == 0 and m["force_violations"] == 0
