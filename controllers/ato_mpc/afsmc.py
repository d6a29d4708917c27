"""AFSMC — the adaptive fuzzy sliding-mode baseline of Paper B (spec §2.15, §6 A16; design not in the paper).

The paper only cites Guo et al. (IET ITS 17(2), 2023). This is the spec's per-carriage sketch:

* tracking errors ``e_i = x_r,i − x_i``, ``ė_i = v_r − v_i`` with ``x_r,i = x_r − (i−1)·l_d``;
* sliding surface ``s_i = ė_i + λ e_i``;
* control ``u_i = m[v̇_r + λ ė_i + a_res,i(v_i) − F_coupler,i/m + f̂_i] + m·k_sw·sat(s_i/φ)`` — feedback
  linearisation of Eq. (1) (resistance, gradient and the measured coupler force are cancelled) plus a
  boundary-layer switching term;
* ``f̂_i = θ_iᵀψ(s_i, ṡ_i)``: a zero-order Takagi–Sugeno system with 5×5 Gaussian memberships on ``s`` and
  ``ṡ`` (normalised firing strengths ψ), adapted by ``θ̇_i = γ s_i ψ`` (Euler at the control period, with a
  projection ``|θ| ≤ θ_max`` so the estimate stays bounded) — it learns what the model misses (wind);
* **actuator envelope and anti-windup — our design, the paper gives none** (a fair baseline must
  respect the same limits as SEMPC/MPC/PID): the demanded force passes :func:`~controllers.ato_mpc.core.limit_forces`
  — the force-rate limit ``|u − u_prev| ≤ 60 kN/s·T`` (Table 1, Eq. 15), then the force box ``[u_min, u_max]``
  (Eq. 14). The adaptive estimate f̂ is an integrator of ``s``, so while the actuator cannot deliver the demand it
  would wind up (and overshoot once the limit releases). Anti-windup by *conditional integration*: the update
  ``θ̇_i = γ s_i ψ`` is frozen for carriage i whenever its applied force differs from the demand (by more than
  1 N) **and** ``s_i`` pushes the demand further beyond the limit (u is increasing in s: demand above the applied
  force with s_i > 0, or below it with s_i < 0). The adaptation runs again as soon as the limit stops binding or
  s changes sign. ``rate_limited=False`` restores the force-box-only law (the old behaviour, 49–416 rate
  violations per run).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from controllers.ato_mpc.core import Situation, limit_forces, reference_window
from railsim.physics.multipoint import G_MPS2, MultipointParams


@dataclass(frozen=True)
class AfsmcParams:
    period_s: float = 0.1
    lambda_per_s: float = 0.5
    switching_gain_mps2: float = 0.05
    boundary_layer_mps: float = 0.2
    adaptation_gain: float = 2.0
    theta_max_mps2: float = 0.5
    s_span_mps: float = 1.0  # membership centres on s span ±this
    sdot_span_mps2: float = 0.5
    rate_limited: bool = True  # force-rate limit + anti-windup (our design, see module docstring)
    windup_tolerance_n: float = 1.0  # |applied − demanded| above this counts as "limit binding"


class AfsmcLaw:
    def __init__(
        self, params: MultipointParams, settings: AfsmcParams = AfsmcParams(), reference_mode: str = "distance"
    ) -> None:
        self.p = params
        self.s = settings
        self.reference_mode = reference_mode
        self.centres_s = np.linspace(-settings.s_span_mps, settings.s_span_mps, 5)
        self.centres_sd = np.linspace(-settings.sdot_span_mps2, settings.sdot_span_mps2, 5)
        self.reset()

    def reset(self) -> None:
        self.theta = np.zeros((self.p.n_cars, 25))
        self.s_prev: np.ndarray | None = None

    def _psi(self, s: np.ndarray, sd: np.ndarray) -> np.ndarray:
        """Normalised firing strengths, computed in logs: far outside the membership span (a train 100 m behind a
        time reference) every Gaussian underflows to 0 and the plain ratio is 0/0; in logs the outermost rule
        takes the whole weight, as the ratio tends to."""
        ws = self.s.s_span_mps / 2.0
        wd = self.s.sdot_span_mps2 / 2.0
        log_s = -0.5 * ((s[:, None] - self.centres_s[None, :]) / ws) ** 2
        log_d = -0.5 * ((sd[:, None] - self.centres_sd[None, :]) / wd) ** 2
        log_fire = (log_s[:, :, None] + log_d[:, None, :]).reshape(s.size, 25)
        fire = np.exp(log_fire - np.max(log_fire, axis=1, keepdims=True))
        return fire / np.sum(fire, axis=1, keepdims=True)

    def forces(self, sit: Situation, u_prev_n: np.ndarray) -> tuple[np.ndarray, dict[str, Any]]:
        p, c = self.p, self.s
        n = p.n_cars
        period = c.period_s
        xr, vr, v0 = reference_window(sit, period, 1, self.reference_mode)
        x_r_now = float(xr[0] - 0.5 * (v0 + vr[0]) * period)
        vdot_r = (float(vr[0]) - v0) / period
        rel = sit.rel_state
        x = rel[0] + np.concatenate(([0.0], np.cumsum(rel[1:n])))
        v = rel[n] + np.concatenate(([0.0], np.cumsum(rel[n + 1 :])))
        x_ri = x_r_now - p.coupler_length_m * np.arange(n)
        e = x_ri - x
        ed = v0 - v
        s = ed + c.lambda_per_s * e
        sd = np.zeros(n) if self.s_prev is None else (s - self.s_prev) / period
        self.s_prev = s
        psi = self._psi(s, sd)
        f_hat = np.sum(self.theta * psi, axis=1)
        stretch = x[:-1] - x[1:] - p.coupler_length_m
        tension = p.coupler_stiffness_n_per_m * stretch
        coupler = np.zeros(n)
        coupler[:-1] -= tension
        coupler[1:] += tension
        a_res = (
            p.c0_mps2
            + p.c1_per_s * v
            + p.c2_per_m * v * np.abs(v)
            + G_MPS2 * np.asarray(sit.gradient_permille) * 1e-3
            + sit.wind_mps2
        )
        sat = np.clip(s / c.boundary_layer_mps, -1.0, 1.0)
        u_des = p.car_mass_kg * (vdot_r + c.lambda_per_s * ed + a_res + f_hat + c.switching_gain_mps2 * sat) - coupler
        if c.rate_limited:
            u = limit_forces(u_des, u_prev_n, p, period)
        else:
            u = np.clip(u_des, p.force_min_n, p.force_max_n)
        short = u_des - u  # > 0: the actuator delivers less than demanded
        winding = (np.abs(short) > c.windup_tolerance_n) & (np.sign(short) == np.sign(s))
        gain = np.where(winding, 0.0, period * c.adaptation_gain * s)
        self.theta = np.clip(self.theta + gain[:, None] * psi, -c.theta_max_mps2, c.theta_max_mps2)
        return u, {"fallback": False, "f_hat_mps2": float(np.mean(f_hat)), "windup_frozen": int(np.sum(winding))}
