"""A line train's (or coupled follower's) whole control step in one compiled call: laws, arbitration, plant.

Most trains on a line, most of the time, are *line trains*: the line ATO (:class:`controllers.ato.Ato`) and the
moving-block separation (:class:`controllers.separation.Separation`) against the train ahead, no formation role,
junction plan, collision avoidance, exact plant, actuator noise or bias. ``ControlStage.control_all``
(:mod:`railsim.engine.control`), the one place where a train's commands are decided, hands them here: both laws,
the smaller acceleration wins (the ATO on a tie, as :func:`controllers.base.arbitrate`), then the plant step — one
call instead of three Python-level calls and a few hundred interpreted float operations per train and step.

**Bit for bit** with the roles one by one (``ControlStage._role_commands``, ``arbitrate``, the plant): the same
law functions (:func:`controllers.line_kernels.ato`, :func:`controllers.line_kernels.separation`,
:func:`railsim.physics.plant_kernel.step`, each held to its interpreted form) on the same values, the same comparison
for arbitration (a NaN from separation loses, as ``<`` does in Python); ``tests/unit/test_line_step_kernel.py``
compares the two. A non-finite winning command is handed back unstepped (``ok`` False): the engine then records it
and brakes. The golden test pins the whole loop.

A coupled follower whose roles are the same line ATO, a CACC (:class:`controllers.cacc.Cacc`) on its leader's t2t
state and, with another train between them, the line separation, with the standard plant and no actuator fault,
is decided the same way by :func:`coupled_step`: the ATO, the CACC law (:func:`controllers.cacc_kernel.cacc`), the
separation, the minimum in that order, the plant. What the CACC keeps between steps (the reconstructed command of
its leader) and the vc bookkeeping (degraded/restored, the effective target gap) stay in Python
(``ControlStage._coupled_step``). ``tests/unit/test_line_step_kernel.py`` holds it to the roles one by one.

Compiled code is cached on disk per version of the kernel sources (:mod:`railsim.kernel_cache`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from controllers import cacc_kernel, line_kernels
from railsim.physics import plant_kernel

ROLE_ATO, ROLE_SEPARATION, ROLE_COUPLED = 0, 1, 2
ROLES = ("ato", "separation", "coupled")  # the role names, by index


@njit(cache=True)
def line_step(
    ato_p: np.ndarray,
    sep_p: np.ndarray,
    plant_p: np.ndarray,
    method: int,
    dt_s: float,
    x: float,
    v: float,
    v_plant: float,
    applied: float,
    target: float,
    length_m: float,
    grade: float,
    line_speed_mps: float,
    limits: np.ndarray,
    has_stop: bool,
    mark_m: float,
    window_start_m: float,
    window_end_m: float,
    dwelling: bool,
    has_authority: bool,
    authority_end_m: float,
    tail_m: float,
    has_rear: bool,
    rear_m: float,
    age_s: float,
) -> tuple[float, bool, int, bool, float, float, float, float, int]:
    """``(command, emergency, role, ok, v_next, applied a_k, target u_k, traction energy, saturation mask)``.

    The laws see the train's own ``x``/``v`` (with sensor noise, if any), the plant steps its true ``v_plant``,
    ``applied`` and ``target``; ``has_rear``: the known rear of the train ahead (``rear_m``, ``age_s``) is given
    and separation runs."""
    accel, emergency, _ = line_kernels.ato(
        ato_p,
        x,
        v,
        applied,
        length_m,
        grade,
        line_speed_mps,
        limits,
        has_stop,
        mark_m,
        window_start_m,
        window_end_m,
        dwelling,
        has_authority,
        authority_end_m,
        tail_m,
    )
    role = ROLE_ATO
    if has_rear:
        sep_accel, sep_emergency, _, _, _ = line_kernels.separation(sep_p, x, v, applied, grade, rear_m, age_s)
        if sep_accel < accel:
            role, accel, emergency = ROLE_SEPARATION, sep_accel, sep_emergency
    return _plant(plant_p, method, dt_s, v_plant, applied, target, grade, accel, emergency, role)


@njit(cache=True)
def coupled_step(
    ato_p: np.ndarray,
    sep_p: np.ndarray,
    plant_p: np.ndarray,
    method: int,
    dt_s: float,
    x: float,
    v: float,
    v_plant: float,
    applied: float,
    target: float,
    length_m: float,
    grade: float,
    line_speed_mps: float,
    limits: np.ndarray,
    has_stop: bool,
    mark_m: float,
    window_start_m: float,
    window_end_m: float,
    dwelling: bool,
    has_authority: bool,
    authority_end_m: float,
    tail_m: float,
    has_rear: bool,
    rear_m: float,
    age_s: float,
    cacc_p: np.ndarray,
    lead_rear_m: float,
    lead_speed_mps: float,
    lead_accel_mps2: float,
    lead_emergency_decel_mps2: float,
    lead_age_s: float,
    lead_command_mps2: float,
    target_gap_m: float,
    tracking: bool,
) -> tuple[float, bool, int, bool, float, float, float, float, int, float]:
    """A coupled follower's step: the ATO, the CACC on its leader's t2t state (``lead_*``; ``lead_command_mps2``
    the feed-forward the controller chose, :meth:`controllers.cacc.Cacc.feed_forward_mps2`), the separation
    against another train ahead (``has_rear``), the smallest acceleration winning in that order (the first on a
    tie), then the plant. :func:`line_step`'s result, then the CACC's effective target gap."""
    accel, emergency, _ = line_kernels.ato(
        ato_p,
        x,
        v,
        applied,
        length_m,
        grade,
        line_speed_mps,
        limits,
        has_stop,
        mark_m,
        window_start_m,
        window_end_m,
        dwelling,
        has_authority,
        authority_end_m,
        tail_m,
    )
    role = ROLE_ATO
    vc_accel, vc_emergency, _, _, _, _, target_used_m = cacc_kernel.cacc(
        cacc_p,
        x,
        v,
        applied,
        grade,
        lead_rear_m,
        lead_speed_mps,
        lead_accel_mps2,
        lead_emergency_decel_mps2,
        lead_age_s,
        lead_command_mps2,
        target_gap_m,
        tracking,
    )
    if vc_accel < accel:
        role, accel, emergency = ROLE_COUPLED, vc_accel, vc_emergency
    if has_rear:
        sep_accel, sep_emergency, _, _, _ = line_kernels.separation(sep_p, x, v, applied, grade, rear_m, age_s)
        if sep_accel < accel:
            role, accel, emergency = ROLE_SEPARATION, sep_accel, sep_emergency
    accel, emergency, role, ok, v_next, a, u, energy, mask = _plant(
        plant_p, method, dt_s, v_plant, applied, target, grade, accel, emergency, role
    )
    return accel, emergency, role, ok, v_next, a, u, energy, mask, target_used_m


@njit(cache=True)
def _plant(
    plant_p: np.ndarray,
    method: int,
    dt_s: float,
    v_plant: float,
    applied: float,
    target: float,
    grade: float,
    accel: float,
    emergency: bool,
    role: int,
) -> tuple[float, bool, int, bool, float, float, float, float, int]:
    """The winning command into the plant; a non-finite one comes back unstepped (``ok`` False)."""
    if not (accel == accel and -np.inf < accel < np.inf):
        return accel, emergency, role, False, 0.0, 0.0, 0.0, 0.0, 0
    v_next, a, u, _, _, energy, mask = plant_kernel.step(
        plant_p, v_plant, applied, target, accel, dt_s, grade, emergency, method
    )
    return accel, emergency, role, True, v_next, a, u, energy, mask
