"""A handful of accepted mutants of the newer sections run in SUMO: exit 0, 1 or 3 — never 2 (validate would have
had to refuse them) or 4 — no traceback, no NaN or infinity in any output (:mod:`tests.fuzz_sections`)."""

from __future__ import annotations

from pathlib import Path

from tests import fuzz, fuzz_sections
from tests.helpers import run_railsim

N_RUNS = 3


def test_accepted_section_mutants_run(tmp_path: Path) -> None:
    picked: list[Path] = []
    k = 0
    while len(picked) < N_RUNS and k < 400:
        m = fuzz_sections.mutant(k)
        if m.kind == "scenario" and m.base in ("passenger_demand.yaml", "disturbed_line.yaml"):  # small worlds
            path = tmp_path / f"m{k:04d}.yaml"
            path.write_bytes(m.data)
            res = fuzz_sections.check_in_process(path, m.kind)
            assert res.problem is None, (k, m.ops, res.problem, res.stderr)
            if res.rc == 0:
                picked.append(path)
        k += 1
    assert len(picked) == N_RUNS
    for path in picked:
        short = fuzz.short_horizon(path, horizon_s=120.0)
        out = short.with_suffix("")
        res = run_railsim(
            ["run", str(short), "--out", str(out), "--no-progress"], cache_dir=tmp_path / "c", timeout=600
        )
        assert res.returncode in (0, 1, 3), (path.name, res.returncode, res.stderr[-600:])
        assert "Traceback" not in res.stderr
        if out.is_dir():
            assert fuzz.non_finite_cells(out) == []
