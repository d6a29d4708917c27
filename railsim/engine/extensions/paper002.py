"""Paper C (spec 002) in the engine: the cooperative graph of a fully distributed constrained controller.

The scenario's ``cooperative:`` section lists neighbour edges with activity windows. Every step the edges whose
both ends are on the line and whose window is open form the graph in force; each member's ATO (a graph law)
observes its neighbours over t2t (``extras["edges"]``, ``extras["neighbours"]``, ``extras["k"]``) and every
member reports to its neighbours. The first graph is checked against Paper C's Assumptions 2.1–2.4 and
condition (13); every change (a join, a leave, an edge added or dropped) re-checks the assumptions and (13) for
the new edges (:func:`controllers.distributed.validate.check_event_preconditions`). A violation stops the run
with the validator's message (exit code 2): an unsafe topology change is never silently accepted.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, Any

from controllers.distributed.graph import CommGraph, Edge, EdgeData
from controllers.distributed.validate import PreconditionError, check_event_preconditions, validate
from railsim.engine.extensions.base import Extension
from railsim.engine.extensions.context import ExtensionContext
from railsim.engine.train import TrainRuntime
from railsim.errors import ConfigError

if TYPE_CHECKING:  # pragma: no cover
    from railsim.scenario import Scenario

Neighbours = dict[str, dict[str, tuple[float, ...]]]


class CooperativeGraph(Extension):
    """The cooperative graph in force and its validation."""

    @classmethod
    def applies(cls, scenario: Scenario) -> bool:
        return bool(scenario.cooperative.edges)

    def __init__(self, ctx: ExtensionContext) -> None:
        super().__init__(ctx)
        self.edges = tuple(ctx.scenario.cooperative.edges)
        self.members = {e.a for e in self.edges} | {e.b for e in self.edges}
        for tid in self.members:
            if tid not in ctx.trains:
                raise ConfigError(ctx.scenario.source, "cooperative.edges", f"no trip {tid!r}")
        self.graph: Any = None  # the neighbour graph in force (the validator's CommGraph)
        self.neighbours: Neighbours = {}

    def t2t_receivers(self, train_id: str) -> Iterable[str]:
        return self.neighbours.get(train_id, {})

    def ato_extras(self, t: float, tr: TrainRuntime) -> dict[str, Any]:
        if tr.train_id not in self.members:
            return {}
        edges = self.neighbours.get(tr.train_id, {})
        states = []
        for j in edges:
            st = self.ctx.knowledge.known_state(tr, self.ctx.trains[j], "t2t", tr.train_id)
            if st is not None:
                states.append(st)
        return {"edges": dict(edges), "neighbours": tuple(states), "k": int(round(t / self.ctx.dt_s))}

    def before_comms(self, t: float, active: Sequence[TrainRuntime]) -> None:
        self.neighbours = self._graph_at(t, active)

    def _graph_at(self, t: float, active: Sequence[TrainRuntime]) -> Neighbours:
        """Active neighbour edges at ``t`` (both ends on the line), oriented per train; validated when they change."""
        on_line = {tr.train_id for tr in active}
        live = [e for e in self.edges if e.from_s <= t < e.until_s and e.a in on_line and e.b in on_line]
        out: Neighbours = {}
        for e in live:
            out.setdefault(e.a, {})[e.b] = (e.d_m, e.lower_m, e.upper_m)
            out.setdefault(e.b, {})[e.a] = (-e.d_m, -e.upper_m, -e.lower_m)
        nodes = sorted(out)
        graph = CommGraph.build(nodes, [Edge(e.a, e.b, EdgeData(e.d_m, e.lower_m, e.upper_m)) for e in live])
        if self.graph is not None and graph.edges == self.graph.edges and graph.nodes == self.graph.nodes:
            return out
        self._validate(t, graph, nodes)
        self.ctx.events.record(
            t, "graph_changed", "cooperative", nodes=nodes, edges=sorted(f"{e.a}-{e.b}" for e in live)
        )
        self.graph = graph
        return out

    def _validate(self, t: float, graph: Any, nodes: list[str]) -> None:
        src = self.ctx.scenario.source
        trains = self.ctx.trains
        params = {}
        v_ref = None
        for tid in nodes:
            law = trains[tid].controllers["ato"]
            if not hasattr(law, "train_params"):
                raise ConfigError(
                    src,
                    "cooperative.edges",
                    f"trip {tid} is in the cooperative graph but its ato controller is not a graph law",
                )
            params[tid] = law.train_params
            v_ref = law.params.v_ref_mps
        x = {tid: trains[tid].front_m for tid in nodes}
        v = {tid: trains[tid].plant.speed_mps for tid in nodes}
        dt = self.ctx.dt_s
        k = int(round(t / dt))
        if not nodes:
            return
        if self.graph is None:
            validate(graph, params, dt, float(v_ref), x, v, k=k, source=src)  # type: ignore[arg-type]
        else:
            problems = check_event_preconditions(self.graph, graph, params, dt, float(v_ref), x, v)  # type: ignore[arg-type]
            if problems:
                raise PreconditionError(src, problems, k=k)
