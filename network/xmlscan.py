"""One streaming pass over a user's XML file (an OSM extract, a SUMO net) before SUMO's tools see it.

netconvert and SUMO read XML with Xerces, whose refusals name no place in the file ("Error: whitespace expected")
and which, given a document type with entity declarations, either expands them (a "billion laughs" file of a few
hundred bytes grows to gigabytes) or switches to validation and reports a missing declaration. :func:`scan` reads
the file once with expat, element by element, in bounded memory, and turns what it finds into a
:class:`~railsim.errors.ConfigError` naming the file and the place:

* not XML (empty, truncated, a stray ``<`` or ``&``, invalid UTF-8): field ``line L, column C``, expat's reason;
* a ``<!DOCTYPE>`` with ``<!ENTITY>`` declarations: refused before any entity is expanded;
* a ``.gz`` file whose gzip stream is broken: the file, "a broken gzip stream";
* whatever the caller's ``on_start(tag, attributes, line)`` raises for one element (a latitude of ``nan``, a lane
  of length 0): the caller names the element.

The root element's tag is returned, so the caller can say what kind of file it expected.
"""

from __future__ import annotations

import gzip
import io
import xml.parsers.expat
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

from railsim.errors import ConfigError

OnStart = Callable[[str, dict[str, str], int], None]
_CHUNK_BYTES = 1 << 20


def open_xml(path: Path) -> gzip.GzipFile | io.BufferedReader:
    """The file's bytes, gunzipped when its name ends in ``.gz``."""
    if path.name.endswith(".gz"):
        return gzip.open(path, "rb")
    return open(path, "rb")


def scan(path: Path, what: str, on_start: OnStart | None = None) -> str:
    """Parse ``path`` (gzip-compressed when its name ends in ``.gz``) as ``what`` (e.g. "an OpenStreetMap file"),
    calling ``on_start(tag, attributes, line)`` for every element; the root element's tag. ConfigError (module
    docstring) on anything that is not well-formed XML free of entity declarations."""
    parser = xml.parsers.expat.ParserCreate()
    root: list[str] = []

    def start(tag: str, attrs: dict[str, str]) -> None:
        if not root:
            root.append(tag)
        if on_start is not None:
            on_start(tag, attrs, parser.CurrentLineNumber)

    def entity(name: str, *_: Any) -> None:
        raise ConfigError(
            path,
            f"line {parser.CurrentLineNumber}",
            f"expected {what} without entity declarations, got <!ENTITY {name}> (an entity expansion can make a "
            "file of a few hundred bytes gigabytes long)",
        )

    parser.StartElementHandler = start
    parser.EntityDeclHandler = entity
    try:
        with open_xml(path) as fh:
            while chunk := fh.read(_CHUNK_BYTES):
                parser.Parse(chunk, False)
            parser.Parse(b"", True)
    except xml.parsers.expat.ExpatError as exc:
        reason = xml.parsers.expat.ErrorString(exc.code)
        raise ConfigError(
            path, f"line {exc.lineno}, column {exc.offset}", f"expected {what} in XML: {reason}"
        ) from None
    except (gzip.BadGzipFile, EOFError, zlib.error) as exc:
        raise ConfigError(
            path, None, f"expected {what} compressed with gzip, got a broken gzip stream ({exc})"
        ) from None
    return root[0]
