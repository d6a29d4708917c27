"""Operating fuzz: valid-but-unusual variants of the mini line, run in real SUMO, held to the safety contract.

:mod:`tests.fuzz` throws hostile *inputs* at validation. This module throws unusual *operations* at the engine: every
variant is a scenario a user could write — the mini line (``tests/data/scenarios/mini_line.yaml``: up and down
trains on a Y, a pair coupling on departure and parting before the switch, a merging branch train) with, drawn from a
seed, any of: step 0.05–2 s and any step method; dwells 0–300 s; departures 1–120 s apart; trains started in motion
(up to 60 km/h, anywhere in the first section); trains 40–230 m long (the platforms are 220 m); low or high top
speed, low service brake, a very low jerk limit; separation margins 0–200 m; ATO margins; formation gaps 5–100 m,
``depart_together``, coupling timeouts; held trains (incidents); radio delays up to 3 s, losses up to 0.9, outages
up to 550 s on either channel; position noise up to 5 m; platform berths off. Variant ``k`` is the same scenario on
every machine (``random.Random(k)``).

The contract (:func:`problems`), whatever the variant:

* the run ends (a time limit per run) with exit 0 (all well), 1 (a collision), 2 (the input is refused: exactly one
  ``railsim: error:`` line naming the field — some draws combine into something impossible, e.g. a start speed
  above the vehicle's top speed) or 3 (the run could not go on or a train never ran: a desync, a stall, a train
  never put on — each reported); never a traceback;
* every run that started writes ``summary.json`` and outputs without NaN or infinity; the summary never counts
  fewer collisions than SUMO reported; exit 0 means no collision, no failure and every train on the line;
* **no collision at all**: in a valid scenario the engine keeps trains apart (it brakes, holds departures, refuses
  an insertion that no braking could make safe) — a collision in a variant is a defect to find, not physics.

``tests/long/test_fuzz_runs.py`` runs a fixed sample in CI; ``python -m tests.fuzz_runs --n 300 --jobs 2`` is a campaign
(its first campaigns found seven defects this way, each now a test of its own).
"""

from __future__ import annotations

import argparse
import json
import random
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tests.fuzz import non_finite_cells, one_error_line
from tests.helpers import mini_line, read_summary, run_mapping

TIMEOUT_S = 400.0  # per run; a healthy variant takes 2–20 s
EXIT_CODES = (0, 1, 2, 3)


def variant(k: int) -> dict[str, Any]:
    """Variant ``k`` of the mini line (deterministic): a scenario mapping."""
    rng = random.Random(k)
    d = mini_line()
    d["name"] = f"fuzz_run_{k}"
    sim = d["simulation"]
    sim["step_s"] = rng.choice([0.05, 0.1, 0.2, 0.25, 0.5, 0.5, 1.0, 1.5, 2.0])
    sim["step_method"] = rng.choice(["euler", "euler", "ballistic", "forward"])
    sim["seed"] = rng.randrange(1000)
    sim["duration_s"] = 2400
    d["outputs"]["trace_stride_s"] = max(1.0, sim["step_s"])
    veh = d["vehicles"]["cq6"]
    if rng.random() < 0.25:
        veh["length_m"] = rng.choice([40.0, 200.0, 230.0])
    if rng.random() < 0.2:
        veh["max_speed_kmh"] = rng.choice([30, 120])
    if rng.random() < 0.2:
        veh.update({"service_decel_mps2": rng.choice([0.5, 1.2]), "jerk_limit_mps3": rng.choice([0.3, 5.0])})
    for svc in d["services"]:
        svc["dwell_s"] = rng.choice([0, 1, 5, 20, 60, 120, 300])
        if rng.random() < 0.35:
            t0 = rng.choice([0, 10, 30, 60])
            gap = rng.choice([1, 2, 5, 20, 30, 60, 90, 120])
            svc["departures"] = {"times": [t0 + i * gap for i in range(rng.choice([1, 2, 3, 4]))]}
        if rng.random() < 0.15:
            svc["start"] = {"offset_m": rng.choice([0, 100, 500, 1200]), "speed_kmh": rng.choice([0, 30, 60])}
    if rng.random() < 0.4:
        d["controllers"]["sep"]["params"]["margin_m"] = rng.choice([0, 1, 5, 20, 200])
    if rng.random() < 0.25:
        d["controllers"]["ato"]["params"] = {
            "speed_margin_mps": rng.choice([0.0, 2.0]),
            "authority_margin_m": rng.choice([0.0, 20.0]),
        }
    _formation(rng, d)
    comm = d["faults"]["comm"]
    if rng.random() < 0.4:
        for ch in ("t2t", "t2g"):
            comm[ch] = {
                "delay_s": {"dist": "uniform", "low": 0.0, "high": rng.choice([0.1, 1.0, 3.0])},
                "loss_prob": rng.choice([0.0, 0.1, 0.5, 0.9]),
            }
    if rng.random() < 0.25:
        comm["t2t"]["outages"] = [{"start_s": rng.choice([100, 200]), "end_s": rng.choice([250, 400])}]
        comm["t2g"]["outages"] = [{"start_s": rng.choice([50, 300]), "end_s": rng.choice([350, 600])}]
    if rng.random() < 0.25:
        trips = [f"{s['id']}.000" for s in d["services"]]
        station = rng.choice(["b", "c", "d"])
        d["disturbances"] = {
            "incidents": [{"trip": rng.choice(trips), "station": station, "hold_s": rng.choice([30, 200])}]
        }
    if rng.random() < 0.2:
        d["interlocking"] = {"platform_berths": False}
    if rng.random() < 0.15:
        d["faults"]["sensor_noise"] = {
            "position_sd_m": rng.choice([0.5, 5.0]),
            "speed_sd_mps": rng.choice([0.05, 0.5]),
        }
    return d


