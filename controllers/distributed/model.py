"""Per-train model data of Paper C (Zhang, Chen & Fang, spec 002): the train parameters and the windows they imply.

Paper C models every train as a point mass in discrete time with sampling period ``T`` (spec 002 eq. (1))::

    x_i(k+1) = x_i(k) + T·v_i(k)                      (explicit / forward Euler in position)
    v_i(k+1) = v_i(k) + T·(u_i(k) − f_i(v_i(k)))
    f_i(v)   = a_i + b_i·v + c_i·v²                    (Davis resistance per unit mass)

Everything is **per unit mass**: ``u``, ``μ`` and ``f`` are specific forces in m/s² (= N/kg), so the Davis
coefficients carry the units m/s², 1/s and 1/m. Only train-local quantities live here (spec 002 §2.10): the
resistance, the velocity bounds ``[ρ̲, ρ̄]`` and the input bounds ``[μ̲, μ̄]``. The reference speed ``v_r`` is the
one global constant every train knows (Assumption 2.3) and is passed alongside.

From these and ``T`` follow the two *constant* halves of the control law's saturation window (eq. (10)):

* the velocity window ``β̲ = (ρ̲ − v_r)·T``, ``β̄ = (ρ̄ − v_r)·T`` — the one-step displacement ``s`` the train may
  add to the moving frame without leaving ``[ρ̲, ρ̄]`` (the law assigns ``v(k+1) = v_r + s/T`` dead-beat);
* the input window ``η̲ = ρ̄·T + (μ̲ − f̲)·T² − v_r·T``, ``η̄ = ρ̲·T + (μ̄ − f̄)·T² − v_r·T`` — the ``s`` that keeps
  ``u`` inside ``[μ̲, μ̄]`` whatever admissible speed the train has now. ``f̲``/``f̄`` are the exact minimum and
  maximum of the quadratic ``f`` on ``[ρ̲, ρ̄]`` (endpoints plus the vertex when it lies inside; erratum A12).

Assumption 2.4 is exactly ``η̲ < 0 < η̄``; solved for ``T`` it is the lower bound ``T > T_min`` of
:func:`min_sample_time_s` (the dead-beat law must be able to reach ``v_r`` from any admissible speed in one step).
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class TrainParams:
    """The local parameters of one train (spec 002 §2.1, §2.3, all per unit mass).

    The paper's symbols: ``resist_a_mps2`` = a_i, ``resist_b_per_s`` = b_i, ``resist_c_per_m`` = c_i,
    ``speed_min_mps`` = ρ̲_i, ``speed_max_mps`` = ρ̄_i, ``input_min_mps2`` = μ̲_i, ``input_max_mps2`` = μ̄_i.
    No checks here: :mod:`controllers.distributed.validate` reports every violated assumption at once.
    """

    resist_a_mps2: float
    resist_b_per_s: float
    resist_c_per_m: float
    speed_min_mps: float
    speed_max_mps: float
    input_min_mps2: float
    input_max_mps2: float

    def resistance_mps2(self, speed_mps: float) -> float:
        """Davis resistance per unit mass ``f_i(v) = a + b·v + c·v²`` [m/s²] (the paper's form, any sign of v)."""
        return self.resist_a_mps2 + self.resist_b_per_s * speed_mps + self.resist_c_per_m * speed_mps * speed_mps

    def resistance_bounds_mps2(self) -> tuple[float, float]:
        """``(f̲, f̄)``: min and max of ``f`` over ``[ρ̲, ρ̄]``, exact for the quadratic (vertex included)."""
        candidates = [self.speed_min_mps, self.speed_max_mps]
        c = self.resist_c_per_m
        if c != 0.0:
            vertex = -self.resist_b_per_s / (2.0 * c)
            if self.speed_min_mps < vertex < self.speed_max_mps:
                candidates.append(vertex)
        values = [self.resistance_mps2(v) for v in candidates]
        return min(values), max(values)


@dataclass(frozen=True)
class LocalWindows:
    """The constant parts of train i's saturation window for one ``(T, v_r)`` [m of displacement per step]."""

    beta_lo_m: float
    beta_hi_m: float
    eta_lo_m: float
    eta_hi_m: float
    resist_min_mps2: float  # f̲_i
    resist_max_mps2: float  # f̄_i

    @property
    def hard_lo_m(self) -> float:
        """``max(β̲, η̲)``: the lower physical limit on ``s`` (velocity and input bounds together)."""
        return max(self.beta_lo_m, self.eta_lo_m)

    @property
    def hard_hi_m(self) -> float:
        """``min(β̄, η̄)``: the upper physical limit on ``s``."""
        return min(self.beta_hi_m, self.eta_hi_m)


def local_windows(params: TrainParams, sample_time_s: float, v_ref_mps: float) -> LocalWindows:
    """β̲, β̄, η̲, η̄ of eq. (10) (with the printed typo "β̲ twice" corrected: the second one is β̄)."""
    t = sample_time_s
    f_lo, f_hi = params.resistance_bounds_mps2()
    return LocalWindows(
        beta_lo_m=(params.speed_min_mps - v_ref_mps) * t,
        beta_hi_m=(params.speed_max_mps - v_ref_mps) * t,
        eta_lo_m=params.speed_max_mps * t + (params.input_min_mps2 - f_lo) * t * t - v_ref_mps * t,
        eta_hi_m=params.speed_min_mps * t + (params.input_max_mps2 - f_hi) * t * t - v_ref_mps * t,
        resist_min_mps2=f_lo,
        resist_max_mps2=f_hi,
    )


def min_sample_time_s(params: TrainParams, v_ref_mps: float) -> float:
    """``T_min,i = max{(ρ̄ − v_r)/(f̲ − μ̲), (v_r − ρ̲)/(μ̄ − f̄)}`` [s]; Assumption 2.4 holds iff ``T > T_min``.

    Requires the first two inequalities of Assumption 2.4 (``μ̲ < f̲``, ``f̄ < μ̄``); ``math.inf`` otherwise, since
    then no sampling period works.
    """
    f_lo, f_hi = params.resistance_bounds_mps2()
    down = f_lo - params.input_min_mps2
    up = params.input_max_mps2 - f_hi
    if not (down > 0.0 and up > 0.0):
        return math.inf
    return max((params.speed_max_mps - v_ref_mps) / down, (v_ref_mps - params.speed_min_mps) / up)
