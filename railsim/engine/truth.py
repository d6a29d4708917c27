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

It also hands the occupancy index the step's columns — route numbers, fronts, lengths, pointers — as the arrays the
pass made, so nothing is listed twice. The memory a check needs from the last one (each train's chainage and speed
then) is kept in per-train *slots*: a row per :class:`~railsim.engine.train.TrainRuntime` for its whole run, given
the first time the train is read.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from railsim.engine import truth_kernel
from railsim.engine.occupancy import Occupancy
from railsim.engine.safety import SafetyMonitor
from railsim.engine.train import TrainRuntime

if TYPE_CHECKING:
    from railsim.engine.sumo import TrainStates

_NO_SPEED = math.nan  # a train railsim has sent no speed yet: SUMO's is not compared


class TruthPass:
    """Reads SUMO's truth into the trains and the occupancy index, with the desync and imposed-speed checks."""

    def __init__(self, occupancy: Occupancy, safety: SafetyMonitor, tolerance_m: float, dt_s: float) -> None:
        self.occupancy = occupancy
        self.safety = safety
        self.tolerance_m = tolerance_m
        self.dt_s = dt_s
        self._slots = 0  # slots handed out
        self._memory = _memory(64)  # slot -> (chainage, SUMO's speed, number of the check) when last seen
        self._check_no = 0
        self._last_t_s = 0.0

    def _slot(self, tr: TrainRuntime) -> int:
        """``tr``'s slot (given on first use, when a train is read for the first time; the memory grows by
        doubling)."""
        if tr.slot < 0:
            tr.slot = self._slots
            self._slots += 1
            if self._slots > len(self._memory):
                self._memory = np.concatenate([self._memory, _memory(len(self._memory))])
        return tr.slot

    def _rows(self, active: list[TrainRuntime]) -> np.ndarray:
        """The trains' inputs to the pass, a float row each (columns ``truth_kernel.SLOT`` … ``SENT_MPS``)."""
        route_of = self.occupancy.route_of
        try:
            rows = [
                (
                    tr.slot if tr.slot >= 0 else self._slot(tr),
                    route_of[id(tr.view)],
                    tr.depart_chainage_m,
                    tr.edge_i,
                    tr.reversing,
                    _NO_SPEED if tr.sent_speed_mps is None else tr.sent_speed_mps,
                )
                for tr in active
            ]
        except KeyError:  # a route not seen before: registered first
            self.occupancy.route_numbers([tr.view for tr in active])
            return self._rows(active)
        return np.array(rows, float).reshape(len(rows), truth_kernel.N_COLUMNS)

    def read(self, t: float, active: list[TrainRuntime], truth: TrainStates) -> None:
        """This step's truth for ``active`` (in the order of ``truth``, the bridge's reading of their ids): chainage,
        pointer and SUMO's state into each train, the checks' events, and the occupancy index placed."""
        occ = self.occupancy
        edge_ids = truth.edge_ids
        speed = truth.speed_mps
        rows = self._rows(active)
        n = len(active)
        front = np.empty(n)
        edge_i = np.empty(n, np.int64)
        verdict = np.empty(n, np.int8)
        railsim_m = np.empty(n)
        sumo_m = np.empty(n)
        self._check_no += 1
        r_off, r_edges, r_starts, r_keys, r_vals = occ.route_tables()
        n_bad, n_imposed = truth_kernel.truth_pass(
            r_off,
            r_edges,
            r_starts,
            r_keys,
            r_vals,
            rows,
            truth.odometer_m,
            occ.edge_codes(edge_ids),
            truth.lane_pos_m,
            speed,
            self._memory,
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
            for k in np.flatnonzero(verdict & truth_kernel.IMPOSED).tolist():
                tr, sumo_v = active[k], float(speed[k])
                self.safety.speed_imposed(t, tr, sumo_v, float(rows[k, truth_kernel.SENT_MPS]), self.dt_s)
                tr.adopt_sumo_speed(t, sumo_v)
        if n_bad:
            out_of_step = np.flatnonzero(verdict & truth_kernel.DESYNC).tolist()
            self.safety.desync_found(t, active, out_of_step, railsim_m, sumo_m, edge_ids)
        lengths = np.array([tr.trip.vehicle.length_m for tr in active])
        occ.update_arrays(
            [tr.train_id for tr in active], rows[:, truth_kernel.ROUTE].astype(np.int64), front, lengths, edge_i
        )


def _memory(n: int) -> np.ndarray:
    """``n`` empty slot rows (never seen: the check number -2)."""
    memory = np.zeros((n, 3))
    memory[:, truth_kernel.SEEN] = -2.0
    return memory
