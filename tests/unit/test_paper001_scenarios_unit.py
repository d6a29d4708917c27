"""Paper B's scenarios B, C-constant and C-harmonic in SUMO, and the measures the engine reports.

Here: the tests of it that start no process; the others are in ``tests/sumo/test_paper001_scenarios.py``.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from controllers.base import Command
from railsim.engine.extensions.paper001 import MultipointPlant
from railsim.physics.multipoint import MultipointParams, WindDisturbance


def _coast(wind: WindDisturbance, seconds: float = 1.0) -> float:
    p = MultipointParams()
    plant = MultipointPlant(p, 0.0, 20.0, wind)
    tr = SimpleNamespace(view=SimpleNamespace(gradient_at=lambda x: 0.0), energy_j=0.0)
    cmd = Command(0.0, info={"forces_n": (0.0,) * p.n_cars})
    v = 20.0
    for k in range(int(round(seconds / 0.1))):
        _, v, _ = plant.advance(0.1 * k, tr, cmd, 0.0, 0.1)
    return v


def test_wind_is_an_extra_resistance_on_the_plant() -> None:
    calm = _coast(WindDisturbance())
    assert calm - _coast(WindDisturbance(kind="constant", constant=0.2)) == pytest.approx(0.2, abs=1e-3)
    # 0.1 + 0.1 cos t over [0, 1 s]: ∫ = 0.1 + 0.1 sin 1
    gust = calm - _coast(WindDisturbance(kind="harmonic", offset=0.1, amplitude=0.1))
    assert gust == pytest.approx(0.1 + 0.1 * np.sin(1.0), abs=1e-3)
