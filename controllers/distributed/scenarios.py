"""Built-in Paper C scenarios: ``zhang2024_fig1``, the numerical example of Sec. IV (spec 002 §3.2).

Six trains on Track 1, train 1 in front (``x_ij = x_i − x_j > 0`` for ``i`` ahead), ``T = 1 s``, ``v_r = 80 m/s``,
``d = 5000 m`` per hop, Davis ``a = 1.176e-2``, ``b = 7.7616e-4``, ``c = 1.6e-5`` (per unit mass), ``ρ ∈ [75, 85]``,
``μ ∈ [−11, 11]``. At ``k_a = 1000`` train 2 leaves and train 5 joins at ``x_5 = 89000 m``, ``v_5 = 80 m/s``; the
control of step 1000 already uses the new graph (erratum A5). Horizon 2000 (A6).

Two corrections of the printed text, both with the paper's literal value still selectable so the validator's
rejection of it can be shown (spec 002 A1, A2):

* ``γ̄_{i−1,i} = 10000 m`` (printed 1000 m, which is below ``d = 5000 m`` and below the initial ``x_23 = 8000 m``);
* ``b = 7.7616e-4`` (printed garbled as "7.7616 × 10^{-2} … 10^{-4}"; ``7.7616e-2`` violates Assumption 2.4).

Topology (Fig. 2 is missing from the text, A4). ``"union"`` (default): every listed edge whose two trains are
present — ``E_a = {1-2, 2-3, 1-3, 3-4, 4-6}``, ``E_b = {1-3, 3-4, 4-5, 5-6, 4-6}``. ``"path"``: predecessor and
successor only — ``E_a = {1-2, 2-3, 3-4, 4-6}``, ``E_b = {1-3, 3-4, 4-5, 5-6}``.
"""

from __future__ import annotations

from collections.abc import Callable

from controllers.distributed.graph import CommGraph, Edge, EdgeAdd, EdgeData, EdgeRemove, TrainJoin, TrainLeave
from controllers.distributed.model import TrainParams
from controllers.distributed.reference import Scenario

TOPOLOGIES = ("union", "path")


def zhang2024_train(resist_b_per_s: float = 7.7616e-4) -> TrainParams:
    """The (identical) parameters of every train in Sec. IV."""
    return TrainParams(
        resist_a_mps2=1.176e-2,
        resist_b_per_s=resist_b_per_s,
        resist_c_per_m=1.6e-5,
        speed_min_mps=75.0,
        speed_max_mps=85.0,
        input_min_mps2=-11.0,
        input_max_mps2=11.0,
    )


def zhang2024_fig1(
    topology: str = "union",
    *,
    horizon_k: int = 2000,
    switch_k: int = 1000,
    gamma_hi_adjacent_m: float = 10000.0,
    resist_b_per_s: float = 7.7616e-4,
    sample_time_s: float = 1.0,
) -> Scenario:
    """The Sec. IV example with the corrected parameters (keyword arguments reproduce the printed ones)."""
    if topology not in TOPOLOGIES:
        raise ValueError(f"topology: expected one of {', '.join(TOPOLOGIES)}, got {topology!r}")
    p = zhang2024_train(resist_b_per_s)
    adjacent = EdgeData(d_m=5000.0, gamma_lo_m=100.0, gamma_hi_m=gamma_hi_adjacent_m)
    skip = EdgeData(d_m=10000.0, gamma_lo_m=5100.0, gamma_hi_m=15000.0)
    x0 = {"1": 24000.0, "2": 21000.0, "3": 13000.0, "4": 12000.0, "6": 0.0}
    v0 = {"1": 85.0, "2": 82.0, "3": 81.0, "4": 81.0, "6": 76.0}
    edges_a = [Edge("1", "2", adjacent), Edge("2", "3", adjacent), Edge("3", "4", adjacent), Edge("4", "6", skip)]
    if topology == "union":
        edges_a.append(Edge("1", "3", skip))
    graph = CommGraph.build(x0, edges_a)
    events: list = [
        TrainLeave(switch_k, "2"),
        TrainJoin(
            switch_k, "5", x_m=89000.0, v_mps=80.0, params=p, edges=(Edge("4", "5", adjacent), Edge("5", "6", adjacent))
        ),
    ]
    if topology == "path":
        events += [EdgeRemove(switch_k, "4", "6"), EdgeAdd(switch_k, Edge("1", "3", skip))]
    return Scenario(
        name=f"zhang2024_fig1[{topology}]",
        sample_time_s=sample_time_s,
        v_ref_mps=80.0,
        horizon_k=horizon_k,
        trains={i: p for i in x0},
        graph=graph,
        initial_positions_m=x0,
        initial_speeds_mps=v0,
        events=tuple(events),
    )


BUILTIN_SCENARIOS: dict[str, Callable[..., Scenario]] = {"zhang2024_fig1": zhang2024_fig1}
