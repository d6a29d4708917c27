"""The extension API: one base class with named no-op hooks, and the ordered set the ports call them through.

An extension overrides only the hooks it uses, like a simpy resource overrides ``_do_put``/``_do_get`` or a traci
``StepListener`` its ``step(t)``. The hooks, and the port that calls them:

=========================================  ======================  =============================================
hook                                       called by               when
=========================================  ======================  =============================================
``on_inserted(t, tr, chainage_m)``         the dispatcher          a train entered the world (exact plants)
``before_bookkeeping(t)``                  the step loop           after the truth checks (junction planning)
``before_comms(t, active)``                the step loop           after bookkeeping, before reports are sent
``ato_extras(t, tr)``                      the control stage       extra observation fields for the ATO role
``drives(train_id)``, ``commands(…)``      the control stage       the extension commands this train itself
``manages_lock(train_id, switch_id)``      the route locks         it requests this switch for this train
``defers_lock(train_id, switch_id)``       the route locks         this train may not request this switch yet
``follower_step(t, tr, formation, a)``     the formation book      per follower and step, before the state
                                                                   machine is fed (Paper D's follower FSM)
``t2t_receivers(train_id)``                the knowledge port      extra receivers of a train's t2t report
``summary()`` under ``summary_key``        the recorder            a dict merged into ``summary.json``
=========================================  ======================  =============================================

The ports hold an :class:`ExtensionSet`, built empty before them and filled once when the extensions are
installed (the extensions need the ports, the ports call the extensions: this is the one place the cycle is
closed). The set keeps, per hook, only the extensions that override it, in installation order, so a run without
extensions pays one empty loop per hook call.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, Any, ClassVar

if TYPE_CHECKING:  # pragma: no cover
    from controllers.base import Command
    from railsim.engine.extensions.context import ExtensionContext
    from railsim.engine.occupancy import Ahead
    from railsim.engine.train import TrainRuntime
    from railsim.scenario import FormationSpec, Scenario

HOOKS = (
    "on_inserted",
    "before_bookkeeping",
    "before_comms",
    "ato_extras",
    "drives",
    "manages_lock",
    "defers_lock",
    "follower_step",
    "t2t_receivers",
)


class Extension:
    """Paper-specific behaviour plugged into the engine; every hook is a no-op until a subclass overrides it.

    A subclass says whether it applies to a scenario (:meth:`applies`) and is built with the
    :class:`~railsim.engine.extensions.context.ExtensionContext` when it does.
    """

    summary_key: ClassVar[str | None] = None  # the key of summary() in summary.json (None: no summary)

    def __init__(self, ctx: ExtensionContext) -> None:
        self.ctx = ctx

    @classmethod
    def applies(cls, scenario: Scenario) -> bool:
        """True if this extension has something to do in ``scenario`` (only then is it built)."""
        return False

    def on_inserted(self, t: float, tr: TrainRuntime, chainage_m: float) -> None:
        """Train ``tr`` was handed to SUMO at route chainage ``chainage_m`` (an exact plant is created here)."""

    def before_bookkeeping(self, t: float) -> None:
        """The step's phase after the truth checks, before the stops, formations and locks are kept."""

    def before_comms(self, t: float, active: Sequence[TrainRuntime]) -> None:
        """The step's phase after bookkeeping, before the trains' reports are sent."""

    def ato_extras(self, t: float, tr: TrainRuntime) -> dict[str, Any]:
        """Extra fields of the ATO role's observation (``Observation.extras``) for ``tr``."""
        return {}

    def drives(self, train_id: str) -> bool:
        """True while this extension, not the roles, commands ``train_id`` (then :meth:`commands` is called)."""
        return False

    def commands(
        self,
        t: float,
        tr: TrainRuntime,
        a: Ahead | None,
        base: dict[str, Any],
        commands: dict[str, Command],
        own_pos_m: float,
        own_v_mps: float,
        fstate: str,
    ) -> None:
        """Add this extension's commands for a train it drives to ``commands`` (the ATO's is already there);
        ``base`` holds the observation fields every role shares, ``fstate`` the train's formation state."""

    def manages_lock(self, train_id: str, switch_id: str) -> bool:
        """True if this extension, not the engine's distance rule, requests ``switch_id`` for ``train_id``."""
        return False

    def defers_lock(self, train_id: str, switch_id: str) -> bool:
        """True while ``train_id`` may not request ``switch_id`` yet under the engine's distance rule (the switch is
        kept for trains the extension orders first). Deferring only withholds a request: the train's authority
        still ends before the switch, so it stops short of it."""
        return False

    def follower_step(self, t: float, tr: TrainRuntime, formation: FormationSpec, a: Ahead) -> None:
        """Follower ``tr`` of ``formation`` with train ``a`` ahead, before the formation state machine is fed."""

    def t2t_receivers(self, train_id: str) -> Iterable[str]:
        """Trains that receive ``train_id``'s t2t report besides its formation followers."""
        return ()

    def summary(self) -> dict[str, Any]:
        """What the extension measured, merged into ``summary.json`` under :attr:`summary_key`."""
        return {}


