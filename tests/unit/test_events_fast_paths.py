"""The event layer's fast paths against the plain behaviour they stand for, over random programs.

- The clock: :meth:`EventLayer.advance_to` with nothing due only sets the clock, and ends an advance by setting it
  instead of running a marker event. The reference (:class:`_ReferenceLayer`) schedules the marker at every move.
- The radio: a constant-delay channel that loses nothing skips its loss draws, messages due at one time travel as
  one batch, and the engine's reports go in flight channel by channel when no one watches the deliveries. The
  reference (:class:`_ReferenceChannel`) draws, decides and delivers one message after another, each its own light
  delivery, in the order the reports were sent (a train's ground report, then its radio reports).
- Messages of random delays stay with their channel (a :class:`~railsim.engine.events.clock.Source`) until the
  layer has it deliver them: against the reference with delivery times that tie with each other and with timed
  events scheduled before and after them (:func:`_ties_program`).

Each case compares, at every point where something reads a mailbox (between steps, and inside timed events placed
before, at and after the deliveries), every receiver's ``latest`` of every sender, the channels' counters and
statistics, and the order and time of every firing.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from heapq import heappop
from itertools import repeat
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from railsim.engine.events import Channel, DelaySpec, EventLayer, Message, Outage
from railsim.engine.events.clock import TimeoutAt
from railsim.engine.knowledge import Knowledge


class _ReferenceLayer(EventLayer):
    """The clock as it was: a marker event at ``t_s`` on every move, simpy's step to reach it."""

    def advance_to(self, t_s: float) -> None:
        t_s = float(t_s)
        env = self.env
        if not math.isfinite(t_s):
            raise ValueError(f"cannot advance to a non-finite time {t_s!r}")
        if t_s < env.now:
            raise ValueError(f"time goes forward only: asked to advance to {t_s!r} s, now is {env.now!r} s")
        if t_s > env.now:
            TimeoutAt(env, t_s)
        light = self._light
        queue = env._queue
        while True:
            if light and light[0][0] <= t_s:
                head = light[0]
                if queue:
                    q = queue[0]
                    if q[0] < head[0] or (q[0] == head[0] and (q[1], q[2]) < (head[1], head[2])):
                        env.step()
                        continue
                when, _, _, callback, value = heappop(light)
                env._now = when
                callback(value)
            elif queue and queue[0][0] <= t_s:
                env.step()
            else:
                break


class _ReferenceChannel(Channel):
    """A channel sending one message after another: per message its loss uniform and its delay from the stream,
    its fate, and a light delivery of its own that adds the delay to the statistics at once."""

    def draw(
        self, senders: Sequence[str], receivers: str | Sequence[str], payloads: Sequence[Any], t_s: float | None = None
    ) -> list[Message | None]:
        t_s = self._env.now if t_s is None else t_s
        spec, block, out = self.delay, self._block, []
        to = repeat(receivers) if isinstance(receivers, str) else receivers
        for sender, receiver, payload in zip(senders, to, payloads):
            if block is None:
                u, delay_s = self._rng.random(), spec.sample(self._rng)
            elif spec.dist == "uniform":
                u, x = block.take(2)
                delay_s = spec.low_s + (spec.high_s - spec.low_s) * x  # type: ignore[operator]
            else:
                u, delay_s = block.take(1)[0], float(spec.value_s)  # type: ignore[arg-type]
            self._seq += 1
            self.sent += 1
            if any(o.covers(sender, t_s) or o.covers(receiver, t_s) for o in self.outages):
                self.lost_outage += 1
                out.append(None)
            elif u < self.loss_prob:
                self.lost_random += 1
                out.append(None)
            else:
                out.append(Message(sender, receiver, payload, t_s, t_s + delay_s, delay_s, self._seq, self.name))
        return out

    def post(self, msgs: Iterable[Message | None]) -> None:
        for m in msgs:
            if m is not None:
                self._layer.deliver_at(m.delivered_s, self._reference_delivery, m)  # type: ignore[arg-type]

    def _reference_delivery(self, msg: Message) -> None:
        """A delivery: its delay added to the statistics at once, the mailbox kept, the subscribers told."""
        self._delays.add(msg.delay_s)
        box = self._mail.setdefault(msg.receiver, {})
        current = box.get(msg.sender)
        if current is None or (msg.sent_s, msg.seq) > (current.sent_s, current.seq):
            box[msg.sender] = msg
        else:
            self.overtaken += 1
        for callback in self._subscribers:
            callback(msg)


