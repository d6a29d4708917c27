"""The engine side of recording: turns the state of a step into samples for :class:`railsim.record.Recorder`
and the finished run into a :class:`railsim.record.snapshot.RunSnapshot` (the recorder never sees the engine).

Every step each *coupled* formation whose follower sees its own leader ahead contributes a gap error (against
the coupled controller's effective target), a speed error and the true gap; every ``trace_stride_s`` each train
on the line contributes a trace row with the state *at* ``t`` (the report taken before the plant step) and the
command decided at ``t``.
"""

from __future__ import annotations

import math
from typing import Any

from railsim.engine.coupling import FormationBook
from railsim.engine.occupancy import Ahead
from railsim.engine.train import TrainRuntime
from railsim.record.recorder import Recorder
from railsim.record.snapshot import FormationOutcome


class RecordingPort:
    """Feeds the recorder from the engine's state."""

    def __init__(self, recorder: Recorder, formations: FormationBook) -> None:
        self.recorder = recorder
        self.formations = formations

    def step(
        self, t: float, active: list[TrainRuntime], ahead: dict[str, Ahead | None], reports: dict[str, tuple[Any, ...]]
    ) -> None:
        book = self.formations
        for f in book.of_follower.values():
            if book.manager.state(f.id) != "coupled":
                continue
            fol = book.follower_of(f)
            lead = book.fleet.trip_ref(f.leader, "formations")
            a = ahead.get(fol.train_id)
            if a is None or a.train_id != lead.train_id:
                continue
            self.recorder.coupled_sample(
                f.id,
                abs(a.gap_m - book.effective_target_m(fol, f)),
                abs(fol.plant.speed_mps - lead.plant.speed_mps),
                a.gap_m,
            )
        if not self.recorder.trace_due(t):
            return
        for tr in active:
            f = book.of_follower.get(tr.train_id)
            rep = reports.get(tr.train_id)
            speed, accel = (rep[2], rep[3]) if rep is not None else (tr.plant.speed_mps, tr.plant.applied_accel_mps2)
            self.recorder.trace_row(
                {
                    "t_s": t,
                    "train": tr.train_id,
                    "service": tr.trip.service_id,
                    "chainage_m": tr.front_m - tr.trip.frame_shift_m,  # in the service's own route frame
                    "speed_mps": speed,
                    "applied_accel_mps2": accel,
                    "command_mps2": tr.last_cmd_mps2,
                    "role": tr.last_role,
                    "gap_m": tr.last_gap_m if math.isfinite(tr.last_gap_m) else None,
                    "formation_state": str(book.manager.state(f.id)) if f is not None else "",
                    "solve_time_s": tr.vc_solve_s,
                    "objective": tr.vc_objective,
                }
            )

    def formation_outcomes(self) -> list[FormationOutcome]:
        book = self.formations
        return [
            FormationOutcome(
                f.id,
                book.fleet.trip_ref(f.leader, "formations").train_id,
                book.follower_of(f).train_id,
                book.manager.stats(f.id),
                book.manager.state(f.id),
            )
            for f in book.of_follower.values()
        ]
