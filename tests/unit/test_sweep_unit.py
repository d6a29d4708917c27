"""``railsim sweep``: expansion and validation of sweep files, real sweeps (2 local workers, interrupted and resumed,
a failing case, a Dask LocalCluster) on the small corridor scenario (scenarios/sweeps/corridor_small.yaml, ~1 s a
case). Every simulation runs in a child process (railsim.studies.sweep.run_case), never in the test process.

Here: the tests of it that start no process; the others are in ``tests/sumo/test_sweep.py``.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from railsim.errors import ConfigError
from railsim.studies import sweep
from tests.sumo.test_sweep import BASE, DOWN_HW, UP_HW, write_sweep


def test_expansion_is_cases_times_grid_times_seeds_with_links_and_labels(tmp_path: Path) -> None:
    path = write_sweep(
        tmp_path,
        {
            "cases": [{"label": "base"}, {"label": "wide", "controllers.sep.params.margin_m": 80}],
            "grid": {UP_HW: [60, 90, 120], "simulation.step_s": [0.5, 0.25]},
            "link": {DOWN_HW: UP_HW},
            "seeds": [1, 2],
        },
    )
    spec = sweep.load_sweep(path)
    assert len(spec.cases) == 2 * 3 * 2 * 2
    assert spec.label_columns == ("label",)
    assert spec.override_columns == ("controllers.sep.params.margin_m", UP_HW, "simulation.step_s", DOWN_HW)
    first, last = spec.cases[0], spec.cases[-1]
    assert first.overrides == {UP_HW: 60, "simulation.step_s": 0.5, DOWN_HW: 60} and first.seed == 1
    assert first.labels == {"label": "base"}
    assert last.overrides == {
        "controllers.sep.params.margin_m": 80,
        UP_HW: 120,
        "simulation.step_s": 0.25,
        DOWN_HW: 120,
    }
    assert last.seed == 2 and last.labels == {"label": "wide"}
    ids = [c.case_id for c in spec.cases]
    assert len(set(ids)) == len(ids) and all(len(i) == sweep.CASE_ID_HEX for i in ids)
    # the id hashes (overrides, seed) only: key order and 150 vs 150.0 do not matter, labels are not hashed
    assert sweep.case_id({"a": 150, "b.c": [1, {"x": 2}]}, 4) == sweep.case_id({"b.c": [1, {"x": 2.0}], "a": 150.0}, 4)
    assert sweep.case_id({"a": 150}, 4) != sweep.case_id({"a": 150}, 5)
    assert sweep.case_id({"a": 150}, 4) != sweep.case_id({"a": 151}, 4)


def test_default_seed_is_the_base_scenarios_and_an_empty_sweep_is_one_case(tmp_path: Path) -> None:
    spec = sweep.load_sweep(write_sweep(tmp_path, {}))
    assert [(c.overrides, c.seed) for c in spec.cases] == [({}, 3)]  # corridor_small has simulation.seed 3


@pytest.mark.parametrize(
    ("body", "field", "words"),
    [
        ({"grid": {UP_HW: 90}}, f"grid.{UP_HW}", "non-empty list"),
        ({"grid": {"services[0.headway": [1]}}, "grid.services[0.headway", "override path"),
        ({"colour": "red"}, "colour", "unknown key"),
        ({"seeds": [1, -2]}, "seeds[1]", "an integer in [0,"),
        ({"seeds": [1, 1]}, "seeds[1]", "listed twice"),
        ({"link": {DOWN_HW: "services[7].x"}}, f"link.{DOWN_HW}", "grid or case path"),
        ({"grid": {UP_HW: [60]}, "cases": [{UP_HW: 90}]}, f"cases[0].{UP_HW}", "also a grid axis"),
        ({"cases": [{"label": {"seed": 1}}]}, "cases[0].label.seed", "column name"),
        ({"cases": [{}, {}]}, "cases[1]", "duplicates case 0"),
        ({"timeout_s": 0}, "timeout_s", ">= 1"),
    ],
)
def test_bad_sweep_files_name_file_and_field(tmp_path: Path, body: dict, field: str, words: str) -> None:
    path = write_sweep(tmp_path, body)
    with pytest.raises(ConfigError) as info:
        sweep.load_sweep(path)
    assert info.value.source == str(path) and info.value.field == field and words in info.value.message


def test_missing_base_is_named(tmp_path: Path) -> None:
    path = tmp_path / "s.yaml"
    path.write_text("base: nowhere.yaml\n", encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        sweep.load_sweep(path)
    assert info.value.field == "base" and "not found" in info.value.message


def test_resuming_into_a_folder_of_another_base_is_refused(tmp_path: Path) -> None:
    base = tmp_path / "base.yaml"
    base.write_text(BASE.read_text(encoding="utf-8"), encoding="utf-8")
    path = tmp_path / "s.yaml"
    path.write_text(f"base: {base}\nseeds: [3]\n", encoding="utf-8")
    out = tmp_path / "out"
    spec = sweep.load_sweep(path)
    out.mkdir()
    (out / "sweep.yaml").write_text(yaml.safe_dump({"base": str(base), "base_sha256": "0" * 64}), encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        sweep.run_sweep(spec, out, workers=1, progress=False)
    assert info.value.field == "base_sha256" and "different version of the base" in info.value.message
