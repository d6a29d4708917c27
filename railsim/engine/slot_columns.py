"""The columns of the slot table (:mod:`railsim.engine.slots`): one float row per train, these fields in this order.

Inputs of the truth pass written when they change (:data:`ROUTE` … :data:`LENGTH_M`), then its memory of each
train's last check and its outputs. Route numbers and pointers are small integers, exact in a double. A module of its
own so that the train (:mod:`railsim.engine.train`, whose resident fields write these columns), the store and the
compiled pass (:mod:`railsim.engine.truth_kernel`) name them without importing each other.
"""

from __future__ import annotations

import math

ROUTE, DEPART_M, HINT, REVERSING, SENT_MPS, LENGTH_M, PREV_FRONT_M, PREV_SPEED_MPS, SEEN, FRONT_M = range(10)
N_COLUMNS = 10
NO_SPEED = math.nan  # no speed handed to SUMO yet: SUMO's is not compared
NEVER_SEEN = -2.0  # SEEN of a slot never checked
