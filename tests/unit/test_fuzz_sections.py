"""The newer sections' fuzz (:mod:`tests.fuzz_sections`) at CI size: validate-level, in this process.

Every mutant of rotations/depots, disturbances/demand, interlocking, formations, sweep files and robustness files
ends in exit 0 or one ``railsim: error: FILE: FIELD: ...`` line naming the mutated file (exit 2): no traceback,
no exit 4, no hang. ``python -m tests.fuzz_sections --mutants 600`` is the larger campaign.
"""

from __future__ import annotations

from pathlib import Path

from tests import fuzz_sections

N_MUTANTS = 160


def test_newer_sections_survive_their_mutants(tmp_path: Path) -> None:
    fig = fuzz_sections.campaign(N_MUTANTS, tmp_path)
    print(
        f"fuzz_sections: mutants {fig.mutants}, accepted {fig.accepted}, rejected {fig.rejected}, by kind "
        f"{fig.by_kind}, {fig.seconds:.1f} s (slowest {fig.slowest_s:.2f} s)"
    )
    assert fig.problems == [], "\n".join(fig.problems[:20])
    assert fig.accepted + fig.rejected == N_MUTANTS
    # every kind reaches both sides of its validation (a mutator that only breaks syntax would test little)
    for kind, (accepted, rejected) in fig.by_kind.items():
        assert rejected >= 5, (kind, accepted, rejected)
    assert fig.accepted >= 10
