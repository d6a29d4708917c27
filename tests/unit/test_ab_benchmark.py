"""``benchmarks/ab.py`` (this working tree against another commit): the instruction count it reads from
cachegrind's file, and a clear one-line refusal (exit 2) for options that cannot be compared, before any git or
SUMO work. What needs git (an unknown revision, a side that fails) is ``tests/sumo/test_ab_benchmark_git.py``; the
comparison itself runs the demo twice a side under valgrind (minutes): it is run by hand, its figures are in
docs/results."""

from __future__ import annotations

import importlib.util
from types import ModuleType

import pytest

from tests.helpers import ROOT

SCRIPT = ROOT / "benchmarks" / "ab.py"


def load_ab() -> ModuleType:
    """The script as a module (benchmarks/ is not a package)."""
    spec = importlib.util.spec_from_file_location("ab_benchmark", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_reads_the_summary_line() -> None:
    ab = load_ab()
    text = "desc: --cache-sim=no\ncmd: python\nevents: Ir\nfl=x.c\n1 5\n2 7\nsummary: 14097611321\n"
    assert ab.summary_instructions(text) == 14097611321
    with pytest.raises(ab.AbError, match="summary"):
        ab.summary_instructions("events: Ir\nfl=x.c\n1 5\n")


@pytest.mark.parametrize(
    ("argv", "says"),
    [
        (["HEAD", "--duration-s", "nan"], "--duration-s"),
        (["HEAD", "--duration-s", "-5"], "--duration-s"),
        (["HEAD", "--measure", "cpu", "--reps", "0"], "at least 1"),
    ],
)
def test_refuses_in_one_line(argv: list[str], says: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert load_ab().main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("ab: ") and says in err and "\n" not in err


def test_without_valgrind_says_so(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    ab = load_ab()
    monkeypatch.setattr(ab.shutil, "which", lambda name: None)
    assert ab.main(["HEAD"]) == 2
    assert "valgrind is not installed" in capsys.readouterr().err
