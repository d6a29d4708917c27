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
from railsim.errors import SimulationError
from railsim.record import output, run_folder


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

    ``out_dir`` holds this run's files only, written as a whole (:mod:`railsim.record.run_folder`): the run writes
    into a staging folder beside it, under a lock (a second run into the same folder is refused), and its files
    replace the previous run's, with a manifest, once it has completed, failed or been interrupted. A run that
    cannot write its files (a full disk) leaves ``out_dir`` as it was and raises
    :class:`railsim.errors.RunFolderError`.

    ``stop`` (:mod:`railsim.engine.interrupt`) ends the run cleanly once a signal is noted on it; an interrupted
    run gets no paper analyses (its files stop at the time reached). ``gui``: watch it in sumo-gui.
    """
    if out_dir is None:
        return engine.run(scenario, None, seed=seed, progress=progress, settings=settings, stop=stop, gui=gui)
    with run_folder.writing(Path(out_dir)) as staging:
        try:
            summary = _run_into(scenario, staging.path, seed, progress, settings, stop, gui)
        except SimulationError:
            if (staging.path / "summary.json").is_file():  # the run failed with its outputs written: keep them
                staging.commit("failed")
            raise
        staging.commit(str(summary["status"]))
    return summary


def _run_into(
    scenario: Any,
    folder: Path,
    seed: int | None,
    progress: bool | None,
    settings: engine.EngineSettings | None,
    stop: StopRequest | None,
    gui: bool,
) -> dict[str, Any]:
    """The run and its analyses, every file written into ``folder`` (the staging folder)."""
    summary = engine.run(scenario, folder, seed=seed, progress=progress, settings=settings, stop=stop, gui=gui)
    if summary["status"] != "interrupted":
        robustness = punctuality.run_kpis(folder, summary)  # only a run with ``disturbances:``
        if robustness is not None:
            summary["robustness"] = robustness
            output.write_json(folder / "summary.json", summary)
        results, tables = registry.run(scenario, folder)
        if results:  # the papers' own metrics, from the files just written
            summary["analyses"] = results
            summary["analysis_tables"] = tables
            output.write_json(folder / "summary.json", {k: v for k, v in summary.items() if k != "analysis_tables"})
    return summary
