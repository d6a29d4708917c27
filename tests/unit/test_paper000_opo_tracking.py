"""OPO's online parameter correction improves late-phase spacing tracking over fixed Θ (spec 000 §2.8).

Short-horizon S-E: two trains already coupled at D^(e) (220 km/h), the leader's 220 → 180 → 220 km/h manoeuvre
known to the follower, noise SD 0.01 m/s², a reduced MSMFO budget (P = 20, K = 10) so the test runs in seconds.
Under the running resistance each fixed-Θ law settles at a spacing offset (IDM+ ≈ 6.9 m with Θ_2, CACC+ ω/θ4 ≈
8.8 m); OPO re-tunes Θ against J^(DMPC) every step and must end closer to D^(e). Measured over [150, 300) s.
"""

from __future__ import annotations

import numpy as np
import pytest

import controllers
from controllers.mcf_dmpc.metrics import follower_metrics
from controllers.mcf_dmpc.sim import KMH, S_E_SEGMENTS, paper000_leader, run_platoon
from controllers.mcf_dmpc.spacing import desired_spacing_m, paper000_vehicle


def _late_error(method: str, seed: int) -> float:
    veh = paper000_vehicle()
    f = controllers.create(method, {"theta_preset": "train2", "population": 20, "iterations": 10, "seed": seed}, veh)
    d0 = float(desired_spacing_m(220 * KMH, 220 * KMH))
    run = run_platoon(
        [f],
        (d0, 0.0),
        (220 * KMH, 220 * KMH),
        300,
        seed=seed,
        leader=paper000_leader(220.0, S_E_SEGMENTS),
    )
    (m,) = follower_metrics(run, 150.0, 300.0)
    assert m.min_safety_margin_m > 0.0
    return m.late_mean_abs_spacing_error_m


def test_opo_beats_fixed_parameters_in_late_phase() -> None:
    mcf = np.array([_late_error("mcf_dmpc", s) for s in (0, 1)])
    opo = np.array([_late_error("opo_mcf_dmpc", s) for s in (0, 1)])
    assert np.all(opo < mcf), (opo, mcf)
    assert opo.mean() < 0.75 * mcf.mean(), (opo, mcf)  # a clear margin, not a tie broken by noise


def _sd_late(method: str, extra: dict) -> tuple[list[float], list[np.ndarray]]:
    """S-D (3 trains, 500 s), reduced MSMFO budget: late-phase mean |ΔS − D^(e)| per follower and the final Θ."""
    veh = paper000_vehicle()
    params = {"population": 20, "iterations": 10, **extra}
    fs = [controllers.create(method, {"theta_preset": p, **params}, veh) for p in ("train2", "train3")]
    run = run_platoon(fs, (2000.0, 1500.0, 0.0), (220 * KMH, 200 * KMH, 180 * KMH), 500, seed=0)
    ms = follower_metrics(run, 300.0, 500.0)
    assert all(m.min_safety_margin_m > 0.0 and m.fallbacks == 0 for m in ms)
    thetas = [np.asarray(run.infos[-1][i].get("theta", np.full(10, np.nan))) for i in (1, 2)]
    return [m.late_mean_abs_spacing_error_m for m in ms], thetas


def test_opo_offsets_remove_the_resistance_offset_the_paper_reading_keeps() -> None:
    """S-D late phase [300, 500) s. Fixed Θ (MCF-DMPC) sits at the laws' resistance offsets (~5–7 m); OPO on
    θ1 … θ7 only (the paper's reading) shrinks them by raising gains, but the J-optimal gains stay moderate
    (~4 m); OPO with the control offsets (ours) learns b ≈ ω(220 km/h) = 0.0966 m/s² and tracks D^(e) to the
    noise floor (< 1.5 m, the DMPC baseline's range)."""
    fixed, _ = _sd_late("mcf_dmpc", {})
    paper, _ = _sd_late("opo_mcf_dmpc", {"opo_bias": False})
    ours, thetas = _sd_late("opo_mcf_dmpc", {})
    for k in range(2):
        assert ours[k] < 1.5 < paper[k] < fixed[k], (ours, paper, fixed)
    omega = 0.0966
    for th in thetas:  # the offsets of the laws in use converge to the running resistance at 220 km/h
        assert np.median(th[7:]) == pytest.approx(omega, abs=0.02), th
