"""The multi-point-mass plant (railsim.physics.multipoint): closed forms, conservation laws, standstill logic, inputs."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from railsim.physics.multipoint import (
    G_MPS2,
    MultipointParams,
    MultipointState,
    WindDisturbance,
    accelerations_mps2,
    coupler_forces_n,
    initial_state,
    state_from_relative,
    step,
)

P = MultipointParams()


def test_table1_defaults_and_si_conversion():
    assert P.n_cars == 6 and P.car_mass_kg == 64_800.0
    assert P.c0_mps2 == pytest.approx(9.888e-3) and P.c2_per_m == pytest.approx(1.95e-6)
    # spec §2.2: 640.7 N per carriage at standstill, 904.2 N at 44.4 m/s
    v = 44.4
    assert P.car_mass_kg * (P.c0_mps2 + P.c1_per_s * v + P.c2_per_m * v * v) == pytest.approx(904.2, abs=0.1)


def test_natural_length_is_an_equilibrium_of_the_couplers():
    s = initial_state(P, 100.0)
    assert np.allclose(coupler_forces_n(P, s.positions_m, s.speeds_mps), 0.0, atol=1e-6)
    # a stretched coupler pulls the front carriage back and the rear one forward, with equal magnitude
    x = s.positions_m.copy()
    x[3:] -= 0.001
    f = coupler_forces_n(P, x, s.speeds_mps)
    assert f[2] == pytest.approx(-1e4) and f[3] == pytest.approx(1e4) and f.sum() == pytest.approx(0.0, abs=1e-6)


@given(a=st.floats(0.05, 1.0), v0=st.floats(0.0, 30.0))
@settings(max_examples=15)
def test_uniform_force_accelerates_rigidly_with_the_closed_form(a, v0):
    """Each carriage gets m(a + c0'); with c1 = c2 = 0 the speed is v0 + a t exactly and couplers stay at rest."""
    p = MultipointParams(davis_c1_ns_per_m_t=0.0, davis_c2_ns2_per_m2_t=0.0)
    s = initial_state(p, 0.0, v0)
    u = np.full(p.n_cars, p.car_mass_kg * (a + p.c0_mps2))
    for _ in range(10):
        s = step(p, s, u, 0.1)
    assert np.allclose(s.speeds_mps, v0 + a * 1.0, atol=1e-9)
    assert s.lead_position_m == pytest.approx(v0 * 1.0 + 0.5 * a, abs=1e-8)
    assert np.allclose(np.diff(s.positions_m), -p.coupler_length_m, atol=1e-9)


def test_free_oscillation_conserves_momentum_and_energy():
    p = MultipointParams(davis_c0_n_per_t=0.0, davis_c1_ns_per_m_t=0.0, davis_c2_ns2_per_m2_t=0.0)
    x = initial_state(p, 0.0).positions_m.copy()
    x[0] += 0.002  # stretch the first coupler by 2 mm
    s = MultipointState(x, np.full(p.n_cars, 10.0))

    def energy(st_: MultipointState) -> float:
        stretch = st_.positions_m[:-1] - st_.positions_m[1:] - p.coupler_length_m
        return 0.5 * p.car_mass_kg * float(np.sum(st_.speeds_mps**2)) + 0.5 * p.coupler_stiffness_n_per_m * float(
            np.sum(stretch**2)
        )

    e0, m0 = energy(s), float(np.sum(s.speeds_mps))
    for _ in range(100):  # 10 s: ~40 periods of the fastest coupler mode
        s = step(p, s, np.zeros(p.n_cars), 0.1)
    assert float(np.sum(s.speeds_mps)) == pytest.approx(m0, rel=1e-12)
    # internal (oscillation) energy is 20 J on top of 19.4 MJ kinetic: compare the oscillation part
    e_int0 = e0 - 0.5 * p.total_mass_kg * 10.0**2
    e_int = energy(s) - 0.5 * p.total_mass_kg * 10.0**2
    assert e_int == pytest.approx(e_int0, rel=1e-3)


def test_gradient_and_wind_act_per_unit_mass():
    s = initial_state(P, 0.0, 10.0)
    zero = np.zeros(P.n_cars)
    base = accelerations_mps2(P, s.positions_m, s.speeds_mps, zero, zero)
    up = accelerations_mps2(P, s.positions_m, s.speeds_mps, zero, np.full(P.n_cars, 10.0), wind_mps2=0.2)
    assert np.allclose(base - up, G_MPS2 * 10.0e-3 + 0.2)


def test_wind_models():
    assert WindDisturbance("constant").accel_mps2(5.0) == pytest.approx(0.2)
    h = WindDisturbance("harmonic")
    assert h.accel_mps2(0.0) == pytest.approx(0.2) and h.accel_mps2(math.pi) == pytest.approx(0.0, abs=1e-12)
    assert WindDisturbance("constant", onset_s=10.0).accel_mps2(9.9) == 0.0
    assert WindDisturbance("constant", unit="n_per_kn").accel_mps2(0.0) == pytest.approx(0.2 * G_MPS2 / 1000)
    with pytest.raises(ValueError, match="kind"):
        WindDisturbance("gale")


def test_holding_brake_on_a_down_gradient_and_release():
    s = initial_state(P, 0.0)
    assert s.held
    down = lambda x: np.full_like(x, -30.0)  # noqa: E731
    s1 = step(P, s, np.zeros(P.n_cars), 1.0, down)
    assert s1.held and s1.lead_position_m == 0.0
    # uphill: traction below the standstill resistance does not move the train, above it does
    up = lambda x: np.full_like(x, 10.0)  # noqa: E731
    need = P.car_mass_kg * (P.c0_mps2 + G_MPS2 * 10e-3)
    assert step(P, s, np.full(P.n_cars, 0.9 * need), 1.0, up).lead_position_m == 0.0
    moved = step(P, s, np.full(P.n_cars, 1.5 * need), 1.0, up)
    assert not moved.held and moved.lead_speed_mps > 0.0


def test_braking_train_stops_and_never_reverses():
    s = initial_state(P, 0.0, 2.0)
    s = MultipointState(s.positions_m, s.speeds_mps, held=False)
    for _ in range(40):
        s = step(P, s, np.full(P.n_cars, -5e4), 0.1)
        assert np.all(s.speeds_mps >= 0.0)
    assert s.held and np.all(s.speeds_mps == 0.0)
    # distance ≈ v²/(2b) with b = 5e4/m + c0'
    b = 5e4 / P.car_mass_kg + P.c0_mps2
    assert s.lead_position_m == pytest.approx(2.0**2 / (2 * b), abs=0.05)


def test_forces_are_saturated():
    s = initial_state(P, 0.0, 5.0)
    a = step(P, s, np.full(P.n_cars, 1e9), 0.1)
    b = step(P, s, np.full(P.n_cars, P.force_max_n), 0.1)
    assert np.allclose(a.speeds_mps, b.speeds_mps)


def test_relative_coordinates_round_trip():
    s = initial_state(P, 50.0, 3.0)
    r = s.relative()
    assert r[0] == 50.0 and np.allclose(r[1:6], -1.2) and r[6] == 3.0
    back = state_from_relative(r)
    assert np.allclose(back.positions_m, s.positions_m) and np.allclose(back.speeds_mps, s.speeds_mps)


def test_bad_inputs_raise():
    s = initial_state(P, 0.0)
    with pytest.raises(ValueError, match="NaN"):
        step(P, s, np.full(P.n_cars, np.nan), 0.1)
    with pytest.raises(ValueError, match="dt_s"):
        step(P, s, np.zeros(P.n_cars), 0.0)
    with pytest.raises(ValueError, match="expected 6"):
        step(P, s, np.zeros(3), 0.1)
    with pytest.raises(ValueError, match="car_mass_kg"):
        MultipointParams(car_mass_kg=-1.0)
