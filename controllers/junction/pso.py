"""Improved and plain particle-swarm optimisation (Paper E §4, spec 004 §3 and §4.2), vectorised over particles.

The optimiser is generic: it minimises ``fitness = f_c + ε·VIOL`` (Eq. 40–41) of an objective that returns
``(f_c, VIOL)`` per particle, inside a box ``[lo, hi]^D``. The junction planner passes
:func:`controllers.junction.model.evaluate`.

Improved PSO (:func:`improved_pso_params`, spec §3.6 = Algorithm 1 with the listing's flaws fixed)
    * speed-limit (constriction) factor ζ and the clamp ``|V| ≤ V_max`` (Eqs. 43, 45);
    * adaptive penalty ``ε = 10^{α(1−β)}``, β = feasible fraction of the **latest evaluation** (Eq. 42; the
      listing's cumulative ``N_f/iteration`` divides by zero — §3.5 c);
    * "no-update" bounds: a particle that leaves the box goes back to its previous position (§3.5 d;
      ``no_update_scope="dimension"`` reverts only the offending coordinates);
    * inertia falling linearly from ω_max to ω_min (Eq. 46);
    * Lu–Hou mutation: when the normalised fitness variance σ² (Eqs. 47–48) drops below σ_d² and
      ``fit(gbest) > f_d``, gbest is mutated with probability ``P_m ~ U(0.1, 0.3)`` by
      ``g_d ← g_d (1 + 0.5 ξ_d)`` (Eqs. 49–50), clipped to the box and accepted unconditionally; a separate
      best-feasible archive keeps the answer (§3.5 e);
    * stale fitness: personal and global bests store ``f_c`` and ``VIOL`` separately and are re-scored with the
      current ε before every comparison (§3.5 f).
    Iterations are counted every loop by default (``count_mode="every_loop"``); ``"improving"`` counts only loops
    that change gbest's fitness (the paper's listing), always under the hard caps ``max_loops`` and
    ``stall_loops``.

Plain PSO (:func:`plain_pso_params`, spec §4.2): Shi–Eberhart global best with ζ = 1, V clamp at the box width,
a static penalty ``10^{α/2}``, constant ω = 0.7298, c1 = c2 = 1.49618, positions clipped to the box, no
mutation. Both variants share encoding, initial swarm and fitness, so any difference is the algorithm's.

Determinism: every random number comes from the ``numpy.random.Generator`` passed in. With ``wall_time_s`` set
the run stops at the first loop that ends past the budget, so results then also depend on machine speed.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np

from controllers.braking import require

Objective = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class PSOParams:
    """Swarm settings (spec §6 #13–22 defaults). ``vmax_fraction`` scales the box width to V_max."""

    swarm_size: int = 50
    max_iterations: int = 300
    max_loops: int = 3000
    stall_loops: int = 200
    constriction: float = 0.729  # ζ
    cognitive: float = 2.05  # c1
    social: float = 2.05  # c2
    inertia_max: float = 0.9  # ω_max
    inertia_min: float = 0.4  # ω_min
    vmax_fraction: float = 0.2  # V_max = fraction · (hi − lo)
    penalty_alpha: float = 3.0  # α
    adaptive_penalty: bool = True
    no_update_bounds: bool = True  # False: clip to the box
    no_update_scope: Literal["particle", "dimension"] = "particle"  # what reverts when a bound is crossed
    linear_inertia: bool = True  # False: constant ω = inertia_max
    mutation: bool = True
    variance_threshold: float = 1.0  # σ_d²
    fitness_floor: float = 0.0  # f_d
    mutation_prob_range: tuple[float, float] = (0.1, 0.3)
    count_mode: Literal["every_loop", "improving"] = "every_loop"
    wall_time_s: float | None = None  # stop after this much wall time (checked once per loop)
    seed_fraction: float = 0.3  # share of the initial swarm built by the caller's heuristic seeds

    def __post_init__(self) -> None:
        require("swarm_size", self.swarm_size >= 2, "an integer >= 2", self.swarm_size)
        require("max_iterations", self.max_iterations >= 1, "an integer >= 1", self.max_iterations)
        require("constriction", 0.0 < self.constriction <= 1.0, "0 < ζ <= 1", self.constriction)
        require("vmax_fraction", self.vmax_fraction > 0.0, "a number > 0", self.vmax_fraction)
        require(
            "count_mode", self.count_mode in ("every_loop", "improving"), "every_loop or improving", self.count_mode
        )
        require("seed_fraction", 0.0 <= self.seed_fraction <= 1.0, "a fraction in [0, 1]", self.seed_fraction)
        require(
            "wall_time_s", self.wall_time_s is None or self.wall_time_s > 0.0, "None or a number > 0", self.wall_time_s
        )


def improved_pso_params(**overrides) -> PSOParams:
    return replace(PSOParams(), **overrides)


def plain_pso_params(**overrides) -> PSOParams:
    base = PSOParams(
        constriction=1.0,
        cognitive=1.49618,
        social=1.49618,
        inertia_max=0.7298,
        inertia_min=0.7298,
        vmax_fraction=1.0,
        adaptive_penalty=False,
        no_update_bounds=False,
        linear_inertia=False,
        mutation=False,
        count_mode="every_loop",
    )
    return replace(base, **overrides)


@dataclass
class PSOResult:
    x: np.ndarray  # best position (best feasible if any was seen, else gbest)
    cost: float  # f_c at x
    violation: float  # VIOL at x
    feasible: bool
    iterations: int
    loops: int
    wall_time_s: float
    mutations: int
    history: dict[str, list[float]] = field(default_factory=dict)  # per loop: gbest fitness, β, ε, ω, σ²


def run_pso(
    objective: Objective,
    dimension: int,
    bounds: tuple[float, float],
    params: PSOParams,
    rng: np.random.Generator,
    initial: np.ndarray | None = None,
) -> PSOResult:
    """Minimise ``objective`` over ``[lo, hi]^dimension``; ``initial`` rows (clipped) replace the first particles."""
    t_start = time.perf_counter()
    lo, hi = float(bounds[0]), float(bounds[1])
    require("bounds", hi > lo, "lo < hi", bounds)
    Np, D = params.swarm_size, dimension
    width = hi - lo
    vmax = params.vmax_fraction * width
    X = rng.uniform(lo, hi, size=(Np, D))
    if initial is not None and len(initial):
        init = np.clip(np.atleast_2d(np.asarray(initial, dtype=float)), lo, hi)[:Np]
        X[: init.shape[0]] = init
    V = rng.uniform(-vmax, vmax, size=(Np, D))
    FC, VIOL = objective(X)
    static_eps = 10.0 ** (params.penalty_alpha / 2.0)

    def eps_of(viol: np.ndarray) -> float:
        if not params.adaptive_penalty:
            return static_eps
        beta = float(np.mean(viol <= 0.0))
        return 10.0 ** (params.penalty_alpha * (1.0 - beta))

    eps = eps_of(VIOL)
    pbest, pFC, pVIOL = X.copy(), FC.copy(), VIOL.copy()
    g = int(np.argmin(FC + eps * VIOL))
    gbest, gFC, gVIOL = X[g].copy(), float(FC[g]), float(VIOL[g])
    arch_x, arch_fc = None, np.inf

    def archive(Xc: np.ndarray, fc: np.ndarray, viol: np.ndarray) -> None:
        nonlocal arch_x, arch_fc
        ok = viol <= 0.0
        if ok.any():
            i = int(np.argmin(np.where(ok, fc, np.inf)))
            if fc[i] < arch_fc:
                arch_x, arch_fc = Xc[i].copy(), float(fc[i])

    archive(X, FC, VIOL)
    it = loops = mutations = stall = 0
    omega = params.inertia_max
    hist: dict[str, list[float]] = {"gbest_fitness": [], "beta": [], "epsilon": [], "omega": [], "sigma2": []}
    first = True
    while it < params.max_iterations and loops < params.max_loops:
        loops += 1
        X_last = X.copy()
        gfit_last = gFC + eps * gVIOL
        if not first:
            FC, VIOL = objective(X)
        first = False
        archive(X, FC, VIOL)
        FIT = FC + eps * VIOL
        imp = FIT < pFC + eps * pVIOL
        pbest[imp], pFC[imp], pVIOL[imp] = X[imp], FC[imp], VIOL[imp]
        pFIT = pFC + eps * pVIOL
        b = int(np.argmin(pFIT))
        if pFIT[b] < gFC + eps * gVIOL:
            gbest, gFC, gVIOL = pbest[b].copy(), float(pFC[b]), float(pVIOL[b])
        gfit = gFC + eps * gVIOL
        changed = gfit != gfit_last
        stall = 0 if gfit < gfit_last else stall + 1
        if params.count_mode == "every_loop" or changed:
            it += 1
        r1 = rng.random((Np, D))
        r2 = rng.random((Np, D))
        V = params.constriction * (omega * V + params.cognitive * r1 * (pbest - X) + params.social * r2 * (gbest - X))
        np.clip(V, -vmax, vmax, out=V)
        X_new = X + V
        if params.no_update_bounds:
            out = (X_new < lo) | (X_new > hi)
            if params.no_update_scope == "particle":
                out = np.broadcast_to(np.any(out, axis=1)[:, None], out.shape)
            X = np.where(out, X_last, X_new)
        else:
            X = np.clip(X_new, lo, hi)
        eps = eps_of(VIOL)
        if params.linear_inertia:
            omega = params.inertia_max - it * (params.inertia_max - params.inertia_min) / params.max_iterations
        dev = FIT - FIT.mean()
        big = float(np.max(np.abs(dev)))
        f_norm = big if big > 1.0 else 1.0
        sigma2 = float(np.sum((dev / f_norm) ** 2))
        gfit = gFC + eps * gVIOL
        if params.mutation and sigma2 < params.variance_threshold and gfit > params.fitness_floor:
            pm = rng.uniform(*params.mutation_prob_range)
            if rng.random() < pm:
                gbest = np.clip(gbest * (1.0 + 0.5 * rng.standard_normal(D)), lo, hi)
                fc1, v1 = objective(gbest[None, :])
                gFC, gVIOL = float(fc1[0]), float(v1[0])
                archive(gbest[None, :], fc1, v1)
                mutations += 1
        hist["gbest_fitness"].append(gFC + eps * gVIOL)
        hist["beta"].append(float(np.mean(VIOL <= 0.0)))
        hist["epsilon"].append(eps)
        hist["omega"].append(omega)
        hist["sigma2"].append(sigma2)
        if stall >= params.stall_loops:
            break
        if params.wall_time_s is not None and time.perf_counter() - t_start >= params.wall_time_s:
            break
    if arch_x is not None:
        x, fc, viol = arch_x, arch_fc, 0.0
    else:
        fc_g, v_g = objective(gbest[None, :])
        x, fc, viol = gbest, float(fc_g[0]), float(v_g[0])
    return PSOResult(
        x=np.asarray(x),
        cost=float(fc),
        violation=float(viol),
        feasible=viol <= 0.0,
        iterations=it,
        loops=loops,
        wall_time_s=time.perf_counter() - t_start,
        mutations=mutations,
        history=hist,
    )
