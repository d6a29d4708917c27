"""Paper A (spec 000) experiments through the engine: S-D and S-E scenario files run by ``railsim run`` in a child
process (SUMO, ballistic steps, actuator noise), scored by :mod:`railsim.analysis.paper000`, plotted by
:mod:`railsim.report.plots.paper000`; plus the metrics on a synthetic output folder whose answers are known by hand.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from controllers.mcf_dmpc.spacing import TABLE_I, desired_spacing_m, safe_spacing_m
from railsim.analysis.paper000 import VcCriterion, format_table, paper000_metrics, vc_times
from railsim.errors import ConfigError

# ------------------------------------------------------------------------------------------------------------------
# Metrics on a synthetic output folder


def _synthetic(tmp: Path, with_solve: bool = False) -> Path:
    """Leader at 60 m/s; follower error e = 20 m for t < 100, 5 m after; Δv = 0.02 m/s for t < 150, 0 after.
    Engine convention: first sample at t_s = 1 (paper t = 0); spacing built from D^(e) at the actual speeds."""
    raw = {
        "name": "synthetic",
        "vehicles": {"u": {"length_m": 203.0, "service_decel_mps2": 0.8, "emergency_decel_mps2": 1.0}},
        "controllers": {"vc": {"type": "cf_idm", "params": {}}},
        "roles": {"ato": "x", "separation": "y", "coupled": "vc"},
        "services": [{"id": "a", "vehicle": "u"}, {"id": "b", "vehicle": "u"}],
        "formations": [{"id": "f", "leader": {"service": "a", "trip": 0}, "follower": {"service": "b", "trip": 0}}],
    }
    (tmp / "scenario.resolved.yaml").write_text(yaml.safe_dump(raw), encoding="utf-8")
    cols = [
        "t_s",
        "train",
        "service",
        "chainage_m",
        "speed_mps",
        "applied_accel_mps2",
        "command_mps2",
        "role",
        "gap_m",
        "formation_state",
    ] + (["solve_time_s"] if with_solve else [])
    with open(tmp / "trace.csv", "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        for k in range(500):
            v_f = 60.0 - (0.02 if k < 150 else 0.0)
            e = 20.0 if k < 100 else 5.0
            spacing = float(desired_spacing_m(v_f, 60.0, TABLE_I)) + e
            solve = [""] if with_solve else []
            w.writerow([k + 1.0, "a.000", "a", 1e4, 60.0, 0, 0, "ato", ""] + [""] + solve)
            w.writerow(
                [k + 1.0, "b.000", "b", 1e4 - spacing, v_f, 0, 0, "coupled", spacing - 203.0, "coupling"]
                + ([0.001 * (k % 100 + 1)] if with_solve else [])
            )
    with open(tmp / "trips.csv", "w", newline="", encoding="utf-8") as fh:
        fh.write("trip_id,fallbacks\na.000,0\nb.000,3\n")
    (tmp / "summary.json").write_text(json.dumps({"steps": 500, "wall_s": 2.0, "collisions": 0}), encoding="utf-8")
    return tmp


def test_metrics_of_a_synthetic_run_match_the_hand_computation(tmp_path: Path) -> None:
    m = paper000_metrics(_synthetic(tmp_path))
    (r,) = m["followers"]
    assert (r["follower"], r["leader"], r["controller"], r["samples"]) == ("b.000", "a.000", "cf_idm", 500)
    assert r["mean_abs_spacing_error_m"] == pytest.approx((100 * 20 + 400 * 5) / 500)
    assert r["late_mean_abs_spacing_error_m"] == pytest.approx(5.0)
    assert r["mean_abs_dv_mps"] == pytest.approx(150 * 0.02 / 500)
    assert r["late_mean_abs_dv_mps"] == pytest.approx(0.0, abs=1e-12)
    assert r["vc_first_s"] == 150.0 and r["vc_sustained_s"] == 150.0
    # D^(e) − D^(s) = v_f²/(2·0.8) − v_f²/(2·1.0) = 0.125·v_f²; the smallest with e = 5 m is at v_f = 59.98
    assert r["min_safety_margin_m"] == pytest.approx(0.125 * 59.98**2 + 5.0)
    assert r["final_spacing_error_m"] == pytest.approx(5.0)
    assert r["fallbacks"] == 3 and math.isnan(r["solve_time_mean_s"]) and not m["solve_times_recorded"]
    assert m["wall_per_train_step_s"] == pytest.approx(2.0 / 500)
    assert "-" in format_table(m).splitlines()[1]  # missing solve times print as '-', never 'nan'


def test_solve_time_column_is_used_when_recorded(tmp_path: Path) -> None:
    (r,) = paper000_metrics(_synthetic(tmp_path, with_solve=True))["followers"]
    times = 0.001 * (np.arange(500) % 100 + 1)
    assert r["solve_time_mean_s"] == pytest.approx(times.mean())
    assert r["solve_time_p95_s"] == pytest.approx(np.percentile(times, 95))


def test_late_phase_and_criterion_are_configurable(tmp_path: Path) -> None:
    out = _synthetic(tmp_path)
    (r,) = paper000_metrics(
        out, VcCriterion(spacing_tol_m=25.0, speed_tol_mps=0.05, late_start_s=50.0, late_end_s=150.0)
    )["followers"]
    assert r["vc_first_s"] == 0.0  # the wider band holds from the start
    assert r["late_mean_abs_spacing_error_m"] == pytest.approx((50 * 20 + 50 * 5) / 100)


def test_vc_times_first_hit_and_sustained() -> None:
    t = np.arange(100.0)
    ok = np.zeros(100, dtype=bool)
    ok[10:20] = True  # a short hit
    ok[40:71] = True  # 31 samples: lasts exactly 30 s
    assert vc_times(t, ok, 30.0) == (10.0, 40.0)
    ok[70] = False  # now 29 s only
    first, sustained = vc_times(t, ok, 30.0)
    assert first == 10.0 and math.isnan(sustained)
    assert all(math.isnan(x) for x in vc_times(t, np.zeros(100, dtype=bool), 30.0))


def test_not_an_output_folder_is_a_config_error(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="scenario.resolved.yaml"):
        paper000_metrics(tmp_path)


def test_safe_spacing_below_desired_at_equal_speed() -> None:
    """The margin D^(e) − D^(s) the synthetic test relies on, from Eq. (5)/(6) directly."""
    v = np.array([50.0, 61.111])
    assert np.allclose(desired_spacing_m(v, v) - safe_spacing_m(v, v), 0.125 * v * v)


def test_figures_are_written(tmp_path: Path) -> None:
    from railsim.report.plots.paper000 import write_figures

    a = _synthetic(tmp_path / "a" if (tmp_path / "a").mkdir() is None else tmp_path)
    files = write_figures({"one": a, "two": a}, tmp_path / "fig")
    assert [p.name for p in files] == ["one.png", "two.png", "comparison.png", "comparison_zoom.png"]
    assert all(p.stat().st_size > 10_000 for p in files)


# ------------------------------------------------------------------------------------------------------------------
# The fast evaluation paths of the MCF controllers must be the same function as rollout + J^(DMPC) in numpy


def test_plain_float_rollout_and_fused_cost_equal_the_numpy_path(monkeypatch: pytest.MonkeyPatch) -> None:
    from controllers.mcf_dmpc import rollout as R
    from controllers.mcf_dmpc.cf_models import THETA_TRAIN3
    from controllers.mcf_dmpc.cost import dmpc_cost, sequence_costs

    rng = np.random.default_rng(7)
    for trial in range(60):
        base = R.constant_speed_horizon(rng.uniform(200, 3000), rng.uniform(30, 80), 60, 1.0, 203.0, 1.0)
        hz = R.PredecessorHorizon(
            base.position_m, base.speed_mps + rng.normal(0, 0.5, 61), rng.normal(0, 0.1, 60), 203.0, 1.0
        )
        pop = int(rng.integers(1, 12))
        seq = rng.integers(0, 3, (pop, 60))
        theta = (
            THETA_TRAIN3.as_array() if trial % 2 else THETA_TRAIN3.as_array() + np.abs(rng.normal(0, 0.05, (pop, 10)))
        )
        x0, v0, u_prev = rng.uniform(-800, 1500), rng.uniform(0, 100), rng.uniform(-0.8, 1.0)
        ff = trial % 3 == 0  # the A9 resistance feed-forward option too
        fast_traj = R.rollout_models(seq, x0, v0, hz, theta, TABLE_I, resistance_feedforward=ff)
        fast_cost = sequence_costs(seq, x0, v0, hz, theta, TABLE_I, u_prev, resistance_feedforward=ff)
        with monkeypatch.context() as mp:
            mp.setattr(R, "SCALAR_MAX_ROWS", 0)  # force the vectorised laws of cf_models
            ref = R.rollout_models(seq, x0, v0, hz, theta, TABLE_I, resistance_feedforward=ff)
        for name in ("u", "v", "s"):
            a, b = getattr(fast_traj, name), getattr(ref, name)
            assert np.allclose(a, b, rtol=1e-12, atol=1e-9), name  # u is saturated, so everything is finite
        ref_cost = dmpc_cost(ref, hz, u_prev, TABLE_I)
        assert np.allclose(fast_cost, ref_cost, rtol=1e-11, atol=1e-9)
