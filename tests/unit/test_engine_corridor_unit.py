"""Engine features the paper experiments need, in a real SUMO run (child process) on the straight corridor:
trains that start in motion at given offsets, a leader on a speed-versus-time profile, chained formations
(train 2 follows 1, train 3 follows 2), actuator noise and ballistic steps. Plus the profile's closed form.

Here: the tests of it that start no process; the others are in ``tests/sumo/test_engine_corridor.py``.
"""

from __future__ import annotations

import pytest

from controllers.speed_profile import make_speed_profile, reference
from railsim.physics.vehicle import preset


def test_profile_reference_closed_form() -> None:
    ctl = make_speed_profile(
        {
            "initial_kmh": 220,
            "segments": [
                {"at_s": 100, "to_kmh": 180, "accel_mps2": 0.2},
                {"at_s": 255, "to_kmh": 220, "accel_mps2": 0.2},
            ],
        },
        preset("hst_203m"),
    )
    p, v0 = ctl.params, 220 / 3.6
    ramp = (220 - 180) / 3.6 / 0.2  # 55.56 s
    assert reference(p, v0, 50.0) == (pytest.approx(v0), 0.0)
    assert reference(p, v0, 120.0) == (pytest.approx(v0 - 0.2 * 20.0), -0.2)
    assert reference(p, v0, 100.0 + ramp + 1.0) == (pytest.approx(180 / 3.6), 0.0)
    assert reference(p, v0, 265.0) == (pytest.approx(180 / 3.6 + 0.2 * 10.0), 0.2)
    assert reference(p, v0, 400.0) == (pytest.approx(v0), 0.0)


@pytest.mark.parametrize(
    "bad, field",
    [
        ({"segments": [{"at_s": 1, "to_kmh": 10}]}, "segments[0]"),
        ({"segments": [{"at_s": 5, "to_kmh": 10, "accel_mps2": 0}]}, "accel_mps2"),
        ({"k_speed_per_s": -1}, "k_speed_per_s"),
        ({"speed": 3}, "speed"),
    ],
)
def test_profile_rejects_bad_params(bad: dict, field: str) -> None:
    with pytest.raises(ValueError, match=field.replace("[", r"\[").replace("]", r"\]")):
        make_speed_profile(bad, preset("hst_203m"))
