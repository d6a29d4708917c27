"""Pure-numpy reference integrator of Paper C's multi-train system (spec 002 eq. (1), §6, §7.1 backend (i)).

This is the ground truth the SUMO backend is compared against (spec 002 §7.2 item 11) and the harness of the
property tests. One step ``k`` runs in this order:

1. **events of step k** (:mod:`controllers.distributed.graph`): removals, leaves, joins (with the joining train's
   state *at* ``k``), additions — then the preconditions are **re-validated** (Assumptions 2.1–2.4 on the new graph,
   condition (13) and O1 for the new edges and trains; erratum A7). At ``k = 0`` the full check of
   :func:`~controllers.distributed.validate.validate` runs. A violation raises
   :class:`~controllers.distributed.validate.PreconditionError` (``strict=True``, default) or, with
   ``strict=False``, is logged as a ``"precondition_violated"`` event and the run continues *flagged*
   (``SimulationLog.flagged``) — it is never accepted silently;
2. **communication**: every present train broadcasts ``x̂_j = x_j(k) + T·v_j(k)`` (all from the same snapshot);
3. **control**: every present train's :class:`~controllers.distributed.control.TrainController` computes ``u_i(k)``
   from its own speed and its neighbours' messages only — synchronously, before any state changes;
4. **log** ``x(k), v(k), u(k), s, G, δ̲, δ̄``, the active edges, ``x_ij(k)`` and every constraint margin;
5. **plant** (eq. (1), forward Euler exactly as the paper): ``x(k+1) = x(k) + T·v(k)``,
   ``v(k+1) = v(k) + T·(u(k) − f(v(k)))``.

Steps run for ``k = 0 … horizon_k``; the control of the last step is computed and logged but not applied. Events
after ``horizon_k`` are never reached and not applied (nor validated).

Logs are arrays indexed ``[k, train]`` / ``[k, edge]`` with **NaN where the train (edge) is absent** (``present``
and ``edge_active`` say so explicitly; the plots draw a train only while it is present). Edges are indexed by the
union of all edges ever active, in the orientation of their first appearance.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from controllers.distributed.control import ControlOutput, NeighbourMessage, TrainController, predicted_position_m
from controllers.distributed.graph import (
    CommGraph,
    EdgeAdd,
    EdgeData,
    EdgeRemove,
    TopologyEvent,
    TrainJoin,
    TrainLeave,
    apply_event,
    sort_events,
)
from controllers.distributed.model import TrainParams
from controllers.distributed.validate import (
    DEFAULT_SOURCE,
    PreconditionError,
    Violation,
    check_assumptions,
    check_event_preconditions,
    validate,
)


@dataclass(frozen=True)
class Scenario:
    """A complete Paper C experiment: trains, graph and state at ``k = 0``, events, ``T``, ``v_r``, horizon.

    ``trains`` holds the parameters of the trains present at ``k = 0``; a joining train brings its own in its
    :class:`~controllers.distributed.graph.TrainJoin` event.
    """

    name: str
    sample_time_s: float
    v_ref_mps: float
    horizon_k: int
    trains: Mapping[str, TrainParams]
    graph: CommGraph
    initial_positions_m: Mapping[str, float]
    initial_speeds_mps: Mapping[str, float]
    events: tuple[TopologyEvent, ...] = ()


@dataclass(frozen=True)
class LoggedEvent:
    k: int
    kind: str  # "join" | "leave" | "edge_add" | "edge_remove" | "precondition_violated"
    detail: str


@dataclass
class SimulationLog:
    """Everything :func:`simulate` recorded (arrays ``[k, train]`` or ``[k, edge]``, NaN where absent)."""

    scenario: Scenario
    train_ids: tuple[str, ...]
    train_params: dict[str, TrainParams]
    k: np.ndarray
    present: np.ndarray
    x_m: np.ndarray
    v_mps: np.ndarray
    u_mps2: np.ndarray
    ubar_mps2: np.ndarray
    s_m: np.ndarray
    g_m: np.ndarray
    delta_lo_m: np.ndarray
    delta_hi_m: np.ndarray
    feasible: np.ndarray
    edge_ids: tuple[tuple[str, str], ...]
    edge_active: np.ndarray
    edge_d_m: np.ndarray
    edge_gamma_lo_m: np.ndarray
    edge_gamma_hi_m: np.ndarray
    x_rel_m: np.ndarray  # x_i − x_j for edge (i, j)
    events: list[LoggedEvent] = field(default_factory=list)
    flagged: bool = False

    # ---- convenience views
    def col(self, train_id: str) -> int:
        return self.train_ids.index(train_id)

    def edge_col(self, i: str, j: str) -> tuple[int, float]:
        """Column of edge ``{i, j}`` and the sign (+1 if logged as ``(i, j)``, −1 if as ``(j, i)``)."""
        for n, (a, b) in enumerate(self.edge_ids):
            if (a, b) == (i, j):
                return n, 1.0
            if (a, b) == (j, i):
                return n, -1.0
        raise KeyError(f"edge {i}-{j} was never active")

    def param_array(self, name: str) -> np.ndarray:
        """A per-train parameter as a row vector aligned with ``train_ids``."""
        return np.array([getattr(self.train_params[i], name) for i in self.train_ids])

    def edge_margins_m(self) -> tuple[np.ndarray, np.ndarray]:
        """``(x_ij − γ̲_ij, γ̄_ij − x_ij)`` per ``[k, edge]`` (NaN when inactive); O1 holds where both ≥ 0."""
        return self.x_rel_m - self.edge_gamma_lo_m, self.edge_gamma_hi_m - self.x_rel_m

    def speed_margins_mps(self) -> tuple[np.ndarray, np.ndarray]:
        return self.v_mps - self.param_array("speed_min_mps"), self.param_array("speed_max_mps") - self.v_mps

    def input_margins_mps2(self) -> tuple[np.ndarray, np.ndarray]:
        return self.u_mps2 - self.param_array("input_min_mps2"), self.param_array("input_max_mps2") - self.u_mps2

    def violations(self, tol: float = 0.0) -> list[tuple[int, str, str, float]]:
        """Every sample where O1 or O2 fails by more than ``tol``: ``(k, kind, where, margin)``."""
        out = []
        checks = [
            ("O1 lower", self.edge_margins_m()[0], self.edge_ids),
            ("O1 upper", self.edge_margins_m()[1], self.edge_ids),
            ("speed lower", self.speed_margins_mps()[0], self.train_ids),
            ("speed upper", self.speed_margins_mps()[1], self.train_ids),
            ("input lower", self.input_margins_mps2()[0], self.train_ids),
            ("input upper", self.input_margins_mps2()[1], self.train_ids),
        ]
        for kind, margin, names in checks:
            bad = np.argwhere(margin < -tol)  # NaN compares False: absent entries never count
            for kk, col in bad:
                name = names[col]
                where = f"{name[0]}-{name[1]}" if isinstance(name, tuple) else name
                out.append((int(self.k[kk]), kind, where, float(margin[kk, col])))
        return out


def _natural_key(s: str) -> tuple:
    return tuple(int(p) if p.isdigit() else p for p in re.split(r"(\d+)", s))


def simulate(
    scenario: Scenario,
    *,
    strict: bool = True,
    on_empty: str = "raise",
    source: str | Path | None = DEFAULT_SOURCE,
) -> SimulationLog:
    """Run ``scenario`` for ``k = 0 … horizon_k`` (see the module docstring for the order of one step)."""
    t = scenario.sample_time_s
    v_r = scenario.v_ref_mps
    horizon = int(scenario.horizon_k)
    if horizon < 0:
        raise PreconditionError(source, [_v("horizon_k", f"expected an integer >= 0, got {scenario.horizon_k!r}")])
    for e in scenario.events:
        if not (isinstance(e.k, int) and not isinstance(e.k, bool) and e.k >= 0):
            raise PreconditionError(source, [_v("events", f"event step k must be an integer >= 0, got {e!r}")])
    events = [e for e in sort_events(scenario.events) if e.k <= horizon]  # later ones are never reached

    params: dict[str, TrainParams] = dict(scenario.trains)
    for e in events:
        if isinstance(e, TrainJoin):
            params.setdefault(e.train_id, e.params)
    train_ids = tuple(
        sorted(set(scenario.graph.nodes) | {e.train_id for e in events if isinstance(e, TrainJoin)}, key=_natural_key)
    )
    col = {i: n for n, i in enumerate(train_ids)}

    # The union of edges ever active, oriented at first appearance (walk the event list once, graphs only).
    edge_ids: list[tuple[str, str]] = []
    edge_col: dict[frozenset[str], int] = {}
    g = scenario.graph

    def note_edges(graph: CommGraph) -> None:
        for i, j, _ in graph.oriented_edges():
            key = frozenset((i, j))
            if key not in edge_col:
                edge_col[key] = len(edge_ids)
                edge_ids.append((i, j))

    # Fail fast: the full check at k = 0, then every assumption that does not depend on the state (2.1–2.4 on
    # each graph the events produce) before the first step; (13) at an event needs the state: checked when it happens.
    x0 = {i: float(scenario.initial_positions_m[i]) for i in g.nodes if i in scenario.initial_positions_m}
    v0 = {i: float(scenario.initial_speeds_mps[i]) for i in g.nodes if i in scenario.initial_speeds_mps}
    validate(g, params, t, v_r, x0, v0, k=0, source=source)
    note_edges(g)
    ahead: list[Violation] = []
    for n_ev, e in enumerate(events):
        try:
            g = apply_event(g, e)
        except ValueError as exc:
            raise PreconditionError(source, [_v("events", f"step {e.k}: {exc}")], k=e.k) from None
        note_edges(g)
        if n_ev + 1 == len(events) or events[n_ev + 1].k != e.k:
            ahead += [
                Violation(viol.assumption, viol.field, f"after the events of k = {e.k}: {viol.message}")
                for viol in check_assumptions(g, params, t, v_r)
            ]
    if ahead and strict:
        raise PreconditionError(source, ahead)

    n_k, n_tr, n_ed = horizon + 1, len(train_ids), len(edge_ids)
    nan_tr = lambda: np.full((n_k, n_tr), np.nan)  # noqa: E731
    nan_ed = lambda: np.full((n_k, n_ed), np.nan)  # noqa: E731
    log = SimulationLog(
        scenario=scenario,
        train_ids=train_ids,
        train_params=params,
        k=np.arange(n_k),
        present=np.zeros((n_k, n_tr), bool),
        x_m=nan_tr(),
        v_mps=nan_tr(),
        u_mps2=nan_tr(),
        ubar_mps2=nan_tr(),
        s_m=nan_tr(),
        g_m=nan_tr(),
        delta_lo_m=nan_tr(),
        delta_hi_m=nan_tr(),
        feasible=np.ones((n_k, n_tr), bool),
        edge_ids=tuple(edge_ids),
        edge_active=np.zeros((n_k, n_ed), bool),
        edge_d_m=nan_ed(),
        edge_gamma_lo_m=nan_ed(),
        edge_gamma_hi_m=nan_ed(),
        x_rel_m=nan_ed(),
    )

    # State of the trains present now.
    graph = scenario.graph
    x, v = dict(x0), dict(v0)
    controllers = {i: TrainController(i, params[i], t, v_r, on_empty) for i in graph.nodes}
    topology = _Topology(graph)

    ev_pos = 0
    for k in range(n_k):
        if ev_pos < len(events) and events[ev_pos].k == k:
            old_graph = graph
            while ev_pos < len(events) and events[ev_pos].k == k:
                e = events[ev_pos]
                graph = apply_event(graph, e)
                kind, detail = _describe(e)
                log.events.append(LoggedEvent(k, kind, detail))
                if isinstance(e, TrainJoin):
                    x[e.train_id], v[e.train_id] = float(e.x_m), float(e.v_mps)
                    params[e.train_id] = e.params  # a re-joining train may bring new bounds
                    controllers[e.train_id] = TrainController(e.train_id, e.params, t, v_r, on_empty)
                elif kind == "leave":
                    for table in (x, v, controllers):
                        table.pop(e.train_id, None)  # type: ignore[union-attr]
                ev_pos += 1
            bad = check_event_preconditions(old_graph, graph, params, t, v_r, x, v)
            if bad:
                if strict:
                    raise PreconditionError(source, bad, k=k)
                log.flagged = True
                for viol in bad:
                    log.events.append(LoggedEvent(k, "precondition_violated", str(viol)))
            topology = _Topology(graph)

        outputs = network_controls(topology, controllers, x, v, t)
        u_now: dict[str, float] = {}
        for i, out in outputs.items():
            u_now[i] = out.u_mps2
            c = col[i]
            log.present[k, c] = True
            log.x_m[k, c], log.v_mps[k, c] = x[i], v[i]
            log.u_mps2[k, c], log.ubar_mps2[k, c] = out.u_mps2, out.ubar_mps2
            log.s_m[k, c], log.g_m[k, c] = out.s_m, out.g_m
            log.delta_lo_m[k, c], log.delta_hi_m[k, c] = out.delta_lo_m, out.delta_hi_m
            log.feasible[k, c] = out.feasible
        for i, j, data in graph.oriented_edges():
            n = edge_col[frozenset((i, j))]
            if edge_ids[n] != (i, j):
                data = data.reversed()
                i, j = j, i
            log.edge_active[k, n] = True
            log.edge_d_m[k, n], log.edge_gamma_lo_m[k, n], log.edge_gamma_hi_m[k, n] = data.as_tuple()
            log.x_rel_m[k, n] = x[i] - x[j]

        if k < horizon:  # plant, eq. (1)
            for i in graph.nodes:
                p = params[i]
                f = p.resistance_mps2(v[i])
                x[i] = x[i] + t * v[i]
                v[i] = v[i] + t * (u_now[i] - f)
                if not (math.isfinite(x[i]) and math.isfinite(v[i])):
                    raise FloatingPointError(f"train {i}: non-finite state at k = {k + 1}")
    return log


class _Topology:
    """Per-graph cache: each train's neighbours with the edge data oriented from it."""

    def __init__(self, graph: CommGraph) -> None:
        self.oriented: dict[str, list[tuple[str, EdgeData]]] = {
            i: [(j, graph.oriented(i, j)) for j in graph.neighbours(i)] for i in graph.nodes
        }


