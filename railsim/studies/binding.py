"""The binding constraint of an infeasible run: which rule, where, and for which train a headway breaks down.

A headway search answers *how short*; a planner also asks *why not shorter*. :func:`binding_constraint` reads one
finished run (its ``summary.json``, ``trips.csv``, ``stops.csv``, ``events.csv``) and names what made it
infeasible (:func:`railsim.studies.headway.feasibility`):

* a **collision**, a **switch violation**, a **missed stop** or a train that **never arrived** is the constraint
  itself (the first such event names train and place);
* otherwise the run was too late: the trip with the largest arrival delay is followed stop by stop, and the
  largest single step of its delay is the binding constraint —

  - at its origin (the departure waited): rule ``departure held`` with the dispatcher's reason ("track occupied
    by X", "approaching train X could not stop": an insertion that needs moving-block room);
  - on a leg between two stops where it waited for a switch lock: rule ``switch lock`` with the switch and the
    wait;
  - on a leg otherwise: rule ``separation`` (movement authority behind the train ahead) with the train that
    reached the next platform last before it. A leg's step runs from arrival to arrival, so it includes the
    dwell at the stop it left (the engine extends no dwell; a train held at a platform by the train ahead shows
    here too).

The result is plain data (:class:`Binding`) with a one-line ``text`` for reports.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any


@dataclass(frozen=True)
class Binding:
    """What made a run infeasible (module docstring)."""

    rule: str  # collision | switch violation | missed stop | not arrived | departure held | switch lock | separation | none
    where: str  # station, leg "a → b", switch or train
    train: str | None
    delay_s: float | None  # the worst trip's arrival delay
    step_s: float | None  # the largest single step of its delay, the binding one
    detail: str

    @property
    def text(self) -> str:
        head = f"{self.rule} at {self.where}" if self.where else self.rule
        who = f" ({self.train}" + (f", delay {self.delay_s:.0f} s" if self.delay_s is not None else "") + ")"
        step = f": +{self.step_s:.0f} s there" if self.step_s is not None else ""
        return head + (who if self.train else "") + step + (f"; {self.detail}" if self.detail else "")

    def to_dict(self) -> dict[str, Any]:
        return {**asdict(self), "text": self.text}


def _events(run_dir: Path) -> Any:
    import pandas as pd

    ev = pd.read_csv(run_dir / "events.csv")
    ev["detail"] = ev["detail"].fillna("{}")
    return ev


def _detail(text: str) -> dict[str, Any]:
    try:
        value = json.loads(text)
    except (TypeError, ValueError):
        return {}
    return value if isinstance(value, dict) else {}


def binding_constraint(run_dir: str | Path) -> Binding:
    """The binding constraint of the run in ``run_dir`` (module docstring)."""
    import pandas as pd

    run = Path(run_dir)
    summary = json.loads((run / "summary.json").read_text())
    ev = _events(run)
    for kind, rule in (
        ("collision", "collision"),
        ("sumo_collision", "collision"),
        ("switch_violation", "switch violation"),
    ):
        hit = ev[ev["kind"] == kind]
        if len(hit):
            first = hit.iloc[0]
            return Binding(
                rule, str(first["subject"]), None, None, None, f"t = {first['t_s']:.1f} s: {first['detail']}"
            )
    stops = pd.read_csv(run / "stops.csv")
    trips = pd.read_csv(run / "trips.csv")
    missed = stops[stops["missed"].astype(str) == "True"]
    if len(missed):
        m = missed.iloc[0]
        return Binding("missed stop", str(m["station"]), str(m["trip_id"]), None, None, "")
    if int(summary.get("n_arrived", 0)) != int(summary.get("n_trains", 0)):
        late = trips[trips["arrival_s"].isna()]
        name = str(late.iloc[0]["trip_id"]) if len(late) else None
        held = ev[(ev["kind"] == "never_inserted") | (ev["kind"] == "departure_held")]
        why = _detail(held.iloc[-1]["detail"]).get("reason", "") if len(held) else ""
        return Binding("not arrived", name or "", name, None, None, why)
    arrived = trips.dropna(subset=["delay_s"])
    if not len(arrived):
        return Binding("none", "", None, None, None, "no trip arrived")
    worst = arrived.loc[arrived["delay_s"].idxmax()]
    return _delay_step(worst, stops, ev)


def _delay_step(worst: Any, stops: Any, ev: Any) -> Binding:
    """Follow the worst trip's delay stop by stop; the largest step is the binding constraint."""
    tid = str(worst["trip_id"])
    delay = float(worst["delay_s"])
    own = stops[stops["trip_id"] == tid].sort_values("planned_arrival_s")
    origin_delay = float(worst["departure_s"]) - float(worst["planned_departure_s"])
    # steps: (size, kind, from, to); kind "origin" or "leg"; the destination closes the last leg
    steps: list[tuple[float, str, str, str]] = [(origin_delay, "origin", str(worst["origin"]), str(worst["origin"]))]
    prev_station, prev_delay = str(worst["origin"]), origin_delay
    for row in own.itertuples(index=False):
        arr_delay = float(row.arrival_s) - float(row.planned_arrival_s)
        steps.append((arr_delay - prev_delay, "leg", prev_station, str(row.station)))
        prev_station, prev_delay = str(row.station), arr_delay
    size, kind, a, b = max(steps, key=lambda s: s[0])
    if kind == "origin":
        held = ev[(ev["kind"] == "departure_held") & (ev["subject"] == tid)]
        reasons = list(dict.fromkeys(_detail(d).get("reason", "") for d in held["detail"]))
        reason = "; ".join(reasons[:2]) + (f"; … ({len(reasons) - 2} more reasons)" if len(reasons) > 2 else "")
        return Binding("departure held", a, tid, delay, size, reason)
    t0 = (
        float(own.loc[own["station"] == a, "departure_s"].iloc[0])
        if a in set(own["station"])
        else float(worst["departure_s"])
    )
    t1 = float(own.loc[own["station"] == b, "arrival_s"].iloc[0])
    waits = []
    for d in ev[(ev["kind"] == "lock_granted") & (ev["t_s"] >= t0) & (ev["t_s"] <= t1)].itertuples(index=False):
        info = _detail(d.detail)
        if tid in info.get("holders", []) and float(info.get("waited_s", 0.0)) > 1.0:
            waits.append((float(info["waited_s"]), str(d.subject)))
    if waits:
        w, sw = max(waits)
        return Binding("switch lock", f"{sw} ({a} → {b})", tid, delay, size, f"waited {w:.0f} s for the lock")
    # the train ahead runs the same way: it stopped at a before it stopped at b (a station id names both platforms)
    at_a = stops[stops["station"] == a].set_index("trip_id")["arrival_s"]
    ahead = stops[(stops["station"] == b) & (stops["trip_id"] != tid) & (stops["arrival_s"] <= t1)]
    ahead = ahead[ahead["trip_id"].map(at_a).lt(ahead["arrival_s"])]
    who = str(ahead.loc[ahead["arrival_s"].idxmax(), "trip_id"]) if len(ahead) else "?"
    return Binding(
        "separation",
        f"{a} → {b}",
        tid,
        delay,
        size,
        f"movement authority behind {who} (the last train to reach {b} before it)",
    )
