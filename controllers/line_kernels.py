"""The line controllers' laws, written once and compiled with numba: ATO, moving-block separation, braking curves.

Why compiled: the line laws run for every train at every step. In the interpreter each call of the ATO costs tens
of microseconds — a few hundred float operations, each a Python object — and its exact discrete stop predictor
sums and solves (:func:`discrete_required_decel_mps2` evaluates the stop sum up to 60 times). Compiled, the same
arithmetic costs about a microsecond plus the call.

**Written once.** Each law is defined here and nowhere else: :class:`controllers.ato.Ato` and
:class:`controllers.separation.Separation` pack their inputs and call :func:`ato` / :func:`separation`; the
engine's compiled loops (``railsim.engine.free_run_kernel``, ``railsim.engine.line_step_kernel``) call them
inside their own; :mod:`controllers.braking` gives the braking curves, the net braking and the relative braking
distance keyword arguments for callers on Python values. The forces the laws apply (running resistance, gradient,
traction envelope) are not written here: they are :mod:`railsim.physics.forces`'s, shared with the plant. The
interpreted form of each function — the dispatcher's ``py_func``, or every function at once with
``NUMBA_DISABLE_JIT=1`` — is the readable reference, and it gives the same bits as the compiled one: only IEEE
operations are used (``+ − × ÷ √``, comparisons, and ``pow`` of two doubles — the integer exponents of the stop sum
are converted to float, where numba would otherwise multiply by squaring, so CPython and numba both call libm's
``pow``), fastmath stays off, and :func:`_mn`/:func:`_mx` return their *first* argument on ties and with NaN, as
Python's ``min``/``max`` do (numba's would not always: ``max(-0.0, 0.0)``). The models behind the braking curves
are derived in :mod:`controllers.braking`'s docstring; the ATO and separation laws in their classes' modules.
``tests/unit/test_line_kernels.py`` holds the laws to closed forms and closed-loop outcomes, and the compiled form to
the interpreted one.

Inputs are packed once per (controller, vehicle, step length) into a float array (:data:`ATO_FIELDS`,
:data:`SEPARATION_FIELDS`); restrictions come as an ``(n, 3)`` array of ``(start, end, speed)``. Phases come back
as indices into :data:`ATO_PHASES` / :data:`SEPARATION_PHASES`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from railsim.physics import forces
from railsim.physics.plant_kernel import PLANT_FIELDS

ATO_PHASES = ("hold", "cruise", "restriction", "stop", "brake", "emergency")
_HOLD, _CRUISE, _RESTRICTION, _STOP, _BRAKE, _EMERGENCY = range(6)
SEPARATION_PHASES = ("follow", "brake", "emergency", "halt")
_FOLLOW, _SEP_BRAKE, _SEP_EMERGENCY, _HALT = range(4)

_VEHICLE_FIELDS = PLANT_FIELDS + ("actuator_time_constant_s",)  # the plant's, and the lag it predicts
# The packed float arrays: vehicle fields, the law's parameters, then the step's dt and lag ratio.
_STEP_FIELDS = ("dt_s", "lag_ratio")
ATO_FIELDS = (
    _VEHICLE_FIELDS
    + (
        "speed_margin_mps",
        "speed_gain_per_s",
        "planning_decel_fraction",
        "release_fraction",
        "max_accel_mps2",
        "authority_margin_m",
        "stop_tolerance_m",
        "creep_speed_mps",
        "creep_zone_m",
        "hold_decel_mps2",
    )
    + _STEP_FIELDS
    + ("lead_s",)  # position_lead × dt: how much farther than the Euler sum the plant runs (controllers.ato)
)
SEPARATION_FIELDS = _VEHICLE_FIELDS + ("margin_m", "reaction_time_s", "barrier_rate_per_s") + _STEP_FIELDS

_MIN_DECEL_MPS2 = 1e-4  # smallest deceleration the solvers consider: below it a stop is "never" [m/s²]
_SOLVE_TOLERANCE_M = 1e-3  # discrete_required_decel_mps2 stops when the distance is this close [m]
_NO_TRIVIAL = -1.0  # _trivial_stop_m: "the sum is needed" (its real answers are 0 and inf)
_STANDING_MPS = 1e-3  # ATO: below this speed the train counts as standing [m/s]
_STANDSTILL_BUFFER_M = 1.0  # separation: aim to halt this far before rear − margin [m]
_CRAWL_MPS = 0.5  # separation: below this speed and ...
_CRAWL_ZONE_M = 1.0  # ... this close to the halting point, brake to a stop [m]
_CRAWL_STOP_DECEL_MPS2 = 0.3  # separation: net deceleration of that final halt [m/s²]


_LAG_RATIOS: dict[tuple[float, float], float] = {}


def lag_ratio(dt_s: float, lag_s: float) -> float:
    """``r = e^{−dt/τ}`` (0 without lag), remembered per ``(dt, τ)``: a run asks for one or two pairs."""
    r = _LAG_RATIOS.get((dt_s, lag_s))
    if r is None:
        r = _LAG_RATIOS[(dt_s, lag_s)] = math.exp(-dt_s / lag_s) if lag_s > 0.0 else 0.0
    return r


def pack(
    fields: tuple[str, ...],
    vehicle: object,
    params: object,
    dt_s: float,
    extra: tuple[float, ...] = (),
) -> np.ndarray:
    """A law's float inputs (``fields``: :data:`ATO_FIELDS` or :data:`SEPARATION_FIELDS`) for one controller,
    vehicle and step length (the lag ratio from the vehicle's actuator time constant); ``extra``: the values of the
    fields after the step's (the ATO's ``lead_s``)."""
    n = len(fields) - len(_STEP_FIELDS) - len(extra)
    if fields[n : n + len(_STEP_FIELDS)] != _STEP_FIELDS:
        raise ValueError(f"{len(extra)} extra value(s) for fields {fields!r}")
    values = [float(getattr(vehicle, f) if hasattr(vehicle, f) else getattr(params, f)) for f in fields[:n]]
    r = lag_ratio(dt_s, vehicle.actuator_time_constant_s)  # type: ignore[attr-defined]
    return np.array([*values, float(dt_s), float(r), *(float(e) for e in extra)], dtype=np.float64)


def limits_array(limits: tuple) -> np.ndarray:
    """Restrictions ``(start, end, speed)`` as an ``(n, 3)`` float array."""
    if not limits:
        return _EMPTY
    return np.array([(lim.start_m, lim.end_m, lim.speed_mps) for lim in limits], dtype=np.float64)


_EMPTY = np.zeros((0, 3), dtype=np.float64)


@njit(cache=True, inline="always")
def _mn(a: float, b: float) -> float:
    """Python's ``min(a, b)``: ``a`` unless ``b < a``."""
    return b if b < a else a


