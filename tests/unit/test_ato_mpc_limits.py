"""Every Paper B controller respects the same actuator envelope: 0 force and 0 force-rate (60 kN/s) violations over
scenarios A, C-constant and C-harmonic in the numpy runner; scenario B (compressed: three sections, the longest
closed loops) is checked the same way in ``tests/long/test_paper001_scenario_b.py``."""

from __future__ import annotations

import pytest

from controllers.ato_mpc.reference import Limit
from controllers.ato_mpc.sim import run, scenario_a, scenario_b, scenario_c


def _b_short():
    sc = scenario_b(dwell_s=3.0, line_speed_mps=25.0)
    return type(sc)(
        **{
            **sc.__dict__,
            "stops_m": (800.0, 1500.0, 2100.0),
            "limits": (Limit(300.0, 500.0, 12.0), Limit(1700.0, 1850.0, 10.0)),
        }
    )


SCEN = {
    "A": lambda: scenario_a(1500.0),
    "B": _b_short,
    "C-constant": lambda: scenario_c("constant", 1500.0),
    "C-harmonic": lambda: scenario_c("harmonic", 1500.0),
}


CONTROLLERS = ("sempc", "mpc", "afsmc", "pid")


def check_envelope(scenario: str, controller: str) -> None:
    """0 force and 0 force-rate violations of ``controller`` on ``scenario`` (a key of :data:`SCEN`)."""
    m = run(SCEN[scenario](), controller).metrics
    assert m["rate_violations"] == 0 and m["force_violations"] == 0, m["max_force_rate_n_per_s"]


@pytest.mark.parametrize("scenario", [s for s in SCEN if s != "B"])
@pytest.mark.parametrize("controller", CONTROLLERS)
def test_zero_force_and_rate_violations(controller: str, scenario: str) -> None:
    check_envelope(scenario, controller)


def test_afsmc_without_the_limiter_breaks_the_rate_limit() -> None:
    """The check can fail: the old force-box-only AFSMC violates the 60 kN/s limit on the same scenario."""
    m = run(SCEN["A"](), "afsmc", law_overrides={"rate_limited": False}).metrics
    assert m["rate_violations"] > 0


def _afsmc_steps(rate_limited: bool, steps: int = 30) -> tuple[list, list, list]:
    """AFSMC alone on a constructed case: a standing train 5 s behind its time reference (paper-literal mode: the
    reference already runs at 4.5 m/s, so ``s > 0``) against a strong headwind it knows of (0.6 m/s²): the demand
    exceeds both the force box and the rate limit for many steps."""
    import numpy as np

    from controllers.ato_mpc.afsmc import AfsmcLaw, AfsmcParams
    from controllers.ato_mpc.core import Situation
    from controllers.ato_mpc.reference import SpeedDistanceProfile, time_profile
    from railsim.physics.multipoint import MultipointParams

    p = MultipointParams()
    law = AfsmcLaw(p, AfsmcParams(rate_limited=rate_limited), reference_mode="time")
    rel = np.concatenate(([0.0], np.full(p.n_cars - 1, -p.coupler_length_m), [0.0], np.zeros(p.n_cars - 1)))
    profile = SpeedDistanceProfile(stop_m=5000.0)
    tref = time_profile(profile, 0.0, 0.1)
    sit = Situation(5.0, rel, np.zeros(p.n_cars), profile, tref, 5.0, wind_mps2=0.6)
    u_prev = np.zeros(p.n_cars)
    forces, thetas, frozen = [], [], []
    for _ in range(steps):
        u, info = law.forces(sit, u_prev)
        forces.append((u_prev.copy(), u.copy()))
        thetas.append(float(np.max(np.abs(law.theta))))
        frozen.append(info["windup_frozen"])
        u_prev = u
    return forces, thetas, frozen


def test_afsmc_rate_limiter_and_anti_windup_on_a_constructed_case() -> None:
    """Every AFSMC step stays within 60 kN/s × T and the force box while the demand is far beyond both, and the
    adaptive estimate does not integrate (conditional integration) while the limit binds in the direction of s."""
    from railsim.physics.multipoint import MultipointParams

    p = MultipointParams()
    forces, thetas, frozen = _afsmc_steps(rate_limited=True)
    for prev, u in forces:
        assert max(abs(u - prev)) <= p.force_rate_max_n_per_s * 0.1 * (1 + 1e-12)
        assert u.max() <= p.force_max_n and u.min() >= p.force_min_n
    assert forces[-1][1].max() == pytest.approx(p.force_max_n)  # it did reach the box: the demand is beyond it
    assert all(f == p.n_cars for f in frozen) and max(thetas) == 0.0  # no wind-up while limited
    unlimited, _, _ = _afsmc_steps(rate_limited=False, steps=2)
    assert max(abs(unlimited[0][1] - unlimited[0][0])) > p.force_rate_max_n_per_s * 0.1  # the check can fail


def test_afsmc_memberships_stay_finite_far_outside_their_span() -> None:
    """A train 100+ m behind a time reference (C-constant, paper-literal mode) drives s far outside the Gaussian
    memberships; every firing strength underflows, and the plain ratio was 0/0 (NaN forces, then an internal error
    in the carriage plant). The normalised strengths stay finite and the outermost rule takes the weight."""
    import numpy as np

    from controllers.ato_mpc.afsmc import AfsmcLaw
    from railsim.physics.multipoint import MultipointParams

    psi = AfsmcLaw(MultipointParams())._psi(np.array([150.0, -80.0]), np.array([40.0, 0.0]))
    assert np.all(np.isfinite(psi)) and np.allclose(psi.sum(axis=1), 1.0)
    assert psi[0].argmax() == 24 and psi[1].argmax() == 2  # (s, ṡ) = (+max, +max) and (−max, 0)


def test_a_law_returning_nan_falls_back_to_rate_limited_braking() -> None:
    import numpy as np

    from controllers.ato_mpc.core import AtoDriver, Situation
    from controllers.ato_mpc.reference import SpeedDistanceProfile
    from railsim.physics.multipoint import MultipointParams

    class Broken:
        resets = 0

        def forces(self, sit, u_prev_n):
            return np.full(u_prev_n.size, np.nan), {}

        def reset(self) -> None:
            Broken.resets += 1

    p = MultipointParams()
    driver = AtoDriver(Broken(), p, 0.1)
    driver.u_prev = np.full(p.n_cars, 30e3)
    rel = np.concatenate(([0.0], np.full(p.n_cars - 1, -p.coupler_length_m), [10.0], np.zeros(p.n_cars - 1)))
    u, info = driver.step(Situation(0.0, rel, np.zeros(p.n_cars), SpeedDistanceProfile(stop_m=5000.0)))
    assert np.all(np.isfinite(u)) and np.allclose(u, 30e3 - 6e3)  # towards the holding brake, one rate step
    assert info["fallback"] and "non-finite" in info["fallback_reason"] and Broken.resets >= 1
    assert driver.stats.fallbacks == 1 and np.all(np.isfinite(driver.u_prev))
