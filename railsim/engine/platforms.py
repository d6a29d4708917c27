"""Platform berths: a train does not run into a platform that another train is still occupying.

A platform track is one berth. Moving-block separation alone would let a follower close up to its margin behind
a train standing at a long platform — inside the platform, where it would halt short of its mark and SUMO could
register the stop there (the depot day's unit at T2 was served 106 m short that way). As with a platform's
entry signal, the follower's movement authority ends the overlap (``protection_margin_m``) before the start of
the platform it is heading for while the train directly ahead stands with any part of its body on that platform.
Once that train moves, the follower may run in behind it, kept back by its separation (as a CBTC movement
authority follows a departing train's rear) — the station headway moving block is known for.
Track-vacancy detection sees the truth, so the train ahead is taken from the ground-truth occupancy
(:class:`railsim.engine.occupancy.Ahead`). A follower coupling or coupled behind the train ahead is exempt: it
enters the platform behind its leader on purpose (a formation partner that is not coupled is not). A train already past the berth's limit (it was let in, or it is standing
at the platform) is not stopped again.

**Opt-in** (``interlocking: {platform_berths: true}``), off by default: with it, the Line 3 service day stalls
(a short-turn train waited more than the 300 s stall limit before Liugongli's up platform, where a unit stood
waiting out its turnback); the stall watchdog does not yet count a berth wait as a reason, and turnback units
that wait at a through platform should wait elsewhere first. Both are left for the next session.
"""

from __future__ import annotations

from collections.abc import Callable

from railsim.engine.occupancy import Ahead
from railsim.engine.trips import TripStop


def berth_limit_m(
    front_m: float,
    train_id: str,
    stop: TripStop | None,
    ahead: Ahead | None,
    ahead_standing: bool,
    overlap_m: float,
    coupled_behind: Callable[[str, str], bool],
) -> float | None:
    """The chainage (own route frame) where the train must stop short of an occupied platform, or None.

    ``stop`` is the stop the train is heading for, ``ahead`` the train directly ahead (its front and rear in the
    same frame)."""
    if ahead is None or not ahead_standing or stop is None or stop.kind != "station":
        return None  # a train ahead that is moving draws clear: the follower may run in behind it (separation)
    platform_start_m = stop.window_end_m - stop.platform_m
    limit_m = platform_start_m - overlap_m
    if front_m > limit_m + 1e-6:  # already let in (or standing at the platform)
        return None
    if ahead.rear_m >= stop.window_end_m or ahead.front_m <= platform_start_m:
        return None  # the train ahead is clear of the platform (beyond it, or not on it yet)
    if coupled_behind(train_id, ahead.train_id):
        return None
    return limit_m
