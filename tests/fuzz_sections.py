"""A seeded fuzz of the newer input sections: rotations and depots, disturbances and demand, interlocking,
formations, sweep files and robustness (disturbances) files — the approach of :mod:`tests.fuzz`, aimed.

:mod:`tests.fuzz` mutates anywhere in a scenario, so most of its mutants die on the older, larger sections
(services, vehicles, controllers). Here each mutant changes only one of the newer sections (1–3 tree mutations
of :func:`tests.fuzz._tree_op` inside it), so every mutant reaches that section's validation:

* **scenario sections** — bases that carry the sections (``chongqing_line3_day_depots.yaml`` with rotations and
  depots, ``chongqing_line3_day.yaml`` with rotations across formations, the test corridor with disturbances
  and passenger demand), each given an ``interlocking`` section; checked with ``railsim validate
  --no-world-check`` in this process (:func:`tests.fuzz.validate_in_process`);
* **sweep files** — a sweep over the disturbed corridor (grid, cases, link, seeds, timeout), mutated anywhere;
  checked with ``railsim validate --no-world-check SWEEP`` in this process;
* **robustness files** — the shipped ``scenarios/disturbances/line3_peak.yaml``, mutated; checked as
  ``railsim robustness --disturbances FILE`` checks it before any run
  (:func:`railsim.studies.robustness.check_disturbances_file`, the world check aside).

Every outcome must keep the contract of :func:`classify`: exit 0 or 2, on 2 one line ``railsim: error: FILE:
FIELD: ...`` naming the mutated file (never a file railsim generated) and a field, no traceback, no hang, never
exit 4. ``python -m tests.fuzz_sections --mutants 600`` prints the figures of a larger campaign.
"""

from __future__ import annotations

import contextlib
import copy
import io
import random
import re
import signal
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from tests import fuzz

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data" / "scenarios"
SCENARIO_BASES = (
    ROOT / "scenarios" / "chongqing_line3_day_depots.yaml",
    ROOT / "scenarios" / "chongqing_line3_day.yaml",
    DATA / "passenger_demand.yaml",
    DATA / "disturbed_line.yaml",
)
SECTIONS = ("rotations", "disturbances", "formations", "interlocking")
INTERLOCKING = {"overlap_m": 20, "stall_timeout_s": 300}
SWEEP_BASE = DATA / "disturbed_line.yaml"
DISTURBANCES_FILE = ROOT / "scenarios" / "disturbances" / "line3_peak.yaml"
DISTURBANCES_SCENARIO = ROOT / "scenarios" / "chongqing_line3_peak.yaml"
KINDS = ("scenario", "scenario", "sweep", "robustness")
# "FILE: FIELD: message": a field is a dotted/indexed path, the "case k (...)" of a sweep, or the line and
# column of a YAML error (where the parser stopped, before there are fields)
_FIELD = re.compile(
    r"^(case \d+ \(|line \d+, column \d+: |[A-Za-z_$<][\w\-<>$]*(\[\d+\])*(\.(?:[^\s:]|:(?! ))+)*(: |$))"
)


@dataclass(frozen=True)
class SectionMutant:
    index: int
    kind: str  # scenario | sweep | robustness
    base: str
    ops: tuple[str, ...]
    data: bytes


def _sweep_tree() -> dict[str, Any]:
    return {
        "name": "fuzz",
        "base": str(SWEEP_BASE),
        "grid": {"services[0].dwell_s": [20, 30], "disturbances.incidents[0].hold_s": [120, 300]},
        "cases": [{"label": "plain"}, {"label": {"kind": "late"}, "simulation.seed": 5}],
        "link": {"services[0].departures.times[0]": "services[0].dwell_s"},
        "seeds": [1, 2],
        "timeout_s": 600,
    }


