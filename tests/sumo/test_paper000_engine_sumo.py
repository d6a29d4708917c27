"""Paper A (spec 000) experiments through the engine: S-D and S-E scenario files run by ``railsim run`` in a child
process (SUMO, ballistic steps, actuator noise), scored by :mod:`railsim.analysis.paper000`, plotted by
:mod:`railsim.report.plots.paper000`; plus the metrics on a synthetic output folder whose answers are known by hand.

Here: the tests of it that run SUMO or a railsim child process; the others are in ``tests/unit/test_paper000_engine.py``.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from railsim.analysis.paper000 import VcCriterion, follower_series, format_table, paper000_metrics
from tests.helpers import ROOT, run_railsim

SCEN = ROOT / "scenarios"


def _run(tmp: pytest.TempPathFactory, scenario: Path, name: str) -> Path:
    out = tmp.mktemp(name)
    res = run_railsim(["run", str(scenario), "--out", str(out), "--no-progress"])
    assert res.returncode == 0, res.stderr[-2000:]
    return out


@pytest.fixture(scope="module")
def sd_runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """S-D initial conditions, 500 s: the DMPC baseline and the single-model IDM (S-A) — the fast methods."""
    return {
        "dmpc": _run(tmp_path_factory, SCEN / "paper000_sd_comparison_dmpc.yaml", "sd_dmpc"),
        "cf_idm": _run(tmp_path_factory, SCEN / "paper000_sa_cf_idm.yaml", "sa_idm"),
    }


def test_sd_platoon_couples_safely_and_dmpc_beats_the_idm_offset(sd_runs: dict[str, Path]) -> None:
    metrics = {k: paper000_metrics(d) for k, d in sd_runs.items()}
    table = format_table(metrics)
    assert table.count("\n") == 4 and "t3.000" in table  # header + 2 methods × 2 followers
    for label, m in metrics.items():
        assert m["collisions"] == 0
        for row in m["followers"]:
            assert row["samples"] == 500  # paper time 0 … 499 s
            assert row["min_safety_margin_m"] >= 0.0, (label, row)  # Eq. (20): ΔS ≥ D^(s) all along
            assert math.isfinite(row["vc_first_s"]), (label, row)  # the A33 band is reached
            assert row["late_mean_abs_spacing_error_m"] < 10.0, (label, row)
            assert row["fallbacks"] == 0
    # CF laws settle with a positive steady offset under resistance (spec §6.1: IDM ≈ 6.9 m / 5.0 m); the DMPC
    # baseline tracks D^(e) itself, so its late error is a fraction of the IDM's for both followers.
    idm, dmpc = metrics["cf_idm"]["followers"], metrics["dmpc"]["followers"]
    for a, b in zip(idm, dmpc):
        assert b["late_mean_abs_spacing_error_m"] < 0.5 * a["late_mean_abs_spacing_error_m"]
    for fs, expected in zip(follower_series(sd_runs["cf_idm"]), (6.87, 4.98)):
        late = fs.t_s >= 300.0
        assert float(np.mean((fs.spacing_m - fs.desired_m)[late])) == pytest.approx(expected, abs=2.0)


def test_se_follower_keeps_the_coupling_through_the_speed_change(tmp_path_factory: pytest.TempPathFactory) -> None:
    out = _run(tmp_path_factory, SCEN / "paper000_se_variable_speed_dmpc.yaml", "se_dmpc")
    m = paper000_metrics(out, VcCriterion(late_start_s=None))
    (row,) = m["followers"]
    assert math.isnan(row["late_mean_abs_dv_mps"])  # Table IV: whole cycle only
    assert row["min_safety_margin_m"] >= 0.0
    assert row["vc_first_s"] <= 5.0  # starts coupled at D^(e)(220, 220)
    assert row["mean_abs_spacing_error_m"] < 10.0
    (fs,) = follower_series(out)
    assert float(fs.v_lead_mps.min()) * 3.6 == pytest.approx(180.0, abs=1.0)  # the leader did slow down


def test_mcf_variants_run_through_the_engine(tmp_path_factory: pytest.TempPathFactory) -> None:
    """A short MCF/OPO run with a small optimiser budget: the plumbing (plans on the wire, min(ato, coupled))."""
    raw = yaml.safe_load((SCEN / "paper000_sd_comparison_opo_mcf_dmpc.yaml").read_text(encoding="utf-8"))
    raw["simulation"]["duration_s"] = 15
    for name in ("vc2", "vc3"):
        raw["controllers"][name]["params"].update(population=8, iterations=4, opo_iterations=2)
    path = tmp_path_factory.mktemp("mcf_scen") / "sd_opo_short.yaml"
    path.write_text(yaml.safe_dump(raw), encoding="utf-8")
    out = _run(tmp_path_factory, path, "sd_opo_short")
    m = paper000_metrics(out)
    assert [r["controller"] for r in m["followers"]] == ["opo_mcf_dmpc", "opo_mcf_dmpc"]
    assert all(r["min_safety_margin_m"] >= 0.0 and r["fallbacks"] == 0 for r in m["followers"])
    roles = {r["role"] for r in csv.DictReader(open(out / "trace.csv", encoding="utf-8")) if r["train"] == "t2.000"}
    assert "coupled" in roles  # train 2 (89 m beyond D^(e)) eases off below the ATO within seconds
