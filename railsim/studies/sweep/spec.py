"""The sweep file: reading and validating it, expanding it into cases, and the stable id of a case.

:func:`load_sweep` turns a sweep YAML file into a :class:`SweepSpec` (its structure only, every mistake a
:class:`railsim.errors.ConfigError` naming the file and the key); the expansion ``cases x grid x seeds`` and the
``link`` copies happen there too, so a :class:`SweepSpec` holds the final list of :class:`Case` objects in table
order. :func:`case_id` is the content hash that makes a sweep resumable: the same overrides and seed always give
the same id. :func:`validate_cases` loads every case's scenario (and checks its world ids) before anything runs.

The file format, the expansion order and the hashing rules are described in :mod:`railsim.studies.sweep`.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from railsim.errors import ConfigError
from railsim.inputs import describe_kind, excerpt
from railsim.scenario import OVERRIDE_PATH_RE, parse_yaml, read_text
from railsim.scenario.model import MAX_SEED
from railsim.studies.bounds import check_cases

MIN_TIMEOUT_S = 1.0  # a case's wall-clock limit: SUMO alone takes longer to start

SWEEP_KEYS = ("name", "description", "base", "grid", "link", "cases", "seeds", "timeout_s")
RESERVED_COLUMNS = ("case_id", "status", "error", "seed", "wall_s")
CASE_ID_HEX = 12


@dataclass(frozen=True)
class Case:
    """One case of a sweep: the overrides applied to the base scenario, the seed, and display labels."""

    case_id: str
    overrides: dict[str, Any]
    seed: int
    labels: dict[str, Any] = field(default_factory=dict)

    def describe(self) -> str:
        parts = [f"{k}={_compact(v)}" for k, v in self.labels.items()]
        parts += [f"{k}={_compact(v)}" for k, v in self.overrides.items()]
        parts.append(f"seed {self.seed}")
        return ", ".join(parts)


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep definition (see the module docstring)."""

    name: str
    source: Path
    base: Path  # absolute path of the base scenario
    base_sha256: str
    cases: tuple[Case, ...]
    override_columns: tuple[str, ...]
    label_columns: tuple[str, ...]
    timeout_s: float | None
    raw: dict[str, Any]  # the resolved definition, written to DIR/sweep.yaml


def _compact(value: Any) -> str:
    text = value if isinstance(value, str) else json.dumps(value, separators=(",", ":"), default=str)
    return text if len(text) <= 40 else text[:37] + "..."


def _canonical(value: Any) -> Any:
    """Value as hashed: integral floats as ints (``150.0`` and ``150`` are the same headway)."""
    if isinstance(value, float) and math.isfinite(value) and value == int(value):
        return int(value)
    if isinstance(value, Mapping):
        return {str(k): _canonical(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_canonical(v) for v in value]
    return value


def case_id(overrides: Mapping[str, Any], seed: int) -> str:
    """Stable id of a case: SHA-256 of the canonical JSON of ``{overrides, seed}``, first 12 hex digits."""
    text = json.dumps(
        {"overrides": _canonical(dict(overrides)), "seed": int(seed)},
        sort_keys=True,
        separators=(",", ":"),
        default=str,
    )
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:CASE_ID_HEX]


def _is_scalar(value: Any) -> bool:
    return value is None or isinstance(value, (str, int, float, bool))


def override_cells(overrides: Mapping[str, Any]) -> dict[str, Any]:
    """The override columns of a case's row: scalars as they are, lists and mappings as compact sorted JSON."""
    return {
        path: value if _is_scalar(value) else json.dumps(value, separators=(",", ":"), sort_keys=True)
        for path, value in overrides.items()
    }


