"""Reading scenario files: YAML text → checked :class:`~railsim.scenario.model.Scenario`, and back.

Three entry points, one pipeline::

    load(path, overrides)   read the file → parse → apply overrides ─┐
    loads(text, source)     parse ───────────────────────────────────┤→ from_mapping → validate → Scenario
    from_mapping(data)      (already parsed) ────────────────────────┘

Parsing uses a stricter YAML loader than PyYAML's ``SafeLoader``:

* no YAML 1.1 base-60 numbers — ``start_time: 17:30`` stays the string "17:30", not the integer 1050;
* ``1e3`` and ``1.0e9`` are floats (YAML 1.1 reads them as strings);
* a duplicated mapping key is an error (PyYAML silently keeps the last one);
* an integer of more than 100 digits is an error at its line and column (Python refuses to convert very long
  digit strings, and no scenario value needs more).

The loader is a :class:`railsim.inputs.BoundedSafeLoader`: it refuses nesting deeper than 50 levels and aliases
that expand to more than 200,000 values as it parses, and :func:`read_text` reads only regular files of at most 4 MiB
(:mod:`railsim.inputs`): no input file can hang, exhaust memory or overflow the stack.

A syntax error names the line and column (both 1-based) and, when the cause is on an earlier line (an
unclosed bracket), that place too::

    peak.yaml: line 3, column 11: YAML syntax error: expected ',' or ']', but got ':' (while parsing a flow
    sequence at line 2, column 8)

:func:`resolved_yaml` writes :attr:`Scenario.raw` (defaults filled in, paths absolute) back as YAML;
loading that text gives an equal scenario — every run's output folder carries it.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from railsim.errors import ConfigError
from railsim.inputs import BoundedSafeLoader, YAMLLimitError, limit_error, read_input_text
from railsim.scenario.model import Scenario
from railsim.scenario.overrides import with_overrides
from railsim.scenario.validate import require_top_mapping
from railsim.scenario.validate_scenario import validate

_STRING_SOURCE = "<string>"  # the source label of a scenario given as text

# ---- the YAML loader -------------------------------------------------------------------------------------------

_INT_TAG = "tag:yaml.org,2002:int"
_FLOAT_TAG = "tag:yaml.org,2002:float"


class _Loader(BoundedSafeLoader):
    """SafeLoader without YAML 1.1 base-60 numbers (``17:30`` stays a string), with ``1e3`` read as a float,
    and rejecting duplicate mapping keys (PyYAML silently keeps the last one)."""


_Loader.yaml_implicit_resolvers = {
    first: [(tag, rx) for tag, rx in resolvers if tag not in (_INT_TAG, _FLOAT_TAG)]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
_Loader.add_implicit_resolver(
    _INT_TAG,
    re.compile(r"^(?:[-+]?0b[0-1_]+|[-+]?0[0-7_]+|[-+]?(?:0|[1-9][0-9_]*)|[-+]?0x[0-9a-fA-F_]+)$"),
    list("-+0123456789"),
)
_Loader.add_implicit_resolver(
    _FLOAT_TAG,
    re.compile(
        r"^(?:[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)(?:[eE][-+]?[0-9]+)?"
        r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$"
    ),
    list("-+0123456789."),
)


def _construct_mapping_no_duplicates(loader: _Loader, node: yaml.MappingNode) -> dict[Any, Any]:
    loader.flatten_mapping(node)
    seen: set[Any] = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=True)
        try:
            duplicate = key in seen
        except TypeError:  # unhashable key: construct_mapping reports it
            continue
        if duplicate:
            raise yaml.constructor.ConstructorError(
                "while constructing a mapping", node.start_mark, f"found duplicate key {key!r}", key_node.start_mark
            )
        seen.add(key)
    return loader.construct_mapping(node, deep=True)


_Loader.add_constructor("tag:yaml.org,2002:map", _construct_mapping_no_duplicates)


def parse_yaml(text: str, source: str) -> Any:
    """Parse YAML ``text`` with the strict loader; a syntax error becomes a ``ConfigError`` at line/column.

    The structure is bounded while parsing (:class:`railsim.inputs.BoundedSafeLoader`: depth, values after aliases)."""
    try:
        return yaml.load(text, Loader=_Loader)  # noqa: S506 - _Loader is a SafeLoader
    except YAMLLimitError as exc:
        raise limit_error(exc, source) from None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark is not None else None
        problem = exc.problem or exc.context or "malformed YAML"
        ctx = exc.context_mark
        if exc.problem and exc.context and ctx is not None and mark is not None and ctx.line != mark.line:
            # The problem often surfaces a line later than its cause (an unclosed bracket): name both.
            problem += f" ({exc.context} at line {ctx.line + 1}, column {ctx.column + 1})"
        raise ConfigError(source, where, f"YAML syntax error: {problem}") from None
    except yaml.reader.ReaderError as exc:  # a character YAML does not allow (NUL, a control character)
        before = text[: exc.position]
        where = f"line {before.count(chr(10)) + 1}, column {len(before) - before.rfind(chr(10))}"
        raise ConfigError(source, where, f"YAML syntax error: {exc.reason} (character #x{exc.character:04x})") from None
    except yaml.YAMLError as exc:
        raise ConfigError(source, None, f"YAML syntax error: {exc}") from None


def read_text(path: Path, source: str) -> str:
    """The UTF-8 text of the regular file ``path`` (:func:`railsim.inputs.read_input_text`), else a ``ConfigError``
    naming ``source`` (never the file's content)."""
    return read_input_text(path, source, "scenario file")


# ---- the public API ---------------------------------------------------------------------------------------------


def load(path: str | Path, overrides: Mapping[str, Any] | None = None) -> Scenario:
    """Read, override (dotted paths, see :func:`with_overrides`) and validate a scenario file."""
    source = str(path)
    p = Path(path)
    data = parse_yaml(read_text(p, source), source)
    if overrides:
        require_top_mapping(data, source)
        data = with_overrides(data, overrides)
    return from_mapping(data, source=p, base_dir=p.resolve().parent)


def loads(text: str, source: str = _STRING_SOURCE, base_dir: str | Path | None = None) -> Scenario:
    """Validate a scenario given as YAML text. Relative world paths resolve against ``base_dir`` (default: the
    directory of ``source`` if it is a path, else the working directory)."""
    data = parse_yaml(text, source)
    is_path = not source.startswith("<")
    if base_dir is None:
        base_dir = Path(source).resolve().parent if is_path else Path.cwd()
    return from_mapping(data, source=Path(source) if is_path else source, base_dir=Path(base_dir))


def from_mapping(data: Any, source: str | Path | None = None, base_dir: str | Path | None = None) -> Scenario:
    """Validate an already parsed scenario mapping (what :func:`load` does after reading the file)."""
    label = str(source) if source is not None else "<scenario>"
    src_path = Path(source) if source is not None and not str(source).startswith("<") else None
    return validate(data, label, Path(base_dir) if base_dir is not None else Path.cwd(), src_path)


def resolved_yaml(scn: Scenario) -> str:
    """The resolved scenario as YAML text; ``loads(resolved_yaml(s)) == s``."""
    header = f"# resolved scenario {scn.name!r} (defaults filled in, paths absolute); loads back unchanged\n"
    return header + yaml.safe_dump(scn.raw, sort_keys=False, allow_unicode=True, default_flow_style=False)
