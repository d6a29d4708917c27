"""The GTFS fuzz through ``railsim timetable import`` onto an imported world, at CI size.

Each mutant of the committed feed (:mod:`tests.fuzz_gtfs`) imported onto the São Paulo centre world ends in exit
0 with a scenario that passes ``railsim validate`` (world check included), or in exit 2 with one ``railsim: error:
FEED: FIELD: ...`` line: no traceback, no exit 4, no hang. The world import runs netconvert (this tier);
``python -m tests.fuzz_gtfs --mutants 500`` is the larger campaign.
"""

from __future__ import annotations

from pathlib import Path

from tests import fuzz_gtfs
from tests.helpers import ok_stdout, run_railsim

N_MUTANTS = 24


def test_imports_of_mutated_feeds_are_ok_or_refused_by_field(tmp_path: Path) -> None:
    world = tmp_path / "spo"
    ok_stdout(
        run_railsim(["network", "import", str(fuzz_gtfs.SAO_PAULO_OSM), "--out", str(world)], cache_dir=tmp_path / "c")
    )
    fig = fuzz_gtfs.campaign(N_MUTANTS, tmp_path, world=world)
    print(f"fuzz_gtfs import: mutants {fig.mutants}, ok {fig.ok}, refused {fig.refused}, {fig.seconds:.1f} s")
    assert fig.problems == [], "\n".join(fig.problems[:20])
    assert fig.ok + fig.refused == N_MUTANTS
    assert fig.ok >= 3 and fig.refused >= 10
