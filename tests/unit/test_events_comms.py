"""Communication channels: exact delivery times, loss, outage windows, staleness, determinism."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from railsim.engine.events import Channel, DelaySpec, EventLayer, Message, Outage
from railsim.errors import ConfigError


def make(seed: int = 0, t0_s: float = 0.0) -> EventLayer:
    return EventLayer(t0_s, rng=np.random.default_rng(seed))


def record_deliveries(layer: EventLayer, channel: Channel) -> list[tuple[Message, float]]:
    seen: list[tuple[Message, float]] = []
    channel.subscribe(lambda m: seen.append((m, layer.now_s)))
    return seen


# ---------------------------------------------------------------- delivery time
def test_constant_delay_delivers_exactly_between_steps() -> None:
    layer = make()
    ch = Channel(layer, "t2t", DelaySpec("constant", value_s=0.37))
    seen = record_deliveries(layer, ch)
    layer.advance_to(1.0)
    sent = ch.send("L", "F", {"v": 10.0})
    assert sent is not None and sent.delivered_s == 1.0 + 0.37
    layer.advance_to(1.2)
    assert ch.latest("F", "L") is None  # still in flight
    assert ch.stats().in_flight == 1
    layer.advance_to(1.5)  # the next engine step; delivery happened at 1.37, between steps
    msg = ch.latest("F", "L")
    assert msg is not None and msg.payload == {"v": 10.0}
    assert (msg.sent_s, msg.delivered_s, msg.delay_s) == (1.0, 1.0 + 0.37, 0.37)
    assert seen == [(msg, 1.0 + 0.37)]  # the simpy clock stood at exactly delivered_s
    assert ch.latest("L", "F") is None  # mailboxes are directional


def test_send_at_a_later_time_is_exact() -> None:
    layer = make()
    ch = Channel(layer, "t2g", DelaySpec("constant", value_s=0.25))
    seen = record_deliveries(layer, ch)
    msg = ch.send("A", "G", 1, t_s=6.144)
    assert msg is not None and msg.sent_s == 6.144
    with pytest.raises(ValueError):
        ch.send("A", "G", 1, t_s=-1.0)
    for k in range(1, 101):
        layer.advance_to(k * 0.1)
    assert seen == [(msg, 6.144 + 0.25)]


def test_staleness_equals_the_delay_with_constant_delay() -> None:
    # Sent every step; at each step the receiver's newest message is the one sent `delay` earlier.
    layer = make()
    dt, delay = 0.2, 0.5
    ch = Channel(layer, "t2t", DelaySpec("constant", value_s=delay))
    send_times: list[float] = []
    for k in range(1, 50):
        t = k * dt
        layer.advance_to(t)
        expected = max((s for s in send_times if s + delay <= t), default=None)
        latest = ch.latest("F", "L")
        assert (latest.sent_s if latest else None) == expected
        ch.send("L", "F", k)
        send_times.append(t)


# ---------------------------------------------------------------- loss
def test_loss_prob_one_loses_everything() -> None:
    layer = make()
    ch = Channel(layer, "t2t", DelaySpec("constant", value_s=0.1), loss_prob=1.0)
    assert all(ch.send("A", "B", i) is None for i in range(500))
    layer.advance_to(10.0)
    s = ch.stats()
    assert (s.sent, s.lost_random, s.delivered, s.in_flight) == (500, 500, 0, 0)
    assert ch.latest("B", "A") is None


def test_loss_frequency_within_binomial_bound() -> None:
    n, p = 20000, 0.3
    layer = make(seed=123)
    ch = Channel(layer, "t2g", DelaySpec("uniform", low_s=0.0, high_s=0.2), loss_prob=p)
    for i in range(n):
        ch.send("T1", "G", i)
    layer.advance_to(1.0)
    s = ch.stats()
    sigma = math.sqrt(n * p * (1 - p))
    assert abs(s.lost_random - n * p) < 5 * sigma
    assert s.delivered == n - s.lost_random and s.in_flight == 0


# ---------------------------------------------------------------- outages
def test_outage_drops_only_inside_window_and_only_listed_trains() -> None:
    layer = make()
    outage = Outage(10.0, 20.0, frozenset({"A"}))
    ch = Channel(layer, "t2t", DelaySpec("constant", value_s=0.05), outages=(outage,))
    fates: list[tuple[float, str, str, bool]] = []
    pairs = [("A", "B"), ("B", "A"), ("B", "C"), ("C", "B")]
    for k in range(0, 301):
        t = k * 0.1
        layer.advance_to(t)
        if k == 100:
            assert ch.active_outages() == (outage,)
        for s, r in pairs:
            fates.append((t, s, r, ch.send(s, r, k) is not None))
    for t, s, r, delivered in fates:
        inside = 10.0 <= t < 20.0 and "A" in (s, r)
        assert delivered == (not inside), (t, s, r)
    stats = ch.stats()
    assert stats.lost_outage == sum(1 for t, s, r, d in fates if not d) == 2 * 100
    assert stats.lost_random == 0
    rows = layer.log.rows()
    assert [(r["kind"], r["t_s"]) for r in rows] == [("outage_start", 10.0), ("outage_end", 20.0)]
    assert ch.active_outages() == ()


def test_outage_for_all_trains_and_common_random_numbers() -> None:
    """Adding an outage changes only the messages inside it: the others keep their exact delays."""

    def run(outages: tuple[Outage, ...]) -> dict[int, float]:
        layer = make(seed=9)
        ch = Channel(layer, "t2t", DelaySpec("normal", mean_s=0.1, std_s=0.05), loss_prob=0.1, outages=outages)
        out: dict[int, float] = {}
        ch.subscribe(lambda m: out.__setitem__(m.payload, m.delivered_s))
        for k in range(1, 200):
            layer.advance_to(k * 0.1)
            ch.send("A", "B", k)
        layer.advance_to(100.0)
        return out

    base = run(())
    faulty = run((Outage(5.0, 8.0, None),))
    inside = {k for k in range(1, 200) if 5.0 <= k * 0.1 < 8.0}
    assert inside and not inside & set(faulty)
    assert {k: v for k, v in base.items() if k not in inside} == faulty


# ---------------------------------------------------------------- ordering and determinism
def test_overtaken_old_message_never_replaces_a_newer_one() -> None:
    layer = make()
    ch = Channel(layer, "t2t", DelaySpec("constant", value_s=1.0))
    old = ch.send("L", "F", "old")  # sent at 0, arrives at 1.0
    layer.advance_to(0.2)
    ch.delay = DelaySpec("constant", value_s=0.1)  # the link improves
    new = ch.send("L", "F", "new")  # sent at 0.2, arrives at 0.3
    layer.advance_to(0.5)
    assert ch.latest("F", "L") == new
    layer.advance_to(2.0)  # the old one arrives late and is ignored
    assert ch.latest("F", "L") == new and old is not None
    assert ch.stats().overtaken == 1 and ch.stats().delivered == 2


def test_latest_is_always_the_newest_sent_under_random_delays() -> None:
    layer = make(seed=4)
    ch = Channel(layer, "t2t", DelaySpec("uniform", low_s=0.0, high_s=1.5), loss_prob=0.2)
    newest: dict[str, float] = {}
    ch.subscribe(lambda m: newest.__setitem__(m.sender, max(newest.get(m.sender, -1.0), m.sent_s)))
    for k in range(1, 400):
        layer.advance_to(k * 0.1)
        for sender in ("L1", "L2"):
            latest = ch.latest("F", sender)
            assert (latest.sent_s if latest else None) == newest.get(sender)
            ch.send(sender, "F", k)
    assert ch.stats().overtaken > 0  # the scenario really did reorder messages


def test_same_seed_same_delivery_sequence() -> None:
    def run(seed: int) -> list[tuple]:
        layer = make(seed)
        ch = Channel(layer, "t2t", DelaySpec("lognormal", mean_s=0.2, std_s=0.15), loss_prob=0.05)
        seen = record_deliveries(layer, ch)
        for k in range(1, 300):
            layer.advance_to(k * 0.1)
            for i in range(5):
                ch.send(f"T{i}", f"T{(i + 1) % 5}", (k, i))
        layer.advance_to(100.0)
        return [(m.sender, m.receiver, m.payload, m.sent_s, m.delivered_s, t) for m, t in seen]

    a, b, c = run(11), run(11), run(12)
    assert a == b
    assert a != c
    assert [x[4] for x in a] == sorted(x[4] for x in a)  # delivered in time order


# ---------------------------------------------------------------- delay distributions
@pytest.mark.parametrize(
    "spec, mean, std",
    [
        (DelaySpec("constant", value_s=0.2), 0.2, 0.0),
        (DelaySpec("uniform", low_s=0.1, high_s=0.5), 0.3, 0.4 / math.sqrt(12)),
        (DelaySpec("exponential", mean_s=0.08), 0.08, 0.08),
        (DelaySpec("lognormal", mean_s=0.1, std_s=0.05), 0.1, 0.05),
        (DelaySpec("normal", mean_s=0.5, std_s=0.05), 0.5, 0.05),  # truncation negligible at 10 sigma
        # mean 0: half-normal after rejection, mean σ√(2/π), std σ√(1 − 2/π)
        (DelaySpec("normal", mean_s=0.0, std_s=0.1), 0.1 * math.sqrt(2 / math.pi), 0.1 * math.sqrt(1 - 2 / math.pi)),
    ],
)
def test_delay_samples_match_closed_form_and_are_non_negative(spec: DelaySpec, mean: float, std: float) -> None:
    rng = np.random.default_rng(2024)
    x = np.array([spec.sample(rng) for _ in range(20000)])
    assert (x >= 0.0).all()
    assert abs(x.mean() - mean) <= 5 * std / math.sqrt(len(x)) + 1e-12
    assert x.std() == pytest.approx(std, rel=0.05, abs=1e-12)


def test_bad_specs_are_config_errors() -> None:
    with pytest.raises(ConfigError, match="delay.dist"):
        DelaySpec("gamma", mean_s=1.0)  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="delay.std_s"):
        DelaySpec("normal", mean_s=0.1)
    with pytest.raises(ConfigError, match="delay.mean_s"):
        DelaySpec("normal", mean_s=-0.1, std_s=0.1)
    with pytest.raises(ConfigError, match="delay.value_s: not a parameter"):
        DelaySpec("uniform", low_s=0.0, high_s=1.0, value_s=3.0)
    with pytest.raises(ConfigError, match="high_s"):
        DelaySpec("uniform", low_s=1.0, high_s=0.5)
    err = pytest.raises(
        ConfigError, DelaySpec.from_mapping, {"dist": "normal", "mean_s": 0.1}, "s.yaml", "comms.t2t.delay"
    )
    assert str(err.value).startswith("s.yaml: comms.t2t.delay.std_s: ")
    assert DelaySpec.from_mapping({"dist": "constant", "value_s": 0.1}) == DelaySpec("constant", value_s=0.1)
    layer = make()
    with pytest.raises(ConfigError, match="loss_prob"):
        Channel(layer, "t2t", DelaySpec(value_s=0.1), loss_prob=1.5)
    with pytest.raises(ConfigError, match="comms.name"):
        Channel(layer, "wifi", DelaySpec(value_s=0.1))
    with pytest.raises(ConfigError, match="outages"):
        Outage(5.0, 5.0)


# ---------------------------------------------------------------- block draws and light deliveries
@pytest.mark.parametrize("spec", [DelaySpec("uniform", low_s=0.1, high_s=0.5), DelaySpec("constant", value_s=0.2)])
def test_block_draws_are_the_per_message_draws(spec: DelaySpec) -> None:
    """Constant and uniform channels read their stream in blocks; every message still gets the loss uniform and
    the delay the per-message draws (``rng.random()`` then ``spec.sample(rng)``) give, across block ends."""
    layer = make(seed=11)
    ch = Channel(layer, "t2g", spec, loss_prob=0.3)
    reference = EventLayer(0.0, rng=np.random.default_rng(11)).spawn_rng()  # the channel's own child stream
    for k in range(5000):  # > one block of 4096 doubles
        msg = ch.send(f"T{k % 7}", "ground", k)
        u = reference.random()
        delay_s = spec.sample(reference)
        assert (msg is None) == (u < 0.3)
        if msg is not None:
            assert msg.delay_s == delay_s


def test_light_deliveries_keep_simpy_order_with_other_events() -> None:
    """A message and a simpy timer due at the same time run in the order they were scheduled, as two simpy
    timeouts would; the clock stands at the delivery time inside the delivery."""
    layer = make()
    ch = Channel(layer, "t2t", DelaySpec("constant", value_s=0.5))
    order: list[tuple[str, float]] = []
    ch.subscribe(lambda m: order.append((f"msg{m.payload}", layer.now_s)))
    layer.timeout_at(0.5).callbacks.append(lambda _e: order.append(("timer_before", layer.now_s)))
    ch.send("L", "F", 1)
    layer.timeout_at(0.5).callbacks.append(lambda _e: order.append(("timer_after", layer.now_s)))
    ch.send("L", "F", 2, t_s=0.25)  # due at 0.75, after the next step's start
    layer.advance_to(0.6)
    assert order == [("timer_before", 0.5), ("msg1", 0.5), ("timer_after", 0.5)]
    assert layer.now_s == 0.6
    layer.advance_to(1.0)
    assert order[-1] == ("msg2", 0.75) and layer.now_s == 1.0


# ---------------------------------------------------------------- sending many at once
@pytest.mark.parametrize(
    "spec",
    [
        DelaySpec("uniform", low_s=0.1, high_s=0.5),
        DelaySpec("constant", value_s=0.2),
        DelaySpec("normal", mean_s=0.2, std_s=0.1),
        DelaySpec("exponential", mean_s=0.1),
    ],
)
def test_send_all_is_send_one_by_one(spec: DelaySpec) -> None:
    """Batches of every size (none, one, across block ends) give the messages, counters and deliveries of sending
    the same messages one by one, and each message the draws of the channel's stream read one by one."""
    outages = [Outage(3.0, 5.0, frozenset({"T2"})), Outage(8.0, 9.0)]
    runs = []
    for batched in (False, True):
        layer = make(seed=5)
        ch = Channel(layer, "t2g", spec, loss_prob=0.2, outages=outages)
        seen = record_deliveries(layer, ch)
        reference = EventLayer(0.0, rng=np.random.default_rng(5)).spawn_rng()  # the channel's stream
        sizes = np.random.default_rng(1)
        sent: list[Message | None] = []
        for step in range(40):
            t = 0.25 * step
            layer.advance_to(t)
            n = int(sizes.choice([0, 1, 2, 7, 300, 5000], p=[0.2, 0.2, 0.2, 0.2, 0.15, 0.05]))
            senders = [f"T{(len(sent) + j) % 5}" for j in range(n)]
            payloads = list(range(len(sent), len(sent) + n))
            if batched:
                msgs = ch.send_all(senders, "ground", payloads)
            else:
                msgs = [ch.send(s, "ground", p) for s, p in zip(senders, payloads)]
            for sender, msg in zip(senders, msgs):
                u, delay_s = reference.random(), spec.sample(reference)
                cut_off = any(o.covers(sender, t) or o.covers("ground", t) for o in outages)
                assert (msg is None) == (cut_off or u < 0.2)
                assert msg is None or msg.delay_s == delay_s
            sent += msgs
        layer.advance_to(20.0)
        runs.append((repr(sent), repr(seen), ch.stats()))
    assert runs[0] == runs[1]
    stats = runs[1][2]
    assert stats.lost_outage > 0 and stats.lost_random > 0 and stats.sent > 4 * 4096  # batches across block ends