# ---------------------------------------------------------------- the clock
def _clock_program(layer: EventLayer, seed: int) -> list[Any]:
    """A random program of timed calls, periodic calls, processes, light deliveries and advances (including to
    the same time), with callbacks that schedule zero-delay and later consequences; returns what happened."""
    rng = np.random.default_rng(seed)
    seen: list[Any] = []

    def note(label: str) -> None:
        seen.append((label, layer.now_s))
        if rng.random() < 0.3:  # a consequence at the same time (fires in this advance or the next at this time)
            layer.deliver_at(layer.now_s, lambda v: seen.append((v, layer.now_s)), f"{label}/light")
        if rng.random() < 0.2:
            layer.at(layer.now_s + float(rng.choice([0.0, 0.05, 0.1])), lambda _t: note(f"{label}/at"), None)

    def proc(label: str, waits: list[float]) -> Any:
        for w in waits:
            yield layer.env.timeout(w)
            note(label)

    t = layer.now_s
    for step in range(int(rng.integers(20, 60))):
        for k in range(int(rng.integers(0, 4))):
            what = int(rng.integers(0, 5))
            offset = float(rng.choice([0.0, 0.0, 0.05, 0.1, 0.1 + 1e-9, 0.25, 1.0]))
            label = f"s{step}k{k}"
            if what == 0:
                layer.at(t + offset, lambda _t, lab=label: note(lab), "k", label)
            elif what == 1:
                layer.deliver_at(t + offset, lambda v: note(str(v)), label)
            elif what == 2:
                layer.env.process(proc(label, [offset, float(rng.choice([0.0, 0.1, 0.3]))]))
            elif what == 3 and step % 7 == 0:
                handle = layer.every(float(rng.choice([0.1, 0.3])), lambda _t, lab=label: note(lab), start_s=t)
                layer.at(t + 1.0, lambda _t, h=handle: h.cancel(), None)
            else:
                layer.timeout_at(t + offset)  # an event no one waits for
        layer.advance_to(t)  # the engine's second call of a step: what became due at t since
        seen.append(("now", layer.now_s))
        t = t + float(rng.choice([0.0, 0.05, 0.1, 0.1, 0.2, 1.5]))
        layer.advance_to(t)
        seen.append(("now", layer.now_s))
    layer.advance_to(t + 5.0)
    seen.append(("now", layer.now_s))
    seen.append(layer.log.rows())
    return seen


@pytest.mark.parametrize("seed", range(40))
def test_advance_to_fires_as_the_marker_clock_did(seed: int) -> None:
    t0 = float(np.random.default_rng(seed).choice([0.0, 6.144, 28800.0]))
    fast = _clock_program(EventLayer(t0, rng=np.random.default_rng(0)), seed)
    reference = _clock_program(_ReferenceLayer(t0, rng=np.random.default_rng(0)), seed)
    assert fast == reference
    assert sum(1 for x in fast if isinstance(x, tuple) and x[0] != "now") > 10, "too few firings: test too weak"


# ---------------------------------------------------------------- the radio
_TRAINS = [f"T{k}" for k in range(6)]
_RECEIVERS = ["ground", *_TRAINS]


def _snapshot(channels: dict[str, Channel]) -> list[Any]:
    return [(name, r, sorted(ch.inbox(r).items())) for name, ch in channels.items() for r in _RECEIVERS]


