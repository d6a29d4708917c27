"""Communication channels: radio messages that arrive late, or not at all.

A follower in a virtually coupled formation knows its leader only through messages (spec 003 §3.5: V2V
between adjacent vehicles, V2I to the ground; link quality enters as latency and packet loss). A
:class:`Channel` models one such medium — ``'t2t'`` (train-to-train) or ``'t2g'`` (train-to-ground) — and
is the one place where delay, loss and outages happen, so the controllers see exactly what a receiver knew.

What happens in time
--------------------
``send(sender, receiver, payload)`` at time ``t`` (now, or a given ``t_s ≥ now``):

1. the message is **lost** if the sender or the receiver is inside an :class:`Outage` window at ``t``
   (counted ``lost_outage``), otherwise with probability ``loss_prob`` (``lost_random``);
2. otherwise a delay ``d`` is drawn from the channel's :class:`DelaySpec` and the event layer delivers the
   message at exactly ``t + d`` — between SUMO steps if that is when it falls — into the receiver's mailbox
   (a light delivery, :meth:`EventLayer.deliver_at`: in simpy's order, without a simpy event per message).

``send_all(senders, receiver(s), payloads)`` is that many sends in one call (the engine's ground reports of every
train, each step): the same draws, counters and deliveries. It is :meth:`Channel.draw` — each message's fate, drawn
from the channel's stream — then :meth:`Channel.post` — the survivors in flight, in order; a sender using two
channels draws each channel's messages at once and posts them in the order it sent them, so the light deliveries
take their event ids (the tie-break of equal times) exactly as one send after another would.

The radio every step costs little per message. Messages due at one time — every message of a constant delay
sent at once, the zero-delay "perfect communication" included — take consecutive event ids, so they travel as one
light delivery that delivers them in turn; messages of random delays stay with the channel, each batch sorted by
(time, event id), and the event layer has them delivered, all that are due before the next other thing, in one
call (:mod:`railsim.engine.events.in_flight`); a constant-delay channel that loses nothing (no ``loss_prob``, no
outage) moves its stream past the loss uniforms without reading them (they could not lose a message); the delay
statistics are folded in delivery order, a block at a time and when read (:meth:`Channel.stats`). The mailboxes, the
counters, the statistics and the streams are those of one message after another
(``tests/unit/test_events_fast_paths.py`` runs both).

``latest(receiver, sender)`` is the newest-**sent** message delivered so far. With random delays a message
can overtake an older one; the older one, arriving later, is counted ``overtaken`` and does not replace the
newer one (a receiver keeps the freshest information it has). If nothing newer has arrived, the receiver
keeps acting on the old message: that staleness (``now − sent_s``) is the point of the model.

Readings and choices
--------------------
- Outage windows are half-open, ``start_s ≤ t < end_s``, judged at the **send** time; ``trains=None``
  means every train. A message already in flight when an outage starts is still delivered.
- Outage start and end are logged (kinds ``outage_start``/``outage_end``, subject = channel name) by simpy
  processes at their exact times. Individual messages are not logged (about a hundred per step): the
  channel keeps counters instead (:meth:`Channel.stats`).
- Common random numbers: every send draws one uniform (loss) and one delay, lost or not, from the
  channel's own child stream of the scenario generator. Adding an outage, or changing ``loss_prob``,
  therefore leaves the fate and delay of every other message unchanged — runs differ only where the fault
  acts. For ``constant`` and ``uniform`` delays the stream is read in blocks (:class:`_UniformBlock`: one
  numpy call per few thousand messages instead of two per message); a uniform delay is
  ``low + (high − low)·U`` with ``U`` the stream's next double, which is what ``Generator.uniform`` computes,
  so the draws are the same numbers in the same order (``tests/unit/test_events_comms.py`` checks it).
- Delays never come out negative. ``normal`` is truncated at 0 by **rejection** (redraw), not by clipping,
  so there is no spike of zero-delay messages; the realised mean is then above ``mean_s`` when ``std_s`` is
  not small against it (``mean_s ≥ 0`` is required, so at least half the draws are accepted). The other
  distributions are non-negative by construction.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator, Iterable, Sequence
from dataclasses import dataclass
from itertools import repeat
from typing import Any, Literal, NamedTuple

import numpy as np
import simpy

from railsim.engine.events.clock import EventLayer
from railsim.engine.events.in_flight import InFlight
from railsim.errors import ConfigError

DelayDist = Literal["constant", "uniform", "normal", "lognormal", "exponential"]

# Which parameters each distribution takes (all in seconds).
_DELAY_PARAMS: dict[str, tuple[str, ...]] = {
    "constant": ("value_s",),
    "uniform": ("low_s", "high_s"),
    "normal": ("mean_s", "std_s"),
    "lognormal": ("mean_s", "std_s"),
    "exponential": ("mean_s",),
}

_MAX_REDRAWS = 64  # P(64 rejections) ≤ 2^-64 because mean_s ≥ 0
_BLOCK = 4096  # doubles read from a channel's stream at a time (constant and uniform delays)


_SCENARIO_KEYS = {"value": "value_s", "low": "low_s", "high": "high_s", "mean": "mean_s", "sd": "std_s"}


@dataclass(frozen=True)
class DelaySpec:
    """A message delay distribution; every parameter in seconds.

    - ``DelaySpec("constant", value_s=0.05)``
    - ``DelaySpec("uniform", low_s=0.02, high_s=0.1)``
    - ``DelaySpec("normal", mean_s=0.1, std_s=0.03)`` — truncated at 0 by rejection
    - ``DelaySpec("lognormal", mean_s=0.1, std_s=0.05)`` — mean and std *of the delay* (converted to the
      log-space μ, σ: σ² = ln(1 + std²/mean²), μ = ln mean − σ²/2)
    - ``DelaySpec("exponential", mean_s=0.05)``
    """

    dist: DelayDist = "constant"
    value_s: float | None = None
    low_s: float | None = None
    high_s: float | None = None
    mean_s: float | None = None
    std_s: float | None = None

    def __post_init__(self) -> None:
        if self.dist not in _DELAY_PARAMS:
            raise ConfigError(None, "delay.dist", f"expected one of {sorted(_DELAY_PARAMS)}, got {self.dist!r}")
        needed = _DELAY_PARAMS[self.dist]
        for name in ("value_s", "low_s", "high_s", "mean_s", "std_s"):
            value = getattr(self, name)
            if name not in needed:
                if value is not None:
                    raise ConfigError(None, f"delay.{name}", f"not a parameter of a {self.dist} delay (takes {needed})")
                continue
            if value is None:
                raise ConfigError(None, f"delay.{name}", f"a {self.dist} delay needs {needed}")
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
                raise ConfigError(None, f"delay.{name}", f"expected a finite number >= 0 s, got {value!r}")
        if self.dist == "uniform" and self.high_s < self.low_s:  # type: ignore[operator]
            raise ConfigError(None, "delay.high_s", f"expected >= low_s = {self.low_s}, got {self.high_s}")
        if self.dist == "lognormal" and self.mean_s == 0.0:
            raise ConfigError(None, "delay.mean_s", "a lognormal delay needs mean_s > 0")

    @classmethod
    def from_scenario(cls, delay: Any, source: str | None = None, field_path: str = "delay") -> DelaySpec:
        """Build from a scenario's delay spec (``dist`` + ``value|low,high|mean,sd`` in seconds)."""
        data: dict[str, Any] = {"dist": delay.dist}
        for key, value in dict(delay.params).items():
            data[_SCENARIO_KEYS.get(str(key), str(key))] = value
        return cls.from_mapping(data, source, field_path)

    @classmethod
    def from_mapping(cls, data: dict[str, Any], source: str | None = None, field_path: str = "delay") -> DelaySpec:
        """Build from a scenario mapping such as ``{dist: normal, mean_s: 0.1, std_s: 0.02}``."""
        if not isinstance(data, dict):
            raise ConfigError(source, field_path, f"expected a mapping with 'dist', got {data!r}")
        unknown = set(data) - {"dist", "value_s", "low_s", "high_s", "mean_s", "std_s"}
        if unknown:
            raise ConfigError(source, f"{field_path}.{sorted(unknown)[0]}", "unknown delay parameter")
        try:
            return cls(**data)
        except ConfigError as err:
            sub = (err.field or "delay").removeprefix("delay")
            raise ConfigError(source, f"{field_path}{sub}", err.message) from None

    @property
    def mean_delay_s(self) -> float:
        """Mean of the *untruncated* distribution (exact for all but a wide ``normal``)."""
        if self.dist == "constant":
            return float(self.value_s)  # type: ignore[arg-type]
        if self.dist == "uniform":
            return 0.5 * (self.low_s + self.high_s)  # type: ignore[operator]
        return float(self.mean_s)  # type: ignore[arg-type]

    def sample(self, rng: np.random.Generator) -> float:
        """One delay in seconds, never negative."""
        dist = self.dist
        if dist == "constant":
            return float(self.value_s)  # type: ignore[arg-type]
        if dist == "uniform":
            return float(rng.uniform(self.low_s, self.high_s))  # type: ignore[arg-type]
        if dist == "exponential":
            return float(rng.exponential(self.mean_s)) if self.mean_s else 0.0
        if dist == "lognormal":
            m, s = self.mean_s, self.std_s
            sigma2 = math.log1p((s / m) ** 2)  # type: ignore[operator]
            return float(rng.lognormal(math.log(m) - 0.5 * sigma2, math.sqrt(sigma2)))  # type: ignore[arg-type]
        # normal, truncated at zero by rejection
        for _ in range(_MAX_REDRAWS):
            d = float(rng.normal(self.mean_s, self.std_s))  # type: ignore[arg-type]
            if d >= 0.0:
                return d
        return 0.0


