"""A trip's free run, written once: the ATO and the plant stepped along the route on an empty line.

A free run (no other trains) gives a trip's planned arrival and departure per station
(:func:`railsim.engine.trips.plan_free_run`); every trip with a running-time factor needs its own
(:mod:`railsim.engine.primary_delays`), so a disturbed Line 3 peak run steps ~200,000 free-run steps before its
first simulated second — in the interpreter about 2 s of a ~25 s run, at 1,000 trains several seconds.
Here the whole loop is one call: the ATO law (:func:`controllers.line_kernels.ato`), the plant step
(:func:`railsim.physics.plant_kernel.step`) and the route lookups (gradient under the front, restrictions in the
window ahead) run compiled.

**Written once.** :func:`free_run` is the only definition of the loop (lookups, law, plant, clock, stops). For the
line ATO (:class:`controllers.ato.Ato`; ``law`` None) it runs compiled, the law being
:func:`controllers.line_kernels.ato`; any other controller passes its decision as ``law`` (a Python callable) and
the same function runs interpreted (``free_run.py_func``): numba prunes the ``law is None`` test at compile time,
so the compiled loop never sees the callable. The interpreted form of the module (``tests.helpers.interpreted``)
is the reference; ``tests/sumo/test_free_run_kernel_sumo.py`` holds the compiled loop to it bit for bit on the mini
line and Line 3, at three step lengths and the three step methods, with and without running-time factors.

numba caches compiled code on disk keyed on each function's *own* source file, and :func:`free_run` compiles the
ATO and plant kernels and the forces they apply into itself: after editing ``controllers/line_kernels.py``,
``railsim/physics/plant_kernel.py`` or ``railsim/physics/forces.py``, clear ``railsim/engine/__pycache__`` (a stale
cache makes the kernel test fail, and the golden test with it).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

from controllers import line_kernels
from railsim.engine.settings import FREE_RUN_MISSED_M
from railsim.physics import plant_kernel

LOOKAHEAD_M = 4000.0  # the restrictions window ahead of the front


@njit(cache=True)
def _gradient_at(starts: np.ndarray, grades: np.ndarray, x: float) -> float:
    """``RouteView.gradient_at``."""
    i = np.searchsorted(starts, x, side="right") - 1
    if i < 0:
        return 0.0
    if grades[i, 0] <= x < grades[i, 1]:
        return grades[i, 2]
    return 0.0


@njit(cache=True)
def _limits_ahead(limits: np.ndarray, from_m: float, to_m: float, line_speed_mps: float) -> np.ndarray:
    """``RouteView.limits_ahead``: from the last restriction starting at or before ``from_m`` until the first
    starting after ``to_m``, those reaching ``from_m`` and below line speed, in order."""
    n = limits.shape[0]
    if n == 0:
        return limits
    i = max(int(np.searchsorted(limits[:, 0], from_m, side="right")) - 1, 0)
    keep = np.zeros(n, dtype=np.bool_)
    count = 0
    for k in range(i, n):
        if limits[k, 0] > to_m:
            break
        if limits[k, 1] >= from_m and limits[k, 2] < line_speed_mps:
            keep[k] = True
            count += 1
    out = np.empty((count, 3), dtype=np.float64)
    j = 0
    for k in range(i, n):
        if keep[k]:
            out[j, 0], out[j, 1], out[j, 2] = limits[k, 0], limits[k, 1], limits[k, 2]
            j += 1
            if j == count:
                break
    return out


@njit(cache=True)
def free_run(
    law: Any,
    ato_p: np.ndarray,
    plant_p: np.ndarray,
    method: int,
    dt_s: float,
    length_m: float,
    line_speed_mps: float,
    grade_starts: np.ndarray,
    grades: np.ndarray,
    limits: np.ndarray,
    stops: np.ndarray,
    x0_m: float,
    v0_mps: float,
    max_time_s: float,
) -> tuple[np.ndarray, np.ndarray, bool]:
    """Arrival and departure time per stop (NaN: not reached; stop 0 is the origin) and whether the loop ran
    through. ``stops`` rows: ``(mark, window start, window end, dwell, is destination, served end)``; a stop the
    front runs more than ``FREE_RUN_MISSED_M`` past its served end is passed (NaN). False when the law returned a
    NaN command (the caller reports it).

    ``law`` None: the line ATO's law on ``ato_p``. Otherwise ``law(t, stop index, x, v, applied accel, gradient,
    restrictions window, dwelling) -> (accel, emergency)``, a Python callable, and the loop must be called
    interpreted (``free_run.py_func``)."""
    n_stops = stops.shape[0]
    arrivals = np.full(n_stops, np.nan)
    departures = np.full(n_stops, np.nan)
    arrivals[0] = 0.0
    departures[0] = 0.0
    x, v, applied, target_u = x0_m, v0_mps, 0.0, 0.0
    t = 0.0
    idx = 1
    dwelling = False
    dwell_until = 0.0
    while idx < n_stops and t < max_time_s:
        grad = _gradient_at(grade_starts, grades, x)
        window = _limits_ahead(limits, x - length_m, x + LOOKAHEAD_M, line_speed_mps)
        if law is None:  # pruned at compile time: the compiled loop is the line ATO's
            accel, emergency, _ = line_kernels.ato(
                ato_p,
                x,
                v,
                applied,
                length_m,
                grad,
                line_speed_mps,
                window,
                True,
                stops[idx, 0],
                stops[idx, 1],
                stops[idx, 2],
                dwelling,
                False,
                0.0,
                0.0,
            )
        else:
            accel, emergency = law(t, idx, x, v, applied, grad, window, dwelling)
        if accel != accel:
            return arrivals, departures, False
        v, applied, target_u, _, advance_m, _, _ = plant_kernel.step(
            plant_p, v, applied, target_u, accel, dt_s, grad, emergency, method
        )
        x += advance_m
        t += dt_s
        if dwelling:
            if t >= dwell_until:
                departures[idx] = t
                dwelling = False
                idx += 1
        elif v == 0.0 and stops[idx, 1] <= x <= stops[idx, 5]:
            arrivals[idx] = t
            if stops[idx, 4] != 0.0:
                break
            dwell_until = t + stops[idx, 3] + 1.0  # SUMO registers the stop ~1 s after the halt
            dwelling = True
        elif x > stops[idx, 5] + FREE_RUN_MISSED_M:
            if stops[idx, 4] != 0.0:
                break
            idx += 1
    return arrivals, departures, True
