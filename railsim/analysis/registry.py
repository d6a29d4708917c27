"""Post-run analyses chosen by the controllers a scenario uses (papers define their own metrics).

A run always writes the generic outputs (:mod:`railsim.record.recorder`). When its formations are driven by a paper's
controllers, that paper's metrics are computed from the written files too, added to ``summary.json`` under
``analyses`` and printed by ``railsim run``:

* Paper A (``cf_idm``, ``cf_cacc``, ``cf_fvd``, ``mcf_dmpc``, ``opo_mcf_dmpc``, ``dmpc``) — :mod:`railsim.analysis.paper000`:
  per follower mean |Δv| and |ΔS − D^(e)| over the run and the late phase, VC-establishment time, min(ΔS − D^(s)),
  solve times, fallbacks;
* Paper D (``monorail_ca``, ``monorail_apf``, ``monorail_dmpc``) — :mod:`railsim.analysis.paper003`: minimum gap per pair
  and when, collision flags, CA and emergency-brake intervals, time to couple, final gaps and speed differences.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

PAPER_A_TYPES = frozenset({"cf_idm", "cf_cacc", "cf_fvd", "mcf_dmpc", "opo_mcf_dmpc", "dmpc"})
PAPER_D_TYPES = frozenset({"monorail_ca", "monorail_apf", "monorail_dmpc"})


def _paper_a(out_dir: Path) -> tuple[dict[str, Any], str]:
    from railsim.analysis.paper000 import format_table, paper000_metrics

    m = paper000_metrics(out_dir)
    return m, format_table(m)


def _paper_d(out_dir: Path) -> tuple[dict[str, Any], str]:
    from railsim.analysis.paper003 import format_table, metrics

    m = metrics(out_dir)
    return m, format_table(m)


_ANALYSES: tuple[tuple[str, frozenset[str], Callable[[Path], tuple[dict[str, Any], str]]], ...] = (
    ("paper000", PAPER_A_TYPES, _paper_a),
    ("paper003", PAPER_D_TYPES, _paper_d),
)


def applicable(scenario: Any) -> list[str]:
    """Names of the analyses that apply to a scenario (by the controller types it uses)."""
    types = {spec.type for spec in scenario.controllers.values()}
    return [name for name, wanted, _ in _ANALYSES if types & wanted]


def run(scenario: Any, out_dir: Path) -> tuple[dict[str, Any], list[str]]:
    """Compute every applicable analysis of a finished run: ``({name: metrics}, [printable tables])``."""
    results: dict[str, Any] = {}
    tables: list[str] = []
    for name, _wanted, func in _ANALYSES:
        if name in applicable(scenario):
            metrics, table = func(Path(out_dir))
            results[name] = metrics
            tables.append(table)
    return results, tables
