"""The golden runs, each made once per test session and read by every test that needs it.

:func:`golden_run` runs a case of :data:`tests.golden.CASES` the first time a test (on any xdist worker) asks
for it, in a session-shared folder under a file lock (:func:`tests.helpers.shared_run`); the byte-for-byte
comparison (``test_golden.py``) and the checks read from the same run (``test_demo_line3.py`` reads the demo
case) then share one SUMO run instead of making one each.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from tests.golden import CASES, Case, run_outputs
from tests.helpers import shared_run

EXIT_CODE_FILE = "exit_code"


@pytest.fixture(scope="session")
def golden_run(tmp_path_factory: pytest.TempPathFactory) -> Callable[[str], tuple[Path, int]]:
    """``golden_run(name)``: (the case's work folder, with its outputs in ``out/``; the run's exit code)."""
    by_name: dict[str, Case] = {c.name: c for c in CASES}

    def get(name: str) -> tuple[Path, int]:
        case = by_name[name]

        def make(workdir: Path) -> None:
            (workdir / EXIT_CODE_FILE).write_text(str(run_outputs(case, workdir)), encoding="utf-8")

        workdir = shared_run(tmp_path_factory, f"golden-{name}", make)
        return workdir, int((workdir / EXIT_CODE_FILE).read_text(encoding="utf-8"))

    return get
