"""A train under the junction plan (Paper E online, :mod:`.coordinator`): its path and its tracking reference.

The coordinator turns each plan's acceleration-over-distance profile into a reference ``(s, v)(τ)`` by
integrating it from the plan instant with a fine step (:meth:`PlannedTrain.set_reference`); the train tracks it
with feed-forward plus feedback (:meth:`railsim.engine.extensions.junction_coordinator.coordinator.JunctionCoordinator.command`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from controllers.junction import baselines

REFERENCE_DT_S = 0.02  # integration step of the reference trajectory
REFERENCE_HORIZON_S = 600.0  # the reference ends here at the latest


@dataclass
class PlannedTrain:
    """One planned train: its path through the junction in route chainage and its tracking reference."""

    train_id: str
    switch_m: dict[str, float]  # planner switch point (turnout start) per switch on the path [route m]
    legs: dict[str, str]  # leg per switch
    point_m: dict[str, float]  # switch point (the node) per switch [route m]
    F_m: float  # route chainage of F
    s0_m: float | None = None  # route chainage of the front at the first plan (measurement origin)
    ref_t0_s: float = 0.0  # plan instant of the current reference
    ref_front_m: float = 0.0  # front at that instant
    ref_t: np.ndarray = field(default_factory=lambda: np.zeros(1))
    ref_s: np.ndarray = field(default_factory=lambda: np.zeros(1))
    ref_v: np.ndarray = field(default_factory=lambda: np.zeros(1))
    segments: tuple[tuple[float, float, float], ...] = ()
    handed_over: bool = False

    def track(self, front_m: float) -> tuple[str, float]:
        """Planner track name and distance from the front to the next planner switch (may be < 0 past it)."""
        if "sw1" in self.switch_m and front_m < self.point_m["sw1"]:
            return ("entry3" if self.legs["sw1"] == "reverse" else "entry2"), self.switch_m["sw1"] - front_m
        if "sw1" in self.switch_m:
            return "trunk", self.switch_m["sw2"] - front_m
        return "entry1", self.switch_m["sw2"] - front_m

    def set_reference(self, min_speed_mps: float, t: float, front_m: float, v0: float, segments: Any) -> None:
        """Integrate a plan's acceleration-over-distance profile from (front, v0) at ``t`` (fine Δt = 0.02 s)."""
        self.segments = tuple(segments)
        self.ref_t0_s, self.ref_front_m = t, front_m
        dt = REFERENCE_DT_S
        end = self.F_m - front_m + 100.0
        ts, ss, vs = [0.0], [0.0], [v0]
        s, v, tau = 0.0, v0, 0.0
        while s < end and tau < REFERENCE_HORIZON_S:
            a = self.accel_at(s)
            v_new = max(v + a * dt, min_speed_mps)
            s += 0.5 * (v + v_new) * dt
            v = v_new
            tau += dt
            ts.append(tau)
            ss.append(s)
            vs.append(v)
        self.ref_t, self.ref_s, self.ref_v = np.array(ts), np.array(ss), np.array(vs)

    def set_reference_exact(self, min_speed_mps: float, t: float, front_m: float, v0: float, segments: Any) -> None:
        """The plan's own trajectory, sampled exactly (``qp_order``): constant acceleration per distance segment,
        so ``v²`` is linear in distance and the segment times are ``2ℓ/(v_j + v_{j+1})`` — the planner's rollout.

        :meth:`set_reference` integrates the acceleration in time instead; its step ends at a segment boundary
        late by up to a step, an error of up to 0.05 m/s per boundary that adds up to ~1 s over a 90 s plan
        (measured: the leader at F 0.9 s before the plan said, the followers 8 m short of their slots).
        """
        self.segments = tuple(segments)
        self.ref_t0_s, self.ref_front_m = t, front_m
        start = np.array([a for a, _, _ in self.segments], dtype=float)
        ell = np.array([b - a for a, b, _ in self.segments], dtype=float)
        acc = np.array([c for _, _, c in self.segments], dtype=float)
        E = np.concatenate([[v0 * v0], v0 * v0 + np.cumsum(2.0 * acc * ell)])
        E = np.maximum(E, min_speed_mps**2)
        v = np.sqrt(E)
        a_eff = np.diff(E) / (2.0 * ell)
        t_bp = np.concatenate([[0.0], np.cumsum(2.0 * ell / (v[:-1] + v[1:]))])
        s_bp = np.concatenate([start, [start[-1] + ell[-1]]]) if start.size else np.array([0.0])
        end_s = self.F_m - front_m + 100.0
        tail_s = t_bp[-1] + max(end_s - s_bp[-1], 0.0) / v[-1]
        tau = np.arange(0.0, min(tail_s, REFERENCE_HORIZON_S) + REFERENCE_DT_S, REFERENCE_DT_S)
        j = np.clip(np.searchsorted(t_bp, tau, side="right") - 1, 0, max(t_bp.size - 2, 0))
        dt = tau - t_bp[j]
        inside = tau < t_bp[-1]
        a_j = np.where(inside, a_eff[j] if a_eff.size else 0.0, 0.0)
        base_s = np.where(inside, s_bp[j], s_bp[-1])
        base_v = np.where(inside, v[j], v[-1])
        dt = np.where(inside, dt, tau - t_bp[-1])
        self.ref_t = tau
        self.ref_s = base_s + base_v * dt + 0.5 * a_j * dt * dt
        self.ref_v = np.maximum(base_v + a_j * dt, min_speed_mps)

    def naive_command(self, p: Any, pos_m: float, v: float, dt_s: float) -> float:
        """The naive baselines' command (spec 004 §4.2): towards the limit speed of the next switch ahead on a
        braking curve (past the last one: its limit); ``p`` are the planner's parameters."""
        ahead = [(self.switch_m[sid], sid) for sid in self.switch_m if self.point_m[sid] > pos_m]
        if ahead:
            d, sid = min(ahead)
            v_lim = p.limit_speed_mps(self.legs[sid]) - p.switch_speed_margin_mps
            cap = baselines.approach_speed_cap(v, d - pos_m, v_lim, dt_s, abs(p.accel_min_mps2))
        else:
            cap = p.limit_speed_mps(self.legs[max(self.point_m, key=lambda k: self.point_m[k])])
        return baselines.accel_towards(cap, v, dt_s, p)

    def accel_at(self, s: float) -> float:
        """The plan's acceleration at distance ``s`` from the plan instant's front."""
        for a, b, acc in self.segments:
            if a <= s < b:
                return acc
        return 0.0

    def time_at(self, s: float) -> float:
        """Plan time (since the plan instant) at which the reference reaches distance ``s`` (extrapolated past it)."""
        if s >= self.ref_s[-1]:
            return float(self.ref_t[-1] + (s - self.ref_s[-1]) / max(self.ref_v[-1], 1e-3))
        return float(np.interp(s, self.ref_s, self.ref_t))

    def reference(self, t: float) -> tuple[float, float]:
        """Reference distance (from the plan instant's front) and speed at ``t`` (constant speed past the end)."""
        tau = t - self.ref_t0_s
        if tau >= self.ref_t[-1]:
            return float(self.ref_s[-1] + self.ref_v[-1] * (tau - self.ref_t[-1])), float(self.ref_v[-1])
        return float(np.interp(tau, self.ref_t, self.ref_s)), float(np.interp(tau, self.ref_t, self.ref_v))


def leader_time_reference(m: PlannedTrain, lead: PlannedTrain, lead_front_m: float, lead_speed_mps: float) -> tuple:
    """A follower's reference ``(s, v, rate)`` read in the platoon leader's time (``qp_order``).

    The plan instant is the one at which the leader's reference is where the leader is known to be; the speed is
    scaled by the rate at which the leader runs through its plan (clipped to [0.5, 1.5]). A leader held back (by
    its ATO's braking curve, a late lock) holds the whole plan back with it, one ahead of it moves it forward, so
    the platoon's geometry — switch intervals, slots at F — is kept while the leader's own feedback pulls it back
    onto the clock.
    """
    t_eff = lead.ref_t0_s + lead.time_at(lead_front_m - lead.ref_front_m)
    _, v_lead_ref = lead.reference(t_eff)
    rate = float(np.clip(lead_speed_mps / max(v_lead_ref, 0.5), 0.5, 1.5))
    s_ref, v_ref = m.reference(t_eff)
    return s_ref, v_ref * rate, rate
