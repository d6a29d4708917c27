"""The junction coupling problem of Paper E (spec 004) as numbers: geometry, parameters, encoding, rollout, cost.

What the planner optimises
    ``n`` trains on different entry tracks must pass one or two switches, merge onto the trunk and reach the
    *coupled state* at the planned point F (spec §2.1). Each train's decision is a vector of piecewise-constant
    accelerations, **one per distance segment of its own path** (Eq. 16), bounded to ``[a_min, a_max]`` (Eq. 36).
    A particle of the PSO is the concatenation of all trains' vectors (§3.7).

Rollout in the distance domain (exact, no time stepping)
    With a constant acceleration ``a_j`` over a segment of length ``ℓ_j`` the kinematic double integrator gives
    ``v_{j+1}² = v_j² + 2 a_j ℓ_j`` and the traversal time ``2 ℓ_j / (v_j + v_{j+1})``. Speeds at every segment
    boundary are therefore a cumulative sum and the boundary times another one: a whole swarm (particles ×
    trains × segments) is evaluated with a handful of vectorised numpy calls. This is the spec's §2.9 rollout
    with Δt → 0 (the spec integrates with Δt = 0.1 s; :func:`controllers.junction.simulate.simulate_plan`
    does exactly that, as an independent check of this module). If ``v²`` would turn negative the train
    stopped inside the segment: the profile is infeasible (Eq. 38), the violation is the signed speed
    ``−sqrt(−v²)`` below ``v_eps`` and the times use ``v_eps`` so they stay finite.

Segment grid (spec §6 #3, reading chosen here)
    Segments are anchored at the final merge switch σ* in the common coordinate ``s̃ = s − d_{k,σ*}``: every
    train has breakpoints at ``s̃ = m·Δx`` and additionally at its start, at each of its switches and at F. So
    switches and F always lie on segment boundaries (the spec's ``x_s``), and trains sharing track share
    breakpoints, which makes the no-overtaking check a comparison of passage times at common points. The
    profile ends at F: the followers reach their slot before F, and behind F every train holds its speed
    (coupled running, segment H), so no margin segments are needed.

Cost (Eqs. 17–26, λ1..λ4 from :class:`JunctionParams`)
    ``T_c`` = time the leader (first train through σ*) reaches F; ``t_1k`` = passage time at σ*,
    ``t_2k = T_c − t_1k`` (spec §6 #9). For each train ``λ4(t_1k + t_2k) + λ2·2·D_braking/(v_k − V_δ)``; for each
    follower ``λ1·|D − S_m|/v_k + λ3·(|Δv| + V_δ)`` relative to its predecessor in the passing order (absolute
    values and the follower's speed in Γ1: spec §6 #8 and §2.7). ``S_m`` is the corrected Eq. (1) of spec §6 #5
    (``max(0, (v_f+V_δ)−(v_l−V_δ))·(T_1+T_2) + L_pred + S_0``, head-to-head); ``paper_literal_margin`` keeps the
    printed ``− L_k``.

Constraints (Eqs. 37–39 plus the implicit ones of §2.8), each as ``max(g, 0)`` and summed into one violation:
    switch speed at every switch (normal 15 / reverse 10 m/s, minus a 1e-3 margin for the strict ``<``);
    ``v ≥ v_eps`` and ``v ≤ v_max`` (Eq. 38, spec §6 #11); switch headway: consecutive trains at a switch must
    be ``t_ls`` apart — by default **only when they use different legs** (the switch must be thrown between
    them; the paper-literal "every consecutive pair" is ``headway_all_consecutive=True``, spec §6 #10); the
    switch's own state (a switch set to the other leg or locked until ``locked_until_s`` delays the first
    passage); no overtaking on shared track (passage times at shared breakpoints keep one sign, in seconds);
    the coupled state at ``T_c``: ``|D − S_m| ≤ S_th`` and ``|Δv| ≤ V_th`` (Eqs. 2–3), planned inside
    ``planning_tolerance_share`` (0.9) of them so a plan executed at Δt = 0.1 s still couples; trains on shared
    track pass every shared breakpoint at least ``min_time_gap_s`` apart (mass points must not touch).

Extension (off by default, the paper has no such constraint): ``rbd_reaction_s > 0`` adds the
**relative-braking-distance spacing** of the engine's coupled-follower guard on shared track: at every instant at
which the follower is on track it shares with the leader, the leader's rear must be at least
:func:`controllers.braking.relative_braking_distance_m` ahead — ``v_f·T + a_f·T²/2 + (v_f + a_f·T)²/(2b) −
v_l²/(2b) + margin`` with the follower's planned acceleration ``a_f``, ``T = rbd_reaction_s``, ``b =
rbd_decel_mps2`` for both trains — the guard's own function, so a plan the guard would cap is infeasible. It is
checked at the follower's shared breakpoints and at ``rbd_samples_per_segment − 1`` interior instants of every
segment (the leader's position there is exact: constant acceleration within its segment). Eq. 1's margin
(closing speed × (T_1 + T_2)) lets a plan close at several m/s tens of metres behind its leader, which the guard
refuses.

The model that SUMO actually flies is :func:`sumo_corrected_params`: switch interval 21.6 s (the
interlocking's release + throw + approach, docs/guide/paper-experiments.md, "Paper E: the junction planner online"), 20 m trains, ``S_0`` = 15 m and
the guard on (T = 0.2 s, b = 1.5 m/s², margin 10 m).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from controllers.braking import relative_braking_distance_m, require

Leg = Literal["normal", "reverse"]


@dataclass(frozen=True)
class JunctionParams:
    """Model parameters (spec Table 1 and the §6 defaults). Units in the names."""

    accel_min_mps2: float = -1.2  # a_min, Table 1
    accel_max_mps2: float = 1.0  # a_max, Table 1
    normal_speed_mps: float = 15.0  # v_lsn, Table 1
    reverse_speed_mps: float = 10.0  # v_lsr, Table 1
    line_speed_mps: float = 20.0  # v_max of segment G, Table 1 (closed bound, spec §6 #11)
    throw_time_s: float = 10.0  # t_ls, Table 1
    segment_m: float = 20.0  # Δx (spec §6 #3 option; 10 m doubles the dimension)
    min_speed_mps: float = 0.1  # v_eps for the open bound v > 0
    switch_speed_margin_mps: float = 1e-3  # strict "<" of Eq. 37
    speed_error_mps: float = 0.1  # V_δ (Eq. 1, 18, 19)
    comm_delay_s: float = 0.1  # T_1
    processing_delay_s: float = 0.2  # T_2
    standstill_gap_m: float = 10.0  # S_0 of the corrected Eq. 1
    pred_length_m: float = 0.0  # L_k; 0 for mass points (the paper reproduction)
    gap_tolerance_m: float = 5.0  # S_th (Eq. 2)
    speed_tolerance_mps: float = 0.5  # V_th (Eq. 3)
    braking_distance_m: float = 17.0  # D_braking (Eq. 23), constant (spec §2.5)
    weight_gap: float = 1.0  # λ1
    weight_speed: float = 1.0  # λ2
    weight_speed_diff: float = 1.0  # λ3
    weight_time: float = 1.0  # λ4
    headway_all_consecutive: bool = False  # paper-literal Eq. 39 scope (spec §6 #10)
    planning_tolerance_share: float = 0.9  # the planner aims inside S_th, V_th by this share (integration slack)
    min_time_gap_s: float = 0.3  # follower reaches every shared point at least this much later
    paper_literal_margin: bool = False  # Eq. 1 with "− L_k" instead of "+ L_pred + S_0"
    # relative-braking-distance spacing on shared track (extension; off = the paper): at every instant the
    # follower's front must stay behind the leader's rear by controllers.braking.relative_braking_distance_m
    rbd_reaction_s: float = 0.0  # T, the guard's dead time (0: the constraint is off)
    rbd_decel_mps2: float = 1.2  # b, both trains' emergency braking
    rbd_margin_m: float = 10.0
    rbd_samples_per_segment: int = 4  # instants checked per follower segment (its start + interior ones)

    def __post_init__(self) -> None:
        require("accel_min_mps2", self.accel_min_mps2 < 0.0, "a number < 0", self.accel_min_mps2)
        require("accel_max_mps2", self.accel_max_mps2 > 0.0, "a number > 0", self.accel_max_mps2)
        require(
            "reverse_speed_mps",
            0.0 < self.reverse_speed_mps <= self.normal_speed_mps,
            "0 < reverse_speed_mps <= normal_speed_mps",
            self.reverse_speed_mps,
        )
        require(
            "line_speed_mps", self.line_speed_mps >= self.normal_speed_mps, ">= normal_speed_mps", self.line_speed_mps
        )
        require("throw_time_s", self.throw_time_s >= 0.0, "a number >= 0", self.throw_time_s)
        require("segment_m", self.segment_m > 0.0, "a number > 0", self.segment_m)
        require("min_speed_mps", self.min_speed_mps > 0.0, "a number > 0", self.min_speed_mps)
        require("gap_tolerance_m", self.gap_tolerance_m > 0.0, "a number > 0", self.gap_tolerance_m)
        require("speed_tolerance_mps", self.speed_tolerance_mps > 0.0, "a number > 0", self.speed_tolerance_mps)
        require(
            "planning_tolerance_share",
            0.0 < self.planning_tolerance_share <= 1.0,
            "a share in (0, 1]",
            self.planning_tolerance_share,
        )
        require("braking_distance_m", self.braking_distance_m > 0.0, "a number > 0", self.braking_distance_m)
        require("rbd_decel_mps2", self.rbd_decel_mps2 > 0.0, "a number > 0", self.rbd_decel_mps2)
        require(
            "rbd_samples_per_segment",
            int(self.rbd_samples_per_segment) == self.rbd_samples_per_segment and self.rbd_samples_per_segment >= 1,
            "an integer >= 1",
            self.rbd_samples_per_segment,
        )
        for name in (
            "weight_gap",
            "weight_speed",
            "weight_speed_diff",
            "weight_time",
            "speed_error_mps",
            "comm_delay_s",
            "processing_delay_s",
            "standstill_gap_m",
            "pred_length_m",
            "rbd_reaction_s",
            "rbd_margin_m",
        ):
            value = getattr(self, name)
            require(name, value >= 0.0, "a number >= 0", value)

    def limit_speed_mps(self, leg: Leg) -> float:
        return self.normal_speed_mps if leg == "normal" else self.reverse_speed_mps


def safety_margin_m(
    leader_speed_mps: np.ndarray | float, follower_speed_mps: np.ndarray | float, params: JunctionParams
) -> np.ndarray:
    """``S_m`` of Eq. (1), head-to-head, corrected reading of spec §6 #5 (or the printed one, by flag)."""
    closing = (np.asarray(follower_speed_mps) + params.speed_error_mps) - (
        np.asarray(leader_speed_mps) - params.speed_error_mps
    )
    delay_s = params.comm_delay_s + params.processing_delay_s
    if params.paper_literal_margin:
        return closing * delay_s - params.pred_length_m
    return np.maximum(closing, 0.0) * delay_s + params.pred_length_m + params.standstill_gap_m


