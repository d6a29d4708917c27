"""Ground-truth geometry at junctions: who is ahead of whom, in whose frame (railsim.engine.occupancy/routeview).

Pins the bug found on the Line 3 demo: a train merging from the branch, front already on the trunk and tail
still on the branch leg, was reported as overlapping the main-line train waiting at the merge switch (a false
"collision"). Only track both routes share counts; at a diverge the tail on the shared track still counts.
"""

from __future__ import annotations

from pathlib import Path

import pytest

import network
from railsim.engine.occupancy import Body, Occupancy
from railsim.engine.routeview import RouteView

LINE = Path(__file__).resolve().parents[1] / "data" / "lines" / "mini_y.yaml"
L = 89.4


@pytest.fixture(scope="module")
def bundle():
    return network.build(LINE)  # into the session's world cache (RAILSIM_CACHE, tests/conftest.py)


def _switch_point(route, switch_id: str) -> float:
    return next(s.point_m for s in route.switches if s.switch_id == switch_id)


def test_merging_train_tail_on_other_leg_is_not_ahead_of_waiting_train(bundle) -> None:
    main = RouteView(bundle.route_between("e", "a"))
    branch = RouteView(bundle.route_between("g", "a"))
    p_main = _switch_point(main.route, "c_down")
    p_branch = _switch_point(branch.route, "c_down")
    occ = Occupancy()
    waiting = Body("main", main, p_main - 20.0, L)  # held 20 m before the switch point
    merging = Body("branch", branch, p_branch + 30.0, L)  # front 30 m past the point, tail on the branch leg
    occ.update([waiting, merging])
    ahead = occ.ahead("main")
    assert ahead is not None and ahead.train_id == "branch"
    # the merging train occupies our track only from the switch point on: the gap is the 20 m to the point
    assert ahead.gap_m == pytest.approx(20.0, abs=0.2)
    assert ahead.front_m == pytest.approx(p_main + 30.0, abs=0.2)


def test_diverging_train_tail_on_shared_track_is_ahead_with_exact_gap(bundle) -> None:
    to_e = RouteView(bundle.route_between("a", "e"))
    to_g = RouteView(bundle.route_between("a", "g"))
    p_e = _switch_point(to_e.route, "c_up")
    p_g = _switch_point(to_g.route, "c_up")
    occ = Occupancy()
    leader = Body("lead", to_e, p_e + 50.0, L)  # front on the main leg, tail (39.4 m) still on the trunk
    follower = Body("fol", to_g, p_g - 40.0, L)
    occ.update([leader, follower])
    ahead = occ.ahead("fol")
    assert ahead is not None and ahead.train_id == "lead"
    assert ahead.gap_m == pytest.approx((p_e + 50.0 - L) - (p_e - 40.0), abs=0.2)  # rear − front, exact


def test_trains_on_different_legs_beyond_the_switch_do_not_see_each_other(bundle) -> None:
    to_e = RouteView(bundle.route_between("a", "e"))
    to_g = RouteView(bundle.route_between("a", "g"))
    occ = Occupancy()
    occ.update(
        [
            Body("lead", to_e, _switch_point(to_e.route, "c_up") + 500.0, L),
            Body("fol", to_g, _switch_point(to_g.route, "c_up") + 100.0, L),
        ]
    )
    assert occ.ahead("fol") is None
    assert occ.ahead("lead") is None


def test_remembered_frame_changes_are_computed_ones(bundle) -> None:
    """map_body remembers the frame change per (other route, front edge, rear edge); asked in any order, on
    routes that share track, merge and diverge, every answer is the one a fresh view computes."""
    import random

    pairs = [("e", "a"), ("g", "a"), ("a", "e"), ("a", "g")]
    views = [RouteView(bundle.route_between(*p)) for p in pairs]
    rng = random.Random(5)
    mapped = 0
    for _ in range(3000):
        me, other = rng.choice(views), rng.choice(views)
        front = rng.uniform(-50.0, other.length_m + 50.0)
        length = rng.choice([L, 2 * L + 30.0, 5.0])
        hint = rng.randrange(len(other.edges))
        got = me.map_body(other, front, length, hint)
        fresh = RouteView(me.route).map_body(RouteView(other.route), front, length, hint)
        assert got == fresh, (front, length)
        mapped += got is not None
    assert mapped > 1000  # most bodies land on shared track: the comparison covers real frame changes
