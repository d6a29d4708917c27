"""Paper E Table 3: naive orders, naive strategies fail to couple at F, improved PSO couples more reliably.

The seeds and budget are fixed, so this is deterministic; the thresholds state the paper's qualitative claim
(spec §4, §5) rather than pinning our numbers. The full 30-seed table is in ``benchmarks/junction_planner.py``;
the 8-seed PSO comparison (10 s of CPU) is in ``tests/long/test_junction_table3_pso.py``.
"""

from __future__ import annotations

from controllers.junction.baselines import priority_order, run_naive
from controllers.junction.planner import build_problem
from controllers.junction.simulate import measure, table3_scenario


def _problem(n: int):
    trains, layout = table3_scenario(n)
    return build_problem(trains, (), layout)


def test_naive_orders_reproduce_the_paper_narratives():
    pr = _problem(1)
    ids = [t.train_id for t in pr.trains]
    assert [ids[k] for k in priority_order(pr, "naive1")] == ["train3", "train2", "train1"]
    assert [ids[k] for k in priority_order(pr, "naive2")] == ["train1", "train3", "train2"]


def test_naive_runs_respect_switch_rules_but_do_not_couple():
    for n in (1, 2, 3):
        pr = _problem(n)
        for rule in ("naive1", "naive2"):
            out = measure(pr, *run_naive(pr, rule))
            assert out.switch_speed_excess_mps <= 1e-6
            assert out.headway_shortfall_s <= 1e-6
            assert out.min_separation_m > 0.0
            assert not out.coupled_at_F, (n, rule, out)
