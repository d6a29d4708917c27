"""Precondition checks of Paper C (spec 002 §2.4, Theorem 1 condition (13), errata A1, A2, A7, A8).

Theorem 1 guarantees the constraints O1, O2 and convergence O3 only under Assumptions 2.1–2.4 and the initial
condition (13). This module checks all of them **before** a run and again after every topology event, and reports
*every* violation at once, each naming the assumption, the train or edge and the numbers:

* **Assumption 2.1** — the graph is connected (components are listed when it is not);
* **Assumption 2.2** — ``γ̲_ij < d_ij < γ̄_ij`` on every edge, and ``d`` is consistent: its sum around every cycle is
  zero (equivalently ``d_ij = d_i − d_j`` for node offsets ``d_i``). The mirror relations ``d_ji = −d_ij``,
  ``γ̲_ji = −γ̄_ij`` hold by construction of :class:`~controllers.distributed.graph.CommGraph`;
* **Assumption 2.3** — ``ρ̲_i < v_r < ρ̄_i`` (and ``ρ̲_i < ρ̄_i``, ``μ̲_i < μ̄_i`` from (3));
* **Assumption 2.4** — ``μ̲_i < f̲_i``, ``f̄_i < μ̄_i`` and the two sampling-period inequalities, reported as
  ``T > T_min,i`` with ``T_min`` computed (:func:`~controllers.distributed.model.min_sample_time_s`);
* **condition (13)** at step ``k`` — ``γ̲_ij ≤ x_ij(k) + T·v_ij(k) ≤ γ̄_ij`` on every edge and ``ρ̲_i ≤ v_i(k) ≤ ρ̄_i``;
* **O1 at the check step itself** (erratum A8: (13) constrains only ``x(k+1)``) — ``γ̲_ij ≤ x_ij(k) ≤ γ̄_ij``.

With the paper's printed values this rejects ``γ̄_{i−1,i} = 1000 m`` (A1: below ``d = 5000``), ``b = 7.7616e-2``
(A2: ``f̄ > μ̄ − (v_r − ρ̲)/T``) and ``T = 0.1 s`` (``T_min = 0.46268 s``).

Errors. :func:`validate` raises :class:`PreconditionError`, a :class:`railsim.errors.ConfigError` (so the CLI
prints one line, exit code 2) that also carries the full list ``violations`` of :class:`Violation` records. Its
``field`` is the field path of the first violation, e.g. ``trains[3].input_max_mps2`` or ``edges[1-2].gamma_hi_m``;
its message joins all of them with "; ". Field paths:

``sample_time_s``, ``v_ref_mps``, ``graph``, ``trains[<id>].<TrainParams field>``, ``edges[<i>-<j>].<EdgeData
field>`` (orientation as stated), ``state[<id>].v_mps`` and ``edges[<i>-<j>]`` for condition (13) / O1 at step k.

Numbers compare exactly, except the cycle sums of ``d`` (floating-point sums; tolerance ``1e-9·max(1, |d|)``).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

from controllers.distributed.graph import CommGraph
from controllers.distributed.model import TrainParams, local_windows, min_sample_time_s
from railsim.errors import ConfigError

DEFAULT_SOURCE = "<distributed>"


@dataclass(frozen=True)
class Violation:
    """One failed precondition: which assumption, where (field path) and what the numbers are."""

    assumption: str
    field: str
    message: str

    def __str__(self) -> str:
        return f"{self.field}: {self.assumption}: {self.message}"


class PreconditionError(ConfigError):
    """Paper C's preconditions fail; ``violations`` lists every failure (the message joins them)."""

    def __init__(self, source: str | Path | None, violations: Iterable[Violation], k: int | None = None) -> None:
        self.violations: tuple[Violation, ...] = tuple(violations)
        self.k = k
        if not self.violations:
            raise ValueError("PreconditionError needs at least one violation")
        first = self.violations[0]
        at = f"at k = {k}: " if k is not None else ""
        parts = [f"{first.assumption}: {first.message}"] + [str(v) for v in self.violations[1:]]
        super().__init__(source, first.field, at + "; ".join(parts))


