"""Paper C — fully distributed cooperative control of constrained discrete-time multi-train systems (spec 002).

Zhang, Chen & Fang: N point-mass trains in discrete time (eq. (1)) on an undirected, possibly changing
communication graph keep every neighbour pair's position difference in ``[γ̲_ij, γ̄_ij]``, every speed in
``[ρ̲_i, ρ̄_i]`` and every input in ``[μ̲_i, μ̄_i]`` at every sample, and converge to the spacings ``d_ij`` and the
reference speed ``v_r`` — with a law that has no gains, no global information and no leader (eqs. (10)–(11)).

Modules (one concept each, pure numpy / floats, no libsumo, no I/O; the figures are in :mod:`railsim.report.plots.paper002`):

* :mod:`.model`     — the per-train parameters (per unit mass) and the constant windows β, η; ``T_min``;
* :mod:`.graph`     — the dynamic communication graph with oriented edge data and topology events;
* :mod:`.validate`  — Assumptions 2.1–2.4, condition (13), d-consistency; :class:`PreconditionError`;
* :mod:`.control`   — the control law (:func:`control_step`, :class:`TrainController`) and the engine adapter
  registered as ``"distributed_constrained"``;
* :mod:`.reference` — the numpy reference integrator of the whole system with events and logs;
* :mod:`.scenarios` — the built-in ``zhang2024_fig1`` example (corrected parameters, ``union``/``path``);
"""

from controllers.distributed.control import (  # noqa: F401  (re-exported API; importing registers the controller)
    ConstraintWindowEmpty,
    ControlOutput,
    DistributedConstrainedController,
    DistributedConstrainedParams,
    NeighbourMessage,
    TrainController,
    control_step,
    paper_vehicle,
    predicted_position_m,
    train_params_from_vehicle,
)
from controllers.distributed.graph import (  # noqa: F401
    CommGraph,
    Edge,
    EdgeAdd,
    EdgeData,
    EdgeRemove,
    TopologyEvent,
    TrainJoin,
    TrainLeave,
    apply_event,
)
from controllers.distributed.model import LocalWindows, TrainParams, local_windows, min_sample_time_s  # noqa: F401
from controllers.distributed.reference import LoggedEvent, Scenario, SimulationLog, simulate  # noqa: F401
from controllers.distributed.scenarios import BUILTIN_SCENARIOS, zhang2024_fig1, zhang2024_train  # noqa: F401
from controllers.distributed.validate import (  # noqa: F401
    PreconditionError,
    Violation,
    check_assumptions,
    check_event_preconditions,
    check_state,
    validate,
)
