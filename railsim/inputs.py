"""Reading user input files so that no file can break the reader: bounded work, bounded echo.

A scenario, a sweep file or a line description is text from a user; a typo, a fuzzer or a hostile file must end in
one :class:`~railsim.errors.ConfigError` line (exit 2), never a hang, a traceback or a disclosure. Four guards, in
the order a file meets them:

1. **Regular files only** (:func:`read_input_text`). ``os.stat`` first (it does not block on a FIFO): a directory,
   a device (``/dev/zero`` would be read forever), a socket or a pipe is refused with a message naming the path.
2. **A size limit before reading** (:data:`MAX_INPUT_BYTES`): at most that many bytes are read, so even a file that
   grows while we read it costs bounded memory.
3. **Bounded YAML structure before constructing** (:func:`check_yaml_bounds`). PyYAML's composer and constructor
   recurse once per nesting level (``[[[[…]]]]`` 5,000 deep is a ``RecursionError``), and aliases let 1 KB of text
   stand for millions of values (the "billion laughs": ``&a [x,x,…]``, ``&b [*a,*a,…]``, …). The check walks
   PyYAML's event stream — its parser keeps an explicit stack, so deep input cannot overflow it — and tracks, per
   anchor, the number of values and the depth its node expands to. It refuses nesting deeper than
   :data:`MAX_DEPTH`, more than :data:`MAX_VALUES` values after alias expansion, and an alias used inside its own
   anchor (a recursive structure), each at the line and column where the limit is crossed.
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


def _where(mark: Any) -> str | None:
    return f"line {mark.line + 1}, column {mark.column + 1}" if mark is not None else None


class _Frame:
    """An open collection in the event stream: values and depth below it so far, its anchor."""

    __slots__ = ("anchor", "values", "depth")

    def __init__(self, anchor: str | None) -> None:
        self.anchor = anchor
        self.values = 0
        self.depth = 0


def check_yaml_bounds(text: str, source: str, loader: type = yaml.SafeLoader) -> None:
    """Refuse YAML ``text`` whose structure, aliases expanded, is deeper than :data:`MAX_DEPTH` or holds more than
    :data:`MAX_VALUES` values, or that uses an alias inside its own anchor. Syntax errors are left to the loader
    (this returns at the first one, so the loader reports it with its own line and column)."""
    anchors: dict[str, tuple[int, int]] = {}  # anchor -> (values, depth) of its node
    stack: list[_Frame] = [_Frame(None)]  # the document level at the bottom
    try:
        for event in yaml.parse(text, Loader=loader):
            if isinstance(event, (yaml.SequenceStartEvent, yaml.MappingStartEvent)):
                if len(stack) > MAX_DEPTH:
                    raise ConfigError(
                        source, _where(event.start_mark), f"expected nesting at most {MAX_DEPTH} levels deep"
                    )
                stack.append(_Frame(event.anchor))
                continue
            if isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)):
                frame = stack.pop()
                values, depth = 1 + frame.values, 1 + frame.depth
                if frame.anchor is not None:
                    anchors[frame.anchor] = (values, depth)
            elif isinstance(event, yaml.ScalarEvent):
                values, depth = 1, 0
                if event.anchor is not None:
                    anchors[event.anchor] = (values, depth)
            elif isinstance(event, yaml.AliasEvent):
                if any(f.anchor == event.anchor for f in stack):
                    raise ConfigError(
                        source, _where(event.start_mark), f"alias *{event.anchor} used inside its own anchor"
                    )
                values, depth = anchors.get(str(event.anchor), (1, 0))  # an undefined alias: the loader says so
                if len(stack) - 1 + depth > MAX_DEPTH:
                    raise ConfigError(
                        source,
                        _where(event.start_mark),
                        f"expected nesting at most {MAX_DEPTH} levels deep (alias *{event.anchor} expanded)",
                    )
            else:
                continue
            top = stack[-1]
            top.values += values
            top.depth = max(top.depth, depth)
            if sum(f.values for f in stack) > MAX_VALUES:
                raise ConfigError(
                    source,
                    _where(event.start_mark),
                    f"expected at most {MAX_VALUES} values with aliases expanded (an alias expands too far)",
                )
    except yaml.YAMLError:
        return  # the loader reports syntax errors with their place