def mutant(index: int, seed: int = 0) -> SectionMutant:
    """Mutant ``index`` of campaign ``seed`` (deterministic)."""
    rng = random.Random(seed * 1_000_003 + index * 7_919 + 17)
    kind = KINDS[index % len(KINDS)]
    ops: list[str] = []
    n_ops = rng.choice((1, 1, 2, 3))
    if kind == "scenario":
        base = SCENARIO_BASES[(index // len(KINDS)) % len(SCENARIO_BASES)]
        tree = yaml.safe_load(base.read_text(encoding="utf-8"))
        tree.setdefault("interlocking", copy.deepcopy(INTERLOCKING))
        if isinstance(tree.get("world"), dict) and "line" in tree["world"]:
            tree["world"]["line"] = str((base.parent / tree["world"]["line"]).resolve())
        present = [s for s in SECTIONS if s in tree]
        for _ in range(n_ops):
            sec = rng.choice(present)
            sub, label = fuzz._tree_op(rng, tree[sec])
            tree[sec] = sub
            ops.append(f"{sec}: {label}")
    elif kind == "sweep":
        base = SWEEP_BASE
        tree = _sweep_tree()
        for _ in range(n_ops):
            tree, label = fuzz._tree_op(rng, tree)
            ops.append(label)
    else:
        base = DISTURBANCES_FILE
        tree = yaml.safe_load(base.read_text(encoding="utf-8"))
        for _ in range(n_ops):
            tree, label = fuzz._tree_op(rng, tree)
            ops.append(label)
    data = yaml.safe_dump(tree, sort_keys=False, allow_unicode=True).encode()
    return SectionMutant(index, kind, base.name, tuple(ops), data)


def _robustness_check(path: Path) -> int:
    """What ``railsim robustness SCENARIO --disturbances PATH`` checks before any run (the world check aside)."""
    from railsim.studies.robustness import check_disturbances_file, load_disturbances

    check_disturbances_file(DISTURBANCES_SCENARIO, load_disturbances(path), path, world_check=False)
    return 0


def check_in_process(path: Path, kind: str, timeout_s: float = fuzz.TIMEOUT_S) -> fuzz.Outcome:
    """Validate ``path`` as its kind in this process, like :func:`tests.fuzz.validate_in_process`, and classify."""
    if kind != "robustness":
        return classify(fuzz.validate_in_process(path, timeout_s), path)
    from railsim.cli.main import run_guarded  # the CLI's error handling: the exit code and line railsim gives

    return classify(_timed(lambda: run_guarded(lambda: _robustness_check(path)), timeout_s), path)


def _timed(run: Callable[[], int], timeout_s: float) -> fuzz.Outcome:
    err = io.StringIO()
    old = signal.signal(signal.SIGALRM, fuzz._on_alarm)
    signal.setitimer(signal.ITIMER_REAL, timeout_s)
    t0 = time.perf_counter()
    rc: int | None = None
    problem: str | None = None
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            rc = run()
    except fuzz.Hang:
        problem = f"hang (> {timeout_s:g} s)"
    except BaseException as exc:  # noqa: BLE001 - anything escaping breaks the contract
        problem = f"escaped {type(exc).__name__}: {str(exc)[:200]}"
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
    return fuzz.Outcome(rc, err.getvalue(), time.perf_counter() - t0, problem)


def classify(res: fuzz.Outcome, path: Path) -> fuzz.Outcome:
    """Add this fuzz's contract to ``res``: exit 0 or 2; on 2 one line naming ``path`` and a field."""
    if res.problem is not None:
        return res
    lines = res.stderr.splitlines()
    if res.rc not in (0, 2):
        res.problem = f"exit {res.rc}"
    elif "Traceback" in res.stderr:
        res.problem = "traceback"
    elif res.rc == 2:
        prefix = f"railsim: error: {path}: "
        if len(lines) != 1:
            res.problem = f"expected one error line, got {len(lines)}"
        elif not lines[0].startswith(prefix):
            res.problem = "the error does not name the mutated file"
        elif not _FIELD.match(lines[0][len(prefix) :]) and not _whole_file_message(lines[0][len(prefix) :]):
            res.problem = "the error names no field"
    return res


def _whole_file_message(message: str) -> bool:
    """A message about the file as a whole (its YAML, its top level): no field to name."""
    return message.startswith(("expected a mapping", "expected valid YAML", "expected a YAML", "not a "))


@dataclass
class Figures:
    mutants: int = 0
    accepted: int = 0
    rejected: int = 0
    by_kind: dict[str, list[int]] = field(default_factory=dict)  # kind -> [accepted, rejected]
    problems: list[str] = field(default_factory=list)
    seconds: float = 0.0
    slowest_s: float = 0.0
    accepted_scenarios: list[Path] = field(default_factory=list)


def campaign(n: int, workdir: Path, seed: int = 0) -> Figures:
    """Check ``n`` mutants in this process; the figures (accepted scenario mutants are kept on disk)."""
    fig = Figures()
    t0 = time.perf_counter()
    for k in range(n):
        m = mutant(k, seed)
        path = workdir / f"{m.kind}_{k:05d}.yaml"
        path.write_bytes(m.data)
        res = check_in_process(path, m.kind)
        fig.mutants += 1
        fig.slowest_s = max(fig.slowest_s, res.seconds)
        counts = fig.by_kind.setdefault(m.kind, [0, 0])
        if res.problem is not None:
            fig.problems.append(
                f"mutant {k} ({m.kind} {m.base}: {'; '.join(m.ops)}): {res.problem}: {res.stderr[:300]}"
            )
        elif res.rc == 0:
            fig.accepted += 1
            counts[0] += 1
            if m.kind == "scenario":
                fig.accepted_scenarios.append(path)
        else:
            fig.rejected += 1
            counts[1] += 1
    fig.seconds = time.perf_counter() - t0
    return fig


def main(argv: list[str] | None = None) -> int:
    ap = fuzz.campaign_parser("Fuzz the newer sections' validation (and run a few accepted mutants).", 600)
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="railsim-fuzz-sections-") as tmp:
        fig = campaign(args.mutants, Path(tmp), args.seed)
        print(
            f"mutants {fig.mutants}, accepted {fig.accepted}, rejected {fig.rejected}, problems {len(fig.problems)}; "
            f"by kind {fig.by_kind}; {fig.seconds:.1f} s, slowest {fig.slowest_s:.2f} s"
        )
        for p in fig.problems:
            print("  " + p)
    return 1 if fig.problems else 0


if __name__ == "__main__":
    sys.exit(main())
