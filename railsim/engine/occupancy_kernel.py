"""The occupancy index over per-train arrays, in compiled passes: edges under each body, the train ahead, the
train facing.

:class:`railsim.engine.occupancy.Occupancy` keeps the ground truth of every train on the line as rows of arrays
indexed by a *slot* (the train's place in the step's list) and every route as a segment of flat route tables; this
module is the geometry on those arrays, one compiled call per step for all trains:

* :func:`place` — the route edges under each body's front and rear (forward-only pointers, :func:`edge_near`)
  and the index *by edge*: which slots cover each SUMO edge, in slot order (compressed rows: the slots of edge
  ``e`` are ``by_slot[by_off[e]:by_off[e + 1]]``);
* :func:`ahead_all` — for every train the nearest train whose front is ahead of its own on its route
  (:func:`ahead_one`), with the other train's body mapped into its frame (:func:`map_body`: only the part of the
  body on track both routes share counts; a tail on the other leg of a merge is clamped to the switch);
* :func:`facing_all` — for every query the nearest train on the partner edges of the train's route ahead
  (:func:`facing_one`: on ``bidi`` track a train running the other way is on the partner edge, ``x`` metres into
  one edge being ``length - x`` into its partner).

**Tables.** Edges are numbered globally (``int64``). Route ``r`` is ``r_off[r]:r_off[r + 1]`` of ``r_edges`` (the
edge ids in route order) and ``r_starts`` (their start chainages); its edge -> route index look-up is the same
segment of ``r_keys`` (the route's edge ids sorted) and ``r_vals`` (for each, the index of the *last* occurrence of
that edge on the route, as a ``dict`` built over the route keeps it); ``r_len`` is its length, ``r_simple`` whether no edge occurs twice.
``partner[e]`` is the bidi partner of edge ``e`` (-1: none) and ``partner_len[e]`` that partner's length.

**Written once, bit for bit.** These functions are the only definition of the search; their interpreted form
(``NUMBA_DISABLE_JIT=1``, ``tests.helpers.interpreted``) is the reference the compiled form gives the same bits
as (``tests/unit/test_occupancy_kernel.py``). :meth:`railsim.engine.routeview.RouteView.edge_near` calls
:func:`near_hint`'s interpreted form on its tuple of edge starts (and searches with ``bisect`` where it has no
answer, as :func:`edge_at` does with ``searchsorted``). Python's ``min``/``max`` tie rules are kept
(``_pymin``/``_pymax``: the first argument unless the second is strictly smaller/greater), and only IEEE sums
and differences are taken, so the compiled and interpreted answers agree to the bit.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

# What the ahead kernels search (Occupancy._ahead_world), in this order: the route tables (RouteTables: offsets,
# edges, edge starts, the sorted edge keys and the index of each, the simple flags), the slot columns (route, front,
# length, front edge, rear edge) and the slots by edge (offsets, slots)
RouteTables = tuple[np.ndarray, ...]
AheadWorld = tuple[Any, ...]

# What the facing kernels search, in this order (Occupancy._facing_world): the route tables (offsets, edges,
# edge starts, lengths), each edge's partner edge and its length, the slot columns (route, front, length, front
# edge, rear edge) and the slots by edge (offsets, slots)
FacingWorld = tuple[np.ndarray, ...]


@njit(cache=True)
def _pymax(a: float, b: float) -> float:
    """Python's ``max(a, b)`` on floats: ``a`` unless ``b`` is strictly greater."""
    return b if b > a else a


@njit(cache=True)
def _pymin(a: float, b: float) -> float:
    """Python's ``min(a, b)`` on floats: ``a`` unless ``b`` is strictly smaller."""
    return b if b < a else a


@njit(cache=True)
def edge_at(starts: np.ndarray, chainage_m: float) -> int:
    """Index of the edge (starting at ``starts``, never decreasing) that covers ``chainage_m``, clamped to the
    route: the last start at or before it (``bisect_right - 1``, as :meth:`RouteView.edge_at`)."""
    i = int(np.searchsorted(starts, chainage_m, side="right")) - 1
    last = len(starts) - 1
    return min(max(i, 0), last)


