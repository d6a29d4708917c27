"""Override paths: change values of a parsed scenario by dotted path before it is validated.

Sweeps and the command line vary a scenario without editing its file::

    load("peak.yaml", {"simulation.seed": 3, "services[0].departures.headway_s": 180})

A path is mapping keys joined by ``.`` with list indices in brackets (``a.b[0].c``). :func:`with_overrides`
applies such paths to a deep copy of the raw mapping: missing mapping keys on the way are created (so
``faults.comm.t2t.loss_prob`` works on a file without ``faults``), list indices must exist. Overrides are
applied *before* validation, so an overridden value is checked like any other; a malformed path, or one
that walks into a value of the wrong shape, is a ``ConfigError`` of source ``<overrides>``.
:data:`OVERRIDE_PATH_RE` is the syntax of one path (``railsim.studies.sweep`` checks sweep axes with it).
"""

from __future__ import annotations

import copy
import re
from collections.abc import Mapping
from typing import Any

from railsim.errors import ConfigError
from railsim.scenario.validate import join_path, short_repr

OVERRIDE_PATH_RE = re.compile(r"^[^.\[\]]+(?:\[\d+\])*(?:\.[^.\[\]]+(?:\[\d+\])*)*$")
_TOKEN_RE = re.compile(r"([^.\[\]]+)|\[(\d+)\]")
_SOURCE = "<overrides>"


def path_tokens(dotted: str) -> list[str | int]:
    """``"a.b[0].c"`` → ``["a", "b", 0, "c"]`` (the path must match :data:`OVERRIDE_PATH_RE`)."""
    return [name if name else int(index) for name, index in _TOKEN_RE.findall(dotted)]


def with_overrides(scn_raw: Mapping[str, Any], overrides: Mapping[str, Any]) -> dict[str, Any]:
    """A deep copy of ``scn_raw`` with values replaced by dotted path (``"services[0].departures.headway_s"``).

    Missing mapping keys on the way are created (so ``faults.comm.t2t.loss_prob`` works on a file without
    ``faults``); list indices must exist. The result is not validated: pass it to :func:`from_mapping`.
    """
    out: dict[str, Any] = copy.deepcopy(dict(scn_raw))
    for dotted, value in overrides.items():
        if not isinstance(dotted, str) or not OVERRIDE_PATH_RE.match(dotted):
            raise ConfigError(_SOURCE, str(dotted), 'expected a path like "a.b[0].c"')
        tokens = path_tokens(dotted)
        node: Any = out
        walked = ""
        for pos, tok in enumerate(tokens):
            last = pos == len(tokens) - 1
            if isinstance(tok, int):
                if not isinstance(node, list):
                    raise ConfigError(_SOURCE, dotted, f"{walked or '<top>'} is not a list, got {short_repr(node)}")
                if tok >= len(node):
                    raise ConfigError(_SOURCE, dotted, f"index {tok} out of range ({walked} has {len(node)} items)")
                walked = f"{walked}[{tok}]"
            else:
                if not isinstance(node, dict):
                    raise ConfigError(_SOURCE, dotted, f"{walked or '<top>'} is not a mapping, got {short_repr(node)}")
                if not last and tok not in node:
                    node[tok] = {}
                walked = join_path(walked, tok)
            if last:
                node[tok] = copy.deepcopy(value)
            else:
                node = node[tok]
    return out