class _UniformBlock:
    """A channel's stream read ahead in blocks: :meth:`take` gives the stream's next ``random()`` doubles.

    The read-ahead is invisible because the stream belongs to this channel alone (:meth:`EventLayer.spawn_rng`).
    """

    __slots__ = ("_rng", "_buf", "_i")

    def __init__(self, rng: np.random.Generator) -> None:
        self._rng = rng
        self._buf: list[float] = []
        self._i = 0

    def take(self, k: int) -> list[float]:
        """The stream's next ``k`` doubles (a new block is read when the last one is used up, as one by one)."""
        i = self._i
        out = self._buf[i : i + k]
        self._i = i + len(out)
        while len(out) < k:
            self._buf = self._rng.random(_BLOCK).tolist()
            more = min(k - len(out), _BLOCK)
            out += self._buf[:more]
            self._i = more
        return out

    def skip(self, k: int) -> None:
        """Move past the stream's next ``k`` doubles without reading them: :meth:`take` then goes on as after
        ``take(k)``."""
        i = self._i + k
        while i > len(self._buf):  # as take: a new block once the last one is used up
            i -= len(self._buf)
            self._buf = self._rng.random(_BLOCK).tolist()
        self._i = i


@dataclass(frozen=True)
class Outage:
    """A communication blackout ``start_s ≤ t < end_s`` for ``trains`` (None = all trains)."""

    start_s: float
    end_s: float
    trains: frozenset[str] | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.start_s) and math.isfinite(self.end_s) and self.end_s > self.start_s):
            raise ConfigError(None, "outages", f"expected finite start_s < end_s, got {self.start_s}..{self.end_s}")
        if self.trains is not None and not isinstance(self.trains, frozenset):
            if isinstance(self.trains, str):
                raise ConfigError(None, "outages.trains", f"expected a list of train ids, got {self.trains!r}")
            object.__setattr__(self, "trains", frozenset(self.trains))

    def covers(self, train_id: str, t_s: float) -> bool:
        """True if ``train_id`` cannot communicate at ``t_s``."""
        return self.start_s <= t_s < self.end_s and (self.trains is None or train_id in self.trains)