def _g(x: float) -> str:
    return f"{x:.6g}"


def _edge_field(i: str, j: str) -> str:
    return f"edges[{i}-{j}]"


def check_assumptions(
    graph: CommGraph,
    trains: Mapping[str, TrainParams],
    sample_time_s: float,
    v_ref_mps: float,
) -> list[Violation]:
    """Assumptions 2.1–2.4 (and the orderings of (3)) for the trains and edges of ``graph``."""
    out: list[Violation] = []
    t = sample_time_s
    if not (isinstance(t, (int, float)) and math.isfinite(t) and t > 0.0):
        out.append(Violation("model (1)", "sample_time_s", f"expected a finite number > 0, got {t!r}"))
        return out
    if not (isinstance(v_ref_mps, (int, float)) and math.isfinite(v_ref_mps)):
        out.append(Violation("Assumption 2.3", "v_ref_mps", f"expected a finite number, got {v_ref_mps!r}"))
        return out

    # Assumption 2.1
    if not graph.nodes:
        out.append(Violation("Assumption 2.1", "graph", "the graph has no trains"))
    else:
        comps = graph.components()
        if len(comps) > 1:
            listed = " | ".join(",".join(sorted(c)) for c in comps)
            out.append(
                Violation(
                    "Assumption 2.1",
                    "graph",
                    f"the communication graph must be connected, it has {len(comps)} components: {listed}",
                )
            )

    # Per-train: (3), Assumption 2.3, Assumption 2.4
    for i in sorted(graph.nodes):
        p = trains.get(i)
        where = f"trains[{i}]"
        if p is None:
            out.append(Violation("model (1)", where, "no parameters for this train"))
            continue
        bad = [
            name
            for name, value in vars(p).items()
            if not (isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value))
        ]
        if bad:
            for name in bad:
                out.append(
                    Violation("model (1)", f"{where}.{name}", f"expected a finite number, got {getattr(p, name)!r}")
                )
            continue
        if not p.speed_min_mps < p.speed_max_mps:
            out.append(
                Violation(
                    "objective O2 (3)",
                    f"{where}.speed_max_mps",
                    f"ρ̲ < ρ̄ fails: ρ̲ = {_g(p.speed_min_mps)}, ρ̄ = {_g(p.speed_max_mps)} m/s",
                )
            )
        if not p.input_min_mps2 < p.input_max_mps2:
            out.append(
                Violation(
                    "objective O2 (3)",
                    f"{where}.input_max_mps2",
                    f"μ̲ < μ̄ fails: μ̲ = {_g(p.input_min_mps2)}, μ̄ = {_g(p.input_max_mps2)} m/s²",
                )
            )
        if not p.speed_min_mps < v_ref_mps:
            out.append(
                Violation(
                    "Assumption 2.3",
                    f"{where}.speed_min_mps",
                    f"ρ̲ < v_r fails: ρ̲ = {_g(p.speed_min_mps)}, v_r = {_g(v_ref_mps)} m/s",
                )
            )
        if not v_ref_mps < p.speed_max_mps:
            out.append(
                Violation(
                    "Assumption 2.3",
                    f"{where}.speed_max_mps",
                    f"v_r < ρ̄ fails: v_r = {_g(v_ref_mps)}, ρ̄ = {_g(p.speed_max_mps)} m/s",
                )
            )
        if not p.speed_min_mps < p.speed_max_mps:
            continue  # f̲, f̄ undefined on an empty interval
        w = local_windows(p, t, v_ref_mps)
        f_lo, f_hi = w.resist_min_mps2, w.resist_max_mps2
        ok_inputs = True
        if not p.input_min_mps2 < f_lo:
            ok_inputs = False
            out.append(
                Violation(
                    "Assumption 2.4",
                    f"{where}.input_min_mps2",
                    f"μ̲ < f̲ fails: μ̲ = {_g(p.input_min_mps2)}, f̲ = min f on "
                    f"[{_g(p.speed_min_mps)}, {_g(p.speed_max_mps)}] = {_g(f_lo)} m/s²",
                )
            )
        if not f_hi < p.input_max_mps2:
            ok_inputs = False
            out.append(
                Violation(
                    "Assumption 2.4",
                    f"{where}.input_max_mps2",
                    f"f̄ < μ̄ fails: f̄ = max f on [{_g(p.speed_min_mps)}, {_g(p.speed_max_mps)}] = "
                    f"{_g(f_hi)}, μ̄ = {_g(p.input_max_mps2)} m/s²",
                )
            )
        lo_ok = (v_ref_mps - p.speed_max_mps) / t > p.input_min_mps2 - f_lo  # ⇔ η̲ < 0
        hi_ok = (v_ref_mps - p.speed_min_mps) / t < p.input_max_mps2 - f_hi  # ⇔ η̄ > 0
        if ok_inputs and not (lo_ok and hi_ok):
            t_min = min_sample_time_s(p, v_ref_mps)
            which = []
            if not lo_ok:
                which.append(
                    f"(v_r − ρ̄)/T = {_g((v_ref_mps - p.speed_max_mps) / t)} ≤ μ̲ − f̲ = "
                    f"{_g(p.input_min_mps2 - f_lo)} (η̲ = {_g(w.eta_lo_m)} m ≥ 0)"
                )
            if not hi_ok:
                which.append(
                    f"(v_r − ρ̲)/T = {_g((v_ref_mps - p.speed_min_mps) / t)} ≥ μ̄ − f̄ = "
                    f"{_g(p.input_max_mps2 - f_hi)} (η̄ = {_g(w.eta_hi_m)} m ≤ 0)"
                )
            out.append(
                Violation(
                    "Assumption 2.4",
                    "sample_time_s",
                    f"train {i} needs T > T_min = {_g(t_min)} s, got T = {_g(t)} s: " + " and ".join(which),
                )
            )

    # Assumption 2.2 per edge, then d-consistency around cycles
    for i, j, e in graph.oriented_edges():
        where = _edge_field(i, j)
        vals = e.as_tuple()
        if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in vals):
            out.append(Violation("Assumption 2.2", where, f"expected finite numbers (d, γ̲, γ̄), got {vals!r}"))
            continue
        if not e.gamma_lo_m < e.d_m:
            out.append(
                Violation(
                    "Assumption 2.2",
                    f"{where}.gamma_lo_m",
                    f"γ̲_ij < d_ij fails for edge {i}-{j}: γ̲ = {_g(e.gamma_lo_m)}, d = {_g(e.d_m)} m",
                )
            )
        if not e.d_m < e.gamma_hi_m:
            out.append(
                Violation(
                    "Assumption 2.2",
                    f"{where}.gamma_hi_m",
                    f"d_ij < γ̄_ij fails for edge {i}-{j}: d = {_g(e.d_m)}, γ̄ = {_g(e.gamma_hi_m)} m",
                )
            )
    if all(math.isfinite(e.data.d_m) for e in graph.edges.values()):
        _, mismatches = graph.node_offsets()
        for i, j, cycle in mismatches:
            scale = max(1.0, abs(graph.oriented(i, j).d_m))
            if abs(cycle) > 1e-9 * scale:
                out.append(
                    Violation(
                        "Assumption 2.2",
                        f"{_edge_field(i, j)}.d_m",
                        f"d is not consistent: the cycle closed by edge {i}-{j} sums to {_g(cycle)} m "
                        f"(d_ij must equal d_il + d_lj around every cycle)",
                    )
                )
    return out


