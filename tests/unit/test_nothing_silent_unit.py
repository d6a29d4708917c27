"""A controller that falls back leaves an event with its reason and a WARNING line.

Here: the tests of it that start no process; the others are in ``tests/sumo/test_nothing_silent.py``.
"""

from __future__ import annotations

import pytest


def test_numpy_floating_point_warnings_fail_in_process() -> None:
    import numpy as np

    with pytest.raises(RuntimeWarning, match="invalid value"):
        np.sqrt(np.float64(-1.0))
