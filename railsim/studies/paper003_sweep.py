"""Communication-delay × load sweep of Paper D's tracking-coupling scenarios through the engine (spec 003 A14, A18).

The paper blames its collision scenarios on a V2V "communication-delay fault" but never gives the delay (t_d is
[LOST]). This sweep asks the engine the question directly: with the t2t delay of ``faults.comm`` set to each of
{0.1, 0.5, 1, 2} s (constant), and the cars empty or loaded, do the accelerated/decelerated tracking-coupling
formations (scenarios/paper003_track_{accel,decel}[_loaded].yaml, APF coupling law on delayed messages, RDBM CA on
the own sensor) still couple, how often does the CA fire, and how close do the cars come?

Each run is a separate ``railsim run`` child process (a SUMO crash cannot take the caller down); runs are
sequential. A delay ≥ the engine's ``max_message_age_s`` (2 s) makes every message too old, so the follower drops
to moving-block separation on ground data (``vc_degraded``) and cannot couple: that is the engine's rule, reported
as such, not a controller result.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import yaml

from railsim.analysis import paper003 as ca_metrics

ROOT = Path(__file__).resolve().parents[2]  # the repository (railsim/studies/<this file>)
DELAYS_S = (0.1, 0.5, 1.0, 2.0)
LOADS = ("empty", "loaded")
SCENARIOS = ("track_accel", "track_decel")


@dataclass(frozen=True)
class SweepRow:
    scenario: str
    load: str
    delay_s: float
    coupled: bool  # every formation coupled at least once
    ca_activations: int  # ca_trigger events over all trains
    min_gap_m: float  # over all consecutive pairs
    collisions: int
    degraded: int  # vc_degraded events (messages older than max_message_age_s)


def run_one(scenario: str, load: str, delay_s: float, workdir: Path) -> SweepRow:
    """One engine run of ``paper003_<scenario>[_loaded].yaml`` with a constant t2t delay ``delay_s``."""
    src = ROOT / "scenarios" / f"paper003_{scenario}{'' if load == 'empty' else '_loaded'}.yaml"
    raw = yaml.safe_load(src.read_text(encoding="utf-8"))
    raw.setdefault("faults", {}).setdefault("comm", {})["t2t"] = {
        "delay_s": {"dist": "constant", "value": float(delay_s)}
    }
    tag = f"{scenario}_{load}_{delay_s:g}"
    path = workdir / f"{tag}.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False), encoding="utf-8")
    out = workdir / tag
    res = subprocess.run(
        [sys.executable, "-m", "railsim.cli.main", "run", str(path), "--out", str(out), "--no-progress"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=600,
    )
    if res.returncode not in (0, 1):  # 1: the run had a collision (still a result)
        raise RuntimeError(f"{tag}: railsim exited {res.returncode}: {res.stderr[-500:]}")
    m = ca_metrics.metrics(out)
    events = ca_metrics._read_csv(out / "events.csv")
    gaps = [p["min_gap_m"] for p in m["pairs"].values() if p["min_gap_m"] is not None]
    return SweepRow(
        scenario,
        load,
        float(delay_s),
        bool(m["coupled"]) and all(m["coupled"].values()),
        sum(1 for e in events if e["kind"] == "ca_trigger"),
        min(gaps),
        int(m["collisions"]),
        sum(1 for e in events if e["kind"] == "vc_degraded"),
    )


def sweep(
    delays_s: Iterable[float] = DELAYS_S,
    loads: Iterable[str] = LOADS,
    scenarios: Iterable[str] = SCENARIOS,
    workdir: Path | None = None,
) -> list[SweepRow]:
    """All combinations, sequentially; outputs go to ``workdir`` (a temporary folder if None)."""
    rows: list[SweepRow] = []
    with tempfile.TemporaryDirectory(prefix="paper003_sweep_") as tmp:
        base = Path(workdir) if workdir is not None else Path(tmp)
        base.mkdir(parents=True, exist_ok=True)
        for scenario in scenarios:
            for load in loads:
                for d in delays_s:
                    rows.append(run_one(scenario, load, d, base))
    return rows


def format_sweep(rows: Iterable[SweepRow]) -> str:
    head = f"{'scenario':<12} {'load':<7} {'delay s':>7} {'coupled':>8} {'CA on':>6} {'min gap m':>9} {'coll':>5} {'degraded':>8}"
    lines = [head, "-" * len(head)]
    for r in rows:
        lines.append(
            f"{r.scenario:<12} {r.load:<7} {r.delay_s:>7g} {str(r.coupled):>8} {r.ca_activations:>6} "
            f"{r.min_gap_m:>9.2f} {r.collisions:>5} {r.degraded:>8}"
        )
    return "\n".join(lines)


if __name__ == "__main__":
    table = sweep()
    print(format_sweep(table))
    print(json.dumps([r.__dict__ for r in table]))
