"""Physically plausible magnitudes, read from the unit in a field's name.

Every number a scenario holds carries its unit in its name (``gap_m``, ``accel_mps2``, ``speed_kmh``,
``duration_s``: docs/architecture.md, conventions), so one table bounds them all, including the free parameter
blocks handed to controllers (``controllers.lead.params.segments[0].to_kmh``) and worlds. A finite value of
absurd size is as harmful as ``inf``: a start speed of 1e308 km/h passes ``> 0`` and turns into NaN in the braking
curve, a gap of −9.2e18 m overflows every sum it enters. The bounds are generous — far beyond any railway (a
maglev runs at 600 km/h, an emergency brake at 3 m/s²) — so they only catch values that cannot be meant::

    suffix   quantity       unit    |value| at most
    _kmh     speed          km/h    1,000
    _mps     speed          m/s     300
    _mps2    acceleration   m/s²    100
    _mps3    jerk           m/s³    10,000,000       (1e6 stands for "no jerk limit")
    _m       length         m       1,000,000        (1,000 km)
    _km      chainage       km      10,000
    _s       time           s       10,000,000       (~116 days)
    _kg      mass           kg      100,000,000
    _t       mass           t       100,000
    (other)  number         -       1e12             (weights, gains, factors, coefficients ``x_per_y``:
                                                      only the absurd is refused)

:func:`plausible_number` checks one value by its field name; :func:`walk_numbers` yields every number of a nested
parameter block with its path, for :meth:`railsim.scenario.validate.Checker.plausible_tree`. Lower bounds and
cross-field rules (``duration_s >= step_s``) stay with each field's own check.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from typing import Any

# suffix -> (quantity, unit, largest plausible magnitude); longest suffix first where one ends another
UNIT_BOUNDS: tuple[tuple[str, str, str, float], ...] = (
    ("_mps3", "jerk", "m/s^3", 1e7),  # 1e6 is the papers' "no jerk limit"
    ("_mps2", "acceleration", "m/s^2", 100.0),
    ("_mps", "speed", "m/s", 300.0),
    ("_kmh", "speed", "km/h", 1e3),
    ("_km", "chainage", "km", 1e4),
    ("_kg", "mass", "kg", 1e8),
    ("_m", "length", "m", 1e6),
    ("_s", "time", "s", 1e7),
    ("_t", "mass", "t", 1e5),
)
OTHER_BOUND = 1e12  # a number without a unit in its name (a weight, a gain, a factor)

_INDEX_RE = re.compile(r"\[\d+\]$")


def field_name(path: str) -> str:
    """The last name of a field path: ``services[0].start.speed_kmh`` → ``speed_kmh``; ``times[3]`` → ``times``."""
    last = path.rsplit(".", 1)[-1]
    while _INDEX_RE.search(last):
        last = _INDEX_RE.sub("", last)
    return last


def unit_bound(name: str) -> tuple[str, str, float]:
    """``(quantity, unit, largest magnitude)`` for a field named ``name`` (by its unit suffix)."""
    if "_per_" in name:  # a coefficient (davis_b_n_per_mps): its unit is not its suffix's
        return "number", "", OTHER_BOUND
    for suffix, quantity, unit, bound in UNIT_BOUNDS:
        if name.endswith(suffix):
            return quantity, unit, bound
    return "number", "", OTHER_BOUND


def as_float(value: int | float) -> float:
    """``float(value)``; an int too large for a float is ``inf`` (``float(10**400)`` would raise)."""
    try:
        return float(value)
    except OverflowError:
        return math.inf if value > 0 else -math.inf


def plausible_number(value: float, path: str) -> str | None:
    """``None`` if ``value`` is finite and plausible for the field at ``path``, else what was expected."""
    quantity, unit, bound = unit_bound(field_name(path))
    in_unit = f" in {unit}" if unit else ""
    if not math.isfinite(value):
        return f"a finite {quantity}{in_unit}"
    if abs(value) > bound:
        article = "an" if quantity[0] in "aeiou" else "a"
        return f"{article} {quantity}{in_unit} of magnitude at most {bound:g} (physically plausible)"
    return None


def walk_numbers(value: Any, path: str) -> Iterator[tuple[str, float]]:
    """Every int/float (not bool) in a nested mapping/list ``value``, with its field path."""
    stack: list[tuple[str, Any]] = [(path, value)]
    while stack:
        where, v = stack.pop()
        if isinstance(v, bool):
            continue
        if isinstance(v, (int, float)):
            yield where, as_float(v)
        elif isinstance(v, dict):
            stack.extend((f"{where}.{k}" if where else str(k), item) for k, item in reversed(list(v.items())))
        elif isinstance(v, (list, tuple)):
            stack.extend((f"{where}[{i}]", item) for i, item in reversed(list(enumerate(v))))
