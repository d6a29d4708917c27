"""The algorithm library: observed state in, acceleration command out (see :mod:`controllers.base`).

No libsumo, no file I/O. Importing this package registers the built-in controllers by name so scenarios can
refer to them (``controllers: {ato: {type: ato}}``).
"""

# The built-in controller families, imported for their ``@register`` side effect, in this order (the registry
# keeps it). An explicit list: a misspelt or missing module fails here, at import, instead of leaving its
# controller types silently unknown to every scenario.
from controllers import ato, ato_mpc, cacc, distributed, mcf_dmpc, monorail, separation, speed_profile  # noqa: F401
from controllers.base import (  # noqa: F401  (re-exported API)
    Command,
    Controller,
    Observation,
    OwnState,
    PredecessorState,
    SpeedLimit,
    StopTarget,
    arbitrate,
    create,
    register,
    registered,
)