class _SweepValidator:
    def __init__(self, source: Path) -> None:
        self.source = str(source)

    def fail(self, where: str | None, message: str) -> ConfigError:
        return ConfigError(self.source, where, message)

    def path(self, value: Any, where: str) -> str:
        if not isinstance(value, str) or not OVERRIDE_PATH_RE.match(value):
            raise self.fail(where, f'expected an override path like "services[0].departures.headway_s", got {value!r}')
        return value

    def labels(self, value: Any, where: str) -> dict[str, Any]:
        if isinstance(value, str):
            return {"label": value}
        if not isinstance(value, Mapping) or not value:
            raise self.fail(where, f"expected a string or a non-empty mapping column -> value, got {value!r}")
        out: dict[str, Any] = {}
        for k, v in value.items():
            if not isinstance(k, str) or not k or k in RESERVED_COLUMNS:
                raise self.fail(f"{where}.{k}", f"expected a column name other than {', '.join(RESERVED_COLUMNS)}")
            if not _is_scalar(v):
                raise self.fail(f"{where}.{k}", f"expected a scalar label value, got {_compact(v)}")
            out[k] = v
        return out


def load_sweep(path: str | Path) -> SweepSpec:
    """Read and validate a sweep file (its structure only; :func:`validate_cases` checks every case's scenario)."""
    src = Path(path)
    v = _SweepValidator(src)
    data = parse_yaml(read_text(src, str(src)), str(src))
    if not isinstance(data, Mapping):
        raise v.fail(None, f"expected a mapping with keys {', '.join(SWEEP_KEYS)}, got {describe_kind(data)}")
    for key in data:
        if key not in SWEEP_KEYS:
            raise v.fail(str(key), f"unknown key; expected one of {', '.join(SWEEP_KEYS)}")
    name = data.get("name", src.stem)
    if not isinstance(name, str) or not name:
        raise v.fail("name", f"expected a non-empty string, got {name!r}")
    base_text = data.get("base")
    if not isinstance(base_text, str) or not base_text:
        raise v.fail("base", "expected the path of a scenario file (relative to the sweep file)")
    base = (src.resolve().parent / base_text).resolve()
    if not base.is_file():
        raise v.fail("base", f"scenario file not found: {base}")

    grid_raw = data.get("grid") or {}
    if not isinstance(grid_raw, Mapping):
        raise v.fail("grid", "expected a mapping override path -> list of values")
    grid: dict[str, list[Any]] = {}
    for key, values in grid_raw.items():
        p = v.path(key, f"grid.{key}")
        if not isinstance(values, list) or not values:
            raise v.fail(f"grid.{p}", f"expected a non-empty list of values, got {_compact(values)}")
        grid[p] = values

    cases_raw = data.get("cases")
    if cases_raw is None:
        cases_raw = [{}]
    if not isinstance(cases_raw, list) or not cases_raw:
        raise v.fail("cases", "expected a non-empty list of override mappings")
    case_defs: list[tuple[dict[str, Any], dict[str, Any]]] = []
    for i, entry in enumerate(cases_raw):
        where = f"cases[{i}]"
        if entry is None:
            entry = {}
        if not isinstance(entry, Mapping):
            raise v.fail(where, f"expected a mapping of override path -> value, got {_compact(entry)}")
        labels: dict[str, Any] = {}
        overrides: dict[str, Any] = {}
        for key, value in entry.items():
            if key == "label":
                labels = v.labels(value, f"{where}.label")
                continue
            p = v.path(key, f"{where}.{key}")
            if p in grid:
                raise v.fail(f"{where}.{p}", "also a grid axis: vary a path either in the grid or in the cases")
            overrides[p] = value
        case_defs.append((overrides, labels))

    link_raw = data.get("link") or {}
    if not isinstance(link_raw, Mapping):
        raise v.fail("link", "expected a mapping override path -> the grid or case path it copies")
    case_paths = {p for o, _ in case_defs for p in o}
    link: dict[str, str] = {}
    for key, src_path in link_raw.items():
        p = v.path(key, f"link.{key}")
        s = v.path(src_path, f"link.{p}")
        if p in grid or p in case_paths:
            raise v.fail(f"link.{p}", "is varied itself (grid or cases); a linked path copies another one")
        if s not in grid and s not in case_paths:
            raise v.fail(f"link.{p}", f"expected a grid or case path to copy, got {s!r}")
        link[p] = s

    seeds_raw = data.get("seeds")
    seeds: list[int] = []  # none given: the base scenario's own seed, read once the count is known to be sane
    if seeds_raw is not None:
        if not isinstance(seeds_raw, list) or not seeds_raw:
            raise v.fail("seeds", "expected a non-empty list of integers >= 0")
        seeds = []
        seen_seeds: set[int] = set()
        for j, s in enumerate(seeds_raw):
            if isinstance(s, bool) or not isinstance(s, int) or not 0 <= s <= MAX_SEED:
                raise v.fail(
                    f"seeds[{j}]", f"expected an integer in [0, {MAX_SEED}] (SUMO's seed range), got {excerpt(s)}"
                )
            if s in seen_seeds:
                raise v.fail(f"seeds[{j}]", f"seed {s} is listed twice")
            seen_seeds.add(s)
            seeds.append(s)

    timeout = data.get("timeout_s")
    if timeout is not None and (
        isinstance(timeout, bool)
        or not isinstance(timeout, (int, float))
        or not math.isfinite(timeout)
        or timeout < MIN_TIMEOUT_S
    ):
        raise v.fail("timeout_s", f"expected a finite number of seconds >= {MIN_TIMEOUT_S:g}, got {excerpt(timeout)}")

    # count before expanding: a grid's product can be astronomically large in a few lines of YAML
    n_cases = len(case_defs) * math.prod(len(values) for values in grid.values()) * max(1, len(seeds))
    check_cases(n_cases, src, "grid" if grid else "cases")
    if not seeds:
        seeds = [_base_seed(base)]

    cases: list[Case] = []
    seen: dict[str, int] = {}
    grid_points = list(itertools.product(*grid.values())) if grid else [()]
    for ci, (case_over, labels) in enumerate(case_defs):
        for point in grid_points:
            over = dict(case_over)
            over.update(zip(grid.keys(), point))
            for target, copied in link.items():
                if copied in over:
                    over[target] = over[copied]
            for seed in seeds:
                cid = case_id(over, seed)
                if cid in seen:
                    raise v.fail(
                        f"cases[{ci}]",
                        f"case ({Case(cid, over, seed, labels).describe()}) duplicates "
                        f"case {seen[cid]}: same overrides and seed",
                    )
                seen[cid] = len(cases)
                cases.append(Case(cid, over, seed, labels))

    override_columns = list(dict.fromkeys([p for o, _ in case_defs for p in o] + list(grid) + list(link)))
    label_columns = list(dict.fromkeys(k for _, lab in case_defs for k in lab))
    for col in label_columns:
        if col in override_columns:
            raise v.fail("cases", f"label column {col!r} has the name of an override path")
    raw = {
        "name": name,
        "description": str(data.get("description", "")),
        "base": str(base),
        "grid": grid,
        "link": link,
        "cases": [dict(({"label": lab} if lab else {}), **o) for o, lab in case_defs],
        "seeds": seeds,
        "timeout_s": timeout,
    }
    return SweepSpec(
        name=name,
        source=src,
        base=base,
        base_sha256=_sha256(base),
        cases=tuple(cases),
        override_columns=tuple(override_columns),
        label_columns=tuple(label_columns),
        timeout_s=float(timeout) if timeout is not None else None,
        raw=raw,
    )


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _base_seed(base: Path) -> int:
    from railsim import scenario

    return int(scenario.load(base).simulation.seed)


def validate_cases(spec: SweepSpec, world_check: bool = True, full: bool = False) -> None:
    """Load every case's scenario (overrides applied) and check its world ids; ConfigError on the first bad case.

    ``full``: instead of the world ids alone, every check ``railsim run`` makes before its first step
    (:func:`railsim.studies.world.run_checks`; ``railsim validate SWEEP.yaml``). The error names the sweep file,
    the case (number and overrides) and the scenario field."""
    from railsim import scenario
    from railsim.studies.world import run_checks, world_check as check_world

    checked: set[str] = set()
    for k, case in enumerate(spec.cases):
        key = case_id(case.overrides, 0)  # the checks do not depend on the seed: each override set once
        if key in checked:
            continue
        checked.add(key)
        try:
            scn = scenario.load(spec.base, case.overrides)
            if world_check:  # station/switch ids depend on the overridden services: every case (builds are cached)
                (run_checks if full else check_world)(scn)
        except ConfigError as err:
            inner = str(err).replace("<overrides>", "override")
            raise ConfigError(spec.source, f"case {k} ({case.describe()})", inner) from None