def test_reports_go_in_flight_in_the_order_sent() -> None:
    """Knowledge.communicate draws each channel's reports at once, yet puts them in flight as sending them one by
    one did (a train's ground report, then its reports to its followers and an extension's receivers, train after
    train): with equal delays on both channels every delivery comes in that order, with the same fates."""
    from railsim.engine.knowledge import Knowledge  # the engine's sender, on stand-in trains

    formations = {"T1": ["f1"], "T3": ["f3a", "f3b"]}
    follows = {"f1": "T2", "f3a": "T4", "f3b": "T0"}
    extra = {"T4": ("T1", "T2"), "T0": ("T3",)}
    trains = [SimpleNamespace(train_id=f"T{k}", last_plan=None, status="running") for k in range(5)]
    book = SimpleNamespace(
        of_leader=formations, follower_of=lambda f: next(tr for tr in trains if tr.train_id == follows[f])
    )
    extensions = SimpleNamespace(t2t_receivers=lambda train_id: extra.get(train_id, ()))

    def run(one_by_one: bool) -> tuple[list[str], int]:
        layer = make(seed=3)
        t2g = Channel(layer, "t2g", DelaySpec("constant", value_s=0.3), loss_prob=0.2)
        t2t = Channel(layer, "t2t", DelaySpec("constant", value_s=0.3), loss_prob=0.2)
        order: list[str] = []
        for ch in (t2g, t2t):
            ch.subscribe(lambda m: order.append(f"{m.channel} {m.sender}->{m.receiver} {m.payload} {layer.now_s}"))
        kn = Knowledge(layer, {"t2g": t2g, "t2t": t2t}, book, extensions)  # type: ignore[arg-type]
        for step in range(30):
            t = 0.5 * step
            layer.advance_to(t)
            reports = {tr.train_id: ("r", float(step), 0.0, 0.0, t) for tr in trains}
            if not one_by_one:
                kn.communicate(trains, reports)  # type: ignore[arg-type]
                continue
            for tr in trains:  # as each report was sent one by one
                report = reports[tr.train_id] + (tr.last_plan,)
                t2g.send(tr.train_id, "ground", report)
                for f in formations.get(tr.train_id, ()):
                    t2t.send(tr.train_id, follows[f], report)
                for other in extra.get(tr.train_id, ()):
                    t2t.send(tr.train_id, other, report)
        layer.advance_to(20.0)
        return order, next(layer.env._eid)

    batched, reference = run(False), run(True)
    assert batched == reference
    channels = [line.split()[0] for line in reference[0]]
    assert "t2g" in channels[channels.index("t2t") :], "no ground report after a train-to-train one: test too weak"
