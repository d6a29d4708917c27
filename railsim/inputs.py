"""Reading user input files so that no file can break the reader: bounded work, bounded echo.

A scenario, a sweep file or a line description is text from a user; a typo, a fuzzer or a hostile file must end in
one :class:`~railsim.errors.ConfigError` line (exit 2), never a hang, a traceback or a disclosure. Four guards, in
the order a file meets them:

1. **Regular files only** (:func:`read_input_text`). ``os.stat`` first (it does not block on a FIFO): a directory,
   a device (``/dev/zero`` would be read forever), a socket or a pipe is refused with a message naming the path.
2. **A size limit before reading** (:data:`MAX_INPUT_BYTES`): at most that many bytes are read, so even a file that
   grows while we read it costs bounded memory.
3. **Bounded YAML structure while parsing** (:class:`BoundedSafeLoader`). PyYAML's composer and constructor
   recurse once per nesting level (``[[[[…]]]]`` 5,000 deep is a ``RecursionError``), and aliases let 1 KB of text
   stand for millions of values (the "billion laughs": ``&a [x,x,…]``, ``&b [*a,*a,…]``, …). The loader checks
   each event of PyYAML's parser — which keeps an explicit stack, so deep input cannot overflow it — before the
   composer sees it, tracking per anchor the number of values and the depth its node expands to. It refuses
   nesting deeper than :data:`MAX_DEPTH`, more than :data:`MAX_VALUES` values after alias expansion, and an alias
   used inside its own anchor (a recursive structure), each at the line and column where the limit is crossed
   (:class:`YAMLLimitError`; :func:`limit_error` makes it the one-line ``ConfigError``). An integer of more than
   :data:`MAX_INT_DIGITS` digits is refused the same way (Python will not convert a 5,000-digit string).
4. **Bounded echo** (:func:`excerpt`): error messages quote a value through a bounded ``repr`` (``reprlib``: a few
   items per level, a few levels, long strings cut) and then at most :data:`EXCERPT_CHARS` characters, so quoting
   a value costs little however large it is, and a file's content is never printed whole.

The module sits beside :mod:`railsim.errors` (it imports nothing else of railsim) so that both the scenario layer
and :mod:`network` read their files through it.
"""

from __future__ import annotations

import os
import reprlib
import stat
from pathlib import Path
from typing import Any

import yaml

from railsim.errors import ConfigError

MAX_INPUT_BYTES = 4 * 1024 * 1024  # a Line 3 scenario is 3.5 KB, a whole-day timetable of explicit times < 100 KB
MAX_DEPTH = 50  # a scenario nests 7 levels deep at most (controllers.x.params.segments[0].at_s)
MAX_VALUES = 200_000  # values after alias expansion; a service day's scenario has a few hundred
EXCERPT_CHARS = 80  # the longest quote of a user value in a message


class _Repr(reprlib.Repr):
    """``reprlib`` keeping a mapping's keys in the user's order (``reprlib`` sorts them)."""

    def repr_dict(self, x: dict[Any, Any], level: int) -> str:
        if not x:
            return "{}"
        if level <= 0:
            return "{...}"
        items = [f"{self.repr1(k, level - 1)}: {self.repr1(v, level - 1)}" for k, v in list(x.items())[: self.maxdict]]
        return "{" + ", ".join(items) + (", ..." if len(x) > self.maxdict else "") + "}"


_REPR = _Repr()
_REPR.maxlevel = 3
_REPR.maxstring = EXCERPT_CHARS
_REPR.maxother = EXCERPT_CHARS
_REPR.maxlong = 40


def excerpt(value: Any, limit: int = EXCERPT_CHARS) -> str:
    """A short ``repr`` of ``value`` for a message: bounded work, at most ``limit`` characters."""
    text = _REPR.repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def describe_kind(value: Any) -> str:
    """What ``value`` is, without its content (``"a string of 1287 characters"``): for a whole file's content."""
    if value is None:
        return "nothing"
    if isinstance(value, str):
        return f"a string of {len(value)} characters"
    if isinstance(value, list):
        return f"a list of {len(value)} items"
    return f"a {type(value).__name__}"


