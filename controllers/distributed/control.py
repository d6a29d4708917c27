"""The fully distributed constrained control law of Paper C (spec 002 eqs. (10)–(11), §6) and its engine adapter.

One control step of train ``i`` at step ``k`` uses only

* its own speed ``v_i(k)`` and its local parameters (:class:`~controllers.distributed.model.TrainParams`), ``T`` and
  the global reference speed ``v_r``;
* for each neighbour ``j``: the predicted relative position ``x_ij(k+1) = x_ij(k) + T·v_ij(k)`` and the edge data
  ``(d_ij, γ̲_ij, γ̄_ij)`` oriented from ``i``.

``x_ij(k+1)`` is known at ``k`` because under the paper's forward-Euler model ``x(k+1) = x(k) + T·v(k)`` does not
depend on ``u(k)``. The paper says the law needs "relative positions only", but a one-step-ahead relative position
needs the relative speed too (erratum A3); the communication layer here is the simplest one that delivers it: each
train broadcasts its **predicted next position** ``x̂_j = x_j(k) + T·v_j(k)`` (:func:`predicted_position_m`) and the
receiver forms ``x_ij(k+1) = x̂_i − x̂_j``. No global clock, node offsets ``d_i``, Laplacian or train count is
used: that is what "fully distributed" means here. The law, with ``ȳ_ij(k+1) = x_ij(k+1) − d_ij``::

    α̲_i = max_j −(ȳ_ij − (γ̲_ij − d_ij))/2      ᾱ_i = min_j ((γ̄_ij − d_ij) − ȳ_ij)/2     (half the slack each)
    G_i  = −Σ_j ȳ_ij / (2|𝒩_i|)                                                          (lazy consensus)
    δ̲_i = max(α̲_i, β̲_i, η̲_i)                 δ̄_i = min(ᾱ_i, β̄_i, η̄_i)
    s_i  = sat(δ̲_i, δ̄_i, G_i) = min(max(G_i, δ̲_i), δ̄_i)
    ū_i  = −(v_i − v_r)/T + s_i/T²                u_i = ū_i + f_i(v_i)                    (eq. (11), ω = 1/T)

so that the plant of eq. (1) gives ``v_i(k+1) = v_r + s_i/T`` exactly (dead-beat) and ``ȳ_i(k+2) = ȳ_i(k+1) + s_i``.
β and η are constant (:func:`~controllers.distributed.model.local_windows`). Typos of the printed text are
corrected as in spec 002 §2 (A11): the window is ``[δ̲, δ̄]`` with ``δ̲ ≤ δ̄``.

An **isolated train** (no neighbours, A9) gets ``α̲ = −∞``, ``ᾱ = +∞``, ``G = 0``: it runs to ``v_r``.

**Empty window** (``δ̲ > δ̄``, A10). Impossible under Theorem 1's conditions; possible after a bad topology event,
a model mismatch or ``T < T_min``. ``on_empty="raise"`` (default) raises :class:`ConstraintWindowEmpty`;
``"fallback"`` keeps the hard physical limits first and the pair constraints as far as they allow:
``s = clip(g, hard_lo, hard_hi)`` with ``g = clip(G, α̲, ᾱ)`` (or the middle of ``[ᾱ, α̲]`` when the α window
itself is empty) and ``[hard_lo, hard_hi] = [max(β̲, η̲), min(β̄, η̄)]`` (just ``[β̲, β̄]`` if that is empty too), and
flags the output ``feasible=False``. The bounds are never swapped silently.

Engine adapter. :class:`DistributedConstrainedController` (registered as ``"distributed_constrained"``) reads the
same information from an :class:`~controllers.base.Observation` (see its docstring for the exact ``extras`` it
needs) and returns the **applied specific force** the railsim plant expects. The plant subtracts
``R(v, gradient)/m_eff``; the adapter therefore returns ``vehicle.net_to_applied(ū_i, v_i, gradient)``, which makes
the plant's net acceleration exactly ``ū_i`` — the paper's closed loop. On level track with a vehicle of
``mass_kg = 1``, ``rotating_mass_factor = 1`` and Davis ``A, B, C = a_i, b_i, c_i`` this *is* the paper's ``u_i``
(bit for bit); :func:`paper_vehicle` builds such a vehicle with no lag, no jerk limit and an envelope wider than
``[μ̲, μ̄]``. The plant must use ``step_method="forward"`` (``x(k+1) = x(k) + T·v(k)``, spec 002 §7.3).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from controllers.base import Command, Observation, PredecessorState, register
from controllers.braking import params_from_mapping, require
from controllers.distributed.graph import EdgeData
from controllers.distributed.model import LocalWindows, TrainParams, local_windows
from railsim.errors import SimulationError
from railsim.physics.vehicle import VehicleParams

ON_EMPTY_CHOICES = ("raise", "fallback")
# Two bounds that meet exactly in exact arithmetic may cross by a few ulps (seen: 5e-14 m); such a window is the
# single point, not empty (found by tests/unit/test_distributed_properties.py).
WINDOW_ROUNDING_M = 1e-9


class ConstraintWindowEmpty(RuntimeError):
    """``δ̲_i > δ̄_i``: no displacement satisfies every constraint of train ``i`` at this step (erratum A10)."""

    def __init__(self, train_id: str, delta_lo_m: float, delta_hi_m: float, detail: str) -> None:
        self.train_id = train_id
        self.delta_lo_m = delta_lo_m
        self.delta_hi_m = delta_hi_m
        super().__init__(
            f"train {train_id}: constraint window empty, δ̲ = {delta_lo_m:.6g} m > δ̄ = {delta_hi_m:.6g} m ({detail})"
        )


@dataclass(frozen=True)
class NeighbourMessage:
    """What train ``i`` knows about neighbour ``j`` at step ``k``: ``x_ij(k+1)`` [m] and the edge seen from ``i``."""

    neighbour_id: str
    rel_next_m: float
    edge: EdgeData


@dataclass(frozen=True)
class ControlOutput:
    """One control step: the input and every intermediate quantity of eq. (10)–(11) (for logs and tests)."""

    u_mps2: float  # u_i(k), the paper's input (resistance included)
    ubar_mps2: float  # ū_i(k) = u_i − f_i(v_i): the net specific force
    s_m: float  # sat(δ̲, δ̄, G): displacement added in the moving frame, v_i(k+1) = v_r + s/T
    g_m: float  # G_i
    delta_lo_m: float
    delta_hi_m: float
    alpha_lo_m: float
    alpha_hi_m: float
    feasible: bool  # δ̲ ≤ δ̄


def predicted_position_m(position_m: float, speed_mps: float, sample_time_s: float) -> float:
    """The broadcast ``x̂ = x(k) + T·v(k)`` = ``x(k+1)`` under the forward-Euler model (A3)."""
    return position_m + sample_time_s * speed_mps


def control_step(
    train_id: str,
    speed_mps: float,
    messages: Sequence[NeighbourMessage],
    params: TrainParams,
    windows: LocalWindows,
    sample_time_s: float,
    v_ref_mps: float,
    on_empty: str = "raise",
) -> ControlOutput:
    """Eq. (10)–(11) for one train (pure; see the module docstring). ``windows`` = ``local_windows(params, T, v_r)``."""
    t = sample_time_s
    if messages:
        alpha_lo = -math.inf
        alpha_hi = math.inf
        total = 0.0
        for m in messages:
            d, g_lo, g_hi = m.edge.d_m, m.edge.gamma_lo_m, m.edge.gamma_hi_m
            ybar = m.rel_next_m - d  # ȳ_ij(k+1)
            lo = -(ybar - (g_lo - d)) / 2.0
            hi = ((g_hi - d) - ybar) / 2.0
            if lo > alpha_lo:
                alpha_lo = lo
            if hi < alpha_hi:
                alpha_hi = hi
            total += ybar
        g = -total / (2.0 * len(messages))
    else:  # isolated train (A9)
        alpha_lo, alpha_hi, g = -math.inf, math.inf, 0.0
    delta_lo = max(alpha_lo, windows.beta_lo_m, windows.eta_lo_m)
    delta_hi = min(alpha_hi, windows.beta_hi_m, windows.eta_hi_m)
    feasible = delta_lo <= delta_hi + WINDOW_ROUNDING_M  # a window empty by rounding only is a point
    if feasible:
        s = min(max(g, delta_lo), delta_hi)
    elif on_empty == "fallback":
        s = _fallback_displacement_m(g, alpha_lo, alpha_hi, windows)
    else:
        raise ConstraintWindowEmpty(
            train_id,
            delta_lo,
            delta_hi,
            f"α = [{alpha_lo:.6g}, {alpha_hi:.6g}], β = [{windows.beta_lo_m:.6g}, {windows.beta_hi_m:.6g}], "
            f"η = [{windows.eta_lo_m:.6g}, {windows.eta_hi_m:.6g}] m",
        )
    ubar = -(speed_mps - v_ref_mps) / t + s / (t * t)
    u = ubar + params.resistance_mps2(speed_mps)
    return ControlOutput(
        u_mps2=u,
        ubar_mps2=ubar,
        s_m=s,
        g_m=g,
        delta_lo_m=delta_lo,
        delta_hi_m=delta_hi,
        alpha_lo_m=alpha_lo,
        alpha_hi_m=alpha_hi,
        feasible=feasible,
    )


def _fallback_displacement_m(g: float, alpha_lo: float, alpha_hi: float, w: LocalWindows) -> float:
    target = min(max(g, alpha_lo), alpha_hi) if alpha_lo <= alpha_hi else 0.5 * (alpha_lo + alpha_hi)
    lo, hi = w.hard_lo_m, w.hard_hi_m
    if lo > hi:  # T < T_min: the input bound cannot be kept; the velocity bound still can (β̲ < 0 < β̄)
        lo, hi = w.beta_lo_m, w.beta_hi_m
    return min(max(target, lo), hi)


class TrainController:
    """The per-train controller object: local parameters in, ``control(v_i, messages)`` per step.

    It holds no state between steps (the law is static); the object exists so the constant windows are computed
    once and so a train carries only *its own* parameters.
    """

    def __init__(
        self, train_id: str, params: TrainParams, sample_time_s: float, v_ref_mps: float, on_empty: str = "raise"
    ) -> None:
        if on_empty not in ON_EMPTY_CHOICES:
            raise ValueError(f"on_empty: expected one of {', '.join(ON_EMPTY_CHOICES)}, got {on_empty!r}")
        self.train_id = train_id
        self.params = params
        self.sample_time_s = sample_time_s
        self.v_ref_mps = v_ref_mps
        self.on_empty = on_empty
        self.windows = local_windows(params, sample_time_s, v_ref_mps)

    def control(self, speed_mps: float, messages: Sequence[NeighbourMessage]) -> ControlOutput:
        return control_step(
            self.train_id,
            speed_mps,
            messages,
            self.params,
            self.windows,
            self.sample_time_s,
            self.v_ref_mps,
            self.on_empty,
        )


# ------------------------------------------------------------------------------------------------ engine adapter


@dataclass(frozen=True)
class DistributedConstrainedParams:
    """Scenario parameters of ``distributed_constrained`` (the train's local bounds; resistance comes from the vehicle).

    ``sample_time_s`` is the ``T`` the bounds were designed for (Assumption 2.4 depends on it); the engine's step
    must equal it. ``on_empty_window`` is ``"raise"`` or ``"fallback"`` (see the module docstring).
    """

    v_ref_mps: float = 80.0
    speed_min_mps: float = 75.0
    speed_max_mps: float = 85.0
    input_min_mps2: float = -11.0
    input_max_mps2: float = 11.0
    sample_time_s: float = 1.0
    on_empty_window: str = "raise"

    def __post_init__(self) -> None:
        require("sample_time_s", self.sample_time_s > 0.0, "a number > 0", self.sample_time_s)
        require(
            "speed_max_mps",
            self.speed_min_mps < self.speed_max_mps,
            f"a number > speed_min_mps = {self.speed_min_mps}",
            self.speed_max_mps,
        )
        require(
            "input_max_mps2",
            self.input_min_mps2 < self.input_max_mps2,
            f"a number > input_min_mps2 = {self.input_min_mps2}",
            self.input_max_mps2,
        )
        require(
            "v_ref_mps",
            self.speed_min_mps < self.v_ref_mps < self.speed_max_mps,
            f"speed_min_mps < v_ref_mps < speed_max_mps (Assumption 2.3) = ({self.speed_min_mps}, "
            f"{self.speed_max_mps})",
            self.v_ref_mps,
        )
        require(
            "on_empty_window",
            self.on_empty_window in ON_EMPTY_CHOICES,
            f"one of {', '.join(ON_EMPTY_CHOICES)}",
            self.on_empty_window,
        )


def train_params_from_vehicle(p: DistributedConstrainedParams, vehicle: VehicleParams) -> TrainParams:
    """Per-unit-mass Davis coefficients of ``vehicle`` (``A/m_eff`` …: the plant's own resistance) plus ``p``'s bounds."""
    m_eff = vehicle.effective_mass_kg
    return TrainParams(
        resist_a_mps2=vehicle.davis_a_n / m_eff,
        resist_b_per_s=vehicle.davis_b_n_per_mps / m_eff,
        resist_c_per_m=vehicle.davis_c_n_per_mps2 / m_eff,
        speed_min_mps=p.speed_min_mps,
        speed_max_mps=p.speed_max_mps,
        input_min_mps2=p.input_min_mps2,
        input_max_mps2=p.input_max_mps2,
    )


def paper_vehicle(params: TrainParams, name: str = "zhang2024_point_mass", length_m: float = 50.0) -> VehicleParams:
    """A railsim vehicle whose plant *is* eq. (1): 1 kg, no rotating allowance, no lag or jerk limit.

    The envelope is wide open (traction 1e9 N and 1e12 W, braking 1e9 m/s²) so it never clips an input inside
    ``[μ̲, μ̄]``; the design speed is 10× ``ρ̄`` so the traction cut never engages. ``length_m`` only matters in SUMO
    (spec 002 A15: keep it below the smallest ``γ̲``).
    """
    return VehicleParams(
        name=name,
        length_m=length_m,
        mass_kg=1.0,
        rotating_mass_factor=1.0,
        davis_a_n=params.resist_a_mps2,
        davis_b_n_per_mps=params.resist_b_per_s,
        davis_c_n_per_mps2=params.resist_c_per_m,
        max_speed_mps=10.0 * max(params.speed_max_mps, 1.0),
        traction_max_force_n=1e9,
        traction_max_power_w=1e12,
        service_decel_mps2=1e9,
        emergency_decel_mps2=1e9,
        jerk_limit_mps3=math.inf,
        actuator_time_constant_s=0.0,
    )


@register("distributed_constrained")
class DistributedConstrainedController:
    """Paper C's law for the railsim engine: ``command(obs)`` with the neighbours in ``obs.extras``.

    What the observation must carry (the engine provides it; nothing else is read):

    * ``obs.own.position_m``, ``obs.own.speed_mps`` — own front position (the frame of every other position) and
      speed ``v_i(k)``; ``obs.own.gradient_permille`` — compensated exactly like the plant applies it;
    * ``obs.dt_s`` — must equal ``sample_time_s`` (else :class:`railsim.errors.SimulationError`);
    * ``obs.extras["edges"]`` — ``{neighbour_id: (d_ij, γ̲_ij, γ̄_ij)}`` oriented **from this train** (``d_ij =
      x_i − x_j`` desired, positive when this train is ahead); an :class:`EdgeData` is accepted too. Its keys are
      ``𝒩_i``: an empty mapping means an isolated train (runs to ``v_r``);
    * ``obs.extras["neighbours"]`` — a tuple of :class:`~controllers.base.PredecessorState`, one per key of
      ``edges`` (extra entries are ignored), ahead **and** behind: ``train_id``, ``position_m`` (the neighbour's
      front in this train's frame at ``stamp_s``), ``speed_mps`` and ``age_s``. The neighbour's predicted next
      position is ``position_m + speed_mps·(age_s + T)``; with fresh messages (``age_s = 0``, the paper's
      assumption) that is exactly ``x_j(k) + T·v_j(k)``. A neighbour in ``edges`` without a state is an engine
      bug and raises ``KeyError``;
    * ``obs.extras["k"]`` — optional step index, only copied into ``Command.info`` for the logs (the law needs no
      clock).

    ``Command.accel_mps2`` = ``vehicle.net_to_applied(ū_i, v_i, gradient)``: the applied specific force that makes
    the plant's net acceleration ``ū_i`` (see the module docstring). ``Command.info`` carries ``u_paper_mps2``
    (= ``ū_i + f_i(v_i)``), ``ubar_mps2``, ``s_m``, ``g_m``, ``delta_lo_m``, ``delta_hi_m``, ``feasible`` and
    ``k``; ``fallback`` is True when the window was empty and ``on_empty_window = "fallback"`` was used.
    """

    def __init__(self, params: Mapping[str, Any] | None, vehicle: VehicleParams) -> None:
        self.params: DistributedConstrainedParams = params_from_mapping(DistributedConstrainedParams, params)
        self.vehicle = vehicle
        self.train_params = train_params_from_vehicle(self.params, vehicle)
        self.windows = local_windows(self.train_params, self.params.sample_time_s, self.params.v_ref_mps)
        # Assumption 2.4 at the design T: reject at construction, as the factory contract asks (ValueError).
        require(
            "sample_time_s",
            self.windows.eta_lo_m < 0.0 < self.windows.eta_hi_m,
            "T > T_min of Assumption 2.4 for this train's speed/input bounds and resistance "
            f"(η̲ = {self.windows.eta_lo_m:.6g} m, η̄ = {self.windows.eta_hi_m:.6g} m)",
            self.params.sample_time_s,
        )

    def reset(self) -> None:  # stateless law
        return None

    def messages(self, obs: Observation) -> list[NeighbourMessage]:
        """The neighbour messages ``control_step`` needs, built from ``obs`` (see the class docstring)."""
        t = self.params.sample_time_s
        edges = obs.extras.get("edges", {})
        states: dict[str, PredecessorState] = {n.train_id: n for n in obs.extras.get("neighbours", ())}
        own_next = predicted_position_m(obs.own.position_m, obs.own.speed_mps, t)
        out = []
        for j in sorted(edges):
            raw = edges[j]
            edge = raw if isinstance(raw, EdgeData) else EdgeData(float(raw[0]), float(raw[1]), float(raw[2]))
            if j not in states:
                raise KeyError(
                    f"distributed_constrained: neighbour {j!r} of {obs.own.train_id!r} is in "
                    f"extras['edges'] but has no state in extras['neighbours']"
                )
            n = states[j]
            neighbour_next = n.position_m + n.speed_mps * (n.age_s + t)
            out.append(NeighbourMessage(j, own_next - neighbour_next, edge))
        return out

    def command(self, obs: Observation) -> Command:
        t = self.params.sample_time_s
        if abs(obs.dt_s - t) > 1e-9 * t:
            raise SimulationError(
                f"distributed_constrained: the control step is {obs.dt_s} s but the controller "
                f"was designed for sample_time_s = {t} s (Paper C's law is dead-beat in T)"
            )
        out = control_step(
            obs.own.train_id,
            obs.own.speed_mps,
            self.messages(obs),
            self.train_params,
            self.windows,
            t,
            self.params.v_ref_mps,
            self.params.on_empty_window,
        )
        applied = self.vehicle.net_to_applied(out.ubar_mps2, obs.own.speed_mps, obs.own.gradient_permille)
        info = dict(
            u_paper_mps2=out.u_mps2,
            ubar_mps2=out.ubar_mps2,
            s_m=out.s_m,
            g_m=out.g_m,
            delta_lo_m=out.delta_lo_m,
            delta_hi_m=out.delta_hi_m,
            feasible=out.feasible,
            k=obs.extras.get("k"),
        )
        if not out.feasible:
            info["fallback_reason"] = "no displacement meets every pair constraint; hard limits kept first"
        return Command(accel_mps2=applied, fallback=not out.feasible, info=info)