def check_state(
    graph: CommGraph,
    trains: Mapping[str, TrainParams],
    sample_time_s: float,
    positions_m: Mapping[str, float],
    speeds_mps: Mapping[str, float],
    *,
    edges: Iterable[frozenset[str]] | None = None,
    speed_trains: Iterable[str] | None = None,
) -> list[Violation]:
    """Condition (13) and O1 at the state of one step, for ``edges`` (default all) and ``speed_trains`` (default all)."""
    out: list[Violation] = []
    t = sample_time_s
    edge_keys = set(graph.edges) if edges is None else set(edges)
    speed_ids = sorted(graph.nodes) if speed_trains is None else sorted(speed_trains)
    for i in speed_ids:
        if i not in positions_m or i not in speeds_mps:
            out.append(Violation("condition (13)", f"state[{i}]", "no position/speed for this train"))
            continue
        v, p = speeds_mps[i], trains.get(i)
        if not (math.isfinite(v) and math.isfinite(positions_m[i])):
            out.append(
                Violation("condition (13)", f"state[{i}]", f"expected finite x and v, got {positions_m[i]!r}, {v!r}")
            )
        elif p is not None and not (p.speed_min_mps <= v <= p.speed_max_mps):
            out.append(
                Violation(
                    "condition (13)",
                    f"state[{i}].v_mps",
                    f"ρ̲ ≤ v_i ≤ ρ̄ fails for train {i}: v = {_g(v)} m/s, "
                    f"bounds [{_g(p.speed_min_mps)}, {_g(p.speed_max_mps)}]",
                )
            )
    for i, j, e in graph.oriented_edges():
        if frozenset((i, j)) not in edge_keys:
            continue
        if not all(n in positions_m and n in speeds_mps for n in (i, j)):
            continue  # reported above when the train is checked; an edge alone cannot be judged
        x_ij = positions_m[i] - positions_m[j]
        x_next = (positions_m[i] + t * speeds_mps[i]) - (positions_m[j] + t * speeds_mps[j])
        band = f"[{_g(e.gamma_lo_m)}, {_g(e.gamma_hi_m)}] m"
        if not (e.gamma_lo_m <= x_ij <= e.gamma_hi_m):
            out.append(
                Violation(
                    "objective O1 at the check step (A8)",
                    _edge_field(i, j),
                    f"x_ij = x_{i} − x_{j} = {_g(x_ij)} m for edge {i}-{j} outside {band}",
                )
            )
        if not (e.gamma_lo_m <= x_next <= e.gamma_hi_m):
            out.append(
                Violation(
                    "condition (13)",
                    _edge_field(i, j),
                    f"x_ij + T·v_ij = {_g(x_next)} m for edge {i}-{j} (x_ij = {_g(x_ij)} m, "
                    f"v_ij = {_g(speeds_mps[i] - speeds_mps[j])} m/s) outside {band}",
                )
            )
    return out


