"""Controller fallbacks are never silent: each one is an event, a count and (rate-limited) a WARNING line.

A controller that cannot compute its law — an infeasible or unsolved QP, a non-finite result — returns its
safe command with ``Command.fallback = True`` and says why in ``Command.info["fallback_reason"]``
(:func:`controllers.base.fallback_reason`). When such a command wins the arbitration, :class:`FallbackReporter`

* counts it on the train (``trips.csv`` ``fallbacks``, ``summary.json`` ``fallbacks``);
* records a ``controller_fallback`` event: subject the train, detail ``role`` (``ato``, ``coupled`` …),
  ``controller`` (the controller's class) and ``reason``;
* logs a WARNING, at most one line per train every ``log_interval_s`` of simulated time; the next line says
  how many fallbacks the interval held (a solver failing at every step would otherwise flood the terminal,
  while the events keep every one).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

from railsim.engine.events.log import EventLog

log = logging.getLogger(__name__)

LOG_INTERVAL_S = 60.0  # at most one WARNING line per train in this much simulated time


@dataclass
class _Quiet:
    """One train's rate limit: when it last logged and how many fallbacks were not logged since."""

    logged_s: float
    suppressed: int = 0


class FallbackReporter:
    """Counts, records and logs the controller fallbacks of a run (see the module docstring)."""

    def __init__(self, events: EventLog, log_interval_s: float = LOG_INTERVAL_S) -> None:
        self.events = events
        self.log_interval_s = float(log_interval_s)
        self._quiet: dict[str, _Quiet] = {}

    def report(self, t_s: float, train_id: str, role: str, controller: str, reason: str) -> None:
        """One fallback of ``train_id``'s ``role`` controller at ``t_s``: an event, and a WARNING if due."""
        self.events.record(t_s, "controller_fallback", train_id, role=role, controller=controller, reason=reason)
        quiet = self._quiet.get(train_id)
        if quiet is not None and t_s - quiet.logged_s < self.log_interval_s:
            quiet.suppressed += 1
            return
        more = f" ({quiet.suppressed} more since t = {quiet.logged_s:g} s)" if quiet and quiet.suppressed else ""
        log.warning("t = %g s: %s: %s controller (%s) fell back: %s%s", t_s, train_id, role, controller, reason, more)
        self._quiet[train_id] = _Quiet(logged_s=t_s)
