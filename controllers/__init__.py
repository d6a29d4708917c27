"""The algorithm library: observed state in, acceleration command out (see :mod:`controllers.base`).

No libsumo, no file I/O. Importing this package registers the built-in controllers by name so scenarios can
refer to them (``controllers: {ato: {type: ato}}``).
"""

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


def _register_builtins() -> None:
    # Imported for their @register side effect; each module is optional while the library grows.
    import importlib

    for mod in ("controllers.ato", "controllers.separation", "controllers.cacc", "controllers.speed_profile",
                "controllers.paper_a", "controllers.distributed", "controllers.ato_mpc", "controllers.monorail"):
        try:
            importlib.import_module(mod)
        except ModuleNotFoundError as exc:  # pragma: no cover - only while a module is not written yet
            if exc.name != mod:
                raise


_register_builtins()
