"""The golden test: fixed-seed runs of the demo, one scenario per paper family and one external net give
byte-identical outputs (wall-clock fields aside) to the hashes in ``tests/data/golden.json``.

It guards every refactor: a change that alters any number of any output fails here, naming the case and the
files. An intended change regenerates the hashes (``python -m tests.golden --update``, see ``tests/golden.py``).
Each case's run is made once per test session (``golden_run``, ``tests/golden/conftest.py``) and also read by
the checks of the same scenario (``test_demo_line3.py``). A case whose outputs depend on the machine's BLAS may
also match one of the outcomes recorded for it on other machines (``tests/data/golden_blas_variants.json``,
``tests.golden.accepted``); the message names the differences from each.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from tests.golden import CASES, accepted, blas_variants, differing, hash_outputs, run_outputs


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_outputs_are_byte_identical_to_golden(case, golden_run: Callable[[str], tuple[Path, int]]) -> None:
    expected, *variants = accepted(case.name)
    workdir, exit_code = golden_run(case.name)
    got = hash_outputs(case.name, workdir, exit_code)
    differ = differing(got, expected)
    assert not differ or got in variants, (
        f"{case.name}: outputs differ from tests/data/golden.json in {differ}"
        + "".join(
            f"; from its BLAS variant seen on {v['machine'][:60]!r} in {differing(got, v['hashes'])}"
            for v in blas_variants().get(case.name, [])
        )
        + "; if the change is intended, run `python -m tests.golden --update` and say why"
    )


def test_the_interpreted_modules_give_the_compiled_cores_bytes(tmp_path: Path) -> None:
    """The suite's golden runs load the compiled core (railsim.native) when it is built; its source is also the
    interpreted reference, which a machine without a C compiler runs: the demo on it gives the golden bytes too."""
    case = next(c for c in CASES if c.name == "demo_line3_peak")
    got = hash_outputs(case.name, tmp_path, run_outputs(case, tmp_path, reference=True))
    expected, *variants = accepted(case.name)
    assert got == expected or got in variants, (
        f"the interpreted demo differs from golden.json in {differing(got, expected)}"
    )
