"""Paper B closed loop on the multi-point plant (scenarios A/B/C) and the registered ``ato``-role controllers
(SEMPC over scenario B's three sections: ``tests/long/test_paper001_scenario_b.py``)."""

from __future__ import annotations

import numpy as np
import pytest

import controllers.ato_mpc  # noqa: F401  (registers sempc, mpc, afsmc, pid_ato)
from controllers.ato_mpc.sim import run, scenario_a, scenario_c
from controllers.base import Observation, OwnState, StopTarget, create
from railsim.physics import dynamics
from railsim.physics.multipoint import MultipointParams
from railsim.physics.vehicle import preset

P = MultipointParams()


def _limits_hold(r) -> None:
    u = r.forces_n
    du = np.diff(np.vstack([np.zeros((1, P.n_cars)), u]), axis=0) / r.period_s
    assert np.all(u <= P.force_max_n + 1e-6) and np.all(u >= P.force_min_n - 1e-6)
    assert np.all(du <= P.force_rate_max_n_per_s * (1 + 1e-9)) and np.all(du >= P.force_rate_min_n_per_s * (1 + 1e-9))
    assert r.metrics["rate_violations"] == 0 and r.metrics["force_violations"] == 0


@pytest.mark.parametrize(
    "make",
    [
        lambda: scenario_a(1500.0),
        lambda: scenario_c("constant", 1500.0),
        lambda: scenario_c("harmonic", 1500.0),
    ],
    ids=["A", "C-constant", "C-harmonic"],
)
def test_sempc_respects_limits_and_stops_on_the_mark(make):
    sc = make()
    r = run(sc, "sempc")
    _limits_hold(r)
    assert len(r.stop_errors_m) == 1 and r.stop_errors_m[0] <= 0.3
    assert r.metrics["fallbacks"] == 0 and r.metrics["speed_limit_violations"] == 0
    assert r.metrics["max_coupler_deviation_m"] < P.coupler_slack_m


def test_mpc_b_baseline_breaks_the_rate_limit_that_sempc_keeps():
    r = run(scenario_a(600.0), "mpc_b")
    assert r.metrics["rate_violations"] > 0 and r.metrics["force_violations"] == 0


def _drive(name: str, params: dict, mark_m: float = 900.0):
    """Run a registered ato-role controller on the engine's single-mass plant to a stop."""
    veh = preset("cq3_6car")
    ctrl = create(name, params, veh)
    dt = 0.1
    st = dynamics.PlantState(0.0)
    x = 0.0
    cmds = []
    stop = StopTarget("S", mark_m, mark_m - 5.0, mark_m + 5.0)
    for k in range(3000):
        own = OwnState("t", x, st.speed_mps, st.applied_accel_mps2, veh.length_m)
        obs = Observation(k * dt, dt, own, veh, 5000.0, line_speed_mps=18.0, next_stop=stop)
        cmd = ctrl.command(obs)
        cmds.append(cmd)
        res = dynamics.step(veh, st, cmd.accel_mps2, dt)
        st = res.state
        x += res.advance_m
        if k > 50 and st.speed_mps == 0.0 and cmd.info.get("phase") == "hold":
            break
    return x, cmds


@pytest.mark.parametrize("name", ["sempc", "mpc", "afsmc", "pid_ato"])
def test_registered_controllers_stop_at_the_mark_on_the_engine_plant(name):
    x, cmds = _drive(name, {})
    assert abs(x - 900.0) <= 1.0
    assert all(np.isfinite(c.accel_mps2) for c in cmds)
    assert len(cmds[10].info["forces_n"]) == 6 and not any(c.fallback for c in cmds)


def test_bad_controller_parameters_are_rejected():
    with pytest.raises(ValueError, match="horizon"):
        create("sempc", {"horizon": 0}, preset("cq3_6car"))
    with pytest.raises(ValueError, match="reference_mode"):
        create("mpc", {"reference_mode": "sideways"}, preset("cq3_6car"))
    with pytest.raises(ValueError, match="bogus"):
        create("afsmc", {"bogus": 1}, preset("cq3_6car"))
