"""The Python API in one call: run a scenario, write its outputs, add the paper analyses.

::

    from railsim import api, scenario
    summary = api.run(scenario.load("scenarios/chongqing_line3_peak.yaml"), "out/peak", seed=7)

:func:`run` is :func:`railsim.engine.run` (the step loop and its files) followed by
:func:`railsim.analysis.registry.run` (each paper family's metrics from the files just written, stored in
``summary.json`` under ``analyses``) and, for a run with ``disturbances:``, the punctuality KPIs
(:mod:`railsim.analysis.punctuality`, under ``robustness``). ``railsim run``, sweeps and studies all call it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from railsim import engine
from railsim.analysis import punctuality, registry
from railsim.engine.interrupt import StopRequest
from railsim.record import output


def run(
    scenario: Any,
    out_dir: Path | str | None,
    seed: int | None = None,
    progress: bool | None = None,
    settings: engine.EngineSettings | None = None,
    stop: StopRequest | None = None,
    gui: bool = False,
) -> dict[str, Any]:
    """Run ``scenario`` and write its outputs to ``out_dir``; return the summary (with ``analyses`` if any).

    ``stop`` (:mod:`railsim.engine.interrupt`) ends the run cleanly once a signal is noted on it; an interrupted
    run gets no paper analyses (its files stop at the time reached). ``gui``: watch it in sumo-gui.
    """
    summary = engine.run(scenario, out_dir, seed=seed, progress=progress, settings=settings, stop=stop, gui=gui)
    if out_dir is not None and summary["status"] != "interrupted":
        robustness = punctuality.run_kpis(Path(out_dir), summary)  # only a run with ``disturbances:``
        if robustness is not None:
            summary["robustness"] = robustness
            output.write_json(Path(out_dir) / "summary.json", summary)
        results, tables = registry.run(scenario, Path(out_dir))
        if results:  # the papers' own metrics, from the files just written
            summary["analyses"] = results
            summary["analysis_tables"] = tables
            output.write_json(
                Path(out_dir) / "summary.json", {k: v for k, v in summary.items() if k != "analysis_tables"}
            )
    return summary
