"""``railsim reproduce``: re-run a paper's numerical experiment in its own (pure numpy) model and draw its figures.

The engine runs the same experiments in SUMO from ``scenarios/paper*.yaml``; this command is the reference side of
that comparison, for users who want the paper's figures without a world:

    railsim reproduce paper002 --out out/paper002 [--topology union|path]
    railsim reproduce paper001 --out out/paper001 [--scenario A|B|C-constant|C-harmonic] [--controllers sempc,mpc,afsmc]

writes ``trains.csv`` (k, train, x, v, u, s, window), ``edges.csv`` (k, edge, x_ij, d_ij, bounds, active) and the
figures ``fig3_positions.png`` … ``fig6_inputs.png`` (positions, position differences with d_ij and γ bands,
speeds with v_r and ρ bounds, inputs with μ bounds). ``paper001`` runs Paper B's ATO scenarios on the six-carriage
multi-point plant with the selected controllers and writes ``metrics.json`` (E_u, E_v, E_x, E_p, max force rate,
violations per controller) and ``scenario_<X>.png``.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

from railsim import output


def add_commands(sub: Any) -> None:
    p = sub.add_parser("reproduce", help="re-run a paper experiment in its numpy model and write its figures")
    p.add_argument("experiment", choices=["paper001", "paper002"], help="which experiment")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--topology", choices=["union", "path"], default="union",
                   help="paper002: reading of the lost Fig. 2 (spec 002 §3.2)")
    p.add_argument("--scenario", choices=["A", "B", "C-constant", "C-harmonic"], default="A",
                   help="paper001: single section, multi-section, constant wind, harmonic gust")
    p.add_argument("--controllers", default="sempc,mpc,afsmc", help="paper001: comma-separated controllers")
    p.set_defaults(func=cmd_reproduce)


def _num(x: float) -> float | None:
    return None if math.isnan(x) else float(x)


def reproduce_paper002(out: Path, topology: str = "union") -> dict[str, Any]:
    from controllers.distributed.reference import simulate
    from controllers.distributed.scenarios import zhang2024_fig1
    from railsim.plots.paper002 import write_figures

    log = simulate(zhang2024_fig1(topology))
    trains = []
    for n, k in enumerate(log.k):
        for j, tid in enumerate(log.train_ids):
            if not log.present[n, j]:
                continue
            trains.append({"k": int(k), "train": tid, "x_m": _num(log.x_m[n, j]), "v_mps": _num(log.v_mps[n, j]),
                           "u_mps2": _num(log.u_mps2[n, j]) if n < len(log.u_mps2) else None,
                           "s_m": _num(log.s_m[n, j]) if n < len(log.s_m) else None})
    edges = []
    for n, k in enumerate(log.k):
        for e, (i, j) in enumerate(log.edge_ids):
            if log.edge_active[n, e]:
                edges.append({"k": int(k), "edge": f"{i}-{j}", "x_rel_m": _num(log.x_rel_m[n, e]),
                              "d_m": _num(log.edge_d_m[n, e]), "gamma_lo_m": _num(log.edge_gamma_lo_m[n, e]),
                              "gamma_hi_m": _num(log.edge_gamma_hi_m[n, e])})
    out.mkdir(parents=True, exist_ok=True)
    output.write_csv(out / "trains.csv", trains, ["k", "train", "x_m", "v_mps", "u_mps2", "s_m"])
    output.write_csv(out / "edges.csv", edges, ["k", "edge", "x_rel_m", "d_m", "gamma_lo_m", "gamma_hi_m"])
    figures = write_figures(log, out)
    violations = log.violations(1e-9)
    summary = {"experiment": "paper002", "topology": topology, "steps": int(log.k[-1]),
               "violations": len(violations), "figures": [str(f) for f in figures]}
    output.write_json(out / "summary.json", summary)
    return summary


def reproduce_paper001(out: Path, scenario: str = "A", controllers: str = "sempc,mpc,afsmc") -> dict[str, Any]:
    from controllers.ato_mpc import sim
    from railsim.plots.paper001 import plot_runs

    if scenario == "A":
        sc = sim.scenario_a()
    elif scenario == "B":
        sc = sim.scenario_b()
    else:
        sc = sim.scenario_c(scenario.split("-")[1])
    runs = [sim.run(sc, c.strip()) for c in controllers.split(",") if c.strip()]
    out.mkdir(parents=True, exist_ok=True)
    figure = plot_runs(runs, out / f"scenario_{scenario}.png")
    metrics = {r.controller: r.metrics for r in runs}
    output.write_json(out / "metrics.json", metrics)
    return {"experiment": "paper001", "scenario": scenario, "metrics": metrics, "figure": str(figure)}


def cmd_reproduce(args: argparse.Namespace) -> int:
    out = Path(args.out)
    if args.experiment == "paper001":
        summary = reproduce_paper001(out, args.scenario, args.controllers)
        for name, m in summary["metrics"].items():
            print(f"{name:8s} " + ", ".join(f"{k}={v:.4g}" for k, v in m.items() if isinstance(v, (int, float))))
        print(f"figure and metrics.json in {out}/")
        return 0
    summary = reproduce_paper002(out, args.topology)
    print(f"{summary['experiment']} ({summary['topology']}): {summary['steps']} steps, "
          f"{summary['violations']} constraint violations; figures and CSV in {out}/")
    return 0 if summary["violations"] == 0 else 1
