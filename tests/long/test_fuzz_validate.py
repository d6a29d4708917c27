"""No input breaks ``railsim validate``, and what it accepts runs (the fuzz test of :mod:`tests.fuzz`).

1,000 seeded mutants of the shipped scenarios are validated in this process, each with a time limit: every one
must end in exit 0 or 2 — on 2 with exactly one ``railsim: error:`` line — with no traceback and no hang. A
deterministic sample of accepted mutants then runs a few simulated seconds in real SUMO (child processes): exit
0, 1 (a collision) or 3 (could not continue) only, never 2 (validate would have had to say so) or 4, and no NaN
or infinity in any output. ``python -m tests.fuzz --mutants 5000 --runs -1`` is the larger campaign.
"""

from __future__ import annotations

from pathlib import Path

from tests import fuzz
from tests.helpers import run_railsim

N_MUTANTS = 1000
N_RUNS = 6


def test_validate_survives_1000_mutants(tmp_path: Path) -> None:
    fig = fuzz.campaign(N_MUTANTS, tmp_path)
    print(
        f"fuzz: mutants {fig.mutants}, accepted {fig.accepted}, rejected {fig.rejected}, hangs {fig.hangs}, "
        f"tracebacks {fig.tracebacks}, {fig.seconds:.1f} s (slowest {fig.slowest_s:.2f} s)"
    )
    assert fig.problems == []
    assert fig.mutants == N_MUTANTS and fig.accepted + fig.rejected == N_MUTANTS
    # the mutator reaches both sides of validation (a mutator that only breaks syntax would test little)
    assert fig.accepted >= 50 and fig.rejected >= 500


def _accepted_sample(tmp_path: Path, n: int) -> list[Path]:
    """The first ``n`` accepted mutants at indices 0, 7, 14, ... (deterministic; spread over the shipped bases)."""
    out: list[Path] = []
    k = 0
    while len(out) < n and k < 5000:
        m = fuzz.mutant(k)
        path = tmp_path / f"mutant_{k:05d}.yaml"
        path.write_bytes(m.data)
        res = fuzz.validate_in_process(path)
        assert res.problem is None, f"mutant {k} ({m.base}: {m.ops}): {res.problem}"
        if res.rc == 0:
            out.append(path)
        k += 7
    return out


def test_accepted_mutants_run_a_short_horizon(tmp_path: Path) -> None:
    picked = _accepted_sample(tmp_path, N_RUNS)
    assert len(picked) == N_RUNS
    for path in picked:
        short = fuzz.short_horizon(path)
        out = tmp_path / f"out_{path.stem}"
        res = run_railsim(["validate", str(short)])
        assert res.returncode in (0, 2), res.stderr
        if res.returncode == 2:  # the world check (stations, routes) may refuse what the schema accepted
            assert fuzz.one_error_line(res.stderr), res.stderr
            continue
        res = run_railsim(["run", str(short), "--out", str(out), "--no-progress"])
        assert res.returncode in (0, 1, 3), f"{path.name}: exit {res.returncode}: {res.stderr[-500:]}"
        assert "Traceback" not in res.stderr
        assert (out / "summary.json").is_file()
        assert fuzz.non_finite_cells(out) == [], path.name
