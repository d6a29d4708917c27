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
   braking (ρ is taken at the present speed; re-solving every step corrects it) and the jerk limit (not in the sum;
   the ATO runs the dead-time model's half-ramp dead time first and sums from there, and plans below service
   braking).

**Defined once.** Each law is written once, compiled with numba, in :mod:`controllers.line_kernels` (the ATO and
separation laws call them inside their own compiled code) — the braking curves, the net braking
(:func:`net_braking_mps2`) and the relative braking distance (:func:`relative_braking_distance_m`); the forces they
rest on are :mod:`railsim.physics.forces`'s. Each law's interpreted form (the dispatcher's ``py_func``, or
``NUMBA_DISABLE_JIT=1``) is the readable reference. The functions here are their adapters for callers on Python
values: keyword defaults, floats, a vehicle's fields, the lag ``τ`` given as a time (the lag ratio ``r`` is computed
once per ``(dt, τ)``), arrays element by element — no arithmetic of the laws' own.

All decelerations here are **net** (what the train really does), positive numbers; callers convert to the
applied command with :meth:`railsim.physics.vehicle.VehicleParams.net_to_applied`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import fields
from typing import Any

import numpy as np

from controllers import line_kernels
from railsim.errors import require  # noqa: F401 - re-exported: controllers check parameters with it
from railsim.physics.dynamics import traction_limit_mps2  # noqa: F401 - re-exported: one definition of the envelope
from railsim.physics.vehicle import VehicleParams


def build_up_delay_s(
    accel_now_mps2: float,
    decel_mps2: float,
    lag_s: float,
    jerk_limit_mps3: float = math.inf,
    reaction_s: float = 0.0,
) -> float:
    """Equivalent dead time before the full deceleration ``decel_mps2`` acts [s]
    (:func:`controllers.line_kernels.build_up_delay_s`). ``jerk_limit_mps3=math.inf``: emergency braking."""
    return line_kernels.build_up_delay_s(  # type: ignore[no-any-return]
        float(accel_now_mps2), float(decel_mps2), float(lag_s), float(jerk_limit_mps3), float(reaction_s)
    )


def stopping_distance_m(
    speed_mps: float,
    decel_mps2: float,
    delay_s: float = 0.0,
    accel_now_mps2: float = 0.0,
    target_speed_mps: float = 0.0,
) -> float:
    """Distance [m] to get down to ``target_speed_mps`` (dead-time model:
    :func:`controllers.line_kernels.stopping_distance_m`)."""
    return line_kernels.stopping_distance_m(  # type: ignore[no-any-return]
        float(speed_mps), float(decel_mps2), float(delay_s), float(accel_now_mps2), float(target_speed_mps)
    )


def allowed_speed_mps(
    distance_m: float,
    decel_mps2: float,
    delay_s: float = 0.0,
    accel_now_mps2: float = 0.0,
    target_speed_mps: float = 0.0,
) -> float:
    """Highest speed [m/s] from which the train gets down to ``target_speed_mps`` within ``distance_m`` (the
    braking curve: :func:`controllers.line_kernels.allowed_speed_mps`)."""
    return line_kernels.allowed_speed_mps(  # type: ignore[no-any-return]
        float(distance_m), float(decel_mps2), float(delay_s), float(accel_now_mps2), float(target_speed_mps)
    )


def required_decel_mps2(
    speed_mps: float,
    distance_m: float,
    delay_s: float = 0.0,
    accel_now_mps2: float = 0.0,
    target_speed_mps: float = 0.0,
) -> float:
    """Constant deceleration [m/s²] that brings ``speed_mps`` down to ``target_speed_mps`` within ``distance_m``
    (:func:`controllers.line_kernels.required_decel_mps2`): 0 when no braking is needed, ``math.inf`` when the
    dead time alone already uses up the distance."""
    return line_kernels.required_decel_mps2(  # type: ignore[no-any-return]
        float(speed_mps), float(distance_m), float(delay_s), float(accel_now_mps2), float(target_speed_mps)
    )


