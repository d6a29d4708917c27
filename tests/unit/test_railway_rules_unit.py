"""Railway rules on any network: safe insertion, one collision truth, desync check, stall detection.

Here: the tests of it that start no process; the others are in ``tests/sumo/test_railway_rules.py``.
"""

from __future__ import annotations

from typing import Any


def test_collisions_count_railsim_and_sumo_together_and_exit_1() -> None:
    from railsim.cli.run import exit_code
    from railsim.record.recorder import Recorder
    from railsim.record.snapshot import RunSnapshot

    def summary(ours: int, sumo: int) -> dict[str, Any]:
        run = RunSnapshot(
            scenario_name="x",
            seed=1,
            trains=[],
            formations=[],
            events=[],
            channel_stats={},
            collisions=ours,
            sumo_collisions=sumo,
            sim_s=1.0,
            wall_s=0.0,
            steps=1,
            step_s=1.0,
            formats=("csv",),
            resolved_scenario={},
            versions={},
        )
        return Recorder(1.0, 1.0).summary(run)

    s = summary(0, 2)
    assert (s["collisions"], s["collisions_railsim"], s["sumo_collisions"]) == (2, 0, 2)
    assert exit_code(s) == 1
    s = summary(1, 1)
    assert s["collisions"] == 2 and exit_code(s) == 1
    assert exit_code(summary(0, 0)) == 0
