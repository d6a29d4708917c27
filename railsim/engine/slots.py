"""The truth pass's per-train state, resident in one array row per train (its *slot*) for the train's whole run.

Each step the truth pass (:mod:`railsim.engine.truth`) needs, for every train on the line, its route, where its trip's
odometer started, last step's edge pointer, whether it is reversing and the speed railsim last handed SUMO, and it
keeps each train's chainage and speed from the last check. Gathering these from the
:class:`~railsim.engine.train.TrainRuntime` objects every step costs as much as the compiled pass saves, so they live
here, in a float table with a row per slot (columns :data:`ROUTE` … :data:`FRONT_M`), and are written when they
change, not when they are read:

* **when the slot is given** (the first time the train is read): its whole row, from the train;
* **a field written on the train** — ``depart_chainage_m`` (insertion, a unit's next trip) and ``reversing`` (a
  turnback set up, a reversal done) are properties of ``TrainRuntime`` that write their slot's column too
  (:class:`railsim.engine.train.TrainRuntime`, "Resident fields");
* **the speeds handed to SUMO** (:meth:`SlotStore.sent`, called with the very list the engine hands the bridge);
* **the truth pass's own outputs**: the compiled pass writes each train's edge pointer, chainage and memory of the
  check into its row (:func:`railsim.engine.truth_kernel.truth_pass`).

A train's route view is read by the later phases ~4.6 times per train-step (the demo), where a property would cost
~30 ns a read, more than a gather: so the view stays a plain attribute, and :meth:`SlotStore.index` compares the
step's views with the last step's (one pointer comparison per train, in C) and numbers the routes again only when
one changed or the set of trains did. The train's length is taken when its slot is given (a trip's vehicle is
fixed once it runs).

``tests/unit/test_slot_store.py`` holds the table to what reading every field from the trains gives, after every
kind of event that changes one.
"""

from __future__ import annotations

from operator import attrgetter
from typing import TYPE_CHECKING, Any

import numpy as np

from railsim.engine.slot_columns import (
    DEPART_M,
    FRONT_M,
    HINT,
    LENGTH_M,
    N_COLUMNS,
    NEVER_SEEN,
    NO_SPEED,
    PREV_FRONT_M,
    PREV_SPEED_MPS,
    REVERSING,
    ROUTE,
    SEEN,
    SENT_MPS,
)

if TYPE_CHECKING:
    from railsim.engine.occupancy import Occupancy
    from railsim.engine.train import TrainRuntime

__all__ = [  # the table's columns (railsim.engine.slot_columns) and the store
    "DEPART_M",
    "FRONT_M",
    "HINT",
    "LENGTH_M",
    "N_COLUMNS",
    "NEVER_SEEN",
    "NO_SPEED",
    "PREV_FRONT_M",
    "PREV_SPEED_MPS",
    "REVERSING",
    "ROUTE",
    "SEEN",
    "SENT_MPS",
    "SlotStore",
]

_VIEW = attrgetter("view")
_SLOT = attrgetter("slot")
_TRAIN_ID = attrgetter("train_id")


class SlotStore:
    """Rows of per-train state by slot (module docstring), and the step's trains as slots."""

    def __init__(self, occupancy: Occupancy, capacity: int = 64) -> None:
        self.occupancy = occupancy  # numbers the routes (Occupancy.route_numbers)
        self.table = _rows(capacity)
        self.n_slots = 0
        self._active: list[Any] = []  # the trains of the last index, in order
        self._views: list[Any] | None = None  # and their views then (None: to be numbered)
        self.slots = np.zeros(0, np.int64)  # their slots
        self.ids: list[str] = []  # and their train ids
        self.routes = np.zeros(0, np.int64)  # and their route numbers
        self.lengths_m = np.zeros(0)  # and lengths (these four arrays are replaced, never changed in place)

    def give(self, tr: TrainRuntime) -> int:
        """``tr``'s slot: a new row, filled from the train (its route is numbered by :meth:`index`)."""
        s = self.n_slots
        if s == len(self.table):
            self.table = np.concatenate([self.table, _rows(len(self.table))])
        self.n_slots += 1
        row = self.table[s]
        row[ROUTE] = -1.0
        row[DEPART_M] = tr.depart_chainage_m
        row[HINT] = tr.edge_i
        row[REVERSING] = tr.reversing
        row[SENT_MPS] = NO_SPEED if tr.sent_speed_mps is None else tr.sent_speed_mps
        row[LENGTH_M] = tr.trip.vehicle.length_m
        tr.slot = s
        tr.store = self
        return s

    def index(self, active: list[TrainRuntime]) -> None:
        """Make ``active`` the step's trains: :attr:`slots`, :attr:`ids`, :attr:`routes` and :attr:`lengths_m` in
        its order (slots given to trains read for the first time), and the route column of each (numbered afresh
        only when a view or the set of trains changed: the routes not seen before are registered in the order of
        ``active``, as the occupancy index always has)."""
        if active != self._active:  # (element by element, identity first: a C loop)
            for tr in active:
                if tr.slot < 0 or tr.store is not self:
                    self.give(tr)
            self._active = list(active)
            self.slots = np.array(list(map(_SLOT, active)), np.int64)
            self.ids = list(map(_TRAIN_ID, active))
            self.lengths_m = self.table[self.slots, LENGTH_M]
            self._views = None
        views = list(map(_VIEW, active))
        if views != self._views:
            self.routes = self.occupancy.route_numbers(views)
            self.table[self.slots, ROUTE] = self.routes
            self._views = views

    def sent(self, speeds_mps: list[float] | np.ndarray) -> None:
        """The speeds handed to SUMO for the trains of the last :meth:`index`, in its order."""
        self.table[self.slots, SENT_MPS] = speeds_mps

    def write(self, column: int, slot: int, value: float) -> None:
        """One field of one slot (the train's property setters)."""
        self.table[slot, column] = value

    def gathered(self, active: list[TrainRuntime]) -> np.ndarray:
        """The inputs as read from the trains themselves (columns :data:`ROUTE` … :data:`LENGTH_M`): what the table
        must hold (the tests' oracle; route -1: a view not numbered yet)."""
        route_of = self.occupancy.route_of
        return np.array(
            [
                (
                    route_of.get(id(tr.view), -1),
                    tr.depart_chainage_m,
                    tr.edge_i,
                    tr.reversing,
                    NO_SPEED if tr.sent_speed_mps is None else tr.sent_speed_mps,
                    tr.trip.vehicle.length_m,
                )
                for tr in active
            ],
            float,
        ).reshape(len(active), LENGTH_M + 1)


def _rows(n: int) -> np.ndarray:
    """``n`` empty slot rows (never seen)."""
    table = np.zeros((n, N_COLUMNS))
    table[:, SEEN] = NEVER_SEEN
    table[:, ROUTE] = -1.0
    table[:, SENT_MPS] = NO_SPEED
    return table
