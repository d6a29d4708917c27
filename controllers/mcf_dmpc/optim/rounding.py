"""From continuous positions to model indices: the roundings of Paper A's optimisers (Eq. 21) and the chaos map (Eq. 22).

The MCF model-selection problem is integer: every coordinate of a solution picks one of ``n`` car-following laws.
Moth-flame, PSO and SA move points through continuous space, so every move ends with a *rounding* that must land
on a valid index — always, whatever the move produced (spirals overshoot, opposites go negative).

Two roundings live here, both in the paper's frame ``{lb, …, ub}`` (Paper A: lb = 1, ub = 3):

* :func:`cyclic_round` — Eq. (21), ``Round(m) = ⌈(⌊m⌋ − lb) mod ub⌉ + lb``. Out-of-range values wrap around
  periodically instead of piling up on the bounds. The printed ``mod ub`` only works because lb = 1; we use the
  general period ``ub − lb + 1`` (spec §2.7 (1)). The ceiling of an integer is a no-op and is dropped. The
  modulo is the non-negative one (MATLAB ``mod``, NumPy ``%``).
* :func:`clamp_round` — the classical alternative (floor, then clip to the bounds), used by plain MFO/PSO and by
  MSMFO when its cyclic rounding is switched off.

:func:`logistic_tent` is the Logistic–Tent chaotic map of Eq. (22). As printed the map is wrapped in "Round",
which turns the chaos value into an integer after one step; the published Logistic–Tent map takes the result
"mod 1" instead (spec A23). Both readings are provided: ``"suggested"`` (mod 1, default) and ``"literal"``
(Eq. 21 applied to the map output).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


def _check_bounds(lb: int, ub: int) -> None:
    if ub < lb:
        raise ValueError(f"rounding bounds need ub >= lb, got lb={lb}, ub={ub}")


def cyclic_round(x: ArrayLike, lb: int, ub: int) -> np.ndarray:
    """Eq. (21): wrap ``⌊x⌋`` periodically into ``{lb, …, ub}``; returns an ``int64`` array of ``x``'s shape.

    Non-finite input is a bug upstream (a diverging move) and raises ``ValueError`` rather than producing a
    garbage index.
    """
    _check_bounds(lb, ub)
    xf = np.asarray(x, dtype=float)
    if not np.all(np.isfinite(xf)):
        raise ValueError("cyclic_round: non-finite position")
    period = ub - lb + 1
    fl = np.floor(xf)
    if fl.size and float(np.max(np.abs(fl))) < 2.0**52:
        # Integer arithmetic after the floor: exact, non-negative modulo and ~5x cheaper than a float np.mod
        # (this runs on every moth move of MSMFO); spiral positions stay within a few box widths.
        return (fl.astype(np.int64) - lb) % period + lb
    # floor() yields integer-valued floats, so fmod/mod are exact and the result lies in [0, period) exactly.
    return (np.mod(fl - lb, period) + lb).astype(np.int64)


def clamp_round(x: ArrayLike, lb: int, ub: int) -> np.ndarray:
    """Floor, then clip into ``{lb, …, ub}`` (bound handling of classical MFO/PSO); ``int64`` array."""
    _check_bounds(lb, ub)
    xf = np.asarray(x, dtype=float)
    if not np.all(np.isfinite(xf)):
        raise ValueError("clamp_round: non-finite position")
    return np.clip(np.floor(xf), lb, ub).astype(np.int64)


def clamp_box_upper(ub: int) -> float:
    """Largest float strictly below ``ub + 1``: the open top of the continuous box ``[lb, ub + 1)``.

    In the continuous relaxation each integer ``v`` owns the cell ``[v, v + 1)``, so every index has the same
    measure; positions are clipped into ``[lb, clamp_box_upper(ub)]`` and floored.
    """
    return float(np.nextafter(float(ub + 1), -np.inf))


def logistic_tent(c: np.ndarray, r1: float, *, variant: str = "suggested", lb: int = 1, ub: int = 3) -> np.ndarray:
    """One step of the Logistic–Tent map, Eq. (22), element-wise.

    ``C' = r1·C·(1 − C) + ½(4 − r1)·C``        if C < 0.5
    ``C' = r1·C·(1 − C) + ½(4 − r1)·(1 − C)``  otherwise

    ``variant="suggested"`` returns ``C' mod 1`` (values in [0, 1)); ``variant="literal"`` returns
    ``cyclic_round(C', lb, ub)`` as printed (values in {lb, …, ub}, as floats).
    """
    c = np.asarray(c, dtype=float)
    logistic = r1 * c * (1.0 - c)
    tent = 0.5 * (4.0 - r1) * np.where(c < 0.5, c, 1.0 - c)
    out = logistic + tent
    if variant == "suggested":
        return np.mod(out, 1.0)
    if variant == "literal":
        return cyclic_round(out, lb, ub).astype(float)
    raise ValueError(f"logistic_tent: unknown variant {variant!r}")
