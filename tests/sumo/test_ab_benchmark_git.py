"""``benchmarks/ab.py`` where it needs git: an unknown revision is refused in one line (exit 2), and a side whose
run fails ends the comparison with exit 2 and the base's worktree removed (``git worktree list`` as before).
The options it refuses before any of this, and the instruction count it reads, are
``tests/unit/test_ab_benchmark.py``."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from tests.helpers import ROOT
from tests.unit.test_ab_benchmark import load_ab

pytestmark = pytest.mark.skipif(not (ROOT / ".git").exists(), reason="not a git checkout")


def _worktrees() -> str:
    return subprocess.run(["git", "-C", str(ROOT), "worktree", "list"], capture_output=True, text=True).stdout


def test_an_unknown_revision_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    assert load_ab().main(["no-such-revision-xyz", "--measure", "cpu"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"ab: base: no commit 'no-such-revision-xyz' in {ROOT}"


def test_a_failed_side_removes_its_worktree(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    before = _worktrees()
    assert load_ab().main(["HEAD", "--measure", "cpu", "--scenario", str(tmp_path / "missing.yaml")]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith("ab: the run in ") and "failed (exit" in err
    assert _worktrees() == before
