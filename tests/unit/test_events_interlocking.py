"""Switch interlocking: exclusive locks, no movement while locked, FIFO grants, exact throw times."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from railsim.engine.events import EventLayer, Interlocking, Switch
from railsim.errors import ConfigError


def setup(*switches: Switch) -> tuple[EventLayer, Interlocking]:
    layer = EventLayer(0.0, rng=np.random.default_rng(0))
    ilk = Interlocking(layer)
    for sw in switches or (Switch("S1", throw_time_s=15.0),):
        ilk.add_switch(sw)
    return layer, ilk


def check_log_invariants(layer: EventLayer, throw_time_s: dict[str, float]) -> None:
    """Replay the log: ≤ 1 lock per switch at any time, no throw while locked, grants on the thrown leg."""
    holder: dict[str, int | None] = {}
    position: dict[str, str] = {}
    throwing: dict[str, float | None] = {}
    for row in layer.log.rows():
        sw, d = row["subject"], json.loads(row["detail"])
        if row["kind"] == "throw_start":
            assert holder.get(sw) is None, f"{sw} starts to throw while locked"
            assert throwing.get(sw) is None
            throwing[sw] = row["t_s"]
        elif row["kind"] == "throw_end":
            assert holder.get(sw) is None, f"{sw} moved while locked"
            start = throwing[sw]
            assert start is not None and row["t_s"] == start + throw_time_s[sw]
            throwing[sw] = None
            position[sw] = d["leg"]
        elif row["kind"] == "lock_granted":
            assert holder.get(sw) is None, f"{sw} has two holders"
            assert throwing.get(sw) is None, f"{sw} granted mid-throw"
            assert position.get(sw, "normal") == d["leg"]
            holder[sw] = d["request"]
        elif row["kind"] == "lock_released":
            assert holder.get(sw) == d["request"]
            holder[sw] = None


# ---------------------------------------------------------------- property test
request_strategy = st.tuples(
    st.floats(min_value=0.0, max_value=200.0).map(lambda x: round(x, 1)),  # request time, s
    st.sampled_from(["normal", "reverse"]),
    st.lists(st.floats(min_value=0.0, max_value=40.0), min_size=1, max_size=3),  # member release offsets
    st.integers(min_value=0, max_value=1),  # which switch
)


@settings(max_examples=150, deadline=None)
@given(
    requests=st.lists(request_strategy, min_size=1, max_size=25),
    throw_times=st.tuples(st.floats(min_value=0.0, max_value=30.0), st.floats(min_value=0.0, max_value=30.0)),
    step_s=st.sampled_from([0.1, 0.5, 1.0, 2.0]),
)
def test_random_arrivals_fifo_exclusive_no_starvation(requests, throw_times, step_s) -> None:
    switch_ids = ("S0", "S1")
    throw = dict(zip(switch_ids, throw_times))
    layer, ilk = setup(*(Switch(s, throw_time_s=throw[s]) for s in switch_ids))
    handles = []

    def hold_and_release(req, offsets):
        yield req.granted
        for member, off in zip(req.holder_ids, offsets):
            layer.env.process(release_later(member, req.switch_id, req.granted_s + off))

    def release_later(member, switch_id, t_s):
        yield layer.timeout_at(t_s)
        ilk.release(member, switch_id)

    for i, (t_req, leg, offsets, s) in enumerate(requests):
        holders = tuple(f"T{i}{chr(ord('a') + m)}" for m in range(len(offsets)))
        req = ilk.request(holders, switch_ids[s], leg, t_s=t_req)
        handles.append((req, offsets))
        layer.env.process(hold_and_release(req, offsets))

    # Closed form of strict FIFO: grant = max(requested, switch free) + (throw if the leg changes).
    expected: dict[int, tuple[float, float]] = {}
    for s in switch_ids:
        pos, free_at = "normal", 0.0
        mine = sorted((r.requested_s, r.seq, r, off) for r, off in handles if r.switch_id == s)
        for t_req, _, r, off in mine:
            start = max(t_req, free_at)
            grant = start + throw[s] if r.leg != pos else start
            pos = r.leg
            free_at = grant + max(off)
            expected[r.seq] = (grant, free_at)

    # Engine-like stepping while watching the live state at every step.
    horizon = max(g for _, g in expected.values()) + 1.0
    k = 0
    while layer.now_s < horizon:
        k += 1
        layer.advance_to(k * step_s)
        for s in switch_ids:
            granted = [r for r, _ in handles if r.switch_id == s and ilk.is_granted(r)]
            assert len(granted) <= 1
            if granted:
                assert ilk.position(s) == granted[0].leg and not ilk.is_throwing(s)

    for req, _ in handles:
        assert req.state == "released", "every request is eventually granted and released"
        assert (req.granted_s, req.released_s) == expected[req.seq]
    for s in switch_ids:
        order = [d["request"] for d in (json.loads(r["detail"]) for r in layer.log.rows("lock_granted", s))]
        fifo = [
            r.seq
            for r, _ in sorted(
                ((r, 0) for r, _ in handles if r.switch_id == s), key=lambda x: (x[0].requested_s, x[0].seq)
            )
        ]
        assert order == fifo
        assert ilk.holder(s) is None
    check_log_invariants(layer, throw)


# ---------------------------------------------------------------- unit tests
def test_change_of_leg_costs_exactly_the_throw_time() -> None:
    layer, ilk = setup(Switch("S1", throw_time_s=12.5))
    layer.advance_to(3.0)
    a = ilk.request(("A",), "S1", "reverse")
    layer.advance_to(3.0)  # let the switch react at this instant
    assert ilk.is_throwing("S1") and not ilk.is_granted(a)
    layer.advance_to(15.0)
    assert not ilk.is_granted(a) and ilk.position("S1") == "normal"
    layer.advance_to(15.5)
    assert ilk.is_granted(a) and a.granted_s == 3.0 + 12.5 and ilk.position("S1") == "reverse"
    assert ilk.is_locked_for("A", "S1", "reverse") and not ilk.is_locked_for("A", "S1", "normal")
    # Same leg again after release: no throw, granted at the instant of the request.
    assert ilk.release("A", "S1")
    b = ilk.request(("B",), "S1", "reverse")
    layer.advance_to(15.5)
    assert ilk.is_granted(b) and b.granted_s == 15.5 and ilk.throw_count("S1") == 1


def test_group_lock_is_freed_only_by_the_last_member() -> None:
    layer, ilk = setup()
    group = ilk.request(("L", "F1", "F2"), "S1", "normal")
    other = ilk.request(("X",), "S1", "normal")
    layer.advance_to(1.0)
    assert ilk.holder("S1") == ("L", "F1", "F2")
    assert all(ilk.is_locked_for(t, "S1", "normal") for t in ("L", "F1", "F2"))
    assert not ilk.is_locked_for("X", "S1", "normal")
    assert ilk.release("L", "S1") is False
    assert not ilk.is_locked_for("L", "S1", "normal") and ilk.is_locked_for("F1", "S1", "normal")
    assert ilk.release("L", "S1") is False  # twice: ignored
    assert ilk.release("X", "S1") is False  # not a holder: ignored
    assert layer.log.count("release_ignored") == 2
    layer.advance_to(5.0)
    assert ilk.holder("S1") == ("L", "F1", "F2") and not ilk.is_granted(other)
    assert ilk.release("F1", "S1") is False
    assert ilk.release("F2", "S1") is True
    layer.advance_to(6.0)
    assert group.released_s == 5.0 and other.granted_s == 5.0 and ilk.holder("S1") == ("X",)


def test_cancel_waiting_granted_and_during_throw() -> None:
    layer, ilk = setup(Switch("S1", throw_time_s=10.0))
    a = ilk.request(("A",), "S1", "normal")
    b = ilk.request(("B",), "S1", "reverse")
    c = ilk.request(("C",), "S1", "normal")
    layer.advance_to(1.0)
    ilk.cancel(c)  # waiting: leaves the queue
    assert c.state == "cancelled" and ilk.queue("S1") == (b,)
    ilk.cancel(a)  # granted: frees the lock now
    assert a.state == "cancelled" and a.released_s == 1.0
    layer.advance_to(2.0)  # the switch starts to throw for B at t = 1
    assert ilk.is_throwing("S1")
    d = ilk.request(("D",), "S1", "normal")
    ilk.cancel(b)  # head cancelled mid-throw: the beam finishes its move, then serves D
    layer.advance_to(11.0)
    assert ilk.position("S1") == "reverse" and not ilk.is_granted(d)
    layer.advance_to(30.0)
    assert d.granted_s == 1.0 + 10.0 + 10.0 and ilk.position("S1") == "normal"
    assert b.granted_s is None and c.granted_s is None
    check_log_invariants(layer, {"S1": 10.0})


def test_future_request_and_grant_event_in_a_process() -> None:
    layer, ilk = setup(Switch("S1", throw_time_s=7.0))
    req = ilk.request(("A",), "S1", "reverse", t_s=20.25)
    assert req.state == "scheduled"
    got: list[float] = []

    def train():
        yield req.granted
        got.append(layer.now_s)

    layer.env.process(train())
    for k in range(1, 61):
        layer.advance_to(k * 1.0)
    assert got == [27.25] and req.granted_s == 27.25
    with pytest.raises(ValueError):
        ilk.request(("B",), "S1", "normal", t_s=10.0)


def test_bad_requests_raise() -> None:
    layer, ilk = setup()
    ilk.request(("A",), "S1", "normal")
    with pytest.raises(ValueError, match="already has request"):
        ilk.request(("B", "A"), "S1", "normal")
    with pytest.raises(ValueError):
        ilk.request(("C",), "S1", "sideways")  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        ilk.request((), "S1", "normal")
    with pytest.raises(KeyError):
        ilk.request(("C",), "S9", "normal")
    with pytest.raises(ValueError):
        ilk.add_switch(Switch("S1"))
    with pytest.raises(ConfigError, match="throw_time_s"):
        Switch("S2", throw_time_s=-1.0)


def test_internal_invariant_check_fires_on_corruption() -> None:
    layer, ilk = setup()
    req = ilk.request(("A",), "S1", "normal")
    layer.advance_to(0.0)
    assert ilk.is_granted(req)
    sw = ilk._switches["S1"]
    with pytest.raises(RuntimeError, match="position change while locked"):
        ilk._set_position(sw, "reverse")
    other = ilk.request(("B",), "S1", "normal")
    with pytest.raises(RuntimeError, match="two|while"):
        ilk._grant(sw, other)