def _formation(rng: random.Random, d: dict[str, Any]) -> None:
    """Vary the coupled pair (leader: main_up's second trip); drop it when main_up has fewer than two trips."""
    f = d["formations"][0]
    if len(d["services"][0]["departures"]["times"]) < 2 or rng.random() < 0.15:
        d.pop("formations")
        return
    f["target_gap_m"] = rng.choice([5, 30, 100])
    if rng.random() < 0.3:
        f["depart_together"] = True
    if rng.random() < 0.3:
        f["coupling_timeout_s"] = rng.choice([10, 60])


@dataclass
class RunOutcome:
    k: int
    rc: int | None  # None: the time limit
    seconds: float
    summary: dict[str, Any] | None
    problems: list[str]
    last_error: str


def run_variant(k: int, folder: Path, timeout_s: float = TIMEOUT_S) -> RunOutcome:
    """Run variant ``k`` with ``railsim run`` in a child process under ``folder``; its outcome and problems."""
    t0 = time.perf_counter()
    try:
        proc, out = run_mapping(folder, variant(k), name=f"v{k}", timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return RunOutcome(k, None, time.perf_counter() - t0, None, [f"no end within {timeout_s:g} s"], "")
    summary = read_summary(out) if (out / "summary.json").is_file() else None
    errs = [ln for ln in proc.stderr.splitlines() if ln.startswith("railsim: error: ")]
    return RunOutcome(
        k,
        proc.returncode,
        time.perf_counter() - t0,
        summary,
        problems(proc.returncode, proc.stderr, out, summary),
        errs[-1] if errs else "",
    )


def problems(rc: int, stderr: str, out: Path, summary: dict[str, Any] | None) -> list[str]:
    """How one run breaks the contract (see the module docstring); empty when it keeps it."""
    bad: list[str] = []
    if rc not in EXIT_CODES:
        bad.append(f"exit {rc}")
    if "Traceback" in stderr:
        bad.append("traceback: " + stderr.strip().splitlines()[-1][:200])
    if rc == 2:
        if not one_error_line(stderr):
            bad.append("refused without exactly one 'railsim: error:' line")
        return bad
    if summary is None:
        return [*bad, f"exit {rc} without summary.json"]
    bad += [f"non-finite output {cell}" for cell in non_finite_cells(out)[:3]]
    collisions = int(summary.get("collisions", 0))
    if collisions < int(summary.get("sumo_collisions", 0)):
        bad.append(f"{collisions} collisions reported, SUMO saw {summary['sumo_collisions']}")
    if collisions > 0:
        bad.append(f"{collisions} collisions (exit {rc})")
    if rc == 0 and (summary.get("failure") or summary.get("n_never_inserted")):
        bad.append(f"exit 0 with failure {summary.get('failure')!r}, never inserted {summary.get('never_inserted')}")
    return bad


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="Run variants of the mini line in SUMO; report contract breaches.")
    ap.add_argument("--n", type=int, default=100, help="number of variants")
    ap.add_argument("--first", type=int, default=0, help="first variant index")
    ap.add_argument("--jobs", type=int, default=2, help="runs at a time (each in its own process)")
    ap.add_argument("--out", type=Path, default=None, help="keep the variants and their outputs here")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="railsim-fuzz-runs-") as tmp:
        folder = args.out or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        codes: dict[str, int] = {}
        broken = 0
        with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
            ks = range(args.first, args.first + args.n)
            for res in pool.map(lambda k: run_variant(k, folder), ks):
                codes[str(res.rc)] = codes.get(str(res.rc), 0) + 1
                broken += bool(res.problems)
                row = {"variant": res.k, "rc": res.rc, "s": round(res.seconds, 1), "problems": res.problems}
                if res.last_error:
                    row["error"] = res.last_error[:200]
                if res.summary is not None:
                    row["failure"] = res.summary.get("failure")
                print(json.dumps(row), flush=True)
        print(f"variants {args.n}: exit codes {dict(sorted(codes.items()))}, breaking the contract {broken}")
    return 1 if broken else 0


if __name__ == "__main__":
    sys.exit(main())
