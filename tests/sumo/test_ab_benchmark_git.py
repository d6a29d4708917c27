"""``benchmarks/ab.py`` where it needs git: an unknown revision is refused in one line (exit 2), a side whose run
fails ends the comparison with exit 2 and both worktrees removed (``git worktree list`` as before), and the
``head`` side carries the checkout's uncommitted work.
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
    argv = ["HEAD", "--measure", "cpu", "--core", "interpreted", "--scenario", str(tmp_path / "missing.yaml")]
    assert load_ab().main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith("ab: the run in ") and "failed (exit" in err
    assert _worktrees() == before


def test_head_side_carries_the_uncommitted_work(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The ``head`` side is a worktree of HEAD with this checkout's changes to tracked files applied and its
    untracked files (not the ignored ones) copied: a repository with one of each, made here."""
    repo = tmp_path / "repo"
    repo.mkdir()

    def git(*args: str, cwd: Path = repo) -> None:
        subprocess.run(
            ["git", "-c", "user.name=t", "-c", "user.email=t@t", *args], cwd=cwd, check=True, capture_output=True
        )

    git("init", "-q")
    (repo / "pkg").mkdir()
    (repo / "pkg" / "kept.py").write_text("A = 1\n")
    (repo / "pkg" / "changed.py").write_text("B = 1\n")
    (repo / ".gitignore").write_text("*.log\n")
    git("add", ".")
    git("commit", "-q", "-m", "one")
    (repo / "pkg" / "changed.py").write_text("B = 2\n")  # a change to a tracked file
    (repo / "pkg" / "new").mkdir()
    (repo / "pkg" / "new" / "added.py").write_text("C = 3\n")  # untracked
    (repo / "run.log").write_text("ignored\n")  # ignored: not carried
    ab = load_ab()
    monkeypatch.setattr(ab, "ROOT", repo)
    head = tmp_path / "head"
    git("worktree", "add", "--detach", str(head), "HEAD")
    ab._carry_changes(head)
    assert (head / "pkg" / "kept.py").read_text() == "A = 1\n"
    assert (head / "pkg" / "changed.py").read_text() == "B = 2\n"
    assert (head / "pkg" / "new" / "added.py").read_text() == "C = 3\n"
    assert not (head / "run.log").exists()
