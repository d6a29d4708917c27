"""User-facing errors: one exception type that names the file, the field path and the expectation.

Everything a user can get wrong (a scenario, a line description, an impossible parameter) raises
:class:`ConfigError`. The CLI prints ``str(err)`` on one line and exits with code 2, so the user sees e.g.::

    scenarios/peak.yaml: services[2].headway_s: expected a number > 0, got -150

and never a traceback. A message is cut at :data:`MAX_MESSAGE_CHARS` characters, a last guard against echoing a
user's file (values are quoted through :func:`railsim.inputs.excerpt`, at most 80 characters, before that).
Internal bugs stay ordinary exceptions: the CLI writes their traceback to a log file and exits with
:data:`EXIT_INTERNAL_ERROR`.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

MAX_MESSAGE_CHARS = 1000
QUOTE_CHARS = 80  # the longest quote of a user value (railsim.inputs.EXCERPT_CHARS)
# a quoted value ('…' or "…") or an unbroken run of characters longer than a quote may be; a quote mark inside a
# word is an apostrophe ("the platform's edge"), neither the start nor the end of a quote
_Q = QUOTE_CHARS - 1
_LONG_QUOTE = re.compile(rf"(?<!\w)'[^'\n]{{{_Q},}}'(?!\w)|(?<!\w)\"[^\"\n]{{{_Q},}}\"(?!\w)|\S{{{2 * QUOTE_CHARS},}}")


def bound_quotes(message: str) -> str:
    """``message`` with every quoted value longer than :data:`QUOTE_CHARS` cut to that length (``...`` marks the
    cut): the last guard for a message that quoted a user's value without :func:`railsim.inputs.excerpt`."""

    def cut(m: re.Match[str]) -> str:
        text = m.group(0)
        limit = QUOTE_CHARS if text[0] in "'\"" else 2 * QUOTE_CHARS
        return text if len(text) <= limit else text[: limit - 4] + "..." + (text[0] if text[0] in "'\"" else "")

    return _LONG_QUOTE.sub(cut, message)


class ConfigError(Exception):
    """Bad input from a user file or an impossible parameter.

    Attributes:
        source: the file (or a short label such as ``"<scenario>"``) the bad value came from.
        field: the dotted/indexed path of the value inside that file, e.g. ``stations[3].km``.
        message: what was expected and what was found.
    """

    def __init__(self, source: str | Path | None, field: str | None, message: str) -> None:
        self.source = str(source) if source is not None else None
        # a field path holds the user's keys: one with a newline or another control character is shown escaped
        self.field = field if field is None or field.isprintable() else field.encode("unicode_escape").decode("ascii")
        message = " ".join(message.split()) if "\n" in message else message  # one line, whatever went in
        message = bound_quotes(message)
        self.message = message if len(message) <= MAX_MESSAGE_CHARS else message[: MAX_MESSAGE_CHARS - 3] + "..."
        super().__init__(self.__str__())

    def __str__(self) -> str:
        parts = [p for p in (self.source, self.field) if p]
        prefix = ": ".join(parts)
        return f"{prefix}: {self.message}" if prefix else self.message


class SimulationError(Exception):
    """A run could not continue (SUMO refused an operation, a world is inconsistent with a scenario).

    The CLI reports these on one line with exit code 3; the partial outputs already written stay on disk.
    """


class RunFolderError(Exception):
    """The machine refused a run's outputs: a full disk, a file-size limit, no permission, a folder in use.

    The message names the path and the OS's reason on one line; the CLI prints it and exits with code 3
    (:data:`EXIT_SIMULATION_ERROR`: an environment error, not bad input and not a bug).
    """


EXIT_CONFIG_ERROR = 2
EXIT_SIMULATION_ERROR = 3
EXIT_INTERNAL_ERROR = 4  # a bug in railsim: one line pointing to a log file with the traceback


def require(name: str, ok: bool, expectation: str, value: Any) -> None:
    """Raise ``ValueError("<name>: expected <expectation>, got <value>")`` unless ``ok``.

    The parameter check of physics and controllers (factories raise ValueError; the scenario layer turns it into
    a message naming the file and field).
    """
    if not ok:
        raise ValueError(f"{name}: expected {expectation}, got {value!r}")