def _radio_program(
    layer: EventLayer, channel_type: type[Channel], spec: DelaySpec, loss_prob: float, outages: tuple[Outage, ...],
    watch: bool, seed: int,
) -> list[Any]:  # fmt: skip
    """The engine's pattern of use, with random formations and receivers: advance, timed reads, reports sent by
    :meth:`Knowledge.communicate` (the reference channel: one by one, in the order the engine sends them), advance
    to the same time, reads."""
    rng = np.random.default_rng(seed)
    channels = {
        "t2g": channel_type(layer, "t2g", spec, loss_prob, outages),
        "t2t": channel_type(layer, "t2t", spec, loss_prob, outages),
    }
    seen: list[Any] = []
    if watch:
        for ch in channels.values():
            ch.subscribe(lambda m: seen.append(("delivered", m, layer.now_s)))
    trains = [SimpleNamespace(train_id=tid, last_plan=None, status="running") for tid in _TRAINS]
    of_leader: dict[str, list[str]] = {}
    follows: dict[str, SimpleNamespace] = {}
    extra: dict[str, tuple[str, ...]] = {}
    book = SimpleNamespace(of_leader=of_leader, follower_of=lambda f: follows[f])
    extensions = SimpleNamespace(t2t_receivers=lambda tid: extra.get(tid, ()))
    knowledge = Knowledge(layer, channels, book, extensions)  # type: ignore[arg-type]
    t = layer.now_s
    for step in range(int(rng.integers(30, 80))):
        layer.advance_to(t)
        seen.append(("step", layer.now_s, _snapshot(channels)))
        if step == 25:  # a loss switched on mid-run: the losses then depend on where each stream stands
            for ch in channels.values():
                ch.loss_prob = max(ch.loss_prob, 0.25)
        if rng.random() < 0.3:  # formations come and go; followers insert, run, leave
            of_leader.clear()
            follows.clear()
            for k, leader in enumerate(rng.choice(_TRAINS, size=int(rng.integers(0, 3)), replace=False)):
                follower = trains[int(rng.integers(0, len(trains)))]
                of_leader.setdefault(str(leader), []).append(f"f{step}.{k}")
                follows[f"f{step}.{k}"] = follower
        for tr in trains:
            tr.status = str(rng.choice(["running", "running", "inserting", "arrived"]))
        extra.clear()
        if rng.random() < 0.3:
            extra[str(rng.choice(_TRAINS))] = tuple(str(x) for x in rng.choice(_TRAINS, size=2))
        for _ in range(int(rng.integers(0, 3))):  # reads inside timed events: at the send time, at the delivery
            offset = float(rng.choice([0.0, spec.mean_delay_s, 0.5 * spec.mean_delay_s, 0.05]))
            layer.at(t + offset, lambda ts: seen.append(("event", ts, _snapshot(channels))), None)
        active = [tr for tr in trains if rng.random() < 0.9]
        reports = {tr.train_id: ("r", float(step), 0.0, 0.0, t) for tr in active}
        if channel_type is Channel:
            knowledge.communicate(active, reports)  # type: ignore[arg-type]
        else:  # the reports sent one by one, in the order the engine sends them
            for tr in active:
                report = reports[tr.train_id] + (tr.last_plan,)
                channels["t2g"].send(tr.train_id, "ground", report)
                for f in of_leader.get(tr.train_id, ()):
                    if follows[f].status in ("inserting", "running"):
                        channels["t2t"].send(tr.train_id, follows[f].train_id, report)
                for other in extra.get(tr.train_id, ()):
                    channels["t2t"].send(tr.train_id, other, report)
        layer.at(t, lambda ts: seen.append(("after", ts, _snapshot(channels))), None)  # after the deliveries
        layer.advance_to(t)
        seen.append(("sent", layer.now_s, _snapshot(channels), [ch.stats() for ch in channels.values()]))
        t = t + float(rng.choice([0.1, 0.2, 0.5]))
    layer.advance_to(t + 5.0)
    seen.append(("end", _snapshot(channels), [ch.stats() for ch in channels.values()], layer.log.rows()))
    return seen


_SPECS = [
    DelaySpec("constant", value_s=0.0),
    DelaySpec("constant", value_s=0.1),
    DelaySpec("constant", value_s=0.35),
    DelaySpec("uniform", low_s=0.0, high_s=0.3),
    DelaySpec("normal", mean_s=0.1, std_s=0.1),
]
_FAULTS = [(0.0, ()), (0.3, ()), (0.0, (Outage(1.0, 2.5, frozenset({"T1", "ground"})),)), (0.2, (Outage(0.5, 1.0),))]


@pytest.mark.parametrize("watch", [False, True])
@pytest.mark.parametrize("faults", _FAULTS)
@pytest.mark.parametrize("spec", _SPECS)
def test_radio_delivers_what_one_message_after_another_did(
    spec: DelaySpec, faults: tuple[float, tuple[Outage, ...]], watch: bool
) -> None:
    loss_prob, outages = faults
    for seed in range(3):
        fast = _radio_program(EventLayer(0.0, rng=np.random.default_rng(seed)), Channel, spec, *faults, watch, seed)
        reference = _radio_program(
            _ReferenceLayer(0.0, rng=np.random.default_rng(seed)), _ReferenceChannel, spec, loss_prob, outages, watch,
            seed,
        )  # fmt: skip
        assert fast == reference
        delivered = fast[-1][2][0].delivered + fast[-1][2][1].delivered
        assert delivered > 100 and fast[-1][2][1].delivered > 0, "too few messages: test too weak"


def test_zero_delay_reports_reach_the_mailbox_in_the_same_step_and_not_before() -> None:
    """The engine's ideal radio: read before the second advance, nothing of this step; after it, all of it."""
    layer = EventLayer(0.0, rng=np.random.default_rng(1))
    t2g = Channel(layer, "t2g", DelaySpec("constant", value_s=0.0))
    layer.advance_to(1.0)
    t2g.send_all(["A", "B"], "ground", ["a", "b"])
    assert t2g.inbox("ground") == {}
    layer.advance_to(1.0)
    assert {s: m.payload for s, m in t2g.inbox("ground").items()} == {"A": "a", "B": "b"}
    assert t2g.stats().delivered == 2 and t2g.stats().delay_max_s == 0.0


