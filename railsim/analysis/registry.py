"""Post-run analyses chosen by the controller families a scenario uses (papers define their own metrics).

A run always writes the generic outputs (:mod:`railsim.record.recorder`). When its formations are driven by a
paper family's controllers, that paper's metrics are computed from the written files too, added to
``summary.json`` under ``analyses`` and printed by ``railsim run``. **One table:** :data:`ANALYSES` maps a paper
name to the controller family (the ``controllers`` sub-package, :func:`controllers.base.family_of`) whose types
trigger it and to the function that computes it — a new family's analysis is one row here:

* ``paper000`` (family ``mcf_dmpc``: enhanced IDM/CACC/FVD, DMPC, MCF-DMPC, OPO-MCF-DMPC) —
  :mod:`railsim.analysis.paper000`: per follower mean |Δv| and |ΔS − D^(e)| over the run and the late phase,
  VC-establishment time, min(ΔS − D^(s)), solve times, fallbacks;
* ``paper003`` (family ``monorail``) — :mod:`railsim.analysis.paper003`: minimum gap per pair and when, collision
  flags, CA and emergency-brake intervals, time to couple, final gaps and speed differences.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any


def _paper000(out_dir: Path) -> tuple[dict[str, Any], str]:
    from railsim.analysis.paper000 import format_table, paper000_metrics

    m = paper000_metrics(out_dir)
    return m, format_table(m)


def _paper003(out_dir: Path) -> tuple[dict[str, Any], str]:
    from railsim.analysis.paper003 import format_table, metrics

    m = metrics(out_dir)
    return m, format_table(m)


@dataclass(frozen=True)
class Analysis:
    name: str  # the paper family's name (the key in summary.json's ``analyses``)
    family: str  # the controllers sub-package whose types trigger it
    compute: Callable[[Path], tuple[dict[str, Any], str]]
    needs_formations: bool = False  # scores formations: a run without any has nothing to score (not an error)


ANALYSES: tuple[Analysis, ...] = (
    Analysis("paper000", "mcf_dmpc", _paper000, needs_formations=True),
    Analysis("paper003", "monorail", _paper003),
)


def applicable_to_types(types: Iterable[str]) -> list[str]:
    """Names of the analyses that apply to these controller types (unknown types are ignored)."""
    import controllers
    from controllers.base import family_of

    families = {family_of(t) for t in types if t in controllers.registered()}
    return [a.name for a in ANALYSES if a.family in families]


def applicable(scenario: Any) -> list[str]:
    """Names of the analyses that apply to a scenario (by the families of the controller types it uses)."""
    names = applicable_to_types(spec.type for spec in scenario.controllers.values())
    if not scenario.formations:
        names = [a.name for a in ANALYSES if a.name in names and not a.needs_formations]
    return names


def run(scenario: Any, out_dir: Path) -> tuple[dict[str, Any], list[str]]:
    """Compute every applicable analysis of a finished run: ``({name: metrics}, [printable tables])``."""
    results: dict[str, Any] = {}
    tables: list[str] = []
    wanted = applicable(scenario)
    for a in ANALYSES:
        if a.name in wanted:
            metrics, table = a.compute(Path(out_dir))
            results[a.name] = metrics
            tables.append(table)
    return results, tables