@njit(cache=True, inline="always")
def _mx(a: float, b: float) -> float:
    """Python's ``max(a, b)``: ``a`` unless ``b > a``."""
    return b if b > a else a


@njit(cache=True)
def build_up_delay_s(accel_now: float, decel: float, lag_s: float, jerk: float, reaction_s: float) -> float:
    """Equivalent dead time before the full deceleration ``decel`` acts [s].

    ``reaction_s`` (detection, communication, decision) + the actuator lag ``lag_s`` + half the jerk-limited ramp
    from the present acceleration ``accel_now`` to ``−decel``. ``jerk = inf`` for emergency braking, which
    bypasses the jerk limit."""
    ramp_s = 0.0
    if math.isfinite(jerk) and jerk > 0.0:
        ramp_s = _mx(accel_now + decel, 0.0) / jerk
    return _mx(reaction_s, 0.0) + _mx(lag_s, 0.0) + 0.5 * ramp_s


@njit(cache=True)
def allowed_speed_mps(distance_m: float, decel: float, delay_s: float, accel_now: float, target: float) -> float:
    """Highest speed [m/s] from which the train gets down to ``target`` within ``distance_m``.

    Inverse of :func:`stopping_distance_m` for the branch where the dead time ends above the target speed:
    with ``w = v + a0·T``: ``w² + 2·b·T·w − (2·b·d + v_end² + a0·b·T²) = 0``. At or past the point
    (``distance_m ≤ 0``) it is the target speed itself."""
    b = decel
    t = _mx(delay_s, 0.0)
    a0 = accel_now
    v_end = _mx(target, 0.0)
    d = distance_m
    if d <= 0.0:
        return v_end
    disc = b * b * t * t + 2.0 * b * d + v_end * v_end + a0 * b * t * t
    if disc <= 0.0:
        return 0.0
    w = -b * t + math.sqrt(disc)
    return _mx(w - a0 * t, 0.0)


