"""Ground truth each step: SUMO's reading of every train turned into its route chainage, edge pointer and checks.

SUMO moves the trains; railsim reads back where they are. Per step :meth:`TruthPass.read` takes the bridge's
reading (:class:`railsim.engine.sumo.TrainStates`: odometer, speed, lane position, edge and stop state of each
train) and, for all trains in one compiled call (:func:`railsim.engine.truth_kernel.truth_pass`):

* sets each train's front chainage (``TrainRuntime.front_m``, from the odometer) and the route edge under it
  (``TrainRuntime.edge_i``, the forward-only pointer every later phase uses);
* checks that railsim and SUMO agree on where the train is (the desync check: a train's advance fits its speed, and
  SUMO's edge and lane position give the same chainage); each train out of step is a ``desync`` event and stops the
  run (:meth:`railsim.engine.safety.SafetyMonitor.desync_found`);
* compares the speed SUMO applied with the one railsim sent: SUMO holds a train at its stop (railsim adopts the
  speed), and anything harder than the train's own brakes is an event
  (:meth:`~railsim.engine.safety.SafetyMonitor.speed_imposed`).

Its inputs are not gathered from the trains: they live in the engine's slot store (:mod:`railsim.engine.slots`,
a row per :class:`~railsim.engine.train.TrainRuntime` for its whole run, given the first time the train is read),
written when they change, and the compiled pass reads them in place by the trains' slots, with the memory a check
needs from the last one (each train's chainage and speed then). It also hands the occupancy index the step's
columns — route numbers, fronts, lengths, pointers — as arrays taken from the store and the pass, so nothing is
listed twice. What the later phases read on the trains (``front_m``, ``edge_i``, ``sumo_stopped_now``,
``sumo_edge``) is still written on each train: they read those fields many times per step.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from railsim.engine import slots, truth_kernel
from railsim.engine.occupancy import Occupancy
from railsim.engine.safety import SafetyMonitor
from railsim.engine.slots import SlotStore
from railsim.engine.train import TrainRuntime

if TYPE_CHECKING:
    from railsim.engine.sumo import TrainStates


class TruthPass:
    """Reads SUMO's truth into the trains and the occupancy index, with the desync and imposed-speed checks."""

    def __init__(
        self,
        occupancy: Occupancy,
        safety: SafetyMonitor,
        tolerance_m: float,
        dt_s: float,
        slots: SlotStore | None = None,
    ) -> None:
        self.occupancy = occupancy
        self.safety = safety
        self.tolerance_m = tolerance_m
        self.dt_s = dt_s
        self.slots = SlotStore(occupancy) if slots is None else slots
        self._check_no = 0
        self._last_t_s = 0.0
        self._scratch = np.empty(0), np.empty(0), np.empty(0, np.int8)  # railsim_m, sumo_m, verdict (reused)

    def read(self, t: float, active: list[TrainRuntime], truth: TrainStates) -> None:
        """This step's truth for ``active`` (in the order of ``truth``, the bridge's reading of their ids): chainage,
        pointer and SUMO's state into each train, the checks' events, and the occupancy index placed."""
        occ = self.occupancy
        store = self.slots
        store.index(active)
        edge_ids = truth.edge_ids
        speed = truth.speed_mps
        n = len(active)
        front = np.empty(n)
        edge_i = np.empty(n, np.int64)
        if len(self._scratch[0]) < n:
            self._scratch = np.empty(2 * n), np.empty(2 * n), np.empty(2 * n, np.int8)
        railsim_m, sumo_m, verdict = self._scratch
        self._check_no += 1
        r_off, r_edges, r_starts, r_keys, r_vals = occ.route_tables()
        table = store.table
        n_bad, n_imposed = truth_kernel.truth_pass(
            r_off,
            r_edges,
            r_starts,
            r_keys,
            r_vals,
            table,
            store.slots,
            truth.odometer_m,
            occ.edge_codes(edge_ids),
            truth.lane_pos_m,
            speed,
            self._check_no,
            t - self._last_t_s,
            self.tolerance_m,
            front,
            edge_i,
            verdict,
            railsim_m,
            sumo_m,
        )
        self._last_t_s = t
        stopped = truth.stopped.tolist()
        for tr, front_m, i, now, edge in zip(active, front.tolist(), edge_i.tolist(), stopped, edge_ids):
            tr.front_m, tr.edge_i, tr.sumo_stopped_now, tr.sumo_edge = front_m, i, now, edge
        if n_imposed:  # SUMO applies exactly the speed railsim sent (speed mode 32) unless it holds the train at a stop
            for k in np.flatnonzero(verdict[:n] & truth_kernel.IMPOSED).tolist():
                tr, sumo_v = active[k], float(speed[k])
                self.safety.speed_imposed(t, tr, sumo_v, float(table[store.slots[k], slots.SENT_MPS]), self.dt_s)
                tr.adopt_sumo_speed(t, sumo_v)
        if n_bad:
            out_of_step = np.flatnonzero(verdict[:n] & truth_kernel.DESYNC).tolist()
            self.safety.desync_found(t, active, out_of_step, railsim_m, sumo_m, edge_ids)
        occ.update_arrays(store.ids, store.routes, front, store.lengths_m, edge_i)
