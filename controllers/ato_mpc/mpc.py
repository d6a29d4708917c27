"""The MPC baselines of Paper B (spec §2.15, §6 A15), both on the same model and QP code as SEMPC.

* **MPC-A** (default ``mpc``): problem (16) — SEMPC without the terminal ingredients (the last stage keeps
  the ordinary weight ``Q_ξ``); same Δu decision variable, same hard u/Δu limits. It isolates the paper's
  stated contribution.
* **MPC-B**: "traction/braking force as the control variable, without taking into account its variation"
  — the decision is U, penalised by a small ``r_u‖U‖²``, with force limits only and **no force-rate limit**;
  the variant that can reproduce the paper's Fig. 5b/7b rate violations. (Implemented as an equivalent
  re-parametrisation over ΔU, see :mod:`controllers.ato_mpc.qp`.)
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from controllers.ato_mpc.qp import MpcSettings
from controllers.ato_mpc.sempc import MpcLaw
from railsim.physics.multipoint import MultipointParams

MPC_VARIANTS = ("A", "B")


def mpc_settings(variant: str = "A", **overrides: Any) -> MpcSettings:
    if variant == "A":
        return replace(MpcSettings(terminal="none"), **overrides)
    if variant == "B":
        return replace(MpcSettings(terminal="none", decision="force"), **overrides)
    raise ValueError(f"variant: expected one of {', '.join(MPC_VARIANTS)}, got {variant!r}")


def make_mpc_law(
    params: MultipointParams, variant: str = "A", reference_mode: str = "distance", **overrides: Any
) -> MpcLaw:
    return MpcLaw(params, mpc_settings(variant, **overrides), reference_mode)