@njit(cache=True, inline="always")
def _dead_time(speed: float, delay_s: float, a0: float) -> tuple[float, float, float]:
    """The dead-time model's start (controllers.braking): ``(v ≥ 0, dead time — shortened if the train stands
    within it, speed after it)``."""
    v = _mx(speed, 0.0)
    t = _mx(delay_s, 0.0)
    if a0 < 0.0 and v + a0 * t < 0.0:  # already braking hard enough to stand within the dead time
        t = v / -a0
    return v, t, _mx(v + a0 * t, 0.0)


@njit(cache=True)
def _ramp_dead_run(speed: float, net_now: float, decel: float, jerk: float) -> tuple[float, float]:
    """The jerk-limited ramp of the command from the net acceleration ``net_now`` down to ``−decel`` as the dead-time
    model's half-ramp dead time (:mod:`controllers.braking`): ``(distance run in it [m], speed after it [m/s])``.
    No ramp (already braking that hard, or no jerk limit): ``(0, speed)``."""
    if jerk <= 0.0 or net_now + decel <= 0.0:
        return 0.0, _mx(speed, 0.0)
    v, t, v_after = _dead_time(speed, 0.5 * (net_now + decel) / jerk, net_now)
    return v * t + 0.5 * net_now * t * t, v_after


@njit(cache=True)
def required_decel_mps2(speed: float, distance_m: float, delay_s: float, accel_now: float, target: float) -> float:
    """Constant deceleration [m/s²] that brings ``speed`` down to ``target`` within ``distance_m`` (dead-time model
    with a fixed delay): ``0`` when no braking is needed, ``inf`` when the dead time alone uses up the distance."""
    v, t, v_after = _dead_time(speed, delay_s, accel_now)
    a0 = accel_now
    v_end = _mx(target, 0.0)
    if v_after <= v_end:
        return 0.0
    room = distance_m - (v * t + 0.5 * a0 * t * t)
    if room <= 0.0:
        return math.inf
    return (v_after * v_after - v_end * v_end) / (2.0 * room)


@njit(cache=True, inline="always")
def _trivial_stop_m(speed: float, net_now: float, decel: float) -> float:
    """0 for a train standing without drive, infinity for a vanishing deceleration, else :data:`_NO_TRIVIAL`."""
    if speed <= 0.0 and net_now <= 0.0:
        return 0.0
    if decel <= _MIN_DECEL_MPS2:
        return math.inf
    return _NO_TRIVIAL


@njit(cache=True)
def discrete_stop_distance_m(speed: float, net_now: float, decel: float, dt_s: float, r: float) -> float:
    """Distance [m] the plant runs until it stands when the net command ``−decel`` is held from now on.

    Exact for the plant's discrete recursion (lag ratio ``r = e^{−dt/τ}``, Euler positions, speed clamp at 0) with
    constant resistance (:mod:`controllers.braking`). ``net_now`` is last step's net acceleration (applied −
    resistance). The first step with ``V_j ≤ 0`` is found from the crossing of the asymptote (``r^j → 0``), then
    walked to the exact one."""
    v = speed
    b = decel
    trivial = _trivial_stop_m(v, net_now, b)
    if trivial != _NO_TRIVIAL:
        return trivial
    s = r / (1.0 - r)
    c = net_now + b
    cds = c * dt_s * s
    bdt = b * dt_s
    n = max(1, math.ceil((v + cds) / bdt))
    while n > 1 and v - (n - 1) * bdt + cds * (1.0 - r ** float(n - 1)) <= 0.0:
        n -= 1
    while v - n * bdt + cds * (1.0 - r ** float(n)) > 0.0:
        n += 1
    m = n - 1
    if m <= 0:
        return 0.0
    total = m * (v + cds) - bdt * m * (m + 1) / 2.0 - cds * s * (1.0 - r ** float(m))
    return _mx(total * dt_s, 0.0)