def net_braking_mps2(
    vehicle: VehicleParams,
    applied_decel_mps2: float,
    gradient_permille: float,
    davis_speed_mps: float | None = None,
) -> float:
    """Net deceleration [m/s²] the train achieves with an applied brake ``applied_decel_mps2`` (positive)
    (:func:`controllers.line_kernels.net_braking_mps2`).

    The gradient always counts (downhill reduces it). Davis running resistance counts only when
    ``davis_speed_mps`` is given, evaluated at that speed: leaving it out (or taking it at a crawl, where only
    the constant term remains) under-estimates a train's own braking over a whole stop (safe for the train that
    must stop); taking it at the present speed over-estimates it (safe when that train is the obstacle ahead).
    """
    return line_kernels.net_braking_mps2(  # type: ignore[no-any-return]
        float(applied_decel_mps2),
        float(vehicle.mass_kg),
        float(vehicle.rotating_mass_factor),
        float(vehicle.davis_a_n),
        float(vehicle.davis_b_n_per_mps),
        float(vehicle.davis_c_n_per_mps2),
        float(gradient_permille),
        davis_speed_mps is not None,
        0.0 if davis_speed_mps is None else float(davis_speed_mps),
    )


# --------------------------------------------------------------------------------------------- exact discrete


def discrete_stop_distance_m(
    speed_mps: float, net_accel_now_mps2: float, decel_mps2: float, dt_s: float, lag_s: float
) -> float:
    """Distance [m] the plant runs until it stands when the net command ``−decel_mps2`` is held from now on,
    exact for its discrete recursion (:func:`controllers.line_kernels.discrete_stop_distance_m`)."""
    r = line_kernels.lag_ratio(dt_s, lag_s)
    return line_kernels.discrete_stop_distance_m(  # type: ignore[no-any-return]
        float(speed_mps), float(net_accel_now_mps2), float(decel_mps2), float(dt_s), r
    )


def discrete_stop_distance_bound_m(
    speed_mps: float, net_accel_now_mps2: float, decel_mps2: float, dt_s: float, lag_s: float
) -> float:
    """An upper bound on :func:`discrete_stop_distance_m` in a few operations
    (:func:`controllers.line_kernels.discrete_stop_distance_bound_m`)."""
    r = line_kernels.lag_ratio(dt_s, lag_s)
    return line_kernels.discrete_stop_distance_bound_m(  # type: ignore[no-any-return]
        float(speed_mps), float(net_accel_now_mps2), float(decel_mps2), float(dt_s), r
    )


def required_decel_surely_below(
    speed_mps: float, net_accel_now_mps2: float, distance_m: float, dt_s: float, lag_s: float, decel_mps2: float
) -> bool:
    """True when :func:`discrete_required_decel_mps2` for ``distance_m`` is certainly below ``decel_mps2``
    (:func:`controllers.line_kernels.required_decel_surely_below`)."""
    r = line_kernels.lag_ratio(dt_s, lag_s)
    return line_kernels.required_decel_surely_below(  # type: ignore[no-any-return]
        float(speed_mps), float(net_accel_now_mps2), float(distance_m), float(dt_s), r, float(decel_mps2)
    )


def discrete_required_decel_mps2(
    speed_mps: float,
    net_accel_now_mps2: float,
    distance_m: float,
    dt_s: float,
    lag_s: float,
    max_decel_mps2: float,
) -> float:
    """Constant net deceleration [m/s²] that makes :func:`discrete_stop_distance_m` equal ``distance_m``, or
    ``max_decel_mps2`` when even that is not enough (:func:`controllers.line_kernels.discrete_required_decel_mps2`)."""
    r = line_kernels.lag_ratio(dt_s, lag_s)
    return line_kernels.discrete_required_decel_mps2(  # type: ignore[no-any-return]
        float(speed_mps),
        float(net_accel_now_mps2),
        float(distance_m),
        float(dt_s),
        float(lag_s),
        r,
        float(max_decel_mps2),
    )


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
    The law is :func:`controllers.line_kernels.relative_braking_distance_m`, written once; arrays go through its
    compiled loop (:func:`controllers.line_kernels.relative_braking_distances_m`) element by element.
    """
    args = (
        follower_speed_mps,
        leader_speed_mps,
        follower_decel_mps2,
        leader_decel_mps2,
        delay_s,
        follower_accel_mps2,
        margin_m,
    )
    if all(isinstance(x, (float, int)) for x in args):
        return float(line_kernels.relative_braking_distance_m(*(float(x) for x in args)))
    arrays = np.broadcast_arrays(*(np.asarray(x, dtype=np.float64) for x in args))
    shape = arrays[0].shape
    flat = [np.ascontiguousarray(a).reshape(-1) for a in arrays]
    out = np.empty(flat[0].shape[0], dtype=np.float64)
    line_kernels.relative_braking_distances_m(*flat, out)  # type: ignore[call-arg]
    return float(out[0]) if not shape else out.reshape(shape)
