"""Coupled-where-asked rate of formations that couple after a merge, on the generated Y world.

Each run is one timetable on :file:`tests/data/lines/merge_y.yaml` (``tests.helpers.merge_world``): ``--pairs``
formations, one every ``--period`` seconds, each a leader from E and a follower from G that couple after the merge
``c_down``; the follower leaves G at a random offset from its leader's departure, uniform in
[``--offset-min``, ``--offset-max``] s (negative: before it — the follower then reaches the merge first); on each
line one unrelated train leaves between the units of two successive formations (at a random time at least 60 s
after the one and before the other). An unrelated train on the main line may so reach the merge between a leader
and its follower: the merge order holds it back. ``--runs`` runs with seeds 1, 2, …; every run is a ``railsim run`` in a child process.

Prints one JSON object: per run the formations asked, coupled where asked, the failure reasons, collisions and
switch violations; and over all runs the coupled-where-asked rate.

    .venv/bin/python benchmarks/merge_coupling.py [--runs 4] [--pairs 5] [--period 420] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.helpers import merge_world, read_summary, run_mapping  # noqa: E402

START_S = 120.0  # the first leader leaves E then (a follower may leave G up to this much before it)
UNRELATED_CLEAR_S = 60.0  # an unrelated train leaves its origin this long after / before the formations' units


def timetable(seed: int, pairs: int, period_s: float, offset_min_s: float, offset_max_s: float) -> dict[str, Any]:
    """One run's scenario (module docstring)."""
    rng = np.random.default_rng(seed)
    formation_times = []
    for k in range(pairs):
        lead_s = START_S + k * period_s
        formation_times.append((lead_s, float(round(lead_s + rng.uniform(offset_min_s, offset_max_s), 1))))
    others = []
    for line, origin, unit in (("main", "e", 0), ("branch", "g", 1)):
        times = sorted(p[unit] for p in formation_times) + [START_S + pairs * period_s + period_s]
        for k, (after_s, before_s) in enumerate(zip(times, times[1:])):
            lo, hi = after_s + UNRELATED_CLEAR_S, before_s - UNRELATED_CLEAR_S
            if hi > lo:
                others.append((f"{line}_x{k}", origin, float(round(rng.uniform(lo, hi), 1))))
    return merge_world(formation_times, others, duration_s=START_S + (pairs + 1) * period_s + 1500.0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=4)
    ap.add_argument("--pairs", type=int, default=5)
    ap.add_argument("--period", type=float, default=420.0)
    ap.add_argument("--offset-min", type=float, default=-90.0)
    ap.add_argument("--offset-max", type=float, default=150.0)
    ap.add_argument("--out", type=Path, default=None, help="keep the run folders here (default: a temporary folder)")
    args = ap.parse_args()
    folder = args.out or Path(tempfile.mkdtemp(prefix="merge_coupling_"))
    folder.mkdir(parents=True, exist_ok=True)
    rows = []
    for seed in range(1, args.runs + 1):
        data = timetable(seed, args.pairs, args.period, args.offset_min, args.offset_max)
        res, out = run_mapping(folder, data, f"run{seed}")
        if res.returncode != 0:
            rows.append({"seed": seed, "exit": res.returncode, "error": res.stderr.strip().splitlines()[-1:]})
            continue
        s = read_summary(out)
        asked = s.get("formations_asked", [])
        rows.append(
            {
                "seed": seed,
                "exit": 0,
                "asked": len(asked),
                "coupled_where_asked": sum(1 for r in asked if r["coupled"]),
                "reasons": dict(Counter(r["reason"] for r in asked if not r["coupled"])),
                "collisions": s["collisions"],
                "switch_violations": s["switch_violations"],
                "arrived": f"{s['n_arrived']}/{s['n_trains']}",
            }
        )
    ok = [r for r in rows if r["exit"] == 0]
    asked_n = sum(r["asked"] for r in ok)
    coupled_n = sum(r["coupled_where_asked"] for r in ok)
    print(
        json.dumps(
            {
                "world": "tests/data/lines/merge_y.yaml",
                "settings": vars(args) | {"out": str(folder)},
                "runs": rows,
                "formations_asked": asked_n,
                "coupled_where_asked": coupled_n,
                "rate": coupled_n / asked_n if asked_n else None,
                "collisions": sum(r["collisions"] for r in ok),
                "switch_violations": sum(r["switch_violations"] for r in ok),
                "failed_runs": len(rows) - len(ok),
            },
            indent=1,
        )
    )


if __name__ == "__main__":
    main()