# t_ls of the SUMO Table 3 runs (docs/guide/paper-experiments.md, "Paper E: the junction planner online")
SUMO_SWITCH_INTERVAL_S = 21.6


def sumo_corrected_params(**overrides: float | bool) -> JunctionParams:
    """The planner model the engine can fly: the Table 3 SUMO runs' numbers instead of the paper's.

    ``throw_time_s`` = 21.6 s (the interlocking releases a switch when the first train's 20 m body has cleared it,
    throws for 10 s and must grant the next lock before the second train's braking point: docs/guide/paper-experiments.md), trains of
    ``pred_length_m`` = 20 m, ``S_0`` = 15 m (the gap the followers' CACC holds at 15 m/s) and the
    relative-braking-distance guard (T = 0.2 s, b = 1.5 m/s², margin 10 m). Keyword overrides win.
    """
    values: dict = {
        "throw_time_s": SUMO_SWITCH_INTERVAL_S,
        "pred_length_m": 20.0,
        "standstill_gap_m": 15.0,
        "rbd_reaction_s": 0.2,
        "rbd_decel_mps2": 1.5,
        "rbd_margin_m": 10.0,
    }
    values.update(overrides)
    return JunctionParams(**values)


@dataclass(frozen=True)
class SwitchOnPath:
    """A switch on a train's path: its id, the along-path distance from the train front [m], the leg used."""

    switch_id: str
    distance_m: float
    leg: Leg