@njit(cache=True)
def near_hint(starts: Any, chainage_m: float, hint: int) -> int:
    """Index of the edge (starting at ``starts``) that covers ``chainage_m`` if that is edge ``hint`` or one of its
    neighbours, else -1 (a search is needed: :func:`edge_at`). The hint and its neighbours are checked against the
    edge bounds; the answer, when there is one, is :func:`edge_at`'s whatever the hint."""
    last = len(starts) - 1
    if 0 <= hint <= last:  # the same answers as the loop below, unrolled (edge starts never decrease)
        if hint == 0 or starts[hint] <= chainage_m:
            if hint == last or chainage_m < starts[hint + 1]:
                return hint
            nxt = hint + 1  # at or past its start
            if nxt == last or chainage_m < starts[nxt + 1]:
                return nxt
        elif hint - 1 == 0 or starts[hint - 1] <= chainage_m:  # before the hint's start: the previous edge?
            return hint - 1
        return -1
    for i in (hint, hint + 1, hint - 1):
        if 0 <= i <= last and (i == 0 or starts[i] <= chainage_m) and (i == last or chainage_m < starts[i + 1]):
            return i
    return -1


@njit(cache=True)
def edge_near(starts: np.ndarray, chainage_m: float, hint: int) -> int:
    """:func:`edge_at` for a chainage on or next to edge ``hint`` (a train's front one step later, its rear):
    :func:`near_hint`, and the search only where it has no answer."""
    i = near_hint(starts, chainage_m, hint)
    return i if i >= 0 else edge_at(starts, chainage_m)


@njit(cache=True)
def _index_of(r_keys: np.ndarray, r_vals: np.ndarray, lo: int, hi: int, edge: int) -> int:
    """Route index of global ``edge`` in the sorted look-up segment ``lo:hi`` (-1: not on the route)."""
    k = lo + int(np.searchsorted(r_keys[lo:hi], edge))
    if k < hi and r_keys[k] == edge:
        return int(r_vals[k])
    return -1