@njit(cache=True)
def discrete_stop_distance_bound_m(speed: float, net_now: float, decel: float, dt_s: float, r: float) -> float:
    """An upper bound on :func:`discrete_stop_distance_m` in a few operations (a screen before the exact sum).

    With ``W = v + max(c·dt·s, 0)`` every speed of the recursion is ``V_j ≤ W − j·b·dt`` (the lag term
    ``c·dt·s·(1 − r^j)`` lies between 0 and ``c·dt·s``), so the distance ``dt·Σ V_j`` over the steps with
    ``V_j > 0`` is at most ``W²/(2·b)``. A relative and an absolute slack of 1e-9 cover the rounding of the exact
    sum, so ``x > bound`` proves ``x > discrete_stop_distance_m(...)`` (ATO cruising far from its stop points)."""
    trivial = _trivial_stop_m(speed, net_now, decel)
    if trivial != _NO_TRIVIAL:
        return trivial
    cds = (net_now + decel) * dt_s * (r / (1.0 - r))
    w = _mx(speed, 0.0) + _mx(cds, 0.0)
    return w * w / (2.0 * decel) * (1.0 + 1e-9) + 1e-9


@njit(cache=True)
def required_decel_surely_below(
    speed: float, net_now: float, distance_m: float, dt_s: float, r: float, decel: float
) -> bool:
    """True when :func:`discrete_required_decel_mps2` for ``distance_m`` is certainly below ``decel``: the distance
    is beyond :func:`discrete_stop_distance_bound_m` at ``decel`` by more than ten times the solver's tolerance,
    so the root (the distance falls with the deceleration) and every answer of the solver lie below it."""
    bound = discrete_stop_distance_bound_m(speed, net_now, decel, dt_s, r)
    return distance_m > bound * (1.0 + 1e-6) + 10.0 * _SOLVE_TOLERANCE_M


@njit(cache=True)
def discrete_required_decel_mps2(
    speed: float, net_now: float, distance_m: float, dt_s: float, lag_s: float, r: float, max_decel: float
) -> float:
    """Constant net deceleration [m/s²] that makes :func:`discrete_stop_distance_m` equal ``distance_m``.

    ``max_decel`` when even that is not enough (the caller decides whether that is an emergency), else a value in
    ``(0, max_decel]``. Bracketed secant (Illinois) on ``D(b) − d``, which is continuous and decreasing, started
    from the continuous lag model's answer (``lag_s``; the Euler offset folded into the distance); typically 3–6
    evaluations."""
    if distance_m <= 0.0:
        return max_decel
    tol = _SOLVE_TOLERANCE_M
    hi = max_decel
    f_hi = discrete_stop_distance_m(speed, net_now, hi, dt_s, r) - distance_m
    if f_hi >= 0.0:
        return hi
    lo = _MIN_DECEL_MPS2
    guess = required_decel_mps2(speed, distance_m + 0.5 * speed * dt_s, lag_s, net_now, 0.0)
    if 0.0 < guess < hi:
        f_guess = discrete_stop_distance_m(speed, net_now, guess, dt_s, r) - distance_m
        if abs(f_guess) <= tol:
            return guess
        if f_guess > 0.0:
            lo, f_lo = guess, f_guess
        else:
            hi, f_hi = guess, f_guess
            f_lo = discrete_stop_distance_m(speed, net_now, lo, dt_s, r) - distance_m
    else:
        f_lo = discrete_stop_distance_m(speed, net_now, lo, dt_s, r) - distance_m
    if not math.isfinite(f_lo):
        while not math.isfinite(f_lo) and lo < hi:
            lo = _mn(lo * 10.0, hi)
            f_lo = discrete_stop_distance_m(speed, net_now, lo, dt_s, r) - distance_m
    if f_lo <= 0.0:
        return lo
    side = 0
    b = hi
    for _ in range(60):
        b = (lo * f_hi - hi * f_lo) / (f_hi - f_lo) if f_hi != f_lo else 0.5 * (lo + hi)
        if not lo < b < hi:
            b = 0.5 * (lo + hi)
        fb = discrete_stop_distance_m(speed, net_now, b, dt_s, r) - distance_m
        if abs(fb) <= tol:
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


