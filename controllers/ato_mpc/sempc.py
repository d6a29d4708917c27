"""SEMPC — Paper B's stability-enhanced MPC: the Δu-MPC with the terminal cost ``Y(N+1)ᵀ P Y(N+1)``.

Spec §2.12 (Eq. (17)–(20), with corrections) and §6 A7: ``P`` is the infinite-horizon tail cost under the
linear feedback ``ΔU = K·Y``. By default K and P come from the DARE of the augmented model (K is the LQR gain,
P then solves the paper's Lyapunov equation ``(Ã+B̃K)ᵀP(Ã+B̃K) − P + Q + KᵀRK = 0``); ``terminal="lyapunov"``
takes a different stabilising K and solves that Lyapunov equation directly. Both are computed once per
controller at a nominal speed and checked (ρ(Ã+B̃K) < 1, P ≻ 0, residual) in
:func:`controllers.ato_mpc.qp.terminal_ingredients`; P replaces the last stage weight
(``Q̄ = blkdiag(I_{N−1}⊗Q_ξ, P)``) and by default only its state block acts (``terminal_blocks="x"``: the
paper's error Y has no u-part); ``"full"`` also penalises the last force against the feed-forward force.

As the paper has it, there is no terminal set: the "stability enhancement" is the terminal cost alone (spec
§2.14). The QP itself, its scaling and its fallback are in :mod:`controllers.ato_mpc.qp`.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from controllers.ato_mpc.core import Situation, reference_window
from controllers.ato_mpc.qp import CondensedMpc, MpcSettings, ReferenceWindow
from railsim.physics.multipoint import MultipointParams


class MpcLaw:
    """Carriage-level law around :class:`CondensedMpc` (used by SEMPC and both MPC baselines)."""

    def __init__(self, params: MultipointParams, settings: MpcSettings, reference_mode: str = "distance") -> None:
        self.p = params
        self.settings = settings
        self.reference_mode = reference_mode
        self.mpc = CondensedMpc(params, settings)

    def reset(self) -> None:
        self.mpc.reset()

    def window(self, sit: Situation) -> ReferenceWindow:
        s = self.settings
        xr, vr, v0 = reference_window(sit, s.period_s, s.horizon_p, self.reference_mode)
        return ReferenceWindow(
            x_ref_m=xr,
            v_ref_mps=vr,
            v_lin_mps=v0,
            x_max_m=max(sit.profile.stop_m, sit.x1_m),
            v_max_mps=float(sit.profile.static_limit_mps(sit.x1_m)),
            gradient_permille=np.asarray(sit.gradient_permille, dtype=float),
            wind_mps2=sit.wind_mps2,
        )

    def forces(self, sit: Situation, u_prev_n: np.ndarray) -> tuple[np.ndarray, dict[str, Any]]:
        u, info = self.mpc.solve(sit.rel_state, u_prev_n, self.window(sit))
        return u, {
            "status": info.status,
            "fallback": info.fallback,
            "fallback_reason": f"QP not solved (OSQP: {info.status}); {self.mpc.s.fallback}" if info.fallback else "",
            "solve_time_s": info.solve_time_s,
            "iterations": info.iterations,
            "max_slack": info.max_slack,
        }


def sempc_settings(**overrides: Any) -> MpcSettings:
    """SEMPC defaults: terminal cost from the DARE (override any field)."""
    return replace(MpcSettings(terminal="dare"), **overrides)


def make_sempc_law(params: MultipointParams, reference_mode: str = "distance", **overrides: Any) -> MpcLaw:
    return MpcLaw(params, sempc_settings(**overrides), reference_mode)
