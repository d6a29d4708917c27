"""Validation primitives: how a scenario value is checked and how a failure is worded.

Every check in the scenario layer goes through a :class:`Checker`. It knows the file being validated
(``source``) and the directory relative paths resolve against (``base_dir``); each primitive takes the
value and its *field path* (``services[2].departures.headway_s``) and either returns the value, converted
(``int`` → ``float``, a relative path → an absolute one), or raises :class:`railsim.errors.ConfigError`
worded the same way everywhere::

    scenarios/peak.yaml: services[2].departures.headway_s: expected a number > 0, got -150
    scenarios/peak.yaml: roles.separaton: unknown key (did you mean 'separation'?); allowed keys: ...

The "did you mean" suffix comes from :func:`did_you_mean` (``difflib`` close matches); values in messages
are shortened by :func:`short_repr`. The section validators (``validate_*.py``, :mod:`.events`) are plain
functions ``section(ck, value, ...) -> (spec, raw)`` built from these primitives: ``spec`` is the frozen
dataclass of :mod:`railsim.scenario.model`, ``raw`` the resolved mapping written back to
``scenario.resolved.yaml``.
"""

from __future__ import annotations

import dataclasses
import difflib
import importlib
import math
import re
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from railsim.errors import ConfigError
from railsim.inputs import describe_kind, excerpt
from railsim.scenario.clock import CLOCK_WHAT, parse_clock
from railsim.scenario.plausible import as_float, plausible_number, walk_numbers

MAX_COUNT = 10**9  # the largest count (trips, cars, every-n) any scenario field may hold
_ID_RE = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_\-]*$")


# ---- wording ---------------------------------------------------------------------------------------------------


def field_type_name(f: dataclasses.Field[Any]) -> str:
    """A dataclass field's type as written ("float", "int", "str"): the annotation's text under postponed
    annotations, the class itself where the dataclass is compiled (railsim.native compiles VehicleParams)."""
    return f.type if isinstance(f.type, str) else str(getattr(f.type, "__name__", f.type))


def join_path(path: str, key: Any) -> str:
    """``path.key`` (just ``key`` at the top level)."""
    return f"{path}.{key}" if path else str(key)


def short_repr(value: Any, limit: int = 60) -> str:
    """``repr(value)`` for messages: bounded work and at most ``limit`` characters (:func:`railsim.inputs.excerpt`;
    a value built from YAML aliases may be huge, and its message must not be)."""
    return excerpt(value, limit)