@njit(cache=True)
def place(
    r_off: np.ndarray,
    r_edges: np.ndarray,
    r_starts: np.ndarray,
    n_edges: int,
    s_route: np.ndarray,
    s_front: np.ndarray,
    s_len: np.ndarray,
    s_edge: np.ndarray,
    s_rear: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Set ``s_edge`` (from its hint, in place) and ``s_rear`` to the route edges under each body's front and rear;
    return the index by edge ``(by_off, by_slot)`` (module docstring), slots in slot order."""
    n = len(s_route)
    counts = np.zeros(n_edges + 1, np.int64)
    for s in range(n):
        a = r_off[s_route[s]]
        starts = r_starts[a : r_off[s_route[s] + 1]]
        i1 = edge_near(starts, s_front[s], s_edge[s])
        i0 = edge_near(starts, s_front[s] - s_len[s], i1)
        s_edge[s] = i1
        s_rear[s] = i0
        for i in range(i0, i1 + 1):
            counts[r_edges[a + i] + 1] += 1
    by_off = np.cumsum(counts)
    fill = by_off[:-1].copy()
    by_slot = np.empty(by_off[-1], np.int64)
    for s in range(n):
        a = r_off[s_route[s]]
        for i in range(s_rear[s], s_edge[s] + 1):
            e = r_edges[a + i]
            by_slot[fill[e]] = s
            fill[e] += 1
    return by_off, by_slot


@njit(cache=True)
def _index_from(r_edges: np.ndarray, a: int, b: int, from_j: int, edge: int) -> int:
    """Route index (within ``a:b``) of the first occurrence of global ``edge`` at or after index ``from_j`` (-1:
    none): on a route that passes an edge twice, the pass nearest ahead of an observer at ``from_j``."""
    for j in range(max(from_j, 0), b - a):
        if r_edges[a + j] == edge:
            return j
    return -1


@njit(cache=True)
def map_body(
    from_j: int,
    r: int,
    o: int,
    world: AheadWorld,
) -> tuple[bool, float, float]:
    """Slot ``o``'s body as ``(found, front, rear)`` in route ``r``'s frame (:func:`map_at` of its body where it is
    this step, on the edges :func:`place` found under it)."""
    routes, s_route, s_front, s_len, s_edge, s_rear, _, _ = world
    front_m = s_front[o]
    return map_at(from_j, r, s_route[o], front_m, front_m - s_len[o], s_edge[o], s_rear[o], routes)


@njit(cache=True)
def map_at(
    from_j: int,
    r: int,
    ro: int,
    front_m: float,
    rear_m: float,
    i_front: int,
    i_rear: int,
    routes: RouteTables,
) -> tuple[bool, float, float]:
    """A body on route ``ro`` — front and rear chainages ``front_m``, ``rear_m`` in its frame, on its route edges
    ``i_rear..i_front`` — as ``(found, front, rear)`` in route ``r``'s frame: only the part on track route ``r``
    uses counts. The frontmost edge under the body that ``r`` uses gives the frame change; if the body's tail
    leaves ``r``'s track behind it (a merge), its rear is raised to where the shared track begins. On a route
    that passes an edge twice (a loop, a turnback path out along the line and back) the body is on the pass
    nearest ahead of route index ``from_j`` (the observer's front edge); ``from_j`` < 0: the last pass
    (:meth:`railsim.engine.routeview.RouteView.map_body`, the same arithmetic)."""
    r_off, r_edges, r_starts, r_keys, r_vals, r_simple = routes
    if ro == r and r_simple[r]:  # one route, no edge twice: the same frame
        return True, front_m, rear_m
    a, b = r_off[r], r_off[r + 1]
    ao = r_off[ro]
    for i in range(i_front, i_rear - 1, -1):  # the frontmost shared edge under the body
        if from_j >= 0 and not r_simple[r]:
            j = _index_from(r_edges, a, b, from_j, r_edges[ao + i])
        else:
            j = _index_of(r_keys, r_vals, a, b, r_edges[ao + i])
        if j < 0:
            continue
        off = r_starts[a + j] - r_starts[ao + i]
        k, jj = i, j
        while k - 1 >= i_rear and jj - 1 >= 0 and r_edges[ao + k - 1] == r_edges[a + jj - 1]:
            k -= 1
            jj -= 1
        rear_here = rear_m + off
        if k > i_rear:  # part of the tail is on track we do not use: it starts where our track is shared
            rear_here = _pymax(rear_here, r_starts[a + jj])
        return True, front_m + off, rear_here
    return False, 0.0, 0.0


@njit(cache=True)
def reported_rears(
    t_s: float,
    ahead: np.ndarray,
    sent_front_m: np.ndarray,
    sent_s: np.ndarray,
    from_j: np.ndarray,
    world: AheadWorld,
) -> tuple[np.ndarray, np.ndarray]:
    """What every slot's train knows from the ground of the train ahead of it (slot ``ahead[k]``, -1: none): the
    rear of that train's body as its last delivered report placed it (front ``sent_front_m[o]`` in its own
    route's frame, sent at ``sent_s[o]``; NaN: no report delivered), mapped into slot ``k``'s frame with
    :func:`map_at` (``from_j[k]``: the observer's front edge pointer), and the age of that report at ``t_s``. The
    tables and columns are :func:`ahead_all`'s (the truth's fronts, rear edges and index by edge are not read).

    Returns ``(rear, age)`` per slot: ``rear`` is ``front - (front - rear)`` of the mapped body (what
    :attr:`controllers.base.PredecessorState.rear_position_m` gives) and ``age`` is ``max(0, t_s - sent)``; both
    NaN where there is no train ahead, no report delivered, or none of the reported body on the observer's track:
    the caller asks :meth:`railsim.engine.knowledge.Knowledge.known_rear_age` there (registrations, where a route
    joins)."""
    routes, s_route, _, s_len, s_edge, _, _, _ = world
    r_off, r_starts, r_simple = routes[0], routes[2], routes[5]
    n = len(ahead)
    rear_out = np.full(n, np.nan)
    age = np.full(n, np.nan)
    for k in range(n):
        o = ahead[k]
        if o < 0:
            continue
        front_m = sent_front_m[o]
        if front_m != front_m:  # NaN: nothing delivered yet
            continue
        rear_m = front_m - s_len[o]
        r = s_route[k]
        ro = s_route[o]
        found, front_here, rear_here = True, front_m, rear_m
        if not (ro == r and r_simple[r]):
            starts = r_starts[r_off[ro] : r_off[ro + 1]]
            i_front = edge_near(starts, front_m, s_edge[o])
            i_rear = edge_near(starts, rear_m, i_front)
            found, front_here, rear_here = map_at(from_j[k], r, ro, front_m, rear_m, i_front, i_rear, routes)
        if found:
            rear_out[k] = front_here - (front_here - rear_here)
            age[k] = _pymax(0.0, t_s - sent_s[o])
    return rear_out, age


@njit(cache=True)
def ahead_one(
    me: int,
    lookahead_m: float,
    world: AheadWorld,
) -> tuple[int, float, float]:
    """The nearest train whose front is ahead of slot ``me``'s front on its route, within ``lookahead_m``:
    ``(slot, front, rear)`` in ``me``'s frame, slot -1 if none. Route edges are walked forward from the one under
    the front; the first edge holding a body ahead decides (the nearest front on it; the first in slot order on a
    tie); a body level with or behind the front is not ahead."""
    routes, s_route, s_front, _, s_edge, _, by_off, by_slot = world
    r_off, r_edges, r_starts = routes[0], routes[1], routes[2]
    r = s_route[me]
    a, b = r_off[r], r_off[r + 1]
    my_front = s_front[me]
    limit = my_front + lookahead_m
    j = s_edge[me]
    while a + j < b and r_starts[a + j] <= limit:
        e = r_edges[a + j]
        best = -1
        best_front = 0.0
        best_rear = 0.0
        for p in range(by_off[e], by_off[e + 1]):
            o = by_slot[p]
            if o == me:
                continue
            found, front, rear = map_body(s_edge[me], r, o, world)
            if not found or front <= my_front:
                continue  # not on our track, or behind us (or level: the one behind is its follower's problem)
            if best < 0 or front < best_front:
                best, best_front, best_rear = o, front, rear
        if best >= 0:
            return best, best_front, best_rear
        j += 1
    return -1, 0.0, 0.0


@njit(cache=True)
def ahead_all(
    lookahead_m: float, world: AheadWorld
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`ahead_one` for every slot: ``(slot ahead or -1, its front, its rear, the gap, the frame offset)`` per
    slot — the gap is its rear less our front, the offset its front (ours) less its own chainage (both 0.0 where
    there is none): :class:`railsim.engine.occupancy.Ahead`'s fields, one subtraction each."""
    s_front = world[2]
    n = len(world[1])
    slot = np.empty(n, np.int64)
    front = np.zeros(n)
    rear = np.zeros(n)
    gap = np.zeros(n)
    offset = np.zeros(n)
    for me in range(n):
        slot[me], front[me], rear[me] = ahead_one(me, lookahead_m, world)
        o = slot[me]
        if o >= 0:
            gap[me] = rear[me] - s_front[me]
            offset[me] = front[me] - s_front[o]
    return slot, front, rear, gap, offset


@njit(cache=True)
def _on_edge(
    o: int,
    edge: int,
    r_off: np.ndarray,
    r_edges: np.ndarray,
    r_starts: np.ndarray,
    r_len: np.ndarray,
    s_route: Any,
    s_front: np.ndarray,
    s_len: np.ndarray,
    s_edge: np.ndarray,
    s_rear: np.ndarray,
) -> tuple[bool, float, float]:
    """The part of slot ``o``'s body on ``edge`` as metres into that edge ``(found, from, to)`` (the first route
    edge under the body that is ``edge``)."""
    ro = s_route[o]
    a, b = r_off[ro], r_off[ro + 1]
    for i in range(s_rear[o], s_edge[o] + 1):
        if r_edges[a + i] != edge:
            continue
        start = r_starts[a + i]
        end = r_starts[a + i + 1] if a + i + 1 < b else r_len[ro]
        lo = _pymax(s_front[o] - s_len[o], start) - start
        hi = _pymin(s_front[o], end) - start
        return True, lo, hi
    return False, 0.0, 0.0


@njit(cache=True)
def facing_one(me: int, from_m: float, lookahead_m: float, world: FacingWorld) -> tuple[int, float, float]:
    """The nearest train on the partner edges of slot ``me``'s route from ``from_m`` on (within ``lookahead_m``)
    whose body lies there at or beyond ``from_m``: ``(slot, near, far)`` in ``me``'s frame (the end of its body
    nearest ``me``'s front, and the other end), slot -1 if none."""
    r_off, r_edges, r_starts, r_len, partner, partner_len, s_route, s_front, s_len, s_edge, s_rear, by_off, by_slot = (
        world
    )
    r = s_route[me]
    a, b = r_off[r], r_off[r + 1]
    j = edge_near(r_starts[a:b], from_m, s_rear[me])
    limit = from_m + lookahead_m
    best = -1
    best_near = 0.0
    best_far = 0.0
    while a + j < b and r_starts[a + j] <= limit:
        edge = partner[r_edges[a + j]]
        if edge >= 0:
            length_m = partner_len[r_edges[a + j]]
            start = r_starts[a + j]
            for p in range(by_off[edge], by_off[edge + 1]):
                o = by_slot[p]
                if o == me:
                    continue
                found, lo, hi = _on_edge(
                    o, edge, r_off, r_edges, r_starts, r_len, s_route, s_front, s_len, s_edge, s_rear
                )
                if not found:
                    continue
                # x into the partner is length - x here (the part on the junction lane after it: at its end)
                near = start + length_m - _pymin(hi, length_m)
                far = start + length_m - _pymin(lo, length_m)
                if far >= from_m and near <= limit and (best < 0 or near < best_near):
                    best, best_near, best_far = o, near, far
        if best >= 0:
            return best, best_near, best_far
        j += 1
    return -1, 0.0, 0.0


@njit(cache=True)
def facing_all(
    q_slot: np.ndarray, q_from: np.ndarray, q_look: np.ndarray, world: FacingWorld
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`facing_one` for every query ``(slot, from, lookahead)``: ``(slot facing or -1, near, far)``."""
    n = len(q_slot)
    slot = np.empty(n, np.int64)
    near = np.zeros(n)
    far = np.zeros(n)
    for q in range(n):
        slot[q], near[q], far[q] = facing_one(q_slot[q], q_from[q], q_look[q], world)
    return slot, near, far


@njit(cache=True)
def facing_hits(
    q_from: np.ndarray, q_look: np.ndarray, world: FacingWorld
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`facing_one` for every slot in order (query ``(slot, q_from[slot], q_look[slot])``), only the slots
    that face a train: ``(slot, the slot facing it, near end)``, ascending by slot (usually empty: no per-train
    row is left for the caller to filter)."""
    n = len(q_from)  # one query per slot
    mine = np.empty(n, np.int64)
    other = np.empty(n, np.int64)
    near = np.empty(n)
    m = 0
    for me in range(n):
        o, near_m, _ = facing_one(me, q_from[me], q_look[me], world)
        if o >= 0:
            mine[m], other[m], near[m] = me, o, near_m
            m += 1
    return mine[:m], other[:m], near[:m]
