"""SUMO's reading of every train turned into route positions and a desync verdict, in one compiled call.

Each step the engine reads every train's odometer, speed, lane position and edge from SUMO. Three things follow
from them, train by train, and all three are plain arithmetic over the route tables of
:mod:`railsim.engine.occupancy_kernel` ("Tables"):

1. **The route chainage of the front** — the odometer plus where the trip's odometer started
   (``depart_m + odometer_m``: SUMO's odometer counts from where the train was put on, railsim's chainage from
   its route's start).
2. **The edge pointer** — the route edge under that front, found next to last step's
   (:func:`.occupancy_kernel.near_hint`, else :func:`.occupancy_kernel.edge_at`): a forward-only pointer, so a route
   passing an edge twice keeps the pass the train is on.
3. **The desync verdict** — railsim's chainage must agree with SUMO's own idea of where the train is:

   * its advance since the last check lies within ``[-tol, max(v before, v now)·dt + tol]`` (SUMO moves a train
     by its speed, never back), unless it reverses (a unit flipped onto its bidi edge); otherwise the chainage
     railsim would have expected (``railsim_m``: the last one moved on by the advance clamped into that range)
     is reported;
   * on a normal edge (not an internal junction lane, code :data:`INTERNAL`), the route's pass of SUMO's edge
     nearest the pointer (the pointer's edge, the next, the previous, else the route's last pass of it) plus the
     lane position lies within ``tol`` of the chainage (``sumo_m``; NaN when the edge is not on the route).

Per-train inputs and memory live in *slots* — a row per train for its whole run in the slot table
(:class:`railsim.engine.slots.SlotStore`), read in place by the train's slot: its route, depart chainage, pointer,
reversing flag and the speed last sent, and the chainage and speed of the train's last check and the number of the
check it was seen in, so a train absent from a check (not yet in SUMO, or gone for a step) has no "last" state at
the next.

This is the only definition of the rules; its interpreted form (``truth_pass.py_func``) is the reference, and
``tests/unit/test_truth_kernel.py`` holds the compiled form to it bit for bit and each rule to a case built by hand.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

from railsim.engine.occupancy_kernel import edge_at, near_hint
from railsim.engine.slot_columns import (
    DEPART_M,
    FRONT_M,
    HINT,
    PREV_FRONT_M,
    PREV_SPEED_MPS,
    REVERSING,
    ROUTE,
    SEEN,
    SENT_MPS,
)

INTERNAL = -2  # SUMO edge code of an internal junction lane (id starting with ":"): no position check there
UNKNOWN = -1  # SUMO edge code of an edge no registered route uses


@njit(cache=True)
def route_index(r_edges: Any, r_keys: Any, r_vals: Any, lo: int, hi: int, code: int) -> int:
    """Index on the route (its tables ``lo:hi``) of its last pass of the edge numbered ``code``, or -1 (the route's
    ``RouteView.edge_index``: a binary search of its sorted edge numbers)."""
    if code < 0:
        return -1
    a, b = lo, hi
    while a < b:
        m = (a + b) // 2
        if r_keys[m] < code:
            a = m + 1
        else:
            b = m
    if a < hi and r_keys[a] == code:
        return int(r_vals[a])
    return -1


@njit(cache=True)
def pass_near(r_edges: Any, r_keys: Any, r_vals: Any, lo: int, hi: int, code: int, i: int) -> int:
    """Index of the pass of edge ``code`` nearest the pointer ``i``: ``i`` itself, ``i + 1`` or ``i - 1`` if the route
    runs on that edge there, else its last pass (-1: the route never uses it)."""
    n = hi - lo
    for j in (i, i + 1, i - 1):
        if 0 <= j < n and r_edges[lo + j] == code:
            return j
    return route_index(r_edges, r_keys, r_vals, lo, hi, code)


DESYNC, IMPOSED = 1, 2  # bits of a train's verdict: out of step with SUMO; a speed SUMO did not take from railsim


@njit(cache=True)
def truth_pass(
    r_off: Any,
    r_edges: Any,
    r_starts: Any,
    r_keys: Any,
    r_vals: Any,
    table: Any,
    slots: Any,
    odometer_m: Any,
    sumo_edge: Any,
    lane_pos_m: Any,
    speed_mps: Any,
    check_no: int,
    dt_s: float,
    tol_m: float,
    front_m: Any,
    edge_i: Any,
    verdict: Any,
    railsim_m: Any,
    sumo_m: Any,
) -> tuple[int, int]:
    """Every train's chainage (``front_m``), edge pointer (``edge_i``) and verdict (``verdict``: :data:`DESYNC`
    with ``railsim_m`` and ``sumo_m``, NaN = none; :data:`IMPOSED`: SUMO's speed differs from the one sent, column
    :data:`~railsim.engine.slots.SENT_MPS`, NaN = none sent, by more than 1e-6 m/s) for check number ``check_no``.
    Train ``k`` of the step is row ``slots[k]`` of the slot ``table`` (:mod:`railsim.engine.slots`: its inputs
    :data:`~railsim.engine.slots.ROUTE` … :data:`~railsim.engine.slots.SENT_MPS`, and the memory of its last check,
    :data:`~railsim.engine.slots.PREV_FRONT_M`, :data:`~railsim.engine.slots.PREV_SPEED_MPS`,
    :data:`~railsim.engine.slots.SEEN`, read and then replaced by this check's); its pointer and chainage are written
    into the row too (:data:`~railsim.engine.slots.HINT`, :data:`~railsim.engine.slots.FRONT_M`). Returns the
    numbers of trains out of step and of speeds imposed (module docstring)."""
    n_bad = 0
    n_imposed = 0
    for k in range(len(slots)):
        s = slots[k]
        r = int(table[s, ROUTE])
        lo, hi = r_off[r], r_off[r + 1]
        starts = r_starts[lo:hi]
        front = table[s, DEPART_M] + odometer_m[k]
        i = near_hint(starts, front, int(table[s, HINT]))
        if i < 0:
            i = edge_at(starts, front)
        front_m[k] = front
        edge_i[k] = i
        table[s, HINT] = i
        table[s, FRONT_M] = front
        v_now = speed_mps[k]
        flags = 0
        if abs(v_now - table[s, SENT_MPS]) > 1e-6:  # (False for NaN: nothing sent yet)
            flags = IMPOSED
            n_imposed += 1
        expected = front
        if table[s, SEEN] == check_no - 1 and table[s, REVERSING] == 0.0:  # moved by its speed: never back, ≤ v·dt
            prev = table[s, PREV_FRONT_M]
            max_advance_m = max(table[s, PREV_SPEED_MPS], v_now) * dt_s
            advance_m = front - prev
            if not -tol_m <= advance_m <= max_advance_m + tol_m:
                expected = prev + min(max(advance_m, 0.0), max_advance_m)
        table[s, PREV_FRONT_M] = front
        table[s, PREV_SPEED_MPS] = v_now
        table[s, SEEN] = check_no
        railsim_m[k] = expected
        sumo_m[k] = front
        code = sumo_edge[k]
        verdict[k] = flags
        if expected == front and code != INTERNAL:
            j = pass_near(r_edges, r_keys, r_vals, lo, hi, code, i)
            if j < 0:
                sumo_m[k] = np.nan
            else:
                sumo_m[k] = starts[j] + lane_pos_m[k]
                if abs(sumo_m[k] - front) <= tol_m:
                    continue
        elif expected == front:
            continue
        verdict[k] = flags | DESYNC
        n_bad += 1
    return n_bad, n_imposed
