"""Compile numba's kernels into their on-disk cache once, before the test processes need them.

The kernels (``@njit(cache=True)``: the line ATO, the free-run planner, the plant and step kernels, Paper A's MCF
and OPO optimisers) compile on first use and are then cached on disk (:mod:`railsim.kernel_cache`: one folder per
version of their sources). On a fresh clone nothing is cached yet, so without this step the first test process (and every child a test starts meanwhile) that reaches a kernel
compiles it itself — the same work done several times at once, and up to ~20 s of CPU inside one unit test.
``make test`` and ``make check`` run this module once, beside the lint (``python -m tests.warm``): it reaches the
kernels the way the suite does (Paper A's ``mcf_dmpc`` and ``opo_mcf_dmpc`` controllers on one observation, and a
short SUMO run of the mini line) and leaves their compiled code on disk. Where the cache is already warm it takes a
few seconds. It checks nothing: the tests do.
"""

from __future__ import annotations

import contextlib
import io
import os
import sys
import tempfile
from pathlib import Path

DATA = Path(__file__).resolve().parent / "data"


def paper000_kernels() -> None:
    """Paper A's controllers with the real optimiser (MSMFO and OPO kernels)."""
    import controllers.mcf_dmpc  # noqa: F401  (registers the controllers)
    from controllers.base import Observation, OwnState, PredecessorState, create
    from controllers.mcf_dmpc.spacing import paper000_vehicle

    kmh = 1 / 3.6
    vehicle = paper000_vehicle()
    pred = PredecessorState("T1", 2000.0, 220 * kmh, 0.0, 203.0, 0.0, 0.0, 0.8, 1.0)
    obs = Observation(0.0, 1.0, OwnState("T2", 1500.0, 200 * kmh, 0.0, 203.0), vehicle, 1e9, predecessor=pred)
    for name in ("mcf_dmpc", "opo_mcf_dmpc"):
        create(name, {"horizon_steps": 15, "population": 6, "iterations": 2, "seed": 7}, vehicle).command(obs)


def line_run_kernels() -> None:
    """A short SUMO run of the mini line (line ATO, free-run planner, plant and step kernels), in this process."""
    from railsim.cli.main import main as run_command

    with tempfile.TemporaryDirectory(prefix="railsim-warm-") as tmp:
        os.environ.setdefault("RAILSIM_CACHE", str(Path(tmp) / "cache"))
        with contextlib.redirect_stdout(io.StringIO()):
            code = run_command(
                ["run", str(DATA / "scenarios" / "mini_line.yaml"), "--out", f"{tmp}/out", "--no-progress"]
            )
        if code != 0:
            print(f"tests.warm: the mini line run ended with exit {code} (the tests will say why)", file=sys.stderr)


def main() -> int:
    """Warm every group; a failure is one line on stderr and exit 0 (the tests that reach it will fail and say why)."""
    for warm in (paper000_kernels, line_run_kernels):
        try:
            warm()
        except Exception as exc:  # noqa: BLE001 - warming checks nothing; the suite does
            print(f"tests.warm: {warm.__name__}: {type(exc).__name__}: {exc}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
