"""Paper D (Hou et al. 2026, spec 003): monorail virtual coupling and active collision avoidance, pure controllers.

Modules:

* :mod:`.vehicle_model` — point-mass monorail with transmission delay, response lag and efficiency (Eq. 5 Form B,
  Eq. 17), load cases from the Chongqing Line 3 data pack; a pure ``plant_step`` and the MPC prediction matrices;
* :mod:`.braking_modes` — safety distance (Eqs 23–26) and the ADBM / RDBM policies;
* :mod:`.states` — the follower VC state machine with passive/active decoupling and CA hysteresis;
* :mod:`.mpc` — the OSQP gap-tracking QP shared by the DMPC and the CA-MPC;
* :mod:`.coupling` — ``monorail_apf`` and ``monorail_dmpc`` for the ``coupled`` role;
* :mod:`.collision_avoidance` — ``monorail_ca``, an extra role driven by ``obs.extras["sensor"]``;
* :mod:`.scenarios` — the paper's six scenarios (empty/loaded) as a pure-numpy runner with metrics.

Importing the package registers the three controllers.
"""

from controllers.monorail import collision_avoidance, coupling, policy_separation  # noqa: F401  (registers)
from controllers.monorail.braking_modes import BrakingPolicy, safety_distance_m  # noqa: F401
from controllers.monorail.collision_avoidance import CaParams, CollisionAvoidance, sensor_extras  # noqa: F401
from controllers.monorail.coupling import ApfParams, DmpcParams, MonorailApf, MonorailDmpc  # noqa: F401
from controllers.monorail.scenarios import SCENARIOS, build_scenario, run_scenario  # noqa: F401
