"""Fast look-ups along one route: speed limits, gradient, which edge a chainage is on, and frame changes.

Every position inside the engine is a **route chainage** (metres of the train front from the start of that
train's route, equal to SUMO's odometer plus the depart chainage). Two trains on different routes (an Airport
unit and a Jurenba unit, or an up train entering at a merge) measure in different frames. Where their routes
share a physical track (a SUMO edge), the frames differ by a constant on that edge::

    chainage_in_B = chainage_in_A + (B.edge_start[e] - A.edge_start[e])

:meth:`RouteView.offset_to` gives that constant for the first edge the two routes share at or after a given
point, which is all the engine needs to express "the train ahead" in the observer's frame.

Edge ``i`` of a route covers ``[edge_start_m[i], edge_start_m[i+1])``: the internal junction lane that follows an
edge is counted with it (SUMO's odometer runs through internal lanes, our chainage does too).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field
from typing import Any

from controllers.base import SpeedLimit
from railsim.engine.occupancy_kernel import near_hint

_near_hint = near_hint.py_func  # interpreted: on a tuple, as fast as a method of its own


@dataclass
class RouteView:
    """Pre-computed arrays for one :class:`network.RouteInfo` (built once per route, shared by its trips)."""

    route: Any
    edges: tuple[str, ...] = ()
    edge_start_m: tuple[float, ...] = ()
    edge_index: dict[str, int] = field(default_factory=dict)
    limit_starts: list[float] = field(default_factory=list)
    limits: tuple[SpeedLimit, ...] = ()
    grade_starts: list[float] = field(default_factory=list)
    grades: tuple[tuple[float, float, float], ...] = ()
    line_speed_mps: float = 20.0
    _offsets: dict[tuple[str, int], float | None] = field(default_factory=dict)
    _joins: dict[tuple[str, int], float | None] = field(default_factory=dict)
    _windows: dict[tuple[int, int, bool], tuple[SpeedLimit, ...]] = field(default_factory=dict)
    # (id of the other view, its front edge, its rear edge, the observer's pass) -> (that view, map_body's frame change)
    _frames: dict[tuple[int, int, int, int], tuple[Any, tuple[float, float | None] | None]] = field(
        default_factory=dict
    )
    _well_formed: bool = True  # every restriction ends at or after its start
    simple: bool = True  # no edge twice on the route (a body on it maps into its own frame unchanged)
    _sorted: bool = True  # edge starts never decrease (edge i covers exactly [start i, start i+1): edge_span)

    def __post_init__(self) -> None:
        r = self.route
        self.edges = tuple(r.edges)
        self.edge_start_m = tuple(float(x) for x in r.edge_start_m)
        self.edge_index = {e: i for i, e in enumerate(self.edges)}
        self.simple = len(self.edge_index) == len(self.edges)
        self._sorted = all(a <= b for a, b in zip(self.edge_start_m, self.edge_start_m[1:]))
        lims = sorted((float(a), float(b), float(v)) for a, b, v in r.speed_limits)
        self.limits = tuple(SpeedLimit(a, b, v) for a, b, v in lims)
        self.limit_starts = [a for a, _, _ in lims]
        self._well_formed = all(b >= a for a, b, _ in lims)
        self.line_speed_mps = max((v for _, _, v in lims), default=20.0)
        self.grades = tuple(sorted((float(a), float(b), float(g)) for a, b, g in r.gradients))
        self.grade_starts = [a for a, _, _ in self.grades]

    @property
    def length_m(self) -> float:
        return float(self.route.length_m)

    def edge_at(self, chainage_m: float) -> int:
        """Index of the route edge that covers ``chainage_m`` (clamped to the route)."""
        i = bisect.bisect_right(self.edge_start_m, chainage_m) - 1
        return min(max(i, 0), len(self.edges) - 1)

    def edge_near(self, chainage_m: float, hint: int) -> int:
        """:meth:`edge_at` for a chainage on or next to edge ``hint`` (a train's front one step later, its rear):
        the hint and its neighbours are checked against the edge bounds before any search
        (:func:`railsim.engine.occupancy_kernel.near_hint`, interpreted: the law the compiled occupancy pass uses).
        The result is :meth:`edge_at`'s, whatever the hint (a wrong one only costs the search)."""
        i = _near_hint(self.edge_start_m, chainage_m, hint)
        return i if i >= 0 else self.edge_at(chainage_m)

    def edge_span(self, i: int) -> tuple[float, float]:
        """The chainages :meth:`edge_at` answers ``i`` for: ``[lo, hi)``, open-ended at the route's first and last
        edge (it clamps). Exact for edge starts that never decrease (the route's, measured along it)."""
        starts = self.edge_start_m
        return (starts[i] if i > 0 else -math.inf), (starts[i + 1] if i < len(starts) - 1 else math.inf)

    def gradient_at(self, chainage_m: float) -> float:
        """Gradient [‰] under ``chainage_m`` (0 where the route has no gradient data)."""
        return self.gradient_span(chainage_m)[0]

    def gradient_span(self, chainage_m: float) -> tuple[float, float, float]:
        """:meth:`gradient_at`'s answer and the chainages ``[lo, hi)`` around ``chainage_m`` it holds for (a caller
        whose train is still inside may keep it: :class:`railsim.engine.control.ControlStage`)."""
        starts = self.grade_starts
        i = bisect.bisect_right(starts, chainage_m) - 1
        next_m = starts[i + 1] if i + 1 < len(starts) else math.inf
        if i < 0:
            return 0.0, -math.inf, next_m
        a, b, g = self.grades[i]
        if a <= chainage_m < b:
            return g, a, min(b, next_m)
        return 0.0, max(a, b), next_m

    def limits_ahead(self, from_m: float, to_m: float) -> tuple[SpeedLimit, ...]:
        """Restrictions overlapping ``[from_m, to_m]`` (those below line speed, in order): :meth:`limits_window`."""
        return self.limits_window(from_m, to_m)[0]

    def limits_window(self, from_m: float, to_m: float) -> tuple[tuple[SpeedLimit, ...], float, float, float, float]:
        """:meth:`limits_ahead`'s answer and where it holds: ``(limits, from_lo, from_hi, to_lo, to_hi)`` — the same
        tuple for every ``from_lo <= from_m < from_hi`` and ``to_lo <= to_m < to_hi`` (NaN bounds: for these
        ``from_m``/``to_m`` only).

        The scan starts at ``i``, the last restriction starting at or before ``from_m``, and ends before ``j``, the
        first starting after ``to_m``; of those only the first can end before ``from_m`` (the others start after
        it), so the answer is remembered per ``(i, j, whether limits[i] reaches from_m)``: every train on this
        route asks for one of a few such windows, step after step, and the bounds are where ``i``, ``j`` and that
        test stay the same.
        """
        starts = self.limit_starts
        i = max(bisect.bisect_right(starts, from_m) - 1, 0)
        if not self._well_formed:  # a restriction ending before it starts: no window reasoning
            return self._scan(i, from_m, to_m), math.nan, math.nan, math.nan, math.nan
        if not starts:
            return (), -math.inf, math.inf, -math.inf, math.inf
        j = bisect.bisect_right(starts, to_m)
        end_m = self.limits[i].end_m
        reaches = end_m >= from_m
        key = (i, j, reaches)
        out = self._windows.get(key)
        if out is None:
            out = self._windows[key] = self._scan(i, from_m, to_m)
        n = len(starts)
        from_lo = starts[i] if i > 0 else -math.inf
        from_hi = starts[i + 1] if i + 1 < n else math.inf
        if reaches:  # from_m <= end_m
            from_hi = min(from_hi, math.nextafter(end_m, math.inf))
        else:
            from_lo = max(from_lo, math.nextafter(end_m, math.inf))
        to_lo = starts[j - 1] if j > 0 else -math.inf
        to_hi = starts[j] if j < n else math.inf
        return out, from_lo, from_hi, to_lo, to_hi

    def _scan(self, i: int, from_m: float, to_m: float) -> tuple[SpeedLimit, ...]:
        out = []
        for lim in self.limits[i:]:
            if lim.start_m > to_m:
                break
            if lim.end_m >= from_m and lim.speed_mps < self.line_speed_mps:
                out.append(lim)
        return tuple(out)

    def offset_on_edge(self, other: RouteView, edge_id: str) -> float | None:
        """Constant taking a chainage of *this* route to ``other``'s frame on the shared edge ``edge_id``."""
        i = self.edge_index.get(edge_id)
        j = other.edge_index.get(edge_id)
        if i is None or j is None:
            return None
        return other.edge_start_m[j] - self.edge_start_m[i]

    def map_body(
        self, other: RouteView, front_m: float, length_m: float, hint: int = 0, from_i: int = -1
    ) -> tuple[float, float] | None:
        """A train on ``other``'s route (front at ``front_m`` in its frame) as ``(front, rear)`` in *this* frame.

        Only the part of its body on track this route shares counts. At a merge the other train's front may be on
        our track while its tail is still on the other leg: its rear is then clamped to where the shared track
        begins (the switch), so the tail on the other leg is not "ahead of us". At a diverge the front may already
        be on the other leg while the tail is on our track: the frame change uses the shared edge under the tail,
        and the rear is exact. Returns None if no part of the body is on our route. ``hint``: an edge index of
        ``other`` at or next to the front (:meth:`edge_near`). ``from_i``: this route's edge index under the
        observer's front — on a route that passes an edge twice the body is on the pass nearest ahead of it (as
        :func:`railsim.engine.occupancy_kernel.map_body`); -1: the last pass.
        """
        rear_m = front_m - length_m
        if other is self and self.simple:  # one route, no edge twice: the frame is the same (what _frame gives)
            return front_m, rear_m
        i_front = other.edge_near(front_m, hint)
        i_rear = other.edge_near(rear_m, i_front)
        return _placed(self._frame_of(other, i_front, i_rear, from_i if not self.simple else -1), front_m, rear_m)

    def map_body_memo(
        self,
        memory: dict[Any, BodyFrame],
        key: Any,
        other: RouteView,
        front_m: float,
        length_m: float,
        hint: int = 0,
        from_i: int = -1,
    ) -> tuple[float, float] | None:
        """:meth:`map_body`, the same value, remembering in ``memory[key]`` (the caller's, ``key`` its name for one
        pair of trains) the last frame change used and the chainages it holds for.

        The frame change depends on the body only through the edges under its front and rear (and on the two
        routes and the pass ``from_i``), and the train ahead reports from the same edges step after step. So while
        the reported front and rear stay within the spans of the edges the last call found them on
        (:meth:`edge_span`), the frame change is that call's: four float compares instead of two edge look-ups and a
        frame look-up. The key only decides which memory is consulted: everything the answer depends on is checked,
        so a key shared by two pairs, or a train that changed route, costs a recomputation, never a wrong answer.
        """
        rear_m = front_m - length_m
        if other is self and self.simple:
            return front_m, rear_m
        if self.simple:
            from_i = -1
        last = memory.get(key)
        if (
            last is not None
            and last[0] is self
            and last[1] is other
            and last[2] == from_i
            and last[3] <= front_m < last[4]
            and last[5] <= rear_m < last[6]
        ):
            return _placed(last[7], front_m, rear_m)
        i_front = other.edge_near(front_m, hint)
        i_rear = other.edge_near(rear_m, i_front)
        shape = self._frame_of(other, i_front, i_rear, from_i)
        if other._sorted:
            memory[key] = (self, other, from_i, *other.edge_span(i_front), *other.edge_span(i_rear), shape)
        return _placed(shape, front_m, rear_m)

    def _frame_of(self, other: RouteView, i_front: int, i_rear: int, from_i: int) -> tuple[float, float | None] | None:
        """:meth:`_frame`, remembered per (other route, front edge, rear edge, pass)."""
        key = (id(other), i_front, i_rear, from_i)
        frame = self._frames.get(key)
        if frame is None or frame[0] is not other:
            frame = self._frames[key] = (other, self._frame(other, i_front, i_rear, from_i))
        return frame[1]

    def _frame(
        self, other: RouteView, i_front: int, i_rear: int, from_i: int = -1
    ) -> tuple[float, float | None] | None:
        """How a body on ``other``'s edges ``i_rear..i_front`` maps into this frame: ``(offset, clamp)`` — add the
        offset to its front and rear, and raise the rear to the clamp if given (part of its tail is on track we do
        not use) — or None (no part of it on our route). It depends on the edges only, so :meth:`map_body`
        remembers it per (other route, front edge, rear edge)."""
        for i in range(i_front, i_rear - 1, -1):  # the frontmost shared edge under the body
            j = self.edge_index.get(other.edges[i]) if from_i < 0 else self._index_from(other.edges[i], from_i)
            if j is None:
                continue
            off = self.edge_start_m[j] - other.edge_start_m[i]
            k, jj = i, j
            while k - 1 >= i_rear and jj - 1 >= 0 and other.edges[k - 1] == self.edges[jj - 1]:
                k -= 1
                jj -= 1
            # part of the tail is on track we do not use: it starts where our track is shared
            return off, (self.edge_start_m[jj] if k > i_rear else None)
        return None

    def _index_from(self, edge: str, from_i: int) -> int | None:
        """Index of the first pass of ``edge`` at or after index ``from_i`` on this route (None: none)."""
        for j in range(max(from_i, 0), len(self.edges)):
            if self.edges[j] == edge:
                return j
        return None

    def offset_to(self, other: RouteView, from_chainage_m: float) -> float | None:
        """Constant to add to a chainage in *this* frame to express it in ``other``'s frame.

        Uses the first edge at or after ``from_chainage_m`` (in this route) that ``other`` also uses; ``None`` if
        the routes share no track from there on.
        """
        i0 = self.edge_at(from_chainage_m)
        key = (other.route.id, i0)
        if key in self._offsets:
            return self._offsets[key]
        result = None
        for i in range(i0, len(self.edges)):
            j = other.edge_index.get(self.edges[i])
            if j is not None:
                result = other.edge_start_m[j] - self.edge_start_m[i]
                break
        self._offsets[key] = result
        return result

    def join_m(self, other: RouteView, from_chainage_m: float) -> float | None:
        """Where, in ``other``'s frame, this route first runs on ``other``'s track at or after ``from_chainage_m``
        (the start of that shared edge): a merge, or the start of ``other``'s route; None if never."""
        i0 = self.edge_at(from_chainage_m)
        key = (other.route.id, i0)
        if key not in self._joins:
            j = next((other.edge_index[e] for e in self.edges[i0:] if e in other.edge_index), None)
            self._joins[key] = None if j is None else other.edge_start_m[j]
        return self._joins[key]


def _placed(shape: tuple[float, float | None] | None, front_m: float, rear_m: float) -> tuple[float, float] | None:
    """A body's front and rear moved by a frame change ``(offset, clamp)`` of :meth:`RouteView._frame` (None: none
    of it on the route)."""
    if shape is None:
        return None
    off, clamp_m = shape
    rear_here = rear_m + off
    if clamp_m is not None:
        rear_here = max(rear_here, clamp_m)
    return front_m + off, rear_here


# what map_body_memo remembers of one pair: (observer's view, other's view, pass, front span, rear span, frame change)
BodyFrame = tuple[RouteView, RouteView, int, float, float, float, float, tuple[float, float | None] | None]

_VIEWS: dict[str, RouteView] = {}


def route_view(route: Any) -> RouteView:
    """The (cached) view of ``route``; routes are identified by their id within a process."""
    view = _VIEWS.get(route.id)
    if view is None or view.route is not route:
        view = RouteView(route)
        _VIEWS[route.id] = view
    return view