def _overrides(ext: Extension, hook: str) -> bool:
    return getattr(type(ext), hook) is not getattr(Extension, hook)


class ExtensionSet:
    """The extensions of a run, in installation order; the ports call their hooks through it (module docstring)."""

    def __init__(self) -> None:
        self.installed: tuple[Extension, ...] | None = None  # None until install(): the set-once slot
        self._by_hook: dict[str, tuple[Extension, ...]] = {hook: () for hook in HOOKS}

    def install(self, extensions: Sequence[Extension]) -> None:
        """Fill the set once, after the ports are built (installing twice is a programming error)."""
        if self.installed is not None:
            raise RuntimeError("the extensions are installed once")
        self.installed = tuple(extensions)
        self._by_hook = {hook: tuple(e for e in self.installed if _overrides(e, hook)) for hook in HOOKS}
        self._on_inserted = self._by_hook["on_inserted"]
        self._before_bookkeeping = self._by_hook["before_bookkeeping"]
        self._before_comms = self._by_hook["before_comms"]
        self._ato_extras = self._by_hook["ato_extras"]
        self._drives = self._by_hook["drives"]
        self._manages_lock = self._by_hook["manages_lock"]
        self._defers_lock = self._by_hook["defers_lock"]
        self._follower_step = self._by_hook["follower_step"]
        self._t2t_receivers = self._by_hook["t2t_receivers"]

    _on_inserted: tuple[Extension, ...] = ()
    _before_bookkeeping: tuple[Extension, ...] = ()
    _before_comms: tuple[Extension, ...] = ()
    _ato_extras: tuple[Extension, ...] = ()
    _drives: tuple[Extension, ...] = ()
    _manages_lock: tuple[Extension, ...] = ()
    _defers_lock: tuple[Extension, ...] = ()
    _follower_step: tuple[Extension, ...] = ()
    _t2t_receivers: tuple[Extension, ...] = ()

    def overriding(self, hook: str) -> tuple[Extension, ...]:
        """The installed extensions that override ``hook``, in order."""
        return self._by_hook[hook]

    def on_inserted(self, t: float, tr: TrainRuntime, chainage_m: float) -> None:
        for ext in self._on_inserted:
            ext.on_inserted(t, tr, chainage_m)

    def before_bookkeeping(self, t: float) -> None:
        for ext in self._before_bookkeeping:
            ext.before_bookkeeping(t)

    def before_comms(self, t: float, active: Sequence[TrainRuntime]) -> None:
        for ext in self._before_comms:
            ext.before_comms(t, active)

    def ato_extras(self, t: float, tr: TrainRuntime) -> dict[str, Any]:
        extras: dict[str, Any] = {}
        for ext in self._ato_extras:
            extras.update(ext.ato_extras(t, tr))
        return extras

    def driver_of(self, train_id: str) -> Extension | None:
        """The first extension that drives ``train_id`` now, or None (the roles command it)."""
        for ext in self._drives:
            if ext.drives(train_id):
                return ext
        return None

    def manages_lock(self, train_id: str, switch_id: str) -> bool:
        for ext in self._manages_lock:
            if ext.manages_lock(train_id, switch_id):
                return True
        return False

    def defers_lock(self, train_id: str, switch_id: str) -> bool:
        for ext in self._defers_lock:
            if ext.defers_lock(train_id, switch_id):
                return True
        return False

    def follower_step(self, t: float, tr: TrainRuntime, formation: FormationSpec, a: Ahead) -> None:
        for ext in self._follower_step:
            ext.follower_step(t, tr, formation, a)

    def t2t_receivers(self, train_id: str) -> Sequence[str]:
        if not self._t2t_receivers:
            return ()
        out: list[str] = []
        for ext in self._t2t_receivers:
            out.extend(ext.t2t_receivers(train_id))
        return out

    def summaries(self) -> dict[str, dict[str, Any]]:
        """Every installed extension's summary under its key (those without a key have none)."""
        return {e.summary_key: e.summary() for e in self.installed or () if e.summary_key is not None}