@njit(cache=True)
def _restriction_far_m(
    v: float, v_target: float, b_plan: float, b_release: float, delay_s: float, net_now: float
) -> float:
    """Distance beyond which a speed restriction ahead changes neither the ATO's cruise target nor its braking.

    Its braking curve allows ``≥ v_target`` once ``d ≥ v_target²/(2·b_plan) + v_target·T`` (the quadratic of
    :func:`allowed_speed_mps` with ``a0 = 0``, whatever the restriction's speed), and the deceleration it requires
    (:func:`required_decel_mps2` with ``a0 = net_now``) stays below ``b_release`` once
    ``d > dead-time run + v_after²/(2·b_release)``. A millimetre and a relative 1e-9 on top cover rounding,
    so skipping a restriction beyond this distance gives the command the full loop gives."""
    v, t, v_after = _dead_time(v, delay_s, net_now)
    dead_m = v * t + 0.5 * net_now * t * t
    vt = _mx(v_target, 0.0)
    far_m = _mx(vt * vt / (2.0 * b_plan) + vt * delay_s, dead_m + v_after * v_after / (2.0 * b_release))
    return far_m * (1.0 + 1e-9) + 1e-3


@njit(cache=True)
def stopping_distance_m(speed: float, decel: float, delay_s: float, accel_now: float, target: float) -> float:
    """Distance [m] to get down to ``target`` (dead-time model, :mod:`controllers.braking`); during the dead time
    the speed follows ``accel_now`` but never goes below zero."""
    v, t, v_after = _dead_time(speed, delay_s, accel_now)
    a0 = accel_now
    dist = v * t + 0.5 * a0 * t * t
    v_end = _mx(target, 0.0)
    if v_after > v_end:
        dist += (v_after * v_after - v_end * v_end) / (2.0 * decel)
    return dist


@njit(cache=True)
def net_braking_mps2(
    applied_decel: float,
    mass: float,
    rot: float,
    davis_a: float,
    davis_b: float,
    davis_c: float,
    grade: float,
    with_davis: bool,
    davis_speed: float,
) -> float:
    """Net deceleration [m/s²] the train achieves with the applied brake ``applied_decel`` (positive).

    The gradient always counts (downhill reduces it); Davis running resistance only ``with_davis``, at
    ``davis_speed`` (:func:`controllers.braking.net_braking_mps2` says which choice is safe for whom)."""
    if with_davis:
        extra_n = forces.resistance_n(mass, davis_a, davis_b, davis_c, _mx(davis_speed, 1e-9), grade)
    else:
        extra_n = forces.gradient_force_n(mass, grade)
    return applied_decel + extra_n / (mass * rot)


@njit(cache=True)
def relative_braking_distance_m(
    v_f: float, v_l: float, b_f: float, b_l: float, delay_s: float, a0: float, margin_m: float
) -> float:
    """The coupled follower's safety spacing, front-to-rear [m] (:func:`controllers.braking.relative_braking_distance_m`):
    the follower's dead-time stop (:func:`stopping_distance_m` to standstill) less the leader's emergency stop
    ``v_l²/(2·b_l)``, plus ``margin_m``."""
    v_lead = _mx(v_l, 0.0)
    return stopping_distance_m(v_f, b_f, delay_s, a0, 0.0) - v_lead * v_lead / (2.0 * b_l) + margin_m