@dataclass(frozen=True)
class TrainPath:
    """One player: its initial speed and its path to F (switches in the order they are passed)."""

    train_id: str
    initial_speed_mps: float
    switches: tuple[SwitchOnPath, ...]
    distance_to_F_m: float


@dataclass(frozen=True)
class SwitchState:
    """What the interlocking knows about a switch at plan time.

    ``position`` is the leg the switch lies in. ``locked_until_s`` (relative to plan time) is when a lock held
    for a movement outside this plan ends (0 = free). Setting it to the other leg takes ``throw_time_s``
    (from :class:`JunctionParams`) after the lock ends.
    """

    switch_id: str
    position: Leg = "normal"
    locked_until_s: float = 0.0
    locked_for: str | None = None


@dataclass
class Problem:
    """A compiled junction problem: per-train segment grids padded to a common length, plus index tables.

    Build it with :func:`compile_problem`; everything the vectorised rollout needs is precomputed here.
    """

    trains: tuple[TrainPath, ...]
    merge_switch_id: str
    params: JunctionParams
    switch_states: dict[str, SwitchState]
    breakpoints_m: np.ndarray  # (n, L+1) along own path, padded by repeating F
    seg_len_m: np.ndarray  # (n, L) zero in the padding
    n_segments: np.ndarray  # (n,) l_k
    dim_index: np.ndarray  # (D,) flat index into (n*L) of each decision variable
    dim_slices: tuple[slice, ...]  # train k's decision variables in a particle
    merge_distance_m: np.ndarray  # (n,) d_{k,σ*}
    switch_ids: tuple[str, ...]
    switch_users: dict[str, np.ndarray]  # switch id -> train indices using it
    switch_boundary: dict[str, np.ndarray]  # switch id -> boundary index (per user)
    switch_legs: dict[str, np.ndarray]  # switch id -> 1 for reverse, 0 for normal (per user)
    switch_limits_mps: dict[str, np.ndarray]  # switch id -> limit speed (per user)
    shared_pairs: tuple[tuple[int, int, np.ndarray, np.ndarray], ...]  # (i, j, boundary idx of i, of j)
    frozen_order: tuple[int, ...] | None = None  # passing order at σ* forced by a re-plan (train indices)

    @property
    def n_trains(self) -> int:
        return len(self.trains)

    @property
    def dimension(self) -> int:
        return int(self.dim_index.size)

    @property
    def bounds(self) -> tuple[float, float]:
        return self.params.accel_min_mps2, self.params.accel_max_mps2

    def split(self, x: np.ndarray) -> list[np.ndarray]:
        """Per-train acceleration vectors of one particle."""
        return [np.asarray(x[s], dtype=float) for s in self.dim_slices]


