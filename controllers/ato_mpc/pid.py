"""A simple reference ATO law: speed PID with resistance/gradient feed-forward, the same force on every carriage.

``a = v̇_r + k_p·(v_r − v_1) + k_i·∫(v_r − v_1)dt``, ``u_i = m·(a + a_res,i)`` clipped to the force limits and,
by default, to the force-rate limit (so it is a fair, comfortable baseline). Integral clamped (anti-windup).
Not from the paper: a sanity baseline for the MPCs and for lines where an MPC is not wanted.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from controllers.ato_mpc.core import Situation, limit_forces, reference_window
from railsim.physics.multipoint import G_MPS2, MultipointParams


@dataclass(frozen=True)
class PidParams:
    period_s: float = 0.1
    kp_per_s: float = 1.5
    ki_per_s2: float = 0.2
    integral_limit_mps2: float = 0.5
    rate_limited: bool = True


class PidLaw:
    def __init__(
        self, params: MultipointParams, settings: PidParams = PidParams(), reference_mode: str = "distance"
    ) -> None:
        self.p = params
        self.s = settings
        self.reference_mode = reference_mode
        self.reset()

    def reset(self) -> None:
        self.integral_mps = 0.0

    def forces(self, sit: Situation, u_prev_n: np.ndarray) -> tuple[np.ndarray, dict[str, Any]]:
        p, c = self.p, self.s
        xr, vr, v0 = reference_window(sit, c.period_s, 1, self.reference_mode)
        err = v0 - sit.v1_mps
        self.integral_mps = float(
            np.clip(
                self.integral_mps + err * c.period_s,
                -c.integral_limit_mps2 / max(c.ki_per_s2, 1e-12),
                c.integral_limit_mps2 / max(c.ki_per_s2, 1e-12),
            )
        )
        a = (float(vr[0]) - v0) / c.period_s + c.kp_per_s * err + c.ki_per_s2 * self.integral_mps
        v = sit.v1_mps
        a_res = (
            p.c0_mps2
            + p.c1_per_s * v
            + p.c2_per_m * v * v
            + G_MPS2 * np.asarray(sit.gradient_permille) * 1e-3
            + sit.wind_mps2
        )
        u = p.car_mass_kg * (a + a_res)
        if c.rate_limited:
            return limit_forces(u, u_prev_n, p, c.period_s), {"fallback": False}
        return np.clip(u, p.force_min_n, p.force_max_n), {"fallback": False}