@njit(cache=True)
def relative_braking_distances_m(
    v_f: np.ndarray,
    v_l: np.ndarray,
    b_f: np.ndarray,
    b_l: np.ndarray,
    delay_s: np.ndarray,
    a0: np.ndarray,
    margin_m: np.ndarray,
    out: np.ndarray,
) -> None:
    """:func:`relative_braking_distance_m` for every ``i`` of equally long 1-d arrays, into ``out``."""
    for i in range(out.shape[0]):
        out[i] = relative_braking_distance_m(v_f[i], v_l[i], b_f[i], b_l[i], delay_s[i], a0[i], margin_m[i])


@njit(cache=True)
def separation(
    p: np.ndarray, x: float, speed_mps: float, a0: float, grade: float, pred_rear_m: float, pred_age_s: float
) -> tuple[float, bool, int, float, float]:
    """Moving-block separation (:mod:`controllers.separation`) against a predecessor rear ``pred_rear_m`` known
    ``pred_age_s`` ago, on packed inputs: ``(applied accel, emergency, phase index, free distance, barrier)``."""
    mass, rot, davis_a, davis_b, davis_c = p[0], p[1], p[2], p[3], p[4]
    f0, power, service, emergency_decel = p[6], p[7], p[8], p[9]
    jerk, tau = p[10], p[11]
    margin, reaction_time, barrier_rate = p[12], p[13], p[14]
    dt_s, r = p[15], p[16]

    v = _mx(speed_mps, 0.0)
    traction = forces.traction_limit_mps2(mass, rot, f0, power, v)
    b = _mx(net_braking_mps2(service, mass, rot, davis_a, davis_b, davis_c, grade, False, 0.0), 0.05)
    age_s = _mx(pred_age_s, 0.0)
    reaction_s = reaction_time + age_s + dt_s  # + one step: a command is held until the next decision
    delay = build_up_delay_s(a0, b, tau, jerk, reaction_s)
    free_m = pred_rear_m - margin - x
    # The barrier aims one step of travel plus a small standstill buffer short of the boundary: the law is
    # continuous-time, the plant is sampled and lagged, and the train should come to rest *before* rear − margin.
    h = free_m - stopping_distance_m(v, b, delay, a0, 0.0) - v * dt_s - _STANDSTILL_BUFFER_M
    phase = _FOLLOW
    if h < 0.0 and v > 0.0:
        # Inside the braking curve's allowance already (a predecessor appeared close, a long outage): emergency
        # only if service braking, predicted exactly for the plant plus the jerk ramp, no longer stops in time.
        rho = forces.resistance_n(mass, davis_a, davis_b, davis_c, v, grade) / (mass * rot)
        ramp_m, v_ramp = _ramp_dead_run(v, a0 - rho, b, jerk)
        if discrete_stop_distance_m(v_ramp, a0 - rho, b, dt_s, r) + ramp_m > free_m:
            return -emergency_decel, True, _SEP_EMERGENCY, free_m, h
        phase = _SEP_BRAKE
    slope_s = delay + _mx(v + a0 * delay, 0.0) / b
    gamma = _mn(barrier_rate, 0.5 / dt_s)  # a sampled barrier with γ·dt near 1 rings
    net_cap = (gamma * h - v) / slope_s if slope_s > 0.0 else math.inf
    if not math.isfinite(net_cap):
        return traction, False, phase, free_m, h
    if v < _CRAWL_MPS and free_m - _STANDSTILL_BUFFER_M < _CRAWL_ZONE_M:
        # The barrier approaches its end point asymptotically; rather than crawl for minutes, halt.
        net_cap = _mn(net_cap, -_CRAWL_STOP_DECEL_MPS2)
        phase = _HALT
    applied = net_cap + forces.resistance_n(mass, davis_a, davis_b, davis_c, v, grade) / (mass * rot)
    return _mn(_mx(applied, -service), traction), False, phase, free_m, h