def compile_problem(
    trains: tuple[TrainPath, ...] | list[TrainPath],
    merge_switch_id: str,
    params: JunctionParams | None = None,
    switch_states: dict[str, SwitchState] | None = None,
    frozen_order: tuple[int, ...] | None = None,
) -> Problem:
    """Build the segment grids and index tables (see the module docstring for the grid reading)."""
    params = params or JunctionParams()
    trains = tuple(trains)
    dx = params.segment_m
    grids: list[np.ndarray] = []
    merge_d = np.zeros(len(trains))
    for k, tr in enumerate(trains):
        merge = [sw for sw in tr.switches if sw.switch_id == merge_switch_id]
        if not merge:
            raise ValueError(f"{tr.train_id}: path does not pass merge switch {merge_switch_id}")
        d_m = merge[0].distance_m
        merge_d[k] = d_m
        # grid points m·Δx in s̃ = s − d_m, strictly inside (0, d_F) in own coordinates
        m_lo = int(np.floor(-d_m / dx)) + 1
        m_hi = int(np.ceil((tr.distance_to_F_m - d_m) / dx)) - 1
        pts = d_m + dx * np.arange(m_lo, m_hi + 1)
        extra = np.array([0.0, tr.distance_to_F_m] + [sw.distance_m for sw in tr.switches])
        # grid points within 1 mm of the start, a switch or F would make slivers: the exact points win
        pts = pts[(pts > 0.0) & (pts < tr.distance_to_F_m)]
        pts = pts[np.min(np.abs(pts[:, None] - extra[None, :]), axis=1) > 1e-3] if pts.size else pts
        allp = np.unique(np.concatenate([pts, extra]))
        grids.append(allp)
    n_seg = np.array([g.size - 1 for g in grids])
    L = int(n_seg.max())
    bp = np.zeros((len(trains), L + 1))
    for k, g in enumerate(grids):
        bp[k, : g.size] = g
        bp[k, g.size :] = g[-1]
    seg = np.diff(bp, axis=1)
    dim_index = np.concatenate([k * L + np.arange(n_seg[k]) for k in range(len(trains))])
    offs = np.concatenate([[0], np.cumsum(n_seg)])
    slices = tuple(slice(int(offs[k]), int(offs[k + 1])) for k in range(len(trains)))

    def boundary_of(k: int, dist: float) -> int:
        return int(np.argmin(np.abs(bp[k, : n_seg[k] + 1] - dist)))

    users: dict[str, list[int]] = {}
    bidx: dict[str, list[int]] = {}
    legs: dict[str, list[int]] = {}
    lims: dict[str, list[float]] = {}
    for k, tr in enumerate(trains):
        for sw in tr.switches:
            users.setdefault(sw.switch_id, []).append(k)
            bidx.setdefault(sw.switch_id, []).append(boundary_of(k, sw.distance_m))
            legs.setdefault(sw.switch_id, []).append(1 if sw.leg == "reverse" else 0)
            lims.setdefault(sw.switch_id, []).append(params.limit_speed_mps(sw.leg))
    # shared track: two trains share every point downstream of the first switch both pass
    pairs = []
    for i in range(len(trains)):
        for j in range(i + 1, len(trains)):
            common = [
                sw.switch_id for sw in trains[i].switches if sw.switch_id in {s.switch_id for s in trains[j].switches}
            ]
            if not common:
                continue
            first = common[0]
            si = next(s.distance_m for s in trains[i].switches if s.switch_id == first) - merge_d[i]
            pi = bp[i, : n_seg[i] + 1] - merge_d[i]
            pj = bp[j, : n_seg[j] + 1] - merge_d[j]
            shared = np.intersect1d(np.round(pi[pi >= si - 1e-9], 6), np.round(pj, 6))
            ii = np.array([int(np.argmin(np.abs(pi - x))) for x in shared])
            jj = np.array([int(np.argmin(np.abs(pj - x))) for x in shared])
            pairs.append((i, j, ii, jj))
    states = dict(switch_states or {})
    return Problem(
        trains=trains,
        merge_switch_id=merge_switch_id,
        params=params,
        switch_states=states,
        breakpoints_m=bp,
        seg_len_m=seg,
        n_segments=n_seg,
        dim_index=dim_index,
        dim_slices=slices,
        merge_distance_m=merge_d,
        switch_ids=tuple(users),
        switch_users={s: np.array(v) for s, v in users.items()},
        switch_boundary={s: np.array(v) for s, v in bidx.items()},
        switch_legs={s: np.array(v) for s, v in legs.items()},
        switch_limits_mps={s: np.array(v, dtype=float) for s, v in lims.items()},
        shared_pairs=tuple(pairs),
        frozen_order=frozen_order,
    )


