"""Safety distance (Paper D Eqs 23–26) and the ADBM / RDBM braking-distance policies (Fig 2).

Paper D triggers collision avoidance when the net gap to the object ahead falls to the **safety distance**::

    S_safe = S_b,max + S_buf                                   (Eq. 23, reconstructed, high confidence)
    S_b,max = v·t_eq + v²/(2·ā_eb)                            (Eq. 26, reconstructed, medium)
    ā_eb   = v0² / (2·(S_b − v0·t_eq))                         (Eq. 25, the average deceleration of a braking run)

The paper's numbers — S_b,max = 23 m, S_buf = 5 m, S_safe = 28 m, t_eq = 1 s — are reproduced by
v = 25 km/h and ā_eb = 1.5 m/s² (6.94 + 48.23/3 = 23.02 m); the "80 km/h" of the text cannot give 23 m (spec
§3.10), so that is the reading implemented here. A **fixed** threshold (28 m) is the paper's trigger.

Two speed-dependent policies are offered as alternatives (standard forms; the paper describes them in words):

* **ADBM** (absolute braking distance, "brick wall"): the follower must stop behind the object's present tail::

      D_ADBM = v_f·t_eq + v_f²/(2·b_f) + S_m

* **RDBM** (relative braking distance): the object ahead is credited with its own braking distance::

      D_RDBM = v_f·t_eq + v_f²/(2·b_f) − v_l²/(2·b_l) + S_m     (never below S_m)

RDBM is only as good as its assumption about ``b_l`` and ``b_f``: if the object ahead stops harder than ``b_l``
(an obstacle hit, a heavier follower than assumed) its credit is wrong while ADBM keeps the whole braking distance
of the object ahead as slack. Both the CA trigger (:mod:`.collision_avoidance`) and the coupling laws' safety
cap (:func:`max_safe_speed_mps`) read the same :class:`BrakingPolicy`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from controllers.braking import require

KMH = 1.0 / 3.6


def max_braking_distance_m(speed_mps: float, t_eq_s: float, decel_mps2: float) -> float:
    """Eq. (26): distance run during the equivalent response time plus the constant-deceleration stop [m]."""
    require("decel_mps2", decel_mps2 > 0.0, "a number > 0", decel_mps2)
    v = max(speed_mps, 0.0)
    return v * max(t_eq_s, 0.0) + v * v / (2.0 * decel_mps2)


def average_emergency_decel_mps2(speed_mps: float, braking_distance_m: float, t_eq_s: float) -> float:
    """Eq. (25) reading: the constant deceleration that, after ``t_eq_s`` at speed, stops within the distance."""
    room = braking_distance_m - speed_mps * t_eq_s
    require("braking_distance_m", room > 0.0, f"a distance > v·t_eq = {speed_mps * t_eq_s:.3f} m", braking_distance_m)
    return speed_mps * speed_mps / (2.0 * room)


def safety_distance_m(
    speed_mps: float = 25.0 * KMH, t_eq_s: float = 1.0, decel_mps2: float = 1.5, buffer_m: float = 5.0
) -> float:
    """Eq. (23): ``S_safe = S_b,max + S_buf``; the defaults give the paper's 28 m (28.02 m)."""
    return max_braking_distance_m(speed_mps, t_eq_s, decel_mps2) + buffer_m


@dataclass(frozen=True)
class BrakingPolicy:
    """Which distance the CA trigger / safety cap protects.

    ``mode``: ``fixed`` (the paper: ``fixed_threshold_m``), ``adbm`` or ``rdbm``. ``follower_decel_mps2`` and
    ``leader_decel_mps2`` are the *assumed* guaranteed emergency decelerations; ``None`` means "use the vehicle's
    own (load-aware) value" for the follower and "same as the follower" for the object ahead.
    """

    mode: str = "fixed"
    fixed_threshold_m: float = 28.0
    t_eq_s: float = 1.0
    margin_m: float = 5.0
    follower_decel_mps2: float | None = None
    leader_decel_mps2: float | None = None

    def __post_init__(self) -> None:
        require("mode", self.mode in ("fixed", "adbm", "rdbm"), "'fixed', 'adbm' or 'rdbm'", self.mode)
        require("fixed_threshold_m", self.fixed_threshold_m > 0.0, "a number > 0", self.fixed_threshold_m)
        require("t_eq_s", self.t_eq_s >= 0.0, "a number >= 0", self.t_eq_s)
        require("margin_m", self.margin_m >= 0.0, "a number >= 0", self.margin_m)
        for name in ("follower_decel_mps2", "leader_decel_mps2"):
            value = getattr(self, name)
            require(name, value is None or value > 0.0, "a number > 0 or null", value)


def adbm_distance_m(v_follower_mps: float, b_follower_mps2: float, t_eq_s: float, margin_m: float) -> float:
    """ADBM: follower's braking distance (incl. response time) plus margin [m]."""
    return max_braking_distance_m(v_follower_mps, t_eq_s, b_follower_mps2) + margin_m


def rdbm_distance_m(
    v_follower_mps: float,
    b_follower_mps2: float,
    v_leader_mps: float,
    b_leader_mps2: float,
    t_eq_s: float,
    margin_m: float,
) -> float:
    """RDBM: follower's braking distance minus the leader's, plus margin, never below the margin [m]."""
    v_l = max(v_leader_mps, 0.0)
    rel = max_braking_distance_m(v_follower_mps, t_eq_s, b_follower_mps2) - v_l * v_l / (2.0 * b_leader_mps2)
    return max(rel, 0.0) + margin_m


def required_gap_m(policy: BrakingPolicy, v_follower_mps: float, v_leader_mps: float, own_decel_mps2: float) -> float:
    """The gap the policy requires now [m]; ``own_decel_mps2`` is the follower's actual emergency deceleration,
    used when the policy does not fix an assumed value."""
    if policy.mode == "fixed":
        return policy.fixed_threshold_m
    b_f = policy.follower_decel_mps2 or own_decel_mps2
    if policy.mode == "adbm":
        return adbm_distance_m(v_follower_mps, b_f, policy.t_eq_s, policy.margin_m)
    b_l = policy.leader_decel_mps2 or b_f
    return rdbm_distance_m(v_follower_mps, b_f, v_leader_mps, b_l, policy.t_eq_s, policy.margin_m)


def max_safe_speed_mps(policy: BrakingPolicy, gap_m: float, v_leader_mps: float, own_decel_mps2: float) -> float:
    """Highest follower speed for which ``required_gap_m(...) ≤ gap_m`` (the separation law's braking curve).

    Solves ``v·t + v²/(2b) = room`` for ``v``. For ``fixed`` the threshold does not depend on speed, so the
    answer is ``inf`` above the threshold and 0 at or below it.
    """
    if policy.mode == "fixed":
        return math.inf if gap_m > policy.fixed_threshold_m else 0.0
    b_f = policy.follower_decel_mps2 or own_decel_mps2
    room = gap_m - policy.margin_m
    if policy.mode == "rdbm":
        b_l = policy.leader_decel_mps2 or b_f
        v_l = max(v_leader_mps, 0.0)
        room += v_l * v_l / (2.0 * b_l)
    if room <= 0.0:
        return 0.0
    t = policy.t_eq_s
    return -b_f * t + math.sqrt(b_f * b_f * t * t + 2.0 * b_f * room)
