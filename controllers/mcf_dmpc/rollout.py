"""Prediction over the MPC horizon (spec 000 §2.2, §2.6): the predecessor's broadcast plan, and the follower's
own trajectory under a model-index sequence (MCF, Eq. 29) or a continuous control sequence (DMPC baseline).

Time grid: step ``j = 0 … Np`` is ``t_k + j·τ``; ``u_j`` acts over ``[t_j, t_{j+1}]`` (A2: Np controls
``u(t_k|t_k) … u(t_k|t_{k+Np−1})``). The prediction model is Eq. (2) with the resistance evaluated at the
current speed (explicit)::

    s_{j+1} = s_j + τ·v_j + τ²/2·(u_j − ω(v_j)),   v_{j+1} = v_j + τ·(u_j − ω(v_j))

No clamp at v = 0 inside predictions: a predicted v < 0 is a violation of Eq. (20) and is penalised by the cost.

MCF rollout (Eq. 29): at every predicted step the law named by ``m_j`` (0 IDM+, 1 CACC+, 2 FVD+) computes
``u_j`` from the predicted own state and the predecessor's predicted state at the same step; CACC's ``a_{i−1}``
is the predecessor's acceleration at step ``j`` (A13, default: its *net* acceleration from the planned speeds,
option ``"applied"``: its planned control). Rollouts are vectorised over a population: sequences ``(P, Np)``,
parameters ``(N_THETA,)`` or ``(P, N_THETA)``. Up to :data:`SCALAR_MAX_ROWS` rows the same equations run in plain floats
(:func:`_rollout_scalar`): the recursion over the horizon is sequential, so numpy pays ~40 operations of
overhead per step whatever the batch, while a float loop evaluates only the law each row selects (measured:
~37x faster for the 2-row calls of the greedy pass, ~2x for a population of 50). Results agree to rounding.

Plans on the wire (``Command.info["plan"]`` and :class:`~controllers.base.PredecessorState`): ``Np + 1`` samples
at ``stamp + j·dt`` (entry 0 is the state at the decision time), ``accel_mps2[j]`` the planned control over
``[t_j, t_{j+1}]`` (last entry repeated). The receiver uses a plan while it is *fresh* (message age ≤
``max_plan_age_s``): it shifts it by the age (:func:`predecessor_horizon`) and extends it past its end at
constant speed. Without a plan, or with a stale one (lost messages: the last delivered report grows old), it
extrapolates the last reported state at constant speed; :attr:`PredecessorHorizon.source` says which
(``"plan"``, ``"stale"``, ``"absent"``), and the controllers turn changes into events.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from controllers.base import PredecessorState
from controllers.mcf_dmpc.cf_models import N_THETA, RATIO_CAP, V_FLOOR_MPS, all_models
from controllers.mcf_dmpc.spacing import TrainParamsA, desired_spacing_m

__all__ = [
    "PredecessorHorizon",
    "Trajectory",
    "constant_speed_horizon",
    "expand_sequence",
    "plan_dict",
    "predecessor_horizon",
    "rollout_controls",
    "rollout_models",
]

FEEDFORWARDS = ("net", "applied")
SCALAR_MAX_ROWS = 64  # up to this many rows plain floats beat numpy (measured: 37x at 2 rows, 2x at 50)


@dataclass(frozen=True)
class PredecessorHorizon:
    """The predecessor over the horizon in the follower's frame: ``position_m``/``speed_mps`` at ``j = 0 … Np``,
    ``accel_mps2`` the CACC feed-forward ``a_{i−1}(t_j)`` for ``j = 0 … Np−1``."""

    position_m: np.ndarray
    speed_mps: np.ndarray
    accel_mps2: np.ndarray
    length_m: float
    emergency_decel_mps2: float
    source: str = "absent"  # "plan": the broadcast plan; "stale"/"absent": extrapolated (plan too old / none)

    @property
    def steps(self) -> int:
        return len(self.accel_mps2)


@dataclass(frozen=True)
class Trajectory:
    """A batch of predicted trajectories: ``u (P, Np)``, ``v`` and ``s`` ``(P, Np + 1)`` (column 0 = now)."""

    u: np.ndarray
    v: np.ndarray
    s: np.ndarray


def constant_speed_horizon(
    position_m: float,
    speed_mps: float,
    steps: int,
    dt_s: float,
    length_m: float,
    emergency_decel_mps2: float,
    elapsed_s: float = 0.0,
) -> PredecessorHorizon:
    """A predecessor cruising at constant speed (no plan received), ``elapsed_s`` after its report."""
    t = elapsed_s + dt_s * np.arange(steps + 1)
    return PredecessorHorizon(
        position_m + speed_mps * t,
        np.full(steps + 1, float(speed_mps)),
        np.zeros(steps),
        float(length_m),
        float(emergency_decel_mps2),
    )


def predecessor_horizon(
    pred: PredecessorState,
    steps: int,
    dt_s: float,
    feedforward: str = "net",
    emergency_decel_mps2: float | None = None,
    max_plan_age_s: float = math.inf,
) -> PredecessorHorizon:
    """Sample the predecessor's broadcast plan at ``age + j·dt`` (j = 0 … steps) — see the module docstring.

    ``emergency_decel_mps2`` overrides ``pred.emergency_decel_mps2`` (Paper A: all units identical, so a controller
    may use its own |b^(m)| instead of trusting a message default). A plan older than ``max_plan_age_s`` is not
    used: the last reported state is extrapolated instead (``source == "stale"``).
    """
    if feedforward not in FEEDFORWARDS:
        raise ValueError(f"feedforward: expected one of {', '.join(FEEDFORWARDS)}, got {feedforward!r}")
    b_p = pred.emergency_decel_mps2 if emergency_decel_mps2 is None else emergency_decel_mps2
    age = max(pred.age_s, 0.0)
    n = min(len(pred.planned_position_m), len(pred.planned_speed_mps))
    has_plan = n >= 2 and pred.plan_dt_s > 0.0
    if not has_plan or age > max_plan_age_s:
        hz = constant_speed_horizon(pred.position_m, max(pred.speed_mps, 0.0), steps, dt_s, pred.length_m, b_p, age)
        acc = np.full(steps, float(pred.accel_mps2)) if feedforward == "applied" else hz.accel_mps2
        source = "stale" if has_plan else "absent"
        return PredecessorHorizon(hz.position_m, hz.speed_mps, acc, hz.length_m, hz.emergency_decel_mps2, source)
    tp = pred.plan_dt_s * np.arange(n)
    xp = np.asarray(pred.planned_position_m[:n], dtype=float)
    vp = np.asarray(pred.planned_speed_mps[:n], dtype=float)
    tq = age + dt_s * np.arange(steps + 1)
    beyond = np.maximum(tq - tp[-1], 0.0)
    pos = np.interp(tq, tp, xp) + vp[-1] * beyond  # np.interp holds the end value; add the cruise past the end
    spd = np.interp(tq, tp, vp)
    if feedforward == "net":
        acc = np.diff(spd) / dt_s
    else:
        ua = np.asarray(pred.planned_accel_mps2, dtype=float)
        if len(ua) == 0:
            acc = np.diff(spd) / dt_s
        else:
            idx = np.minimum((tq[:-1] / pred.plan_dt_s + 1e-9).astype(int), len(ua) - 1)
            acc = ua[idx]
    return PredecessorHorizon(pos, spd, acc, float(pred.length_m), float(b_p), "plan")


def expand_sequence(seq: np.ndarray, steps: int) -> np.ndarray:
    """Move blocking (A15 option): a ``(P, D)`` sequence with ``D < steps`` holds its last index to ``steps``."""
    seq = np.atleast_2d(np.asarray(seq))
    d = seq.shape[1]
    if d == steps:
        return seq
    if d > steps:
        raise ValueError(f"sequence length {d} exceeds the horizon {steps}")
    return np.concatenate([seq, np.repeat(seq[:, -1:], steps - d, axis=1)], axis=1)


def rollout_models(
    seq: np.ndarray,
    x0_m: float,
    v0_mps: float,
    pred: PredecessorHorizon,
    theta: np.ndarray,
    train: TrainParamsA,
    *,
    resistance_feedforward: bool = False,
) -> Trajectory:
    """MCF rollout (Eq. 29) of model-index sequences ``seq (P, Np)`` from the own state ``(x0, v0)``.

    ``resistance_feedforward`` (A9 option): the law's output is a *net* acceleration and ``u = a_CF + ω(v)``
    (then saturated); default off: the law's output is the control u.
    """
    seq = np.atleast_2d(np.asarray(seq, dtype=np.int64))
    pop, steps = seq.shape
    if steps != pred.steps:
        raise ValueError(f"sequence length {steps} != predecessor horizon {pred.steps}")
    theta = np.asarray(theta, dtype=float)
    if pop <= SCALAR_MAX_ROWS and theta.shape in ((N_THETA,), (pop, N_THETA)):
        return _rollout_scalar(seq, x0_m, v0_mps, pred, theta, train, resistance_feedforward)
    tau = train.dt_s
    u_lo, u_hi = -train.service_decel_mps2, train.max_accel_mps2
    used = [bool(np.any(seq == m)) for m in range(3)]
    single = sum(used) == 1
    u = np.empty((pop, steps))
    v = np.empty((pop, steps + 1))
    s = np.empty((pop, steps + 1))
    v[:, 0], s[:, 0] = v0_mps, x0_m
    vj = v[:, 0].copy()
    sj = s[:, 0].copy()
    # With a feed-forward the saturation must come after adding ω, so evaluate the laws unsaturated.
    lo, hi = (-np.inf, np.inf) if resistance_feedforward else (u_lo, u_hi)
    for j in range(steps):
        vp = pred.speed_mps[j]
        spacing = pred.position_m[j] - sj
        de = desired_spacing_m(vj, vp, train, pred.length_m, pred.emergency_decel_mps2)
        outs = _laws(used, vj, vp, spacing, de, pred.accel_mps2[j], theta, train.max_accel_mps2, lo, hi)
        uj = outs[int(np.flatnonzero(used)[0])] if single else np.choose(seq[:, j], outs)
        omega = _omega(vj, train.davis_c0_mps2, train.davis_c1_per_s, train.davis_c2_per_m)
        if resistance_feedforward:
            uj = np.clip(uj + omega, u_lo, u_hi)
        a = uj - omega
        sj = sj + tau * vj + 0.5 * tau * tau * a
        vj = vj + tau * a
        u[:, j], v[:, j + 1], s[:, j + 1] = uj, vj, sj
    return Trajectory(u, v, s)


def _rollout_scalar(
    seq: np.ndarray,
    x0_m: float,
    v0_mps: float,
    pred: PredecessorHorizon,
    theta: np.ndarray,
    train: TrainParamsA,
    resistance_feedforward: bool = False,
) -> Trajectory:
    """:func:`rollout_models` for up to :data:`SCALAR_MAX_ROWS` rows (Θ ``(N_THETA,)`` or one per row ``(P, N_THETA)``) in
    plain floats: the same arithmetic as the vectorised laws of :mod:`.cf_models` (guards A11 included), but
    only the law each step selects is evaluated.

    Why: the optimisers score a population (≤ 50 rows) or, in the greedy refinement of Eq. (28), two sequences
    per call; the recursion over Np steps is sequential, so numpy pays its per-operation overhead (~1 µs × ~40
    operations × Np steps) whatever the batch, while plain floats cost ~1 µs per row and step.
    """
    thetas = np.broadcast_to(theta, (seq.shape[0], N_THETA)).tolist()
    tau = train.dt_s
    half_tau2 = 0.5 * tau * tau
    u_lo, u_hi, a_max = -train.service_decel_mps2, train.max_accel_mps2, train.max_accel_mps2
    c0, c1, c2 = train.davis_c0_mps2, train.davis_c1_per_s, train.davis_c2_per_m
    # D^(e) = L^(s) + L_{i-1} + v²/(2|b^(c)|) − v_{i−1}²/(2|b^(m)_{i−1}|): the predecessor part is known per step
    own_k = 1.0 / (2.0 * train.service_decel_mps2)
    xp = pred.position_m.tolist()
    vp_list = pred.speed_mps.tolist()
    ap = pred.accel_mps2.tolist()
    base = [train.safety_margin_m + pred.length_m - vpj * vpj / (2.0 * pred.emergency_decel_mps2) for vpj in vp_list]
    pop, steps = seq.shape
    u = np.empty((pop, steps))
    v = np.empty((pop, steps + 1))
    s = np.empty((pop, steps + 1))
    for r, row in enumerate(seq.tolist()):
        th1, th2, th3, th4, th5, th6, th7, *biases = thetas[r]
        vj, sj = float(v0_mps), float(x0_m)
        us, vs, ss = [], [vj], [sj]
        for j, m in enumerate(row):
            vpj = vp_list[j]
            spacing = xp[j] - sj
            de = base[j] + vj * vj * own_k
            if m == 0:  # enhanced IDM, Eq. (8)
                if spacing > 0.0:
                    vpos = vj if vj > 0.0 else 0.0
                    speed_term = (vpos / (vpj if vpj > V_FLOOR_MPS else V_FLOOR_MPS)) ** th1
                    ratio = (de if de > 0.0 else 0.0) / spacing
                    if ratio > RATIO_CAP:
                        ratio = RATIO_CAP
                    a = a_max * (2.0 - speed_term - ratio**th2)
                else:
                    a = -math.inf
            elif m == 1:  # enhanced CACC, Eq. (10)
                a = th3 * ap[j] + th4 * (spacing - de) + th5 * (vpj - vj)
            else:  # enhanced FVD, Eq. (11)-(13)
                v_star = vpj * (vpj + spacing - de) / (vj if vj > V_FLOOR_MPS else V_FLOOR_MPS)
                a = th6 * (v_star - vj) + (th7 if spacing <= de else 0.0) * (vpj - vj)
            a += biases[m]  # the law's control offset (cf_models docstring)
            av = abs(vj)
            omega = c0 + c1 * av + c2 * av * av if av != 0.0 else 0.0
            if resistance_feedforward:  # A9 option: the law gives the net acceleration, saturate u = a + ω
                a += omega
            uj = u_lo if a < u_lo else (u_hi if a > u_hi else a)
            acc = uj - omega
            sj = sj + tau * vj + half_tau2 * acc
            vj = vj + tau * acc
            us.append(uj)
            vs.append(vj)
            ss.append(sj)
        u[r], v[r], s[r] = us, vs, ss
    return Trajectory(u, v, s)


def _laws(used, v, vp, spacing, de, a_pred, theta, a_max, lo, hi):
    """The enhanced laws with their offsets (all three: the population path is for large mixed batches)."""
    return all_models(v, vp, spacing, de, a_pred, theta, a_max, lo, hi)


def rollout_controls(u: np.ndarray, x0_m: float, v0_mps: float, train: TrainParamsA) -> Trajectory:
    """Eq. (2) under given controls ``u (P, Np)`` (DMPC baseline, brute-force references)."""
    u = np.atleast_2d(np.asarray(u, dtype=float))
    pop, steps = u.shape
    tau = train.dt_s
    c0, c1, c2 = train.davis_c0_mps2, train.davis_c1_per_s, train.davis_c2_per_m
    if pop == 1:  # one trajectory (the DMPC solve): plain floats beat numpy's per-call overhead ~10x
        vs, ss = [float(v0_mps)], [float(x0_m)]
        vj, sj = vs[0], ss[0]
        for uj in u[0].tolist():
            av = abs(vj)
            a = uj - (c0 + c1 * av + c2 * av * av if av != 0.0 else 0.0)
            sj = sj + tau * vj + 0.5 * tau * tau * a
            vj = vj + tau * a
            vs.append(vj)
            ss.append(sj)
        return Trajectory(u, np.array([vs]), np.array([ss]))
    v = np.empty((pop, steps + 1))
    s = np.empty((pop, steps + 1))
    v[:, 0], s[:, 0] = v0_mps, x0_m
    for j in range(steps):
        a = u[:, j] - _omega(v[:, j], c0, c1, c2)
        s[:, j + 1] = s[:, j] + tau * v[:, j] + 0.5 * tau * tau * a
        v[:, j + 1] = v[:, j] + tau * a
    return Trajectory(u, v, s)


def _omega(v: np.ndarray, c0: float, c1: float, c2: float) -> np.ndarray:
    """Davis resistance per unit mass, zero at standstill (same as :meth:`TrainParamsA.resistance_mps2`)."""
    av = np.abs(v)
    return (c0 + c1 * av + c2 * av * av) * (av != 0.0)


def plan_dict(traj: Trajectory, row: int, dt_s: float) -> dict[str, object]:
    """``Command.info["plan"]`` from row ``row`` of a trajectory: ``Np + 1`` samples (see module docstring)."""
    u = traj.u[row]
    return {
        "dt_s": float(dt_s),
        "position_m": tuple(float(x) for x in traj.s[row]),
        "speed_mps": tuple(float(x) for x in traj.v[row]),
        "accel_mps2": tuple(float(x) for x in np.append(u, u[-1])),
    }
