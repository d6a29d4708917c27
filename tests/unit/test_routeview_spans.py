"""A route's gradient and restriction window hold over the spans its view names (railsim/engine/routeview.py).

The control stage keeps a train's gradient and restriction window while the train stays inside the chainages
:meth:`RouteView.gradient_span` and :meth:`RouteView.limits_window` say they hold for, instead of looking them up
every step. On random routes — restrictions that overlap, touch, share starts or end before they start, gradients
with gaps between them, chainages before, on and past every boundary — every chainage inside a span must get the
same answer as asking afresh (the very same window tuple: the line ATO's kernel arrays are remembered by it), and a
chainage at the boundary itself must be judged as asking afresh does.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from railsim.engine.routeview import RouteView


def _view(rng: np.random.Generator, well_formed: bool) -> RouteView:
    length_m = 5000.0
    limits = []
    for _ in range(int(rng.integers(0, 9))):
        a = float(rng.choice([rng.uniform(0, length_m), 1000.0]))  # some share a start
        b = a + float(rng.uniform(0, 800)) * (1 if well_formed or rng.random() < 0.7 else -1)
        limits.append((a, b, float(rng.choice([8.0, 12.0, 16.0, 22.0]))))
    grades = []
    x = float(rng.uniform(-100, 300))
    for _ in range(int(rng.integers(0, 7))):
        b = x + float(rng.uniform(50, 900))
        grades.append((x, b, float(rng.uniform(-30, 30))))
        x = b + float(rng.choice([0.0, rng.uniform(0, 400)]))  # touching, or a gap without data
    route = SimpleNamespace(
        id="r", edges=("a",), edge_start_m=(0.0,), speed_limits=limits, gradients=grades, length_m=length_m
    )
    return RouteView(route)  # type: ignore[arg-type]


def _probes(rng: np.random.Generator, view: RouteView) -> list[float]:
    marks = [*view.limit_starts, *(lim.end_m for lim in view.limits), *(g[0] for g in view.grades)]
    marks += [g[1] for g in view.grades]
    near = [m + d for m in marks for d in (-1e-9, 0.0, 1e-9, math.nextafter(m, math.inf) - m)]
    return [*near, *rng.uniform(-500, 5500, 60)]


@pytest.mark.parametrize("seed", range(12))
def test_a_gradient_holds_over_its_span(seed: int) -> None:
    rng = np.random.default_rng(seed)
    view = _view(rng, True)
    probes = _probes(rng, view)
    for x in probes:
        g, lo, hi = view.gradient_span(x)
        assert lo <= x < hi and g == view.gradient_at(x)
        for y in probes:
            if lo <= y < hi:
                assert view.gradient_at(y) == g, (x, y, lo, hi)


@pytest.mark.parametrize("seed", range(12))
def test_a_restriction_window_holds_over_its_spans(seed: int) -> None:
    rng = np.random.default_rng(seed)
    view = _view(rng, seed % 4 != 0)
    probes = _probes(rng, view)
    for x in probes:
        to_x = x + float(rng.choice([0.0, 300.0, 1500.0]))
        got, f_lo, f_hi, t_lo, t_hi = view.limits_window(x, to_x)
        assert got == view.limits_ahead(x, to_x)
        if math.isnan(f_lo):  # a restriction ending before it starts: no window reasoning, nothing to keep
            assert not view._well_formed
            continue
        assert f_lo <= x < f_hi and t_lo <= to_x < t_hi
        for y in probes:
            to_y = y + float(rng.choice([0.0, 300.0, 1500.0]))
            if f_lo <= y < f_hi and t_lo <= to_y < t_hi:
                assert view.limits_ahead(y, to_y) is got, (x, to_x, y, to_y)