def validate(
    graph: CommGraph,
    trains: Mapping[str, TrainParams],
    sample_time_s: float,
    v_ref_mps: float,
    positions_m: Mapping[str, float] | None = None,
    speeds_mps: Mapping[str, float] | None = None,
    *,
    k: int | None = None,
    source: str | Path | None = DEFAULT_SOURCE,
) -> None:
    """Raise :class:`PreconditionError` listing every failed assumption (and (13)/O1 if a state is given)."""
    violations = check_assumptions(graph, trains, sample_time_s, v_ref_mps)
    if (
        positions_m is not None
        and speeds_mps is not None
        and not any(v.field == "sample_time_s" and v.assumption == "model (1)" for v in violations)
    ):
        violations += check_state(graph, trains, sample_time_s, positions_m, speeds_mps)
    if violations:
        raise PreconditionError(source, violations, k=k)


def check_event_preconditions(
    old_graph: CommGraph,
    new_graph: CommGraph,
    trains: Mapping[str, TrainParams],
    sample_time_s: float,
    v_ref_mps: float,
    positions_m: Mapping[str, float],
    speeds_mps: Mapping[str, float],
) -> list[Violation]:
    """Re-validation after the topology events of one step (erratum A7).

    All assumptions are re-checked on the new graph. Condition (13) and O1 are checked on the edges that are new
    (their pair constraint was never enforced) and the speed bound for trains that are new; on the old edges the
    control law has already guaranteed both since the last check (Theorem 1's invariance step), so a violation
    there would be a bug, not a precondition — the simulator's constraint log catches those.
    """
    out = check_assumptions(new_graph, trains, sample_time_s, v_ref_mps)
    new_edges = {key for key, e in new_graph.edges.items() if old_graph.edges.get(key) != e}
    new_trains = new_graph.nodes - old_graph.nodes
    out += check_state(
        new_graph, trains, sample_time_s, positions_m, speeds_mps, edges=new_edges, speed_trains=new_trains
    )
    return out
