"""A compiled kernel called through its entry point gives what its dispatcher gives (railsim/engine/kernel_entry.py).

:func:`kernel_entry.direct` hands back a kernel's compiled entry point only when a call's arguments have exactly
the declared types, else the dispatcher; :func:`kernel_entry.checked_array` refuses any array an entry point would
misread. On 600 of the random line trains and coupled followers of ``tests/unit/test_line_step_kernel.py``, the line step's
entry point for :data:`line_step_kernel.SIGNATURE` must be found and give the dispatcher's result, bit for bit.
"""

from __future__ import annotations

from itertools import islice

import numpy as np
import pytest
from numba import njit, types

from controllers.cacc import make_cacc
from railsim.engine import kernel_entry, line_step_kernel
from tests.unit.test_line_step_kernel import _cases, _known_rear


@njit(cache=False)
def _axpy(a: float, x: np.ndarray, flag: bool) -> float:
    return a * x[0] + (1.0 if flag else 0.0)


_AXPY_SIG = (types.float64, types.Array(types.float64, 1, "C"), types.boolean)


def test_direct_is_the_entry_point_only_for_the_declared_types() -> None:
    x = np.array([3.0, 4.0])
    args = (2.0, x, True)
    assert _axpy(*args) == 7.0  # compiled for these types
    entry = kernel_entry.direct(_axpy, args, _AXPY_SIG)
    assert entry is not _axpy and entry(*args) == 7.0 and entry(0.5, x, False) == 1.5
    assert entry(2, x, True) == 7.0  # an int for a float is that float
    # any other types, or another signature: the dispatcher itself
    _axpy(2, x, True)
    assert kernel_entry.direct(_axpy, (2, x, True), _AXPY_SIG) is _axpy
    assert kernel_entry.direct(_axpy, (2.0, x), _AXPY_SIG) is _axpy
    assert kernel_entry.direct(_axpy, args, (types.float32, *_AXPY_SIG[1:])) is _axpy
    # a function numba does not compile (NUMBA_DISABLE_JIT) is its own entry
    assert kernel_entry.direct(_axpy.py_func, args, _AXPY_SIG) is _axpy.py_func


@pytest.mark.parametrize(
    "bad",
    [
        np.zeros(3, dtype=np.int64),
        np.zeros(3, dtype=np.float32),
        np.zeros((3, 2)),
        np.zeros((3, 2))[:, 0],  # a strided view
        [0.0, 1.0],
    ],
)
def test_checked_array_refuses_what_an_entry_point_would_misread(bad: object) -> None:
    with pytest.raises(TypeError, match="float64, 1-D, C-contiguous"):
        kernel_entry.checked_array(bad, 1)  # type: ignore[arg-type]


def test_checked_array_passes_the_kernels_arrays() -> None:
    arr = np.zeros((4, 3))
    assert kernel_entry.checked_array(arr, 2) is arr
    assert kernel_entry.checked_array(line_step_kernel.NO_COUPLED, 1) is line_step_kernel.NO_COUPLED


def test_line_step_entry_point_is_the_dispatcher() -> None:
    """The line step as ControlStage calls it (tests/unit/test_line_step_kernel.py's arguments): its entry point for
    SIGNATURE exists, and a line train's and a CACC follower's step through it are the dispatcher's."""
    calls = []
    seen_coupled = 0
    for rng, case in islice(_cases(53), 600):
        dt, method = float(rng.choice([0.1, 0.5, 1.0])), "euler"
        known = _known_rear(rng, case.state[0], 600.0) if rng.random() < 0.6 else None
        coupled = line_step_kernel.NO_COUPLED
        if rng.random() < 0.3:
            ctl = make_cacc({"gap_policy": "safe"}, case.veh)
            coupled = kernel_entry.checked_array(line_step_kernel.coupled_inputs(ctl.packed(case.veh, dt)), 1)
            lead = (case.state[0] + float(rng.uniform(5.0, 80.0)), *rng.uniform(0.0, 20.0, 2), 1.2, 0.1, 0.0)
            coupled[:8] = (*lead, 30.0, 1.0)
            seen_coupled += 1
        calls.append(lambda m=method, d=dt, k=known, c=coupled, cs=case: cs.step(d, m, k, c))
    captured: list[tuple[object, ...]] = []
    step = line_step_kernel.step

    def capture(*args: object) -> tuple[object, ...]:
        captured.append(args)
        return step(*args)  # type: ignore[no-any-return]

    line_step_kernel.step = capture  # type: ignore[assignment]
    try:
        for call in calls:
            call()
    finally:
        line_step_kernel.step = step
    entry = kernel_entry.direct(step, captured[0], line_step_kernel.SIGNATURE)
    assert entry is not step, "the line step's arguments are not of line_step_kernel.SIGNATURE"
    for args in captured:
        assert repr(entry(*args)) == repr(step(*args))
    assert seen_coupled > 120