def network_controls(
    graph: CommGraph | _Topology,
    controllers: Mapping[str, TrainController],
    positions_m: Mapping[str, float],
    speeds_mps: Mapping[str, float],
    sample_time_s: float,
) -> dict[str, ControlOutput]:
    """All trains' controls of one step from one snapshot (steps 2–3 of the module docstring).

    Every train broadcasts ``x̂ = x + T·v``; train ``i`` receives ``x_ij(k+1) = x̂_i − x̂_j`` from each neighbour and
    nothing else. Pure: the states are not changed.
    """
    topology = graph if isinstance(graph, _Topology) else _Topology(graph)
    broadcast = {i: predicted_position_m(positions_m[i], speeds_mps[i], sample_time_s) for i in topology.oriented}
    out: dict[str, ControlOutput] = {}
    for i, neighbours in topology.oriented.items():
        msgs = [NeighbourMessage(j, broadcast[i] - broadcast[j], data) for j, data in neighbours]
        out[i] = controllers[i].control(speeds_mps[i], msgs)
    return out


def _v(field_path: str, message: str) -> Violation:
    return Violation("scenario", field_path, message)


def _describe(e: TopologyEvent) -> tuple[str, str]:
    if isinstance(e, TrainJoin):
        edges = ", ".join(f"{x.i}-{x.j}" for x in e.edges)
        return "join", f"train {e.train_id} joins at x = {e.x_m:g} m, v = {e.v_mps:g} m/s with edges [{edges}]"
    if isinstance(e, TrainLeave):
        return "leave", f"train {e.train_id} leaves"
    if isinstance(e, EdgeAdd):
        return "edge_add", f"edge {e.edge.i}-{e.edge.j} added {e.edge.data.as_tuple()}"
    if isinstance(e, EdgeRemove):
        return "edge_remove", f"edge {e.i}-{e.j} removed"
    raise TypeError(e)
