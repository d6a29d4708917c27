"""Braking curves shared by the line controllers (ATO, moving-block separation, CACC).

Two models of "how far does the train run before it stands (or is down to a target speed)" live here, both for
the plant of :mod:`railsim.physics.dynamics` (a command ``u`` is jerk-limited, then goes through a first-order lag of
time constant τ before it becomes the applied acceleration; resistance and gradient act on top):

1. **Continuous dead-time model** (conservative, cheap, used for supervision: separation, CACC, speed
   restrictions). The train keeps its present acceleration ``a0`` for an equivalent dead time ``T``, then
   decelerates at a constant ``b`` (a positive number)::

       S(v) = v·T + a0·T²/2 + ((v + a0·T)² − v_end²) / (2·b)

   ``T`` collects everything that delays the full braking force (see :func:`build_up_delay_s`):

   * a first-order lag of time constant τ behaves, for the speed it loses, exactly like a dead time τ and for the
     distance it runs like a dead time τ minus ``(a0 + b)·τ²/2`` — so the dead time τ over-estimates the
     distance (safe side);
   * a jerk-limited ramp of the command from ``a0`` to ``−b`` at ``J`` [m/s³] lasts ``(a0 + b)/J`` and is
     matched in speed by a dead time of half that ramp; the dead time over-estimates the distance by
     ``(a0 + b)·t_ramp²/24`` (safe side);
   * reaction / communication allowances add linearly.

   :func:`allowed_speed_mps` inverts ``S`` for ``v`` (the braking curve) and :func:`required_decel_mps2` solves
   it for ``b``.

2. **Exact discrete model** (used by ATO to place the train front on the stopping mark). For one constant
   command held from now on, the plant's recursion (lag ``a_k = a_{k−1} + (u − a_{k−1})·(1 − r)``,
   ``r = e^{−dt/τ}``; speed ``v_{k+1} = max(0, v_k + (a_k − ρ)·dt)``; Euler position ``x_{k+1} = x_k + v_{k+1}·dt``)
   has a closed form. With ``n0`` the net acceleration of the last step and ``b`` the commanded constant net
   deceleration, ``c = n0 + b`` and ``s = r/(1 − r)``::

       V_j = v − j·b·dt + c·dt·s·(1 − r^j)                    (speed after j steps, j ≥ 1)
       Σ_{j=1..m} V_j = m·(v + c·dt·s) − b·dt·m(m+1)/2 − c·dt·s²·(1 − r^m)

   The train halts in the first step ``n`` whose ``V_n ≤ 0`` (the plant clamps speed at zero), so it runs
   ``D(b) = dt·Σ_{j=1..n−1} V_j``. ``D`` is continuous and decreasing in ``b``; :func:`discrete_required_decel_mps2`
   inverts it by a bracketed secant (Illinois) search. The only model errors left are the resistance change while
   braking (ρ is taken at the present speed; re-solving every step corrects it) and the jerk limit (ignored here;
   ATO starts braking early by the ramp's dead time and plans below service braking).

All decelerations here are **net** (what the train really does), positive numbers; callers convert to the
applied command with :meth:`railsim.physics.vehicle.VehicleParams.net_to_applied`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import fields
from typing import Any

import numpy as np

from railsim.errors import require  # noqa: F401 - re-exported: controllers check parameters with it
from railsim.physics.dynamics import traction_limit_mps2  # noqa: F401 - re-exported: one definition of the envelope
from railsim.physics.vehicle import G_MPS2, VehicleParams

# Smallest deceleration the solvers consider [m/s²]: below it a stop is "never" (distance diverges).
_MIN_DECEL_MPS2 = 1e-4
_SOLVE_TOLERANCE_M = 1e-3  # discrete_required_decel_mps2 stops when the distance is this close [m]


def build_up_delay_s(
    accel_now_mps2: float,
    decel_mps2: float,
    lag_s: float,
    jerk_limit_mps3: float = math.inf,
    reaction_s: float = 0.0,
) -> float:
    """Equivalent dead time before the full deceleration ``decel_mps2`` acts [s].

    ``reaction_s`` (detection, communication, decision) + the actuator lag ``lag_s`` + half the jerk-limited ramp
    from the present acceleration to ``−decel_mps2``. Pass ``jerk_limit_mps3=math.inf`` for emergency braking,
    which bypasses the jerk limit.
    """
    ramp_s = 0.0
    if math.isfinite(jerk_limit_mps3) and jerk_limit_mps3 > 0.0:
        ramp_s = max(accel_now_mps2 + decel_mps2, 0.0) / jerk_limit_mps3
    return max(reaction_s, 0.0) + max(lag_s, 0.0) + 0.5 * ramp_s


def stopping_distance_m(
    speed_mps: float,
    decel_mps2: float,
    delay_s: float = 0.0,
    accel_now_mps2: float = 0.0,
    target_speed_mps: float = 0.0,
) -> float:
    """Distance [m] to get down to ``target_speed_mps`` (dead-time model, see module docstring).

    During the dead time the speed follows ``accel_now_mps2`` but never goes below zero.
    """
    v = max(speed_mps, 0.0)
    t = max(delay_s, 0.0)
    a0 = accel_now_mps2
    if a0 < 0.0 and v + a0 * t < 0.0:  # already braking hard enough to stand within the dead time
        t = v / -a0
    v_after = max(v + a0 * t, 0.0)
    dist = v * t + 0.5 * a0 * t * t
    v_end = max(target_speed_mps, 0.0)
    if v_after > v_end:
        dist += (v_after * v_after - v_end * v_end) / (2.0 * decel_mps2)
    return dist


def allowed_speed_mps(
    distance_m: float,
    decel_mps2: float,
    delay_s: float = 0.0,
    accel_now_mps2: float = 0.0,
    target_speed_mps: float = 0.0,
) -> float:
    """Highest speed [m/s] from which the train gets down to ``target_speed_mps`` within ``distance_m``.

    Inverse of :func:`stopping_distance_m` for the branch where the dead time ends above the target speed:
    with ``w = v + a0·T``: ``w² + 2·b·T·w − (2·b·d + v_end² + a0·b·T²) = 0``. At or past the point
    (``distance_m ≤ 0``) it is the target speed itself.
    """
    b = decel_mps2
    t = max(delay_s, 0.0)
    a0 = accel_now_mps2
    v_end = max(target_speed_mps, 0.0)
    d = distance_m
    if d <= 0.0:
        return v_end  # at or past the point: the target speed itself
    disc = b * b * t * t + 2.0 * b * d + v_end * v_end + a0 * b * t * t
    if disc <= 0.0:
        return 0.0
    w = -b * t + math.sqrt(disc)
    return max(w - a0 * t, 0.0)


def required_decel_mps2(
    speed_mps: float,
    distance_m: float,
    delay_s: float = 0.0,
    accel_now_mps2: float = 0.0,
    target_speed_mps: float = 0.0,
) -> float:
    """Constant deceleration [m/s²] that brings ``speed_mps`` down to ``target_speed_mps`` within ``distance_m``.

    Dead-time model with a fixed delay (see :func:`stopping_distance_m`). ``0`` when no braking is needed,
    ``math.inf`` when the dead time alone already uses up the distance.
    """
    v = max(speed_mps, 0.0)
    t = max(delay_s, 0.0)
    a0 = accel_now_mps2
    if a0 < 0.0 and v + a0 * t < 0.0:
        t = v / -a0
    v_after = max(v + a0 * t, 0.0)
    v_end = max(target_speed_mps, 0.0)
    if v_after <= v_end:
        return 0.0
    room = distance_m - (v * t + 0.5 * a0 * t * t)
    if room <= 0.0:
        return math.inf
    return (v_after * v_after - v_end * v_end) / (2.0 * room)


def net_braking_mps2(
    vehicle: VehicleParams,
    applied_decel_mps2: float,
    gradient_permille: float,
    davis_speed_mps: float | None = None,
) -> float:
    """Net deceleration [m/s²] the train achieves with an applied brake ``applied_decel_mps2`` (positive).

    The gradient always counts (downhill reduces it). Davis running resistance counts only when
    ``davis_speed_mps`` is given, evaluated at that speed: leaving it out (or taking it at a crawl, where only
    the constant term remains) under-estimates a train's own braking over a whole stop (safe for the train that
    must stop); taking it at the present speed over-estimates it (safe when that train is the obstacle ahead).
    """
    if davis_speed_mps is None:
        extra_n = vehicle.mass_kg * G_MPS2 * gradient_permille / 1000.0
    else:
        extra_n = vehicle.resistance_n(max(davis_speed_mps, 1e-9), gradient_permille)
    return applied_decel_mps2 + extra_n / vehicle.effective_mass_kg


# --------------------------------------------------------------------------------------------- exact discrete


_LAG_RATIOS: dict[tuple[float, float], float] = {}


def _lag_ratio(dt_s: float, lag_s: float) -> float:
    """``r = e^{−dt/τ}`` (0 without lag), remembered per ``(dt, τ)``: a run asks for one or two pairs."""
    r = _LAG_RATIOS.get((dt_s, lag_s))
    if r is None:
        r = _LAG_RATIOS[(dt_s, lag_s)] = math.exp(-dt_s / lag_s) if lag_s > 0.0 else 0.0
    return r


def _trivial_stop_m(speed_mps: float, net_accel_now_mps2: float, decel_mps2: float) -> float | None:
    """0 for a train standing without drive, infinity for a vanishing deceleration, else None (sum needed)."""
    if speed_mps <= 0.0 and net_accel_now_mps2 <= 0.0:
        return 0.0
    if decel_mps2 <= _MIN_DECEL_MPS2:
        return math.inf
    return None


def discrete_stop_distance_m(
    speed_mps: float,
    net_accel_now_mps2: float,
    decel_mps2: float,
    dt_s: float,
    lag_s: float,
) -> float:
    """Distance [m] the plant runs until it stands when the net command ``−decel_mps2`` is held from now on.

    Exact for the plant's discrete recursion (lag, Euler positions, speed clamp at 0) with constant resistance;
    see the module docstring. ``net_accel_now_mps2`` is last step's net acceleration (applied − resistance).
    """
    v = speed_mps
    b = decel_mps2
    trivial = _trivial_stop_m(v, net_accel_now_mps2, b)
    if trivial is not None:
        return trivial
    r = _lag_ratio(dt_s, lag_s)
    s = r / (1.0 - r)
    c = net_accel_now_mps2 + b
    cds = c * dt_s * s
    bdt = b * dt_s
    # First step with V_j <= 0 (V_j = v − j·b·dt + c·dt·s·(1 − r^j)): start from the crossing of the asymptote
    # (r^j -> 0), then walk to the exact one.
    n = max(1, math.ceil((v + cds) / bdt))
    while n > 1 and v - (n - 1) * bdt + cds * (1.0 - r ** (n - 1)) <= 0.0:
        n -= 1
    while v - n * bdt + cds * (1.0 - r**n) > 0.0:
        n += 1
    m = n - 1
    if m <= 0:
        return 0.0
    total = m * (v + cds) - bdt * m * (m + 1) / 2.0 - cds * s * (1.0 - r**m)
    return max(total * dt_s, 0.0)


def discrete_stop_distance_bound_m(
    speed_mps: float,
    net_accel_now_mps2: float,
    decel_mps2: float,
    dt_s: float,
    lag_s: float,
) -> float:
    """An upper bound on :func:`discrete_stop_distance_m` in a few operations (a screen before the exact sum).

    With ``W = v + max(c·dt·s, 0)`` every speed of the recursion is ``V_j ≤ W − j·b·dt`` (the lag term
    ``c·dt·s·(1 − r^j)`` lies between 0 and ``c·dt·s``), so the distance ``dt·Σ V_j`` over the steps with
    ``V_j > 0`` is at most ``dt·Σ_j max(W − j·b·dt, 0) ≤ W²/(2·b)``. A relative and an absolute slack of 1e-9
    cover the rounding of the exact sum, so ``x > bound`` proves ``x > discrete_stop_distance_m(...)`` and the
    callers skip the exact evaluation (ATO cruising far from its stop points: every step).
    """
    trivial = _trivial_stop_m(speed_mps, net_accel_now_mps2, decel_mps2)
    if trivial is not None:
        return trivial
    r = _lag_ratio(dt_s, lag_s)
    cds = (net_accel_now_mps2 + decel_mps2) * dt_s * (r / (1.0 - r))
    w = max(speed_mps, 0.0) + max(cds, 0.0)
    return w * w / (2.0 * decel_mps2) * (1.0 + 1e-9) + 1e-9


def required_decel_surely_below(
    speed_mps: float, net_accel_now_mps2: float, distance_m: float, dt_s: float, lag_s: float, decel_mps2: float
) -> bool:
    """True when :func:`discrete_required_decel_mps2` for ``distance_m`` is certainly below ``decel_mps2``.

    The distance run braking at ``decel_mps2`` is at most :func:`discrete_stop_distance_bound_m`; with
    ``distance_m`` beyond that bound by more than ten times the solver's tolerance, the root lies below
    ``decel_mps2`` (the distance falls with the deceleration) and every answer the solver gives (within its
    tolerance of the root, or a bracket end on the root's side) does too. The ATO uses it to skip the solve
    while it only checks whether braking is still needed.
    """
    bound = discrete_stop_distance_bound_m(speed_mps, net_accel_now_mps2, decel_mps2, dt_s, lag_s)
    return distance_m > bound * (1.0 + 1e-6) + 10.0 * _SOLVE_TOLERANCE_M


def discrete_required_decel_mps2(
    speed_mps: float,
    net_accel_now_mps2: float,
    distance_m: float,
    dt_s: float,
    lag_s: float,
    max_decel_mps2: float,
    tolerance_m: float = _SOLVE_TOLERANCE_M,
) -> float:
    """Constant net deceleration [m/s²] that makes :func:`discrete_stop_distance_m` equal ``distance_m``.

    Returns ``max_decel_mps2`` when even that is not enough (the caller decides whether that is an emergency)
    and a value in ``(0, max_decel_mps2]`` otherwise. Bracketed secant (Illinois) on ``D(b) − d``, which is
    continuous and decreasing; typically 3–6 evaluations.
    """
    if distance_m <= 0.0:
        return max_decel_mps2

    def f(b: float) -> float:
        return discrete_stop_distance_m(speed_mps, net_accel_now_mps2, b, dt_s, lag_s) - distance_m

    hi = max_decel_mps2
    f_hi = f(hi)
    if f_hi >= 0.0:
        return hi
    # Initial guess from the continuous lag model, the Euler offset folded into the distance.
    lo = _MIN_DECEL_MPS2
    guess = required_decel_mps2(speed_mps, distance_m + 0.5 * speed_mps * dt_s, lag_s, net_accel_now_mps2)
    if 0.0 < guess < hi:
        f_guess = f(guess)
        if abs(f_guess) <= tolerance_m:
            return guess
        if f_guess > 0.0:
            lo, f_lo = guess, f_guess
        else:
            hi, f_hi = guess, f_guess
            f_lo = f(lo)
    else:
        f_lo = f(lo)
    if not math.isfinite(f_lo):
        # A vanishing deceleration never stops: bisect geometrically until the distance is finite.
        while not math.isfinite(f_lo) and lo < hi:
            lo = min(lo * 10.0, hi)
            f_lo = f(lo)
    if f_lo <= 0.0:  # even the gentlest braking stops short (standing, or creeping uphill)
        return lo
    side = 0
    b = hi
    for _ in range(60):
        b = (lo * f_hi - hi * f_lo) / (f_hi - f_lo) if f_hi != f_lo else 0.5 * (lo + hi)
        if not lo < b < hi:
            b = 0.5 * (lo + hi)
        fb = f(b)
        if abs(fb) <= tolerance_m:
            return b
        if fb > 0.0:
            lo, f_lo = b, fb
            if side == 1:
                f_hi *= 0.5
            side = 1
        else:
            hi, f_hi = b, fb
            if side == -1:
                f_lo *= 0.5
            side = -1
        if hi - lo < 1e-9:
            break
    return b


# ------------------------------------------------------------------------------------------ parameter parsing


def params_from_mapping(cls: type, params: Mapping[str, Any] | None, ignore: tuple[str, ...] = ("type",)) -> Any:
    """Build the frozen parameter dataclass ``cls`` from a scenario mapping.

    Unknown names raise ``ValueError("<name>: expected one of ...")``; numbers must be real and finite
    (``bool`` is not a number here), booleans must be booleans. Range checks live in each dataclass's
    ``__post_init__``. ``ignore`` lists keys the scenario loader may leave in the mapping (the controller type).
    Shared by every line controller so the error messages read the same.
    """
    known = {f.name: f for f in fields(cls)}
    values: dict[str, Any] = {}
    for key, value in (params or {}).items():
        if key in ignore:
            continue
        if key not in known:
            raise ValueError(f"{key}: expected one of {', '.join(sorted(known))}")
        default = known[key].default
        if isinstance(default, bool):
            if not isinstance(value, bool):
                raise ValueError(f"{key}: expected true or false, got {value!r}")
        elif isinstance(default, (int, float)):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"{key}: expected a finite number, got {value!r}")
            value = float(value)
        values[key] = value
    return cls(**values)


# ------------------------------------------------------------------------------- relative braking distance


def relative_braking_distance_m(
    follower_speed_mps: Any,
    leader_speed_mps: Any,
    follower_decel_mps2: Any,
    leader_decel_mps2: Any,
    delay_s: Any,
    follower_accel_mps2: Any = 0.0,
    margin_m: Any = 0.0,
) -> Any:
    """The coupled follower's safety spacing, front-to-rear [m]: the **one** definition of the RBD guard.

    Relative braking distance (spec 004 Eqs. 4–5 with the dead-time model of this module): if the leader starts
    an emergency stop at ``b_l`` now, the follower — which keeps its present acceleration ``a0`` for the dead time
    ``T`` and then brakes at ``b_f`` — must still stop ``margin`` behind the leader's rear::

        RBD = S_f − v_l²/(2·b_l) + margin,      S_f = v_f·T + a0·T²/2 + (v_f + a0·T)²/(2·b_f)

    ``S_f`` is :func:`stopping_distance_m` (to standstill; a follower already braking so hard that it stands within
    the dead time stops after ``v_f/−a0``). The guard of :class:`controllers.cacc.Cacc` holds ``gap ≥ RBD`` (it
    passes the worst-case extrapolated leader speed as ``leader_speed_mps``); the junction planner
    (:mod:`controllers.junction.model`, :mod:`controllers.junction.qp`) requires it along its plans, so a plan
    the guard would cap is infeasible. Accepts floats or numpy arrays (broadcast); returns a float for floats.
    Scalars take a plain-float path (the guard runs every step for every coupled train; numpy costs ~10x there)
    with the same operations in the same order, so both paths give the same bits (tested).
    """
    args = (follower_speed_mps, leader_speed_mps, follower_decel_mps2, leader_decel_mps2, delay_s)
    if all(isinstance(x, (float, int)) for x in args) and isinstance(follower_accel_mps2, (float, int)):
        return _rbd_scalar_m(*args, follower_accel_mps2, margin_m)
    v = np.maximum(np.asarray(follower_speed_mps, dtype=float), 0.0)
    a0 = np.asarray(follower_accel_mps2, dtype=float)
    t = np.maximum(np.asarray(delay_s, dtype=float), 0.0)
    # a follower braking hard enough to stand within the dead time: the dead time ends when it stands
    stands = (a0 < 0.0) & (v + a0 * t < 0.0)
    t = np.where(stands, v / np.where(a0 < 0.0, -a0, 1.0), t)
    v_after = np.maximum(v + a0 * t, 0.0)
    own_stop = v * t + 0.5 * a0 * t * t + v_after * v_after / (2.0 * np.asarray(follower_decel_mps2, dtype=float))
    v_l = np.maximum(np.asarray(leader_speed_mps, dtype=float), 0.0)
    out = own_stop - v_l * v_l / (2.0 * np.asarray(leader_decel_mps2, dtype=float)) + margin_m
    return float(out) if np.ndim(out) == 0 else out


def _rbd_scalar_m(v_f: float, v_l: float, b_f: float, b_l: float, delay_s: float, a0: float, margin_m: float) -> float:
    """:func:`relative_braking_distance_m` on plain floats: its array expression, operation for operation."""
    v = max(float(v_f), 0.0)
    a0 = float(a0)
    t = max(float(delay_s), 0.0)
    if a0 < 0.0 and v + a0 * t < 0.0:
        t = v / -a0
    v_after = max(v + a0 * t, 0.0)
    own_stop = v * t + 0.5 * a0 * t * t + v_after * v_after / (2.0 * float(b_f))
    v_lead = max(float(v_l), 0.0)
    return float(own_stop - v_lead * v_lead / (2.0 * float(b_l)) + margin_m)