@njit(cache=True)
def ato(
    p: np.ndarray,
    x: float,
    speed_mps: float,
    applied_now: float,
    length_m: float,
    grade: float,
    line_speed_mps: float,
    limits: np.ndarray,
    has_stop: bool,
    mark_m: float,
    window_start_m: float,
    window_end_m: float,
    dwelling: bool,
    has_authority: bool,
    authority_end_m: float,
    tail_m: float,
) -> tuple[float, bool, int]:
    """The ATO law (:mod:`controllers.ato`) on packed inputs: ``(applied accel, emergency, phase index)``.

    ``limits``: restrictions ``(start, end, speed)``; the next stop (``mark_m``, its window, ``dwelling``) is read
    only with ``has_stop``, the end of authority only with ``has_authority``; ``tail_m`` > 0: the train leads a
    formation that long, and every restriction's end moves on by it."""
    mass, rot, davis_a, davis_b, davis_c = p[0], p[1], p[2], p[3], p[4]
    max_speed, f0, power, service, emergency_decel = p[5], p[6], p[7], p[8], p[9]
    jerk, tau = p[10], p[11]
    speed_margin, gain, plan_frac, release_frac, max_accel = p[12], p[13], p[14], p[15], p[16]
    authority_margin, stop_tol, creep_speed, creep_zone, hold_decel = p[17], p[18], p[19], p[20], p[21]
    dt, r, lead_s = p[22], p[23], p[24]

    v = _mx(speed_mps, 0.0)
    rho = forces.resistance_n(mass, davis_a, davis_b, davis_c, v, grade) / (mass * rot)  # a deceleration [m/s²]
    net_now = applied_now - rho
    standing = v <= _STANDING_MPS
    # Net braking the train can plan with: on a downhill part of the brake only holds the train.
    b_service_net = _mx(service + rho, 0.05)
    b_plan = plan_frac * _mn(service, b_service_net)
    hold_applied = -_mn(service, _mx(hold_decel, -rho + 0.1))

    if has_stop:
        # not short of the window by any tolerance: SUMO registers no stop there, so a train held just short of
        # it (by the train ahead) creeps in rather than hold for ever
        in_window = window_start_m <= x <= window_end_m + stop_tol
        if dwelling or (standing and in_window):
            return hold_applied, False, _HOLD

    # ---- cruise target: line speed, vehicle limit, restrictions under the train (rear rule)
    v_target = _mn(line_speed_mps, max_speed) - speed_margin
    delay_plan = build_up_delay_s(applied_now, b_plan, tau, jerk, 0.0)
    brake_net = math.inf  # most restrictive braking sub-law (net acceleration, <= 0)
    phase = _CRUISE
    braking_now = net_now <= -0.3 * b_plan
    n_lim = limits.shape[0]
    far_m = _restriction_far_m(v, v_target, b_plan, release_frac * b_plan, delay_plan, net_now) if n_lim > 0 else 0.0
    for k in range(n_lim):
        start_m, end_m, lim_speed = limits[k, 0], limits[k, 1], limits[k, 2]
        if tail_m > 0.0:  # a formation's rear must clear it
            end_m = end_m + tail_m
        v_lim = lim_speed - speed_margin
        if start_m <= x < end_m + length_m:
            v_target = _mn(v_target, v_lim)
        elif x < start_m <= x + far_m:  # farther restrictions change nothing yet (_restriction_far_m)
            d = start_m - x
            v_target = _mn(v_target, allowed_speed_mps(d, b_plan, delay_plan, 0.0, v_lim))
            if v > v_lim:
                b_req = required_decel_mps2(v, d, delay_plan, net_now, v_lim)
                if b_req >= b_plan or (braking_now and b_req >= release_frac * b_plan):
                    if -_mn(b_req, b_service_net) < brake_net:
                        brake_net = -_mn(b_req, b_service_net)
                        phase = _RESTRICTION
    v_target = _mx(v_target, 0.0)

    # ---- stop points: the stopping mark (aimed inside the window) and the end of authority
    points = np.empty(2)
    n_points = 0
    if has_stop:
        lo = window_start_m + stop_tol
        hi = window_end_m - stop_tol
        aim = _mn(_mx(mark_m, lo), hi) if lo <= hi else 0.5 * (window_start_m + window_end_m)
        points[n_points] = aim
        n_points += 1
    emergency = False
    if has_authority:
        points[n_points] = authority_end_m - authority_margin
        n_points += 1
        hard_m = authority_end_m - x
        if lead_s > 0.0:  # the plant runs lead_s·v farther than the Euler sum (controllers.ato)
            hard_m -= lead_s * v
        # the cheap upper bound first: far from the end of authority the exact sum is not needed
        if (
            v > 0.0
            and hard_m < discrete_stop_distance_bound_m(v, net_now, b_service_net, dt, r)
            and discrete_stop_distance_m(v, net_now, b_service_net, dt, r) > hard_m
        ):
            emergency = True
    # The jerk-limited ramp from the present net acceleration down to the planned braking, as the dead-time model
    # has it (controllers.braking): the present acceleration held for half the ramp, then the stop sum from there.
    ramp_m, v_ramp = _ramp_dead_run(v, net_now, b_plan, jerk)
    # One more step of cruise first: out of a restriction (or a station) close before a stop point, cruise asks
    # for full traction, and the train would be past the point where even service braking stops it in time (a
    # train leaving a 6.6 m/s junction curve 43 m before its mark overran it by 2.6 m: SUMO's routes_cross_twice
    # net). If the state after that step could no longer stop there with the service brake, brake now. (Only
    # then: a braking onset the plan's deceleration still allows one step later stays where it was.)
    traction = _mn(forces.traction_limit_mps2(mass, rot, f0, power, v), max_accel)
    if v >= max_speed:
        traction = 0.0
    cruise_ahead = _mn(_mx(gain * (v_target - v), -b_plan), traction - rho)
    speeding_up = cruise_ahead > net_now + 1e-9
    net_next = net_now + (1.0 - r) * (cruise_ahead - net_now)  # the actuator's lag, no jerk cap: conservative
    v_next = v + dt * _mx(net_next, 0.0)
    ramp_next_m, v_ramp_next = _ramp_dead_run(v_next, net_next, b_service_net, jerk)
    for k in range(n_points):
        d = points[k] - x
        if lead_s > 0.0:
            d -= lead_s * v
        if standing and d <= stop_tol:
            return hold_applied, False, _HOLD
        creeping = v <= creep_speed and d <= creep_zone
        if creeping:
            v_target = _mn(v_target, creep_speed)
        if d <= 0.0:
            brake_net = -b_service_net
            phase = _STOP
            continue
        room_m = d - v * dt - ramp_m
        triggered = room_m <= discrete_stop_distance_bound_m(v_ramp, net_now, b_plan, dt, r) and (
            room_m <= discrete_stop_distance_m(v_ramp, net_now, b_plan, dt, r)
        )
        if not triggered and speeding_up and not creeping:  # a creep's step is the creep speed's, not full traction
            room_next_m = d - v_next * dt - ramp_next_m
            triggered = room_next_m <= discrete_stop_distance_bound_m(v_ramp_next, net_next, b_service_net, dt, r) and (
                room_next_m <= discrete_stop_distance_m(v_ramp_next, net_next, b_service_net, dt, r)
            )
        if triggered or braking_now:
            b_release = release_frac * b_plan
            # solved past the ramp too: from full traction the ramp alone runs as far as the braking after it
            solve_m, v_solve = (0.0, v) if braking_now else (ramp_m, v_ramp)
            if not triggered and required_decel_surely_below(v_solve, net_now, d - solve_m, dt, r, b_release):
                continue  # braking for something else, this point far off: no solve needed to stay released
            b_req = discrete_required_decel_mps2(v_solve, net_now, d - solve_m, dt, tau, r, b_service_net)
            if (triggered or b_req >= b_release) and -b_req < brake_net:
                brake_net = -b_req
                phase = _STOP

    # ---- cruise law and the minimum
    cruise_net = gain * (v_target - v)
    cruise_net = _mn(_mx(cruise_net, -b_plan), traction - rho)
    net = _mn(cruise_net, brake_net)
    if net < cruise_net and phase == _CRUISE:
        phase = _BRAKE
    if emergency:
        return -emergency_decel, True, _EMERGENCY
    applied = net + rho  # VehicleParams.net_to_applied(net, v, grade), the same operations
    return _mn(_mx(applied, -service), traction), False, phase
