"""The event log: one row per thing that *happened* in simulated time.

Every module of the event layer writes here when something changes state — a coupling completes, a switch
starts to throw, an outage begins, a departure falls due. The recorder exports the rows next to the per-step
traces, so a reader can line up "the follower reached the coupled state at t = 47.3 s" with the gap trace.

What a row is
-------------
``{"t_s": float, "seq": int, "kind": str, "subject": str, "detail": str}``

- ``t_s`` is the exact simulated time of the event (not rounded to a SUMO step).
- ``seq`` is the order in which rows were recorded; it breaks ties between events at the same instant, so
  the order is deterministic (same scenario and seed → identical rows).
- ``kind`` names what happened (``"coupled"``, ``"throw_start"``, ``"outage_end"`` …; each module lists the
  kinds it writes in its docstring); ``subject`` names what it happened to (a formation, switch, channel or
  trip id).
- ``detail`` is the keyword arguments of :meth:`EventLog.record` as **one compact JSON string** with sorted
  keys. Reading: the kinds carry different details, so flat columns would give a sparse table whose schema
  changes with the scenario; a fixed five-column schema exports cleanly to CSV/Parquet and
  ``json.loads`` recovers the fields. For use inside Python, :meth:`EventLog.entries` keeps the details as
  dicts.

Rows come back sorted by ``(t_s, seq)``. The simpy layer records in time order anyway; the sort only matters
if a caller records an event stamped earlier than one already logged.

A detail that cannot be written as strict JSON (NaN, infinity, an arbitrary object) raises at ``record``
time: a silent NaN in a log is worse than a loud error.
"""

from __future__ import annotations

import json
import math
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True, slots=True)
class LogEntry:
    """One logged event, with its detail as a dict (see the module docstring for the exported row)."""

    t_s: float
    seq: int
    kind: str
    subject: str
    detail: Mapping[str, Any]
    detail_json: str


def _json_default(value: Any) -> Any:
    # numpy scalars and sets turn up in details (train id sets, rng-drawn delays); give them a stable
    # JSON form instead of failing.
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (set, frozenset)):
        return sorted(value)
    raise TypeError(f"event detail of type {type(value).__name__} is not JSON-serialisable")


class EventLog:
    """Append-only, deterministic log of timed events."""

    def __init__(self) -> None:
        self._entries: list[LogEntry] = []
        self._counts: Counter[str] = Counter()
        self._sorted = True

    def record(self, t_s: float, kind: str, subject: str, **detail: Any) -> LogEntry:
        """Record that ``kind`` happened to ``subject`` at ``t_s`` seconds; ``detail`` becomes JSON."""
        t_s = float(t_s)
        if not math.isfinite(t_s):
            raise ValueError(f"event time must be finite, got {t_s!r} for {kind} {subject}")
        detail_json = json.dumps(detail, sort_keys=True, separators=(",", ":"), allow_nan=False, default=_json_default)
        entry = LogEntry(t_s, len(self._entries), str(kind), str(subject), dict(detail), detail_json)
        if self._entries and t_s < self._entries[-1].t_s:
            self._sorted = False
        self._entries.append(entry)
        self._counts[entry.kind] += 1
        return entry

    def entries(self, kind: str | None = None, subject: str | None = None) -> list[LogEntry]:
        """Entries sorted by ``(t_s, seq)``, optionally only those of one kind and/or subject."""
        if not self._sorted:
            self._entries.sort(key=lambda e: (e.t_s, e.seq))
            self._sorted = True
        return [
            e for e in self._entries if (kind is None or e.kind == kind) and (subject is None or e.subject == subject)
        ]

    def rows(self, kind: str | None = None, subject: str | None = None) -> list[dict[str, Any]]:
        """Export rows ``{t_s, seq, kind, subject, detail}`` with ``detail`` a compact JSON string."""
        return [
            {"t_s": e.t_s, "seq": e.seq, "kind": e.kind, "subject": e.subject, "detail": e.detail_json}
            for e in self.entries(kind, subject)
        ]

    def count(self, kind: str) -> int:
        """How many events of ``kind`` were recorded."""
        return self._counts[kind]

    def __len__(self) -> int:
        return len(self._entries)