@dataclass
class Rollout:
    """Everything the vectorised rollout computes for a batch of particles (leading axis P)."""

    speed_signed_mps: np.ndarray  # (P, n, L+1) boundary speeds, negative where the train would have stopped
    time_s: np.ndarray  # (P, n, L+1) boundary times
    accel_mps2: np.ndarray  # (P, n, L)
    merge_time_s: np.ndarray  # (P, n) t_{k,σ*}
    order: np.ndarray  # (P, n) train indices in passing order at σ*
    coupling_time_s: np.ndarray  # (P,) T_c
    position_at_tc_m: np.ndarray  # (P, n) along own path
    speed_at_tc_mps: np.ndarray  # (P, n)
    gap_m: np.ndarray  # (P, n-1) head-to-head D between consecutive trains in order
    speed_diff_mps: np.ndarray  # (P, n-1) Δv = v_pred − v_follower
    margin_m: np.ndarray  # (P, n-1) S_m
    cost: np.ndarray  # (P,) f_c
    violation: np.ndarray  # (P,) Σ max(g, 0)
    terms: dict[str, np.ndarray] = field(default_factory=dict)  # per-constraint violation (P,)


def rollout(problem: Problem, X: np.ndarray) -> Rollout:
    """Evaluate a batch of particles ``X`` (P × D): trajectories at breakpoints, f_c and the violations."""
    p = problem.params
    X = np.atleast_2d(np.asarray(X, dtype=float))
    P = X.shape[0]
    n = problem.n_trains
    L = problem.seg_len_m.shape[1]
    A = np.zeros((P, n * L))
    A[:, problem.dim_index] = X
    A = A.reshape(P, n, L)
    v0 = np.array([tr.initial_speed_mps for tr in problem.trains])
    v2 = np.empty((P, n, L + 1))
    v2[:, :, 0] = v0**2
    np.cumsum(2.0 * A * problem.seg_len_m, axis=2, out=v2[:, :, 1:])
    v2[:, :, 1:] += (v0**2)[None, :, None]
    v_signed = np.sign(v2) * np.sqrt(np.abs(v2))
    v_pos = np.maximum(v_signed, p.min_speed_mps)
    dt = 2.0 * problem.seg_len_m / (v_pos[:, :, :-1] + v_pos[:, :, 1:])
    t = np.zeros((P, n, L + 1))
    np.cumsum(dt, axis=2, out=t[:, :, 1:])
    rows = np.arange(n)
    # passage at σ*
    ms = problem.merge_switch_id
    users = problem.switch_users[ms]
    t_merge = np.empty((P, n))
    t_merge[:, users] = t[:, users, problem.switch_boundary[ms]]
    if problem.frozen_order is not None:
        order = np.broadcast_to(np.array(problem.frozen_order), (P, n)).copy()
    else:
        order = np.argsort(t_merge, axis=1, kind="stable")
    t_F = t[:, rows, problem.n_segments]  # (P, n)
    v_F = v_pos[:, rows, problem.n_segments]
    leader = order[:, 0]
    T_c = t_F[np.arange(P), leader]
    # position and speed of every train at T_c
    seg_idx = np.sum(t[:, :, 1:] <= T_c[:, None, None], axis=2)  # completed segments
    seg_idx = np.minimum(seg_idx, problem.n_segments[None, :] - 1)
    beyond = T_c[:, None] >= t_F
    gi = seg_idx[:, :, None]
    t_j = np.take_along_axis(t, gi, axis=2)[:, :, 0]
    v_j = np.take_along_axis(v_pos, gi, axis=2)[:, :, 0]
    a_j = np.take_along_axis(A, gi, axis=2)[:, :, 0]
    s_j = problem.breakpoints_m[rows[None, :], seg_idx]
    s_j1 = problem.breakpoints_m[rows[None, :], seg_idx + 1]
    tau = np.maximum(T_c[:, None] - t_j, 0.0)
    s_in = np.clip(s_j + v_j * tau + 0.5 * a_j * tau**2, s_j, s_j1)
    v_in = np.clip(v_j + a_j * tau, p.min_speed_mps, None)
    d_F = np.array([tr.distance_to_F_m for tr in problem.trains])
    s_tc = np.where(beyond, d_F[None, :] + v_F * np.maximum(T_c[:, None] - t_F, 0.0), s_in)
    v_tc = np.where(beyond, v_F, v_in)
    s_tilde = s_tc - problem.merge_distance_m[None, :]
    s_ord = np.take_along_axis(s_tilde, order, axis=1)
    v_ord = np.take_along_axis(v_tc, order, axis=1)
    gap = s_ord[:, :-1] - s_ord[:, 1:]
    dv = v_ord[:, :-1] - v_ord[:, 1:]
    margin = safety_margin_m(v_ord[:, :-1], v_ord[:, 1:], p)
    # cost f_c(N) (§2.6 written out)
    t1 = t_merge
    t2 = T_c[:, None] - t_merge
    denom = np.maximum(v_tc - p.speed_error_mps, p.min_speed_mps)
    own = p.weight_time * (t1 + t2) + p.weight_speed * 2.0 * p.braking_distance_m / denom
    v_fol = np.maximum(v_ord[:, 1:], p.min_speed_mps)
    pair = p.weight_gap * np.abs(gap - margin) / v_fol + p.weight_speed_diff * (np.abs(dv) + p.speed_error_mps)
    cost = own.sum(axis=1) + pair.sum(axis=1)
    # constraints
    terms: dict[str, np.ndarray] = {}
    sw_speed = np.zeros(P)
    headway = np.zeros(P)
    state = np.zeros(P)
    for sid in problem.switch_ids:
        u = problem.switch_users[sid]
        b = problem.switch_boundary[sid]
        vs = v_signed[:, u, b]
        sw_speed += np.maximum(vs - (problem.switch_limits_mps[sid] - p.switch_speed_margin_mps), 0.0).sum(axis=1)
        ts = t[:, u, b]
        srt = np.argsort(ts, axis=1, kind="stable")
        ts_s = np.take_along_axis(ts, srt, axis=1)
        legs = problem.switch_legs[sid][srt]
        if u.size > 1:
            need = np.full(legs[:, 1:].shape, p.throw_time_s)
            if not p.headway_all_consecutive:
                need = np.where(legs[:, 1:] != legs[:, :-1], p.throw_time_s, 0.0)
            headway += np.maximum(need - np.diff(ts_s, axis=1), 0.0).sum(axis=1)
        st = problem.switch_states.get(sid)
        if st is not None:
            first_leg = legs[:, 0]
            cur = 1 if st.position == "reverse" else 0
            ready = st.locked_until_s + np.where(first_leg != cur, p.throw_time_s, 0.0)
            state += np.maximum(ready - ts_s[:, 0], 0.0)
    terms["switch_speed"] = sw_speed
    terms["switch_headway"] = headway
    terms["switch_state"] = state
    idx_valid = np.arange(L + 1)[None, :] <= problem.n_segments[:, None]  # (n, L+1)
    vmin = np.where(idx_valid[None], v_signed, np.inf).min(axis=2)
    vmax = np.where(idx_valid[None], v_signed, -np.inf).max(axis=2)
    terms["speed_low"] = np.maximum(p.min_speed_mps - vmin, 0.0).sum(axis=1)
    terms["speed_high"] = np.maximum(vmax - p.line_speed_mps, 0.0).sum(axis=1)
    overtake = np.zeros(P)
    for i, j, ii, jj in problem.shared_pairs:
        d = t[:, i, ii] - t[:, j, jj]  # < 0 everywhere: i ahead on the whole shared track
        overtake += np.maximum(np.minimum(d.max(axis=1), (-d).max(axis=1)) + p.min_time_gap_s, 0.0)
    if problem.frozen_order is not None:
        # a frozen order must also be the actual order at σ*
        tm_ord = np.take_along_axis(t_merge, order, axis=1)
        overtake += np.maximum(tm_ord[:, :-1] - tm_ord[:, 1:], 0.0).sum(axis=1)
    terms["overtaking"] = overtake
    if p.rbd_reaction_s > 0.0:
        terms["relative_braking"] = _rbd_violation(problem, t, v_pos, A)
    share = p.planning_tolerance_share
    terms["coupling_gap"] = np.maximum(np.abs(gap - margin) - share * p.gap_tolerance_m, 0.0).sum(axis=1)
    terms["coupling_speed"] = np.maximum(np.abs(dv) - share * p.speed_tolerance_mps, 0.0).sum(axis=1)
    violation = sum(terms.values())
    return Rollout(v_signed, t, A, t_merge, order, T_c, s_tc, v_tc, gap, dv, margin, cost, violation, terms)