class Message(NamedTuple):
    """A delivered (or in-flight) message; ``delivered_s = sent_s + drawn delay``, exactly. (Immutable; a named
    tuple rather than a frozen dataclass because one is built per train, step and channel.)"""

    sender: str
    receiver: str
    payload: Any
    sent_s: float
    delivered_s: float
    delay_s: float  # the drawn delay (delivered_s − sent_s up to rounding)
    seq: int  # send order on its channel; breaks ties between equal sent_s
    channel: str


@dataclass(frozen=True)
class ChannelStats:
    """Counters of one channel. Delay statistics (population std) are over delivered messages, overtaken
    ones included; ``in_flight`` = sent − lost − delivered."""

    name: str
    sent: int
    lost_random: int
    lost_outage: int
    delivered: int
    overtaken: int
    in_flight: int
    delay_mean_s: float | None
    delay_std_s: float | None
    delay_min_s: float | None
    delay_max_s: float | None


@dataclass(eq=False)
class _DelayAccumulator:
    # Welford's running mean/variance: no cancellation for near-constant delays.
    n: int = 0
    mean: float = 0.0
    m2: float = 0.0
    lo: float = math.inf
    hi: float = -math.inf

    def add(self, d: float) -> None:
        self.n += 1
        delta = d - self.mean
        self.mean += delta / self.n
        self.m2 += delta * (d - self.mean)
        if d < self.lo:
            self.lo = d
        if d > self.hi:
            self.hi = d

    def add_all(self, delays: list[float]) -> None:
        """``add(d)`` for each delay in turn: the same operations in the same order (so the same doubles), in
        local variables."""
        n, mean, m2, lo, hi = self.n, self.mean, self.m2, self.lo, self.hi
        for d in delays:
            n += 1
            delta = d - mean
            mean += delta / n
            m2 += delta * (d - mean)
            if d < lo:
                lo = d
            if d > hi:
                hi = d
        self.n, self.mean, self.m2, self.lo, self.hi = n, mean, m2, lo, hi

    def add_same(self, d: float, k: int) -> None:
        """``add(d)`` ``k`` times. Once every delay so far equals ``d`` (the mean is ``d``, nothing spread), each
        ``add(d)`` only counts: ``delta`` is 0, so the mean and ``m2`` stay as they are."""
        while k > 0 and not (self.n and self.mean == d and self.m2 == 0.0):
            self.add(d)
            k -= 1
        if k > 0:
            self.n += k
            if d < self.lo:
                self.lo = d
            if d > self.hi:
                self.hi = d