def read_input_text(path: Path, source: str, what: str = "file") -> str:
    """The UTF-8 text of the regular file ``path`` (at most :data:`MAX_INPUT_BYTES`); else a ``ConfigError``.

    ``source`` labels the error (usually the path as the user wrote it); ``what`` names the expected kind of file
    ("scenario file", "line description"). The message names the path, never the file's content.
    """
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise ConfigError(source, None, "file not found") from None
    except OSError as exc:
        raise ConfigError(source, None, f"cannot read the {what}: {exc.strerror or exc}") from None
    if stat.S_ISDIR(st.st_mode):
        raise ConfigError(source, None, f"expected a {what}, got a directory")
    if not stat.S_ISREG(st.st_mode):
        raise ConfigError(source, None, f"expected a {what} (a regular file), got a device, pipe or socket")
    if st.st_size > MAX_INPUT_BYTES:
        raise ConfigError(source, None, f"expected a {what} of at most {MAX_INPUT_BYTES} bytes, got {st.st_size}")
    try:
        with open(path, "rb") as fh:
            data = fh.read(MAX_INPUT_BYTES + 1)
    except OSError as exc:
        raise ConfigError(source, None, f"cannot read the {what}: {exc.strerror or exc}") from None
    if len(data) > MAX_INPUT_BYTES:
        raise ConfigError(source, None, f"expected a {what} of at most {MAX_INPUT_BYTES} bytes, got more")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        raise ConfigError(source, None, "expected UTF-8 text, got undecodable bytes") from None


class YAMLLimitError(yaml.MarkedYAMLError):
    """YAML beyond the structural limits (depth, values after aliases, a recursive alias), at its line/column."""


class _Bounds:
    """The structure seen so far in an event stream: open collections (values and depth below each, its anchor)
    and, per anchor, the values and depth its node expands to."""

    def __init__(self) -> None:
        self.anchors: dict[str, tuple[int, int]] = {}
        self.stack: list[list[Any]] = [[None, 0, 0]]  # [anchor, values, depth]; the document level at the bottom

    def feed(self, event: yaml.Event) -> None:
        stack = self.stack
        if isinstance(event, (yaml.SequenceStartEvent, yaml.MappingStartEvent)):
            if len(stack) > MAX_DEPTH:
                self._fail(event, f"expected nesting at most {MAX_DEPTH} levels deep")
            stack.append([event.anchor, 0, 0])
            return
        if isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)):
            anchor, inner, inner_depth = stack.pop()
            values, depth = 1 + inner, 1 + inner_depth
            if anchor is not None:
                self.anchors[anchor] = (values, depth)
        elif isinstance(event, yaml.ScalarEvent):
            values, depth = 1, 0
            if event.anchor is not None:
                self.anchors[event.anchor] = (values, depth)
        elif isinstance(event, yaml.AliasEvent):
            if any(frame[0] == event.anchor for frame in stack):
                self._fail(event, f"expected no alias inside its own anchor, got *{event.anchor}")
            values, depth = self.anchors.get(str(event.anchor), (1, 0))  # an undefined alias: the composer says so
            if len(stack) - 1 + depth > MAX_DEPTH:
                self._fail(event, f"expected nesting at most {MAX_DEPTH} levels deep (alias *{event.anchor} expanded)")
        else:
            if isinstance(event, yaml.DocumentStartEvent):  # every document starts afresh
                self.anchors.clear()
            return
        top = stack[-1]
        top[1] += values
        top[2] = max(top[2], depth)
        if sum(frame[1] for frame in stack) > MAX_VALUES:
            self._fail(event, f"expected at most {MAX_VALUES} values with aliases expanded (an alias expands too far)")

    @staticmethod
    def _fail(event: yaml.Event, problem: str) -> None:
        raise YAMLLimitError(problem=problem, problem_mark=event.start_mark)  # type: ignore[arg-type]


class BoundedSafeLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that checks every event against the limits *before* the composer sees it, in the same
    single pass: the composer recurses at most :data:`MAX_DEPTH` levels and no alias graph beyond
    :data:`MAX_VALUES` values is built. A breach raises :class:`YAMLLimitError` at its line and column."""

    def __init__(self, stream: Any) -> None:
        super().__init__(stream)
        self._bounds = _Bounds()

    def get_event(self) -> Any:
        event = super().get_event()
        self._bounds.feed(event)
        return event


MAX_INT_DIGITS = 100


def _construct_bounded_int(loader: BoundedSafeLoader, node: yaml.ScalarNode) -> int:
    """An int of at most :data:`MAX_INT_DIGITS` digits (Python refuses to convert very long digit strings)."""
    if sum(ch.isalnum() for ch in str(node.value)) > MAX_INT_DIGITS:
        raise YAMLLimitError(
            problem=f"expected an integer of at most {MAX_INT_DIGITS} digits", problem_mark=node.start_mark
        )
    return int(loader.construct_yaml_int(node))


BoundedSafeLoader.add_constructor("tag:yaml.org,2002:int", _construct_bounded_int)


def limit_error(exc: YAMLLimitError, source: str) -> ConfigError:
    """The one-line error for a :class:`YAMLLimitError` raised while loading ``source``."""
    mark = exc.problem_mark
    where = f"line {mark.line + 1}, column {mark.column + 1}" if mark is not None else None
    return ConfigError(source, where, str(exc.problem))
