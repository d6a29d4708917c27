"""Paper D scenario runner: every scenario safe, CA only where designed, comm-delay × load sweep, RDBM vs ADBM."""

from __future__ import annotations

import numpy as np
import pytest

from controllers.monorail.collision_avoidance import CaParams
from controllers.monorail.scenarios import SCENARIOS, build_scenario, run_scenario

COUPLING = ("in_station", "track_accel", "track_decel")


@pytest.mark.parametrize("load", ["empty", "loaded"])
@pytest.mark.parametrize("name", SCENARIOS)
def test_scenario_safe_and_guarded(name: str, load: str) -> None:
    res = run_scenario(build_scenario(name, load))
    m = res.metrics
    assert not m["collision"]
    for pair in m["pairs"].values():
        assert pair["min_gap_m"] > 0.0
        assert pair["unguarded_steps"] == 0  # deeper than the debounce band below the trigger only while CA brakes
    if name in COUPLING:
        assert all(t is not None for t in m["time_to_couple_s"].values())
        for label in ("L-F1", "F1-F2"):
            assert m["pairs"][label]["final_gap_m"] == pytest.approx(5.0, abs=0.5)
    else:
        assert m["ca_intervals"]["F1"], "the scenario is designed to cross F1's trigger"
    if name == "ca_obstacle":  # latched to standstill: one interval per vehicle, emergency throughout
        for i, veh in enumerate(("L", "F1", "F2")):
            ((on, off),) = m["ca_intervals"][veh]
            k_on = int(round(on / 0.1))
            assert res.emergency[k_on:, i].all() and np.all(np.diff(res.v_mps[k_on + 1 :, i]) <= 1e-12)
            assert res.v_mps[-1, i] == 0.0


BARE = {"trigger_dwell_s": 0.0, "trigger_band_m": 0.0, "rearm_s": 0.0, "release_margin_m": 0.0}


def _triggers(load: str, k_cap_per_s: float | None = None, bare: bool = False) -> tuple[int, int, dict]:
    """(CA triggers, emergency-brake intervals, metrics) of accelerated coupling, optionally with the old cap
    gain and/or the paper's bare trigger."""
    import dataclasses

    from controllers.monorail.coupling import ApfParams

    cfg = build_scenario("track_accel", load)
    if bare:
        cfg = dataclasses.replace(cfg, ca=dataclasses.replace(cfg.ca, **BARE))
    if k_cap_per_s is not None:
        cfg = dataclasses.replace(cfg, apf=ApfParams(k_cap_per_s=k_cap_per_s))
    m = run_scenario(cfg).metrics
    return sum(p["ca_triggers"] for p in m["pairs"].values()), sum(map(len, m["emergency_intervals"].values())), m


@pytest.mark.parametrize("load", ["empty", "loaded"])
def test_accelerated_coupling_never_fires_the_emergency_brake(load: str) -> None:
    """Normal accelerated coupling (the scenario's defaults: APF safety cap 2/s, debounced trigger)
    couples without a single CA trigger or emergency brake, collision-free."""
    ca, eb, m = _triggers(load)
    assert ca == 0 and eb == 0
    assert not m["collision"] and all(t is not None for t in m["time_to_couple_s"].values())


def test_the_old_cap_and_the_bare_trigger_chatter() -> None:
    """The checks above can fail: with the old cap gain (1/s) and the paper's bare trigger the loaded follower
    fires CA repeatedly; each remedy alone still fires (the pure runner needs both)."""
    assert _triggers("loaded", k_cap_per_s=1.0, bare=True)[0] >= 5
    assert _triggers("loaded", k_cap_per_s=1.0)[0] >= 1  # debounce alone
    assert _triggers("loaded", bare=True)[0] >= 1  # tighter cap alone


def test_dmpc_couples() -> None:
    m = run_scenario(build_scenario("track_decel", "empty", coupling_law="dmpc")).metrics
    assert not m["collision"] and all(t is not None for t in m["time_to_couple_s"].values())


def test_comm_delay_load_sweep() -> None:
    rows = []
    for delay in (0.1, 0.5, 1.0, 2.0):
        for load in ("empty", "loaded"):
            for name in ("track_accel", "track_decel"):
                m = run_scenario(build_scenario(name, load, comm_delay_s=delay)).metrics
                assert not m["collision"]
                coupled = all(t is not None for t in m["time_to_couple_s"].values())
                ca = {k: len(v) for k, v in m["ca_intervals"].items() if v}
                rows.append((delay, load, name, coupled, ca))
    print("\ndelay load scenario coupled ca_activations")
    for row in rows:
        print(*row)
    assert all(r[3] for r in rows if r[0] <= 1.0)


def test_rdbm_collides_where_adbm_does_not() -> None:
    """Loaded obstacle case with load-unaware assumptions (own 1.5 m/s², lead 1.0 m/s²): the overloaded F1 really
    brakes at 0.92 m/s². RDBM credits the lead's braking distance and only covers the *difference*, so F1's
    over-estimated braking is not absorbed; ADBM keeps the lead's whole braking distance as slack."""
    out = {}
    for mode in ("rdbm", "adbm"):
        ca = CaParams(
            threshold_mode=mode,
            assumed_own_decel_mps2=1.5,
            assumed_object_decel_mps2=1.0,
            law="bang_bang",
            latch="never",
            release_margin_m=0.0,
            trigger_dwell_s=0.0,
            trigger_band_m=0.0,
            rearm_s=0.0,
        )  # the paper's bare trigger: compares the modes only
        out[mode] = run_scenario(build_scenario("ca_obstacle", "loaded", ca=ca)).metrics
    assert out["rdbm"]["collision"] and out["rdbm"]["pairs"]["L-F1"]["collision"]
    assert not out["adbm"]["collision"]


def test_arrival_ca_adds_gentle_braking_to_the_faulty_service_braking() -> None:
    """A27 arrival (pure runner, the SUMO file's parameters): the CA adds a gentle increment to the followers'
    faulty 0.15 m/s² service braking — one long CA interval for F1 (released above 28 m at a low speed), the gap
    stays above the CA's s_min of 5 m, no collision. The same weights in the engine's plain minimum do not brake
    at all until the gap is far smaller (the QP's absolute command is then priced, not the increment)."""
    import dataclasses

    cfg = build_scenario("ca_arrival", "empty")
    res = run_scenario(cfg)
    m = res.metrics
    assert not m["collision"] and m["pairs"]["L-F1"]["unguarded_steps"] == 0
    ((on, off),) = m["ca_intervals"]["F1"]
    assert on < 2.0 and off - on > 20.0
    k_off = int(round(off / cfg.dt_s))
    assert res.gap_m[k_off, 1] > 28.0 and res.v_mps[k_off, 1] < 2.0
    assert 10.0 < m["pairs"]["L-F1"]["min_gap_m"] < 28.0 and m["pairs"]["F1-F2"]["min_gap_m"] > cfg.ca.s_min_m
    plain = run_scenario(dataclasses.replace(cfg, ca=dataclasses.replace(cfg.ca, additive=False))).metrics
    assert plain["pairs"]["L-F1"]["min_gap_m"] < m["pairs"]["L-F1"]["min_gap_m"] - 5.0
