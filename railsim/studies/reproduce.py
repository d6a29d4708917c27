"""Paper reproductions: re-run a paper's numerical experiment in its own (pure numpy) model and draw its figures.

The engine runs the same experiments in SUMO from ``scenarios/paper*.yaml``; :func:`reproduce_paper002` and
:func:`reproduce_paper001` are the reference side of that comparison, for users who want the paper's figures
without a world; :func:`reproduce_paper004` runs Paper E's Table 3 sweeps on SUMO. The command
(:mod:`railsim.cli.reproduce`):

    railsim reproduce paper002 --out out/paper002 [--topology union|path]
    railsim reproduce paper001 --out out/paper001 [--scenario A|B|C-constant|C-harmonic] [--controllers sempc,mpc,afsmc]

writes ``trains.csv`` (k, train, x, v, u, s, window), ``edges.csv`` (k, edge, x_ij, d_ij, bounds, active) and the
figures ``fig3_positions.png`` … ``fig6_inputs.png`` (positions, position differences with d_ij and γ bands,
speeds with v_r and ρ bounds, inputs with μ bounds). ``paper001`` runs Paper B's ATO scenarios on the six-carriage
multi-point plant with the selected controllers and writes ``metrics.json`` (E_u, E_v, E_x, E_p, max force rate,
violations per controller) and ``scenario_<X>.png``.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from railsim.record import output


def _num(x: float) -> float | None:
    return None if math.isnan(x) else float(x)


def reproduce_paper002(out: Path, topology: str = "union") -> dict[str, Any]:
    from controllers.distributed.reference import simulate
    from controllers.distributed.scenarios import zhang2024_fig1
    from railsim.report.plots.paper002 import write_figures

    log = simulate(zhang2024_fig1(topology))
    trains = []
    for n, k in enumerate(log.k):
        for j, tid in enumerate(log.train_ids):
            if not log.present[n, j]:
                continue
            trains.append(
                {
                    "k": int(k),
                    "train": tid,
                    "x_m": _num(log.x_m[n, j]),
                    "v_mps": _num(log.v_mps[n, j]),
                    "u_mps2": _num(log.u_mps2[n, j]) if n < len(log.u_mps2) else None,
                    "s_m": _num(log.s_m[n, j]) if n < len(log.s_m) else None,
                }
            )
    edges = []
    for n, k in enumerate(log.k):
        for e, (i, j) in enumerate(log.edge_ids):  # type: ignore[assignment]
            if log.edge_active[n, e]:
                edges.append(
                    {
                        "k": int(k),
                        "edge": f"{i}-{j}",
                        "x_rel_m": _num(log.x_rel_m[n, e]),
                        "d_m": _num(log.edge_d_m[n, e]),
                        "gamma_lo_m": _num(log.edge_gamma_lo_m[n, e]),
                        "gamma_hi_m": _num(log.edge_gamma_hi_m[n, e]),
                    }
                )
    out.mkdir(parents=True, exist_ok=True)
    output.write_csv(out / "trains.csv", trains, ["k", "train", "x_m", "v_mps", "u_mps2", "s_m"])
    output.write_csv(out / "edges.csv", edges, ["k", "edge", "x_rel_m", "d_m", "gamma_lo_m", "gamma_hi_m"])
    figures = write_figures(log, out)
    violations = log.violations(1e-9)
    summary = {
        "experiment": "paper002",
        "topology": topology,
        "steps": int(log.k[-1]),
        "violations": len(violations),
        "figures": [str(f) for f in figures],
    }
    output.write_json(out / "summary.json", summary)
    return summary


def reproduce_paper001(out: Path, scenario: str = "A", controllers: str = "sempc,mpc,afsmc") -> dict[str, Any]:
    from controllers.ato_mpc import sim
    from railsim.report.plots.paper001 import plot_runs

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


PAPER004_METRICS = (
    "coupling_time_s",
    "coupled_speed_mps",
    "cost",
    "operation_time_s",
    "min_separation_m",
    "max_gap_error_m",
    "max_speed_diff_mps",
    "plan_wall_time_s_mean",
)


def paper004_table(tables: dict[int, Any]) -> Any:
    """Table 3 comparison from the SUMO sweep tables: one row per (scenario, method), mean ± std over the seeds.

    ``coupled_rate`` is the share of runs coupled at F (spec Eq. 2–3 at the moment the leader reaches F, measured on
    the SUMO trajectories); the safety columns add up collisions and switch violations over all runs.
    """
    import pandas as pd

    rows = []
    for sc, df in sorted(tables.items()):
        df = df[df["status"] == "ok"]
        for method, g in df.groupby("junction.method", sort=False):
            row: dict[str, Any] = {
                "scenario": sc,
                "method": method,
                "runs": len(g),
                "coupled_rate": float(g["junction.coupled_at_F"].astype(float).mean()),
                "collisions": int(g["collisions"].sum()),
                "switch_violations": int(g["switch_violations"].sum()),
            }
            for m in PAPER004_METRICS:
                col = f"junction.{m}"
                vals = pd.to_numeric(g[col], errors="coerce").dropna() if col in g else pd.Series(dtype=float)
                row[f"{m}_mean"] = float(vals.mean()) if len(vals) else None
                row[f"{m}_std"] = float(vals.std(ddof=0)) if len(vals) else None
            rows.append(row)
    return pd.DataFrame(rows)


def paper004_markdown(table: Any) -> str:
    def pm(r: Any, m: str, nd: int = 1) -> str:
        mean, std = r[f"{m}_mean"], r[f"{m}_std"]
        return "–" if mean is None or mean != mean else f"{mean:.{nd}f} ± {std:.{nd}f}"

    lines = [
        "| scenario | method | runs | coupled at F | T_c [s] | V_c [m/s] | f_c | operation [s] | "
        "min head-to-head [m] | max gap error [m] | collisions | switch violations |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for _, r in table.iterrows():
        lines.append(
            f"| {r['scenario']} | {r['method']} | {r['runs']} | {r['coupled_rate']:.2f} | "
            f"{pm(r, 'coupling_time_s')} | {pm(r, 'coupled_speed_mps', 2)} | {pm(r, 'cost')} | "
            f"{pm(r, 'operation_time_s')} | {pm(r, 'min_separation_m')} | {pm(r, 'max_gap_error_m')} | "
            f"{r['collisions']} | {r['switch_violations']} |"
        )
    return "\n".join(lines)


def reproduce_paper004(out: Path, workers: int | None = None, dask: str | None = None) -> dict[str, Any]:
    """Paper E Table 3 on SUMO: the sweeps ``scenarios/sweeps/paper004_table3_s{1,2,3}.yaml`` (methods × seeds),
    resumable in ``out/s1..s3``, then the comparison table (``comparison.csv``/``.md``)."""
    from railsim.record import output
    from railsim.studies import sweep

    root = Path(__file__).resolve().parents[2] / "scenarios" / "sweeps"
    tables = {}
    for sc in (1, 2, 3):
        folder = out / f"s{sc}"
        sweep.run_sweep(root / f"paper004_table3_s{sc}.yaml", folder, workers=workers, dask_address=dask)
        tables[sc] = sweep.load_table(folder)
    table = paper004_table(tables)
    out.mkdir(parents=True, exist_ok=True)
    output.write_csv(out / "comparison.csv", table.to_dict("records"), list(table.columns))
    md = paper004_markdown(table)
    (out / "comparison.md").write_text(md + "\n", encoding="utf-8")
    return {"experiment": "paper004", "table": md}