CHANNEL_NAMES = ("t2t", "t2g")

_new = tuple.__new__


class Channel:
    """One communication medium with a delay distribution, random loss and outage windows."""

    def __init__(
        self,
        layer: EventLayer,
        name: str,
        delay: DelaySpec,
        loss_prob: float = 0.0,
        outages: Iterable[Outage] = (),
    ) -> None:
        if name not in CHANNEL_NAMES:
            raise ConfigError(None, "comms.name", f"expected one of {CHANNEL_NAMES}, got {name!r}")
        if isinstance(loss_prob, bool) or not isinstance(loss_prob, (int, float)) or not 0.0 <= loss_prob <= 1.0:
            raise ConfigError(None, f"comms.{name}.loss_prob", f"expected a probability in [0, 1], got {loss_prob!r}")
        self._layer = layer
        self._env = layer.env
        # messages of differing delivery times, delivered when the layer asks (registered at the first of them)
        self._in_flight = InFlight(self._deliver_quietly, self._deliver_at)
        self._source = False
        self.name = name
        self.delay = delay
        self.loss_prob = float(loss_prob)
        self.outages: tuple[Outage, ...] = tuple(outages)
        self._rng = layer.spawn_rng()
        # constant and uniform delays: the loss uniform and the delay come from the stream read in blocks
        self._block = _UniformBlock(self._rng) if delay.dist in ("constant", "uniform") else None
        self._mail: dict[str, dict[str, Message]] = {}
        self._subscribers: list[Callable[[Message], object]] = []
        self._active_outages: list[Outage] = []
        self._delays = _DelayAccumulator()
        self._unfolded: list[float] = []  # delays delivered, not yet in _delays (folded in order: _fold_delays)
        self._seq = 0
        self.sent = 0
        self.lost_random = 0
        self.lost_outage = 0
        self.overtaken = 0
        for outage in self.outages:
            if outage.end_s > layer.now_s:
                self._env.process(self._outage_window(outage))

    # ------------------------------------------------------------------ sending
    def send(self, sender: str, receiver: str, payload: Any, t_s: float | None = None) -> Message | None:
        """Send ``payload`` now (or at ``t_s ≥ now``). Returns the in-flight message, or None if lost."""
        msg = self.draw((sender,), receiver, (payload,), t_s)[0]
        self.post((msg,))
        return msg

    def send_all(
        self, senders: Sequence[str], receivers: str | Sequence[str], payloads: Sequence[Any], t_s: float | None = None
    ) -> list[Message | None]:
        """:meth:`send` for each sender, receiver (one for all, if a string) and payload in turn: the same draws,
        messages and deliveries as that many calls, in that order."""
        msgs = self.draw(senders, receivers, payloads, t_s)
        self.post(msgs)
        return msgs

    def draw(
        self, senders: Sequence[str], receivers: str | Sequence[str], payloads: Sequence[Any], t_s: float | None = None
    ) -> list[Message | None]:
        """The fate of each message :meth:`send_all` would send — the in-flight message, or None if lost — with the
        draws and counters of sending it, but not yet in flight (:meth:`post`). Two channels sending in turn draw
        each from its own stream, so a caller may draw each channel's messages at once and post them in the order
        they were sent."""
        now = self._env.now
        if t_s is None:
            t_s = now
        elif not t_s >= now:  # also rejects NaN
            raise ValueError(f"channel {self.name}: cannot send at {t_s!r} s, now is {now!r} s")
        n = len(senders)
        delay = self.delay
        block = self._block
        to = repeat(receivers) if isinstance(receivers, str) else receivers
        if block is not None and not self.outages and self.loss_prob <= 0.0 and delay.dist == "constant":
            # nothing is ever lost (a loss uniform u in [0, 1) is never < 0) and every delay is the constant: the
            # stream moves past the loss uniforms unread, and every message is in flight
            block.skip(n)
            delay_s = float(delay.value_s)  # type: ignore[arg-type]
            when_s = t_s + delay_s
            seq = self._seq
            name = self.name
            msgs: list[Message | None] = [
                _new(Message, (sender, receiver, payload, t_s, when_s, delay_s, k, name))
                for sender, receiver, payload, k in zip(senders, to, payloads, range(seq + 1, seq + n + 1))
            ]
            self._seq = seq + len(msgs)
            self.sent += n
            return msgs
        if block is not None:  # the same draws as one by one: per message the loss uniform, then the delay's
            if delay.dist == "uniform":
                draws = block.take(2 * n)
                losses = draws[0::2]
                low_s = delay.low_s
                width_s = delay.high_s - low_s  # type: ignore[operator]
                delays = [low_s + width_s * x for x in draws[1::2]]  # type: ignore[operator]
            else:
                losses = block.take(n)
                delays = [float(delay.value_s)] * n  # type: ignore[arg-type]
        else:
            rng = self._rng
            losses, delays = [], []
            for _ in range(n):
                losses.append(rng.random())
                delays.append(delay.sample(rng))
        seq = self._seq
        lost_outage = lost_random = 0
        outages = self.outages
        loss_prob = self.loss_prob
        name = self.name
        out: list[Message | None] = []
        for sender, receiver, payload, u, delay_s in zip(senders, to, payloads, losses, delays):
            seq += 1
            if outages and self._in_outage(sender, receiver, t_s):
                lost_outage += 1
                out.append(None)
            elif u < loss_prob:
                lost_random += 1
                out.append(None)
            else:  # Message(...) without the named tuple's Python-level __new__
                out.append(_new(Message, (sender, receiver, payload, t_s, t_s + delay_s, delay_s, seq, name)))
        self._seq = seq
        self.sent += n
        self.lost_outage += lost_outage
        self.lost_random += lost_random
        return out

    def post(self, msgs: Iterable[Message | None]) -> None:
        """Put messages from :meth:`draw` in flight, in this order (None: lost, skipped).

        Messages due at one and the same time (every message of a constant delay sent at once) go in flight as one
        light delivery of the batch (:meth:`_on_batch`): they take consecutive places in the event order, so
        delivering them one after another in one call is what their own deliveries would do."""
        live = [m for m in msgs if m is not None]
        if not live:
            return
        when_s = live[0][4]  # (delivered_s: by index, a plain tuple read in compiled code)
        if len(live) > 1 and all(m[4] == when_s for m in live):
            self._layer.deliver_at(when_s, self._on_batch, live)  # type: ignore[arg-type]
        else:
            self._fly(live)

    def _fly(self, live: list[Message]) -> None:
        """Messages of differing delivery times in flight: each takes its event id now, in this order, as a timed
        delivery of its own would; :class:`~railsim.engine.events.in_flight.InFlight` keeps them in order and the
        layer has it deliver them."""
        layer = self._layer
        if not self._source:
            layer.add_source(self._in_flight)
            self._source = True
        times = [m[4] for m in live]  # delivered_s
        if not min(times) >= self._env.now:
            raise ValueError(f"time {min(times)!r} s is before now ({self._env.now!r} s)")
        self._in_flight.add(times, layer.next_eids(len(live)), live)

    def _deliver_at(self, t_s: float, msg: Message) -> None:
        """One message delivered with the clock at its time (someone watches each delivery)."""
        self._env._now = t_s
        self._on_delivery(msg)

    def _deliver_quietly(self, msgs: list[Message]) -> None:
        """:meth:`_on_delivery` of each message in turn, with no subscriber to tell."""
        self._keep(msgs)
        self._unfolded += [m[5] for m in msgs]  # delay_s
        if len(self._unfolded) >= _BLOCK:
            self._fold_delays()

    def _keep(self, msgs: list[Message]) -> None:
        """The mailboxes and the overtaken count after delivering ``msgs`` in turn: a receiver keeps the newest-sent
        message of each sender."""
        box: dict[str, Message] = {}
        box_of: str | None = None
        overtaken = 0
        for msg in msgs:
            sender, receiver, _, sent_s, _, _, seq, _ = msg
            if receiver is not box_of:
                box_of = receiver
                box = self.mailbox(receiver)
            current = box.get(sender)
            if current is None or sent_s > current[3] or (sent_s == current[3] and seq > current[6]):
                box[sender] = msg
            else:
                overtaken += 1
        self.overtaken += overtaken

    def out(self, train_id: str, t_s: float) -> bool:
        """Is ``train_id`` cut off this channel at ``t_s`` (an outage window covers it)?"""
        return any(o.covers(train_id, t_s) for o in self.outages)

    def _in_outage(self, sender: str, receiver: str, t_s: float) -> bool:
        for o in self.outages:
            if o.covers(sender, t_s) or o.covers(receiver, t_s):
                return True
        return False

    @property
    def delivered(self) -> int:
        """Messages delivered so far (overtaken ones included)."""
        return self._delays.n + len(self._unfolded)

    def _fold_delays(self) -> None:
        """Bring the delay statistics up to date: the delays delivered since, in delivery order."""
        self._delays.add_all(self._unfolded)
        self._unfolded.clear()

    def _on_delivery(self, msg: Message) -> None:
        sender, receiver, _, sent_s, _, delay_s, seq, _ = msg
        unfolded = self._unfolded
        unfolded.append(delay_s)  # the statistics are folded in blocks, in this order
        if len(unfolded) >= _BLOCK:
            self._fold_delays()
        box = self._mail.get(receiver)
        if box is None:
            box = self._mail[receiver] = {}
        current = box.get(sender)
        # (sent_s, seq) ordered as a pair
        if current is None or sent_s > current[3] or (sent_s == current[3] and seq > current[6]):
            box[sender] = msg
        else:
            self.overtaken += 1
        if self._subscribers:
            for callback in self._subscribers:
                callback(msg)

    def _on_batch(self, msgs: list[Message]) -> None:
        """:meth:`_on_delivery` of each message in turn (a batch from :meth:`post`), the loop written out when no
        subscriber can look in between."""
        if self._subscribers:
            for msg in msgs:
                self._on_delivery(msg)
            return
        delay_s = msgs[0][5]
        if all(m[5] == delay_s for m in msgs):  # (delay_s) every message of a constant delay: counted at once
            self._keep(msgs)
            self._fold_delays()
            self._delays.add_same(delay_s, len(msgs))
        else:
            self._deliver_quietly(msgs)

    # ------------------------------------------------------------------ outages
    def _outage_window(self, outage: Outage) -> Generator[simpy.Event, None, None]:
        layer = self._layer
        start_s = max(outage.start_s, layer.now_s)
        yield layer.timeout_at(start_s)
        trains = "all" if outage.trains is None else sorted(outage.trains)
        self._active_outages.append(outage)
        layer.log.record(start_s, "outage_start", self.name, trains=trains, end_s=outage.end_s)
        yield layer.timeout_at(outage.end_s)
        self._active_outages.remove(outage)
        layer.log.record(outage.end_s, "outage_end", self.name, trains=trains, start_s=outage.start_s)

    def active_outages(self) -> tuple[Outage, ...]:
        """Outages in force now (as switched by their simpy processes)."""
        return tuple(self._active_outages)

    # ------------------------------------------------------------------ receiving
    def latest(self, receiver: str, sender: str) -> Message | None:
        """Newest-sent message from ``sender`` delivered to ``receiver`` so far, or None."""
        box = self._mail.get(receiver)
        return None if box is None else box.get(sender)

    def mailbox(self, receiver: str) -> dict[str, Message]:
        """The live mapping behind :meth:`latest` for ``receiver`` (made empty if nothing reached it yet): read it,
        never write it. For a reader that asks one receiver's mailbox every step without the two look-ups."""
        box = self._mail.get(receiver)
        if box is None:
            box = self._mail[receiver] = {}
        return box

    def inbox(self, receiver: str) -> dict[str, Message]:
        """``latest`` for every sender that has reached ``receiver`` (a copy)."""
        return dict(self._mail.get(receiver, {}))

    @property
    def watched(self) -> bool:
        """Does anyone :meth:`subscribe` to the deliveries (and so see their order across channels)?"""
        return bool(self._subscribers)

    def subscribe(self, callback: Callable[[Message], object]) -> None:
        """Call ``callback(message)`` at every delivery (overtaken messages included), in delivery order."""
        self._subscribers.append(callback)
        self._in_flight.watched_now = True

    def stats(self) -> ChannelStats:
        """Counters and delay statistics so far."""
        self._fold_delays()
        acc = self._delays
        lost = self.lost_random + self.lost_outage
        mean_s: float | None = None
        std_s: float | None = None
        lo: float | None = None
        hi: float | None = None
        if acc.n:
            mean_s, std_s, lo, hi = acc.mean, math.sqrt(acc.m2 / acc.n), acc.lo, acc.hi
        return ChannelStats(
            self.name,
            self.sent,
            self.lost_random,
            self.lost_outage,
            self.delivered,
            self.overtaken,
            self.sent - lost - self.delivered,
            mean_s,
            std_s,
            lo,
            hi,
        )
