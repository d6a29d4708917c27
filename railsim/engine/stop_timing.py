"""When a train standing at a stop may ask for what lies beyond it, and how close to a resource it may aim to halt.

A single-track section, a flat crossing or a set of points beyond a station stop is asked for as a route is set
from a station's starting signal: when the train is about to leave the stop (:func:`stop_before`, within
:data:`SECTION_REQUEST_LEAD_S` of its due departure, :func:`departure_due_s`), not while it dwells. Until the
resource is the train's, its authority ends short of the resource's point, and the ATO's aim at a stop there keeps
:data:`STOP_OVERRUN_ALLOWANCE_M` before the point (:func:`stop_aim_m`), so that an overrun of the aim never puts
the front into the resource; a stop with no such aim in its window is served only with the resource held, which
the train then asks for on its way in. :func:`separation_margin_m` is the room a train keeps behind the train
ahead, counted wherever trains are fitted into a piece of track (between two sections, at a terminus, beyond a
crossing, before a merge). Used by :mod:`railsim.engine.section_requests`, :mod:`railsim.engine.locking` and
:mod:`railsim.engine.authority`.
"""

from __future__ import annotations

from railsim.engine.train import TrainRuntime
from railsim.engine.trips import TripStop

SECTION_REQUEST_LEAD_S = 20.0  # a train standing at its last stop before a section asks this long before it may go
# The ATO's halt may lie this far past the point it stops on: the worst overrun of a stop point measured with the
# ATO as it is (a tram handed from its separation controller to the ATO 39 m before Potsdam's Platz der Einheit/West
# at 6 m/s, still accelerating) is 1.12 m; Dresden's standing starts 1.09 m, Helsinki's 0.89 m. Rounded up to the
# next half metre. An authority carried to a stop (RouteLocks._reach_stop) keeps the ATO's aim this far before an
# unreserved resource's point, so the front never stops inside it.
STOP_OVERRUN_ALLOWANCE_M = 1.5


def departure_due_s(tr: TrainRuntime, stop: TripStop) -> float | None:
    """When the train standing at ``stop`` (its next stop) may leave: its dwell after SUMO registered the halt,
    at an origin not before the planned (and primarily delayed) departure; None while it is not standing there."""
    if not tr.sumo_stopped or tr.dwell_started_s is None:
        return None
    due_s = tr.dwell_started_s + stop.dwell_s
    if stop.is_origin:
        due_s = max(due_s, tr.trip.depart_s + tr.trip.departure_delay_s)
    return due_s


def stop_aim_m(tr: TrainRuntime, stop: TripStop, point_m: float) -> float | None:
    """Where the train may aim to halt at ``stop`` (its mark, or less) with an unreserved resource at ``point_m``
    beyond: at least :data:`STOP_OVERRUN_ALLOWANCE_M` before the point, so that the ATO's overrun of its aim never
    puts the front into the resource. None if that aim would lie short of the stop's window (less than the ATO's
    stopping tolerance inside it): the stop cannot be served without the resource, which the train must then hold
    before it arrives."""
    aim_m = point_m - STOP_OVERRUN_ALLOWANCE_M
    if stop.mark_m <= aim_m:
        return stop.mark_m
    params = getattr(tr.controllers.get("ato"), "params", None)
    tolerance_m = float(getattr(params, "stop_tolerance_m", 0.0))
    if aim_m < stop.window_start_m + tolerance_m - 1e-9:
        return None
    return aim_m


def stop_before(t: float, tr: TrainRuntime, point_m: float, resource_m: float | None = None) -> bool:
    """True while the train still has a station stop to make before ``point_m`` and is not about to leave it
    (within :data:`SECTION_REQUEST_LEAD_S` of its due departure). A single-track section or flat crossing beyond
    that stop is requested only then — as a route is set from a station's starting signal when the train is
    ready — not while the train dwells (a unit waiting out its turnback at a terminal held the Bijin crossing
    for minutes, and the Jurenba trains crossing there stalled). A stop the train cannot serve without the
    resource at ``resource_m`` itself (:func:`stop_aim_m`) does not hold the request back: the train asks for
    the resource on its way in."""
    stops = tr.trip.stops
    for k in range(tr.next_stop, len(stops)):
        stop = stops[k]
        if stop.window_end_m >= point_m:
            return False
        if resource_m is not None and stop.kind == "station" and stop_aim_m(tr, stop, resource_m) is None:
            return False
        if stop.kind != "station":
            continue
        due_s = departure_due_s(tr, stop) if k == tr.next_stop else None
        if due_s is None or t < due_s - SECTION_REQUEST_LEAD_S:
            return True
    return False


def separation_margin_m(tr: TrainRuntime) -> float:
    """The margin the train's moving-block separation controller keeps behind the train ahead (0 without one)."""
    params = getattr(tr.controllers.get("separation"), "params", None)
    return float(getattr(params, "margin_m", 0.0))