def test_constant_delay_statistics_are_welfords_one_by_one() -> None:
    """The batch's counting shortcut and the folding of delays in blocks give the running mean/variance of adding
    each delay in turn, bit for bit."""
    from railsim.engine.events.comms import _DelayAccumulator

    rng = np.random.default_rng(7)
    for _ in range(200):
        runs = [(float(rng.choice([0.0, 0.1, 0.3, 1e-300])), int(rng.integers(1, 6))) for _ in range(5)]
        batched, folded, one_by_one = _DelayAccumulator(), _DelayAccumulator(), _DelayAccumulator()
        for d, k in runs:
            batched.add_same(d, k)
            folded.add_all([d] * k + [float(x) for x in rng.uniform(0.0, 0.5, size=int(rng.integers(0, 3)))])
            for _ in range(k):
                one_by_one.add(d)
        assert vars(batched) == vars(one_by_one)
    for _ in range(50):  # random delays folded in blocks: add() in turn, bit for bit
        delays = [float(x) for x in rng.lognormal(-1.6, 0.5, size=int(rng.integers(0, 50)))]
        folded, one_by_one = _DelayAccumulator(), _DelayAccumulator()
        cut = int(rng.integers(0, len(delays) + 1))
        folded.add_all(delays[:cut])
        folded.add_all(delays[cut:])
        for d in delays:
            one_by_one.add(d)
        assert vars(folded) == vars(one_by_one)


def _ties_program(layer: EventLayer, channel_type: type[Channel], watch: bool, seed: int) -> list[Any]:
    """Messages put in flight by hand at times that tie with each other, with timed reads (scheduled before and
    after the messages went in flight, so with smaller and larger event ids) and with a simpy process started at
    the same time (its first event is URGENT), on two channels: every read's snapshot and the final counters."""
    rng = np.random.default_rng(seed)
    channels = {name: channel_type(layer, name, DelaySpec("uniform", low_s=0.0, high_s=1.0)) for name in ("t2g", "t2t")}
    seen: list[Any] = []
    if watch:
        channels["t2t"].subscribe(lambda m: seen.append(("delivered", m.seq, layer.now_s)))

    def read(label: str) -> Any:
        return lambda ts: seen.append((label, ts, _snapshot(channels)))

    def proc(label: str) -> Any:
        seen.append((label, layer.now_s, _snapshot(channels)))
        yield layer.env.timeout(0.0)
        seen.append((label + "/after", layer.now_s, _snapshot(channels)))

    grid = [0.1, 0.2, 0.2, 0.3, 0.5]  # delivery offsets: ties on purpose
    t = 0.0
    for step in range(12):
        for when in rng.choice(grid, size=2):
            layer.at(t + float(when), read(f"early{step}"), None)
        for name, ch in channels.items():
            senders = [str(s) for s in rng.choice(_TRAINS, size=int(rng.integers(1, 6)))]
            offsets = [float(x) for x in rng.choice(grid, size=len(senders))]
            ch.sent += len(senders)
            msgs = []
            for sender, off in zip(senders, offsets):
                ch._seq += 1
                msgs.append(Message(sender, "ground", (name, step), t, t + off, off, ch._seq, name))
            ch.post(msgs)
        for when in rng.choice(grid, size=2):
            layer.at(t + float(when), read(f"late{step}"), None)
        if step % 3 == 0:
            layer.at(t + float(rng.choice(grid)), lambda _ts, s=step: layer.env.process(proc(f"proc{s}")), None)
        t = round(t + float(rng.choice([0.1, 0.2])), 9)
        layer.advance_to(t)
        seen.append(("step", layer.now_s, _snapshot(channels)))
    layer.advance_to(t + 5.0)
    seen.append(("end", _snapshot(channels), [ch.stats() for ch in channels.values()]))
    return seen


@pytest.mark.parametrize("watch", [False, True])
@pytest.mark.parametrize("seed", range(6))
def test_messages_in_flight_take_their_place_among_events_at_the_same_time(watch: bool, seed: int) -> None:
    """A channel's messages in flight (kept by the channel, :class:`railsim.engine.events.clock.Source`) are
    delivered where one light delivery per message would be: ties with each other and with timed events broken
    by event id, a process's first (urgent) event before them."""
    fast = _ties_program(EventLayer(0.0, rng=np.random.default_rng(seed)), Channel, watch, seed)
    reference = _ties_program(_ReferenceLayer(0.0, rng=np.random.default_rng(seed)), _ReferenceChannel, watch, seed)
    assert fast == reference
    assert fast[-1][2][0].overtaken + fast[-1][2][1].overtaken > 0, "no message overtaken: test too weak"