def _position_at(
    problem: Problem, k: int, t: np.ndarray, v_pos: np.ndarray, A: np.ndarray, tq: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Train ``k``'s position along its path and speed at query times ``tq`` (P, Q): exact within a segment
    (constant acceleration), constant speed beyond F. Vectorised over particles with one ``searchsorted``."""
    P = t.shape[0]
    nk = int(problem.n_segments[k])
    tk = t[:, k, : nk + 1]  # (P, nk+1) increasing in each row
    span = float(max(tk[:, -1].max(), tq.max())) + 1.0
    rows = np.arange(P)[:, None]
    idx = np.searchsorted((tk + rows * span).ravel(), (tq + rows * span).ravel(), side="right")
    idx = idx.reshape(tq.shape) - rows * (nk + 1)  # first boundary strictly after tq
    seg = np.clip(idx - 1, 0, nk - 1)
    t0 = np.take_along_axis(tk, seg, axis=1)
    v0 = np.take_along_axis(v_pos[:, k, : nk + 1], seg, axis=1)
    a = np.take_along_axis(A[:, k, :nk], seg, axis=1)
    bp = problem.breakpoints_m[k]
    tau = np.maximum(tq - t0, 0.0)
    s_in = np.clip(bp[seg] + v0 * tau + 0.5 * a * tau**2, bp[seg], bp[seg + 1])
    v_in = np.maximum(v0 + a * tau, problem.params.min_speed_mps)
    done = tq >= tk[:, -1:]
    v_F = v_pos[:, k, nk][:, None]
    s = np.where(done, bp[nk] + v_F * (tq - tk[:, -1:]), s_in)
    v = np.where(done, v_F, v_in)
    return s, v


def _follower_samples(
    problem: Problem, k: int, t: np.ndarray, v_pos: np.ndarray, A: np.ndarray, boundaries: np.ndarray
) -> tuple[np.ndarray, ...]:
    """Instants at which train ``k`` is checked along the segments starting at ``boundaries`` (plus the last one):
    each segment's start and ``rbd_samples_per_segment − 1`` equally spaced interior instants. Returns
    ``(time, position along own path, speed, acceleration)``, each (P, Q); exact kinematics within a segment."""
    K = int(problem.params.rbd_samples_per_segment)
    seg = boundaries[:-1]
    frac = np.arange(K) / K
    t0 = t[:, k, seg][:, :, None]
    dur = (t[:, k, seg + 1] - t[:, k, seg])[:, :, None]
    tau = (dur * frac).reshape(t.shape[0], -1)
    segs = np.repeat(seg, K)
    v0 = v_pos[:, k, segs]
    a = A[:, k, segs]
    tq = t0.repeat(K, axis=2).reshape(t.shape[0], -1) + tau
    s = problem.breakpoints_m[k, segs][None, :] + v0 * tau + 0.5 * a * tau**2
    v = np.maximum(v0 + a * tau, problem.params.min_speed_mps)
    last = boundaries[-1]
    tq = np.concatenate([tq, t[:, k, last][:, None]], axis=1)
    s = np.concatenate([s, np.broadcast_to(problem.breakpoints_m[k, last], (t.shape[0], 1))], axis=1)
    v = np.concatenate([v, v_pos[:, k, last][:, None]], axis=1)
    a = np.concatenate([a, np.zeros((t.shape[0], 1))], axis=1)  # at F the follower holds its speed
    return tq, s, v, a


def _rbd_violation(problem: Problem, t: np.ndarray, v_pos: np.ndarray, A: np.ndarray) -> np.ndarray:
    """Σ over shared pairs of the worst shortfall of the relative-braking-distance spacing (m), per particle.

    The follower is the train that reaches the first shared point later; at every sampled instant of its run on
    the shared track (:func:`_follower_samples`) the leader's rear must be at least the guard's
    :func:`controllers.braking.relative_braking_distance_m` ahead.
    """
    p = problem.params
    out = np.zeros(t.shape[0])
    for i, j, ii, jj in problem.shared_pairs:
        worst = []
        for lead, fol, jf in ((i, j, jj), (j, i, ii)):
            tq, s_f, v_f, a_f = _follower_samples(problem, fol, t, v_pos, A, jf)
            s_lead, v_lead = _position_at(problem, lead, t, v_pos, A, tq)
            gap = (s_lead - problem.merge_distance_m[lead]) - (s_f - problem.merge_distance_m[fol]) - p.pred_length_m
            need = relative_braking_distance_m(
                v_f, v_lead, p.rbd_decel_mps2, p.rbd_decel_mps2, p.rbd_reaction_s, a_f, p.rbd_margin_m
            )
            worst.append(np.maximum(need - gap, 0.0).max(axis=1))
        first_i = t[:, i, ii[0]] <= t[:, j, jj[0]]  # who is ahead at the first shared point
        out += np.where(first_i, worst[0], worst[1])
    return out


def evaluate(problem: Problem, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(f_c, violation)`` per particle — the PSO's objective and constraint aggregate."""
    r = rollout(problem, X)
    return r.cost, r.violation


def profile_from_speed_waypoints(
    problem: Problem, k: int, waypoints_m: np.ndarray, speeds_mps: np.ndarray
) -> np.ndarray:
    """Accelerations for train ``k`` that follow ``v(s)`` linear in ``v²`` between waypoints, clipped to bounds.

    Used to seed the swarm with smooth, roughly sensible profiles (spec §6 #23) and by the baselines. The
    clipping means the realised speeds can deviate from the waypoints when they ask for more than a_max/a_min.
    """
    p = problem.params
    nk = int(problem.n_segments[k])
    bp = problem.breakpoints_m[k, : nk + 1]
    v2_target = np.interp(bp, waypoints_m, np.asarray(speeds_mps, dtype=float) ** 2)
    acc = np.empty(nk)
    v2 = problem.trains[k].initial_speed_mps ** 2
    for j in range(nk):
        ell = bp[j + 1] - bp[j]
        a = (v2_target[j + 1] - v2) / (2.0 * ell)
        a = float(np.clip(a, p.accel_min_mps2, p.accel_max_mps2))
        acc[j] = a
        v2 = v2 + 2.0 * a * ell
    return acc