def did_you_mean(value: str, choices: Iterable[str]) -> str:
    """`` (did you mean 'x'?)`` for the closest of ``choices``, or ``""`` when none is close."""
    close = difflib.get_close_matches(str(value), [str(c) for c in choices], n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _num(x: float) -> str:
    return f"{x:g}"


def bound_text(gt: float | None, ge: float | None, le: float | None) -> str:
    """``"> 0"``, ``">= 1"``, ``"in [0, 1]"``, ``"<= 5"`` or ``""``: the range part of "expected a number ..."."""
    lo = f"> {_num(gt)}" if gt is not None else f">= {_num(ge)}" if ge is not None else None
    if lo and le is not None:
        return f"in ({_num(gt)}, {_num(le)}]" if gt is not None else f"in [{_num(ge)}, {_num(le)}]"  # type: ignore[arg-type]
    if lo:
        return lo
    return f"<= {_num(le)}" if le is not None else ""


def require_top_mapping(data: Any, source: str) -> None:
    """A scenario file must hold a mapping (an empty file parses to ``None``)."""
    if data is None:
        raise ConfigError(source, None, "expected a scenario mapping, got an empty file")
    if not isinstance(data, dict):
        raise ConfigError(source, None, f"expected a mapping at the top level, got {describe_kind(data)}")


# ---- the checker -----------------------------------------------------------------------------------------------


class Checker:
    """Checks values of one scenario file; every failure becomes a :class:`ConfigError` naming ``source``."""

    def __init__(self, source: str, base_dir: Path) -> None:
        self.source = source
        self.base_dir = base_dir

    def fail(self, path: str | None, message: str) -> ConfigError:
        """The error for ``path`` (``None``/``""``: the file as a whole); raise it."""
        return ConfigError(self.source, path or None, message)

    def expect(self, path: str, what: str, got: Any) -> ConfigError:
        """``expected <what>, got <value>``."""
        return self.fail(path, f"expected {what}, got {short_repr(got)}")

    def mapping(
        self, value: Any, path: str, required: Sequence[str] = (), optional: Sequence[str] = (), what: str = "a mapping"
    ) -> dict[str, Any]:
        """Check a mapping with a fixed key set; returns it. ``required``/``optional`` empty = free keys."""
        if not isinstance(value, dict):
            raise self.expect(path, what, value)
        allowed = list(required) + list(optional)
        if allowed:
            for key in value:
                if key not in allowed:
                    hint = did_you_mean(str(key), allowed)
                    raise self.fail(
                        join_path(path, key), f"unknown key{hint}; allowed keys: {', '.join(sorted(allowed))}"
                    )
            for key in required:
                if key not in value:
                    raise self.fail(join_path(path, key), "missing required key")
        return value

    def free_mapping(self, value: Any, path: str, what: str = "a mapping") -> dict[str, Any]:
        """A mapping with any string keys."""
        if not isinstance(value, dict):
            raise self.expect(path, what, value)
        for key in value:
            if not isinstance(key, str):
                raise self.expect(join_path(path, key), "string keys", key)
        return value

    def number(
        self, value: Any, path: str, gt: float | None = None, ge: float | None = None, le: float | None = None
    ) -> float:
        """A finite int or float (not a bool) within the given bounds and physically plausible for the unit in the
        field's name (:mod:`railsim.scenario.plausible`), as a float."""
        bound = bound_text(gt, ge, le)
        what = f"a number {bound}".rstrip()
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.expect(path, what, value)
        x = as_float(value)
        if not math.isfinite(x):
            raise self.expect(path, f"a finite number {bound}".rstrip(), value)
        if (gt is not None and not x > gt) or (ge is not None and not x >= ge) or (le is not None and not x <= le):
            raise self.expect(path, what, value)
        implausible = plausible_number(x, path)
        if implausible is not None:
            raise self.expect(path, implausible, value)
        return x

    def integer(self, value: Any, path: str, ge: int | None = None, le: int = MAX_COUNT) -> int:
        """An int (not a bool), at least ``ge`` and at most ``le`` (a count: default :data:`MAX_COUNT`)."""
        what = f"an integer >= {ge}" if ge is not None else "an integer"
        if isinstance(value, bool) or not isinstance(value, int) or (ge is not None and value < ge):
            raise self.expect(path, what, value)
        if value > le:
            raise self.expect(path, f"an integer in [{ge}, {le}]" if ge is not None else f"an integer <= {le}", value)
        return int(value)

    def boolean(self, value: Any, path: str) -> bool:
        """``true`` or ``false`` (not 0/1, not a string)."""
        if not isinstance(value, bool):
            raise self.expect(path, "true or false", value)
        return value

    def plausible_tree(self, value: Any, path: str) -> None:
        """Every number in a free parameter block (a controller's ``params``, a world's ``params``) finite and
        plausible for the unit in its name; the block's own checks come after."""
        for where, x in walk_numbers(value, path):
            implausible = plausible_number(x, where)
            if implausible is not None:
                raise self.fail(where, f"expected {implausible}, got {x:g}")

    def string(
        self, value: Any, path: str, choices: Sequence[str] | None = None, what: str = "a non-empty string"
    ) -> str:
        """A non-blank string, or one of ``choices`` (with a "did you mean")."""
        if choices is not None:
            if not isinstance(value, str) or value not in choices:
                hint = did_you_mean(value, choices) if isinstance(value, str) else ""
                raise self.fail(path, f"expected one of {', '.join(choices)}, got {short_repr(value)}{hint}")
            return value
        if not isinstance(value, str) or not value.strip():
            raise self.expect(path, what, value)
        return value

    def ident(self, value: Any, path: str) -> str:
        """An id usable in trip names and file names: letters, digits, ``_``, ``-``."""
        if not isinstance(value, str) or not _ID_RE.match(value):
            raise self.expect(path, "an id of letters, digits, '_' or '-'", value)
        return value

    def string_list(self, value: Any, path: str) -> list[str]:
        """A list of non-blank strings."""
        if not isinstance(value, list):
            raise self.expect(path, "a list of strings", value)
        return [self.string(v, f"{path}[{i}]") for i, v in enumerate(value)]

    def subset(self, value: Any, path: str, choices: Sequence[str]) -> list[str]:
        """A list of distinct members of ``choices``."""
        if not isinstance(value, list):
            raise self.expect(path, f"a list, a subset of [{', '.join(choices)}]", value)
        out: list[str] = []
        for i, v in enumerate(value):
            item = self.string(v, f"{path}[{i}]", choices)
            if item in out:
                raise self.fail(f"{path}[{i}]", f"expected distinct values, got {item!r} twice")
            out.append(item)
        return out

    def window(self, m: Mapping[str, Any], path: str) -> tuple[float, float]:
        """The activity window ``from_s <= t < until_s`` of ``m`` (``from_s`` default 0, ``until_s`` default ∞)."""
        from_s = self.number(m.get("from_s", 0.0), f"{path}.from_s", ge=0.0)
        until_s = self.number(m["until_s"], f"{path}.until_s", ge=from_s) if "until_s" in m else math.inf
        return from_s, until_s

    def clock(self, value: Any, path: str) -> float:
        """A clock time string → seconds after midnight."""
        try:
            return parse_clock(value)
        except ValueError:
            raise self.expect(path, CLOCK_WHAT, value) from None

    def path_value(self, value: Any, path: str) -> Path:
        """An existing file, relative to ``base_dir`` unless absolute; returned resolved."""
        text = self.string(value, path, what="a file path")
        p = Path(text).expanduser()
        p = p if p.is_absolute() else (self.base_dir / p)
        p = p.resolve()
        if not p.is_file():
            raise self.fail(path, f"expected an existing file, got {short_repr(text)} (looked for {p})")
        return p

    def dataclass_fields(self, values: Mapping[str, Any], path: str, module: str, cls_name: str) -> None:
        """Build ``module.cls_name(**values)`` once: unknown fields and rejected values name ``path.field``.

        For parameter blocks handed to another layer's dataclass (``junction.params`` →
        ``controllers.junction.model.JunctionParams``); a ``ValueError("field: reason")`` from the dataclass
        becomes an error at ``path.field``. The module is imported only when such a block is validated.
        """
        self.plausible_tree(dict(values), path)
        cls = getattr(importlib.import_module(module), cls_name)
        types = {f.name: field_type_name(f) for f in dataclasses.fields(cls)}
        names = set(types)
        for key in values:
            if key not in names:
                raise self.fail(
                    f"{path}.{key}",
                    f"unknown field{did_you_mean(key, sorted(names))}; known: {', '.join(sorted(names))}",
                )
            if types[key] == "float":  # a number field: no strings ('inf' is one), no bools
                self.number(values[key], f"{path}.{key}")
            elif types[key] == "int":
                self.integer(values[key], f"{path}.{key}")
        try:
            cls(**values)
        except (TypeError, ValueError) as exc:
            msg = str(exc)
            field_name, _, rest = msg.partition(":")
            if field_name in values:
                raise self.fail(f"{path}.{field_name}", rest.strip() or msg) from None
            raise self.fail(path, msg) from None
