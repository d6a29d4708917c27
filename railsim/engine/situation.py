"""What a train knows of itself at a step, as the control stage reads it before deciding.

:meth:`railsim.engine.control.ControlStage.control_all` first works out every train's :class:`Situation` at the
step's time (own odometry with any sensor noise, the gradient, the speed limits ahead, the next stop, the movement
authority, the formation's tail, what the ground reports of the train ahead), then decides train by train on them.
Both are plain compiled classes rather than tuples: their numbers stay unboxed on the way from one pass to the other.
:class:`RouteSpans` is what the situation keeps of a train's route from step to step (the gradient and the
restriction window, with the stretches of the front over which they hold: :class:`~railsim.engine.routeview.RouteView`'s
spans), so most steps ask the route nothing.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from controllers.base import SpeedLimit
from railsim.engine.routeview import RouteView

NO_LIMITS = np.zeros((0, 3))  # no restriction window yet (made at a train's first step)

_Target = tuple[float, float, float, bool] | None


class Situation:
    """What a train knows of itself at a step: own position and speed (with sensor noise), gradient, speed limits,
    the next stop (its TripStop) and, for it, ``target`` (mark behind any leader, window start, window end,
    dwelling) or None, the end of movement authority, and the length of the formation behind it (a restriction
    holds until the formation's rear clears it: the limits' ends move on by it, see :meth:`railsim.engine.control.ControlStage._base`), the
    limits as the compiled line step's array (made once per restriction window, with it), and what the ground
    reports of the rear of the train ahead, ``(rear, age)``, NaN: ask (``Knowledge.ground_rears``). (A class, not
    a tuple: compiled, its numbers stay unboxed between the situation pass and the decision.)"""

    __slots__ = (
        "own_pos_m",
        "own_v_mps",
        "grad",
        "limits",
        "stop",
        "target",
        "authority_m",
        "tail_m",
        "limits_arr",
        "rear",
    )

    def __init__(
        self,
        own_pos_m: float,
        own_v_mps: float,
        grad: float,
        limits: tuple[SpeedLimit, ...],
        stop: Any,
        target: _Target,
        authority_m: float | None,
        tail_m: float,
        limits_arr: np.ndarray,
        rear: tuple[float, float],
    ) -> None:
        self.own_pos_m = own_pos_m
        self.own_v_mps = own_v_mps
        self.grad = grad
        self.limits = limits
        self.stop = stop
        self.target = target
        self.authority_m = authority_m
        self.tail_m = tail_m
        self.limits_arr = limits_arr
        self.rear = rear


class RouteSpans:
    """What a train's situation keeps while the train stays where it holds (:class:`RouteView`'s spans): the
    gradient and the chainages ``[lo, hi)`` of the front it holds for; the restriction window, the ranges of the
    window's start and end it holds for, and the window as the kernels' array."""

    def __init__(self, view: RouteView) -> None:
        self.view = view
        self.grad = 0.0
        self.grad_lo_m = math.nan  # NaN: worked out at the first step
        self.grad_hi_m = math.nan
        self.limits: tuple[SpeedLimit, ...] = ()
        self.from_lo_m = math.nan
        self.from_hi_m = math.nan
        self.to_lo_m = math.nan
        self.to_hi_m = math.nan
        self.limits_arr: np.ndarray = NO_LIMITS
