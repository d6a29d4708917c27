"""A line train's or a CACC follower's whole control step in one compiled call: laws, arbitration, plant.

Most trains on a line, most of the time, are *line trains*: the line ATO (:class:`controllers.ato.Ato`) and the
moving-block separation (:class:`controllers.separation.Separation`) against the train ahead, no formation role,
junction plan, collision avoidance, exact plant, actuator noise or bias. A coupled follower that is otherwise a line
train and whose coupled role is the CACC (:class:`controllers.cacc.Cacc`, on its leader's t2t state) differs by that
one role. ``ControlStage.control_all`` (:mod:`railsim.engine.control`), the one place where a train's commands are
decided, hands both to :func:`step`: the ATO, the CACC law (:func:`controllers.cacc_kernel.cacc`, only with a
coupled role), the separation (only with a known rear ahead), the smallest acceleration winning in that order (the
first on a tie, as :func:`controllers.base.arbitrate`), then the plant step — one call instead of three or four
Python-level calls and a few hundred interpreted float operations per train and step.

**Bit for bit** with the roles one by one (``ControlStage._role_commands``, ``arbitrate``, the plant): the same
law functions (:func:`controllers.line_kernels.ato`, :func:`controllers.line_kernels.separation`,
:func:`~controllers.cacc_kernel.cacc`, :func:`railsim.physics.plant_kernel.step`, each held to its interpreted form)
on the same values, the same comparison for arbitration (a NaN loses, as ``<`` does in Python);
``tests/unit/test_line_step_kernel.py`` compares the two. A non-finite winning command is handed back unstepped
(``ok`` False): the engine then records it and brakes. The golden test pins the whole loop.

The coupled role's inputs are one float array (``coupled``): the leader's state and the CACC's other inputs
(:data:`LEAD_FIELDS`), then the CACC's packed law (:data:`controllers.cacc_kernel.CACC_FIELDS`). A follower keeps
its array from step to step and refills the lead fields (:func:`coupled_inputs`, :func:`set_lead`); a line train
passes the empty :data:`NO_COUPLED`. One array, not nine more scalars, keeps what a line train's call costs extra
under a tenth of a microsecond. What the CACC keeps between steps (the reconstructed command of its leader) and the
vc bookkeeping stay in Python (``ControlStage._coupled_step``).

Compiled code is cached on disk per version of the kernel sources (:mod:`railsim.kernel_cache`).
"""

from __future__ import annotations

import numpy as np
from numba import njit, types

from controllers import cacc_kernel, line_kernels
from controllers.base import PredecessorState
from railsim.physics import plant_kernel

ROLE_ATO, ROLE_SEPARATION, ROLE_COUPLED = 0, 1, 2
ROLES = ("ato", "separation", "coupled")  # the role names, by index
# The coupled role's inputs, in the order of cacc_kernel.cacc: the leader's t2t state, the feed-forward the
# controller chose (Cacc.feed_forward_mps2), the formation's target gap and tracking (1.0, or 0.0: safety cap only)
LEAD_FIELDS = (
    "lead_rear_m",
    "lead_speed_mps",
    "lead_accel_mps2",
    "lead_emergency_decel_mps2",
    "lead_age_s",
    "lead_command_mps2",
    "target_gap_m",
    "tracking",
)
_N_LEAD = len(LEAD_FIELDS)
NO_COUPLED = np.zeros(0)  # a line train: no coupled role (the CACC is not asked)
# The types callers pass to :func:`step`, in its order (railsim.engine.kernel_entry: a caller that passes exactly
# these may call the compiled version directly; every array made float64, C-contiguous, aligned)
_A1, _A2 = types.Array(types.float64, 1, "C"), types.Array(types.float64, 2, "C")
_F, _B = types.float64, types.boolean
SIGNATURE = (_A1, _A1, _A1, types.int64, *(_F,) * 9, _A2, _B, _F, _F, _F, _B, _B, _F, _F, _B, _F, _F, _A1)


def coupled_inputs(cacc_p: np.ndarray) -> np.ndarray:
    """A follower's ``coupled`` array for its CACC's packed law ``cacc_p`` (the lead fields still to be set)."""
    return np.concatenate((np.zeros(_N_LEAD), cacc_p))


def set_lead(
    coupled: np.ndarray, lead: PredecessorState, lead_command_mps2: float, target_gap_m: float, tracking: bool
) -> None:
    """Write this step's :data:`LEAD_FIELDS` into a follower's ``coupled`` array: the leader's t2t state ``lead``,
    the feed-forward the CACC chose, the formation's target gap, tracking."""
    coupled[:_N_LEAD] = (
        lead.rear_position_m,
        lead.speed_mps,
        lead.accel_mps2,
        lead.emergency_decel_mps2,
        lead.age_s,
        lead_command_mps2,
        target_gap_m,
        1.0 if tracking else 0.0,
    )


@njit(cache=True)
def step(
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
    coupled: np.ndarray,
) -> tuple[float, bool, int, bool, float, float, float, float, int, float]:
    """``(command, emergency, role, ok, v_next, applied a_k, target u_k, traction energy, saturation mask, CACC
    target gap)``; the last is NaN without a coupled role.

    The laws see the train's own ``x``/``v`` (with sensor noise, if any), the plant steps its true ``v_plant``,
    ``applied`` and ``target``; ``has_rear``: the known rear of the train ahead (``rear_m``, ``age_s``) is given
    and separation runs; ``coupled``: the coupled role's inputs (module docstring), empty for none."""
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
    target_used_m = np.nan
    if coupled.size:
        vc_accel, vc_emergency, _, _, _, _, target_used_m = cacc_kernel.cacc(
            coupled[_N_LEAD:],
            x,
            v,
            applied,
            grade,
            coupled[0],
            coupled[1],
            coupled[2],
            coupled[3],
            coupled[4],
            coupled[5],
            coupled[6],
            coupled[7] != 0.0,
        )
        if vc_accel < accel:
            role, accel, emergency = ROLE_COUPLED, vc_accel, vc_emergency
    if has_rear:
        sep_accel, sep_emergency, _, _, _ = line_kernels.separation(sep_p, x, v, applied, grade, rear_m, age_s)
        if sep_accel < accel:
            role, accel, emergency = ROLE_SEPARATION, sep_accel, sep_emergency
    return _plant(plant_p, method, dt_s, v_plant, applied, target, grade, accel, emergency, role, target_used_m)


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
    target_used_m: float,
) -> tuple[float, bool, int, bool, float, float, float, float, int, float]:
    """The winning command into the plant; a non-finite one comes back unstepped (``ok`` False)."""
    if not (accel == accel and -np.inf < accel < np.inf):
        return accel, emergency, role, False, 0.0, 0.0, 0.0, 0.0, 0, target_used_m
    v_next, a, u, _, _, energy, mask = plant_kernel.step(
        plant_p, v_plant, applied, target, accel, dt_s, grade, emergency, method
    )
    return accel, emergency, role, True, v_next, a, u, energy, mask, target_used_m
